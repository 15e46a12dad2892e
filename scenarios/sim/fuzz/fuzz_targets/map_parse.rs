//! Any map text: the parser never panics; a map it accepts builds a world whose chair steps
//! and senses without panicking.
#![no_main]

use iw_sim::{ChairKind, ChairSpec, Map, World};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    match Map::parse(text, "fuzz.map") {
        Ok(map) => {
            let start = map.starts.first().map(|s| s.t_world_body).unwrap_or_default();
            let mut world = World::new(map, 0);
            let id = world.add_chair(ChairSpec::default(), start, ChairKind::Simulated);
            world.step(0.05);
            assert!(world.sensors(id).is_ok());
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.map:")),
    }
});
