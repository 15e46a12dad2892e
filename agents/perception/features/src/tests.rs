//! Pipeline tests on synthetic images: blob scale, orientation under rotation, illumination
//! invariance of LN-SURF and LSAC-SURF descriptors, self-matching.

use image::{Rgb, RgbImage};

use crate::experiment::{Relight, repeatability};
use crate::{
    DetectorConfig, DetectorKind, FeatureClass, Keypoint, MatchConfig, detect, match_features,
};

/// A gray image from `f(x, y)` in 8-bit units (clamped).
fn render(width: u32, height: u32, f: impl Fn(f32, f32) -> f32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        let v = f(x as f32, y as f32).clamp(0.0, 255.0).round() as u8;
        Rgb([v, v, v])
    })
}

fn gaussian(x: f32, y: f32, cx: f32, cy: f32, sigma: f32) -> f32 {
    (-((x - cx).powi(2) + (y - cy).powi(2)) / (2.0 * sigma * sigma)).exp()
}

/// Deterministic random blobs: textured enough for hundreds of keypoints.
fn texture(width: u32, height: u32, seed: u64) -> RgbImage {
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as f32 / (1u64 << 31) as f32
    };
    let blobs: Vec<(f32, f32, f32, f32, [f32; 3])> = (0..400)
        .map(|_| {
            let (cx, cy) = (next() * width as f32, next() * height as f32);
            let sigma = 1.2 + next() * 3.5;
            let amp = next() * 160.0 - 80.0;
            (cx, cy, sigma, amp, [next(), next(), next()])
        })
        .collect();
    RgbImage::from_fn(width, height, |x, y| {
        let mut px = [90.0f32; 3];
        for &(cx, cy, s, a, tint) in &blobs {
            let g = a * gaussian(x as f32, y as f32, cx, cy, s);
            for c in 0..3 {
                px[c] += g * (0.5 + tint[c]);
            }
        }
        Rgb(px.map(|v| v.clamp(0.0, 255.0).round() as u8))
    })
}

fn nearest(kps: &[Keypoint], x: f32, y: f32) -> Option<&Keypoint> {
    kps.iter()
        .min_by(|a, b| ((a.x - x).hypot(a.y - y)).total_cmp(&(b.x - x).hypot(b.y - y)))
}

#[test]
fn a_gaussian_blob_is_found_at_its_centre_and_scale() {
    for sigma in [2.5f32, 4.0, 6.0] {
        let img = render(160, 160, |x, y| {
            40.0 + 180.0 * gaussian(x, y, 80.3, 76.6, sigma)
        });
        let f = detect(
            DetectorKind::Surf,
            &img,
            &DetectorConfig::for_kind(DetectorKind::Surf),
        )
        .unwrap();
        let kp = nearest(&f.keypoints, 80.3, 76.6).expect("the blob is detected");
        assert!(
            (kp.x - 80.3).abs() < 0.7 && (kp.y - 76.6).abs() < 0.7,
            "sigma {sigma}: centre {kp:?}"
        );
        assert!(
            (kp.scale / sigma - 1.0).abs() < 0.3,
            "sigma {sigma}: scale {}",
            kp.scale
        );
        // A bright blob on a dark background has a negative Laplacian.
        assert_eq!(kp.laplacian_sign, -1);
    }
}

#[test]
fn a_blob_found_on_the_doubled_image_is_reported_in_input_pixels() {
    // sigma 1.5: finer than the input-resolution pipeline's finest interior level (15 px filter,
    // interpolated down to 12 px at most: scale 1.6).
    let img = render(120, 120, |x, y| {
        40.0 + 180.0 * gaussian(x, y, 60.3, 56.6, 1.5)
    });
    let config = DetectorConfig {
        upsample: true,
        ..DetectorConfig::for_kind(DetectorKind::Surf)
    };
    let f = detect(DetectorKind::Surf, &img, &config).unwrap();
    let kp = nearest(&f.keypoints, 60.3, 56.6).expect("the blob is detected");
    assert!(
        (kp.x - 60.3).abs() < 0.25 && (kp.y - 56.6).abs() < 0.25,
        "centre {kp:?}"
    );
    assert!(kp.scale < 1.6, "scale {}", kp.scale);
    assert!((kp.size / kp.scale - 9.0 / 1.2).abs() < 1e-3);
}

