//! `intellwheels sl ...`: FIPA-SL content at a chosen level.

use std::io::Read;
use std::process::ExitCode;

use anyhow::Context;
use iw_sl::Level;

/// The `sl` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Read SL content on stdin and print its tree as JSON.
    ///
    /// Output: `{"level", "sl", "jade_tree", "content"}`: the level, the content printed back as
    /// canonical SL, the tree as JADE's codec renders it, and the typed tree. Content the level
    /// does not accept: the error (line, column, expected) on stderr and exit status 2.
    Parse {
        /// SL level: sl0, sl1, sl2 or full.
        #[arg(long, default_value = "full", value_parser = parse_level)]
        level: Level,
    },
}

fn parse_level(s: &str) -> Result<Level, String> {
    s.parse().map_err(|e: iw_sl::SlError| e.to_string())
}

pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    match command {
        Command::Parse { level } => {
            // One byte past the parser's limit is enough to refuse; the rest is never read.
            let mut input = String::new();
            std::io::stdin()
                .take(iw_sl::MAX_INPUT_BYTES as u64 + 1)
                .read_to_string(&mut input)
                .context("reading SL content from stdin")?;
            anyhow::ensure!(
                input.len() <= iw_sl::MAX_INPUT_BYTES,
                "SL content on stdin is longer than the limit of {} bytes; refused unread",
                iw_sl::MAX_INPUT_BYTES
            );
            let content = iw_sl::parse(&input, level)
                .with_context(|| format!("SL content refused at level {level}"))?;
            let out = serde_json::json!({
                "level": level.short_name(),
                "sl": content.to_string(),
                "jade_tree": iw_sl::jade_tree(&content, level),
                "content": content,
            });
            println!("{out}");
            Ok(ExitCode::SUCCESS)
        }
    }
}
