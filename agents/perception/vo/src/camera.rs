//! Pinhole camera with Brown-Conrady distortion and a depth scale: pixels <-> camera-frame points.
//!
//! Camera frame: x right, y down, z forward (optical axis), metres.

use nalgebra::{Point2, Point3};

use crate::VoError;

/// Brown-Conrady lens distortion (OpenCV order k1, k2, p1, p2, k3), applied in normalised coordinates.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Distortion {
    /// Radial r^2 coefficient.
    pub k1: f64,
    /// Radial r^4 coefficient.
    pub k2: f64,
    /// Tangential coefficient 1.
    pub p1: f64,
    /// Tangential coefficient 2.
    pub p2: f64,
    /// Radial r^6 coefficient.
    pub k3: f64,
}

impl Distortion {
    /// Maps undistorted normalised coordinates to distorted ones.
    pub fn distort(&self, p: Point2<f64>) -> Point2<f64> {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        Point2::new(
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Inverts [`Distortion::distort`] by fixed-point iteration (as OpenCV's `undistortPoints`):
    /// converges to well below a hundredth of a pixel inside the image of a Kinect-class lens.
    pub fn undistort(&self, distorted: Point2<f64>) -> Point2<f64> {
        let (mut x, mut y) = (distorted.x, distorted.y);
        for _ in 0..8 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            x = (distorted.x - dx) / radial;
            y = (distorted.y - dy) / radial;
        }
        Point2::new(x, y)
    }
}

/// Intrinsics of a registered RGB-D camera: the depth image shares the colour image's pixel grid.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, px.
    pub fx: f64,
    /// Focal length along y, px.
    pub fy: f64,
    /// Principal point column, px.
    pub cx: f64,
    /// Principal point row, px.
    pub cy: f64,
    /// Lens distortion of the colour image; `None` when images are already rectified.
    pub distortion: Option<Distortion>,
    /// Raw depth units per metre (TUM: 5000).
    pub depth_units_per_m: f64,
    /// Depth readings below this are rejected, m (Kinect: about 0.4).
    pub min_depth_m: f64,
    /// Depth readings beyond this are rejected, m (Kinect noise grows with depth squared).
    pub max_depth_m: f64,
}

impl Intrinsics {
    /// TUM freiburg1 Kinect (fx 517.3, fy 516.5, cx 318.6, cy 255.3), with its published distortion.
    pub fn tum_freiburg1() -> Self {
        Self::tum(
            517.3,
            516.5,
            318.6,
            255.3,
            Some([0.2624, -0.9531, -0.0054, 0.0026, 1.1633]),
        )
    }

    /// TUM freiburg2 Kinect (fx 520.9, fy 521.0, cx 325.1, cy 249.7), with its published distortion.
    pub fn tum_freiburg2() -> Self {
        Self::tum(
            520.9,
            521.0,
            325.1,
            249.7,
            Some([0.2312, -0.7849, -0.0033, -0.0001, 0.9172]),
        )
    }

    /// TUM freiburg3 Asus Xtion (fx 535.4, fy 539.2, cx 320.1, cy 247.6); its images are rectified.
    pub fn tum_freiburg3() -> Self {
        Self::tum(535.4, 539.2, 320.1, 247.6, None)
    }

    fn tum(fx: f64, fy: f64, cx: f64, cy: f64, distortion: Option<[f64; 5]>) -> Self {
        Intrinsics {
            fx,
            fy,
            cx,
            cy,
            distortion: distortion.map(|[k1, k2, p1, p2, k3]| Distortion { k1, k2, p1, p2, k3 }),
            depth_units_per_m: 5000.0,
            min_depth_m: 0.3,
            max_depth_m: 6.0,
        }
    }

    /// The camera by name: `freiburg1|fr1`, `freiburg2|fr2`, `freiburg3|fr3`.
    pub fn by_name(name: &str) -> Result<Self, VoError> {
        match name.to_ascii_lowercase().as_str() {
            "freiburg1" | "fr1" => Ok(Self::tum_freiburg1()),
            "freiburg2" | "fr2" => Ok(Self::tum_freiburg2()),
            "freiburg3" | "fr3" => Ok(Self::tum_freiburg3()),
            _ => Err(VoError::UnknownCamera {
                name: name.to_string(),
            }),
        }
    }

