//! Maps: the text format of `docs/map-format.md` and the PNG occupancy import.

use std::path::Path;

use nalgebra::{Isometry2, Point2, Vector2};

use crate::SimError;

/// Default wall height, m.
pub const DEFAULT_WALL_HEIGHT_M: f64 = 2.5;
/// Default furniture height, m.
pub const DEFAULT_FURNITURE_HEIGHT_M: f64 = 0.75;
/// Largest landmark id (the marker encodes 8 bits).
pub const MAX_MARKER_ID: u32 = 255;
/// Default landmark side, m.
pub const DEFAULT_MARKER_SIZE_M: f64 = 0.3;
/// Default height of a landmark's centre, m (the camera's lens is at 0.9 m).
pub const DEFAULT_MARKER_HEIGHT_M: f64 = 1.0;
/// Coordinates beyond this magnitude are rejected (a map is a building, not a continent).
const MAX_COORD_M: f64 = 10_000.0;

/// A solid obstacle other than a wall: a table, a cupboard, a pillar.
#[derive(Debug, Clone, PartialEq)]
pub struct Furniture {
    /// Name, if the map gave one.
    pub name: Option<String>,
    /// Outline, world frame, m (closed implicitly).
    pub polygon: Vec<Point2<f64>>,
    /// Height, m.
    pub height_m: f64,
}

/// A door: a segment that blocks while closed. Its id is what a door agent names.
#[derive(Debug, Clone, PartialEq)]
pub struct Door {
    /// Identifier, unique in the map.
    pub id: String,
    /// Hinge end, m.
    pub a: Point2<f64>,
    /// Free end, m.
    pub b: Point2<f64>,
    /// Initial state.
    pub open: bool,
}

/// A named polygon: a restricted area, where chairs are counted when they enter.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    /// Name.
    pub name: String,
    /// Outline, m.
    pub polygon: Vec<Point2<f64>>,
}

/// A named narrow passage (a corridor, a doorway) that chairs cross one direction at a time:
/// the strip of `width_m` around the axis from `a` to `b`. The map only describes it; the
/// watcher agent keeps the traffic, and crossing from `a`'s end towards `b`'s is `forward`.
#[derive(Debug, Clone, PartialEq)]
pub struct NarrowPassage {
    /// Name, as chairs ask the watcher for it.
    pub name: String,
    /// One end of the axis, m.
    pub a: Point2<f64>,
    /// The other end, m.
    pub b: Point2<f64>,
    /// Width of the strip, m.
    pub width_m: f64,
}

/// A named point: a place or landmark (dining hall, bedroom, lift).
#[derive(Debug, Clone, PartialEq)]
pub struct Place {
    /// Name.
    pub name: String,
    /// Position, m.
    pub position: Point2<f64>,
}

/// An artificial landmark (thesis 3.8): a square marker on a wall or post with a known pose,
/// which the RGB-D camera sees and the perception agent recognises by its id.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    /// Identifier encoded on the marker (0..=255).
    pub id: u32,
    /// Centre of the marker's face, m.
    pub position: Point2<f64>,
    /// Direction the face looks (its outward normal), rad.
    pub facing_rad: f64,
    /// Side of the square, m.
    pub size_m: f64,
    /// Height of the marker's centre above the floor, m.
    pub height_m: f64,
}

/// A named start pose for a chair.
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    /// Name.
    pub name: String,
    /// Body pose in the world.
    pub t_world_body: Isometry2<f64>,
}

/// A named waypoint polyline, e.g. the lap of a circuit.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// Name.
    pub name: String,
    /// Waypoints, m.
    pub points: Vec<Point2<f64>>,
    /// Whether the last waypoint leads back to the first (a lap).
    pub closed: bool,
}

/// Largest map file [`Map::load`] reads, bytes: a building of thousands of walls is well below.
pub const MAX_MAP_BYTES: u64 = 16 << 20;

