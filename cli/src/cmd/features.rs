//! `intellwheels features ...`

use std::process::ExitCode;

/// Flags of `intellwheels features`.
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`features` is not implemented yet")
}
