//! Errors of the ontology codecs.

use iw_sl::SlError;

/// Why SL content does not map onto an ontology's types.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum OntologyError {
    /// A term of the wrong shape where a concept or value was expected.
    #[error("expected {expected}, found {found}")]
    UnexpectedTerm {
        /// What the ontology expects here.
        expected: &'static str,
        /// The term found, printed as SL.
        found: String,
    },
    /// A mandatory slot is absent.
    #[error("({concept} ...) lacks its mandatory :{slot}")]
    MissingSlot {
        /// The concept.
        concept: &'static str,
        /// The slot.
        slot: &'static str,
    },
    /// A slot holds a value outside its type.
    #[error("({concept} :{slot} {value}): {reason}")]
    BadValue {
        /// The concept.
        concept: &'static str,
        /// The slot.
        slot: &'static str,
        /// The value found, printed as SL.
        value: String,
        /// What was expected.
        reason: &'static str,
    },
    /// Content whose overall form is none the ontology defines.
    #[error("expected {expected}, found content {found}")]
    UnexpectedContent {
        /// The forms accepted.
        expected: &'static str,
        /// The content, printed as SL.
        found: String,
    },
    /// The message names another `:ontology`.
    #[error("message is in ontology {found:?}, expected {expected:?}")]
    WrongOntology {
        /// This content type's ontology.
        expected: &'static str,
        /// The message's.
        found: String,
    },
    /// The message has no content, or byte content.
    #[error("message has no text content")]
    NoTextContent,
    /// The text is not SL at the level given.
    #[error("content is not valid SL: {0}")]
    Sl(#[from] SlError),
}
