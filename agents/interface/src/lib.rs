//! The interface agent (thesis 3.3.4): the user's side of the wheelchair. Readings of several
//! input devices are normalised to input events; user-defined input sequences, accepted after a
//! reliability test, are recognised in that stream and turned into FIPA-ACL requests: goals to
//! the cognitive agent, manual commands to the control agent.
//!
//! # Organization
//! - [`input`]: [`RawInput`] readings (joystick, gamepad, keyboard, head accelerometer, voice
//!   text, facial-expression labels) normalised to [`InputEvent`]s.
//! - [`sequence`]: [`InputSequence`] (homogeneous or mixed devices), the [`ReliabilityTest`]
//!   a sequence must pass before it is bound, and the [`Recognizer`] that fires bound actions.
//! - [`InterfaceAgent`]: drains the shared [`InputQueue`] each tick, recognises, and sends
//!   [`Command`]s as ACL requests; its [`Display`] tells the on-chair screen what is going on.
//!
//! # Guarantees
//! - A sequence is bound only after it passed its reliability test, and never when it occurs
//!   inside another bound sequence (or one inside it), so entering one cannot fire the other.
//! - No input can panic the agent: bad symbols are refused with [`InterfaceError`] and dropped.
//! - Everything leaves as ordinary ACL messages through the bus; the agent holds no other agent.
#![warn(missing_docs)]

mod agent;
pub mod input;
pub mod sequence;

pub use agent::{Command, Display, InputQueue, InterfaceAgent, InterfaceConfig};
pub use input::{Device, InputEvent, RawInput};
pub use sequence::{InputSequence, Recognizer, ReliabilityTest, Verdict};

/// What the interface refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InterfaceError {
    /// A device name that is empty, too long or has characters other than letters, digits, `-`, `_`.
    #[error("{device:?}: bad symbol `{symbol}` (letters, digits, `-` and `_`, 1 to 64 characters)")]
    BadSymbol {
        /// The device.
        device: Device,
        /// The symbol as read.
        symbol: String,
    },
    /// A reliability test that cannot be run.
    #[error(
        "reliability test of a {length}-step sequence needing {required} of {repetitions} attempts: need 1 <= required <= repetitions and a non-empty sequence"
    )]
    BadTest {
        /// Steps in the sequence.
        length: usize,
        /// Attempts asked.
        repetitions: u32,
        /// Successes asked.
        required: u32,
    },
    /// The sequence has not passed its reliability test.
    #[error("sequence not reliable enough (recognised in {:.0}% of attempts)", rate * 100.0)]
    NotReliable {
        /// Recognition rate so far.
        rate: f64,
    },
    /// The sequence occurs inside a bound one or the other way round.
    #[error("sequence {sequence} conflicts with bound sequence {other}")]
    Ambiguous {
        /// The new sequence.
        sequence: String,
        /// The bound one.
        other: String,
    },
}
