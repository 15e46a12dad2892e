//! `intellwheels log ...`: query and replay the logger agent's message log.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use iw_logger::{LoggedMessage, Query};

/// The `log` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Print the logged messages that match every given filter, in log order.
    ///
    /// Output: one line per message, `time_ns sender -> receivers performative [conversation]`,
    /// then the ACL text indented; with `--json`, one JSON object per line (`time_ns`, `sender`,
    /// `receivers`, `performative`, `conversation_id`, `acl`). Exit status 0 even when nothing
    /// matches; 1 when the log cannot be read (the error names the file and offset).
    Query {
        /// The log file.
        #[arg(long)]
        log: PathBuf,
        /// Sent by this agent.
        #[arg(long)]
        sender: Option<String>,
        /// Addressed to this agent.
        #[arg(long)]
        receiver: Option<String>,
        /// Sent by or to this agent.
        #[arg(long)]
        agent: Option<String>,
        /// With this performative (any case).
        #[arg(long)]
        performative: Option<String>,
        /// In this conversation.
        #[arg(long)]
        conversation: Option<String>,
        /// Logged at or after this time, ns.
        #[arg(long)]
        since_ns: Option<u64>,
        /// Logged before this time, ns.
        #[arg(long)]
        until_ns: Option<u64>,
        /// Whose ACL text contains this string.
        #[arg(long)]
        contains: Option<String>,
        /// One JSON object per line.
        #[arg(long)]
        json: bool,
    },
    /// Print every logged message in order, spaced as they were logged divided by `--speed`
    /// (`--speed 0`: as fast as possible).
    Replay {
        /// The log file.
        #[arg(long)]
        log: PathBuf,
        /// Replay speed: 1 = real time, 10 = ten times faster, 0 = no waiting.
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
    },
}

fn print_line(out: &mut impl Write, m: &LoggedMessage) -> std::io::Result<()> {
    let conversation = m
        .conversation_id
        .as_deref()
        .map(|c| format!(" [{c}]"))
        .unwrap_or_default();
    writeln!(
        out,
        "{} {} -> {} {}{}",
        m.time_ns,
        m.sender,
        m.receivers.join(","),
        m.performative,
        conversation
    )?;
    writeln!(out, "    {}", m.acl)
}

/// Runs a `log` subcommand.
pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match command {
        Command::Query {
            log,
            sender,
            receiver,
            agent,
            performative,
            conversation,
            since_ns,
            until_ns,
            contains,
            json,
        } => {
            let query = Query {
                sender,
                receiver,
                agent,
                performative,
                conversation_id: conversation,
                since_ns,
                until_ns,
                contains,
            };
            let found = query
                .run(&log)
                .with_context(|| format!("querying {}", log.display()))?;
            for m in &found {
                if json {
                    writeln!(out, "{}", serde_json::to_string(m)?)?;
                } else {
                    print_line(&mut out, m)?;
                }
            }
        }
        Command::Replay { log, speed } => {
            if !(speed.is_finite() && speed >= 0.0) {
                anyhow::bail!("--speed must be a finite number >= 0, got {speed}");
            }
            let all = Query::default()
                .run(&log)
                .with_context(|| format!("reading {}", log.display()))?;
            let mut previous_ns = None;
            for m in &all {
                if let (Some(previous), true) = (previous_ns, speed > 0.0) {
                    let gap_ns = m.time_ns.saturating_sub(previous) as f64 / speed;
                    out.flush()?;
                    std::thread::sleep(Duration::from_secs_f64(gap_ns * 1e-9));
                }
                previous_ns = Some(m.time_ns);
                print_line(&mut out, m)?;
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
