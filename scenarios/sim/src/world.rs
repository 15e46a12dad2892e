//! The world: static geometry from a map, doors, chairs, and the fixed-step simulation.

use iw_body::{SONAR_COUNT, SensorFrame, WheelSpeeds};
use nalgebra::{Isometry2, Point2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::chair::ChairSpec;
use crate::geom::{Grid, Owner, Segment, ray_segment, segment_hits_polygon, segments_intersect};
use crate::render::{RgbdFrame, TextureSet};
use crate::{Map, SimError};

/// Broad-phase cell size, m: about one chair length, so a chair touches few cells.
const CELL_M: f64 = 1.0;
/// Largest distance any footprint point travels in one collision substep, m: far below the
/// footprint's 0.65 m, so a solid segment cannot pass between two substeps.
const SUBSTEP_M: f64 = 0.02;
/// Longest drive tick, s (a 1.5 m/s chair moves 15 cm, well under one broad-phase cell).
const MAX_TICK_S: f64 = 0.1;
/// A contact ends once the chair is this far from everything, m; creeping along an obstacle
/// is one collision, not one per step.
const CONTACT_RELEASE_M: f64 = 0.05;
/// Extra space around the map bounds covered by the grid, m.
const MARGIN_M: f64 = 2.0;

/// Index of a chair in its [`World`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ChairId(pub usize);

/// How a chair's pose evolves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChairKind {
    /// Driven by the simulator from wheel speed references.
    Simulated,
    /// Placed from outside each period: the virtual body of a real chair (mixed reality).
    Tracked,
}

/// Per-chair state.
#[derive(Debug, Clone)]
struct Chair {
    spec: ChairSpec,
    kind: ChairKind,
    t_world_body: Isometry2<f64>,
    reference: WheelSpeeds,
    /// Wheel surface speeds at the nominal radius (what the motors turn), m/s.
    wheel_mps: (f64, f64),
    /// Effective/nominal radius per wheel (tyre compression).
    radius_scale: (f64, f64),
    ticks: (f64, f64),
    collisions: u64,
    in_contact: bool,
    restricted_entries: u64,
    inside_restricted: Option<usize>,
    distance_m: f64,
    sensors: SensorFrame,
    /// Sonar ray directions across the cone, sonar frame (computed once).
    sonar_rays: Vec<Vector2<f64>>,
    /// Laser beam directions, laser frame (computed once).
    laser_beams: Vec<Vector2<f64>>,
    wants_rgbd: bool,
    rgbd: Option<RgbdFrame>,
    rng: ChaCha8Rng,
}

/// A ray hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the ray, m.
    pub range_m: f64,
    /// What was hit.
    pub owner: Owner,
    /// Height of what was hit, m.
    pub height_m: f64,
    /// Texture index of the surface.
    pub texture: usize,
    /// Distance from the surface's start to the hit point along it, m (texture coordinate).
    pub along_m: f64,
}

/// A 2D world with chairs. Step it with [`World::step`]; everything is deterministic for a
/// given seed and sequence of calls.
#[derive(Debug, Clone)]
pub struct World {
    map: Map,
    statics: Vec<Segment>,
    static_grid: Grid,
    door_open: Vec<bool>,
    chairs: Vec<Chair>,
    chair_segments: Vec<Segment>,
    chair_grid: Grid,
    seed: u64,
    time_ns: u64,
    light: f64,
    textures: TextureSet,
}

