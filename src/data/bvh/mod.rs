//! BVH (Biovision Hierarchy) motion files: a reader for any hierarchy and channel layout, and
//! a writer that reproduces a layout or picks a standard one.
//!
//! Reading:
//! - `ROOT` / `JOINT` blocks become joints in file order (depth first, so parents come before
//!   children and the frame values follow joint order). Several `ROOT`s are allowed.
//! - `End Site` blocks are **not** joints: they carry no channels and only mark where a leaf
//!   bone ends, so they are checked and dropped. Joint counts are therefore those of the
//!   `ROOT`/`JOINT` lines (Bandai: 22, CMU dance: 43).
//! - `CHANNELS` may list position and rotation channels in any order on any joint. Rotation
//!   channels compose in the order listed (`Zrotation Xrotation Yrotation` is
//!   `Rz * Rx * Ry`, angles in degrees). Position channels *replace* the matching component of
//!   the joint's `OFFSET` (the offset stays the skeleton's rest offset).
//! - Keywords are case-insensitive; tokens may be separated by spaces or tabs; lines may end
//!   in LF or CRLF; a UTF-8 byte-order mark is skipped.
//! - `fps` is `1 / Frame Time`, snapped to the nearest integer when within 1e-4 of it
//!   relatively (files store `0.0333333` for 30 fps).
//! - Every problem is a [`FormatError`] naming the file and line; no input makes the reader
//!   panic (see the fuzz target in `fuzz/`).
//!
//! Writing: see [`write_bvh`].

mod layout;
mod reader;
#[cfg(test)]
mod tests;
mod writer;

pub use layout::{BvhLayout, JointChannels};
pub use reader::{read_bvh, read_bvh_layout, read_bvh_layout_with_unit, read_bvh_with_unit};
pub use writer::write_bvh;
