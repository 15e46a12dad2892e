//! Artificial landmarks (thesis 3.8) as printed and as seen. A marker is a square of
//! [`MARKER_CELLS`] x [`MARKER_CELLS`] cells: a black border ring around 4 x 4 data cells that
//! hold the id's 8 bits and then their complement, row by row from the top left (dark = 1), on a
//! white quiet zone one cell wide. The complement makes a misread id fail the check instead of
//! reading as another marker.
//!
//! The detector finds markers in an upright camera's image (the chair's camera does not roll,
//! markers hang upright): dark connected regions, sampled cell by cell between their top and
//! bottom edges in each cell column, so a marker seen at an angle (a trapezoid) still reads.

use iw_vo::{Intrinsics, RgbdFrame};
use nalgebra::{Isometry3, Point2, Point3};

/// Cells along a marker's side, border included.
pub const MARKER_CELLS: usize = 6;

/// Whether cell (`col`, `row`) of marker `id` is printed dark; `col` and `row` in
/// `0..MARKER_CELLS`, from the top left as one faces the marker. Outside that range: the white
/// quiet zone.
pub fn marker_cell_dark(id: u8, col: i32, row: i32) -> bool {
    let n = MARKER_CELLS as i32;
    if !(0..n).contains(&col) || !(0..n).contains(&row) {
        return false;
    }
    if col == 0 || row == 0 || col == n - 1 || row == n - 1 {
        return true;
    }
    let bit = ((row - 1) * 4 + (col - 1)) as u32;
    let code = u16::from(id) | (u16::from(!id) << 8);
    (code >> bit) & 1 == 1
}

/// A marker found in an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerSighting {
    /// The id it encodes.
    pub id: u8,
    /// Column and row of its centre, px.
    pub centre_px: (f64, f64),
    /// Median optical depth over its dark pixels, m.
    pub depth_m: f64,
    /// Its width in the image, px.
    pub width_px: usize,
}

impl MarkerSighting {
    /// The marker's centre in the base frame (x forward, y left; m), for a camera with
    /// `intrinsics` mounted at `t_base_camera` (optical frame: x right, y down, z forward).
    pub fn base_point(
        &self,
        intrinsics: &Intrinsics,
        t_base_camera: &Isometry3<f64>,
    ) -> Point2<f64> {
        let z = self.depth_m;
        let (u, v) = self.centre_px;
        let optical = Point3::new(
            (u - intrinsics.cx) / intrinsics.fx * z,
            (v - intrinsics.cy) / intrinsics.fy * z,
            z,
        );
        let base = t_base_camera * optical;
        Point2::new(base.x, base.y)
    }
}

/// The markers in an RGB-D `frame` from a camera with `intrinsics` mounted at `t_base_camera`:
/// each one's id and its centre in the base frame, m.
pub fn markers_in(
    frame: &RgbdFrame,
    intrinsics: &Intrinsics,
    t_base_camera: &Isometry3<f64>,
) -> Vec<(u8, Point2<f64>)> {
    let (w, h) = (frame.rgb.width() as usize, frame.rgb.height() as usize);
    let grey: Vec<u8> = frame
        .rgb
        .pixels()
        .map(|p| ((u32::from(p[0]) * 77 + u32::from(p[1]) * 150 + u32::from(p[2]) * 29) >> 8) as u8)
        .collect();
    let depth = |x: usize, y: usize| {
        let raw = frame.depth.get_pixel_checked(x as u32, y as u32)?[0];
        (raw > 0).then(|| f64::from(raw) / intrinsics.depth_units_per_m)
    };
    detect_markers(w, h, &grey, depth)
        .into_iter()
        .map(|s| (s.id, s.base_point(intrinsics, t_base_camera)))
        .collect()
}

/// Smallest marker side the detector reads, px (two pixels per cell).
const MIN_SIDE_PX: usize = 2 * MARKER_CELLS;

