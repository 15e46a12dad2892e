//! Per-stage cost of one visual odometry frame on fr1_rpy (640x480): PNG decoding, detection,
//! matching, RANSAC + Umeyama, and a whole tracked frame of each pipeline.
//! `cargo bench -p iw-vo --bench vo_frame` (skips when the shared data is absent).

use criterion::{Criterion, criterion_group, criterion_main};
use iw_features::{Detector, DetectorConfig, DetectorKind, MatchConfig, match_features};
use iw_vo::{
    Intrinsics, Pipeline, RansacParams, TumSequence, VisualOdometry, VoConfig, load_pair,
    ransac_rigid, tum,
};
use nalgebra::Point3;
use rand::SeedableRng;

fn bench(c: &mut Criterion) {
    let Some(dir) = iw_testdata::require("vo_frame bench", "data/tum/rgbd_dataset_freiburg1_rpy")
    else {
        return;
    };
    let Ok(seq) = TumSequence::open(&dir, tum::DEFAULT_MAX_DT_S) else {
        return;
    };
    let (Ok(a), Ok(b)) = (load_pair(&seq.frames[100]), load_pair(&seq.frames[101])) else {
        return;
    };
    let k = Intrinsics::tum_freiburg1();
    let mut group = c.benchmark_group("vo_frame");
    group
        .sample_size(10)
        .measurement_time(std::time::Duration::from_secs(4));
    group.bench_function("load (decode rgb + depth png)", |bench| {
        bench.iter(|| load_pair(&seq.frames[100]))
    });
    for kind in DetectorKind::ALL {
        let config = DetectorConfig::for_kind(kind);
        let mut detector = Detector::new();
        group.bench_function(format!("detect {kind}"), |bench| {
            bench.iter(|| detector.detect(kind, &a.rgb, &config))
        });
    }
    let config = DetectorConfig::for_kind(DetectorKind::LsacSurf);
    let mut detector = Detector::new();
    let (Ok(fa), Ok(fb)) = (
        detector.detect(DetectorKind::LsacSurf, &a.rgb, &config),
        detector.detect(DetectorKind::LsacSurf, &b.rgb, &config),
    ) else {
        return;
    };
    let match_config = MatchConfig::default();
    group.bench_function("match lsac-surf (brute force, mutual, ratio)", |bench| {
        bench.iter(|| match_features(&fb, &fa, &match_config))
    });
    let matches = match_features(&fb, &fa, &match_config);
    let point = |frame: &iw_vo::RgbdFrame, kp: &iw_features::Keypoint| {
        let raw = frame
            .depth
            .get_pixel(kp.x.round() as u32, kp.y.round() as u32)
            .0[0];
        k.depth_m(raw)
            .map(|z| k.back_project(nalgebra::Point2::new(f64::from(kp.x), f64::from(kp.y)), z))
    };
    let (mut src, mut dst): (Vec<Point3<f64>>, Vec<Point3<f64>>) = (Vec::new(), Vec::new());
    for m in &matches {
        if let (Some(p), Some(q)) = (
            point(&b, &fb.keypoints[m.query_index]),
            point(&a, &fa.keypoints[m.train_index]),
        ) {
            src.push(p);
            dst.push(q);
        }
    }
    for (name, params) in [
        ("ransac thesis (35 hypotheses)", RansacParams::default()),
        (
            "ransac keyframe (100 + 2 refits)",
            RansacParams {
                iterations: 100,
                refit_rounds: 2,
                ..RansacParams::default()
            },
        ),
    ] {
        group.bench_function(format!("{name}, {} pairs", src.len()), |bench| {
            bench.iter(|| {
                ransac_rigid(
                    &src,
                    &dst,
                    &params,
                    &mut rand_chacha::ChaCha8Rng::seed_from_u64(0),
                )
            })
        });
    }
    for pipeline in [Pipeline::Thesis, Pipeline::Keyframe] {
        group.bench_function(
            format!("track one frame lsac-surf {pipeline:?} (no decode)"),
            |bench| {
                bench.iter_batched(
                    || {
                        let mut vo =
                            VisualOdometry::new(VoConfig::new(DetectorKind::LsacSurf, pipeline), k);
                        let _ = vo.process(&a);
                        vo
                    },
                    |mut vo| vo.process(&b),
                    criterion::BatchSize::LargeInput,
                )
            },
        );
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