/// A 2D world description. Build it with [`Map::parse`], [`Map::load`] or
/// [`Map::from_occupancy_png`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Map {
    /// Human-readable name.
    pub name: String,
    /// Height of walls, m.
    pub wall_height_m: f64,
    /// Wall polylines, m.
    pub walls: Vec<Vec<Point2<f64>>>,
    /// Furniture.
    pub furniture: Vec<Furniture>,
    /// Doors.
    pub doors: Vec<Door>,
    /// Restricted areas.
    pub restricted: Vec<Area>,
    /// Narrow passages kept one-way at a time.
    pub passages: Vec<NarrowPassage>,
    /// Named places and landmarks.
    pub places: Vec<Place>,
    /// Named start poses.
    pub starts: Vec<Start>,
    /// Named routes.
    pub routes: Vec<Route>,
    /// Landmarks (markers with known poses).
    pub landmarks: Vec<Marker>,
}

impl Map {
    /// Reads and parses a map file; errors name the file and line.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SimError> {
        let path = path.as_ref();
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            return Self::from_occupancy_png(path, 0.05);
        }
        let text = crate::file::read_text(path, MAX_MAP_BYTES).map_err(|source| SimError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses map text; `file` is only used to name the source in errors (`file:line: reason`).
    pub fn parse(text: &str, file: &str) -> Result<Self, SimError> {
        let mut map = Map {
            name: String::new(),
            wall_height_m: DEFAULT_WALL_HEIGHT_M,
            ..Map::default()
        };
        // The line of each route, to name it when a later check refuses it.
        let mut route_lines = Vec::new();
        for (index, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let err = |reason: String| SimError::Parse {
                file: file.to_string(),
                line: index + 1,
                reason,
            };
            parse_line(&mut map, line).map_err(err)?;
            route_lines.resize(map.routes.len(), index + 1);
        }
        let ids: Vec<String> = map.landmarks.iter().map(|l| l.id.to_string()).collect();
        check_unique(ids.iter(), "landmark").map_err(|reason| SimError::Parse {
            file: file.to_string(),
            line: 0,
            reason,
        })?;
        check_unique(map.doors.iter().map(|d| &d.id), "door").map_err(|reason| {
            SimError::Parse {
                file: file.to_string(),
                line: 0,
                reason,
            }
        })?;
        if map.walls.is_empty() && map.furniture.is_empty() && map.doors.is_empty() {
            return Err(SimError::Parse {
                file: file.to_string(),
                line: 0,
                reason: "map has no walls, furniture or doors".into(),
            });
        }
        for (route, line) in map.routes.iter().zip(route_lines) {
            map.check_route(route).map_err(|reason| SimError::Parse {
                file: file.to_string(),
                line,
                reason,
            })?;
        }
        Ok(map)
    }

    /// Refuses a route with a leg through a wall or furniture: a chair could never follow it,
    /// and an experiment on it would measure nothing but the obstacle. Doors are not checked
    /// (a route may pass a door that is opened for it).
    fn check_route(&self, route: &Route) -> Result<(), String> {
        let n = route.points.len();
        let legs = if route.closed { n } else { n.saturating_sub(1) };
        for k in 0..legs {
            let (a, b) = (&route.points[k], &route.points[(k + 1) % n]);
            let leg = || {
                format!(
                    "route `{}`: leg {} from ({}, {}) to ({}, {})",
                    route.name,
                    k + 1,
                    a.x,
                    a.y,
                    b.x,
                    b.y
                )
            };
            for wall in &self.walls {
                if let Some(w) = wall
                    .windows(2)
                    .find(|w| crate::geom::segments_intersect(a, b, &w[0], &w[1]))
                {
                    return Err(format!(
                        "{} crosses the wall segment ({}, {})-({}, {})",
                        leg(),
                        w[0].x,
                        w[0].y,
                        w[1].x,
                        w[1].y
                    ));
                }
            }
            if let Some(f) = self
                .furniture
                .iter()
                .find(|f| crate::geom::segment_hits_polygon(a, b, &f.polygon))
            {
                return Err(format!(
                    "{} goes through furniture{}",
                    leg(),
                    f.name
                        .as_deref()
                        .map(|n| format!(" `{n}`"))
                        .unwrap_or_default()
                ));
            }
        }
        Ok(())
    }

    /// Imports an occupancy image: dark pixels (luma < 128) are solid, `resolution_m` metres per
    /// pixel, image bottom-left at the world origin. Solid regions become wall outlines (edges
    /// between solid and free pixels, merged into straight runs).
    pub fn from_occupancy_png(path: &Path, resolution_m: f64) -> Result<Self, SimError> {
        let bytes = crate::file::read_file(path, MAX_MAP_BYTES).map_err(|source| SimError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .map_err(|e| SimError::ImageFile {
                path: path.display().to_string(),
                source: Box::new(e),
            })?
            .to_luma8();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let solid = |x: isize, y: isize| -> bool {
            x >= 0
                && y >= 0
                && (x as usize) < w
                && (y as usize) < h
                && img.get_pixel(x as u32, y as u32).0[0] < 128
        };
        let to_world = |x: usize, row: usize| {
            Point2::new(x as f64 * resolution_m, (h - row) as f64 * resolution_m)
        };
        let mut walls = Vec::new();
        // horizontal edges at the top of pixel row `row` (between row-1 and row)
        edge_runs(
            h + 1,
            w,
            |row, x| solid(x as isize, row as isize) != solid(x as isize, row as isize - 1),
            |row, x0, x1| {
                walls.push(vec![to_world(x0, row), to_world(x1, row)]);
            },
        );
        // vertical edges at the left of pixel column `col`
        edge_runs(
            w + 1,
            h,
            |col, row| solid(col as isize, row as isize) != solid(col as isize - 1, row as isize),
            |col, r0, r1| {
                walls.push(vec![to_world(col, r0), to_world(col, r1)]);
            },
        );
        if walls.is_empty() {
            return Err(SimError::Image {
                path: path.display().to_string(),
                reason: "no dark (occupied) pixels".into(),
            });
        }
        Ok(Map {
            name: path.display().to_string(),
            wall_height_m: DEFAULT_WALL_HEIGHT_M,
            walls,
            ..Map::default()
        })
    }

    /// The start pose called `name`.
    pub fn start(&self, name: &str) -> Option<Isometry2<f64>> {
        self.starts
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.t_world_body)
    }

    /// The place called `name`.
    pub fn place(&self, name: &str) -> Option<Point2<f64>> {
        self.places
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.position)
    }

    /// The route called `name`.
    pub fn route(&self, name: &str) -> Option<&Route> {
        self.routes.iter().find(|r| r.name == name)
    }

    /// Every solid segment that stays put: walls and furniture outlines (doors open and close,
    /// so they are left out). What a localizer matches range readings against.
    pub fn solid_segments(&self) -> Vec<(Point2<f64>, Point2<f64>)> {
        let walls = self
            .walls
            .iter()
            .flat_map(|w| w.windows(2).map(|p| (p[0], p[1])));
        let furniture = self.furniture.iter().flat_map(|f| {
            let n = f.polygon.len();
            (0..n).map(move |i| (f.polygon[i], f.polygon[(i + 1) % n]))
        });
        walls.chain(furniture).collect()
    }

    /// The first closed route, if any (a lap to drive round).
    pub fn closed_route(&self) -> Option<&Route> {
        self.routes.iter().find(|r| r.closed)
    }

    /// Axis-aligned bounds of everything in the map, m.
    pub fn bounds(&self) -> (Point2<f64>, Point2<f64>) {
        let points = self
            .walls
            .iter()
            .flatten()
            .chain(self.furniture.iter().flat_map(|f| &f.polygon))
            .chain(self.doors.iter().flat_map(|d| [&d.a, &d.b]))
            .chain(self.restricted.iter().flat_map(|a| &a.polygon))
            .chain(self.places.iter().map(|p| &p.position))
            .chain(self.routes.iter().flat_map(|r| &r.points));
        let mut min = Point2::new(f64::INFINITY, f64::INFINITY);
        let mut max = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in points {
            min = min.inf(p);
            max = max.sup(p);
        }
        if !min.x.is_finite() {
            return (Point2::origin(), Point2::new(1.0, 1.0));
        }
        (min, max)
    }
}

