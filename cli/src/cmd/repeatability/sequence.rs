//! `intellwheels repeatability --sequence DIR --out OUT`: the thesis's repeatability protocol on a
//! real sequence, `img1..imgN` plus `H1toKp` (the homography from img1 to imgK), every detector
//! (`iw_features::sequence`).
//!
//! Before scoring, the homographies' pixel convention is checked against the detectors' own
//! descriptor matches: the residuals of all matches within 5 px are compared with the matrices
//! read as 0-based, corner-based (0.5) and 1-based; the origin with the smallest median residual
//! over the whole sequence is used and reported.
//!
//! Writes `OUT/summary.json` (`sequence`, `images`, `pixel_convention`, `pairs`: one object per
//! detector and image with the fields of `iw_features::sequence::PairScore`, `summary`: by
//! detector) and `OUT/sequence.png` (box plots of the three rates over the pairs).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use image::RgbImage;
use indicatif::{ProgressBar, ProgressStyle};
use iw_features::experiment::Summary;
use iw_features::homography::{Homography, MAX_TEXT_BYTES};
use iw_features::sequence::{PairScore, origin_residuals, score_pair};
use iw_features::{
    Detector, DetectorConfig, DetectorKind, Features, Match, MatchConfig, match_features,
};
use iw_plot::boxplot::{BoxPanel, BoxSeries, plot_boxes};
use rayon::prelude::*;
use serde_json::{Value, json};

use super::write_json;
use crate::cmd::features::load_rgb;

/// Pixel origins the homographies may have been estimated with (see
/// `Homography::with_pixel_origin`).
const ORIGINS: [f64; 3] = [0.0, 0.5, 1.0];

/// Image file extensions a sequence may use.
const EXTENSIONS: [&str; 5] = ["png", "jpg", "jpeg", "ppm", "pgm"];

/// A loaded sequence: `images[0]` is the reference, `homographies[k]` maps it onto
/// `images[k + 1]`.
pub(super) struct Sequence {
    pub(super) name: String,
    pub(super) files: Vec<PathBuf>,
    pub(super) images: Vec<RgbImage>,
    pub(super) homographies: Vec<(PathBuf, Homography)>,
}

/// The index K of a file named `imgK.<ext>`, if it is one.
fn image_index(path: &Path) -> Option<usize> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    if !EXTENSIONS.contains(&ext.as_str()) {
        return None;
    }
    let digits = path.file_stem()?.to_str()?.strip_prefix("img")?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

fn read_homography(path: &Path) -> anyhow::Result<Homography> {
    // A regular file of at most a 3x3 matrix's text: a FIFO or device is refused, not read.
    let text = iw_sim::file::read_text(path, MAX_TEXT_BYTES as u64)
        .with_context(|| format!("reading homography {}", path.display()))?;
    Homography::parse(&text).with_context(|| format!("homography {}", path.display()))
}