impl World {
    /// A world from `map`; `seed` drives every random error (encoders, sensor noise).
    pub fn new(map: Map, seed: u64) -> Self {
        let (min, max) = map.bounds();
        let (min, max) = (
            min - Vector2::repeat(MARGIN_M),
            max + Vector2::repeat(MARGIN_M),
        );
        let mut statics = Vec::new();
        let mut texture = 0;
        for wall in &map.walls {
            for w in wall.windows(2) {
                statics.push(Segment {
                    a: w[0],
                    b: w[1],
                    owner: Owner::Wall,
                    height_m: map.wall_height_m,
                    texture,
                });
            }
            texture += 1;
        }
        for f in &map.furniture {
            let n = f.polygon.len();
            for i in 0..n {
                statics.push(Segment {
                    a: f.polygon[i],
                    b: f.polygon[(i + 1) % n],
                    owner: Owner::Furniture,
                    height_m: f.height_m,
                    texture,
                });
            }
            texture += 1;
        }
        for (i, d) in map.doors.iter().enumerate() {
            statics.push(Segment {
                a: d.a,
                b: d.b,
                owner: Owner::Door(i),
                height_m: map.wall_height_m,
                texture: usize::MAX,
            });
        }
        let mut static_grid = Grid::new(min, max, CELL_M);
        for (i, s) in statics.iter().enumerate() {
            static_grid.insert(i as u32, &s.a, &s.b);
        }
        let door_open = map.doors.iter().map(|d| d.open).collect();
        Self {
            chair_grid: static_grid.empty_like(),
            map,
            statics,
            static_grid,
            door_open,
            chairs: Vec::new(),
            chair_segments: Vec::new(),
            seed,
            time_ns: 0,
            light: 1.0,
            textures: TextureSet::procedural(seed),
        }
    }

    /// The map the world was built from.
    pub fn map(&self) -> &Map {
        &self.map
    }

    /// Simulated time since creation, ns.
    pub fn time_ns(&self) -> u64 {
        self.time_ns
    }

    /// Adds a chair at `t_world_body`. Its random errors come from the world seed and its index,
    /// so adding chairs in the same order reproduces the same run.
    pub fn add_chair(
        &mut self,
        spec: ChairSpec,
        t_world_body: Isometry2<f64>,
        kind: ChairKind,
    ) -> ChairId {
        let index = self.chairs.len();
        let mut rng = ChaCha8Rng::seed_from_u64(
            self.seed ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
        );
        let (lo, hi) = spec.encoder.compression;
        let mut compression = || {
            if hi > lo {
                rng.random_range(lo..hi)
            } else {
                lo
            }
        };
        let radius_scale = (1.0 - compression(), 1.0 - compression());
        let (sonar_rays, laser_beams) = (spec.sonar_ray_dirs(), spec.laser_beam_dirs());
        self.chairs.push(Chair {
            spec,
            kind,
            t_world_body,
            reference: WheelSpeeds::STOP,
            wheel_mps: (0.0, 0.0),
            radius_scale,
            ticks: (0.0, 0.0),
            collisions: 0,
            in_contact: false,
            restricted_entries: 0,
            inside_restricted: None,
            distance_m: 0.0,
            sensors: SensorFrame::empty(self.time_ns),
            sonar_rays,
            laser_beams,
            wants_rgbd: false,
            rgbd: None,
            rng,
        });
        self.rebuild_chair_grid();
        let id = ChairId(index);
        self.update_sensors(index);
        id
    }

    /// Number of chairs.
    pub fn chair_count(&self) -> usize {
        self.chairs.len()
    }

    fn chair(&self, id: ChairId) -> Result<&Chair, SimError> {
        self.chairs.get(id.0).ok_or(SimError::NoSuchChair {
            id: id.0,
            count: self.chairs.len(),
        })
    }

    fn chair_mut(&mut self, id: ChairId) -> Result<&mut Chair, SimError> {
        let count = self.chairs.len();
        self.chairs
            .get_mut(id.0)
            .ok_or(SimError::NoSuchChair { id: id.0, count })
    }

    /// The chair's model.
    pub fn spec(&self, id: ChairId) -> Result<&ChairSpec, SimError> {
        Ok(&self.chair(id)?.spec)
    }

    /// Sets the wheel speed references; the drive applies speed and acceleration limits.
    pub fn command(&mut self, id: ChairId, speeds: WheelSpeeds) -> Result<(), SimError> {
        let chair = self.chair_mut(id)?;
        let limit = chair.spec.max_wheel_mps;
        let clean = |v: f64| {
            if v.is_finite() {
                v.clamp(-limit, limit)
            } else {
                0.0
            }
        };
        chair.reference = WheelSpeeds {
            left_mps: clean(speeds.left_mps),
            right_mps: clean(speeds.right_mps),
        };
        Ok(())
    }

