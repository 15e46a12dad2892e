//! [`BodyWorker`]: a body's blocking I/O on its own thread, so a control period never waits for
//! the serial link (a read blocks up to the board timeout, 200 ms, while a period is 50 ms).
//!
//! The worker reads the inner body in a loop and keeps the newest frame; between reads it sends
//! the newest wheel command. The hand-over is a slot of one in each direction (a bounded channel
//! that keeps the newest): a late command or frame is replaced, never queued.

use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::{Body, BodyError, SensorFrame, SharedBodyError, WheelSpeeds};

/// Pause after a failed read before the next.
const FAILED_READ_PAUSE: Duration = Duration::from_millis(10);

/// What the control side and the worker share.
#[derive(Default)]
struct Slots {
    /// The newest frame and when it arrived, or why the last read failed.
    frame: Option<(Result<SensorFrame, SharedBodyError>, Instant)>,
    /// The newest command not yet sent.
    command: Option<WheelSpeeds>,
    /// Why the last command sent failed, until reported.
    command_error: Option<BodyError>,
    stop: bool,
}

/// A [`Body`] whose `read` and `command` return at once; the inner body runs on a thread.
pub struct BodyWorker {
    shared: Arc<Mutex<Slots>>,
    max_age: Duration,
    thread: Option<JoinHandle<()>>,
}

impl BodyWorker {
    /// Starts the worker on `body`; [`Body::read`] refuses frames older than `max_age`.
    pub fn start<B: Body + Send + 'static>(
        mut body: B,
        max_age: Duration,
    ) -> Result<Self, BodyError> {
        let shared = Arc::new(Mutex::new(Slots::default()));
        let slots = shared.clone();
        let thread = std::thread::Builder::new()
            .name("body-io".into())
            .spawn(move || {
                loop {
                    let command = {
                        let mut s = slots.lock().unwrap_or_else(PoisonError::into_inner);
                        if s.stop {
                            break;
                        }
                        s.command.take()
                    };
                    if let Some(speeds) = command
                        && let Err(err) = body.command(speeds)
                    {
                        let mut s = slots.lock().unwrap_or_else(PoisonError::into_inner);
                        s.command_error = Some(err);
                    }
                    let frame = body.read().map_err(SharedBodyError::from);
                    let failed = frame.is_err();
                    slots.lock().unwrap_or_else(PoisonError::into_inner).frame =
                        Some((frame, Instant::now()));
                    if failed {
                        // A link that fails at once (a closed port) must not spin a core.
                        std::thread::sleep(FAILED_READ_PAUSE);
                    }
                }
                // Last words: the wheels are stopped whatever was pending.
                let _ = body.stop();
            })
            .map_err(|source| BodyError::Thread { source })?;
        Ok(BodyWorker {
            shared,
            max_age,
            thread: Some(thread),
        })
    }

    fn slots(&self) -> std::sync::MutexGuard<'_, Slots> {
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Body for BodyWorker {
    /// The newest frame the worker read, without waiting; an error when the last read failed
    /// or the newest frame is older than `max_age`.
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        let max_age = self.max_age;
        match &self.slots().frame {
            None => Err(BodyError::Worker {
                reason: "no sensor frame read yet".into(),
            }),
            Some((_, at)) if at.elapsed() > max_age => Err(BodyError::Worker {
                reason: format!(
                    "newest sensor frame is {} ms old (limit {} ms): the link is stalled",
                    at.elapsed().as_millis(),
                    max_age.as_millis()
                ),
            }),
            Some((Ok(frame), _)) => Ok(frame.clone()),
            Some((Err(source), _)) => Err(BodyError::Link {
                source: source.clone(),
            }),
        }
    }

    /// Hands `speeds` to the worker (replacing a command not yet sent); reports the failure of
    /// the previous command, if it failed.
    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        let mut slots = self.slots();
        slots.command = Some(speeds);
        match slots.command_error.take() {
            Some(err) => Err(BodyError::Link { source: err.into() }),
            None => Ok(()),
        }
    }
}

impl Drop for BodyWorker {
    fn drop(&mut self) {
        self.slots().stop = true;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::mpsc;

    use super::*;

    /// A body whose every read waits for the test to release it, as a silent link blocks.
    struct Gated {
        reads: mpsc::Receiver<()>,
        commands: mpsc::Sender<WheelSpeeds>,
        fail_commands: bool,
    }

    impl Body for Gated {
        fn read(&mut self) -> Result<SensorFrame, BodyError> {
            self.reads.recv().map_err(|_| BodyError::Worker {
                reason: "gate closed".into(),
            })?;
            Ok(SensorFrame::empty(7))
        }
        fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
            let _ = self.commands.send(speeds);
            if self.fail_commands {
                return Err(BodyError::Worker {
                    reason: "board refused".into(),
                });
            }
            Ok(())
        }
    }

    fn gated(fail_commands: bool) -> (BodyWorker, mpsc::Sender<()>, mpsc::Receiver<WheelSpeeds>) {
        let (release, reads) = mpsc::channel();
        let (commands, sent) = mpsc::channel();
        let body = Gated {
            reads,
            commands,
            fail_commands,
        };
        let worker = BodyWorker::start(body, Duration::from_secs(60)).unwrap();
        (worker, release, sent)
    }

    #[test]
    fn reads_and_commands_never_wait_for_a_blocked_link() {
        let (mut worker, release, sent) = gated(false);
        // The inner read is blocked: the worker answers at once that nothing came yet.
        let err = worker.read().unwrap_err().to_string();
        assert!(err.contains("no sensor frame read yet"), "{err}");
        worker.command(WheelSpeeds::STOP).unwrap();
        // Once a frame arrives, reads return it, still without waiting.
        release.send(()).unwrap();
        let deadline = Instant::now() + Duration::from_secs(10);
        let frame = loop {
            match worker.read() {
                Ok(frame) => break frame,
                Err(_) if Instant::now() < deadline => std::thread::yield_now(),
                Err(e) => panic!("no frame handed over: {e}"),
            }
        };
        assert_eq!(frame, SensorFrame::empty(7));
        release.send(()).unwrap();
        assert_eq!(
            sent.recv().unwrap(),
            WheelSpeeds::STOP,
            "the command reached the body"
        );
        // Dropping stops the worker (it stops the wheels on its way out).
        drop(release);
        drop(worker);
    }

    #[test]
    fn a_failed_command_is_reported_on_the_next() {
        let (mut worker, release, sent) = gated(true);
        let speeds = WheelSpeeds {
            left_mps: 0.1,
            right_mps: 0.1,
        };
        worker.command(speeds).unwrap();
        release.send(()).unwrap();
        assert_eq!(sent.recv().unwrap(), speeds);
        // Wait until the worker has recorded the failure (it reads after commanding).
        release.send(()).unwrap();
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            match worker.command(WheelSpeeds::STOP) {
                Err(e) => {
                    assert!(e.to_string().contains("board refused"), "{e}");
                    // the body's own error is kept, not its text
                    let inner = std::error::Error::source(&e)
                        .and_then(|s| s.downcast_ref::<BodyError>())
                        .unwrap_or_else(|| panic!("no body error under `{e}`"));
                    assert!(
                        matches!(inner, BodyError::Worker { reason } if reason == "board refused"),
                        "{inner}"
                    );
                    break;
                }
                Ok(()) if Instant::now() < deadline => std::thread::yield_now(),
                Ok(()) => panic!("the failed command was never reported"),
            }
        }
        drop(release);
    }
}
