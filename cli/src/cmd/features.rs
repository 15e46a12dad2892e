//! `intellwheels features IMG [IMG2] --detector surf|ln-surf|lsac-surf|lsac-surf-nt (-o OUT.png | --json)`:
//! visual debugging of the detectors. The PNG shows hard features red, soft green, the circle's
//! diameter the keypoint size and a line its orientation; with two images, side by side with
//! their matches as yellow lines. `--json` prints one keypoint per line for other tools.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use image::{Rgb, RgbImage};
use iw_features::{DetectorConfig, DetectorKind, FeatureClass, Features, MatchConfig};

/// Flags of `intellwheels features`.
#[derive(clap::Args)]
pub struct Args {
    /// Image to detect on (PNG or JPEG; gray images are read as RGB).
    image: PathBuf,
    /// Second image: its features are matched against the first one's.
    image2: Option<PathBuf>,
    /// Detector: surf, ln-surf, lsac-surf or lsac-surf-nt.
    #[arg(long, default_value = "lsac-surf")]
    detector: DetectorKind,
    /// Output PNG with the features (and matches) drawn.
    #[arg(
        short = 'o',
        long = "output",
        conflicts_with = "json",
        required_unless_present = "json"
    )]
    output: Option<PathBuf>,
    /// Print the first image's keypoints as JSON lines instead of drawing:
    /// {"x","y","scale","size","orientation","response","class"}.
    #[arg(long, conflicts_with = "image2")]
    json: bool,
    /// Override the detector's response threshold (see `DetectorConfig::threshold`).
    #[arg(long)]
    threshold: Option<f32>,
    /// Override the noise-aware threshold's factor (see `DetectorConfig::noise_factor`; 0: off).
    #[arg(long)]
    noise_factor: Option<f32>,
    /// Override the contrast-normalised threshold (see `DetectorConfig::contrast_threshold`; 0: off).
    #[arg(long)]
    contrast_threshold: Option<f32>,
    /// Keep at most this many keypoints, in the detector's ranking order (see `DetectorConfig::max_keypoints`).
    #[arg(long)]
    max_keypoints: Option<usize>,
    /// Override the de-quantisation rounds before detection (see
    /// `DetectorConfig::dequantise_iterations`; 0: off).
    #[arg(long)]
    dequantise_iterations: Option<usize>,
    /// Skip orientation (U-SURF).
    #[arg(long)]
    upright: bool,
}

/// One keypoint as printed by `--json` (field order and names are a contract).
#[derive(serde::Serialize)]
struct JsonKeypoint {
    x: f32,
    y: f32,
    scale: f32,
    size: f32,
    orientation: f32,
    response: f32,
    class: FeatureClass,
}

