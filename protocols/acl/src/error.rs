//! The crate's one error type.

use thiserror::Error;

/// Everything that can go wrong reading or writing ACL messages.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum Error {
    /// The text does not follow the SC00070 grammar at this point.
    #[error("line {line}, column {column}: expected {expected}, found {found}")]
    Syntax {
        /// 1-based line of the offending token.
        line: u32,
        /// 1-based column (in characters) of the offending token.
        column: u32,
        /// What the grammar allows here.
        expected: &'static str,
        /// The offending token, quoted, or "end of input".
        found: String,
    },
    /// The message starts with a word that is no FIPA performative.
    #[error(
        "line {line}, column {column}: unknown performative `{word}` (expected a FIPA name such as REQUEST or INFORM)"
    )]
    UnknownPerformative {
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// The word found.
        word: String,
    },
    /// A parameter name that SC00061 does not define and that lacks the `X-` user prefix.
    #[error(
        "line {line}, column {column}: unknown parameter `:{name}` (user-defined parameters start with `:X-`)"
    )]
    UnknownParameter {
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// The name after the colon.
        name: String,
    },
    /// The same parameter twice in one message or agent identifier.
    #[error("line {line}, column {column}: parameter `:{name}` given twice")]
    DuplicateParameter {
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// The repeated name.
        name: String,
    },
    /// An agent identifier without its mandatory `:name`.
    #[error("line {line}, column {column}: agent-identifier has no `:name`")]
    MissingAgentName {
        /// 1-based line of the identifier's opening parenthesis.
        line: u32,
        /// 1-based column.
        column: u32,
    },
    /// Agent identifiers nested (through `:resolvers`) deeper than the parser allows.
    #[error("line {line}, column {column}: agent identifiers nested deeper than {limit} levels")]
    TooDeep {
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// The nesting limit.
        limit: usize,
    },
    /// A value that must be a FIPA date-time is not one.
    #[error(
        "invalid FIPA date-time `{value}`: {reason} (form: YYYYMMDDTHHMMSSmmm with optional sign and zone letter, e.g. 20991231T235959000Z)"
    )]
    InvalidDateTime {
        /// The offending text.
        value: String,
        /// What is wrong with it.
        reason: String,
    },
    /// Content announced as Base64 (`:X-JADE-Encoding Base64`) does not decode.
    #[error("content announced as Base64 does not decode: {source} (content starts `{start}`)")]
    InvalidBase64 {
        /// What the decoder said.
        #[source]
        source: base64::DecodeError,
        /// The first characters of the content.
        start: String,
    },
    /// A parameter value of the right shape but wrong content (a bad date, bad Base64).
    #[error("line {line}, column {column}: invalid `:{param}` value: {source}")]
    InvalidValue {
        /// 1-based line of the value.
        line: u32,
        /// 1-based column.
        column: u32,
        /// The parameter.
        param: String,
        /// Why it is invalid: the date's or the Base64 decoder's error.
        #[source]
        source: ValueError,
    },
    /// A JSON message whose content fields contradict each other.
    #[error("inconsistent message content: {reason}")]
    InconsistentContent {
        /// What contradicts what.
        reason: String,
    },
    /// Input longer than the configured limit (a guard against memory exhaustion).
    #[error(
        "message of {len} bytes exceeds the {limit}-byte limit (raise ParseOptions::max_len if this is legitimate)"
    )]
    TooLarge {
        /// Input length in bytes.
        len: usize,
        /// The limit in bytes.
        limit: usize,
    },
    /// A string JADE's escaping cannot carry: it would reach JADE altered or unparseable.
    #[error(
        "{slot} value `{value}` cannot be written with JADE escaping (it ends in a backslash); send it as byte content or use standard escaping"
    )]
    NotRepresentable {
        /// The parameter holding it (`content`, `ontology`, ...).
        slot: &'static str,
        /// The value.
        value: String,
    },
    /// `FromStr` of a performative name.
    #[error("unknown performative `{name}` (expected a FIPA name such as REQUEST or INFORM)")]
    UnknownPerformativeName {
        /// The name given.
        name: String,
    },
}

/// The error under [`Error::InvalidValue`], kept behind a pointer because it is an
/// [`enum@Error`] itself; `source()` of an [`Error::InvalidValue`] is that inner [`enum@Error`].
pub type ValueError = iw_cause::Cause<Error>;