#[test]
fn orientation_turns_with_the_image() {
    let img = texture(200, 200, 7);
    let rotated = image::imageops::rotate90(&img);
    let config = DetectorConfig::for_kind(DetectorKind::Surf);
    let a = detect(DetectorKind::Surf, &img, &config).unwrap();
    let b = detect(DetectorKind::Surf, &rotated, &config).unwrap();
    // rotate90 (clockwise): (x, y) -> (h - 1 - y, x); directions turn by +pi/2.
    let mut checked = 0;
    let mut agree = 0;
    for kp in a.keypoints.iter().filter(|k| k.scale < 6.0) {
        let (x, y) = (199.0 - kp.y, kp.x);
        let Some(other) = nearest(&b.keypoints, x, y) else {
            continue;
        };
        if (other.x - x).hypot(other.y - y) > 0.5 || (other.size / kp.size - 1.0).abs() > 0.1 {
            continue;
        }
        checked += 1;
        let diff = (other.orientation - kp.orientation - std::f32::consts::FRAC_PI_2)
            .rem_euclid(std::f32::consts::TAU);
        if diff.min(std::f32::consts::TAU - diff) < 0.25 {
            agree += 1;
        }
    }
    assert!(
        checked >= 20,
        "only {checked} keypoints found again after rotation"
    );
    // Pixel rounding of the Haar samples and ambiguous textures leave a minority off.
    assert!(
        agree * 10 >= checked * 6,
        "{agree}/{checked} orientations turned by pi/2"
    );
}

#[test]
fn ln_and_lsac_descriptors_ignore_a_brightness_change() {
    let img = texture(240, 200, 11);
    let dim = Relight::Intensity(0.5).apply(&img);
    for kind in [DetectorKind::LnSurf, DetectorKind::LsacSurf] {
        let config = DetectorConfig::for_kind(kind);
        let a = detect(kind, &img, &config).unwrap();
        let b = detect(kind, &dim, &config).unwrap();
        let r = repeatability(&b.keypoints, &a.keypoints);
        assert!(
            r > 70.0,
            "{kind}: repeatability {r:.1} % under a x0.5 change"
        );
        let mut close = 0;
        let mut total = 0;
        for (kp, d) in a.keypoints.iter().zip(&a.descriptors) {
            let Some(j) = (0..b.keypoints.len()).find(|&j| {
                (b.keypoints[j].x - kp.x).hypot(b.keypoints[j].y - kp.y) < 0.3
                    && (b.keypoints[j].size / kp.size - 1.0).abs() < 0.05
            }) else {
                continue;
            };
            total += 1;
            let dist: f32 = d
                .iter()
                .zip(&b.descriptors[j])
                .map(|(p, q)| (p - q) * (p - q))
                .sum::<f32>()
                .sqrt();
            if dist < 0.15 {
                close += 1;
            }
        }
        assert!(
            total >= 20 && close * 10 >= total * 9,
            "{kind}: {close}/{total} descriptors unchanged"
        );
    }
}

#[test]
fn matching_an_image_with_itself_finds_the_identity() {
    let img = texture(200, 160, 3);
    for kind in DetectorKind::ALL {
        let f = detect(kind, &img, &DetectorConfig::for_kind(kind)).unwrap();
        let m = match_features(&f, &f, &MatchConfig::default());
        let hard = f
            .keypoints
            .iter()
            .filter(|k| k.class == FeatureClass::Hard)
            .count();
        assert!(
            f.keypoints.len() >= 30,
            "{kind}: {} keypoints",
            f.keypoints.len()
        );
        assert!(
            m.iter().all(|m| m.query_index == m.train_index),
            "{kind}: a non-identity match"
        );
        assert!(
            m.len() * 10 >= hard * 9,
            "{kind}: {} of {hard} hard features matched",
            m.len()
        );
    }
}

