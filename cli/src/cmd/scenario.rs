//! `intellwheels scenario run FILE`: plays a scenario file and prints its pass/fail report (exit
//! 0: every assertion holds, 1: one fails, 2: the file or run is in error). In process by
//! default (simulated time); with `--processes` as the deployment: world, services and each chair
//! as `intellwheels spawn` processes (this binary) over loopback UDP, in real time.

use std::path::PathBuf;
use std::process::ExitCode;

/// Scenario commands.
#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Run one scenario file and print the report.
    Run {
        /// The scenario TOML file (format: docs/scenario-format.md).
        file: PathBuf,
        /// Print the report as JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Play it as real processes (world, services, one per chair) over loopback UDP, in
        /// real time, instead of in this process in simulated time.
        #[arg(long)]
        processes: bool,
    },
}

/// Runs the command.
pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    let Command::Run {
        file,
        json,
        processes,
    } = command;
    let scenario = match iw_scenario::Scenario::load(&file) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    let bar = indicatif::ProgressBar::new(0);
    let progress = |step, steps| {
        bar.set_length(steps);
        bar.set_position(step);
    };
    let report = if processes {
        let exe = std::env::current_exe()?;
        iw_scenario::run_processes(&scenario, &iw_scenario::ProcessOptions::new(exe), progress)
    } else {
        iw_scenario::run_with_progress(&scenario, progress)
    };
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
