//! Errors of the SL codec.

use crate::level::Level;

/// Why SL text was refused. Positions are 1-based; columns count characters.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum SlError {
    /// Characters that start no SL token.
    #[error("line {line}, column {column}: unexpected character {found:?}: {reason}")]
    Lexical {
        /// Line of the character.
        line: usize,
        /// Column of the character.
        column: usize,
        /// The offending character.
        found: char,
        /// What was wrong or expected.
        reason: &'static str,
    },
    /// A token the grammar does not allow here.
    #[error("line {line}, column {column}: found {found}, expected {expected}")]
    Syntax {
        /// Line of the token.
        line: usize,
        /// Column of the token.
        column: usize,
        /// The token found (quoted text, or `end of input`).
        found: String,
        /// What the grammar allows at this point.
        expected: &'static str,
    },
    /// A construct valid SL but outside the requested level.
    #[error(
        "line {line}, column {column}: {construct} is not allowed in {level} (parse with level {needs} or above)"
    )]
    NotAllowed {
        /// Line of the operator.
        line: usize,
        /// Column of the operator.
        column: usize,
        /// The construct, e.g. `the quantifier "forall"`.
        construct: String,
        /// The level parsed with.
        level: Level,
        /// The lowest level accepting it.
        needs: Level,
    },
    /// Parentheses nested deeper than the parser's bound.
    #[error("line {line}, column {column}: nesting deeper than {limit} levels")]
    TooDeep {
        /// Line of the parenthesis that went too deep.
        line: usize,
        /// Its column.
        column: usize,
        /// The bound ([`crate::MAX_DEPTH`]).
        limit: usize,
    },
    /// Content longer than the parser's bound, refused before reading it.
    #[error("content of {bytes} bytes is longer than the limit of {limit} bytes")]
    TooLarge {
        /// Length of the input.
        bytes: usize,
        /// The bound ([`crate::MAX_INPUT_BYTES`]).
        limit: usize,
    },
    /// Content of more tokens than the parser's bound.
    #[error("line {line}, column {column}: more than {limit} tokens in one content")]
    TooManyTokens {
        /// Line of the first token past the bound.
        line: usize,
        /// Its column.
        column: usize,
        /// The bound ([`crate::MAX_TOKENS`]).
        limit: usize,
    },
    /// A level name that is none of `sl0`, `sl1`, `sl2`, `full` (or `fipa-sl*`).
    #[error("unknown SL level {name:?} (use sl0, sl1, sl2 or full)")]
    UnknownLevel {
        /// The name given.
        name: String,
    },
}
