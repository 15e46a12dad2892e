//! `intellwheels`: one thin binary over the libraries. `main` only parses flags and dispatches;
//! each subcommand lives in `cmd/<name>.rs` and every thesis experiment is one of them.
//!
//! Exit codes: 0 success, 1 a check or assertion failed (a scenario, a comparison), 2 an error.

mod cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// IntellWheels: a FIPA multi-agent platform for intelligent wheelchairs.
///
/// With no subcommand it runs the fleet demo on the embedded sample building.
#[derive(Parser)]
#[command(name = "intellwheels", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    demo: cmd::demo::Args,
}

#[derive(Subcommand)]
enum Command {
    /// Run the fleet demo on the embedded sample building (the default with no subcommand).
    Demo(cmd::demo::Args),
    /// FIPA-ACL messages: parse and print the string representation, send one over HTTP.
    #[command(subcommand)]
    Acl(cmd::acl::Command),
    /// FIPA-SL content: parse at a given SL level.
    #[command(subcommand)]
    Sl(cmd::sl::Command),
    /// Benchmarks measured in this run (the message bus per transport and layer set).
    #[command(subcommand)]
    Bench(cmd::bench::Command),
    /// Thesis chapter 4: repeatability of SURF, LN-SURF and LSAC-SURF under illumination changes.
    Repeatability(cmd::repeatability::Args),
    /// Detect features in one image (or match two) and draw them or print them as JSON.
    Features(cmd::features::Args),
    /// Thesis chapter 5: RGB-D visual odometry on a TUM-layout sequence.
    Vo(cmd::vo::Args),
    /// Run scripted scenarios (docs/scenario-format.md).
    #[command(subcommand)]
    Scenario(cmd::scenario::Command),
    /// The logger agent's message log: query it, replay it.
    #[command(subcommand)]
    Log(cmd::log::Command),
    /// Thesis experiments run in the simulator.
    #[command(subcommand)]
    Experiment(cmd::experiment::Command),
    /// Run one container process (a chair's agents or the services) over UDP or shared memory.
    Spawn(cmd::spawn::Args),
    /// Relay UDP datagrams between two loopback endpoints, injecting seeded faults.
    Impair(cmd::impair::Args),
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        None => cmd::demo::run(cli.demo),
        Some(Command::Demo(args)) => cmd::demo::run(args),
        Some(Command::Acl(c)) => cmd::acl::run(c),
        Some(Command::Sl(c)) => cmd::sl::run(c),
        Some(Command::Bench(c)) => cmd::bench::run(c),
        Some(Command::Repeatability(a)) => cmd::repeatability::run(a),
        Some(Command::Features(a)) => cmd::features::run(a),
        Some(Command::Vo(a)) => cmd::vo::run(a),
        Some(Command::Scenario(c)) => cmd::scenario::run(c),
        Some(Command::Experiment(c)) => cmd::experiment::run(c),
        Some(Command::Log(c)) => cmd::log::run(c),
        Some(Command::Spawn(a)) => cmd::spawn::run(a),
        Some(Command::Impair(a)) => cmd::impair::run(a),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            if cmd::is_broken_pipe(&err) {
                return ExitCode::SUCCESS;
            }
            eprintln!("error: {}", cmd::describe(&err));
            ExitCode::from(2)
        }
    }
}
