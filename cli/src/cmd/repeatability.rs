//! `intellwheels repeatability`: thesis 4.6, the repeatability of SURF, LN-SURF and LSAC-SURF
//! under illumination changes, reproduced on any folder of photographs.
//!
//! `--images DIR --out OUT`: every PNG/JPEG in DIR is relit with the LIC, LIS and LCC collections
//! (stored 8-bit, clipped and rounded); each detector's relit keypoints are scored against its
//! own keypoints on the unchanged image (`iw_features::experiment::repeatability`). Writes
//! `OUT/summary.json` (`{"lic"|"lis"|"lcc": {detector: {"median","mean","iqr","n"}}}`),
//! `OUT/statistics.json` (keypoint-count ratios, per-parameter medians, Wilcoxon signed-rank
//! tests between detectors), `OUT/rows.csv` (every measurement) and `OUT/boxplot.png`.
//!
//! `--pair A B --out OUT`: two photographs of one scene from a fixed camera under different real
//! light; `OUT/summary.json` is `{"pair": {detector: {"repeatability": %, "features": N}}}`
//! where N counts the keypoints of B (the denominator).
//!
//! `--sequence DIR --out OUT`: a real sequence with ground-truth homographies (see [`sequence`]).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use image::RgbImage;
use indicatif::{ProgressBar, ProgressStyle};
use iw_features::experiment::{Collection, Relight, Summary, repeatability};
use iw_features::{Detector, DetectorConfig, DetectorKind, Keypoint};
use iw_plot::boxplot::{BoxPanel, BoxSeries, plot_boxes};
use iw_stats::{Alternative, wilcoxon_signed_rank};
use rayon::prelude::*;
use serde_json::{Value, json};

use super::features::load_rgb;

mod sequence;

/// Flags of `intellwheels repeatability`.
#[derive(clap::Args)]
pub struct Args {
    /// Folder of photographs (PNG/JPEG) to relight with LIC, LIS and LCC.
    #[arg(
        long,
        required_unless_present_any = ["pair", "sequence"],
        conflicts_with_all = ["pair", "sequence"]
    )]
    images: Option<PathBuf>,
    /// Two photographs of one scene under different real light (reference first).
    #[arg(long, num_args = 2, value_names = ["A", "B"], conflicts_with = "sequence")]
    pair: Option<Vec<PathBuf>>,
    /// A real sequence: `img1..imgN` (PNG/JPEG/PPM) and `H1toKp`, the homography from img1 to
    /// imgK, 9 numbers row by row.
    #[arg(long)]
    sequence: Option<PathBuf>,
    /// Output folder (created if missing).
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    match (&args.images, &args.pair, &args.sequence) {
        (Some(dir), _, _) => run_collections(dir, &args.out),
        (None, Some(pair), _) => match pair.as_slice() {
            [a, b] => run_pair(a, b, &args.out),
            _ => anyhow::bail!("--pair takes exactly two images"),
        },
        (None, None, Some(dir)) => sequence::run_sequence(dir, &args.out),
        (None, None, None) => anyhow::bail!("give --images DIR, --pair A B or --sequence DIR"),
    }
}

fn detect(
    detector: &mut Detector,
    kind: DetectorKind,
    image: &RgbImage,
) -> anyhow::Result<Vec<Keypoint>> {
    Ok(detector
        .detect(kind, image, &DetectorConfig::for_kind(kind))?
        .keypoints)
}

fn write_json(path: &Path, value: &Value) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))
}

fn run_pair(a: &Path, b: &Path, out: &Path) -> anyhow::Result<ExitCode> {
    let (reference, relit) = (load_rgb(a)?, load_rgb(b)?);
    if reference.dimensions() != relit.dimensions() {
        anyhow::bail!(
            "--pair needs one scene from a fixed camera: {} is {:?} but {} is {:?}",
            a.display(),
            reference.dimensions(),
            b.display(),
            relit.dimensions()
        );
    }
    let mut detector = Detector::new();
    let mut pair = serde_json::Map::new();
    for kind in DetectorKind::ALL {
        let kr = detect(&mut detector, kind, &reference)?;
        let ki = detect(&mut detector, kind, &relit)?;
        let r = repeatability(&ki, &kr);
        println!(
            "{kind}: repeatability {r:.1} % over {} keypoints (reference {})",
            ki.len(),
            kr.len()
        );
        pair.insert(
            kind.name().into(),
            json!({"repeatability": r, "features": ki.len()}),
        );
    }
    write_json(&out.join("summary.json"), &json!({ "pair": pair }))?;
    Ok(ExitCode::SUCCESS)
}

