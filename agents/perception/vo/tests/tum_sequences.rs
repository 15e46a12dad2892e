//! End-to-end runs on the shared TUM fixture (skipped with a message when the data is absent).

use std::path::Path;

use iw_features::DetectorKind;
use iw_vo::{
    CameraSource, Intrinsics, Pipeline, TumReplay, TumSequence, VisualOdometry, VoConfig, VoError,
    eval, tum,
};

const DESK_MINI: &str = "data/tum/rgbd_dataset_freiburg1_desk_mini";

#[test]
fn own_association_matches_the_shipped_associations() {
    let Some(dir) = iw_testdata::require(
        "own_association_matches_the_shipped_associations",
        DESK_MINI,
    ) else {
        return;
    };
    let shipped = TumSequence::open(&dir, tum::DEFAULT_MAX_DT_S).expect("opens");
    // Same folder without associations.txt: the lists must associate to the same pairs.
    let tmp = tempfile::tempdir().expect("temp dir");
    for f in ["rgb.txt", "depth.txt"] {
        std::fs::copy(dir.join(f), tmp.path().join(f)).expect("copy list");
    }
    let own = TumSequence::open(tmp.path(), tum::DEFAULT_MAX_DT_S).expect("associates");
    assert_eq!(own.frames.len(), shipped.frames.len());
    for (a, b) in own.frames.iter().zip(&shipped.frames) {
        assert_eq!(a.timestamp_s, b.timestamp_s);
        assert_eq!(a.depth_timestamp_s, b.depth_timestamp_s);
        assert_eq!(a.rgb.file_name(), b.rgb.file_name());
    }
    assert!(own.groundtruth.is_none());
}

#[test]
fn broken_lists_name_file_and_line() {
    let tmp = tempfile::tempdir().expect("temp dir");
    std::fs::write(
        tmp.path().join("rgb.txt"),
        "# header\n1.0 rgb/1.png\n1.1 rgb/2.png extra\n",
    )
    .expect("write");
    std::fs::write(tmp.path().join("depth.txt"), "1.0 depth/1.png\n").expect("write");
    let err = TumSequence::open(tmp.path(), 0.02).expect_err("three fields");
    let text = err.to_string();
    assert!(
        text.ends_with("rgb.txt:3: expected `timestamp filename`, got 3 fields"),
        "{text}"
    );
    std::fs::write(tmp.path().join("rgb.txt"), "5.0 rgb/1.png\n").expect("write");
    assert!(matches!(
        TumSequence::open(tmp.path(), 0.02),
        Err(VoError::NoAssociations { .. })
    ));
    assert!(matches!(
        TumSequence::open(&tmp.path().join("missing"), 0.02),
        Err(VoError::Io { .. })
    ));
}

#[test]
fn unreadable_image_is_an_error_not_a_panic() {
    let tmp = tempfile::tempdir().expect("temp dir");
    std::fs::write(
        tmp.path().join("associations.txt"),
        "1.0 rgb.png 1.0 depth.png\n",
    )
    .expect("write");
    std::fs::write(tmp.path().join("rgb.png"), b"not a png").expect("write");
    let seq = TumSequence::open(tmp.path(), 0.02).expect("lists parse");
    let mut replay = TumReplay::new(seq.frames, Intrinsics::tum_freiburg1(), 2, 2).unwrap();
    let err = replay
        .next_frame()
        .expect("one frame")
        .expect_err("bad png");
    assert!(err.to_string().contains("rgb.png"), "{err}");
    assert!(replay.next_frame().is_none());
}

fn run(dir: &Path, pipeline: Pipeline) -> Vec<iw_vo::StampedPose> {
    let seq = TumSequence::open(dir, tum::DEFAULT_MAX_DT_S).expect("opens");
    let mut replay = TumReplay::new(seq.frames.clone(), Intrinsics::tum_freiburg1(), 2, 4).unwrap();
    let mut vo = VisualOdometry::new(
        VoConfig::new(DetectorKind::LsacSurf, pipeline),
        Intrinsics::tum_freiburg1(),
    );
    let mut poses = Vec::new();
    while let Some(frame) = replay.next_frame() {
        let (pose, stats) = vo.process(&frame.expect("decodes")).expect("processes");
        assert!(stats.features > 50, "{stats:?}");
        poses.push(pose);
    }
    assert_eq!(poses.len(), seq.frames.len());
    poses
}

#[test]
fn desk_mini_produces_a_trajectory_close_to_ground_truth() {
    let Some(dir) = iw_testdata::require(
        "desk_mini_produces_a_trajectory_close_to_ground_truth",
        DESK_MINI,
    ) else {
        return;
    };
    let gt = tum::read_trajectory(&dir.join("groundtruth.txt")).expect("ground truth");
    for pipeline in [Pipeline::Thesis, Pipeline::Keyframe] {
        let poses = run(&dir, pipeline);
        let ate = eval::ate(&poses, &gt, tum::DEFAULT_MAX_DT_S).expect("ate");
        eprintln!(
            "desk_mini {pipeline:?}: ATE RMSE {:.2} cm over {} poses",
            ate.rmse_m * 100.0,
            ate.errors.len()
        );
        assert_eq!(ate.errors.len(), 9);
        // The camera moves ~8 cm over these 0.27 s; a working tracker stays within a few cm.
        assert!(ate.rmse_m < 0.03, "{pipeline:?}: {} m", ate.rmse_m);
        // Same input, same seed: same trajectory.
        assert_eq!(poses, run(&dir, pipeline));
    }
}
