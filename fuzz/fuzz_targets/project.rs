//! `cargo +nightly fuzz run project`: the studio's project reader never panics on arbitrary
//! text.
#![no_main]

use glocal::studio::project::Project;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = Project::from_json(&String::from_utf8_lossy(data), "fuzz.glocal");
});
