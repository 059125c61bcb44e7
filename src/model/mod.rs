//! GloGen and LocGen.
pub mod block;
pub mod lstm;
pub mod bench;
pub mod adamw;
pub mod corpus;
pub mod glocal;
pub mod spec;
pub mod train;
