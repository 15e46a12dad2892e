//! The ACL message (SC00061): a performative plus the optional FIPA parameters.

use std::collections::BTreeMap;

use base64::Engine as _;
use serde::{Deserialize, Deserializer, Serialize};

use crate::{AgentId, Error, FipaDateTime, Performative};

/// What a message is about. FIPA content is text in the message's `language`; byte content
/// (JADE's `setByteSequenceContent`) travels Base64-encoded on the string representation.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Content {
    /// Text, typically an SL expression.
    Text(String),
    /// Opaque bytes.
    Bytes(Vec<u8>),
}

/// A FIPA-ACL message with every SC00061 parameter. Absent parameters are `None`/empty.
///
/// Fields are public (it is plain data); build with [`AclMessage::new`] and the `with_*`
/// methods, answer with [`AclMessage::create_reply`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "MessageRepr", try_from = "MessageRepr")]
#[non_exhaustive]
pub struct AclMessage {
    /// The communicative act.
    pub performative: Performative,
    /// Who sent it.
    pub sender: Option<AgentId>,
    /// Who it is for (`:receiver`, a set).
    pub receivers: Vec<AgentId>,
    /// Where replies go instead of the sender (`:reply-to`, a set).
    pub reply_to: Vec<AgentId>,
    /// The content.
    pub content: Option<Content>,
    /// Content language, e.g. `fipa-sl`.
    pub language: Option<String>,
    /// Content encoding (a FIPA parameter; JADE's Base64 marker is separate, see [`Content::Bytes`]).
    pub encoding: Option<String>,
    /// Ontology of the content's symbols.
    pub ontology: Option<String>,
    /// Interaction protocol, e.g. `fipa-request`.
    pub protocol: Option<String>,
    /// Conversation this message belongs to.
    pub conversation_id: Option<String>,
    /// Expression a reply must quote in `in-reply-to`.
    pub reply_with: Option<String>,
    /// The `reply-with` of the message this answers.
    pub in_reply_to: Option<String>,
    /// Latest time a reply is useful.
    pub reply_by: Option<FipaDateTime>,
    /// User-defined parameters, keyed without the `X-` wire prefix.
    pub user_params: BTreeMap<String, String>,
}

/// `key` without its `X-` wire prefix (any case, any number of times), so that keys given with
/// or without it name the same parameter.
pub(crate) fn user_key(mut key: &str) -> &str {
    while key.len() >= 2 && key.as_bytes()[..2].eq_ignore_ascii_case(b"x-") {
        key = &key[2..];
    }
    key
}

/// Deserializes a user-parameter map, dropping `X-` prefixes from the keys.
pub(crate) fn normalize_user_params<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<BTreeMap<String, String>, D::Error> {
    let raw = BTreeMap::<String, String>::deserialize(deserializer)?;
    Ok(raw
        .into_iter()
        .map(|(k, v)| (user_key(&k).to_owned(), v))
        .collect())
}

impl AclMessage {
    /// An empty message with this performative.
    pub fn new(performative: Performative) -> Self {
        Self {
            performative,
            sender: None,
            receivers: Vec::new(),
            reply_to: Vec::new(),
            content: None,
            language: None,
            encoding: None,
            ontology: None,
            protocol: None,
            conversation_id: None,
            reply_with: None,
            in_reply_to: None,
            reply_by: None,
            user_params: BTreeMap::new(),
        }
    }

    /// The content as text; `None` when absent or bytes.
    pub fn content_text(&self) -> Option<&str> {
        match &self.content {
            Some(Content::Text(text)) => Some(text),
            _ => None,
        }
    }

    /// A user-defined parameter (with or without the `X-` prefix in `key`).
    pub fn user_param(&self, key: &str) -> Option<&str> {
        self.user_params.get(user_key(key)).map(String::as_str)
    }

    /// A reply skeleton, as JADE's `createReply`: same performative (change it), addressed to
    /// the `reply-to` agents or else the sender, `in-reply-to` set from `reply-with`, and the
    /// language, encoding, ontology, protocol and conversation id copied. The caller sets its own
    /// sender and, if it expects an answer, a fresh `reply-with`.
    pub fn create_reply(&self) -> AclMessage {
        let mut reply = AclMessage::new(self.performative);
        reply.receivers = if self.reply_to.is_empty() {
            self.sender.iter().cloned().collect()
        } else {
            self.reply_to.clone()
        };
        reply.in_reply_to = self.reply_with.clone();
        reply.language = self.language.clone();
        reply.encoding = self.encoding.clone();
        reply.ontology = self.ontology.clone();
        reply.protocol = self.protocol.clone();
        reply.conversation_id = self.conversation_id.clone();
        reply
    }

