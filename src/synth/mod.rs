//! Synthesis: timelines of activities, pace, long-term generation and export.

pub mod class_map;
pub mod export;
pub mod foot_lock;
pub mod generate;
pub mod gltf;
pub mod init;
pub mod render;
pub mod rig;
pub mod timeline;

pub use generate::{generate, GenerateOptions, Generated, SegmentSpan, Transition, DEFAULT_CLASS_STRENGTH, DEFAULT_TRANSITION_SECONDS};
pub use init::InitPose;
pub use timeline::{Segment, Timeline};