    /// The sensor frame computed at the end of the last step.
    pub fn sensors(&self, id: ChairId) -> Result<&SensorFrame, SimError> {
        Ok(&self.chair(id)?.sensors)
    }

    /// The true pose (ground truth).
    pub fn pose(&self, id: ChairId) -> Result<Isometry2<f64>, SimError> {
        Ok(self.chair(id)?.t_world_body)
    }

    /// True linear and angular speed of the chair (m/s, rad/s), nominal wheel radius.
    pub fn twist(&self, id: ChairId) -> Result<(f64, f64), SimError> {
        let c = self.chair(id)?;
        let (l, r) = c.wheel_mps;
        Ok(((l + r) / 2.0, (r - l) / c.spec.geometry.track_m))
    }

    /// Collision events so far (a contact that lasts several steps counts once).
    pub fn collisions(&self, id: ChairId) -> Result<u64, SimError> {
        Ok(self.chair(id)?.collisions)
    }

    /// Whether the chair touched something in the last step.
    pub fn in_contact(&self, id: ChairId) -> Result<bool, SimError> {
        Ok(self.chair(id)?.in_contact)
    }

    /// Whether the chair's footprint overlaps anything solid right now (never true after a
    /// simulated step; a placed chair may overlap).
    pub fn overlapping(&self, id: ChairId) -> Result<bool, SimError> {
        let pose = self.chair(id)?.t_world_body;
        Ok(self.footprint_collides(id.0, &pose))
    }

    /// Ground distance travelled, m.
    pub fn distance_m(&self, id: ChairId) -> Result<f64, SimError> {
        Ok(self.chair(id)?.distance_m)
    }

    /// How many times the chair entered a restricted area, and the one it is in now.
    pub fn restricted(&self, id: ChairId) -> Result<(u64, Option<&str>), SimError> {
        let c = self.chair(id)?;
        Ok((
            c.restricted_entries,
            c.inside_restricted
                .and_then(|i| self.map.restricted.get(i))
                .map(|a| a.name.as_str()),
        ))
    }

    /// Places a chair (mixed reality: the real chair's pose). Overlaps are counted as collisions
    /// but the pose is taken as given; sensors are recomputed at once; the displacement counts as
    /// distance travelled.
    pub fn place(&mut self, id: ChairId, t_world_body: Isometry2<f64>) -> Result<(), SimError> {
        let chair = self.chair_mut(id)?;
        chair.distance_m +=
            (t_world_body.translation.vector - chair.t_world_body.translation.vector).norm();
        chair.t_world_body = t_world_body;
        let hit = self.footprint_collides(id.0, &t_world_body);
        let near = hit || self.footprint_collides_within(id.0, &t_world_body, CONTACT_RELEASE_M);
        let chair = &mut self.chairs[id.0];
        if hit && !chair.in_contact {
            chair.collisions += 1;
        }
        chair.in_contact = hit || (chair.in_contact && near);
        self.rebuild_chair_grid();
        self.update_restricted(id.0);
        self.update_sensors(id.0);
        Ok(())
    }

    /// Opens or closes the door `door_id`. Closing fails while a chair stands in the doorway.
    pub fn set_door(&mut self, door_id: &str, open: bool) -> Result<(), SimError> {
        let index = self
            .map
            .doors
            .iter()
            .position(|d| d.id == door_id)
            .ok_or_else(|| SimError::NoSuchDoor {
                id: door_id.to_string(),
            })?;
        if !open {
            let door = &self.map.doors[index];
            if let Some(blocker) = self.chairs.iter().position(|c| {
                segment_hits_polygon(&door.a, &door.b, &c.spec.footprint_at(&c.t_world_body))
            }) {
                return Err(SimError::DoorBlocked {
                    id: door_id.to_string(),
                    chair: blocker,
                });
            }
        }
        self.door_open[index] = open;
        Ok(())
    }

