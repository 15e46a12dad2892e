//! The TUM RGB-D layout: `rgb.txt`/`depth.txt` lists, their association by timestamp, and
//! trajectories (`timestamp tx ty tz qx qy qz qw`, camera-to-world).
//!
//! Association follows TUM's `associate.py`: every pair closer than the limit is a candidate, the
//! closest candidates are taken first, each timestamp is used once, and pairs come out in time order.

use std::io::Write;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::VoError;

/// TUM's default association limit, s.
pub const DEFAULT_MAX_DT_S: f64 = 0.02;

/// One `timestamp filename` line of rgb.txt or depth.txt.
#[derive(Debug, Clone, PartialEq)]
pub struct ListEntry {
    /// Capture time, s.
    pub timestamp_s: f64,
    /// Path relative to the sequence folder.
    pub file: String,
}

/// An associated colour/depth pair; the frame's time is the colour image's.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePair {
    /// Colour capture time, s (the time the pose is reported at).
    pub timestamp_s: f64,
    /// Colour PNG, absolute or relative to the working directory.
    pub rgb: PathBuf,
    /// Depth capture time, s.
    pub depth_timestamp_s: f64,
    /// 16-bit depth PNG.
    pub depth: PathBuf,
}

/// A camera pose at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedPose {
    /// Time, s.
    pub timestamp_s: f64,
    /// Maps camera coordinates into the world frame.
    pub t_world_camera: Isometry3<f64>,
}

/// A TUM sequence folder, its frame pairs and optional ground truth.
#[derive(Debug, Clone)]
pub struct TumSequence {
    /// The folder.
    pub dir: PathBuf,
    /// Associated frames in time order.
    pub frames: Vec<FramePair>,
    /// `groundtruth.txt` when present.
    pub groundtruth: Option<PathBuf>,
}

impl TumSequence {
    /// Opens a folder: uses `associations.txt` when present, else associates rgb.txt with depth.txt
    /// within `max_dt_s`.
    pub fn open(dir: &Path, max_dt_s: f64) -> Result<Self, VoError> {
        if !dir.is_dir() {
            return Err(VoError::io(
                dir,
                std::io::Error::new(std::io::ErrorKind::NotFound, "not a sequence folder"),
            ));
        }
        let associations = dir.join("associations.txt");
        let frames = if associations.is_file() {
            parse_associations(&associations, &read(&associations)?)?
                .into_iter()
                .map(|p| FramePair {
                    rgb: dir.join(p.rgb),
                    depth: dir.join(p.depth),
                    ..p
                })
                .collect()
        } else {
            let rgb_path = dir.join("rgb.txt");
            let depth_path = dir.join("depth.txt");
            let rgb = parse_list(&rgb_path, &read(&rgb_path)?)?;
            let depth = parse_list(&depth_path, &read(&depth_path)?)?;
            associate(&rgb, &depth, max_dt_s)
                .into_iter()
                .map(|(i, j)| FramePair {
                    timestamp_s: rgb[i].timestamp_s,
                    rgb: dir.join(&rgb[i].file),
                    depth_timestamp_s: depth[j].timestamp_s,
                    depth: dir.join(&depth[j].file),
                })
                .collect()
        };
        let frames: Vec<FramePair> = frames;
        if frames.is_empty() {
            return Err(VoError::NoAssociations {
                dir: dir.display().to_string(),
                max_dt_s,
            });
        }
        let gt = dir.join("groundtruth.txt");
        Ok(TumSequence {
            dir: dir.to_path_buf(),
            frames,
            groundtruth: gt.is_file().then_some(gt),
        })
    }
}

/// The largest list or trajectory file read: an hour of ground truth at 100 Hz is about 30 MB.
pub const MAX_TEXT_BYTES: u64 = 256 << 20;

/// Reads a whole text file of at most [`MAX_TEXT_BYTES`], with its path in the error.
pub fn read(path: &Path) -> Result<String, VoError> {
    iw_file::read_text(path, MAX_TEXT_BYTES).map_err(|e| VoError::io(path, e))
}

