//! [`check_with`]: the parser's accept/reject decision without building the message.
//!
//! The bus's parser layer reads every inbound payload only to know that it is well-formed and
//! whom it names as sender and receivers, then throws the message away. Building an owned
//! [`AclMessage`](crate::AclMessage) for that (every value copied into a `String`, the content
//! copied, vectors of identifiers, maps of user parameters, then all of it dropped) is most of
//! the cost of that check. [`check_with`] runs the same parser with a builder that keeps only an
//! [`AclSummary`] borrowing the input, so the usual message is checked without allocating.

use std::borrow::Cow;
use std::collections::BTreeSet;
use std::fmt;

use super::parse::{Build, Param, RawContent, RawText, run};
use super::{ParseOptions, check_base64};
use crate::{Error, FipaDateTime, Performative};

/// Checks one message with [`ParseOptions::default`]; see [`check_with`].
pub fn check(text: &str) -> Result<AclSummary<'_>, Error> {
    check_with(text, &ParseOptions::default())
}

/// Checks one message as [`parse_with`](super::parse_with) reads it, without building it.
///
/// The same parser runs, so `check_with(text, o)` is `Ok` exactly when `parse_with(text, o)` is,
/// and fails with the same [`Error`]: the grammar, keywords in any case, duplicate parameters
/// (user `X-` parameters included), `:reply-by` as a date-time, JADE's Base64 content, UTF-8 in
/// byte strings, the size and depth limits. What it returns is only an [`AclSummary`]: the
/// performative and the sender's and receivers' names, borrowed from `text`.
///
/// It allocates nothing for a message with at most [`AclSummary::INLINE_RECEIVERS`] receivers,
/// 8 user parameters per message or identifier, no escaped quote or backslash in those names,
/// and no Base64 content over 1 KiB; beyond that it allocates only for the excess. Errors
/// allocate their message.
pub fn check_with<'a>(text: &'a str, options: &ParseOptions) -> Result<AclSummary<'a>, Error> {
    run(text, options, &mut SummaryBuilder)
}

/// What [`check_with`] keeps of a well-formed message: its performative and the `:name`s of its
/// sender and receivers, borrowed from the input unless unescaping changed them.
#[derive(Clone)]
pub struct AclSummary<'a> {
    performative: Performative,
    sender: Option<Cow<'a, str>>,
    receivers: Names<'a>,
}

impl<'a> AclSummary<'a> {
    /// Receivers kept without allocating; more go to the heap.
    pub const INLINE_RECEIVERS: usize = 4;

    /// The communicative act.
    pub fn performative(&self) -> Performative {
        self.performative
    }

    /// The `:name` of the `:sender`, if the message has one.
    pub fn sender(&self) -> Option<&str> {
        self.sender.as_deref()
    }

    /// The `:name`s of the `:receiver` set, in the order given.
    pub fn receivers(&self) -> impl DoubleEndedIterator<Item = &str> + '_ {
        self.receivers.iter().map(|name| &**name)
    }

    /// How many receivers the message names.
    pub fn receiver_count(&self) -> usize {
        self.receivers.len()
    }

    /// Whether `name` is among the receivers' names.
    pub fn has_receiver(&self, name: &str) -> bool {
        self.receivers().any(|receiver| receiver == name)
    }
}

impl fmt::Debug for AclSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("AclSummary")
            .field("performative", &self.performative)
            .field("sender", &self.sender())
            .field("receivers", &self.receivers().collect::<Vec<_>>())
            .finish()
    }
}

/// A few values in place, the rest on the heap (which stays unallocated until needed).
#[derive(Clone)]
struct Inline<T, const N: usize> {
    first: [T; N],
    len: usize,
    more: Vec<T>,
}

impl<T: Default, const N: usize> Default for Inline<T, N> {
    fn default() -> Self {
        Self {
            first: std::array::from_fn(|_| T::default()),
            len: 0,
            more: Vec::new(),
        }
    }
}

impl<T, const N: usize> Inline<T, N> {
    fn push(&mut self, value: T) {
        match self.first.get_mut(self.len) {
            Some(slot) => *slot = value,
            None => self.more.push(value),
        }
        self.len += 1;
    }

    fn len(&self) -> usize {
        self.len
    }

    fn iter(&self) -> impl DoubleEndedIterator<Item = &T> {
        self.first[..self.len.min(N)].iter().chain(&self.more)
    }
}

type Names<'a> = Inline<Cow<'a, str>, { AclSummary::INLINE_RECEIVERS }>;

/// User parameters kept in place per message or identifier; more go to the heap.
const INLINE_KEYS: usize = 8;

/// User parameter keys seen in one message or identifier, for duplicate detection: the first
/// few compared in place, the rest in a tree (so that many parameters cost n log n, not n^2).
#[derive(Default)]
struct Keys<'a> {
    first: Inline<&'a str, INLINE_KEYS>,
    more: BTreeSet<&'a str>,
}

impl<'a> Keys<'a> {
    /// Adds `key`; false if it was there.
    fn insert(&mut self, key: &'a str) -> bool {
        if self.first.iter().any(|&seen| seen == key) {
            return false;
        }
        if self.first.len() < INLINE_KEYS {
            self.first.push(key);
            true
        } else {
            self.more.insert(key)
        }
    }
}