/// Finds the markers in a grey image (`width` x `height`, row major) with optical depth in m per
/// pixel (`None` where invalid). Markers without a valid depth are not reported.
pub fn detect_markers(
    width: usize,
    height: usize,
    grey: &[u8],
    depth_m: impl Fn(usize, usize) -> Option<f64>,
) -> Vec<MarkerSighting> {
    if width == 0 || height == 0 || grey.len() != width * height {
        return Vec::new();
    }
    // Printed black renders at 0 whatever the light; textures and shadows rarely go this dark,
    // and what does must still pass the border, quiet zone and complement checks.
    const DARK: u8 = 40;
    let dark = |x: usize, y: usize| grey[y * width + x] < DARK;
    let mut label = vec![false; width * height];
    let mut found = Vec::new();
    let mut stack = Vec::new();
    let mut pixels = Vec::new();
    for start in 0..width * height {
        if label[start] || grey[start] >= DARK {
            continue;
        }
        label[start] = true;
        stack.push(start);
        pixels.clear();
        while let Some(i) = stack.pop() {
            pixels.push(i);
            let (x, y) = (i % width, i / width);
            let mut visit = |j: usize| {
                if !label[j] && grey[j] < DARK {
                    label[j] = true;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < width {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - width);
            }
            if y + 1 < height {
                visit(i + width);
            }
        }
        if let Some(s) = read_region(width, height, &pixels, &dark, &depth_m) {
            found.push(s);
        }
    }
    found
}

/// Reads one dark region as a marker, if it is one.
fn read_region(
    width: usize,
    height: usize,
    pixels: &[usize],
    dark: &impl Fn(usize, usize) -> bool,
    depth_m: &impl Fn(usize, usize) -> Option<f64>,
) -> Option<MarkerSighting> {
    let (mut x0, mut x1) = (usize::MAX, 0);
    for &i in pixels {
        x0 = x0.min(i % width);
        x1 = x1.max(i % width);
    }
    let w = x1 - x0 + 1;
    // touching the image's edge: part of it may be cut off
    if w < MIN_SIDE_PX || x0 == 0 || x1 + 1 >= width {
        return None;
    }
    // top and bottom of the region in each of its columns
    let mut top = vec![usize::MAX; w];
    let mut bottom = vec![0usize; w];
    for &i in pixels {
        let (x, y) = (i % width - x0, i / width);
        top[x] = top[x].min(y);
        bottom[x] = bottom[x].max(y);
    }
    let n = MARKER_CELLS;
    let mut code: u16 = 0;
    let mut centre = (0.0, 0.0);
    for col in 0..n {
        let x = x0 + ((col as f64 + 0.5) / n as f64 * w as f64) as usize;
        let (t, b) = (top[x - x0], bottom[x - x0]);
        if t == usize::MAX || b < t || b - t + 1 < MIN_SIDE_PX || t == 0 || b + 1 >= height {
            return None;
        }
        let h = (b - t + 1) as f64;
        // the quiet zone above and below must be light
        if dark(x, t - 1) || dark(x, b + 1) {
            return None;
        }
        for row in 0..n {
            let y = t + ((row as f64 + 0.5) / n as f64 * h) as usize;
            let is_dark = dark(x, y);
            if col == 0 || row == 0 || col == n - 1 || row == n - 1 {
                if !is_dark {
                    return None;
                }
            } else if is_dark {
                code |= 1 << ((row - 1) * 4 + (col - 1));
            }
        }
        if col == n / 2 {
            centre = (x0 as f64 + w as f64 / 2.0, (t + b) as f64 / 2.0);
        }
    }
    let (id, check) = (code as u8, (code >> 8) as u8);
    if id != !check {
        return None;
    }
    let mut depths: Vec<f64> = pixels
        .iter()
        .filter_map(|&i| depth_m(i % width, i / width))
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if depths.len() * 2 < pixels.len() {
        return None;
    }
    let mid = depths.len() / 2;
    let (_, depth, _) = depths.select_nth_unstable_by(mid, f64::total_cmp);
    Some(MarkerSighting {
        id,
        centre_px: centre,
        depth_m: *depth,
        width_px: w,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Paints marker `id` with `cell` px cells at (`x`, `y`) (its quiet zone's top left) on grey.
    fn paint(img: &mut [u8], width: usize, id: u8, x: usize, y: usize, cell: usize) {
        let n = MARKER_CELLS as i32;
        for row in -1..=n {
            for col in -1..=n {
                let v = if marker_cell_dark(id, col, row) {
                    0
                } else {
                    230
                };
                for dy in 0..cell {
                    for dx in 0..cell {
                        let px = x + (col + 1) as usize * cell + dx;
                        let py = y + (row + 1) as usize * cell + dy;
                        img[py * width + px] = v;
                    }
                }
            }
        }
    }

    #[test]
    fn every_id_reads_back_and_a_flipped_cell_does_not() {
        let (w, h) = (120, 60);
        for id in 0..=255u8 {
            let mut img = vec![128u8; w * h];
            paint(&mut img, w, id, 10, 5, 4);
            let found = detect_markers(w, h, &img, |_, _| Some(2.0));
            assert_eq!(found.len(), 1, "id {id}");
            assert_eq!(found[0].id, id);
            assert_eq!(found[0].width_px, 24);
            assert!((found[0].centre_px.0 - 26.0).abs() <= 0.5, "{:?}", found[0]);
            assert_eq!(found[0].depth_m, 2.0);
        }
        // one data cell flipped: the complement no longer matches
        let mut img = vec![128u8; w * h];
        paint(&mut img, w, 77, 10, 5, 4);
        let (cx, cy) = (10 + 2 * 4 + 1, 5 + 2 * 4 + 1);
        let v = img[cy * w + cx];
        for dy in 0..4 {
            for dx in 0..4 {
                img[(cy - 1 + dy) * w + cx - 1 + dx] = if v == 0 { 230 } else { 0 };
            }
        }
        assert!(detect_markers(w, h, &img, |_, _| Some(2.0)).is_empty());
    }

    #[test]
    fn garbage_dark_blobs_and_bad_input_find_nothing() {
        let (w, h) = (64, 48);
        let mut img = vec![200u8; w * h];
        for y in 10..30 {
            for x in 10..30 {
                img[y * w + x] = 0;
            }
        }
        assert!(detect_markers(w, h, &img, |_, _| Some(1.0)).is_empty());
        assert!(detect_markers(w, h, &img[1..], |_, _| Some(1.0)).is_empty());
        assert!(detect_markers(0, 0, &[], |_, _| Some(1.0)).is_empty());
        // a marker without depth is not reported
        let mut img = vec![128u8; w * h];
        paint(&mut img, w, 3, 5, 5, 3);
        assert!(detect_markers(w, h, &img, |_, _| None).is_empty());
        assert_eq!(detect_markers(w, h, &img, |_, _| Some(1.5)).len(), 1);
    }
}
