//! The RGB-D camera: one ray per image column through the 2D world, walls and furniture
//! extruded to their heights, textured with photographs, lit by a global light level.
//! Depth is 16-bit in TUM units (5000 per metre, 0 = invalid), with the exact camera pose.

use std::path::Path;

use image::{ImageBuffer, Luma, Rgb, RgbImage};
use nalgebra::{
    Isometry2, Isometry3, Matrix3, Point2, Rotation3, Translation3, UnitQuaternion, Vector2,
    Vector3,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::SimError;
use crate::chair::CameraModel;
use crate::geom::Owner;
use crate::world::{Hit, World};
use markers::Painted;

/// TUM RGB-D depth scale: raw value per metre.
pub const TUM_DEPTH_PER_M: f64 = 5000.0;
/// Width of wall covered by one texture tile, m.
const TILE_WIDTH_M: f64 = 2.0;
/// Height covered by one texture tile, m.
const TILE_HEIGHT_M: f64 = 2.5;
/// Farthest surface the camera draws (beyond the depth range it still shows colour), m.
const DRAW_RANGE_M: f64 = 30.0;

/// One RGB-D frame with its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFrame {
    /// Simulated time, ns.
    pub time_ns: u64,
    /// Colour image.
    pub rgb: RgbImage,
    /// Depth along the optical axis, 1/5000 m per unit (TUM), 0 where invalid.
    pub depth: ImageBuffer<Luma<u16>, Vec<u16>>,
    /// Camera pose in the world, optical frame (x right, y down, z forward), world z up.
    pub t_world_camera: Isometry3<f64>,
    /// Pinhole intrinsics `(fx, fy, cx, cy)`, px.
    pub intrinsics: (f64, f64, f64, f64),
}

impl RgbdFrame {
    /// Writes the colour image and the 16-bit depth image as PNGs (the TUM RGB-D layout).
    pub fn save(&self, rgb_path: &Path, depth_path: &Path) -> Result<(), SimError> {
        let err = |path: &Path, e| SimError::ImageFile {
            path: path.display().to_string(),
            source: Box::new(e),
        };
        self.rgb.save(rgb_path).map_err(|e| err(rgb_path, e))?;
        self.depth.save(depth_path).map_err(|e| err(depth_path, e))
    }
}

/// Textures for walls and furniture, picked by surface index.
#[derive(Debug, Clone, PartialEq)]
pub struct TextureSet {
    textures: Vec<RgbImage>,
}

