//! `cargo +nightly fuzz run expmap`: the exponential-map reader, on both layouts (Human3.6M's
//! incremental root and CMU's absolute one), never panics on arbitrary text, and what it
//! accepts has finite positions.
#![no_main]

use glocal::data::expmap::{ExpmapFormat, RootEncoding};
use libfuzzer_sys::fuzz_target;

const SKELETON: &str = r#"{"parents": [-1, 0, 1], "offsets": [[0,0,0],[0,10,0],[0,0,5]]}"#;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for root in [RootEncoding::Incremental, RootEncoding::Absolute] {
        let format = ExpmapFormat::from_skeleton_json(SKELETON, "fuzz.json", root, 50.0, 0.001).expect("fixed skeleton");
        if let Ok(m) = format.read(&text, "fuzz.txt") {
            assert!(m.positions().iter().all(|p| p.is_finite()), "non-finite positions accepted");
        }
    }
});