/// One measurement: an image relit one way, scored for one detector.
struct Row {
    image: usize,
    kind: DetectorKind,
    collection: Collection,
    change: Relight,
    repeatability: f64,
    relit_keypoints: usize,
    reference_keypoints: usize,
}

fn list_images(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("listing {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        anyhow::bail!("no PNG or JPEG images in {}", dir.display());
    }
    Ok(files)
}

fn run_collections(dir: &Path, out: &Path) -> anyhow::Result<ExitCode> {
    let files = list_images(dir)?;
    let images: Vec<RgbImage> = files
        .iter()
        .map(|f| load_rgb(f))
        .collect::<anyhow::Result<_>>()?;
    let changes: Vec<(Collection, Relight)> = Collection::ALL
        .iter()
        .flat_map(|&c| c.changes().into_iter().map(move |r| (c, r)))
        .collect();
    let kinds = DetectorKind::ALL;
    let total = images.len() * kinds.len() * (1 + changes.len());
    let bar = ProgressBar::new(total as u64).with_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} detections ({eta} left)",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    // Phase 1: reference keypoints per image and detector.
    let reference_jobs: Vec<(usize, DetectorKind)> = (0..images.len())
        .flat_map(|i| kinds.iter().map(move |&k| (i, k)))
        .collect();
    let references: Vec<Vec<Keypoint>> = reference_jobs
        .par_iter()
        .map_init(Detector::new, |det, &(i, kind)| {
            let kps = detect(det, kind, &images[i]);
            bar.inc(1);
            kps
        })
        .collect::<anyhow::Result<_>>()?;
    // Phase 2: every relit version, scored against its reference.
    let jobs: Vec<(usize, usize, Collection, Relight)> = reference_jobs
        .iter()
        .enumerate()
        .flat_map(|(r, &(i, _))| changes.iter().map(move |&(c, change)| (r, i, c, change)))
        .collect();
    let rows: Vec<Row> = jobs
        .par_iter()
        .map_init(Detector::new, |det, &(r, i, collection, change)| {
            let kind = reference_jobs[r].1;
            let relit = detect(det, kind, &change.apply(&images[i]))?;
            bar.inc(1);
            Ok(Row {
                image: i,
                kind,
                collection,
                change,
                repeatability: repeatability(&relit, &references[r]),
                relit_keypoints: relit.len(),
                reference_keypoints: references[r].len(),
            })
        })
        .collect::<anyhow::Result<_>>()?;
    bar.finish_and_clear();
    write_outputs(out, &files, &rows)?;
    Ok(ExitCode::SUCCESS)
}

fn values(
    rows: &[Row],
    collection: Collection,
    kind: DetectorKind,
    f: impl Fn(&Row) -> f64,
) -> Vec<f64> {
    rows.iter()
        .filter(|r| r.collection == collection && r.kind == kind)
        .map(f)
        .collect()
}

/// Wilcoxon signed-rank test of `b - a` (normal approximation, as the thesis's detector tables):
/// `{n, w_plus, z, p_two_sided, p_greater}`, or null when no pair differs.
fn wilcoxon(a: &[f64], b: &[f64]) -> anyhow::Result<Value> {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let two = wilcoxon_signed_rank(b, a, Alternative::TwoSided)
        .context("Wilcoxon test of the repeatabilities")?;
    if two.n == 0 {
        return Ok(Value::Null);
    }
    let greater = wilcoxon_signed_rank(b, a, Alternative::Greater)
        .context("Wilcoxon test of the repeatabilities")?;
    Ok(
        json!({ "n": two.n, "w_plus": two.w_plus, "z": two.z, "p_two_sided": two.p_normal, "p_greater": greater.p_normal }),
    )
}

fn count_ratio(r: &Row) -> f64 {
    r.relit_keypoints as f64 / r.reference_keypoints.max(1) as f64
}

