//! `codec::check_with` against `codec::parse_with`: the same verdict, the same error, and a
//! summary naming the parsed message's performative, sender and receivers, in both escapings,
//! on printed messages, damaged ones, and text built from the grammar's own words.

use iw_acl::codec::{self, ParseOptions, PrintOptions};
use proptest::prelude::*;

mod common;
use common::{assert_check_agrees, message, text};

/// Both escapings with the default limits, and now and then tight ones.
fn options() -> impl Strategy<Value = ParseOptions> {
    (
        any::<bool>(),
        prop::option::weighted(0.1, 0..4usize),
        prop::option::weighted(0.1, 0..400usize),
    )
        .prop_map(|(jade, max_depth, max_len)| {
            let mut options = if jade {
                ParseOptions::jade()
            } else {
                ParseOptions::default()
            };
            if let Some(depth) = max_depth {
                options.max_depth = depth;
            }
            max_len.map_or(options, |len| options.with_max_len(len))
        })
}

/// A generated message as one of the two printers writes it.
fn printed() -> impl Strategy<Value = String> {
    (message(), any::<bool>()).prop_map(|(m, jade)| {
        let standard = || codec::print(&m);
        if jade {
            codec::print_with(&m, &PrintOptions::jade()).unwrap_or_else(|_| standard())
        } else {
            standard()
        }
    })
}

/// Words that shape a message, right and wrong.
const FRAME: &[&str] = &[
    "(",
    ")",
    "(",
    ")",
    "inform",
    "REQUEST",
    "informs",
    "agent-identifier",
    "AGENT-Identifier",
    "set",
    "SET",
    "sequence",
];

/// Parameter and slot names, right and wrong, user ones among them.
const PARAMS: &[&str] = &[
    ":sender",
    ":receiver",
    ":RECEIVER",
    ":reply-to",
    ":content",
    ":language",
    ":ontology",
    ":reply-by",
    ":conversation-id",
    ":name",
    ":NAME",
    ":addresses",
    ":resolvers",
    ":X-",
    ":x-X-",
    ":X-a",
    ":x-a",
    ":X-X-a",
    ":X-b",
    ":X-JADE-Encoding",
    ":x-X-JADE-Encoding",
    ":X-jade-encoding",
    ":unknown",
    ":",
];

/// Values, among them ones that trip the date-time, Base64, escaping and byte-string checks.
const VALUES: &[&str] = &[
    "Base64",
    "\"base64\"",
    "\"Base\\64\"",
    "AAEC/yJc",
    "\"AAE=\"",
    "\"A\\\"==\"",
    "\"***\"",
    "20991231T235959000Z",
    "\"20991231T235959000Z\"",
    "20991331T235959000Z",
    "+00000000T000030000",
    "2099",
    "\"a\\\"b\"",
    "\"a\\\\b\"",
    "\"\\\"\"",
    "\"c\\d\"",
    "\"",
    "\"x\\",
    "#3\"abc",
    "#2\"\u{e9}",
    "#1\"\u{e9}",
    "#9\"x",
    "#\"",
    "echo",
    "ping@P",
    "é",
];

/// Identifiers and sets, well-formed or nearly.
const AGENTS: &[&str] = &[
    "(agent-identifier :name a)",
    "(set (agent-identifier :name echo) (agent-identifier :name \"e\\\"2\" :X-k v))",
    "(set (agent-identifier :name echo :addresses (sequence http://h:1/acc \"b c\")))",
    "(set)",
    "(sequence http://h:1/acc)",
    "(agent-identifier :name a :resolvers (sequence (agent-identifier :name r :X-a 1 :x-a 2)))",
    "(agent-identifier :X-a 1 :name a :X-b 2 :x-x-a 3)",
    "(set (agent-identifier :name a :name b))",
];

/// Tokens of all the above and free text, joined by assorted whitespace.
fn word_soup() -> impl Strategy<Value = String> {
    let words: Vec<&str> = [FRAME, PARAMS, VALUES, AGENTS].concat();
    let token = prop_oneof![4 => prop::sample::select(words).prop_map(str::to_owned), 1 => text()];
    prop::collection::vec(
        (token, prop::sample::select(&[" ", " ", "\n", "\t", ""][..])),
        0..40,
    )
    .prop_map(|tokens| tokens.into_iter().map(|(t, sep)| t + sep).collect())
}

