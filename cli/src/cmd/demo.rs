//! `intellwheels demo ...`

use std::process::ExitCode;

/// Flags of `intellwheels demo`.
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`demo` is not implemented yet")
}