/// Lines that carry data: 1-based number and fields, skipping blanks and `#` comments.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines().enumerate().filter_map(|(i, line)| {
        let line = line.trim();
        (!line.is_empty() && !line.starts_with('#')).then(|| {
            (
                i + 1,
                line.split([' ', '\t', ','])
                    .filter(|f| !f.is_empty())
                    .collect(),
            )
        })
    })
}

fn number(path: &Path, line: usize, field: &str, what: &str) -> Result<f64, VoError> {
    match field.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(VoError::parse(
            path,
            line,
            format!("{what} `{field}` is not a finite number"),
        )),
    }
}

/// Parses rgb.txt / depth.txt (`timestamp filename` lines); `path` only labels errors.
pub fn parse_list(path: &Path, text: &str) -> Result<Vec<ListEntry>, VoError> {
    let mut entries: Vec<ListEntry> = data_lines(text)
        .map(|(line, fields)| match fields.as_slice() {
            [t, file] => Ok(ListEntry {
                timestamp_s: number(path, line, t, "timestamp")?,
                file: file.to_string(),
            }),
            _ => Err(VoError::parse(
                path,
                line,
                format!("expected `timestamp filename`, got {} fields", fields.len()),
            )),
        })
        .collect::<Result<_, _>>()?;
    entries.sort_by(|a, b| a.timestamp_s.total_cmp(&b.timestamp_s));
    Ok(entries)
}

/// Parses associations.txt (`t_rgb rgb_file t_depth depth_file`); paths stay relative.
pub fn parse_associations(path: &Path, text: &str) -> Result<Vec<FramePair>, VoError> {
    data_lines(text)
        .map(|(line, fields)| match fields.as_slice() {
            [t_rgb, rgb, t_depth, depth] => Ok(FramePair {
                timestamp_s: number(path, line, t_rgb, "rgb timestamp")?,
                rgb: PathBuf::from(rgb),
                depth_timestamp_s: number(path, line, t_depth, "depth timestamp")?,
                depth: PathBuf::from(depth),
            }),
            _ => Err(VoError::parse(
                path,
                line,
                format!(
                    "expected `t_rgb rgb_file t_depth depth_file`, got {} fields",
                    fields.len()
                ),
            )),
        })
        .collect()
}

/// Greedy one-to-one nearest-timestamp association of two time-sorted lists (TUM `associate.py`):
/// index pairs `(a, b)` with `|t_a - t_b| < max_dt_s`, closest first, returned in `a` order.
pub fn associate(a: &[ListEntry], b: &[ListEntry], max_dt_s: f64) -> Vec<(usize, usize)> {
    associate_times(
        &a.iter().map(|e| e.timestamp_s).collect::<Vec<_>>(),
        &b.iter().map(|e| e.timestamp_s).collect::<Vec<_>>(),
        max_dt_s,
    )
}

