//! Where RGB-D frames come from: the [`CameraSource`] trait and its TUM replay, which decodes PNGs
//! on a pool of loader threads ahead of tracking (a bounded channel keeps memory flat).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, mpsc};
use std::thread::JoinHandle;

use image::{ImageBuffer, Luma, RgbImage};

use crate::tum::FramePair;
use crate::{Intrinsics, VoError};

/// A 16-bit depth image in raw sensor units (see [`Intrinsics::depth_units_per_m`]).
pub type DepthImage = ImageBuffer<Luma<u16>, Vec<u16>>;

/// One registered colour + depth frame.
#[derive(Debug, Clone)]
pub struct RgbdFrame {
    /// Capture time of the colour image, s.
    pub timestamp_s: f64,
    /// Colour image.
    pub rgb: RgbImage,
    /// Depth registered to the colour image's pixel grid.
    pub depth: DepthImage,
    /// Time spent decoding this frame on a loader thread, ms (0 for live sources).
    pub decode_ms: f64,
}

/// A stream of RGB-D frames: a replayed dataset, the simulator's camera, a real sensor.
pub trait CameraSource {
    /// Calibration of the frames this source yields.
    fn intrinsics(&self) -> &Intrinsics;
    /// The next frame in time order: `None` at the end, `Some(Err)` for a frame that could not be
    /// produced (the stream may continue).
    fn next_frame(&mut self) -> Option<Result<RgbdFrame, VoError>>;
    /// Number of frames still to come, when known.
    fn remaining(&self) -> Option<usize> {
        None
    }
}

/// Decodes one colour/depth pair, checking formats and that both images have the same size.
pub fn load_pair(pair: &FramePair) -> Result<RgbdFrame, VoError> {
    let started = std::time::Instant::now();
    let open = |path: &Path| {
        let file = iw_file::open_regular(path).map_err(|e| VoError::io(path, e))?;
        image::ImageReader::new(std::io::BufReader::new(file))
            .with_guessed_format()
            .map_err(|e| VoError::io(path, e))?
            .decode()
            .map_err(|source| VoError::Decode {
                path: path.display().to_string(),
                source,
            })
    };
    let rgb = open(&pair.rgb)?.into_rgb8();
    let depth = match open(&pair.depth)? {
        image::DynamicImage::ImageLuma16(d) => d,
        other => {
            return Err(VoError::Image {
                path: pair.depth.display().to_string(),
                reason: format!("depth must be 16-bit grey, got {:?}", other.color()),
            });
        }
    };
    if rgb.dimensions() != depth.dimensions() {
        return Err(VoError::Image {
            path: pair.depth.display().to_string(),
            reason: format!(
                "depth is {:?} but colour is {:?}; they must be registered",
                depth.dimensions(),
                rgb.dimensions()
            ),
        });
    }
    Ok(RgbdFrame {
        timestamp_s: pair.timestamp_s,
        rgb,
        depth,
        decode_ms: started.elapsed().as_secs_f64() * 1e3,
    })
}

/// Replays a TUM sequence: `threads` loaders decode frames ahead, at most `lookahead` waiting.
pub struct TumReplay {
    intrinsics: Intrinsics,
    total: usize,
    next: usize,
    receiver: Option<mpsc::Receiver<(usize, Result<RgbdFrame, VoError>)>>,
    pending: BTreeMap<usize, Result<RgbdFrame, VoError>>,
    stop: Arc<AtomicBool>,
    workers: Vec<JoinHandle<()>>,
}

impl TumReplay {
    /// Starts the loaders on `frames` (at least one thread, at least one frame of lookahead);
    /// fails, stopping the loaders already started, when the system refuses a thread.
    pub fn new(
        frames: Vec<FramePair>,
        intrinsics: Intrinsics,
        threads: usize,
        lookahead: usize,
    ) -> Result<Self, VoError> {
        let total = frames.len();
        let frames = Arc::new(frames);
        let cursor = Arc::new(AtomicUsize::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let (sender, receiver) = mpsc::sync_channel(lookahead.max(1));
        let mut replay = TumReplay {
            intrinsics,
            total,
            next: 0,
            receiver: Some(receiver),
            pending: BTreeMap::new(),
            stop,
            workers: Vec::new(),
        };
        for n in 0..threads.max(1) {
            let (frames, cursor, stop, sender) = (
                frames.clone(),
                cursor.clone(),
                replay.stop.clone(),
                sender.clone(),
            );
            let worker = std::thread::Builder::new()
                .name(format!("vo-loader-{n}"))
                .spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        let i = cursor.fetch_add(1, Ordering::Relaxed);
                        let Some(pair) = frames.get(i) else { break };
                        if sender.send((i, load_pair(pair))).is_err() {
                            break;
                        }
                    }
                })
                .map_err(|source| VoError::Threads {
                    requested: threads,
                    started: n,
                    source,
                })?;
            replay.workers.push(worker);
        }
        Ok(replay)
    }
}

impl CameraSource for TumReplay {
    fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    fn next_frame(&mut self) -> Option<Result<RgbdFrame, VoError>> {
        if self.next >= self.total {
            return None;
        }
        // Loaders finish out of order; hold early frames until their turn comes.
        while !self.pending.contains_key(&self.next) {
            let (i, frame) = self.receiver.as_ref()?.recv().ok()?;
            self.pending.insert(i, frame);
        }
        let frame = self.pending.remove(&self.next);
        self.next += 1;
        frame
    }

    fn remaining(&self) -> Option<usize> {
        Some(self.total - self.next)
    }
}

impl Drop for TumReplay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Dropping the receiver unblocks loaders waiting on a full channel.
        self.receiver = None;
        for worker in self.workers.drain(..) {
            let _ = worker.join();
        }
    }
}
