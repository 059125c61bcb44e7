//! `cargo +nightly fuzz run npy`: the NPY reader never panics on arbitrary bytes, and a
//! `(T, J, 3)` array it accepts as a motion has finite positions.
#![no_main]

use std::sync::Arc;

use glam::Vec3;
use glocal::data::npy::{motion_from_npy, read_npy};
use glocal::motion::Skeleton;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = read_npy(data, "fuzz.npy");
    let skeleton = Skeleton::new(vec!["r".into(), "a".into()], vec![None, Some(0)], vec![Vec3::ZERO, Vec3::Y], 0.01).expect("fixed skeleton");
    if let Ok(m) = motion_from_npy(data, "fuzz.npy", Arc::new(skeleton), 25.0) {
        assert!(m.positions().iter().all(|p| p.is_finite()), "non-finite positions accepted");
    }
});