impl TextureSet {
    /// Loads every `.png`/`.jpg` in `dir` (sorted by name; grey images become RGB).
    pub fn load_dir(dir: &Path) -> Result<Self, SimError> {
        let io = |source| SimError::Io {
            path: dir.display().to_string(),
            source,
        };
        let mut paths: Vec<_> = std::fs::read_dir(dir)
            .map_err(io)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg")
                })
            })
            .collect();
        paths.sort();
        let textures = paths
            .iter()
            .map(|p| {
                image::open(p)
                    .map(|i| i.to_rgb8())
                    .map_err(|e| SimError::ImageFile {
                        path: p.display().to_string(),
                        source: Box::new(e),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Self::from_images(textures).ok_or_else(|| SimError::Image {
            path: dir.display().to_string(),
            reason: "no png/jpg images in the folder".into(),
        })
    }

    /// Textures from images (`None` if the list is empty or an image has no pixels).
    pub fn from_images(textures: Vec<RgbImage>) -> Option<Self> {
        (!textures.is_empty() && textures.iter().all(|t| t.width() > 0 && t.height() > 0))
            .then_some(Self { textures })
    }

    /// Procedural textures (brick-like courses with seeded noise), used when no photographs
    /// are given.
    pub fn procedural(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let textures = (0..4)
            .map(|k| {
                let base: [f64; 3] = [
                    rng.random_range(90.0..200.0),
                    rng.random_range(70.0..180.0),
                    rng.random_range(60.0..170.0),
                ];
                let noise: Vec<f64> = (0..256 * 256)
                    .map(|_| rng.random_range(-25.0..25.0))
                    .collect();
                RgbImage::from_fn(256, 256, |x, y| {
                    let course = y / 32;
                    let offset = if course % 2 == 0 { 0 } else { 32 };
                    let mortar = y % 32 < 3 || (x + offset + 16 * k) % 64 < 3;
                    let n = noise[(y * 256 + x) as usize];
                    let shade = if mortar { 0.55 } else { 1.0 };
                    Rgb(base.map(|c| ((c + n) * shade).clamp(0.0, 255.0) as u8))
                })
            })
            .collect();
        Self { textures }
    }

    fn sample(&self, index: usize, along_m: f64, height_m: f64) -> [f64; 3] {
        let tex = &self.textures[index % self.textures.len()];
        let (w, h) = (tex.width() as f64, tex.height() as f64);
        let x = ((along_m / TILE_WIDTH_M).rem_euclid(1.0) * w) as u32;
        let y = ((1.0 - (height_m / TILE_HEIGHT_M).rem_euclid(1.0)) * h) as u32;
        let p = tex
            .get_pixel(x.min(tex.width() - 1), y.min(tex.height() - 1))
            .0;
        p.map(f64::from)
    }
}

/// The camera pose in the optical convention for a camera at 2D pose `t_world_cam2` and
/// `height_m` above the floor, looking level.
pub fn optical_pose(t_world_cam2: &Isometry2<f64>, height_m: f64) -> Isometry3<f64> {
    let h = t_world_cam2.rotation.angle();
    let x_right = Vector3::new(h.sin(), -h.cos(), 0.0);
    let y_down = Vector3::new(0.0, 0.0, -1.0);
    let z_forward = Vector3::new(h.cos(), h.sin(), 0.0);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::from_columns(&[x_right, y_down, z_forward]),
    ));
    let t = t_world_cam2.translation.vector;
    Isometry3::from_parts(Translation3::new(t.x, t.y, height_m), rotation)
}

/// Renders chair `ignore`'s camera at body pose `t_world_body`.
pub(crate) fn render(
    world: &World,
    ignore: usize,
    camera: &CameraModel,
    t_world_body: &Isometry2<f64>,
    textures: &TextureSet,
    light: f64,
) -> RgbdFrame {
    let (w, h) = (camera.width_px.max(1), camera.height_px.max(1));
    let cam = CameraModel {
        width_px: w,
        height_px: h,
        ..*camera
    };
    let (fx, fy, cx, cy) = cam.intrinsics();
    let t_world_cam2 = t_world_body * cam.t_body_camera;
    let origin = Point2::from(t_world_cam2.translation.vector);
    let heading = t_world_cam2.rotation.angle();
    let ceiling_m = world.map().wall_height_m;
    let hc = cam.height_m;
    let mut rgb = RgbImage::new(w, h);
    let mut depth = ImageBuffer::<Luma<u16>, Vec<u16>>::new(w, h);
    let mut hits: Vec<Hit> = Vec::new();
    let markers = Painted::facing(world, &origin);
    for u in 0..w {
        let offset = ((cx - u as f64) / fx).atan();
        let (cos_off, dir) = (
            offset.cos(),
            Vector2::new((heading + offset).cos(), (heading + offset).sin()),
        );
        world.cast_all(&origin, &dir, DRAW_RANGE_M, Some(ignore), &mut hits);
        for v in 0..h {
            let slope = (cy - v as f64) / fy; // height gained per metre of optical depth
            // distance along the 2D ray to the floor (looking down) or ceiling (looking up)
            let plane_range = if slope < -1e-9 {
                hc / -slope / cos_off
            } else if slope > 1e-9 {
                (ceiling_m - hc) / slope / cos_off
            } else {
                f64::INFINITY
            };
            let surface = hits.iter().find(|hit| {
                let z = hc + hit.range_m * cos_off * slope;
                hit.range_m < plane_range && (0.0..=hit.height_m).contains(&z)
            });
            let (range, colour) = match surface {
                Some(hit) => {
                    let z = hc + hit.range_m * cos_off * slope;
                    let colour = match hit.owner {
                        Owner::Door(_) => [150.0, 100.0, 60.0],
                        Owner::Chair(_) => [40.0, 45.0, 60.0],
                        Owner::Wall | Owner::Furniture => {
                            let at = origin + dir * hit.range_m;
                            markers
                                .iter()
                                .find_map(|m| m.colour(&at, z))
                                .unwrap_or_else(|| textures.sample(hit.texture, hit.along_m, z))
                        }
                    };
                    (hit.range_m, colour)
                }
                None if plane_range.is_finite() => {
                    let p = origin + dir * plane_range;
                    let colour = if slope < 0.0 {
                        if ((p.x / 0.5).floor() + (p.y / 0.5).floor()).rem_euclid(2.0) < 1.0 {
                            [170.0, 160.0, 140.0]
                        } else {
                            [120.0, 110.0, 95.0]
                        }
                    } else {
                        [225.0, 225.0, 220.0]
                    };
                    (plane_range, colour)
                }
                None => (f64::INFINITY, [0.0; 3]),
            };
            let shade = light / (1.0 + 0.06 * range.min(DRAW_RANGE_M));
            rgb.put_pixel(
                u,
                v,
                Rgb(colour.map(|c| (c * shade).clamp(0.0, 255.0) as u8)),
            );
            let z_m = range * cos_off;
            let raw = if z_m >= cam.min_depth_m && z_m <= cam.max_depth_m {
                (z_m * TUM_DEPTH_PER_M).round() as u16
            } else {
                0
            };
            depth.put_pixel(u, v, Luma([raw]));
        }
    }
    RgbdFrame {
        time_ns: world.time_ns(),
        rgb,
        depth,
        t_world_camera: optical_pose(&t_world_cam2, hc),
        intrinsics: (fx, fy, cx, cy),
    }
}

