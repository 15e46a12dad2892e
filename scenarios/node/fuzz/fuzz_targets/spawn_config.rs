//! Any spawn configuration text: the TOML loader never panics, every error names the file, a
//! configuration it accepts validates (or is refused naming a key) for every role without
//! panicking, and re-serialises to itself.
#![no_main]

use iw_node::{Role, SpawnConfig};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    let config = match SpawnConfig::parse(text, "fuzz.toml") {
        Ok(config) => config,
        Err(e) => {
            assert!(e.to_string().contains("fuzz.toml"), "{e}");
            return;
        }
    };
    let roles = [Role::Services, Role::World, Role::Chair { name: "c1".into() }];
    for role in &roles {
        if config.validate(role).is_ok() {
            if let Role::Chair { .. } = role {
                assert!(config.body.start.iter().all(|v| v.is_finite()));
            }
        }
    }
    let again = toml::to_string(&config).expect("a parsed configuration serialises");
    let reparsed = SpawnConfig::parse(&again, "again.toml").expect("it parses back");
    // Compared as text: the loader keeps a `nan` (only a chair's validation refuses it), and a
    // NaN is never equal to itself as a number.
    assert_eq!(
        toml::to_string(&reparsed).expect("it serialises again"),
        again
    );
});
