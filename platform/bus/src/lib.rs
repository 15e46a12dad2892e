//! The message bus: envelopes, the layer trait and stack, routing, the frame transport trait and
//! the in-process transport (thesis 3.3.3).
//!
//! API CONTRACT (shared by the layer crates and the transport crates): the bus work fills in
//! envelopes, layers and routing; [`transport::FrameTransport`] keeps its name and methods.
#![warn(missing_docs)]

pub mod transport;