#[test]
fn lsac_marks_features_near_saturation_soft() {
    let img = render(120, 120, |x, y| {
        255.0 * (gaussian(x, y, 40.0, 60.0, 4.0) * 2.0)
            + 120.0 * gaussian(x, y, 85.0, 60.0, 4.0)
            + 20.0
    });
    let f = detect(
        DetectorKind::LsacSurf,
        &img,
        &DetectorConfig::for_kind(DetectorKind::LsacSurf),
    )
    .unwrap();
    let saturated = nearest(&f.keypoints, 40.0, 60.0).unwrap();
    let normal = nearest(&f.keypoints, 85.0, 60.0).unwrap();
    assert_eq!(
        (saturated.class, normal.class),
        (FeatureClass::Soft, FeatureClass::Hard)
    );
}

#[test]
fn invalid_config_is_an_error_naming_the_field() {
    let mut config = DetectorConfig::for_kind(DetectorKind::Surf);
    config.levels = 2;
    let err = detect(DetectorKind::Surf, &RgbImage::new(10, 10), &config).unwrap_err();
    assert!(err.to_string().contains("levels"), "{err}");
}

mod properties {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn any_small_image_detects_without_panic(w in 0u32..48, h in 0u32..48, seed in any::<u64>(), kind in 0usize..DetectorKind::ALL.len()) {
            let mut state = seed;
            let img = RgbImage::from_fn(w, h, |_, _| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                let b = (state >> 40) as u8;
                Rgb([b, b.wrapping_mul(3), b.wrapping_add(91)])
            });
            let kind = DetectorKind::ALL[kind];
            let f = detect(kind, &img, &DetectorConfig::for_kind(kind)).unwrap();
            prop_assert_eq!(f.keypoints.len(), f.descriptors.len());
            for kp in &f.keypoints {
                prop_assert!(kp.x >= 0.0 && kp.y >= 0.0 && kp.x < w as f32 && kp.y < h as f32);
                prop_assert!(kp.size.is_finite() && kp.orientation.is_finite() && kp.response.is_finite());
            }
        }
    }
}

#[test]
fn the_doubled_images_blur_is_checked_and_used() {
    let mut config = DetectorConfig::for_kind(DetectorKind::LsacSurfNt);
    for bad in [0.4, 8.5, f32::NAN] {
        config.doubled_sigma = bad;
        assert!(
            matches!(
                config.validate(),
                Err(crate::FeatureError::InvalidConfig {
                    field: "doubled_sigma",
                    ..
                })
            ),
            "{bad} accepted"
        );
    }
    let img = texture(96, 96, 7);
    let count = |sigma: f32| {
        let config = DetectorConfig {
            doubled_sigma: sigma,
            ..DetectorConfig::for_kind(DetectorKind::LsacSurfNt)
        };
        detect(DetectorKind::LsacSurfNt, &img, &config)
            .unwrap()
            .keypoints
            .len()
    };
    // More blur leaves fewer fine extrema (the default is the SIFT base scale, 1.6).
    assert!(count(4.0) < count(1.6), "{} vs {}", count(4.0), count(1.6));
}

#[test]
fn dequantisation_is_checked_and_used() {
    let mut config = DetectorConfig::for_kind(DetectorKind::LsacSurfNt);
    config.dequantise_iterations = 257;
    assert!(matches!(
        config.validate(),
        Err(crate::FeatureError::InvalidConfig {
            field: "dequantise_iterations",
            ..
        })
    ));
    // A low-contrast image (the texture at a fifth of its contrast): its rounding plateaus
    // are what the rounds smooth, with and without the doubled image.
    let mut dim = texture(96, 96, 7);
    for px in dim.pixels_mut() {
        px.0 = px.0.map(|v| (f32::from(v) * 0.2).round() as u8);
    }
    for upsample in [true, false] {
        let run = |rounds: usize| {
            let config = DetectorConfig {
                dequantise_iterations: rounds,
                upsample,
                ..DetectorConfig::for_kind(DetectorKind::LsacSurfNt)
            };
            detect(DetectorKind::LsacSurfNt, &dim, &config)
                .unwrap()
                .keypoints
        };
        let (plain, smoothed) = (run(0), run(16));
        assert!(!plain.is_empty() && !smoothed.is_empty());
        assert_ne!(
            plain, smoothed,
            "upsample {upsample}: the rounds changed nothing"
        );
    }
}
