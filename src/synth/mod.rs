//! Synthesis: timelines of activities, pace, long-term generation and export.

pub mod class_map;
pub mod constraints;
mod course;
pub mod export;
pub mod foot_lock;
pub mod generate;
mod generated;
mod finish;
mod finish_thread;
mod given;
pub mod held;
pub mod held_frames;
pub mod gltf;
pub mod init;
pub mod joint_names;
pub mod keys;
pub mod looping;
pub mod model_switch;
pub mod options;
pub mod own_start;
mod pace;
pub mod path_follow;
mod plan;
pub mod preset;
pub mod project;
mod reuse;
pub mod render;
pub mod rig;
mod steer;
mod t_pose;
mod take;
pub mod timeline;

/// How a generation ends other than with a take, where the caller acts on the kind (other
/// failures are messages naming what is wrong).
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum Error {
    /// The progress callback asked to stop (a newer edit or the Cancel button in the studio).
    #[error("cancelled")]
    Cancelled,
}

/// 0 below 0, 1 above 1, and the cubic between with zero slope at both ends: the ease of
/// class mixes, key offsets, foot-lock fades and a stand's drift removal.
pub(crate) fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// 1 at 0, falling smoothly (zero slope at both ends) to 0 at 1: the fade of a key's warp
/// and of a given start's join.
pub(crate) fn raised_cosine(x: f32) -> f32 {
    if x >= 1.0 {
        0.0
    } else {
        0.5 * (1.0 + (std::f32::consts::PI * x).cos())
    }
}

pub use generate::generate_reusing;
pub use generated::{Generated, TakeEvents};
pub use reuse::TakeCache;
pub use take::{generate, generate_with};
pub use options::{GenerateOptions, KeyMethod, Transition, DEFAULT_TRANSITION_SECONDS};
pub use plan::SegmentSpan;
pub use constraints::{Key, KeySource, RootPath, Waypoint};
pub use given::file_start_frames;
pub use init::InitPose;
pub use preset::Preset;
pub use project::{Document, Request};
pub use timeline::{Segment, Timeline};
