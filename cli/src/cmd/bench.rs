//! `intellwheels bench ...`

use std::process::ExitCode;

/// The `bench` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Placeholder until implemented.
    Todo,
}

pub fn run(_command: Command) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`bench` is not implemented yet")
}
