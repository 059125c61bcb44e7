//! `cargo +nightly fuzz run model_json`: model.json's reader never panics, and a spec it
//! accepts is one the model can be built from (its validation ran before anything else).
#![no_main]

use glocal::model::spec::ModelSpec;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(spec) = ModelSpec::from_json(&String::from_utf8_lossy(data), "fuzz/model.json") {
        assert!(spec.validate().is_ok());
        assert_eq!(spec.layout.dim(), spec.glogen.block.in_dim);
    }
});
