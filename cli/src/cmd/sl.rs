//! `intellwheels sl ...`

use std::process::ExitCode;

/// The `sl` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Placeholder until implemented.
    Todo,
}

pub fn run(_command: Command) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`sl` is not implemented yet")
}
