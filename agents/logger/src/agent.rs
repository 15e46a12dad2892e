//! The logger agent: appends every message it is given to a [`LogStore`] and answers queries.
//!
//! # How messages reach it
//! Two ways, both plain ACL on the bus:
//! - Copies: a container (or the composer's bus tap) forwards each message it routes as an
//!   INFORM to the logger with `:ontology IntellWheels-Log`, the original ACL text as `:content`
//!   and the time it crossed the bus in the user parameter `X-logged-ns`; [`copy_for_logger`]
//!   builds it. The stored record is the original message (sender, receivers, performative,
//!   conversation id, text), not the copy.
//! - Carbon copies: an agent may add the logger as one more receiver of a message; any message
//!   that is neither a copy nor a query is stored as itself, at the bus time it arrived.
//!
//! # Queries
//! `fipa-request`, answered through the protocol's state machine (`iw_agent::Responder`).
//! REQUEST with `:ontology IntellWheels-Log`, `:language JSON` and a JSON [`Query`] as content
//! (fields `sender`, `receiver`, `agent`, `performative`, `conversation_id`, `since_ns`,
//! `until_ns`, `contains`, all optional): INFORM with a [`QueryAnswer`], a JSON array of
//! [`LoggedMessage`]; FAILURE `((error-message "..."))` when the log cannot be read,
//! NOT-UNDERSTOOD for content that is not a query. Both JSON contents are typed
//! ([`TypedContent`]), so neither side writes content, language or ontology by hand. A copy
//! whose content is not ACL gets NOT-UNDERSTOOD and is not stored.
//!
//! Durability: the store's [`SyncPolicy`]; besides, every tick and at take-down the agent syncs,
//! so nothing acknowledged by a sync is lost on a crash (the store's recovery truncates a torn
//! tail only).

use std::path::PathBuf;
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context, TypedContent};
use serde::Serialize;

use crate::{LogError, LogStore, LoggedMessage, Query, SyncPolicy};

/// The `:ontology` of copies and queries.
pub const LOG_ONTOLOGY: &str = "IntellWheels-Log";

/// The `:language` of queries and their answers: JSON, not SL (a query selects fields of stored
/// records; its answer is the records).
pub const LOG_LANGUAGE: &str = "JSON";

/// The INFORM content answering a [`Query`]: the messages found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QueryAnswer(pub Vec<LoggedMessage>);

/// `message` with `value` as JSON content in the log's ontology.
fn fill_json(value: &impl Serialize, message: AclMessage) -> AclMessage {
    message
        // Structs of strings, integers and options always serialise.
        .with_content(serde_json::to_string(value).unwrap_or_default())
        .with_language(LOG_LANGUAGE)
        .with_ontology(LOG_ONTOLOGY)
}

impl TypedContent for Query {
    fn fill_into(&self, message: AclMessage) -> AclMessage {
        fill_json(self, message)
    }
}

impl TypedContent for QueryAnswer {
    fn fill_into(&self, message: AclMessage) -> AclMessage {
        fill_json(&self.0, message)
    }
}

/// The user parameter of a copy that carries the time the original crossed the bus, ns.
pub const LOGGED_NS_PARAM: &str = "X-logged-ns";

/// Where the log lives and how it is synced.
#[derive(Debug, Clone, PartialEq)]
pub struct LoggerConfig {
    /// The log file (created if missing, recovered if torn).
    pub path: PathBuf,
    /// When appends are forced to disk.
    pub policy: SyncPolicy,
    /// How often the agent syncs whatever the policy left unsynced.
    pub sync_period: Duration,
}

/// The logger agent.
pub struct LoggerAgent {
    store: LogStore,
    sync_period: Duration,
}

/// `message` wrapped as a copy for `logger`, stamped with the time it crossed the bus.
pub fn copy_for_logger(message: &AclMessage, logger: &AgentId, time_ns: u64) -> AclMessage {
    AclMessage::new(Performative::Inform)
        .with_receiver(logger.clone())
        .with_ontology(LOG_ONTOLOGY)
        .with_content(iw_acl::codec::print(message))
        .with_user_param(LOGGED_NS_PARAM, time_ns.to_string())
}

fn logged(message: &AclMessage, time_ns: u64) -> LoggedMessage {
    LoggedMessage {
        time_ns,
        sender: message
            .sender
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default(),
        receivers: message.receivers.iter().map(|r| r.name.clone()).collect(),
        performative: message.performative.to_string().to_ascii_lowercase(),
        conversation_id: message.conversation_id.clone(),
        acl: iw_acl::codec::print(message),
    }
}

impl LoggerAgent {
    /// Opens (or recovers) the log.
    pub fn open(config: &LoggerConfig) -> Result<Self, LogError> {
        let store = LogStore::open(&config.path, config.policy)?;
        let recovery = store.recovery();
        tracing::info!(path = %config.path.display(), records = recovery.records, truncated_bytes = recovery.truncated_bytes, "log opened");
        Ok(LoggerAgent {
            store,
            sync_period: config.sync_period,
        })
    }

    fn append(&mut self, entry: &LoggedMessage, now_ns: u64) {
        if let Err(err) = self.store.append(&entry.to_payload(), now_ns) {
            tracing::error!(error = %err, sender = %entry.sender, "message not logged");
        }
    }

    fn query(&mut self, ctx: &mut Context<'_>, message: &AclMessage) {
        let query: Query = match serde_json::from_str(message.content_text().unwrap_or_default()) {
            Ok(query) => query,
            Err(err) => {
                let _ =
                    ctx.not_understood(message, &format!("content is not a JSON log query: {err}"));
                return;
            }
        };
        let Some(mut request) = ctx.accept(message) else {
            return;
        };
        let result = self
            .store
            .sync()
            .map_err(crate::QueryError::from)
            .and_then(|_| query.run(self.store.path()));
        let _ = match result {
            Ok(found) => ctx.answer(&mut request, Performative::Inform, &QueryAnswer(found)),
            Err(err) => ctx.answer_error(&mut request, Performative::Failure, &err.to_string()),
        };
    }
}

impl Agent for LoggerAgent {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let now_ns = ctx.now().0;
        let ours = message
            .ontology
            .as_deref()
            .is_some_and(|o| o.eq_ignore_ascii_case(LOG_ONTOLOGY));
        match message.performative {
            Performative::Inform if ours => {
                let original = message.content_text().map(iw_acl::codec::parse);
                match original {
                    Some(Ok(original)) => {
                        let time_ns = message
                            .user_param(LOGGED_NS_PARAM)
                            .and_then(|t| t.parse().ok())
                            .unwrap_or(now_ns);
                        self.append(&logged(&original, time_ns), now_ns);
                    }
                    Some(Err(err)) => {
                        let _ = ctx.not_understood(
                            &message,
                            &format!("the copy's content is not ACL: {err}"),
                        );
                    }
                    None => {
                        let _ = ctx.not_understood(
                            &message,
                            "a copy needs the original ACL text as content",
                        );
                    }
                }
            }
            Performative::Request if ours => self.query(ctx, &message),
            _ => self.append(&logged(&message, now_ns), now_ns),
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(self.sync_period)
    }

    fn tick(&mut self, _ctx: &mut Context<'_>) {
        if let Err(err) = self.store.sync() {
            tracing::error!(error = %err, "log sync failed");
        }
    }

    fn take_down(&mut self, _ctx: &mut Context<'_>) {
        if let Err(err) = self.store.sync() {
            tracing::error!(error = %err, "log sync at shutdown failed");
        }
    }
}
