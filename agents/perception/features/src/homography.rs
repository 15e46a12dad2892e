//! Plane-to-plane mappings for repeatability on real sequences (Mikolajczyk-style `H1toKp` files):
//! parsing with clear errors, mapping points both ways, the local scale a keypoint size changes by,
//! and the pixel convention the matrix was estimated in.

use nalgebra::{Matrix3, Vector3};

/// Largest homography file accepted, bytes (nine numbers need a few hundred).
pub const MAX_TEXT_BYTES: usize = 64 * 1024;

/// Smallest ratio of the smallest to the largest singular value: below it the matrix is treated
/// as singular (it would map the image onto a line or a point).
const MIN_SINGULAR_RATIO: f64 = 1e-9;

/// Why a homography could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HomographyError {
    /// More than [`MAX_TEXT_BYTES`] of text.
    #[error("{bytes} bytes is too long for a 3x3 matrix (at most {MAX_TEXT_BYTES})")]
    TooLong {
        /// Length of the text.
        bytes: usize,
    },
    /// A token that is not a finite decimal number.
    #[error("`{token}` is not a finite number")]
    NotANumber {
        /// The offending token (cut to 40 characters).
        token: String,
    },
    /// Not exactly nine numbers.
    #[error("expected 9 numbers (a 3x3 matrix, row by row), found {found}")]
    WrongCount {
        /// How many numbers were found.
        found: usize,
    },
    /// The matrix has no usable inverse.
    #[error("the matrix is singular (singular value ratio {ratio:e}); it cannot map an image")]
    Singular {
        /// Smallest over largest singular value.
        ratio: f64,
    },
}

/// `x' ~ H x` from the reference image to another one, in 0-based pixel coordinates whose
/// integers are pixel centres (the detectors' and OpenCV's convention), with its inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography {
    forward: Matrix3<f64>,
    inverse: Matrix3<f64>,
}

impl Homography {
    /// Checks that `m` is finite and invertible.
    pub fn new(m: Matrix3<f64>) -> Result<Self, HomographyError> {
        if let Some(v) = m.iter().find(|v| !v.is_finite()) {
            return Err(HomographyError::NotANumber {
                token: v.to_string(),
            });
        }
        let sv = m.singular_values();
        let (min, max) = (sv.min(), sv.max());
        let ratio = if max > 0.0 { min / max } else { 0.0 };
        if ratio.is_nan() || ratio < MIN_SINGULAR_RATIO {
            return Err(HomographyError::Singular { ratio });
        }
        let inverse = m.try_inverse().ok_or(HomographyError::Singular { ratio })?;
        Ok(Homography {
            forward: m,
            inverse,
        })
    }

    /// Nine whitespace-separated numbers, row by row (LF or CRLF line ends).
    pub fn parse(text: &str) -> Result<Self, HomographyError> {
        if text.len() > MAX_TEXT_BYTES {
            return Err(HomographyError::TooLong { bytes: text.len() });
        }
        let mut values = Vec::with_capacity(9);
        for token in text.split_whitespace() {
            let v: f64 = token
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| HomographyError::NotANumber {
                    token: token.chars().take(40).collect(),
                })?;
            values.push(v);
        }
        if values.len() != 9 {
            return Err(HomographyError::WrongCount {
                found: values.len(),
            });
        }
        Homography::new(Matrix3::from_row_slice(&values))
    }

    /// The same mapping for a matrix estimated with pixel centres at `origin` (0: 0-based
    /// centres, 0.5: corner-based, 1: 1-based as MATLAB), expressed in 0-based coordinates:
    /// `p' = H (p + o) - o`.
    pub fn with_pixel_origin(&self, origin: f64) -> Self {
        let shift = |o: f64| Matrix3::new(1.0, 0.0, o, 0.0, 1.0, o, 0.0, 0.0, 1.0);
        let forward = shift(-origin) * self.forward * shift(origin);
        let inverse = shift(-origin) * self.inverse * shift(origin);
        Homography { forward, inverse }
    }

    /// The 3x3 matrix, reference to other image.
    pub fn matrix(&self) -> &Matrix3<f64> {
        &self.forward
    }

    /// Maps a reference point into the other image; `None` on the line at infinity.
    pub fn map(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        project(&self.forward, x, y)
    }

    /// Maps a point of the other image back into the reference.
    pub fn map_inverse(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        project(&self.inverse, x, y)
    }

    /// How much a small reference length grows when mapped at `(x, y)`: the square root of the
    /// Jacobian's determinant (an area ratio), so a keypoint of size `s` becomes `s * scale`.
    pub fn local_scale(&self, x: f64, y: f64) -> f64 {
        let h = &self.forward;
        let w = h[(2, 0)] * x + h[(2, 1)] * y + h[(2, 2)];
        // det of the Jacobian of a homography: det(H) / w^3.
        (h.determinant() / (w * w * w)).abs().sqrt()
    }
}

