//! Properties over generated messages: print then parse is the identity, and no input panics.

use iw_acl::codec::{self, ParseOptions, PrintOptions};
use iw_acl::{AclMessage, AgentId, Error, FipaDateTime, Performative};
use proptest::prelude::*;

/// Text that stresses the escaping: quotes, backslashes, parentheses, spaces, non-ASCII.
fn text() -> impl Strategy<Value = String> {
    prop_oneof![
        "[a-z][a-z0-9@:/.-]{0,12}",
        r#"[ a-z0-9"\\()#:@+\-\t\né€]{0,24}"#,
        any::<String>(),
    ]
}

fn user_params() -> impl Strategy<Value = Vec<(String, String)>> {
    prop::collection::vec(("[a-wyzA-WYZ][a-zA-Z0-9_-]{0,8}", text()), 0..3)
}

fn agent_id() -> impl Strategy<Value = AgentId> {
    let leaf = (text(), prop::collection::vec(text(), 0..3), user_params()).prop_map(|(name, addresses, params)| {
        let aid = addresses.into_iter().fold(AgentId::new(name), AgentId::with_address);
        params.into_iter().fold(aid, |aid, (k, v)| aid.with_user_param(&k, v))
    });
    leaf.prop_recursive(2, 6, 2, |inner| {
        (inner.clone(), prop::collection::vec(inner, 0..2))
            .prop_map(|(aid, resolvers)| resolvers.into_iter().fold(aid, AgentId::with_resolver))
    })
}

prop_compose! {
    fn message()(
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn standard_print_parses_back(m in message()) {
        let text = codec::print(&m);
        prop_assert_eq!(codec::parse(&text).unwrap(), m);
    }

    #[test]
    fn jade_print_parses_back_or_refuses(m in message()) {
        match codec::print_with(&m, &PrintOptions::jade()) {
            Ok(text) => prop_assert_eq!(codec::parse_with(&text, &ParseOptions::jade()).unwrap(), m),
            Err(err) => prop_assert!(matches!(err, Error::NotRepresentable { .. }), "{}", err),
        }
    }

    #[test]
    fn json_round_trips(m in message()) {
        let json = serde_json::to_string(&m).unwrap();
        prop_assert_eq!(serde_json::from_str::<AclMessage>(&json).unwrap(), m);
    }

    #[test]
    fn arbitrary_text_never_panics(text in any::<String>()) {
        let _ = codec::parse(&text);
        let _ = codec::parse_with(&text, &ParseOptions::jade());
    }

    #[test]
    fn damaged_messages_error_or_round_trip(m in message(), cut in any::<prop::sample::Index>(), insert in r#"[()":\\# a]"#) {
        let mut text = codec::print(&m);
        let mut at = cut.index(text.len() + 1);
        while !text.is_char_boundary(at) {
            at -= 1;
        }
        text.insert_str(at, &insert);
        if let Ok(parsed) = codec::parse(&text) {
            prop_assert_eq!(codec::parse(&codec::print(&parsed)).unwrap(), parsed);
        }
    }
}
