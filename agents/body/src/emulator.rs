//! The interface board emulated on a pseudo-terminal, so the real [`crate::SerialBody`] driver is
//! tested over a real tty.
//!
//! The emulated board is a small plant: each sensor request advances its clock by one control
//! period and integrates the last wheel speed references into encoder ticks (nominal geometry,
//! no errors), so runs are deterministic whatever the wall-clock timing. Sonar ranges are set
//! through the [`BoardHandle`]; faults are injected with [`BoardHandle::corrupt_next_reply`] and
//! [`BoardHandle::set_silent`].

use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};

use crate::protocol::{Decoder, Message, encode};
use crate::{BodyError, SONAR_COUNT, SensorFrame, WheelGeometry, WheelSpeeds};

/// What the emulated board holds.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardState {
    /// Board clock, ns.
    pub time_ns: u64,
    /// Cumulative ticks, left.
    pub left_ticks: i64,
    /// Cumulative ticks, right.
    pub right_ticks: i64,
    /// Sonar ranges the board will report.
    pub sonar_m: [Option<f64>; SONAR_COUNT],
    /// Last wheel speed references received.
    pub speeds: WheelSpeeds,
    /// Speed reference frames accepted.
    pub commands: u64,
    /// Frames the board rejected (bad checksum etc.).
    pub rejected: u64,
    /// Times the watchdog zeroed the speed references because none arrived in time.
    pub watchdog_stops: u64,
    /// Sub-tick remainder of the integration, per wheel.
    residual_ticks: (f64, f64),
    corrupt_next: bool,
    silent: bool,
}

/// Shared access to a running emulator's state.
#[derive(Debug, Clone)]
pub struct BoardHandle(Arc<Mutex<BoardState>>);

impl BoardHandle {
    fn lock(&self) -> MutexGuard<'_, BoardState> {
        // a panic in the emulator thread cannot leave the plain-data state half-written
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// A snapshot of the board state.
    pub fn state(&self) -> BoardState {
        self.lock().clone()
    }

    /// Sets the range the board reports for sonar `index` (0 = S1).
    pub fn set_sonar(&self, index: usize, range_m: Option<f64>) {
        if let Some(slot) = self.lock().sonar_m.get_mut(index) {
            *slot = range_m;
        }
    }

    /// Flips one payload bit in the next sensor frame sent, as line noise would.
    pub fn corrupt_next_reply(&self) {
        self.lock().corrupt_next = true;
    }

    /// Cuts the link (`true`) or restores it: while cut, the board drops every byte it is sent
    /// and answers nothing, as with a pulled cable, and its watchdog stops the wheels as on a
    /// real board.
    pub fn set_silent(&self, silent: bool) {
        self.lock().silent = silent;
    }
}

/// A running board emulator on the master side of a pseudo-terminal.
pub struct BoardEmulator {
    port_name: String,
    handle: BoardHandle,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    // held open so the pty stays up while drivers open and close the slave path
    _slave: TTYPort,
}

impl BoardEmulator {
    /// Opens a pty pair and serves the protocol on it; drivers open [`Self::port_name`].
    /// `period_ns` is how far the board clock advances per sensor request.
    pub fn spawn(geometry: WheelGeometry, period_ns: u64) -> Result<Self, BodyError> {
        Self::spawn_with_watchdog(geometry, period_ns, None)
    }

    /// As [`Self::spawn`], with the board's hardware watchdog: when no speed reference arrives
    /// for `watchdog` (wall-clock time, as on the board), the references drop to zero, so a
    /// chair whose computer died stops.
    pub fn spawn_with_watchdog(
        geometry: WheelGeometry,
        period_ns: u64,
        watchdog: Option<Duration>,
    ) -> Result<Self, BodyError> {
        Self::start(geometry, Pace::PerRequest(period_ns), watchdog)
    }

    /// A board that keeps real time, for a driver in another process running in real time (a
    /// deployment's chair container): it answers a sensor request no sooner than `period`
    /// after its last answer, as the board does, and its clock and encoders advance by the
    /// wall-clock time between answers. With the board's hardware watchdog, as
    /// [`Self::spawn_with_watchdog`].
    pub fn spawn_real_time(
        geometry: WheelGeometry,
        period: Duration,
        watchdog: Option<Duration>,
    ) -> Result<Self, BodyError> {
        Self::start(geometry, Pace::RealTime(period), watchdog)
    }

