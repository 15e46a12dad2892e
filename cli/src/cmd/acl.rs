//! `intellwheels acl ...`

use std::process::ExitCode;

/// The `acl` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Placeholder until implemented.
    Todo,
}

pub fn run(_command: Command) -> anyhow::Result<ExitCode> {
    anyhow::bail!("`acl` is not implemented yet")
}