/// For each `line` in `0..lines`, finds the maximal runs `start..end` of `0..len` where
/// `is_edge(line, i)` holds and calls `emit(line, start, end)`.
fn edge_runs(
    lines: usize,
    len: usize,
    is_edge: impl Fn(usize, usize) -> bool,
    mut emit: impl FnMut(usize, usize, usize),
) {
    for line in 0..lines {
        let mut run: Option<usize> = None;
        for i in 0..=len {
            match (i < len && is_edge(line, i), run) {
                (true, None) => run = Some(i),
                (false, Some(start)) => {
                    emit(line, start, i);
                    run = None;
                }
                _ => {}
            }
        }
    }
}

fn check_unique<'a>(names: impl Iterator<Item = &'a String>, what: &str) -> Result<(), String> {
    let mut seen = std::collections::HashSet::new();
    for n in names {
        if !seen.insert(n) {
            return Err(format!("{what} id `{n}` is defined twice"));
        }
    }
    Ok(())
}

/// Positional tokens, then `key=value` options.
struct Args<'a> {
    positional: Vec<&'a str>,
    options: Vec<(&'a str, &'a str)>,
}

impl<'a> Args<'a> {
    fn split(tokens: &[&'a str]) -> Self {
        let mut positional = Vec::new();
        let mut options = Vec::new();
        for t in tokens {
            match t.split_once('=') {
                Some((k, v)) => options.push((k, v)),
                None => positional.push(*t),
            }
        }
        Self {
            positional,
            options,
        }
    }

    fn option(&self, key: &str) -> Option<&'a str> {
        self.options
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, v)| *v)
    }

    fn check_options(&self, allowed: &[&str]) -> Result<(), String> {
        match self.options.iter().find(|(k, _)| !allowed.contains(k)) {
            Some((k, _)) => Err(format!(
                "unknown option `{k}=` (allowed: {})",
                if allowed.is_empty() {
                    "none".to_string()
                } else {
                    allowed.join(", ")
                }
            )),
            None => Ok(()),
        }
    }
}