    /// Whether door `door_id` is open.
    pub fn door_is_open(&self, door_id: &str) -> Result<bool, SimError> {
        let index = self
            .map
            .doors
            .iter()
            .position(|d| d.id == door_id)
            .ok_or_else(|| SimError::NoSuchDoor {
                id: door_id.to_string(),
            })?;
        Ok(self.door_open[index])
    }

    /// Global light level: 1 nominal, 0 dark, above 1 brighter (RGB only, depth unaffected).
    pub fn set_light(&mut self, level: f64) {
        self.light = if level.is_finite() {
            level.max(0.0)
        } else {
            1.0
        };
    }

    /// Wall and furniture textures for the RGB-D camera (default: procedural).
    pub fn set_textures(&mut self, textures: TextureSet) {
        self.textures = textures;
    }

    /// Asks for (or stops) RGB-D frames for this chair at every step; other chairs pay nothing.
    pub fn request_rgbd(&mut self, id: ChairId, wanted: bool) -> Result<(), SimError> {
        let chair = self.chair_mut(id)?;
        chair.wants_rgbd = wanted;
        if !wanted {
            chair.rgbd = None;
        }
        Ok(())
    }

    /// The RGB-D frame of the last step, if this chair asked for them.
    pub fn rgbd(&self, id: ChairId) -> Result<Option<&RgbdFrame>, SimError> {
        Ok(self.chair(id)?.rgbd.as_ref())
    }

    /// Renders an RGB-D frame for this chair now.
    pub fn render_rgbd(&self, id: ChairId) -> Result<RgbdFrame, SimError> {
        let c = self.chair(id)?;
        Ok(crate::render::render(
            self,
            id.0,
            &c.spec.camera,
            &c.t_world_body,
            &self.textures,
            self.light,
        ))
    }

    /// Advances the world by `dt_s` seconds: drives, collisions, then sensors.
    pub fn step(&mut self, dt_s: f64) {
        let dt_s = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        self.time_ns += (dt_s * 1e9).round() as u64;
        // long steps are driven in ticks of at most MAX_TICK_S: acceleration stays accurate and
        // no chair outruns the broad phase's one-cell margin
        let ticks = ((dt_s / MAX_TICK_S).ceil() as usize).clamp(1, 1_000_000);
        for _ in 0..ticks {
            for i in 0..self.chairs.len() {
                if self.chairs[i].kind == ChairKind::Simulated {
                    self.drive(i, dt_s / ticks as f64);
                    self.update_restricted(i);
                }
            }
            self.rebuild_chair_grid();
        }
        for i in 0..self.chairs.len() {
            self.update_sensors(i);
            if self.chairs[i].wants_rgbd {
                let frame = self.render_rgbd(ChairId(i)).ok();
                self.chairs[i].rgbd = frame;
            }
        }
    }

