//! The three detectors on a real shared photograph (skips when `shared/` is absent): enough
//! keypoints, all inside the image, and LN-SURF and LSAC-SURF at least as repeatable as SURF
//! when the light is halved (thesis 4.6.4, the LIC collection).

use iw_features::experiment::{Relight, repeatability};
use iw_features::{DetectorConfig, DetectorKind, MatchConfig, detect, match_features};

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