fn number(token: &str, what: &str) -> Result<f64, String> {
    let v: f64 = token
        .parse()
        .map_err(|_| format!("{what}: `{token}` is not a number"))?;
    if !v.is_finite() || v.abs() > MAX_COORD_M {
        return Err(format!(
            "{what}: `{token}` is not finite or beyond +-{MAX_COORD_M} m"
        ));
    }
    Ok(v)
}

fn positive(token: &str, what: &str) -> Result<f64, String> {
    let v = number(token, what)?;
    if v <= 0.0 {
        return Err(format!("{what}: `{token}` must be positive"));
    }
    Ok(v)
}

fn points(tokens: &[&str], min: usize, what: &str) -> Result<Vec<Point2<f64>>, String> {
    if !tokens.len().is_multiple_of(2) {
        return Err(format!(
            "{what}: coordinates come in x y pairs, got {} numbers",
            tokens.len()
        ));
    }
    if tokens.len() / 2 < min {
        return Err(format!(
            "{what}: needs at least {min} points, got {}",
            tokens.len() / 2
        ));
    }
    let pts = tokens
        .chunks(2)
        .map(|c| Ok(Point2::new(number(c[0], what)?, number(c[1], what)?)))
        .collect::<Result<Vec<_>, String>>()?;
    if pts.windows(2).any(|w| (w[1] - w[0]).norm() < 1e-9) {
        return Err(format!("{what}: two consecutive points coincide"));
    }
    Ok(pts)
}

