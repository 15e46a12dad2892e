//! `intellwheels log ...`: query and replay the logger agent's message log.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use iw_logger::{LogItem, LoggedMessage, Query};

/// The `log` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Print the logged messages that match every given filter, in log order.
    ///
    /// Output: one line per message, `time_ns sender -> receivers performative [conversation]`,
    /// then the ACL text indented; with `--json`, one JSON object per line (`time_ns`, `sender`,
    /// `receivers`, `performative`, `conversation_id`, `acl`). Exit status 0 when the whole log
    /// was read, even when nothing matches; 1 when any of it could not be read: each damaged
    /// region (a flipped byte, a torn tail left by a crash or a write in progress) is reported on
    /// stderr with the file, its byte offset and what is wrong, and the intact records after it
    /// are still printed; a file that is not a log at all prints nothing. The log is read as it
    /// is printed, so a log of any size is queried in bounded memory.
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
    ///
    /// Damage is handled as by `log query`: each damaged region is reported on stderr (file, byte
    /// offset, what) when the replay reaches it, every intact record is replayed, and the exit
    /// status is 1.
    Replay {
        /// The log file.
        #[arg(long)]
        log: PathBuf,
        /// Replay speed: 1 = real time, 10 = ten times faster, 0 = no waiting; otherwise between
        /// 0.001 and 1e9.
        #[arg(long, default_value = "1", value_parser = super::flags::replay_speed)]
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

/// The messages of the log at `log` that `query` selects, handed to `each` in log order as they
/// are read (memory does not follow the log's size); each damaged region is reported on stderr
/// as it is met. True when there was any.
fn stream(
    log: &Path,
    query: &Query,
    mut each: impl FnMut(&LoggedMessage) -> anyhow::Result<()>,
) -> anyhow::Result<bool> {
    let context = || format!("reading {}", log.display());
    let mut damaged = 0usize;
    for item in query.stream(log).with_context(context)? {
        match item.with_context(context)? {
            LogItem::Record(m) => each(&m)?,
            LogItem::Damage(d) => {
                eprintln!("warning: {}: {d}", log.display());
                damaged += 1;
            }
        }
    }
    if damaged > 0 {
        eprintln!(
            "error: {}: {damaged} damaged region(s) skipped; every intact record was read",
            log.display()
        );
    }
    Ok(damaged > 0)
}

/// Runs a `log` subcommand: exit 1 for a log that could not be read wholly (see `--help`).
pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    match run_inner(command) {
        Ok(code) => Ok(code),
        Err(err) if super::is_broken_pipe(&err) => Err(err),
        Err(err) => {
            eprintln!("error: {}", super::describe(&err));
            Ok(ExitCode::FAILURE)
        }
    }
}

fn run_inner(command: Command) -> anyhow::Result<ExitCode> {
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
            let damaged = stream(&log, &query, |m| {
                if json {
                    writeln!(out, "{}", serde_json::to_string(m)?)?;
                } else {
                    print_line(&mut out, m)?;
                }
                Ok(())
            })?;
            out.flush()?;
            if damaged {
                return Ok(ExitCode::FAILURE);
            }
        }
        Command::Replay { log, speed } => {
            let mut previous_ns = None;
            let damaged = stream(&log, &Query::default(), |m| {
                if let (Some(previous), true) = (previous_ns, speed > 0.0) {
                    let gap_ns = m.time_ns.saturating_sub(previous) as f64 / speed;
                    out.flush()?;
                    // The speed's range keeps this within Duration's (see flags::replay_speed).
                    std::thread::sleep(Duration::from_secs_f64(gap_ns * 1e-9));
                }
                previous_ns = Some(m.time_ns);
                Ok(print_line(&mut out, m)?)
            })?;
            out.flush()?;
            if damaged {
                return Ok(ExitCode::FAILURE);
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