    /// Sets the performative.
    pub fn with_performative(mut self, performative: Performative) -> Self {
        self.performative = performative;
        self
    }

    /// Sets the sender.
    pub fn with_sender(mut self, sender: AgentId) -> Self {
        self.sender = Some(sender);
        self
    }

    /// Adds a receiver.
    pub fn with_receiver(mut self, receiver: AgentId) -> Self {
        self.receivers.push(receiver);
        self
    }

    /// Adds a reply-to agent.
    pub fn with_reply_to(mut self, agent: AgentId) -> Self {
        self.reply_to.push(agent);
        self
    }

    /// Sets text content.
    pub fn with_content(mut self, text: impl Into<String>) -> Self {
        self.content = Some(Content::Text(text.into()));
        self
    }

    /// Sets byte content.
    pub fn with_byte_content(mut self, bytes: impl Into<Vec<u8>>) -> Self {
        self.content = Some(Content::Bytes(bytes.into()));
        self
    }

    /// Sets the content language.
    pub fn with_language(mut self, language: impl Into<String>) -> Self {
        self.language = Some(language.into());
        self
    }

    /// Sets the content encoding.
    pub fn with_encoding(mut self, encoding: impl Into<String>) -> Self {
        self.encoding = Some(encoding.into());
        self
    }

    /// Sets the ontology.
    pub fn with_ontology(mut self, ontology: impl Into<String>) -> Self {
        self.ontology = Some(ontology.into());
        self
    }

    /// Sets the interaction protocol.
    pub fn with_protocol(mut self, protocol: impl Into<String>) -> Self {
        self.protocol = Some(protocol.into());
        self
    }

    /// Sets the conversation id.
    pub fn with_conversation_id(mut self, id: impl Into<String>) -> Self {
        self.conversation_id = Some(id.into());
        self
    }

    /// Sets `reply-with`.
    pub fn with_reply_with(mut self, tag: impl Into<String>) -> Self {
        self.reply_with = Some(tag.into());
        self
    }

    /// Sets `in-reply-to`.
    pub fn with_in_reply_to(mut self, tag: impl Into<String>) -> Self {
        self.in_reply_to = Some(tag.into());
        self
    }

    /// Sets the reply deadline.
    pub fn with_reply_by(mut self, deadline: FipaDateTime) -> Self {
        self.reply_by = Some(deadline);
        self
    }

    /// Sets a user-defined parameter; a leading `X-` on `key` is dropped (it is the wire prefix).
    pub fn with_user_param(mut self, key: &str, value: impl Into<String>) -> Self {
        self.user_params
            .insert(user_key(key).to_owned(), value.into());
        self
    }
}

/// The JSON shape (the `parsed` objects of the FIPA test vectors): text content in `content`;
/// byte content as `content: null`, `byte_content_len`, and the Base64 bytes in `byte_content`.
#[derive(Serialize, Deserialize)]
struct MessageRepr {
    performative: Performative,
    #[serde(default)]
    sender: Option<AgentId>,
    #[serde(default)]
    receivers: Vec<AgentId>,
    #[serde(default)]
    reply_to: Vec<AgentId>,
    #[serde(default)]
    content: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    byte_content_len: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    byte_content: Option<String>,
    #[serde(default)]
    language: Option<String>,
    #[serde(default)]
    encoding: Option<String>,
    #[serde(default)]
    ontology: Option<String>,
    #[serde(default)]
    protocol: Option<String>,
    #[serde(default)]
    conversation_id: Option<String>,
    #[serde(default)]
    reply_with: Option<String>,
    #[serde(default)]
    in_reply_to: Option<String>,
    #[serde(default)]
    reply_by: Option<FipaDateTime>,
    #[serde(default, deserialize_with = "normalize_user_params")]
    user_params: BTreeMap<String, String>,
}

impl From<AclMessage> for MessageRepr {
    fn from(m: AclMessage) -> Self {
        let (content, byte_content_len, byte_content) = match m.content {
            None => (None, None, None),
            Some(Content::Text(text)) => (Some(text), None, None),
            Some(Content::Bytes(bytes)) => (
                None,
                Some(bytes.len()),
                Some(base64::engine::general_purpose::STANDARD.encode(&bytes)),
            ),
        };
        Self {
            performative: m.performative,
            sender: m.sender,
            receivers: m.receivers,
            reply_to: m.reply_to,
            content,
            byte_content_len,
            byte_content,
            language: m.language,
            encoding: m.encoding,
            ontology: m.ontology,
            protocol: m.protocol,
            conversation_id: m.conversation_id,
            reply_with: m.reply_with,
            in_reply_to: m.in_reply_to,
            reply_by: m.reply_by,
            user_params: m.user_params,
        }
    }
}