fn name(tokens: &[&str], what: &str) -> Result<String, String> {
    tokens
        .first()
        .map(|s| s.to_string())
        .ok_or_else(|| format!("{what}: missing name"))
}

fn parse_line(map: &mut Map, line: &str) -> Result<(), String> {
    let tokens: Vec<&str> = line.split_whitespace().collect();
    let (keyword, rest) = tokens.split_first().ok_or("empty line")?;
    let args = Args::split(rest);
    let pos = &args.positional;
    match *keyword {
        "name" => {
            map.name = rest.join(" ");
        }
        "wall_height" => {
            args.check_options(&[])?;
            map.wall_height_m = positive(
                pos.first().ok_or("wall_height: missing value")?,
                "wall_height",
            )?;
        }
        "wall" => {
            args.check_options(&[])?;
            let (closed, coords) = match pos.first() {
                Some(&"closed") => (true, &pos[1..]),
                _ => (false, &pos[..]),
            };
            let mut pts = points(coords, if closed { 3 } else { 2 }, "wall")?;
            if closed {
                pts.push(pts[0]);
            }
            map.walls.push(pts);
        }
        "box" => {
            args.check_options(&["angle", "height", "name"])?;
            if pos.len() != 4 {
                return Err(format!(
                    "box: expected `box cx cy width depth [angle=deg] [height=m] [name=..]`, got {} numbers",
                    pos.len()
                ));
            }
            let (cx, cy) = (number(pos[0], "box cx")?, number(pos[1], "box cy")?);
            let (w, d) = (
                positive(pos[2], "box width")?,
                positive(pos[3], "box depth")?,
            );
            let angle = args
                .option("angle")
                .map(|a| number(a, "box angle"))
                .transpose()?
                .unwrap_or(0.0)
                .to_radians();
            let iso = Isometry2::new(Vector2::new(cx, cy), angle);
            let polygon = [(-w, -d), (w, -d), (w, d), (-w, d)]
                .iter()
                .map(|(x, y)| iso * Point2::new(x / 2.0, y / 2.0))
                .collect();
            map.furniture.push(Furniture {
                name: args.option("name").map(str::to_string),
                polygon,
                height_m: height(&args)?,
            });
        }
        "polygon" => {
            args.check_options(&["height", "name"])?;
            let polygon = points(pos, 3, "polygon")?;
            map.furniture.push(Furniture {
                name: args.option("name").map(str::to_string),
                polygon,
                height_m: height(&args)?,
            });
        }
        "door" => {
            args.check_options(&[])?;
            let id = name(pos, "door")?;
            let state = match pos.len() {
                5 => "closed",
                6 => pos[5],
                n => {
                    return Err(format!(
                        "door: expected `door ID x1 y1 x2 y2 [open|closed]`, got {} tokens",
                        n
                    ));
                }
            };
            let open = match state {
                "open" => true,
                "closed" => false,
                other => {
                    return Err(format!(
                        "door {id}: state `{other}` is neither `open` nor `closed`"
                    ));
                }
            };
            let pts = points(&pos[1..5], 2, "door")?;
            map.doors.push(Door {
                id,
                a: pts[0],
                b: pts[1],
                open,
            });
        }
        "restricted" => {
            args.check_options(&[])?;
            let area = name(pos, "restricted")?;
            map.restricted.push(Area {
                name: area,
                polygon: points(&pos[1..], 3, "restricted")?,
            });
        }
        "passage" => {
            args.check_options(&["width"])?;
            let passage = name(pos, "passage")?;
            if pos.len() != 5 {
                return Err(format!(
                    "passage: expected `passage NAME x1 y1 x2 y2 width=W`, got {} tokens",
                    pos.len()
                ));
            }
            let width_m = positive(
                args.option("width").ok_or("passage: missing `width=`")?,
                "passage width",
            )?;
            let axis = points(&pos[1..5], 2, "passage")?;
            map.passages.push(NarrowPassage {
                name: passage,
                a: axis[0],
                b: axis[1],
                width_m,
            });
        }
        "landmark" => {
            args.check_options(&["size", "height"])?;
            if pos.len() != 4 {
                return Err(format!(
                    "landmark: expected `landmark ID x y facing_deg [size=m] [height=m]`, got {} tokens",
                    pos.len()
                ));
            }
            let id: u32 = pos[0]
                .parse()
                .ok()
                .filter(|id| *id <= MAX_MARKER_ID)
                .ok_or_else(|| {
                    format!(
                        "landmark: id `{}` is not a whole number in 0..={MAX_MARKER_ID}",
                        pos[0]
                    )
                })?;
            let size_m = args
                .option("size")
                .map(|v| positive(v, "landmark size"))
                .transpose()?
                .unwrap_or(DEFAULT_MARKER_SIZE_M);
            let height_m = args
                .option("height")
                .map(|v| positive(v, "landmark height"))
                .transpose()?
                .unwrap_or(DEFAULT_MARKER_HEIGHT_M);
            map.landmarks.push(Marker {
                id,
                position: Point2::new(number(pos[1], "landmark x")?, number(pos[2], "landmark y")?),
                facing_rad: number(pos[3], "landmark facing")?.to_radians(),
                size_m,
                height_m,
            });
        }
        "place" => {
            args.check_options(&[])?;
            let place = name(pos, "place")?;
            if pos.len() != 3 {
                return Err(format!(
                    "place: expected `place NAME x y`, got {} tokens",
                    pos.len()
                ));
            }
            map.places.push(Place {
                name: place,
                position: Point2::new(number(pos[1], "place x")?, number(pos[2], "place y")?),
            });
        }
        "start" => {
            args.check_options(&[])?;
            let start = name(pos, "start")?;
            if pos.len() != 4 {
                return Err(format!(
                    "start: expected `start NAME x y heading_deg`, got {} tokens",
                    pos.len()
                ));
            }
            let (x, y) = (number(pos[1], "start x")?, number(pos[2], "start y")?);
            let heading = number(pos[3], "start heading")?.to_radians();
            map.starts.push(Start {
                name: start,
                t_world_body: Isometry2::new(Vector2::new(x, y), heading),
            });
        }
        "route" => {
            args.check_options(&[])?;
            let route = name(pos, "route")?;
            let (closed, coords) = match pos.get(1) {
                Some(&"closed") => (true, &pos[2..]),
                _ => (false, &pos[1..]),
            };
            map.routes.push(Route {
                name: route,
                points: points(coords, 2, "route")?,
                closed,
            });
        }
        other => {
            return Err(format!(
                "unknown keyword `{other}` (expected name, wall_height, wall, box, polygon, door, restricted, passage, place, start, route)"
            ));
        }
    }
    Ok(())
}

