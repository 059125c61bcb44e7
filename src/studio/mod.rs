//! The desktop studio (egui). Nothing below this module knows egui exists.

pub mod viewport;

use anyhow::Result;

/// Opens the studio window.
pub fn run() -> Result<()> {
    anyhow::bail!("the studio is not built yet")
}
