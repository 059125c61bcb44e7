//! `cargo +nightly fuzz run json_take`: the JSON take reader never panics, and a take it
//! accepts has a valid skeleton, finite positions and segments inside the take.
#![no_main]

use glocal::synth::export::parse_json_take;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok((motion, segments)) = parse_json_take(data, "fuzz.json") {
        assert!(motion.positions().iter().all(|p| p.is_finite()), "non-finite positions accepted");
        assert!(segments.iter().all(|s| s.start_frame <= s.end_frame && s.end_frame <= motion.frames()));
    }
});
