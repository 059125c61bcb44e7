//! GloGen and LocGen.
pub mod lstm;
