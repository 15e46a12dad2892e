//! Visual odometry's errors keep their cause: an image that does not decode keeps the decoder's
//! error, a detector that refuses its configuration keeps the detector's, each as `source()`
//! and at the end of the message.

use iw_features::{DetectorKind, FeatureError};
use iw_testdata::cause;
use iw_vo::{
    DepthImage, FramePair, Intrinsics, Pipeline, RgbdFrame, VisualOdometry, VoConfig, VoError,
    load_pair,
};

#[test]
fn an_image_that_does_not_decode_keeps_the_decoders_error() {
    let dir = tempfile::tempdir().unwrap();
    let rgb = dir.path().join("rgb.png");
    // a PNG signature and then nothing a decoder can use
    std::fs::write(&rgb, b"\x89PNG\r\n\x1a\nnot a png at all").unwrap();
    let pair = FramePair {
        timestamp_s: 0.0,
        rgb: rgb.clone(),
        depth_timestamp_s: 0.0,
        depth: dir.path().join("depth.png"),
    };
    let err = load_pair(&pair).unwrap_err();
    assert!(
        matches!(&err, VoError::Decode { path, .. } if *path == rgb.display().to_string()),
        "{err}"
    );
    cause::<image::ImageError>(&err);
}

#[test]
fn a_detector_that_refuses_its_configuration_keeps_its_error() {
    let mut config = VoConfig::new(DetectorKind::LsacSurf, Pipeline::Thesis);
    config.detector_config.octaves = 0;
    let mut vo = VisualOdometry::new(config, Intrinsics::tum_freiburg1());
    let frame = RgbdFrame {
        timestamp_s: 0.0,
        rgb: image::RgbImage::new(64, 48),
        depth: DepthImage::new(64, 48),
        decode_ms: 0.0,
    };
    let err = vo.process(&frame).unwrap_err();
    assert!(
        matches!(
            cause::<FeatureError>(&err),
            FeatureError::InvalidConfig {
                field: "octaves",
                ..
            }
        ),
        "{err}"
    );
}
