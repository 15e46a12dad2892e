//! Shared-control obstacle avoidance (thesis 3.6), VFH+ baseline and tactical actions.
#![warn(missing_docs)]
