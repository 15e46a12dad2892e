//! The three detectors on a real shared photograph (skips when `shared/` is absent): enough
//! keypoints, all inside the image, and LN-SURF and LSAC-SURF at least as repeatable as SURF
//! when the light is halved (thesis 4.6.4, the LIC collection).

use iw_features::experiment::{Relight, repeatability};
use iw_features::{DetectorConfig, DetectorKind, MatchConfig, detect, match_features};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn detectors_on_a_shared_photo() {
    let Some(path) = iw_testdata::require(
        "detectors_on_a_shared_photo",
        "data/images/skimage/astronaut.png",
    ) else {
        return;
    };
    let img = image::open(&path).expect("shared photo decodes").to_rgb8();
    let dim = Relight::Intensity(0.5).apply(&img);
    let mut rates = Vec::new();
    for kind in DetectorKind::ALL {
        let config = DetectorConfig::for_kind(kind);
        let reference = detect(kind, &img, &config).unwrap();
        let relit = detect(kind, &dim, &config).unwrap();
        assert!(
            reference.keypoints.len() > 100,
            "{kind}: {} keypoints",
            reference.keypoints.len()
        );
        for kp in &reference.keypoints {
            assert!(
                kp.x >= 0.0
                    && kp.y >= 0.0
                    && kp.x < img.width() as f32
                    && kp.y < img.height() as f32
            );
        }
        let matches = match_features(&reference, &relit, &MatchConfig::default());
        // The scene did not move: a match should join the same place in both images.
        let same_place = matches
            .iter()
            .filter(|m| {
                let (a, b) = (
                    &reference.keypoints[m.query_index],
                    &relit.keypoints[m.train_index],
                );
                (a.x - b.x).hypot(a.y - b.y) < 2.0
            })
            .count();
        assert!(
            matches.len() > 30 && same_place * 10 >= matches.len() * 9,
            "{kind}: {same_place}/{} matches in place",
            matches.len()
        );
        rates.push(repeatability(&relit.keypoints, &reference.keypoints));
    }
    eprintln!(
        "repeatability under x0.5: surf {:.1} %, ln-surf {:.1} %, lsac-surf {:.1} %",
        rates[0], rates[1], rates[2]
    );
    assert!(rates[2] > 60.0, "lsac-surf {:.1} %", rates[2]);
}

/// Issue 22: dimmed to 1/8 with read noise (sigma 2, 8-bit units), a photograph gives
/// LSAC-SURF-NT (uncapped) about as many keypoints as in full light: the noise model keeps the
/// amplified noise from becoming keypoints. Without it (factor 0) the count is higher, and
/// without it and the contrast-normalised threshold it grows by over 30 %, so the test can fail.
#[test]
fn lsac_surf_nt_does_not_promote_noise_in_the_dark() {
    let Some(path) = iw_testdata::require(
        "lsac_surf_nt_does_not_promote_noise_in_the_dark",
        "data/images/skimage/camera.png",
    ) else {
        return;
    };
    let img = image::open(&path).expect("shared photo decodes").to_rgb8();
    // Deterministic Gaussian noise from a seeded stream.
    let mut rng = ChaCha8Rng::seed_from_u64(0x2545_f491);
    let mut dark = img.clone();
    for px in dark.pixels_mut() {
        let n = iw_stats::standard_normal(&mut rng);
        // One noise sample per pixel (a gray sensor): the channels stay equal.
        for c in px.0.iter_mut() {
            *c = (f64::from(*c) / 8.0 + 2.0 * n).round().clamp(0.0, 255.0) as u8;
        }
    }
    let count = |image: &image::RgbImage, factor: Option<f32>, contrast: Option<f32>| {
        let mut config = DetectorConfig::for_kind(DetectorKind::LsacSurfNt);
        config.max_keypoints = Some(usize::MAX);
        if let Some(k) = factor {
            config.noise_factor = k;
        }
        if let Some(c) = contrast {
            config.contrast_threshold = c;
        }
        detect(DetectorKind::LsacSurfNt, image, &config)
            .unwrap()
            .keypoints
            .len() as f64
    };
    let (light, dark_aware, dark_no_model, dark_blind) = (
        count(&img, None, None),
        count(&dark, None, None),
        count(&dark, Some(0.0), None),
        count(&dark, Some(0.0), Some(0.0)),
    );
    eprintln!(
        "uncapped keypoints: full light {light}, dark {dark_aware} (noise model), \
         {dark_no_model} (no model), {dark_blind} (no model, no contrast threshold)"
    );
    let ratio = dark_aware / light;
    assert!((0.7..=1.3).contains(&ratio), "dark / light = {ratio:.2}");
    assert!(
        dark_no_model > dark_aware,
        "the noise model removed nothing"
    );
    assert!(
        dark_blind / light > 1.3,
        "without the model and the contrast threshold: {:.2}",
        dark_blind / light
    );
}