/// An identifier under check: its name, unescaped only if it is kept.
#[derive(Default)]
struct CheckedAgent<'a> {
    name: Option<RawText<'a>>,
}

/// Builds the [`AclSummary`] of [`check_with`], checking what it does not keep.
struct SummaryBuilder;

impl<'a> Build<'a> for SummaryBuilder {
    type Message = AclSummary<'a>;
    type Agent = CheckedAgent<'a>;
    type UserParams = Keys<'a>;

    fn message(&mut self, performative: Performative) -> AclSummary<'a> {
        AclSummary {
            performative,
            sender: None,
            receivers: Names::default(),
        }
    }

    fn agent(&mut self) -> CheckedAgent<'a> {
        CheckedAgent::default()
    }

    fn user_params(&mut self) -> Keys<'a> {
        Keys::default()
    }

    fn user_param(&mut self, keys: &mut Keys<'a>, key: &'a str, _value: RawText<'a>) -> bool {
        keys.insert(key)
    }

    fn message_params(&mut self, _message: &mut AclSummary<'a>, _keys: Keys<'a>) {}

    fn agent_params(&mut self, _agent: &mut CheckedAgent<'a>, _keys: Keys<'a>) {}

    fn agent_param(&mut self, message: &mut AclSummary<'a>, param: Param, agent: CheckedAgent<'a>) {
        let name = || agent.name.map_or(Cow::Borrowed(""), RawText::into_cow);
        match param {
            Param::Sender => message.sender = Some(name()),
            Param::Receiver => message.receivers.push(name()),
            _ => {}
        }
    }

    fn text_param(&mut self, _message: &mut AclSummary<'a>, _param: Param, _value: RawText<'a>) {}

    fn content(&mut self, _message: &mut AclSummary<'a>, _content: RawContent<'a>) {}

    fn reply_by(&mut self, _message: &mut AclSummary<'a>, _deadline: FipaDateTime) {}

    fn remove_jade_marker(&mut self, _message: &mut AclSummary<'a>) {}

    fn base64_content(
        &mut self,
        _message: &mut AclSummary<'a>,
        content: RawText<'a>,
    ) -> Result<(), Error> {
        check_base64(&content.into_cow())
    }

    fn agent_name(&mut self, agent: &mut CheckedAgent<'a>, name: RawText<'a>) {
        agent.name = Some(name);
    }

    fn address(&mut self, _agent: &mut CheckedAgent<'a>, _address: RawText<'a>) {}

    fn resolver(&mut self, _agent: &mut CheckedAgent<'a>, _resolver: CheckedAgent<'a>) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::parse;

    #[test]
    fn summary_borrows_the_names() {
        let text = r#"(request :sender (agent-identifier :name ping :X-a 1 :X-b 2)
            :receiver (set (agent-identifier :name echo) (agent-identifier :name "e\"2")) :content "x")"#;
        let summary = check(text).unwrap();
        assert_eq!(summary.performative(), Performative::Request);
        assert!(matches!(summary.sender, Some(Cow::Borrowed("ping"))));
        assert_eq!(summary.receivers().collect::<Vec<_>>(), ["echo", "e\"2"]);
        assert!(summary.has_receiver("echo") && !summary.has_receiver("ping"));
        assert_eq!(summary.receiver_count(), 2);
    }

    #[test]
    fn many_receivers_and_user_parameters() {
        let mut text = String::from("(inform :receiver (set");
        for i in 0..10 {
            text.push_str(&format!(" (agent-identifier :name r{i})"));
        }
        text.push(')');
        for i in 0..20 {
            text.push_str(&format!(" :X-k{i} v"));
        }
        text.push(')');
        let summary = check(&text).unwrap();
        assert_eq!(
            summary.receivers().collect::<Vec<_>>(),
            (0..10).map(|i| format!("r{i}")).collect::<Vec<_>>()
        );
        for dup in ["k0", "k7", "k8", "k19"] {
            let twice = format!("{} :x-X-{dup} w)", &text[..text.len() - 1]);
            assert!(
                matches!(check(&twice), Err(Error::DuplicateParameter { .. })),
                "{twice}"
            );
            assert_eq!(
                check(&twice).unwrap_err(),
                parse(&twice).unwrap_err(),
                "{twice}"
            );
        }
    }

    #[test]
    fn verdicts_and_errors_are_the_parsers() {
        for text in [
            "(INFORM :X- a)",
            "(INFORM :X-a 1 :x-a 2)",
            "(INFORM :sender (agent-identifier :name a :X-k 1 :X-X-k 2))",
            "(INFORM :reply-by \"2099\")",
            "(INFORM :X-JADE-Encoding base64 :content \"***\")",
            "(INFORM :X-JADE-Encoding \"Base\\64\" :content \"ab\\\"\")",
            "(INFORM :X-JADE-Encoding \"BASE64\" :content \"AA\\\"A\")",
            "(INFORM :ontology #2\"\u{e9})",
            "(INFORM :sender (agent-identifier :name a) :sender (agent-identifier :name a))",
        ] {
            assert_eq!(check(text).err(), parse(text).err(), "{text}");
        }
    }
}
