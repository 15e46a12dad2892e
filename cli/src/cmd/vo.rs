//! `intellwheels vo ...`

use std::process::ExitCode;

/// Flags of `intellwheels vo`.
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`vo` is not implemented yet")
}
