//! Detection + description of one 640x480 frame per detector: the centre crop of the shared
//! `graf1.png` (dense texture, ~1000 keypoints) and the first RGB frame of TUM fr1_rpy (the
//! visual-odometry workload), with OpenCV SIFT and ORB timed in the same run on the same frames
//! by `benches/opencv_peer.py` when python3 and OpenCV are available.
//!
//! Run: `cargo bench -p iw-features --bench detect`

use std::time::Duration;

use criterion::{Criterion, criterion_group};
use iw_features::{Detector, DetectorConfig, DetectorKind};

/// The benchmarked frames: (name, shared path), each centre-cropped to 640x480.
const FRAMES: [(&str, &str); 2] = [
    ("graf1", "data/images/opencv_samples/graf1.png"),
    (
        "tum_rpy",
        "data/tum/rgbd_dataset_freiburg1_rpy/rgb/1305031229.528748.png",
    ),
];

fn frame(rel: &str) -> Option<(std::path::PathBuf, image::RgbImage)> {
    let path = iw_testdata::require("bench detect", rel)?;
    let img = image::open(&path).ok()?.to_rgb8();
    let (x0, y0) = (
        img.width().checked_sub(640)? / 2,
        img.height().checked_sub(480)? / 2,
    );
    Some((
        path,
        image::imageops::crop_imm(&img, x0, y0, 640, 480).to_image(),
    ))
}

fn bench_detectors(c: &mut Criterion) {
    for (name, rel) in FRAMES {
        let Some((_, img)) = frame(rel) else { continue };
        let mut group = c.benchmark_group(format!("detect_describe_640x480/{name}"));
        group
            .measurement_time(Duration::from_secs(4))
            .sample_size(20);
        for kind in DetectorKind::ALL {
            let config = DetectorConfig::for_kind(kind);
            let mut detector = Detector::new();
            let n = detector
                .detect(kind, &img, &config)
                .map(|f| f.keypoints.len())
                .unwrap_or(0);
            eprintln!("{name} {kind}: {n} keypoints");
            group.bench_function(kind.name(), |b| {
                b.iter(|| detector.detect(kind, &img, &config))
            });
        }
        group.finish();
    }
}

fn opencv_peer() {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/opencv_peer.py");
    for (name, rel) in FRAMES {
        let Some((path, _)) = frame(rel) else {
            continue;
        };
        match std::process::Command::new("python3")
            .arg(script)
            .arg(&path)
            .output()
        {
            Ok(out) if out.status.success() => {
                for line in String::from_utf8_lossy(&out.stdout).lines() {
                    println!("{name} {line}");
                }
            }
            Ok(out) => eprintln!(
                "SKIP opencv peer: {}",
                String::from_utf8_lossy(&out.stderr)
                    .lines()
                    .last()
                    .unwrap_or("")
            ),
            Err(e) => eprintln!("SKIP opencv peer: python3 not runnable ({e})"),
        }
    }
}

criterion_group!(benches, bench_detectors);

fn main() {
    benches();
    opencv_peer();
    Criterion::default().configure_from_args().final_summary();
}