    fn drive(&mut self, i: usize, dt: f64) {
        let chair = &mut self.chairs[i];
        let spec = &chair.spec;
        let max_dv = spec.max_wheel_accel_mps2 * dt;
        let (l0, r0) = chair.wheel_mps;
        let l1 = l0 + (chair.reference.left_mps - l0).clamp(-max_dv, max_dv);
        let r1 = r0 + (chair.reference.right_mps - r0).clamp(-max_dv, max_dv);
        // encoders count the motor shaft: nominal travel
        let (enc_l, enc_r) = ((l0 + l1) / 2.0 * dt, (r0 + r1) / 2.0 * dt);
        // the ground sees the compressed tyre, less what slips
        let enc = spec.encoder;
        let mut slip = |accel: f64| {
            (iw_stats::standard_normal(&mut chair.rng).abs() * enc.slip_std
                + enc.slip_per_mps2 * accel.abs())
            .min(0.5)
        };
        let slip_l = slip((l1 - l0) / dt.max(1e-9));
        let slip_r = slip((r1 - r0) / dt.max(1e-9));
        let ground_l = enc_l * chair.radius_scale.0 * (1.0 - slip_l);
        let ground_r = enc_r * chair.radius_scale.1 * (1.0 - slip_r);
        let ds = (ground_l + ground_r) / 2.0;
        let dtheta = (ground_r - ground_l) / spec.geometry.track_m;
        let reach = spec.reach_m();
        let substeps =
            ((ds.abs().max(dtheta.abs() * reach) / SUBSTEP_M).ceil() as usize).clamp(1, 10_000);
        let start = chair.t_world_body;
        let mut pose = start;
        let mut hit = false;
        for k in 1..=substeps {
            let f = k as f64 / substeps as f64;
            let (s, th) = (ds * f, dtheta * f);
            let t_start_now =
                Isometry2::new(Vector2::new(s * (th / 2.0).cos(), s * (th / 2.0).sin()), th);
            let candidate = start * t_start_now;
            if self.footprint_collides(i, &candidate) {
                hit = true;
                break;
            }
            pose = candidate;
        }
        let chair = &mut self.chairs[i];
        chair.distance_m += (pose.translation.vector - start.translation.vector).norm();
        chair.t_world_body = pose;
        let per_tick = chair.spec.geometry.m_per_tick();
        if hit {
            // the motors stall against the obstacle: count what turned before the contact only
            let fraction = if ds.abs() > 1e-12 {
                ((pose.translation.vector - start.translation.vector).norm() / ds.abs()).min(1.0)
            } else {
                0.0
            };
            chair.ticks.0 += enc_l * fraction / per_tick;
            chair.ticks.1 += enc_r * fraction / per_tick;
            chair.wheel_mps = (0.0, 0.0);
            if !chair.in_contact {
                chair.collisions += 1;
                tracing::debug!(chair = i, collisions = chair.collisions, "collision");
            }
        } else {
            chair.ticks.0 += enc_l / per_tick;
            chair.ticks.1 += enc_r / per_tick;
            chair.wheel_mps = (l1, r1);
        }
        let was_in_contact = chair.in_contact;
        let released =
            !hit && was_in_contact && !self.footprint_collides_within(i, &pose, CONTACT_RELEASE_M);
        let chair = &mut self.chairs[i];
        chair.in_contact = hit || (was_in_contact && !released);
    }

    /// Whether chair `i`'s footprint at `pose` touches a wall, furniture, a closed door or
    /// another chair.
    fn footprint_collides(&self, i: usize, pose: &Isometry2<f64>) -> bool {
        self.footprint_collides_within(i, pose, 0.0)
    }

    /// [`Self::footprint_collides`] for the footprint grown by `margin_m` on every side.
    fn footprint_collides_within(&self, i: usize, pose: &Isometry2<f64>, margin_m: f64) -> bool {
        self.footprint_hit_within(i, pose, margin_m).is_some()
    }

    /// What chair `id`'s footprint overlaps at its pose now, if anything: a wall, furniture, a
    /// closed door or another chair (the first found). For refusing a start pose.
    pub fn obstruction(&self, id: ChairId) -> Result<Option<Owner>, SimError> {
        let pose = self.chair(id)?.t_world_body;
        Ok(self.footprint_hit_within(id.0, &pose, 0.0))
    }

    /// Names what an [`Owner`] is in this world, for messages (`the closed door `d1``).
    pub fn describe(&self, owner: Owner) -> String {
        match owner {
            Owner::Wall => "a wall".into(),
            Owner::Furniture => "furniture".into(),
            Owner::Door(d) => match self.map.doors.get(d) {
                Some(door) => format!("the closed door `{}`", door.id),
                None => format!("closed door {d}"),
            },
            Owner::Chair(j) => format!("chair {j}"),
        }
    }