/// [`associate`] on bare timestamps (both sorted ascending).
pub fn associate_times(a: &[f64], b: &[f64], max_dt_s: f64) -> Vec<(usize, usize)> {
    let mut candidates = Vec::new();
    for (i, &ta) in a.iter().enumerate() {
        let start = b.partition_point(|&tb| tb <= ta - max_dt_s);
        for (j, &tb) in b.iter().enumerate().skip(start) {
            if tb >= ta + max_dt_s {
                break;
            }
            candidates.push(((ta - tb).abs(), i, j));
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let (mut used_a, mut used_b) = (vec![false; a.len()], vec![false; b.len()]);
    let mut pairs = Vec::new();
    for (_, i, j) in candidates {
        if !used_a[i] && !used_b[j] {
            used_a[i] = true;
            used_b[j] = true;
            pairs.push((i, j));
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Parses a TUM trajectory (`timestamp tx ty tz qx qy qz qw`); `path` only labels errors.
pub fn parse_trajectory(path: &Path, text: &str) -> Result<Vec<StampedPose>, VoError> {
    let mut poses: Vec<StampedPose> = data_lines(text)
        .map(|(line, fields)| {
            if fields.len() != 8 {
                return Err(VoError::parse(
                    path,
                    line,
                    format!(
                        "expected `timestamp tx ty tz qx qy qz qw`, got {} fields",
                        fields.len()
                    ),
                ));
            }
            let mut v = [0.0; 8];
            for (slot, (field, what)) in v.iter_mut().zip(fields.iter().zip([
                "timestamp",
                "tx",
                "ty",
                "tz",
                "qx",
                "qy",
                "qz",
                "qw",
            ])) {
                *slot = number(path, line, field, what)?;
            }
            let q = Quaternion::new(v[7], v[4], v[5], v[6]);
            let length = q.norm();
            if length < 1e-6 {
                return Err(VoError::parse(path, line, "quaternion has zero length"));
            }
            // finite components whose squares overflow would normalise to zeros
            if !length.is_finite() {
                return Err(VoError::parse(
                    path,
                    line,
                    "quaternion's length overflows (a unit quaternion is expected)",
                ));
            }
            Ok(StampedPose {
                timestamp_s: v[0],
                t_world_camera: Isometry3::from_parts(
                    Translation3::new(v[1], v[2], v[3]),
                    UnitQuaternion::from_quaternion(q),
                ),
            })
        })
        .collect::<Result<_, _>>()?;
    poses.sort_by(|a, b| a.timestamp_s.total_cmp(&b.timestamp_s));
    Ok(poses)
}

/// Reads a TUM trajectory file.
pub fn read_trajectory(path: &Path) -> Result<Vec<StampedPose>, VoError> {
    parse_trajectory(path, &read(path)?)
}

/// Writes poses in TUM format, one line each, microsecond timestamps, 0.1 mm / 1e-7 precision.
pub fn write_trajectory(mut out: impl Write, poses: &[StampedPose]) -> std::io::Result<()> {
    for p in poses {
        let t = p.t_world_camera.translation.vector;
        let q = p.t_world_camera.rotation.into_inner();
        writeln!(
            out,
            "{:.6} {:.7} {:.7} {:.7} {:.7} {:.7} {:.7} {:.7}",
            p.timestamp_s, t.x, t.y, t.z, q.i, q.j, q.k, q.w
        )?;
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `f` on a thread and fails (instead of hanging the suite) if it blocks.
    fn within_seconds<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || tx.send(f()));
        rx.recv_timeout(std::time::Duration::from_secs(10))
            .expect("blocked: a FIFO was opened")
    }

    #[test]
    fn a_fifo_in_a_sequence_is_refused_not_waited_on() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("rgb.txt");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("SKIP: mkfifo is not available");
            return;
        }
        std::fs::write(dir.path().join("depth.txt"), "1.0 depth/1.png\n").unwrap();
        let seq_dir = dir.path().to_path_buf();
        let err = within_seconds(move || TumSequence::open(&seq_dir, 0.02).err()).unwrap();
        assert!(err.to_string().contains("not a regular file"), "{err}");

        // Named as an image in a frame pair: the loader refuses it too.
        let pair = FramePair {
            timestamp_s: 1.0,
            rgb: fifo,
            depth_timestamp_s: 1.0,
            depth: dir.path().join("depth.txt"),
        };
        let err = within_seconds(move || crate::source::load_pair(&pair).err()).unwrap();
        assert!(err.to_string().contains("not a regular file"), "{err}");
    }

    #[test]
    fn a_list_over_the_cap_is_refused_naming_it_unread() {
        let dir = tempfile::tempdir().unwrap();
        let list = dir.path().join("groundtruth.txt");
        // sparse: no disk is spent on the gigabyte
        std::fs::File::create(&list)
            .and_then(|f| f.set_len(4 * MAX_TEXT_BYTES))
            .unwrap();
        let err = read_trajectory(&list).unwrap_err().to_string();
        assert!(
            err.contains("groundtruth.txt") && err.contains("larger than"),
            "{err}"
        );
    }

    fn p() -> &'static Path {
        Path::new("x.txt")
    }

    #[test]
    fn association_is_greedy_one_to_one_and_bounded() {
        let a = [1.00, 1.03, 1.07, 2.0];
        let b = [1.005, 1.02, 1.065, 1.5];
        // 1.03 is 0.01 from 1.02 (closest), 1.00 gets 1.005, 1.07 gets 1.065, 2.0 has nothing.
        assert_eq!(associate_times(&a, &b, 0.02), vec![(0, 0), (1, 1), (2, 2)]);
        // A depth stamp is used once even when two rgb stamps want it.
        assert_eq!(associate_times(&[1.0, 1.01], &[1.006], 0.02), vec![(1, 0)]);
        assert!(
            associate_times(&[1.0], &[1.02], 0.02).is_empty(),
            "limit is exclusive"
        );
    }

    #[test]
    fn list_parse_skips_comments_and_reports_line() {
        let text = "# color images\n# timestamp filename\n1.5 rgb/1.5.png\n\n1.0 rgb/1.0.png\n";
        let list = parse_list(p(), text).expect("valid");
        assert_eq!(list.len(), 2);
        assert_eq!(list[0].file, "rgb/1.0.png", "sorted by time");
        let err = parse_list(p(), "# h\n1.0 a.png\nabc b.png\n").expect_err("bad timestamp");
        assert_eq!(
            err.to_string(),
            "x.txt:3: timestamp `abc` is not a finite number"
        );
        let err = parse_list(p(), "1.0\n").expect_err("one field");
        assert!(
            err.to_string()
                .starts_with("x.txt:1: expected `timestamp filename`"),
            "{err}"
        );
        assert!(parse_list(p(), "nan a.png").is_err());
    }

    #[test]
    fn trajectory_round_trips_and_rejects_bad_lines() {
        let poses = parse_trajectory(
            p(),
            "# gt\n1.0 1 2 3 0 0 0 1\n2.0 0.5 0 0 0 0.7071068 0 0.7071068\n",
        )
        .expect("valid");
        let mut out = Vec::new();
        write_trajectory(&mut out, &poses).expect("in memory");
        let again = parse_trajectory(p(), std::str::from_utf8(&out).expect("utf8"))
            .expect("own output parses");
        assert_eq!(again.len(), 2);
        for (a, b) in poses.iter().zip(&again) {
            assert!(
                (a.t_world_camera.inverse() * b.t_world_camera)
                    .translation
                    .vector
                    .norm()
                    < 1e-6
            );
            assert!(
                a.t_world_camera
                    .rotation
                    .angle_to(&b.t_world_camera.rotation)
                    < 1e-6
            );
        }
        let err = parse_trajectory(p(), "1 2 3\n").expect_err("short line");
        assert_eq!(
            err.to_string(),
            "x.txt:1: expected `timestamp tx ty tz qx qy qz qw`, got 3 fields"
        );
        let err = parse_trajectory(p(), "1 0 0 0 0 0 0 0\n").expect_err("zero quaternion");
        assert!(err.to_string().contains("zero length"), "{err}");
        // found by the `tum_text` fuzz target: a component of 6.7e179 was accepted and
        // normalised to a zero quaternion, which the writer wrote and the parser then refused
        let err = parse_trajectory(p(), "1 3 9 0 3 3 -6.7e179 8\n").expect_err("huge quaternion");
        assert!(err.to_string().contains("overflows"), "{err}");
        let err = parse_associations(p(), "1 a 2\n").expect_err("three fields");
        assert!(err.to_string().starts_with("x.txt:1:"), "{err}");
    }

    proptest::proptest! {
        #[test]
        fn parsers_never_panic(text in "\\PC{0,200}") {
            let _ = parse_list(p(), &text);
            let _ = parse_associations(p(), &text);
            let _ = parse_trajectory(p(), &text);
        }

        #[test]
        fn associations_are_within_limit_and_unique(
            mut a in proptest::collection::vec(0.0f64..2.0, 0..40),
            mut b in proptest::collection::vec(0.0f64..2.0, 0..40),
        ) {
            a.sort_by(f64::total_cmp);
            b.sort_by(f64::total_cmp);
            let pairs = associate_times(&a, &b, 0.02);
            let mut seen_b = std::collections::HashSet::new();
            for w in pairs.windows(2) { proptest::prop_assert!(w[0].0 < w[1].0); }
            for &(i, j) in &pairs {
                proptest::prop_assert!((a[i] - b[j]).abs() < 0.02);
                proptest::prop_assert!(seen_b.insert(j));
            }
        }
    }
}
