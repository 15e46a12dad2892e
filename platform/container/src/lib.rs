//! Agent containers: hosting agents, Local and Global Agent Lists, container election.
#![warn(missing_docs)]