/// A message frame around parameters drawn from the words above: deep enough to reach the
/// duplicate, user-parameter, date-time and Base64 checks.
fn message_of_words() -> impl Strategy<Value = String> {
    let value = prop_oneof![
        4 => prop::sample::select(VALUES).prop_map(str::to_owned),
        3 => prop::sample::select(AGENTS).prop_map(str::to_owned),
        1 => text().prop_map(|t| format!("{t:?}")),
        1 => prop::sample::select(FRAME).prop_map(str::to_owned),
        1 => word_soup(),
    ];
    let performative = prop_oneof![8 => Just("inform"), 1 => Just("informs"), 1 => Just("(")];
    (
        performative,
        prop::collection::vec((prop::sample::select(PARAMS), value), 0..8),
    )
        .prop_map(|(performative, params)| {
            let params: String = params
                .into_iter()
                .map(|(p, v)| format!(" {p} {v}"))
                .collect();
            format!("({performative}{params})")
        })
}

/// Printed text with a few bytes replaced, removed or added, and perhaps cut short.
fn damaged() -> impl Strategy<Value = String> {
    let edit = (
        any::<prop::sample::Index>(),
        0..4u8,
        prop::sample::select(&b"()\":\\# aX-\n\x80\xff"[..]),
    );
    (
        printed(),
        prop::collection::vec(edit, 1..4),
        prop::option::of(any::<prop::sample::Index>()),
    )
        .prop_map(|(text, edits, cut)| {
            let mut bytes = text.into_bytes();
            for (at, kind, byte) in edits {
                let at = at.index(bytes.len() + 1);
                match kind {
                    0 if at < bytes.len() => bytes[at] = byte,
                    1 if at < bytes.len() => bytes[at] ^= 1 << (byte % 8),
                    2 if at < bytes.len() => drop(bytes.remove(at)),
                    _ => bytes.insert(at, byte),
                }
            }
            if let Some(cut) = cut {
                bytes.truncate(cut.index(bytes.len() + 1));
            }
            String::from_utf8_lossy(&bytes).into_owned()
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    #[test]
    fn printed_messages(text in printed(), options in options()) {
        assert_check_agrees(&text, &options);
    }

    #[test]
    fn printed_messages_in_both_escapings(text in printed()) {
        assert_check_agrees(&text, &ParseOptions::default());
        assert_check_agrees(&text, &ParseOptions::jade());
    }

    #[test]
    fn damaged_messages(text in damaged()) {
        assert_check_agrees(&text, &ParseOptions::default());
        assert_check_agrees(&text, &ParseOptions::jade());
    }

    #[test]
    fn messages_of_grammar_words(text in message_of_words()) {
        assert_check_agrees(&text, &ParseOptions::default());
        assert_check_agrees(&text, &ParseOptions::jade());
    }

    #[test]
    fn word_soups(text in word_soup(), options in options()) {
        assert_check_agrees(&text, &options);
    }

    #[test]
    fn strings_of_the_acl_alphabet(text in r#"\(?[()":\\# a-zX09é\n-]{0,80}\)?"#, options in options()) {
        assert_check_agrees(&text, &options);
    }
}

#[test]
fn hand_picked_cases() {
    for text in [
        "(INFORM :X-JADE-Encoding Base64 :content \"AAEC/yJc\")",
        "(INFORM :X-JADE-Encoding Base64 :content \"AAEC/yJ\")",
        "(INFORM :x-x-JADE-Encoding BASE64 :content #3\"abc)",
        "(INFORM :X-JADE-Encoding Base64 :X-JADE-Encoding Base64)",
        "(INFORM :X-jade-encoding Base64 :content \"***\")",
        "(INFORM :sender (agent-identifier :name \"a\\\"b\") :receiver (set (agent-identifier :name \"c\\\\d\")))",
        "(INFORM :receiver (set (agent-identifier :addresses (sequence a) :name a :addresses (sequence b))))",
        "(INFORM :receiver (set (agent-identifier :name a :X-k 1 :X-X-k 2)))",
        "(INFORM :reply-by #19\"20991231T235959000Z)",
        "(INFORM :ontology #2\"\u{e9})",
        "(INFORM :content #2\"\u{e9})",
        "(inform :receiver (set (agent-identifier :name a :resolvers (sequence (agent-identifier :name b :resolvers (sequence (agent-identifier :name c)))))))",
    ] {
        assert_check_agrees(text, &ParseOptions::default());
        assert_check_agrees(text, &ParseOptions::jade());
    }
    let mut shallow = ParseOptions::default();
    shallow.max_depth = 2;
    assert_check_agrees(
        "(inform :receiver (set (agent-identifier :name a :resolvers (sequence (agent-identifier :name b :resolvers (sequence (agent-identifier :name c)))))))",
        &shallow,
    );
}
