//! The ACL string representation (SC00070, `fipa.acl.rep.string.std`): [`parse`] and [`print()`].
//!
//! ```text
//! (REQUEST                                          <- performative, any case
//!  :sender (agent-identifier :name a@P :addresses (sequence http://h:1/acc))
//!  :receiver (set (agent-identifier :name b@P))     <- sets of agent identifiers
//!  :content "((action ...) \"quoted\")"             <- string; escaping per `Escaping`
//!  :reply-by 20991231T235959000Z                    <- FIPA date-time
//!  :X-battery 87)                                   <- user parameter, `X-` prefix
//! ```
//!
//! [`check_with`] runs the same parser without building the message: the same verdict and
//! errors as [`parse_with`], plus an [`AclSummary`] of the sender and receiver names, borrowed.
//!
//! Byte content travels as JADE sends it: `:X-JADE-Encoding Base64` plus the Base64 text as
//! `:content`; SC00070's `#N"bytes` form is read too.

mod check;
mod parse;
mod print;

use base64::engine::general_purpose::STANDARD;
use base64::{DecodeSliceError, Engine as _};

pub use check::{AclSummary, check, check_with};
pub use parse::{parse, parse_with};
pub use print::{print, print_into, print_with};

use crate::Error;

/// Bytes accepted by [`parse`] unless [`ParseOptions::max_len`] says otherwise (1 MiB).
pub const DEFAULT_MAX_LEN: usize = 1 << 20;

/// Agent identifiers nested through `:resolvers` accepted by default.
pub const DEFAULT_MAX_DEPTH: usize = 8;

/// The user parameter (without `X-`) that marks Base64 byte content, as JADE writes it.
pub const JADE_ENCODING_PARAM: &str = "JADE-Encoding";

/// How backslashes and quotes inside `"..."` strings are read and written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Escaping {
    /// A backslash takes the next character with it: `\"` is a quote, `\\` a backslash, any
    /// other `\x` stays as is. Every string can be written.
    #[default]
    Standard,
    /// JADE 4.x: a string ends at the first quote not preceded by a backslash, reading deletes
    /// each backslash right before a quote (so `\\` stays two backslashes), and writing escapes
    /// only `"`. A string ending in a backslash cannot be written ([`Error::NotRepresentable`]);
    /// JADE itself emits such strings unparseable.
    Jade,
}

/// Options for [`parse_with`] and [`check_with`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct ParseOptions {
    /// How strings are unescaped.
    pub escaping: Escaping,
    /// Longest input accepted, bytes (default [`DEFAULT_MAX_LEN`]).
    pub max_len: usize,
    /// Deepest `:resolvers` nesting accepted (default [`DEFAULT_MAX_DEPTH`]).
    pub max_depth: usize,
}

impl Default for ParseOptions {
    fn default() -> Self {
        Self {
            escaping: Escaping::Standard,
            max_len: DEFAULT_MAX_LEN,
            max_depth: DEFAULT_MAX_DEPTH,
        }
    }
}

impl ParseOptions {
    /// Default limits with JADE's escaping.
    pub fn jade() -> Self {
        Self {
            escaping: Escaping::Jade,
            ..Self::default()
        }
    }

    /// These options with another input limit.
    pub fn with_max_len(self, max_len: usize) -> Self {
        Self { max_len, ..self }
    }
}

/// Options for [`print_with`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct PrintOptions {
    /// How strings are escaped.
    pub escaping: Escaping,
}

impl PrintOptions {
    /// JADE's escaping.
    pub fn jade() -> Self {
        Self {
            escaping: Escaping::Jade,
        }
    }
}

/// Decodes standard Base64 (JADE's byte-content form).
pub(crate) fn decode_base64(text: &str) -> Result<Vec<u8>, Error> {
    STANDARD
        .decode(text.trim())
        .map_err(|err| base64_error(err, text))
}

/// Whether [`decode_base64`] would succeed, with its error if not; up to 1 KiB of decoded
/// bytes without allocating.
pub(crate) fn check_base64(text: &str) -> Result<(), Error> {
    let mut buffer = [0u8; 1024];
    let trimmed = text.trim();
    // With room for the decoder's estimate, `decode_slice` fails exactly as `decode` does.
    if base64::decoded_len_estimate(trimmed.len()) > buffer.len() {
        return decode_base64(text).map(drop);
    }
    match STANDARD.decode_slice(trimmed, &mut buffer) {
        Ok(_) => Ok(()),
        Err(DecodeSliceError::DecodeError(err)) => Err(base64_error(err, text)),
        Err(DecodeSliceError::OutputSliceTooSmall) => decode_base64(text).map(drop),
    }
}

fn base64_error(source: base64::DecodeError, text: &str) -> Error {
    Error::InvalidBase64 {
        source,
        start: text.chars().take(24).collect(),
    }
}
