//! [`LoggedMessage`], what one log record holds, and [`Query`], how records are selected.
//!
//! The routing fields are copied out of the ACL message when it is logged so that queries need
//! not parse every stored message; `acl` keeps the message exactly as it crossed the bus.

use serde::{Deserialize, Serialize};

use crate::store::{LogError, LogItem, LogReader, Record};

/// One message as the logger agent saw it on the bus.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LoggedMessage {
    /// Platform time the message was logged, ns.
    pub time_ns: u64,
    /// Sender agent name.
    pub sender: String,
    /// Receiver agent names.
    pub receivers: Vec<String>,
    /// FIPA performative, lower case as in the ACL string (`request`, `inform`, ...).
    pub performative: String,
    /// Conversation id, if the message had one.
    pub conversation_id: Option<String>,
    /// The ACL string representation of the message.
    pub acl: String,
}

impl LoggedMessage {
    /// Serialises for [`crate::LogStore::append`].
    pub fn to_payload(&self) -> Vec<u8> {
        // A struct of strings and integers always serialises.
        serde_json::to_vec(self).unwrap_or_default()
    }

    /// Decodes a stored record; a record that is not a logged message is reported with its seq.
    pub fn from_record(record: &Record) -> Result<Self, EntryError> {
        serde_json::from_slice(&record.payload).map_err(|source| EntryError {
            seq: record.seq,
            source,
        })
    }
}

/// A stored record that does not hold a [`LoggedMessage`].
#[derive(Debug, thiserror::Error)]
#[error("log record {seq} is not a logged message: {source}")]
pub struct EntryError {
    /// The record's sequence number.
    pub seq: u64,
    /// What the JSON decoder said.
    #[source]
    pub source: serde_json::Error,
}

/// Selects logged messages; every field that is set must match.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Query {
    /// Sent by this agent.
    pub sender: Option<String>,
    /// Addressed to this agent.
    pub receiver: Option<String>,
    /// Either end is this agent.
    pub agent: Option<String>,
    /// With this performative (case-insensitive).
    pub performative: Option<String>,
    /// In this conversation.
    pub conversation_id: Option<String>,
    /// Logged at or after this time, ns.
    pub since_ns: Option<u64>,
    /// Logged before this time, ns.
    pub until_ns: Option<u64>,
    /// Whose ACL text contains this string.
    pub contains: Option<String>,
}

impl Query {
    /// Whether `m` satisfies every set field.
    pub fn matches(&self, m: &LoggedMessage) -> bool {
        let is = |want: &Option<String>, got: &str| want.as_deref().is_none_or(|w| w == got);
        is(&self.sender, &m.sender)
            && self
                .receiver
                .as_ref()
                .is_none_or(|r| m.receivers.iter().any(|x| x == r))
            && self
                .agent
                .as_ref()
                .is_none_or(|a| m.sender == *a || m.receivers.iter().any(|x| x == a))
            && self
                .performative
                .as_ref()
                .is_none_or(|p| p.eq_ignore_ascii_case(&m.performative))
            && self
                .conversation_id
                .as_ref()
                .is_none_or(|c| m.conversation_id.as_ref() == Some(c))
            && self.since_ns.is_none_or(|t| m.time_ns >= t)
            && self.until_ns.is_none_or(|t| m.time_ns < t)
            && self
                .contains
                .as_ref()
                .is_none_or(|s| m.acl.contains(s.as_str()))
    }

    /// The matching messages of the log at `path`, in log order; fails on any damage (the
    /// logger agent answers from its own, open log, where damage means something went wrong).
    /// Read as [`Query::stream`] reads: only the matches are held, not the whole log.
    pub fn run(&self, path: &std::path::Path) -> Result<Vec<LoggedMessage>, QueryError> {
        let mut found = Vec::new();
        for item in self.stream(path)? {
            match item? {
                LogItem::Record(m) => found.push(m),
                LogItem::Damage(damage) => {
                    return Err(LogError::Damaged {
                        path: path.to_path_buf(),
                        damage,
                    }
                    .into());
                }
            }
        }
        Ok(found)
    }

    /// The matching messages of every intact record of the log at `path` and each damaged region
    /// read past (see [`crate::read_log`]), in file order, one record in memory at a time: for
    /// tools that must show what survived of a log of any size.
    pub fn stream<'q>(
        &'q self,
        path: &std::path::Path,
    ) -> Result<impl Iterator<Item = Result<LogItem<LoggedMessage>, QueryError>> + 'q, QueryError>
    {
        let reader = LogReader::open(path, crate::store::DEFAULT_MAX_RECORD_LEN)?;
        Ok(reader.filter_map(move |item| match item {
            Ok(LogItem::Record(record)) => match LoggedMessage::from_record(&record) {
                Ok(m) => self.matches(&m).then_some(Ok(LogItem::Record(m))),
                Err(e) => Some(Err(e.into())),
            },
            Ok(LogItem::Damage(damage)) => Some(Ok(LogItem::Damage(damage))),
            Err(e) => Some(Err(e.into())),
        }))
    }
}

/// Why a query could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum QueryError {
    /// The log could not be read.
    #[error(transparent)]
    Log(#[from] LogError),
    /// A record held something else.
    #[error(transparent)]
    Entry(#[from] EntryError),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{LogStore, SyncPolicy};

    fn message(t: u64, from: &str, to: &str, perf: &str, conv: &str) -> LoggedMessage {
        LoggedMessage {
            time_ns: t,
            sender: from.into(),
            receivers: vec![to.into()],
            performative: perf.into(),
            conversation_id: Some(conv.into()),
            acl: format!(
                "({perf} :sender (agent-identifier :name {from}) :conversation-id {conv})"
            ),
        }
    }

    #[test]
    fn query_selects_by_every_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bus.iwl");
        let mut log = LogStore::open(&path, SyncPolicy::EveryN(100)).unwrap();
        let all = [
            message(10, "cognitive@chair1", "control@chair1", "request", "c1"),
            message(20, "control@chair1", "cognitive@chair1", "agree", "c1"),
            message(30, "door@building", "interface@chair2", "refuse", "d7"),
        ];
        for m in &all {
            log.append(&m.to_payload(), m.time_ns).unwrap();
        }
        log.sync().unwrap();
        let q = |q: Query| q.run(&path).unwrap();
        assert_eq!(q(Query::default()), all);
        assert_eq!(
            q(Query {
                conversation_id: Some("c1".into()),
                ..Query::default()
            }),
            all[..2]
        );
        assert_eq!(
            q(Query {
                agent: Some("control@chair1".into()),
                ..Query::default()
            }),
            all[..2]
        );
        assert_eq!(
            q(Query {
                performative: Some("REFUSE".into()),
                ..Query::default()
            }),
            all[2..]
        );
        assert_eq!(
            q(Query {
                since_ns: Some(20),
                until_ns: Some(30),
                ..Query::default()
            }),
            all[1..2]
        );
        assert_eq!(
            q(Query {
                receiver: Some("interface@chair2".into()),
                ..Query::default()
            }),
            all[2..]
        );
        assert!(
            q(Query {
                sender: Some("nobody".into()),
                ..Query::default()
            })
            .is_empty()
        );
    }

    #[test]
    fn foreign_record_is_reported_with_its_seq() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bus.iwl");
        let mut log = LogStore::open(&path, SyncPolicy::Always).unwrap();
        log.append(b"not json", 0).unwrap();
        let err = Query::default().run(&path).unwrap_err();
        assert!(err.to_string().contains("log record 1"), "{err}");
    }
}