fn height(args: &Args) -> Result<f64, String> {
    args.option("height")
        .map(|h| positive(h, "height"))
        .transpose()
        .map(|h| h.unwrap_or(DEFAULT_FURNITURE_HEIGHT_M))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const SAMPLE: &str = "name test room\nwall closed 0 0 10 0 10 8 0 8 # outer\nbox 5 4 1 2 angle=90 name=table\npolygon 1 1 2 1 1.5 2 height=1.8\ndoor d1 3 0 4 0 open\nrestricted stairs 8 6 10 6 10 8 8 8\npassage hall 1 4 9 4 width=2\nplace kitchen 2 6\nstart s0 1 1 90\nroute lap closed 0.5 0.5 9 0.5 9 7 0.5 7\n";

    #[test]
    fn sample_parses() {
        let m = Map::parse(SAMPLE, "sample.map").unwrap();
        assert_eq!(m.name, "test room");
        assert_eq!(m.walls[0].len(), 5);
        assert_eq!(m.furniture.len(), 2);
        assert_eq!(m.furniture[1].height_m, 1.8);
        assert!(m.doors[0].open);
        assert_eq!(
            (m.passages[0].name.as_str(), m.passages[0].width_m),
            ("hall", 2.0)
        );
        assert_eq!(m.place("kitchen"), Some(Point2::new(2.0, 6.0)));
        assert!(
            (m.start("s0").unwrap().rotation.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-12
        );
        assert!(m.route("lap").unwrap().closed);
        // rotated box: width 1 along y now
        let ys: Vec<f64> = m.furniture[0].polygon.iter().map(|p| p.y).collect();
        assert!(ys.iter().all(|y| (y - 4.0).abs() <= 0.5 + 1e-9));
    }

    #[test]
    fn landmarks_parse_with_defaults_and_ids_are_checked() {
        let map = Map::parse(
            "wall 0 0 5 0\nlandmark 7 2 0.01 90\nlandmark 8 4 0.01 90 size=0.5 height=1.2\n",
            "m",
        )
        .unwrap();
        assert_eq!(map.landmarks.len(), 2);
        assert_eq!(map.landmarks[0].id, 7);
        assert!((map.landmarks[0].facing_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(map.landmarks[0].size_m, DEFAULT_MARKER_SIZE_M);
        assert_eq!(map.landmarks[1].height_m, 1.2);
        for (text, why) in [
            ("wall 0 0 5 0\nlandmark 256 1 1 0\n", "0..=255"),
            ("wall 0 0 5 0\nlandmark -1 1 1 0\n", "whole number"),
            ("wall 0 0 5 0\nlandmark 1 1 1\n", "expected `landmark"),
            (
                "wall 0 0 5 0\nlandmark 1 1 1 0 colour=red\n",
                "unknown option",
            ),
            (
                "wall 0 0 5 0\nlandmark 1 1 1 0\nlandmark 1 2 2 0\n",
                "defined twice",
            ),
        ] {
            let err = Map::parse(text, "m").unwrap_err().to_string();
            assert!(err.contains(why), "{text:?}: {err}");
        }
        let segments = map.solid_segments();
        assert_eq!(segments.len(), 1);
    }

    #[test]
    fn errors_point_at_file_line_and_reason() {
        let text = "wall 0 0 1 0\n\nbox 1 2 3\n";
        let e = Map::parse(text, "bad.map").unwrap_err().to_string();
        assert!(e.starts_with("bad.map:3: box: expected"), "{e}");
        let e = Map::parse("wall 0 0 x 1", "w.map").unwrap_err().to_string();
        assert_eq!(e, "w.map:1: wall: `x` is not a number");
        let e = Map::parse("wall 0 0 1 1\ndoor a 0 0 1 0 ajar", "d.map")
            .unwrap_err()
            .to_string();
        assert!(e.contains("d.map:2:") && e.contains("ajar"), "{e}");
        let e = Map::parse("passage p 0 0 1 0", "p.map")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "p.map:1: passage: missing `width=`");
        let e = Map::parse("sofa 1 2", "k.map").unwrap_err().to_string();
        assert!(e.contains("unknown keyword `sofa`"), "{e}");
    }

    proptest! {
        #[test]
        fn no_panic_on_any_text(text in ".{0,400}") {
            let _ = Map::parse(&text, "fuzz.map");
        }

        #[test]
        fn no_panic_on_keyword_soup(lines in proptest::collection::vec(
            (prop::sample::select(vec!["wall", "box", "polygon", "door", "restricted", "passage", "place", "start", "route", "wall_height", "name", "landmark"]),
             proptest::collection::vec(prop::sample::select(vec!["0", "1", "-2.5", "closed", "open", "x", "angle=30", "height=-1", "width=1.5", "nan", "1e9", "d1", "255", "256", "size=0.3", "size=0", "height=1.2"]), 0..9)), 0..8)) {
            let text: String = lines.iter().map(|(k, args)| format!("{k} {}\n", args.join(" "))).collect();
            let _ = Map::parse(&text, "soup.map");
        }
    }
}
