//! The logger agent's store: a permanent, append-only, crash-safe log of every message exchanged.
//!
//! Organization:
//! - [`agent`]: the logger agent on the bus ([`agent::LoggerAgent`]): how copies reach it, queries.
//! - [`store`]: [`LogStore`], checksummed records in segment files, the fsync policy and recovery.
//! - [`entry`]: [`LoggedMessage`], what one record holds, and [`Query`], how records are selected.
//!
//! Guarantees: a record acknowledged by [`LogStore::append`] under [`SyncPolicy::Always`] (or
//! covered by a later [`LogStore::sync`]) survives a crash; recovery truncates a torn tail and
//! refuses, with the offset, to open a log damaged anywhere else, so no acknowledged record is lost
//! silently; readers report each damaged region and read on past it.
#![warn(missing_docs)]

pub mod agent;
pub mod entry;
pub mod store;

pub use entry::{EntryError, LoggedMessage, Query, QueryError};
pub use store::{
    DEFAULT_MAX_RECORD_LEN, Damage, LogError, LogItem, LogRead, LogReader, LogStore, Record,
    Recovery, SyncPolicy, parse_log, read_log, read_records,
};