    fn start(
        geometry: WheelGeometry,
        pace: Pace,
        watchdog: Option<Duration>,
    ) -> Result<Self, BodyError> {
        let (mut master, slave) = TTYPort::pair().map_err(|source| BodyError::Port {
            port: "<pty pair>".to_string(),
            source,
        })?;
        let port_name = slave.name().unwrap_or_default();
        let handle = BoardHandle(Arc::new(Mutex::new(BoardState {
            time_ns: 0,
            left_ticks: 0,
            right_ticks: 0,
            sonar_m: [None; SONAR_COUNT],
            speeds: WheelSpeeds::STOP,
            commands: 0,
            rejected: 0,
            watchdog_stops: 0,
            residual_ticks: (0.0, 0.0),
            corrupt_next: false,
            silent: false,
        })));
        let stop = Arc::new(AtomicBool::new(false));
        let (thread_handle, thread_stop) = (handle.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("iw-board-emulator".into())
            .spawn(move || {
                serve(
                    &mut master,
                    &thread_handle,
                    &thread_stop,
                    geometry,
                    pace,
                    watchdog,
                )
            })
            .map_err(|source| BodyError::Io {
                port: port_name.clone(),
                source,
            })?;
        Ok(Self {
            port_name,
            handle,
            stop,
            thread: Some(thread),
            _slave: slave,
        })
    }

    /// The slave tty path a driver opens, e.g. `/dev/pts/3`.
    pub fn port_name(&self) -> &str {
        &self.port_name
    }

    /// Access to the board state.
    pub fn handle(&self) -> BoardHandle {
        self.handle.clone()
    }
}

impl Drop for BoardEmulator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join(); // the thread only ends by this flag or a dead pty
        }
    }
}

/// How the board's clock advances per sensor request.
#[derive(Debug, Clone, Copy)]
enum Pace {
    /// By this many ns, whenever it is asked (deterministic, for simulated time).
    PerRequest(u64),
    /// By the wall-clock time since the last answer, answering at most once per period.
    RealTime(Duration),
}

fn serve(
    master: &mut TTYPort,
    handle: &BoardHandle,
    stop: &AtomicBool,
    geometry: WheelGeometry,
    pace: Pace,
    watchdog: Option<Duration>,
) {
    let mut decoder = Decoder::new();
    let mut last_answer = Instant::now();
    let mut chunk = [0u8; 256];
    let mut last_reference = (Instant::now(), 0);
    while !stop.load(Ordering::Relaxed) {
        if let Some(limit) = watchdog {
            let mut state = handle.lock();
            if state.commands != last_reference.1 {
                last_reference = (Instant::now(), state.commands);
            } else if last_reference.0.elapsed() > limit && state.speeds != WheelSpeeds::STOP {
                state.speeds = WheelSpeeds::STOP;
                state.watchdog_stops += 1;
            }
        }
        match master.read(&mut chunk) {
            Ok(0) => continue,
            Ok(_) if handle.lock().silent => continue,
            Ok(n) => decoder.push(&chunk[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                continue;
            }
            Err(e) => {
                tracing::warn!(error = %e, "board emulator: pty closed");
                return;
            }
        }
        loop {
            let reply = match decoder.decode() {
                Ok(None) => break,
                Ok(Some(message)) => {
                    let period_ns = match (pace, &message) {
                        (Pace::PerRequest(ns), _) => ns,
                        (Pace::RealTime(period), Message::RequestSensors) => {
                            std::thread::sleep(
                                (last_answer + period).saturating_duration_since(Instant::now()),
                            );
                            let now = Instant::now();
                            let elapsed = now.duration_since(last_answer);
                            last_answer = now;
                            u64::try_from(elapsed.as_nanos()).unwrap_or(u64::MAX)
                        }
                        (Pace::RealTime(_), _) => 0,
                    };
                    answer(&mut handle.lock(), message, geometry, period_ns)
                }
                Err(e) => {
                    tracing::debug!(error = %e, "board emulator rejected a frame");
                    handle.lock().rejected += 1;
                    None
                }
            };
            if let Some(bytes) = reply
                && let Err(e) = master.write_all(&bytes).and_then(|()| master.flush())
            {
                tracing::warn!(error = %e, "board emulator: write failed");
                return;
            }
        }
    }
}

fn answer(
    state: &mut BoardState,
    message: Message,
    geometry: WheelGeometry,
    period_ns: u64,
) -> Option<Vec<u8>> {
    match message {
        Message::SpeedRef {
            left_mmps,
            right_mmps,
        } => {
            state.speeds = WheelSpeeds {
                left_mps: f64::from(left_mmps) / 1000.0,
                right_mps: f64::from(right_mmps) / 1000.0,
            };
            state.commands += 1;
            None
        }
        Message::RequestSensors => {
            let dt = period_ns as f64 * 1e-9;
            let per_tick = geometry.m_per_tick();
            let (rl, rr) = state.residual_ticks;
            let (dl, dr) = (
                rl + state.speeds.left_mps * dt / per_tick,
                rr + state.speeds.right_mps * dt / per_tick,
            );
            state.left_ticks += dl.trunc() as i64;
            state.right_ticks += dr.trunc() as i64;
            state.residual_ticks = (dl.fract(), dr.fract());
            state.time_ns += period_ns;
            let frame = SensorFrame {
                time_ns: state.time_ns,
                left_ticks: state.left_ticks,
                right_ticks: state.right_ticks,
                sonar_m: state.sonar_m,
                laser_m: Vec::new(),
                ranges_time_ns: state.time_ns,
                ticks_time_ns: state.time_ns,
            };
            let mut bytes = encode(&Message::Sensors(frame));
            if std::mem::take(&mut state.corrupt_next)
                && let Some(b) = bytes.get_mut(8)
            {
                *b ^= 0x10;
            }
            Some(bytes)
        }
        Message::Sensors(_) => {
            state.rejected += 1;
            None
        }
    }
}