    /// The camera a TUM folder name implies (`rgbd_dataset_freiburg2_xyz` -> freiburg2), if any.
    pub fn from_sequence_name(name: &str) -> Option<Self> {
        let lower = name.to_ascii_lowercase();
        ["1", "2", "3"].iter().find_map(|n| {
            (lower.contains(&format!("freiburg{n}")) || lower.contains(&format!("fr{n}_")))
                .then(|| Self::by_name(&format!("fr{n}")).ok())
                .flatten()
        })
    }

    /// Undistorted normalised image coordinates (x/z, y/z) of a pixel.
    pub fn normalise(&self, pixel: Point2<f64>) -> Point2<f64> {
        let distorted = Point2::new((pixel.x - self.cx) / self.fx, (pixel.y - self.cy) / self.fy);
        match &self.distortion {
            Some(d) => d.undistort(distorted),
            None => distorted,
        }
    }

    /// Camera-frame point of a pixel with a metric depth (thesis eq. 5.1-5.3, plus undistortion).
    pub fn back_project(&self, pixel: Point2<f64>, depth_m: f64) -> Point3<f64> {
        let n = self.normalise(pixel);
        Point3::new(n.x * depth_m, n.y * depth_m, depth_m)
    }

    /// Metric depth of a raw reading, or `None` when missing (0) or outside the valid range.
    pub fn depth_m(&self, raw: u16) -> Option<f64> {
        let z = f64::from(raw) / self.depth_units_per_m;
        (raw != 0 && z >= self.min_depth_m && z <= self.max_depth_m).then_some(z)
    }

    /// Pixel of a camera-frame point in front of the camera (with distortion), else `None`.
    pub fn project(&self, p_camera: &Point3<f64>) -> Option<Point2<f64>> {
        if p_camera.z <= 1e-6 {
            return None;
        }
        let n = Point2::new(p_camera.x / p_camera.z, p_camera.y / p_camera.z);
        let d = match &self.distortion {
            Some(dist) => dist.distort(n),
            None => n,
        };
        Some(Point2::new(
            d.x * self.fx + self.cx,
            d.y * self.fy + self.cy,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_back_project_with_distortion() {
        let k = Intrinsics::tum_freiburg1();
        for (u, v, z) in [(10.0, 12.0, 0.8), (320.0, 240.0, 2.0), (630.0, 470.0, 4.5)] {
            let p = k.back_project(Point2::new(u, v), z);
            assert!((p.z - z).abs() < 1e-12);
            let back = k.project(&p).expect("in front");
            assert!(
                (back.x - u).abs() < 1e-3 && (back.y - v).abs() < 1e-3,
                "{u},{v} -> {back}"
            );
        }
    }

    #[test]
    fn depth_rejects_missing_and_out_of_range() {
        let k = Intrinsics::tum_freiburg1();
        assert_eq!(k.depth_m(0), None);
        assert_eq!(k.depth_m(100), None, "2 cm is closer than the sensor sees");
        assert_eq!(k.depth_m(5000), Some(1.0));
        assert_eq!(k.depth_m(u16::MAX), None, "13 m is beyond range");
    }

    #[test]
    fn camera_from_folder_name() {
        let fr2 = Intrinsics::from_sequence_name("rgbd_dataset_freiburg2_xyz").expect("fr2");
        assert_eq!(fr2.fx, 520.9);
        assert_eq!(
            Intrinsics::from_sequence_name("my_fr3_walk").map(|k| k.fx),
            Some(535.4)
        );
        assert!(Intrinsics::from_sequence_name("office").is_none());
        assert!(matches!(
            Intrinsics::by_name("kinect"),
            Err(VoError::UnknownCamera { .. })
        ));
    }
}