/// `image` as a camera would see it under `gain` of the light: shot noise (0.25 DN^2 per DN) and
/// read noise `read` DN, one sample per pixel (a gray sensor), rounded to 8 bits.
fn darkened(image: &image::RgbImage, gain: f64, read: f64, seed: u64) -> image::RgbImage {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = image.clone();
    for px in out.pixels_mut() {
        let n = iw_stats::standard_normal(&mut rng);
        for c in px.0.iter_mut() {
            let signal = f64::from(*c) * gain;
            let noisy = signal + n * (0.25 * signal + read * read).sqrt();
            *c = noisy.round().clamp(0.0, 255.0) as u8;
        }
    }
    out
}

/// LSAC-SURF-NT's keypoints below its cap: the detector's own count, not the cap's.
fn uncapped_count(image: &image::RgbImage) -> f64 {
    let mut config = DetectorConfig::for_kind(DetectorKind::LsacSurfNt);
    config.max_keypoints = Some(usize::MAX);
    detect(DetectorKind::LsacSurfNt, image, &config)
        .unwrap()
        .keypoints
        .len() as f64
}

/// Photographs of the tuning set (docs/results/repeatability.md): a low-contrast texture, a
/// gray portrait, a colour photograph with dark regions.
const DIMMED: [&str; 3] = ["brick.png", "camera.png", "chelsea.png"];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]
    /// Issue 22: as the light on a photograph falls to 1/4 with shot and read noise,
    /// LSAC-SURF-NT's uncapped count stays within +-30 % of full light. The detector before
    /// the contrast-normalised threshold (base threshold 10, noise factor 11) fails it: brick
    /// at 1/2 and 1/4 gave 2.0-3.6x its full-light count (measured through `intellwheels
    /// features`). Not held further down: at 1/8 brick gains 32-45 % (see the results page).
    #[test]
    fn lsac_surf_nt_keeps_its_count_as_a_photograph_darkens(
        photo in 0..DIMMED.len(),
        stops in 1.0f64..2.0,
        read in 1.0f64..1.5,
        seed in any::<u64>(),
    ) {
        let Some(path) = iw_testdata::require(
            "lsac_surf_nt_keeps_its_count_as_a_photograph_darkens",
            &format!("data/images/skimage/{}", DIMMED[photo]),
        ) else {
            return Ok(());
        };
        let light = image::open(&path).expect("shared photo decodes").to_rgb8();
        let dark = darkened(&light, 2f64.powf(-stops), read, seed);
        let (before, after) = (uncapped_count(&light), uncapped_count(&dark));
        let ratio = after / before;
        prop_assert!(
            (0.7..=1.3).contains(&ratio),
            "{} at 1/{:.1}, read {read:.1} DN: {before} -> {after} keypoints ({ratio:.2})",
            DIMMED[photo],
            2f64.powf(stops)
        );
    }
}
