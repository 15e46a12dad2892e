//! `intellwheels repeatability ...`

use std::process::ExitCode;

/// Flags of `intellwheels repeatability`.
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`repeatability` is not implemented yet")
}
