//! `intellwheels scenario run FILE`: plays a scenario file in simulated time and prints its
//! pass/fail report (exit 0: every assertion holds, 1: one fails, 2: the file or run is in error).

use std::path::PathBuf;
use std::process::ExitCode;

/// Scenario commands.
#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Run one scenario file faster than real time and print the report.
    Run {
        /// The scenario TOML file (format: docs/scenario-format.md).
        file: PathBuf,
        /// Print the report as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

/// Runs the command.
pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    let Command::Run { file, json } = command;
    let scenario = match iw_scenario::Scenario::load(&file) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    let bar = indicatif::ProgressBar::new(0);
    let report = iw_scenario::run_with_progress(&scenario, |step, steps| {
        bar.set_length(steps);
        bar.set_position(step);
    });
    bar.finish_and_clear();
    let report = match report {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.render());
    }
    Ok(if report.passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
