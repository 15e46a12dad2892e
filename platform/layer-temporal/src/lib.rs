//! Temporal layer: timestamps, sequence numbers, stale and future message rejection.
#![warn(missing_docs)]
