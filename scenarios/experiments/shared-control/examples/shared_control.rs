//! The experiment without the CLI: `cargo run --example shared_control -- DRIVERS LAPS OUT`
//! (defaults 8, 1, shared-control-out) on the embedded office circuit.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let drivers = args.next().map_or(Ok(8), |a| a.parse())?;
    let laps = args.next().map_or(Ok(1), |a| a.parse())?;
    let out = std::path::PathBuf::from(args.next().unwrap_or_else(|| "shared-control-out".into()));
    let map = iw_shared_control_experiment::office_circuit()?;
    let config = iw_shared_control_experiment::Config {
        drivers,
        laps,
        ..Default::default()
    };
    let report = iw_shared_control_experiment::run(&map, &config, |t| {
        eprintln!(
            "driver {} {}: {} collisions",
            t.driver + 1,
            t.mode.key(),
            t.collisions
        )
    })?;
    let summary = iw_shared_control_experiment::write_outputs(&report, &map, &out)?;
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(())
}
