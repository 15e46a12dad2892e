//! Renders what a chair's RGB-D camera sees at the office circuit's lap start, under three light
//! levels, as TUM-style PNGs: `cargo run -p iw-sim --example render -- OUT_DIR [TEXTURE_DIR]`.

use std::path::PathBuf;

use iw_sim::{ChairKind, ChairSpec, Map, TextureSet, World};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().ok_or("usage: render OUT_DIR [TEXTURE_DIR]")?);
    std::fs::create_dir_all(&out)?;
    let map =
        Map::load(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../maps/office-circuit.map"))?;
    let start = map.start("lap").ok_or("map has no `lap` start")?;
    let mut world = World::new(map, 1);
    if let Some(dir) = args.next() {
        world.set_textures(TextureSet::load_dir(&PathBuf::from(dir))?);
    }
    let id = world.add_chair(ChairSpec::default(), start, ChairKind::Simulated);
    for (name, light) in [("dim", 0.4), ("normal", 1.0), ("bright", 1.6)] {
        world.set_light(light);
        let frame = world.render_rgbd(id)?;
        frame.save(
            &out.join(format!("rgb-{name}.png")),
            &out.join(format!("depth-{name}.png")),
        )?;
        let t = frame.t_world_camera.translation.vector;
        println!("{name}: camera at ({:.3}, {:.3}, {:.3}) m", t.x, t.y, t.z);
    }
    Ok(())
}
