//! Synthesis: timelines of activities, pace, long-term generation and export.

pub mod export;
pub mod generate;
pub mod init;
pub mod render;
pub mod timeline;

pub use generate::{generate, GenerateOptions, Generated, InitPose, SegmentSpan, Transition, DEFAULT_CLASS_STRENGTH};
pub use timeline::{Segment, Timeline};
