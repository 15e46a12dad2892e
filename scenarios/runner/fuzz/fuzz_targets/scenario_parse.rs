//! Any scenario text: the parser never panics, a scenario it accepts is checked against the
//! sample building without panicking, and every error names the file.
#![no_main]

use std::path::Path;

use iw_scenario::Scenario;
use iw_sim::Map;
use libfuzzer_sys::fuzz_target;

const SAMPLE: &str = include_str!("../../../maps/sample-building.map");

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    let path = Path::new("fuzz.toml");
    match Scenario::parse(text, path) {
        Ok(scenario) => {
            let map = Map::parse(SAMPLE, "sample-building.map").expect("the sample building parses");
            if let Err(e) = scenario.validate(&map) {
                assert!(e.to_string().starts_with("fuzz.toml:"), "{e}");
            }
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.toml:"), "{e}"),
    }
});
