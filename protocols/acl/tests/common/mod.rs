//! Shared by the integration tests: generators of messages, and the check that
//! `codec::check_with` agrees with `codec::parse_with`. Each test crate uses part of it.
#![allow(dead_code)]

use iw_acl::codec::{self, ParseOptions};
use iw_acl::{AclMessage, AgentId, FipaDateTime, Performative};
use proptest::prelude::*;

/// Text that stresses the escaping: quotes, backslashes, parentheses, spaces, non-ASCII.
pub fn text() -> impl Strategy<Value = String> {
    prop_oneof![
        "[a-z][a-z0-9@:/.-]{0,12}",
        r#"[ a-z0-9"\\()#:@+\-\t\né€]{0,24}"#,
        any::<String>(),
    ]
}

pub fn user_params() -> impl Strategy<Value = Vec<(String, String)>> {
    prop::collection::vec(("[a-wyzA-WYZ][a-zA-Z0-9_-]{0,8}", text()), 0..3)
}

pub fn agent_id() -> impl Strategy<Value = AgentId> {
    let leaf = (text(), prop::collection::vec(text(), 0..3), user_params()).prop_map(
        |(name, addresses, params)| {
            let aid = addresses
                .into_iter()
                .fold(AgentId::new(name), AgentId::with_address);
            params
                .into_iter()
                .fold(aid, |aid, (k, v)| aid.with_user_param(&k, v))
        },
    );
    leaf.prop_recursive(2, 6, 2, |inner| {
        (inner.clone(), prop::collection::vec(inner, 0..2))
            .prop_map(|(aid, resolvers)| resolvers.into_iter().fold(aid, AgentId::with_resolver))
    })
}

prop_compose! {
    pub fn message()(
        performative in prop::sample::select(Performative::ALL.to_vec()),
        sender in prop::option::of(agent_id()),
        receivers in prop::collection::vec(agent_id(), 0..3),
        reply_to in prop::collection::vec(agent_id(), 0..2),
        content in prop::option::of(prop_oneof![text().prop_map(Ok), prop::collection::vec(any::<u8>(), 0..16).prop_map(Err)]),
        slots in prop::collection::vec(prop::option::of(text()), 7),
        reply_by in prop::option::of(-62_000_000_000_000i64..250_000_000_000_000),
        params in user_params(),
    ) -> AclMessage {
        let mut m = AclMessage::new(performative);
        m.sender = sender;
        m.receivers = receivers;
        m.reply_to = reply_to;
        m = match content {
            Some(Ok(text)) => m.with_content(text),
            Some(Err(bytes)) => m.with_byte_content(bytes),
            None => m,
        };
        let [language, encoding, ontology, protocol, conversation_id, reply_with, in_reply_to] =
            <[Option<String>; 7]>::try_from(slots).unwrap();
        m.language = language;
        m.encoding = encoding;
        m.ontology = ontology;
        m.protocol = protocol;
        m.conversation_id = conversation_id;
        m.reply_with = reply_with;
        m.in_reply_to = in_reply_to;
        m.reply_by = reply_by.map(FipaDateTime::from_unix_ms);
        params.into_iter().fold(m, |m, (k, v)| m.with_user_param(&k, v))
    }
}

/// `check_with(text)` is `Ok` exactly when `parse_with(text)` is, fails with the same error, and
/// summarizes the parsed message's performative, sender name and receiver names.
pub fn assert_check_agrees(text: &str, options: &ParseOptions) {
    let parsed = codec::parse_with(text, options);
    let checked = codec::check_with(text, options);
    match (&parsed, &checked) {
        (Ok(message), Ok(summary)) => {
            assert_eq!(summary.performative(), message.performative, "{text:?}");
            assert_eq!(
                summary.sender(),
                message.sender.as_ref().map(|s| s.name.as_str()),
                "{text:?}"
            );
            let receivers: Vec<&str> = message.receivers.iter().map(|r| r.name.as_str()).collect();
            assert_eq!(
                summary.receivers().collect::<Vec<_>>(),
                receivers,
                "{text:?}"
            );
            assert_eq!(summary.receiver_count(), receivers.len(), "{text:?}");
            assert!(
                receivers.iter().all(|r| summary.has_receiver(r)),
                "{text:?}"
            );
        }
        (Err(parse_err), Err(check_err)) => assert_eq!(check_err, parse_err, "{text:?}"),
        _ => panic!("parse_with and check_with disagree on {text:?}: {parsed:?} vs {checked:?}"),
    }
}
