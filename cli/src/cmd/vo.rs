//! `intellwheels vo SEQ_DIR --detector lsac-surf|surf|ln-surf -o EST.txt [--plot OUT.png]`:
//! RGB-D visual odometry on a TUM-layout sequence (thesis chapter 5).
//!
//! Writes one TUM-format pose per associated frame, prints per-stage timings, and when the folder
//! has `groundtruth.txt`, prints ATE/RPE and plots the estimate against it.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use iw_features::DetectorKind;
use iw_vo::{
    CameraSource, FrameStats, Intrinsics, Pipeline, StampedPose, TumReplay, TumSequence,
    VisualOdometry, VoConfig, eval, tum,
};

/// Flags of `intellwheels vo`.
#[derive(clap::Args)]
pub struct Args {
    /// TUM-layout folder: rgb/, depth/, rgb.txt, depth.txt (associations.txt and groundtruth.txt
    /// are used when present).
    seq_dir: PathBuf,
    /// Feature detector: lsac-surf, surf or ln-surf.
    #[arg(long, default_value = "lsac-surf")]
    detector: DetectorKind,
    /// Output trajectory (TUM format: timestamp tx ty tz qx qy qz qw).
    #[arg(short, long)]
    output: PathBuf,
    /// Plot the estimate against groundtruth.txt (PNG).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// `thesis` (frame-to-frame, Algorithm 3) or `keyframe` (keyframes + local bundle adjustment).
    #[arg(long, default_value = "keyframe")]
    pipeline: Pipeline,
    /// Camera model (freiburg1|2|3); default: from the folder name, else freiburg1.
    #[arg(long)]
    camera: Option<String>,
    /// Raw depth units per metre (TUM: 5000).
    #[arg(long)]
    depth_units_per_m: Option<f64>,
    /// Ignore lens distortion (the thesis's plain pinhole model).
    #[arg(long)]
    no_distortion: bool,
    /// Largest rgb/depth timestamp difference when associating, s.
    #[arg(long, default_value_t = tum::DEFAULT_MAX_DT_S)]
    max_dt: f64,
    /// RANSAC seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// PNG loader threads decoding ahead of tracking.
    #[arg(long, default_value_t = 2, value_parser = super::flags::threads)]
    loader_threads: usize,
    /// Process only the first N frames.
    #[arg(long)]
    frames: Option<usize>,
    /// Per-frame statistics as JSON lines (features, matches, inliers, time per stage).
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Print the summary as one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

fn intrinsics(args: &Args) -> anyhow::Result<Intrinsics> {
    let mut k = match &args.camera {
        Some(name) => Intrinsics::by_name(name)?,
        None => {
            let name = args
                .seq_dir
                .canonicalize()
                .unwrap_or_else(|_| args.seq_dir.clone());
            let name = name
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            Intrinsics::from_sequence_name(&name).unwrap_or_else(|| {
                tracing::warn!(folder = %name, "camera not recognised from the folder name; using freiburg1 (set --camera)");
                Intrinsics::tum_freiburg1()
            })
        }
    };
    if let Some(units) = args.depth_units_per_m {
        anyhow::ensure!(
            units.is_finite() && units > 0.0,
            "--depth-units-per-m must be positive, got {units}"
        );
        k.depth_units_per_m = units;
    }
    if args.no_distortion {
        k.distortion = None;
    }
    Ok(k)
}

fn mean(stats: &[FrameStats], f: impl Fn(&FrameStats) -> f64) -> f64 {
    if stats.is_empty() {
        0.0
    } else {
        stats.iter().map(f).sum::<f64>() / stats.len() as f64
    }
}

/// Samples for the plot: time and position.
fn samples(poses: &[StampedPose]) -> Vec<(f64, [f64; 3])> {
    poses
        .iter()
        .map(|p| {
            let t = p.t_world_camera.translation.vector;
            (p.timestamp_s, [t.x, t.y, t.z])
        })
        .collect()
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let mut sequence = TumSequence::open(&args.seq_dir, args.max_dt)?;
    if let Some(n) = args.frames {
        sequence.frames.truncate(n);
    }
    let intrinsics = intrinsics(&args)?;
    let total = sequence.frames.len();
    let mut source = TumReplay::new(sequence.frames.clone(), intrinsics, args.loader_threads, 8)?;
    let mut config = VoConfig::new(args.detector, args.pipeline);
    config.seed = args.seed;
    config.refine.focal_px = 0.5 * (intrinsics.fx + intrinsics.fy);
    let mut vo = VisualOdometry::new(config, intrinsics);

    let bar = indicatif::ProgressBar::new(total as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} vo [{bar:40}] {pos}/{len} frames {per_sec} eta {eta} {msg}",
        )
        .context("progress template")?
        .progress_chars("=> "),
    );
    let mut poses = Vec::with_capacity(total);
    let mut stats = Vec::with_capacity(total);
    while let Some(frame) = source.next_frame() {
        let frame = frame?;
        let (pose, frame_stats) = vo.process(&frame)?;
        bar.set_message(format!("inliers {}", frame_stats.inliers));
        bar.inc(1);
        poses.push(pose);
        stats.push(frame_stats);
    }
    bar.finish_and_clear();
    let wall_s = started.elapsed().as_secs_f64();

    let file = std::fs::File::create(&args.output)
        .with_context(|| format!("creating {}", args.output.display()))?;
    tum::write_trajectory(std::io::BufWriter::new(file), &poses)
        .with_context(|| format!("writing {}", args.output.display()))?;
    if let Some(path) = &args.stats {
        let mut out = std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        );
        for s in &stats {
            serde_json::to_writer(&mut out, s)?;
            writeln!(out)?;
        }
        out.flush()
            .with_context(|| format!("writing {}", path.display()))?;
    }

    let groundtruth = match &sequence.groundtruth {
        Some(path) => Some(tum::read_trajectory(path)?),
        None => None,
    };
    let accuracy = match &groundtruth {
        Some(gt) => Some((
            eval::ate(&poses, gt, tum::DEFAULT_MAX_DT_S)?,
            eval::rpe(&poses, gt, tum::DEFAULT_MAX_DT_S, 1)?,
        )),
        None => None,
    };
    if let (Some(path), Some(gt)) = (&args.plot, &groundtruth) {
        // Only the ground truth around the sequence, the estimate aligned onto it as ATE aligns it.
        let (first, last) = (
            poses.first().map_or(0.0, |p| p.timestamp_s),
            poses.last().map_or(0.0, |p| p.timestamp_s),
        );
        let gt_window: Vec<StampedPose> = gt
            .iter()
            .filter(|p| p.timestamp_s >= first - 0.05 && p.timestamp_s <= last + 0.05)
            .copied()
            .collect();
        let aligned: Vec<StampedPose> = match &accuracy {
            Some((ate, _)) => poses
                .iter()
                .map(|p| StampedPose {
                    t_world_camera: ate.t_reference_estimate * p.t_world_camera,
                    ..*p
                })
                .collect(),
            None => poses.clone(),
        };
        let title = format!(
            "{} - {} {:?} pipeline{}",
            args.seq_dir
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            args.detector,
            args.pipeline,
            accuracy
                .as_ref()
                .map(|(a, _)| format!(", ATE RMSE {:.2} cm", a.rmse_m * 100.0))
                .unwrap_or_default()
        );
        iw_plot::trajectory::plot_trajectories(
            path,
            &title,
            &[
                iw_plot::trajectory::Trajectory {
                    name: "ground truth".into(),
                    samples: samples(&gt_window),
                },
                iw_plot::trajectory::Trajectory {
                    name: format!("estimate ({})", args.detector),
                    samples: samples(&aligned),
                },
            ],
        )?;
    } else if args.plot.is_some() {
        tracing::warn!(
            "no groundtruth.txt in {}: nothing to plot against",
            args.seq_dir.display()
        );
    }

    let tracked = stats.iter().filter(|s| s.tracked).count();
    let keyframes = stats.iter().filter(|s| s.keyframe).count();
    let fps = total as f64 / wall_s;
    let summary = serde_json::json!({
        "sequence": args.seq_dir.display().to_string(),
        "detector": args.detector.name(),
        "pipeline": args.pipeline,
        "frames": total,
        "tracked": tracked,
        "keyframes": keyframes,
        "wall_s": wall_s,
        "fps": fps,
        "mean_ms": {
            "decode": mean(&stats, |s| s.decode_ms),
            "detect": mean(&stats, |s| s.detect_ms),
            "match": mean(&stats, |s| s.match_ms),
            "ransac": mean(&stats, |s| s.ransac_ms),
            "refine": mean(&stats, |s| s.refine_ms),
        },
        "mean_features": mean(&stats, |s| s.features as f64),
        "mean_matches": mean(&stats, |s| s.matches as f64),
        "mean_inliers": mean(&stats, |s| s.inliers as f64),
        "ate_rmse_m": accuracy.as_ref().map(|(a, _)| a.rmse_m),
        "rpe_trans_rmse_m": accuracy.as_ref().map(|(_, r)| r.trans_rmse_m),
        "rpe_rot_rmse_deg": accuracy.as_ref().map(|(_, r)| r.rot_rmse_deg),
    });
    if args.json {
        println!("{summary}");
    } else {
        println!(
            "{total} frames ({tracked} tracked, {keyframes} keyframes) in {wall_s:.2} s: {fps:.1} frames/s end to end ({} {:?})",
            args.detector, args.pipeline
        );
        println!(
            "mean per frame: decode {:.1} ms (loader threads), detect {:.1} ms, match {:.1} ms, ransac {:.2} ms, refine {:.2} ms",
            mean(&stats, |s| s.decode_ms),
            mean(&stats, |s| s.detect_ms),
            mean(&stats, |s| s.match_ms),
            mean(&stats, |s| s.ransac_ms),
            mean(&stats, |s| s.refine_ms)
        );
        println!(
            "mean features {:.0}, matches {:.0}, inliers {:.0}",
            mean(&stats, |s| s.features as f64),
            mean(&stats, |s| s.matches as f64),
            mean(&stats, |s| s.inliers as f64)
        );
        if let Some((ate, rpe)) = &accuracy {
            println!(
                "ATE RMSE {:.2} cm (mean {:.2}, median {:.2}, max {:.2} cm; {} poses); RPE/frame {:.2} cm {:.3} deg",
                ate.rmse_m * 100.0,
                ate.mean_m * 100.0,
                ate.median_m * 100.0,
                ate.max_m * 100.0,
                ate.errors.len(),
                rpe.trans_rmse_m * 100.0,
                rpe.rot_rmse_deg
            );
        }
        println!("wrote {}", args.output.display());
    }
    Ok(ExitCode::SUCCESS)
}
