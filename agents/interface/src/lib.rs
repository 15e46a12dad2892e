//! The interface agent (thesis 3.3.1, 3.3.4): the user's side of the wheelchair. Proportional
//! devices (joystick, gamepad stick, head cap, arrow keys) drive the chair: while one is held the
//! agent streams `drive` requests (the wheelchair ontology's `WheelchairAction::Drive`) to the
//! control agent, one per tick, in one conversation per hold; on release it sends a stop and
//! falls silent. Symbolic inputs are normalised to input events; user-defined input sequences,
//! accepted after a reliability test, are recognised in that stream and turned into FIPA-ACL
//! requests: goals to the cognitive agent, a stop to the control agent. A drive panel in
//! another container (the services' dashboard, through the staff console) sends it `drive`
//! requests; from an agent of [`InterfaceConfig::remote_drivers`] they are held and streamed like
//! a device's input ([`Device::Remote`]), from anyone else refused.
//!
//! # Organization
//! - [`drive`]: dead zones and gains from proportional readings to the user's velocity command.
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
//! - No input can panic the agent: bad symbols are refused with [`InterfaceError`] and dropped;
//!   a broken proportional reading (NaN, infinite, out of range) is dropped and stops the chair.
//! - A held input streams at the tick rate (20 Hz by default); a device silent for
//!   [`InterfaceConfig::hold`] counts as released. After the control agent refuses or ends a
//!   stream, nothing is sent until the user lets go.
//! - A remote `drive` is refused with a reason when its sender is not a remote driver, when it
//!   is not finite or beyond the mapping's speeds (the chair stops too), or while another driver
//!   (a device of the chair or another remote) holds the chair; the chair's own device takes
//!   the chair back from a remote driver.
//! - Its goal and stop requests and its drive streams (a fipa-request refined by each further
//!   command, `iw_interaction::Initiator::stream`) run on the interaction protocols' state
//!   machines: answers are matched by conversation and `in-reply-to`, and one the protocol does
//!   not allow changes nothing.
//! - Everything leaves as ordinary ACL messages through the bus; the agent holds no other agent.
#![warn(missing_docs)]

mod agent;
pub mod drive;
pub mod input;
pub mod sequence;

pub use agent::{Command, Display, InputQueue, InterfaceAgent, InterfaceConfig};
pub use drive::{Axes, DriveCommand, DriveMapping};
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
    /// A proportional reading that is not finite or out of its range.
    #[error("{device:?}: reading ({x}, {y}) refused: {range}")]
    BadAxes {
        /// The device.
        device: Device,
        /// Sideways reading.
        x: f64,
        /// Forward reading.
        y: f64,
        /// The range accepted.
        range: &'static str,
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