/// Lists, reads and checks a sequence folder: images `img1..imgN` numbered without gaps, all of
/// img1's size, and a readable, invertible `H1toKp` for every K >= 2.
pub(super) fn load_sequence(dir: &Path) -> anyhow::Result<Sequence> {
    let mut numbered: Vec<(usize, PathBuf)> = std::fs::read_dir(dir)
        .with_context(|| format!("listing sequence folder {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter_map(|p| image_index(&p).map(|k| (k, p)))
        .collect();
    numbered.sort();
    if let Some(w) = numbered.windows(2).find(|w| w[0].0 == w[1].0) {
        anyhow::bail!(
            "two images with number {}: {} and {}",
            w[0].0,
            w[0].1.display(),
            w[1].1.display()
        );
    }
    for (expected, (k, path)) in (1..).zip(&numbered) {
        if *k != expected {
            anyhow::bail!(
                "{}: img{expected} is missing (images must be numbered 1..N)",
                path.display()
            );
        }
    }
    if numbered.len() < 2 {
        anyhow::bail!(
            "{} holds {} image(s) named imgK.png/.jpg/.ppm; a sequence needs img1 and at least img2",
            dir.display(),
            numbered.len()
        );
    }
    let files: Vec<PathBuf> = numbered.into_iter().map(|(_, p)| p).collect();
    let images: Vec<RgbImage> = files
        .iter()
        .map(|f| load_rgb(f))
        .collect::<anyhow::Result<_>>()?;
    let size = images[0].dimensions();
    for (file, image) in files.iter().zip(&images).skip(1) {
        if image.dimensions() != size {
            anyhow::bail!(
                "{} is {}x{} but {} is {}x{}: a sequence's images must have one size",
                file.display(),
                image.width(),
                image.height(),
                files[0].display(),
                size.0,
                size.1
            );
        }
    }
    let homographies = (2..=files.len())
        .map(|k| {
            let path = dir.join(format!("H1to{k}p"));
            read_homography(&path).map(|h| (path, h))
        })
        .collect::<anyhow::Result<_>>()?;
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| dir.display().to_string());
    Ok(Sequence {
        name,
        files,
        images,
        homographies,
    })
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The pixel origin whose median residual is smallest, with the JSON that documents the check.
fn choose_origin(residuals: &[Vec<f64>]) -> (f64, Value) {
    let medians: Vec<f64> = residuals.iter().map(|r| Summary::of(r).median).collect();
    let chosen = ORIGINS
        .iter()
        .zip(&medians)
        .filter(|_| residuals.first().is_some_and(|r| !r.is_empty()))
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0.0, |(o, _)| *o);
    let candidates: Vec<Value> = ORIGINS
        .iter()
        .zip(residuals)
        .map(|(o, r)| {
            let s = Summary::of(r);
            json!({"origin_px": o, "median_residual_px": s.median, "mean_residual_px": s.mean})
        })
        .collect();
    let n = residuals.first().map_or(0, Vec::len);
    (
        chosen,
        json!({"origin_px": chosen, "matches": n, "candidates": candidates}),
    )
}

fn progress(total: usize) -> ProgressBar {
    ProgressBar::new(total as u64).with_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {msg} ({eta} left)")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    )
}

pub(super) fn run_sequence(dir: &Path, out: &Path) -> anyhow::Result<ExitCode> {
    let seq = load_sequence(dir)?;
    let kinds = DetectorKind::ALL;
    let n = seq.images.len();
    let bar = progress(kinds.len() * (2 * n - 1));
    bar.set_message("detections and matchings");
    let jobs: Vec<(DetectorKind, usize)> = kinds
        .iter()
        .flat_map(|&k| (0..n).map(move |i| (k, i)))
        .collect();
    let features: Vec<Features> = jobs
        .par_iter()
        .map_init(Detector::new, |det, &(kind, i)| {
            let f = det.detect(kind, &seq.images[i], &DetectorConfig::for_kind(kind));
            bar.inc(1);
            f
        })
        .collect::<Result<_, _>>()?;
    let of = |kind_index: usize, i: usize| &features[kind_index * n + i];
    let pair_jobs: Vec<(usize, usize)> = (0..kinds.len())
        .flat_map(|k| (1..n).map(move |i| (k, i)))
        .collect();
    let matches: Vec<Vec<Match>> = pair_jobs
        .par_iter()
        .map(|&(k, i)| {
            let m = match_features(of(k, 0), of(k, i), &MatchConfig::default());
            bar.inc(1);
            m
        })
        .collect();
    bar.finish_and_clear();
    // The pixel convention, from every detector's matches over the whole sequence.
    let mut residuals = vec![Vec::new(); ORIGINS.len()];
    for (&(k, i), m) in pair_jobs.iter().zip(&matches) {
        let (_, h) = &seq.homographies[i - 1];
        let r = origin_residuals(&of(k, 0).keypoints, &of(k, i).keypoints, h, m, &ORIGINS);
        for (all, r) in residuals.iter_mut().zip(r) {
            all.extend(r);
        }
    }
    let (origin, convention) = choose_origin(&residuals);
    let size = seq.images[0].dimensions();
    let scores: Vec<PairScore> = pair_jobs
        .iter()
        .zip(&matches)
        .map(|(&(k, i), m)| {
            let h = seq.homographies[i - 1].1.with_pixel_origin(origin);
            score_pair(&of(k, 0).keypoints, size, &of(k, i).keypoints, size, &h, m)
        })
        .collect();
    write_sequence_outputs(out, &seq, &kinds, &pair_jobs, &scores, convention)?;
    Ok(ExitCode::SUCCESS)
}

fn stats(values: &[f64]) -> Value {
    let s = Summary::of(values);
    json!({"mean": s.mean, "median": s.median, "iqr": s.iqr, "n": s.n})
}

fn write_sequence_outputs(
    out: &Path,
    seq: &Sequence,
    kinds: &[DetectorKind],
    pair_jobs: &[(usize, usize)],
    scores: &[PairScore],
    convention: Value,
) -> anyhow::Result<()> {
    let mut pairs = Vec::new();
    for (&(k, i), s) in pair_jobs.iter().zip(scores) {
        let mut row = serde_json::to_value(s)?;
        if let Value::Object(map) = &mut row {
            map.insert("detector".into(), json!(kinds[k].name()));
            map.insert("image".into(), json!(file_name(&seq.files[i])));
            map.insert(
                "homography".into(),
                json!(file_name(&seq.homographies[i - 1].0)),
            );
        }
        pairs.push(row);
    }
    let mut summary = serde_json::Map::new();
    let metric_names = [
        "R = C / m_i (%)",
        "R = C / min(m_1, m_i) (%)",
        "matching score (%)",
    ];
    let mut panels: Vec<BoxPanel> = metric_names
        .iter()
        .map(|c| BoxPanel {
            caption: (*c).into(),
            boxes: Vec::new(),
        })
        .collect();
    println!(
        "{}: {} images, homography pixel origin {} px; mean over pairs",
        seq.name,
        seq.images.len(),
        convention["origin_px"]
    );
    println!(
        "| detector | R = C/m_i | R = C/min | matching score | keypoints img1 | count ratio min-max |"
    );
    println!("|---|---|---|---|---|---|");
    for (k, kind) in kinds.iter().enumerate() {
        let rows: Vec<&PairScore> = pair_jobs
            .iter()
            .zip(scores)
            .filter(|((kk, _), _)| *kk == k)
            .map(|(_, s)| s)
            .collect();
        let metrics: [Vec<f64>; 3] = [
            rows.iter().map(|s| s.repeatability).collect(),
            rows.iter().map(|s| s.repeatability_symmetric).collect(),
            rows.iter().map(|s| s.matching_score).collect(),
        ];
        let reference = rows.first().map_or(0, |s| s.reference_keypoints_total);
        let ratios: Vec<f64> = rows
            .iter()
            .map(|s| s.keypoints_total as f64 / reference.max(1) as f64)
            .collect();
        let (lo, hi) = ratios
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &r| {
                (lo.min(r), hi.max(r))
            });
        summary.insert(
            kind.name().into(),
            json!({
                "repeatability": stats(&metrics[0]),
                "repeatability_symmetric": stats(&metrics[1]),
                "matching_score": stats(&metrics[2]),
                "reference_keypoints_total": reference,
                "count_ratio_min": lo,
                "count_ratio_max": hi,
            }),
        );
        let mean = |v: &[f64]| Summary::of(v).mean;
        println!(
            "| {kind} | {:.1} | {:.1} | {:.1} | {reference} | {lo:.2}-{hi:.2} |",
            mean(&metrics[0]),
            mean(&metrics[1]),
            mean(&metrics[2])
        );
        for (panel, values) in panels.iter_mut().zip(metrics) {
            panel.boxes.push(BoxSeries {
                label: kind.name().into(),
                values,
            });
        }
    }
    let doc = json!({
        "sequence": seq.name,
        "images": seq.files.iter().map(|f| file_name(f)).collect::<Vec<_>>(),
        "pixel_convention": convention,
        "pairs": pairs,
        "summary": summary,
    });
    write_json(&out.join("summary.json"), &doc)?;
    plot_boxes(
        &out.join("sequence.png"),
        &format!(
            "{}: {} pairs with ground-truth homographies",
            seq.name,
            seq.images.len() - 1
        ),
        "%",
        0.0..100.0,
        &panels,
    )?;
    println!("wrote {}/summary.json, sequence.png", out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(width: u32, height: u32) -> RgbImage {
        RgbImage::from_fn(width, height, |x, y| {
            let v = ((x * 7 + y * 13) % 97 + (x * y) % 31) as u8;
            image::Rgb([v, v.wrapping_add(20), v / 2])
        })
    }

    /// A valid three-image sequence in a fresh folder.
    fn sequence_dir() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for k in 1..=3 {
            textured(64, 48)
                .save(dir.path().join(format!("img{k}.png")))
                .unwrap();
        }
        for k in 2..=3 {
            std::fs::write(
                dir.path().join(format!("H1to{k}p")),
                "1 0 2\r\n0 1 1\r\n0 0 1\r\n",
            )
            .unwrap();
        }
        std::fs::write(dir.path().join("README.md"), "not an image, ignored").unwrap();
        dir
    }

    fn error_of(dir: &Path) -> String {
        match load_sequence(dir) {
            Ok(_) => panic!("expected an error for {}", dir.display()),
            Err(e) => format!("{e:#}"),
        }
    }

    #[test]
    fn a_valid_sequence_loads() {
        let dir = sequence_dir();
        let seq = load_sequence(dir.path()).unwrap();
        assert_eq!((seq.images.len(), seq.homographies.len()), (3, 2));
        assert_eq!(seq.homographies[0].1.map(0.0, 0.0), Some((2.0, 1.0)));
    }

    #[test]
    fn a_missing_homography_is_named() {
        let dir = sequence_dir();
        std::fs::remove_file(dir.path().join("H1to3p")).unwrap();
        let e = error_of(dir.path());
        assert!(
            e.contains("reading homography") && e.contains("H1to3p"),
            "{e}"
        );
    }

    #[test]
    fn a_device_or_folder_as_a_homography_is_refused_unread() {
        let dir = sequence_dir();
        let h = dir.path().join("H1to2p");
        std::fs::remove_file(&h).unwrap();
        // `/dev/zero` never ends: it was read until memory ran out.
        std::os::unix::fs::symlink("/dev/zero", &h).unwrap();
        let e = error_of(dir.path());
        assert!(
            e.contains("H1to2p") && e.contains("not a regular file"),
            "{e}"
        );
        std::fs::remove_file(&h).unwrap();
        std::fs::create_dir(&h).unwrap();
        let e = error_of(dir.path());
        assert!(
            e.contains("H1to2p") && e.contains("not a regular file"),
            "{e}"
        );
    }

    #[test]
    fn a_singular_homography_is_named() {
        let dir = sequence_dir();
        std::fs::write(dir.path().join("H1to2p"), "1 2 3\n2 4 6\n0 0 1\n").unwrap();
        let e = error_of(dir.path());
        assert!(e.contains("H1to2p") && e.contains("singular"), "{e}");
    }

    #[test]
    fn a_malformed_homography_is_named() {
        let dir = sequence_dir();
        std::fs::write(dir.path().join("H1to2p"), "1 0 0\n0 1 0\n").unwrap();
        let e = error_of(dir.path());
        assert!(
            e.contains("H1to2p") && e.contains("expected 9 numbers"),
            "{e}"
        );
    }

    #[test]
    fn images_of_different_sizes_are_named() {
        let dir = sequence_dir();
        textured(50, 48).save(dir.path().join("img2.png")).unwrap();
        let e = error_of(dir.path());
        assert!(e.contains("img2.png") && e.contains("one size"), "{e}");
    }

    #[test]
    fn a_non_image_file_is_named() {
        let dir = sequence_dir();
        std::fs::write(dir.path().join("img3.png"), "this is text, not a PNG").unwrap();
        let e = error_of(dir.path());
        assert!(e.contains("img3.png"), "{e}");
    }

    #[test]
    fn a_gap_or_a_lone_image_is_refused() {
        let dir = sequence_dir();
        std::fs::remove_file(dir.path().join("img2.png")).unwrap();
        let e = error_of(dir.path());
        assert!(e.contains("img2 is missing"), "{e}");
        let lone = tempfile::tempdir().unwrap();
        textured(8, 8).save(lone.path().join("img1.png")).unwrap();
        let e = error_of(lone.path());
        assert!(e.contains("at least img2"), "{e}");
        let e = error_of(&lone.path().join("absent"));
        assert!(e.contains("listing sequence folder"), "{e}");
    }

    #[test]
    fn a_sequence_run_writes_pairs_and_summary() {
        let dir = sequence_dir();
        let out = tempfile::tempdir().unwrap();
        run_sequence(dir.path(), out.path()).unwrap();
        let text = std::fs::read_to_string(out.path().join("summary.json")).unwrap();
        let doc: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            doc["pairs"].as_array().unwrap().len(),
            2 * DetectorKind::ALL.len()
        );
        for kind in DetectorKind::ALL {
            assert!(doc["summary"][kind.name()]["repeatability"]["mean"].is_number());
        }
        assert!(out.path().join("sequence.png").exists());
    }
}
