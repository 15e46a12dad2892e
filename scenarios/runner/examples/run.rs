//! Runs one scenario file and prints its report (the CLI's `scenario run` without the CLI).
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: run FILE")?;
    let report = iw_scenario::run(&iw_scenario::Scenario::load(path)?)?;
    print!("{}", report.render());
    Ok(())
}
