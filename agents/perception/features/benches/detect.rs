//! Detection + description of one 640x480 frame per detector (centre crop of the shared
//! `graf1.png`), with OpenCV SIFT and ORB timed in the same run on the same crop by
//! `benches/opencv_peer.py` when python3 and OpenCV are available.
//!
//! Run: `cargo bench -p iw-features --bench detect`

use std::time::Duration;

use criterion::{Criterion, criterion_group};
use iw_features::{Detector, DetectorConfig, DetectorKind};

const IMAGE: &str = "data/images/opencv_samples/graf1.png";

fn frame() -> Option<(std::path::PathBuf, image::RgbImage)> {
    let path = iw_testdata::require("bench detect", IMAGE)?;
    let img = image::open(&path).ok()?.to_rgb8();
    let (x0, y0) = (img.width().checked_sub(640)? / 2, img.height().checked_sub(480)? / 2);
    Some((path, image::imageops::crop_imm(&img, x0, y0, 640, 480).to_image()))
}

fn bench_detectors(c: &mut Criterion) {
    let Some((_, img)) = frame() else { return };
    let mut group = c.benchmark_group("detect_describe_640x480");
    group.measurement_time(Duration::from_secs(4)).sample_size(30);
    for kind in DetectorKind::ALL {
        let config = DetectorConfig::for_kind(kind);
        let mut detector = Detector::new();
        let n = detector.detect(kind, &img, &config).map(|f| f.keypoints.len()).unwrap_or(0);
        eprintln!("{kind}: {n} keypoints on the 640x480 frame");
        group.bench_function(kind.name(), |b| b.iter(|| detector.detect(kind, &img, &config)));
    }
    group.finish();
}

fn opencv_peer() {
    let Some((path, _)) = frame() else { return };
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/opencv_peer.py");
    match std::process::Command::new("python3").arg(script).arg(&path).output() {
        Ok(out) if out.status.success() => print!("{}", String::from_utf8_lossy(&out.stdout)),
        Ok(out) => eprintln!("SKIP opencv peer: {}", String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")),
        Err(e) => eprintln!("SKIP opencv peer: python3 not runnable ({e})"),
    }
}

criterion_group!(benches, bench_detectors);

fn main() {
    benches();
    opencv_peer();
    Criterion::default().configure_from_args().final_summary();
}
