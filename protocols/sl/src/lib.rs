//! FIPA-SL content language (SC00008): SL0, SL1, SL2 and full SL, read and written.
//!
//! SL is the Lisp-like language of ACL `:content`: `((action (agent-identifier :name df@P)
//! (search ...)))`. This crate turns such text into one typed tree for every level and back.
//!
//! # Organization
//! - [`parse`] reads content at a [`Level`]; [`Content`] and the other tree types in [`ast`]
//!   print back as SL through `Display`.
//! - [`jade_tree`] renders a tree the way JADE's codec shows it (the reference for tests).
//! - [`SlError`] says what went wrong and where (line, column, what was expected).
//!
//! # Guarantees
//! - Levels accept and refuse what JADE 4.6.5's `SLCodec` does for each (see [`Level`]), checked
//!   against every row of JADE's answers in `shared/fipa/vectors/sl-decode.jsonl`.
//! - No input panics: nesting is bounded by [`MAX_DEPTH`]; lexing never indexes past the input.
//! - Memory is bounded: input by [`MAX_INPUT_BYTES`], the tree by [`MAX_TOKENS`].
//! - `parse(&content.to_string(), level) == Ok(content)` for parsed content (property-tested),
//!   except the two values SL cannot spell that the printer documents.
#![warn(missing_docs)]

pub mod ast;
mod error;
mod jade;
mod level;
mod lexer;
mod parser;
mod printer;

pub use ast::{
    ActionExpression, ActionOp, ActionOperand, Arguments, ArithmeticOp, BinaryOp, Collection,
    Constant, Content, ContentExpression, DateTime, Formula, IdentifyingExpression, ModalOp,
    Parameter, Quantifier, ReferentialOp, Term,
};
pub use error::SlError;
pub use jade::jade_tree;
pub use level::Level;
pub use parser::{MAX_DEPTH, MAX_INPUT_BYTES, MAX_TOKENS, parse};