/// Landmarks as the camera paints them: each marker's cells on the surface it hangs on, seen
/// from the front only. The printed pattern is iw-localization's (whose detector reads it), so
/// markers are drawn with the `localization` feature only.
#[cfg(feature = "localization")]
mod markers {
    use nalgebra::{Point2, Vector2};

    use crate::world::World;

    pub(super) struct Painted {
        marker: crate::Marker,
        /// Outward normal of the face.
        normal: Vector2<f64>,
        /// Along the face, to the right as one faces it.
        right: Vector2<f64>,
    }

    impl Painted {
        /// The map's markers whose face looks towards `origin`.
        pub(super) fn facing(world: &World, origin: &Point2<f64>) -> Vec<Painted> {
            world
                .map()
                .landmarks
                .iter()
                .map(|m| {
                    let normal = Vector2::new(m.facing_rad.cos(), m.facing_rad.sin());
                    Painted {
                        marker: *m,
                        normal,
                        right: Vector2::new(-normal.y, normal.x),
                    }
                })
                .filter(|p| (origin - p.marker.position).dot(&p.normal) > 0.0)
                .collect()
        }

        /// The colour at surface point `at`, `z_m` above the floor, if it falls on the marker
        /// or its quiet zone.
        pub(super) fn colour(&self, at: &Point2<f64>, z_m: f64) -> Option<[f64; 3]> {
            let d = at - self.marker.position;
            if d.dot(&self.normal).abs() > 0.05 {
                return None;
            }
            let n = iw_localization::MARKER_CELLS as f64;
            let cell = self.marker.size_m / n;
            let half = self.marker.size_m / 2.0;
            let col = ((d.dot(&self.right) + half) / cell).floor();
            let row = ((self.marker.height_m + half - z_m) / cell).floor();
            if !(-1.0..=n).contains(&col) || !(-1.0..=n).contains(&row) {
                return None;
            }
            let id = u8::try_from(self.marker.id).unwrap_or(u8::MAX);
            let dark = iw_localization::marker_cell_dark(id, col as i32, row as i32);
            Some(if dark { [0.0; 3] } else { [245.0; 3] })
        }
    }
}

#[cfg(not(feature = "localization"))]
mod markers {
    use nalgebra::Point2;

    use crate::world::World;

    pub(super) struct Painted;

    impl Painted {
        pub(super) fn facing(_: &World, _: &Point2<f64>) -> Vec<Painted> {
            Vec::new()
        }

        pub(super) fn colour(&self, _: &Point2<f64>, _: f64) -> Option<[f64; 3]> {
            None
        }
    }
}
