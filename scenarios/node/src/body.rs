//! One body shared by a chair's perception and control agents.
//!
//! A real board advances its clock on every sensor request, so two agents each reading it would
//! run it at twice its rate. Here the control agent's handle is the one that reads the board;
//! the perception agent's handle gets the frame last read (encoder ticks are cumulative, so a
//! frame seen twice is zero motion, never a wrong one).

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use iw_body::{Body, BodyError, SensorFrame, WheelSpeeds};

struct Inner {
    body: Box<dyn Body + Send>,
    last: Option<SensorFrame>,
}

/// A handle on a shared body; see the module docs for who reads.
pub struct SharedBody {
    inner: Arc<Mutex<Inner>>,
    reads_board: bool,
}

impl SharedBody {
    /// The driving handle: it reads the board and commands it.
    pub fn new(body: Box<dyn Body + Send>) -> SharedBody {
        SharedBody { inner: Arc::new(Mutex::new(Inner { body, last: None })), reads_board: true }
    }

    /// An observing handle: it gets the frame last read (the board only before the first).
    pub fn observer(&self) -> SharedBody {
        SharedBody { inner: self.inner.clone(), reads_board: false }
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Zero wheel speeds, whichever handle asks (the last resort on shutdown).
    pub fn halt(&self) -> Result<(), BodyError> {
        self.lock().body.stop()
    }
}

impl Body for SharedBody {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        let reads_board = self.reads_board;
        let mut inner = self.lock();
        match (&inner.last, reads_board) {
            (Some(frame), false) => Ok(frame.clone()),
            _ => {
                let frame = inner.body.read()?;
                inner.last = Some(frame.clone());
                Ok(frame)
            }
        }
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        self.lock().body.command(speeds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts reads; the frame's time is the read count.
    struct Counting(u64, Arc<Mutex<Vec<WheelSpeeds>>>);
    impl Body for Counting {
        fn read(&mut self) -> Result<SensorFrame, BodyError> {
            self.0 += 1;
            Ok(SensorFrame::empty(self.0))
        }
        fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
            self.1.lock().unwrap().push(speeds);
            Ok(())
        }
    }

    #[test]
    fn only_the_driver_reads_the_board() {
        let commands = Arc::new(Mutex::new(Vec::new()));
        let mut driver = SharedBody::new(Box::new(Counting(0, commands.clone())));
        let mut observer = driver.observer();
        assert_eq!(observer.read().unwrap().time_ns, 1, "the observer reads once before any frame exists");
        assert_eq!(driver.read().unwrap().time_ns, 2);
        assert_eq!(observer.read().unwrap().time_ns, 2);
        assert_eq!(observer.read().unwrap().time_ns, 2);
        assert_eq!(driver.read().unwrap().time_ns, 3);
        observer.halt().unwrap();
        assert_eq!(*commands.lock().unwrap(), [WheelSpeeds::STOP]);
    }
}
