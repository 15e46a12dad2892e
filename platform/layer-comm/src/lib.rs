//! Communication layer: de-duplication, retransmission until acknowledged, size limits.
#![warn(missing_docs)]
