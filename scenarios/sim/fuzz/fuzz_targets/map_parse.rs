//! Any map text: the parser never panics; a map it accepts builds a world whose chair steps
//! and senses without panicking; its localization map (walls, closed doors, landmarks) is
//! built or refused with an error; and when it has landmarks, the chair's camera renders them
//! and the marker reader reads the frame without panicking. Seed: `seeds/map_parse/` (a room
//! with two markers facing the start), e.g. `cargo fuzz run map_parse seeds/map_parse`.
#![no_main]

use iw_localization::markers_in;
use iw_sim::vo::{SimCamera, vo_frame};
use iw_sim::{ChairKind, ChairSpec, Map, World};
use iw_vo::CameraSource;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    match Map::parse(text, "fuzz.map") {
        Ok(map) => {
            let start = map
                .starts
                .first()
                .map(|s| s.t_world_body)
                .unwrap_or_default();
            let landmarks = !map.landmarks.is_empty();
            if let Err(e) = iw_sim::localization::localization_map(&map) {
                assert!(e.to_string().starts_with("localization map:"));
            }
            let mut world = World::new(map, 0);
            let id = world.add_chair(ChairSpec::default(), start, ChairKind::Simulated);
            world.step(0.05);
            assert!(world.sensors(id).is_ok());
            if landmarks {
                let camera = SimCamera::new(iw_sim::shared(world), id).unwrap();
                let frame = vo_frame(&camera.render().unwrap());
                let _ = markers_in(&frame, camera.intrinsics(), &camera.t_base_camera());
            }
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.map:")),
    }
});