impl TryFrom<MessageRepr> for AclMessage {
    type Error = Error;

    fn try_from(r: MessageRepr) -> Result<Self, Error> {
        let inconsistent = |reason: &str| Error::InconsistentContent {
            reason: reason.to_owned(),
        };
        let content = match (r.content, r.byte_content, r.byte_content_len) {
            (Some(_), Some(_), _) => {
                return Err(inconsistent("both `content` and `byte_content` are set"));
            }
            (Some(text), None, None) => Some(Content::Text(text)),
            (Some(_), None, Some(_)) => {
                return Err(inconsistent(
                    "`byte_content_len` is set with text `content`",
                ));
            }
            (None, Some(encoded), len) => {
                let bytes = crate::codec::decode_base64(&encoded)?;
                if len.is_some_and(|len| len != bytes.len()) {
                    return Err(inconsistent(
                        "`byte_content_len` differs from the decoded `byte_content`",
                    ));
                }
                Some(Content::Bytes(bytes))
            }
            (None, None, Some(_)) => {
                return Err(inconsistent(
                    "`byte_content_len` without the bytes (give them Base64 in `byte_content`)",
                ));
            }
            (None, None, None) => None,
        };
        Ok(Self {
            performative: r.performative,
            sender: r.sender,
            receivers: r.receivers,
            reply_to: r.reply_to,
            content,
            language: r.language,
            encoding: r.encoding,
            ontology: r.ontology,
            protocol: r.protocol,
            conversation_id: r.conversation_id,
            reply_with: r.reply_with,
            in_reply_to: r.in_reply_to,
            reply_by: r.reply_by,
            user_params: r.user_params,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reply_goes_to_reply_to_else_sender_and_quotes_reply_with() {
        let request = AclMessage::new(Performative::Request)
            .with_sender(AgentId::new("a@p"))
            .with_receiver(AgentId::new("b@p"))
            .with_protocol("fipa-request")
            .with_conversation_id("c1")
            .with_reply_with("r1")
            .with_language("fipa-sl");
        let reply = request
            .create_reply()
            .with_performative(Performative::Agree);
        assert_eq!(reply.receivers, vec![AgentId::new("a@p")]);
        assert_eq!(reply.in_reply_to.as_deref(), Some("r1"));
        assert_eq!(reply.conversation_id.as_deref(), Some("c1"));
        assert_eq!(reply.protocol.as_deref(), Some("fipa-request"));
        assert_eq!(reply.reply_with, None);
        let redirected = request.with_reply_to(AgentId::new("c@p")).create_reply();
        assert_eq!(redirected.receivers, vec![AgentId::new("c@p")]);
    }

    #[test]
    fn user_param_keys_drop_the_wire_prefix() {
        let m = AclMessage::new(Performative::Inform).with_user_param("X-battery", "87");
        assert_eq!(m.user_param("battery"), Some("87"));
        assert_eq!(m.user_param("X-battery"), Some("87"));
        assert_eq!(m.user_params.keys().collect::<Vec<_>>(), ["battery"]);
    }

    #[test]
    fn json_round_trip_keeps_bytes_and_text() {
        let m = AclMessage::new(Performative::Inform)
            .with_byte_content(vec![0u8, 1, 2, 255])
            .with_reply_by("20991231T235959000Z".parse().unwrap());
        let json = serde_json::to_value(&m).unwrap();
        assert_eq!(json["content"], serde_json::Value::Null);
        assert_eq!(json["byte_content_len"], 4);
        assert_eq!(json["reply_by"], "20991231T235959000Z");
        assert_eq!(serde_json::from_value::<AclMessage>(json).unwrap(), m);
        let text = AclMessage::new(Performative::Cfp).with_content("(x)");
        assert_eq!(
            serde_json::from_str::<AclMessage>(&serde_json::to_string(&text).unwrap()).unwrap(),
            text
        );
    }

    #[test]
    fn json_with_length_only_is_refused() {
        let json = r#"{"performative":"INFORM","content":null,"byte_content_len":6}"#;
        let err = serde_json::from_str::<AclMessage>(json).unwrap_err();
        assert!(err.to_string().contains("byte_content"), "{err}");
    }
}
