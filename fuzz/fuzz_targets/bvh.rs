//! `cargo +nightly fuzz run bvh`: the BVH reader on arbitrary text never panics, and whatever
//! it accepts the writer writes back into a file the reader accepts with the same shape.
#![no_main]

use glocal::data::bvh::{read_bvh_layout, write_bvh};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok((motion, layout)) = read_bvh_layout(&text, "fuzz.bvh") else { return };
    for l in [Some(&layout), None] {
        let written = write_bvh(&motion, l);
        let back = match glocal::data::bvh::read_bvh(&written, "written.bvh") {
            Ok(m) => m,
            Err(e) => panic!("written file does not read back: {e}\n--- input ---\n{text}\n--- written ---\n{written}"),
        };
        assert_eq!(back.joints(), motion.joints());
        assert_eq!(back.frames(), motion.frames());
    }
});
