//! FIPA interaction protocols as typed state machines.
#![warn(missing_docs)]
