//! `intellwheels acl ...`: FIPA-ACL messages between their string form (SC00070) and JSON, and
//! one message sent to another FIPA platform over HTTP ([`send`]).
//!
//! One variant per subcommand in [`Command`], each with its own args struct and function.

use std::io::{Read, Write};
use std::process::ExitCode;

use anyhow::Context;
use iw_acl::AclMessage;
use iw_acl::codec::{self, DEFAULT_MAX_LEN, ParseOptions, PrintOptions};

mod send;

/// The `acl` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Read one ACL string message on stdin and print it as JSON (the FIPA vectors' shape).
    Parse(ParseArgs),
    /// Read a message as JSON on stdin and print its ACL string form.
    Print(PrintArgs),
    /// Send one message to an agent of another FIPA platform over HTTP and print every reply
    /// (performative and content, one per line) until the conversation ends or the timeout.
    Send(Box<send::SendArgs>),
}

/// Flags of `acl parse`.
#[derive(clap::Args)]
pub struct ParseArgs {
    /// Unescape strings as JADE does (only `\"`), instead of also `\\`.
    #[arg(long)]
    jade_compat: bool,
    /// Also print byte content, Base64, under `byte_content` (normally only its length is shown).
    #[arg(long)]
    byte_content: bool,
}

/// Flags of `acl print`.
#[derive(clap::Args)]
pub struct PrintArgs {
    /// Escape strings as JADE reads them (only `"`); fails on strings JADE cannot carry.
    #[arg(long)]
    jade_compat: bool,
}

pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    match command {
        Command::Parse(args) => parse(&args),
        Command::Print(args) => print(&args),
        Command::Send(args) => send::run(&args),
    }
}

/// Stdin as UTF-8, refusing more than `limit` bytes.
fn read_stdin(limit: usize) -> anyhow::Result<String> {
    let mut bytes = Vec::new();
    let limit_plus_one = u64::try_from(limit).unwrap_or(u64::MAX).saturating_add(1);
    std::io::stdin()
        .take(limit_plus_one)
        .read_to_end(&mut bytes)
        .context("reading stdin")?;
    anyhow::ensure!(bytes.len() <= limit, "input exceeds the {limit}-byte limit");
    String::from_utf8(bytes).context("stdin is not UTF-8 text")
}

fn write_stdout(text: &str) -> anyhow::Result<ExitCode> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}").context("writing stdout")?;
    out.flush().context("writing stdout")?;
    Ok(ExitCode::SUCCESS)
}

fn parse(args: &ParseArgs) -> anyhow::Result<ExitCode> {
    let text = read_stdin(DEFAULT_MAX_LEN)?;
    let options = if args.jade_compat {
        ParseOptions::jade()
    } else {
        ParseOptions::default()
    };
    let message = codec::parse_with(&text, &options).context("invalid ACL message on stdin")?;
    let has_bytes = matches!(message.content, Some(iw_acl::Content::Bytes(_)));
    if has_bytes && !args.byte_content {
        // Through a map (its keys come out sorted) to drop the Base64 bytes.
        let mut json = serde_json::to_value(&message)?;
        if let Some(object) = json.as_object_mut() {
            object.remove("byte_content");
        }
        return write_stdout(&serde_json::to_string(&json)?);
    }
    write_stdout(&serde_json::to_string(&message)?)
}

fn print(args: &PrintArgs) -> anyhow::Result<ExitCode> {
    let text = read_stdin(DEFAULT_MAX_LEN)?;
    let message: AclMessage =
        serde_json::from_str(&text).context("invalid message JSON on stdin")?;
    let options = if args.jade_compat {
        PrintOptions::jade()
    } else {
        PrintOptions::default()
    };
    write_stdout(&codec::print_with(&message, &options)?)
}