fn write_outputs(out: &Path, files: &[PathBuf], rows: &[Row]) -> anyhow::Result<()> {
    let mut summary = serde_json::Map::new();
    let mut statistics = serde_json::Map::new();
    let mut panels = Vec::new();
    println!(
        "{} images; median repeatability % [median keypoint-count ratio relit/reference]",
        files.len()
    );
    println!(
        "| collection | {} |",
        DetectorKind::ALL.map(|k| k.name()).join(" | ")
    );
    println!("|---|{}", "---|".repeat(DetectorKind::ALL.len()));
    for collection in Collection::ALL {
        let mut per_kind = serde_json::Map::new();
        let mut stats = serde_json::Map::new();
        let mut cells = Vec::new();
        let mut boxes = Vec::new();
        for kind in DetectorKind::ALL {
            let rep = values(rows, collection, kind, |r| r.repeatability);
            let ratios = values(rows, collection, kind, count_ratio);
            let s = Summary::of(&rep);
            let ratio = Summary::of(&ratios);
            per_kind.insert(
                kind.name().into(),
                json!({"median": s.median, "mean": s.mean, "iqr": s.iqr, "n": s.n}),
            );
            let mut by_parameter = BTreeMap::new();
            for change in collection.changes() {
                let at: Vec<f64> = rows
                    .iter()
                    .filter(|r| r.collection == collection && r.kind == kind && r.change == change)
                    .map(|r| r.repeatability)
                    .collect();
                let ratio_at: Vec<f64> = rows
                    .iter()
                    .filter(|r| r.collection == collection && r.kind == kind && r.change == change)
                    .map(count_ratio)
                    .collect();
                by_parameter.insert(
                    format!("{:.3}", change.parameter()),
                    json!({"median": Summary::of(&at).median, "count_ratio_median": Summary::of(&ratio_at).median}),
                );
            }
            stats.insert(
                kind.name().into(),
                json!({"repeatability": s, "count_ratio": ratio, "by_parameter": by_parameter}),
            );
            cells.push(format!("{:.1} [{:.2}]", s.median, ratio.median));
            boxes.push(BoxSeries {
                label: kind.name().into(),
                values: rep,
            });
        }
        let mut tests = serde_json::Map::new();
        for (a, b) in [
            (DetectorKind::Surf, DetectorKind::LnSurf),
            (DetectorKind::Surf, DetectorKind::LsacSurf),
            (DetectorKind::LnSurf, DetectorKind::LsacSurf),
            (DetectorKind::LsacSurf, DetectorKind::LsacSurfNt),
        ] {
            let w = wilcoxon(
                &values(rows, collection, a, |r| r.repeatability),
                &values(rows, collection, b, |r| r.repeatability),
            )?;
            tests.insert(format!("{} - {}", b.name(), a.name()), w);
        }
        stats.insert("wilcoxon".into(), Value::Object(tests));
        println!(
            "| {} | {} |",
            collection.name().to_uppercase(),
            cells.join(" | ")
        );
        summary.insert(collection.name().into(), Value::Object(per_kind));
        statistics.insert(collection.name().into(), Value::Object(stats));
        panels.push(BoxPanel {
            caption: collection.name().to_uppercase(),
            boxes,
        });
    }
    statistics.insert(
        "images".into(),
        json!(
            files
                .iter()
                .map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()))
                .collect::<Vec<_>>()
        ),
    );
    write_json(&out.join("summary.json"), &Value::Object(summary))?;
    write_json(&out.join("statistics.json"), &Value::Object(statistics))?;
    let csv_path = out.join("rows.csv");
    let mut csv = std::io::BufWriter::new(
        std::fs::File::create(&csv_path)
            .with_context(|| format!("writing {}", csv_path.display()))?,
    );
    writeln!(
        csv,
        "image,detector,collection,parameter,repeatability,relit_keypoints,reference_keypoints"
    )?;
    for r in rows {
        let name = files
            .get(r.image)
            .and_then(|f| f.file_name())
            .map(|n| n.to_string_lossy())
            .unwrap_or_default();
        writeln!(
            csv,
            "{name},{},{},{},{:.3},{},{}",
            r.kind,
            r.collection.name(),
            r.change.parameter(),
            r.repeatability,
            r.relit_keypoints,
            r.reference_keypoints
        )?;
    }
    csv.flush()?;
    plot_boxes(
        &out.join("boxplot.png"),
        &format!(
            "Repeatability under illumination changes ({} images)",
            files.len()
        ),
        "repeatability (%)",
        0.0..100.0,
        &panels,
    )?;
    println!(
        "wrote {}/summary.json, statistics.json, rows.csv, boxplot.png",
        out.display()
    );
    Ok(())
}