/// Reads an image as 8-bit RGB, saying which file failed and why. Only a regular file is
/// opened (a FIFO blocks the open); the decoder's own limits bound what a header may ask for.
pub fn load_rgb(path: &Path) -> anyhow::Result<RgbImage> {
    let context = || format!("reading image {}", path.display());
    let file = iw_file::open_regular(path).with_context(context)?;
    let img = image::ImageReader::new(std::io::BufReader::new(file))
        .with_guessed_format()
        .with_context(context)?
        .decode()
        .with_context(context)?;
    Ok(img.to_rgb8())
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mut config = DetectorConfig::for_kind(args.detector);
    if let Some(t) = args.threshold {
        config.threshold = t;
    }
    if let Some(k) = args.noise_factor {
        config.noise_factor = k;
    }
    if let Some(c) = args.contrast_threshold {
        config.contrast_threshold = c;
    }
    if let Some(n) = args.dequantise_iterations {
        config.dequantise_iterations = n;
    }
    if args.max_keypoints.is_some() {
        config.max_keypoints = args.max_keypoints;
    }
    config.upright = args.upright;
    config.validate()?;
    let first = load_rgb(&args.image)?;
    let features = iw_features::detect(args.detector, &first, &config)?;
    if args.json {
        let stdout = std::io::stdout();
        let mut out = std::io::BufWriter::new(stdout.lock());
        for kp in &features.keypoints {
            let line = JsonKeypoint {
                x: kp.x,
                y: kp.y,
                scale: kp.scale,
                size: kp.size,
                orientation: kp.orientation,
                response: kp.response,
                class: kp.class,
            };
            // Serialize first so a closed stdout surfaces as an io::Error (a clean stop).
            let text = serde_json::to_string(&line)?;
            out.write_all(text.as_bytes())?;
            out.write_all(b"\n")?;
        }
        out.flush()?;
        return Ok(ExitCode::SUCCESS);
    }
    let Some(output) = args.output else {
        anyhow::bail!("give -o OUT.png or --json");
    };
    let canvas = match &args.image2 {
        None => {
            let mut canvas = first.clone();
            draw_features(&mut canvas, &features, 0);
            eprintln!(
                "{}: {} keypoints ({})",
                args.image.display(),
                features.keypoints.len(),
                args.detector
            );
            canvas
        }
        Some(path2) => {
            let second = load_rgb(path2)?;
            let features2 = iw_features::detect(args.detector, &second, &config)?;
            let matches =
                iw_features::match_features(&features, &features2, &MatchConfig::default());
            let offset = first.width();
            let mut canvas = RgbImage::new(
                first.width() + second.width(),
                first.height().max(second.height()),
            );
            image::imageops::replace(&mut canvas, &first, 0, 0);
            image::imageops::replace(&mut canvas, &second, i64::from(offset), 0);
            draw_features(&mut canvas, &features, 0);
            draw_features(&mut canvas, &features2, offset);
            for m in &matches {
                let (a, b) = (
                    &features.keypoints[m.query_index],
                    &features2.keypoints[m.train_index],
                );
                draw_line(
                    &mut canvas,
                    (a.x, a.y),
                    (b.x + offset as f32, b.y),
                    Rgb([255, 255, 0]),
                );
            }
            eprintln!(
                "{} keypoints, {} keypoints, {} matches ({})",
                features.keypoints.len(),
                features2.keypoints.len(),
                matches.len(),
                args.detector
            );
            canvas
        }
    };
    canvas
        .save(&output)
        .with_context(|| format!("writing {}", output.display()))?;
    Ok(ExitCode::SUCCESS)
}

/// Circles of the keypoint size, a radius toward the orientation; hard red, soft green.
fn draw_features(canvas: &mut RgbImage, features: &Features, x_offset: u32) {
    for kp in &features.keypoints {
        let colour = match kp.class {
            FeatureClass::Hard => Rgb([255, 0, 0]),
            FeatureClass::Soft => Rgb([0, 255, 0]),
        };
        let (cx, cy, r) = (kp.x + x_offset as f32, kp.y, kp.size / 2.0);
        let n = ((std::f32::consts::TAU * r) as usize).max(12);
        for k in 0..n {
            let (s, c) = (std::f32::consts::TAU * k as f32 / n as f32).sin_cos();
            put(canvas, cx + r * c, cy + r * s, colour);
        }
        let (s, c) = kp.orientation.sin_cos();
        draw_line(canvas, (cx, cy), (cx + r * c, cy + r * s), colour);
    }
}

fn put(canvas: &mut RgbImage, x: f32, y: f32, colour: Rgb<u8>) {
    let (x, y) = (x.round(), y.round());
    if x >= 0.0 && y >= 0.0 && (x as u32) < canvas.width() && (y as u32) < canvas.height() {
        canvas.put_pixel(x as u32, y as u32, colour);
    }
}

fn draw_line(canvas: &mut RgbImage, from: (f32, f32), to: (f32, f32), colour: Rgb<u8>) {
    let steps = (to.0 - from.0)
        .abs()
        .max((to.1 - from.1).abs())
        .ceil()
        .max(1.0) as usize;
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        put(
            canvas,
            from.0 + t * (to.0 - from.0),
            from.1 + t * (to.1 - from.1),
            colour,
        );
    }
}