    fn footprint_hit_within(
        &self,
        i: usize,
        pose: &Isometry2<f64>,
        margin_m: f64,
    ) -> Option<Owner> {
        let spec = &self.chairs[i].spec;
        let grown = ChairSpec {
            front_m: spec.front_m + margin_m,
            rear_m: spec.rear_m + margin_m,
            half_width_m: spec.half_width_m + margin_m,
            ..spec.clone()
        };
        let poly = grown.footprint_at(pose);
        let (min, max) = poly
            .iter()
            .fold((poly[0], poly[0]), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        let mut hit = None;
        self.static_grid.query_box(&min, &max, |s| {
            if hit.is_none()
                && let Some(seg) = self.statics.get(s as usize)
                && self.solid(seg)
                && segment_hits_polygon(&seg.a, &seg.b, &poly)
            {
                hit = Some(seg.owner);
            }
        });
        if hit.is_some() {
            return hit;
        }
        // other chairs at their current poses; the chair grid (built before this step's moves)
        // proposes candidates within one cell of margin, more than any chair moves per tick
        let margin = Vector2::repeat(CELL_M);
        let mut candidates: Vec<usize> = Vec::new();
        self.chair_grid
            .query_box(&(min - margin), &(max + margin), |s| {
                if let Some(Segment {
                    owner: Owner::Chair(j),
                    ..
                }) = self.chair_segments.get(s as usize)
                    && *j != i
                    && !candidates.contains(j)
                {
                    candidates.push(*j);
                }
            });
        candidates.sort_unstable();
        candidates.into_iter().find_map(|j| {
            let other = &self.chairs[j];
            let theirs = other.spec.footprint_at(&other.t_world_body);
            let overlaps = (0..4)
                .any(|k| segment_hits_polygon(&theirs[k], &theirs[(k + 1) % 4], &poly))
                || (0..4).any(|k| {
                    segments_intersect(&poly[k], &poly[(k + 1) % 4], &theirs[0], &theirs[2])
                });
            overlaps.then_some(Owner::Chair(j))
        })
    }

    fn solid(&self, seg: &Segment) -> bool {
        match seg.owner {
            Owner::Door(d) => !self.door_open.get(d).copied().unwrap_or(true),
            _ => true,
        }
    }

    fn rebuild_chair_grid(&mut self) {
        self.chair_grid.clear();
        self.chair_segments.clear();
        for (j, c) in self.chairs.iter().enumerate() {
            let poly = c.spec.footprint_at(&c.t_world_body);
            for k in 0..4 {
                let seg = Segment {
                    a: poly[k],
                    b: poly[(k + 1) % 4],
                    owner: Owner::Chair(j),
                    height_m: 1.2,
                    texture: usize::MAX - 1,
                };
                self.chair_grid
                    .insert(self.chair_segments.len() as u32, &seg.a, &seg.b);
                self.chair_segments.push(seg);
            }
        }
    }

    fn update_restricted(&mut self, i: usize) {
        let p = Point2::from(self.chairs[i].t_world_body.translation.vector);
        let now = self
            .map
            .restricted
            .iter()
            .position(|a| crate::geom::point_in_polygon(&p, &a.polygon));
        let chair = &mut self.chairs[i];
        if now.is_some() && now != chair.inside_restricted {
            chair.restricted_entries += 1;
        }
        chair.inside_restricted = now;
    }

    /// The nearest solid thing along a ray from `origin` (unit `dir`) within `max_m`, ignoring
    /// chair `ignore` (the one casting).
    pub fn cast(
        &self,
        origin: &Point2<f64>,
        dir: &Vector2<f64>,
        max_m: f64,
        ignore: Option<usize>,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        self.walk(origin, dir, max_m, ignore, |seg, t, u| {
            if best.is_none_or(|b| t < b.range_m) {
                best = Some(Hit {
                    range_m: t,
                    owner: seg.owner,
                    height_m: seg.height_m,
                    texture: seg.texture,
                    along_m: u * (seg.b - seg.a).norm(),
                });
            }
            best.map_or(f64::INFINITY, |b| b.range_m)
        });
        best
    }

    /// Every solid surface along a ray within `max_m`, nearest first (for the camera, which
    /// sees over low furniture).
    pub fn cast_all(
        &self,
        origin: &Point2<f64>,
        dir: &Vector2<f64>,
        max_m: f64,
        ignore: Option<usize>,
        out: &mut Vec<Hit>,
    ) {
        out.clear();
        self.walk(origin, dir, max_m, ignore, |seg, t, u| {
            // a segment spanning several cells is met once per cell: keep one hit per surface
            if !out.iter().any(|h| h.range_m == t && h.owner == seg.owner) {
                out.push(Hit {
                    range_m: t,
                    owner: seg.owner,
                    height_m: seg.height_m,
                    texture: seg.texture,
                    along_m: u * (seg.b - seg.a).norm(),
                });
            }
            f64::INFINITY
        });
        out.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    }

    /// One grid walk over static and chair segments: `on_hit(segment, t, u)` for every solid
    /// segment the ray meets within `max_m`, returning the range beyond which the walk may stop.
    fn walk(
        &self,
        origin: &Point2<f64>,
        dir: &Vector2<f64>,
        max_m: f64,
        ignore: Option<usize>,
        mut on_hit: impl FnMut(&Segment, f64, f64) -> f64,
    ) {
        let own = Owner::Chair(ignore.unwrap_or(usize::MAX));
        let mut stop_at = f64::INFINITY;
        self.static_grid.walk_ray(origin, dir, max_m, |cell| {
            let statics = self
                .static_grid
                .cell(cell)
                .iter()
                .filter_map(|&s| self.statics.get(s as usize))
                .filter(|seg| self.solid(seg));
            let chairs = self
                .chair_grid
                .cell(cell)
                .iter()
                .filter_map(|&s| self.chair_segments.get(s as usize))
                .filter(|seg| seg.owner != own);
            for seg in statics.chain(chairs) {
                if let Some((t, u)) = ray_segment(origin, dir, &seg.a, &seg.b)
                    && t <= max_m
                {
                    stop_at = on_hit(seg, t, u);
                }
            }
            stop_at
        });
    }

    fn update_sensors(&mut self, i: usize) {
        let chair = &self.chairs[i];
        let spec = &chair.spec;
        let pose = chair.t_world_body;
        let mut rng = chair.rng.clone();
        let mut sonar_m = [None; SONAR_COUNT];
        let model = spec.sonar;
        for (reading, mount) in sonar_m.iter_mut().zip(spec.sonars.iter()) {
            let t_world_sonar = pose * mount.t_body_sonar;
            let origin = Point2::from(t_world_sonar.translation.vector);
            let nearest = chair
                .sonar_rays
                .iter()
                .filter_map(|local| {
                    self.cast(
                        &origin,
                        &(t_world_sonar.rotation * local),
                        model.max_range_m,
                        Some(i),
                    )
                })
                .map(|hit| hit.range_m)
                .fold(f64::INFINITY, f64::min);
            let noise = iw_stats::standard_normal(&mut rng) * model.noise_std_m;
            *reading = nearest
                .is_finite()
                .then(|| (nearest + noise).clamp(model.min_range_m, model.max_range_m));
        }
        let laser_m = match &spec.laser {
            Some(laser) => {
                let t_world_laser = pose * laser.t_body_laser;
                let origin = Point2::from(t_world_laser.translation.vector);
                chair
                    .laser_beams
                    .iter()
                    .map(|local| {
                        match self.cast(
                            &origin,
                            &(t_world_laser.rotation * local),
                            laser.max_range_m,
                            Some(i),
                        ) {
                            Some(hit) => (hit.range_m
                                + iw_stats::standard_normal(&mut rng) * laser.noise_std_m)
                                .clamp(0.0, laser.max_range_m),
                            None => laser.max_range_m,
                        }
                    })
                    .collect()
            }
            None => Vec::new(),
        };
        let chair = &mut self.chairs[i];
        chair.rng = rng;
        chair.sensors = SensorFrame {
            time_ns: self.time_ns,
            left_ticks: chair.ticks.0.floor() as i64,
            right_ticks: chair.ticks.1.floor() as i64,
            sonar_m,
            laser_m,
            ranges_time_ns: self.time_ns,
            ticks_time_ns: self.time_ns,
        };
    }
}

/// Advances `world` by `dt_s` seconds (the simulator's one entry point for time).
pub fn step(world: &mut World, dt_s: f64) {
    world.step(dt_s);
}
