//! `intellwheels experiment ...`

use std::process::ExitCode;

/// The `experiment` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Placeholder until implemented.
    Todo,
}

pub fn run(_command: Command) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`experiment` is not implemented yet")
}