fn project(m: &Matrix3<f64>, x: f64, y: f64) -> Option<(f64, f64)> {
    let p = m * Vector3::new(x, y, 1.0);
    (p.z.abs() > 1e-12 && p.x.is_finite() && p.y.is_finite()).then(|| (p.x / p.z, p.y / p.z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn parses_crlf_and_scientific_notation() {
        let text = "  883.392404836646e-003   -67.5218642049985e-003    21.9535083569646e+000\r\n\
                    27.1332639047034e-003    765.083252831313e-003   -5.01617117001212e+000\r\n\
                    49.2895332333057e-006   -291.843814560728e-006    1.00336174941904e+000\r\n";
        let h = Homography::parse(text).unwrap();
        assert!((h.matrix()[(0, 2)] - 21.9535083569646).abs() < 1e-12);
        let (x, y) = h.map(100.0, 50.0).unwrap();
        let (bx, by) = h.map_inverse(x, y).unwrap();
        assert!((bx - 100.0).abs() < 1e-9 && (by - 50.0).abs() < 1e-9);
    }

    #[test]
    fn bad_text_gives_the_reason() {
        assert_eq!(
            Homography::parse("1 0 0 0 1 0 0 0"),
            Err(HomographyError::WrongCount { found: 8 })
        );
        assert!(matches!(
            Homography::parse("1 0 0 0 1 0 0 0 x"),
            Err(HomographyError::NotANumber { .. })
        ));
        assert!(matches!(
            Homography::parse("1 0 0 0 1 0 0 0 NaN"),
            Err(HomographyError::NotANumber { .. })
        ));
        assert!(matches!(
            Homography::parse("1 2 3 2 4 6 0 0 1"),
            Err(HomographyError::Singular { .. })
        ));
        assert!(matches!(
            Homography::parse("0 0 0 0 0 0 0 0 0"),
            Err(HomographyError::Singular { .. })
        ));
        let long = "1 ".repeat(MAX_TEXT_BYTES);
        assert!(matches!(
            Homography::parse(&long),
            Err(HomographyError::TooLong { .. })
        ));
    }

    #[test]
    fn pixel_origin_and_local_scale() {
        // A pure 2x zoom about the origin of a 1-based frame.
        let zoom = Homography::parse("2 0 0 0 2 0 0 0 1").unwrap();
        assert_eq!(zoom.map(10.0, 20.0), Some((20.0, 40.0)));
        // 0-based (10, 20) is 1-based (11, 21) -> (22, 42) -> 0-based (21, 41).
        assert_eq!(
            zoom.with_pixel_origin(1.0).map(10.0, 20.0),
            Some((21.0, 41.0))
        );
        assert!((zoom.local_scale(5.0, 7.0) - 2.0).abs() < 1e-12);
        let back = zoom.with_pixel_origin(1.0).map_inverse(21.0, 41.0).unwrap();
        assert!((back.0 - 10.0).abs() < 1e-12 && (back.1 - 20.0).abs() < 1e-12);
    }

    proptest! {
        #[test]
        fn parse_never_panics(text in "\\PC{0,200}") {
            let _ = Homography::parse(&text);
        }

        #[test]
        fn parse_never_panics_on_numbers(values in proptest::collection::vec(-1e300f64..1e300, 0..12)) {
            let text: Vec<String> = values.iter().map(|v| format!("{v:e}")).collect();
            if let Ok(h) = Homography::parse(&text.join(" ")) {
                let _ = (h.map(1.0, 2.0), h.map_inverse(3.0, 4.0), h.local_scale(5.0, 6.0));
            }
        }
    }
}
