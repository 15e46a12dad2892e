//! The SC00070 reader: a byte-level tokenizer feeding one recursive-descent parser, generic over
//! what it builds. The grammar, every check and every error live in [`Parser`]; a [`Build`]er
//! only stores what it keeps. [`parse_with`] builds the owned [`AclMessage`] ([`MessageBuilder`]);
//! [`check_with`](super::check_with) builds a borrowed summary (`super::check`). Sharing the
//! parser is what makes the two accept and refuse exactly the same texts, with the same errors.
//!
//! Tokens borrow the input, and values reach the builder as [`RawText`], still in wire form: a
//! builder copies and unescapes only the values it keeps (strings without backslashes are copied
//! without unescaping).

use std::borrow::Cow;
use std::collections::BTreeMap;

use super::{Escaping, JADE_ENCODING_PARAM, ParseOptions, decode_base64};
use crate::message::user_key;
use crate::{AclMessage, AgentId, Content, Error, FipaDateTime, Performative};

/// Parses one message with [`ParseOptions::default`] (standard escaping, 1 MiB limit).
pub fn parse(text: &str) -> Result<AclMessage, Error> {
    parse_with(text, &ParseOptions::default())
}

/// Parses one message; only whitespace may follow its closing parenthesis.
pub fn parse_with(text: &str, options: &ParseOptions) -> Result<AclMessage, Error> {
    run(text, options, &mut MessageBuilder)
}

/// Reads one message from `text` into `builder`: the one entry to the grammar.
pub(super) fn run<'a, B: Build<'a>>(
    text: &'a str,
    options: &ParseOptions,
    builder: &mut B,
) -> Result<B::Message, Error> {
    if text.len() > options.max_len {
        return Err(Error::TooLarge {
            len: text.len(),
            limit: options.max_len,
        });
    }
    let mut parser = Parser {
        text,
        pos: 0,
        escaping: options.escaping,
        max_depth: options.max_depth,
    };
    let message = parser.message(builder)?;
    let end = parser.next()?;
    if !matches!(end.kind, Kind::End) {
        return Err(parser.syntax(&end, "end of input after the message's closing `)`"));
    }
    Ok(message)
}

/// The message parameters SC00061 defines, in the order the printer writes them.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Param {
    Sender,
    Receiver,
    ReplyTo,
    Content,
    Language,
    Encoding,
    Ontology,
    Protocol,
    ConversationId,
    ReplyWith,
    InReplyTo,
    ReplyBy,
}

impl Param {
    const ALL: [(Param, &'static str); 12] = [
        (Param::Sender, "sender"),
        (Param::Receiver, "receiver"),
        (Param::ReplyTo, "reply-to"),
        (Param::Content, "content"),
        (Param::Language, "language"),
        (Param::Encoding, "encoding"),
        (Param::Ontology, "ontology"),
        (Param::Protocol, "protocol"),
        (Param::ConversationId, "conversation-id"),
        (Param::ReplyWith, "reply-with"),
        (Param::InReplyTo, "in-reply-to"),
        (Param::ReplyBy, "reply-by"),
    ];

    fn lookup(name: &str) -> Option<Param> {
        let exact = Self::ALL.iter().find(|(_, n)| *n == name);
        exact
            .or_else(|| Self::ALL.iter().find(|(_, n)| is_keyword(name, n)))
            .map(|&(p, _)| p)
    }
}

/// A text value as it stands in the input, already checked (a word, a quoted string's body, or
/// a byte string that is UTF-8) but not yet unescaped.
#[derive(Clone, Copy, Debug)]
pub(super) struct RawText<'a> {
    body: &'a str,
    /// The escaping to undo.
    unescape: Unescape,
}

/// Whether and how a [`RawText`] is unescaped. Word-sized on purpose: with a one-byte field the
/// copies of a `RawText` (and of results holding one) move odd-sized pieces of padding, and the
/// loads that follow stall on store forwarding; that cost the parser about 15%.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(usize)]
enum Unescape {
    /// No backslash in it (or a word, which is never unescaped).
    No,
    /// A quoted string with a backslash, standard escaping.
    Standard,
    /// A quoted string with a backslash, JADE escaping.
    Jade,
}

impl<'a> RawText<'a> {
    fn plain(body: &'a str) -> Self {
        Self {
            body,
            unescape: Unescape::No,
        }
    }

    fn escaped(body: &'a str, escaping: Escaping) -> Self {
        let unescape = match escaping {
            Escaping::Standard => Unescape::Standard,
            Escaping::Jade => Unescape::Jade,
        };
        Self { body, unescape }
    }

    fn escaping(self) -> Option<Escaping> {
        match self.unescape {
            Unescape::No => None,
            Unescape::Standard => Some(Escaping::Standard),
            Unescape::Jade => Some(Escaping::Jade),
        }
    }

    /// The value, copied.
    pub(super) fn into_string(self) -> String {
        match self.escaping() {
            None => self.body.to_owned(),
            Some(escaping) => unescape(self.body, escaping),
        }
    }

    /// The value, borrowed from the input unless unescaping changes it.
    pub(super) fn into_cow(self) -> Cow<'a, str> {
        match self.escaping() {
            Some(escaping) if unescaping_changes(self.body, escaping) => {
                Cow::Owned(unescape(self.body, escaping))
            }
            _ => Cow::Borrowed(self.body),
        }
    }
}

/// A `:content` value: text, or the raw bytes of a `#N"` byte string.
#[derive(Clone, Copy, Debug)]
pub(super) enum RawContent<'a> {
    Text(RawText<'a>),
    Bytes(&'a [u8]),
}

/// What the parser builds. The parser alone decides what is accepted and which error is
/// returned (in the order the input is read); a builder stores values and cannot fail, except
/// in [`Build::base64_content`], whose error the parser places. So every builder accepts and
/// refuses exactly the same texts.
///
/// Calls follow the input: [`Build::message`], then one call per parameter as it is read; an
/// identifier starts with [`Build::agent`], receives its slots, gets its user parameters and name
/// last ([`Build::agent_params`], [`Build::agent_name`]) and is handed to [`Build::agent_param`]
/// or [`Build::resolver`]. User parameters are collected apart (in the parser's frame, made
/// only when there are some) so that the values handed around stay small.
pub(super) trait Build<'a> {
    /// The message being built, and the result.
    type Message;
    /// An agent identifier.
    type Agent;
    /// The user parameters of a message or an identifier, keyed without `X-`.
    type UserParams;

    /// A message with this performative and nothing else yet.
    fn message(&mut self, performative: Performative) -> Self::Message;
    /// An identifier with nothing in it yet.
    fn agent(&mut self) -> Self::Agent;
    /// No user parameters yet: made for a message or an identifier when its first is read.
    fn user_params(&mut self) -> Self::UserParams;
    /// Adds user parameter `key` (non-empty, without `X-`); false if `params` already has it.
    fn user_param(
        &mut self,
        params: &mut Self::UserParams,
        key: &'a str,
        value: RawText<'a>,
    ) -> bool;
    /// The message's user parameters, once its `)` is read (if it has any).
    fn message_params(&mut self, message: &mut Self::Message, params: Self::UserParams);
    /// The identifier's user parameters, once its `)` is read (if it has any).
    fn agent_params(&mut self, agent: &mut Self::Agent, params: Self::UserParams);
    /// `:sender` (once), or one member of the `:receiver` or `:reply-to` set, in order.
    fn agent_param(&mut self, message: &mut Self::Message, param: Param, agent: Self::Agent);
    /// `:language`, `:encoding`, `:ontology`, `:protocol`, `:conversation-id`, `:reply-with` or
    /// `:in-reply-to`.
    fn text_param(&mut self, message: &mut Self::Message, param: Param, value: RawText<'a>);
    /// `:content`.
    fn content(&mut self, message: &mut Self::Message, content: RawContent<'a>);
    /// `:reply-by`, already read as a date-time.
    fn reply_by(&mut self, message: &mut Self::Message, deadline: FipaDateTime);
    /// The message said `:X-JADE-Encoding Base64`: the marker is no user parameter of its own.
    fn remove_jade_marker(&mut self, message: &mut Self::Message);
    /// Under that marker, the text content holds Base64: decode it, or at least check that it
    /// decodes ([`Error::InvalidBase64`] if not).
    fn base64_content(
        &mut self,
        message: &mut Self::Message,
        content: RawText<'a>,
    ) -> Result<(), Error>;
    /// The identifier's `:name`, given after its other slots.
    fn agent_name(&mut self, agent: &mut Self::Agent, name: RawText<'a>);
    /// One of the identifier's `:addresses`, in order.
    fn address(&mut self, agent: &mut Self::Agent, address: RawText<'a>);
    /// One of the identifier's `:resolvers`, in order.
    fn resolver(&mut self, agent: &mut Self::Agent, resolver: Self::Agent);
}

#[derive(Clone, Copy)]
enum Kind<'a> {
    Open,
    Close,
    /// A run of characters other than whitespace, parentheses and `"`.
    Word(&'a str),
    /// A `"..."` string's body without a backslash.
    Quoted(&'a str),
    /// A `"..."` string's body holding a backslash, still escaped. (A variant rather than a flag
    /// keeps the token free of odd-sized fields, which the hot token copies stall on.)
    Escaped(&'a str),
    /// SC00070 `#N"` followed by N raw bytes.
    ByteString(&'a [u8]),
    End,
}

#[derive(Clone, Copy)]
struct Token<'a> {
    kind: Kind<'a>,
    /// Byte offset of the token's first character.
    start: usize,
}

/// The grammar: reads tokens and hands the values to a [`Build`]er.
///
/// The small steps every token goes through (`next`, `word`, `expect_*`, `next_text`,
/// `text_value`) are inlined into their callers. Out of line, each returned its `Result` through
/// memory (an `Error` makes it large), and the caller's wide load of a value just written in
/// narrower pieces stalled on store forwarding: inlined, the parser ran about a third faster.
struct Parser<'a> {
    text: &'a str,
    pos: usize,
    escaping: Escaping,
    max_depth: usize,
}

const WHITESPACE: u8 = 1;
const DELIMITER: u8 = 2;

/// Byte classes: whitespace (also a delimiter), and the delimiters that end a word.
static CLASS: [u8; 256] = {
    let mut table = [0u8; 256];
    let mut b = 0;
    while b < 256 {
        let byte = b as u8;
        if byte.is_ascii_whitespace() || byte == 0x0b {
            table[b] = WHITESPACE | DELIMITER;
        } else if matches!(byte, b'(' | b')' | b'"') {
            table[b] = DELIMITER;
        }
        b += 1;
    }
    table
};

const LOW: u64 = 0x0101_0101_0101_0101;
const HIGH: u64 = 0x8080_8080_8080_8080;

/// Flags (high bit) the bytes of `x` below `n` (n <= 128). The lowest flag is always exact:
/// borrows only create false flags above a true one.
fn bytes_below(x: u64, n: u8) -> u64 {
    x.wrapping_sub(LOW * u64::from(n)) & !x & HIGH
}

/// Scans `bytes` from `from` eight bytes at a time; `flags` marks candidate bytes of a chunk
/// (its lowest flag exact) and `is_hit` confirms one. Returns the first confirmed index.
fn scan(
    bytes: &[u8],
    from: usize,
    flags: impl Fn(u64) -> u64,
    is_hit: impl Fn(u8) -> bool,
) -> Option<usize> {
    let mut i = from;
    while let Some(chunk) = bytes.get(i..i + 8) {
        let mut word = [0u8; 8];
        word.copy_from_slice(chunk);
        let hits = flags(u64::from_le_bytes(word));
        if hits == 0 {
            i += 8;
            continue;
        }
        let at = i + (hits.trailing_zeros() / 8) as usize;
        if is_hit(bytes[at]) {
            return Some(at);
        }
        i = at + 1;
    }
    bytes
        .get(i..)?
        .iter()
        .position(|&b| is_hit(b))
        .map(|p| i + p)
}

/// The first index at or after `from` holding `a` or `b`.
fn find_either(bytes: &[u8], from: usize, a: u8, b: u8) -> Option<usize> {
    let (splat_a, splat_b) = (LOW * u64::from(a), LOW * u64::from(b));
    scan(
        bytes,
        from,
        |x| bytes_below(x ^ splat_a, 1) | bytes_below(x ^ splat_b, 1),
        |x| x == a || x == b,
    )
}

/// The first delimiter (whitespace, parenthesis, quote) at or after `from`. Candidates are the
/// bytes below `#` (whitespace, `"`, also `!` and controls) and `(`/`)`. Kept out of line so
/// that [`Parser::word`] can be inlined into [`Parser::next`] without copying the loop everywhere.
#[inline(never)]
fn find_delimiter(bytes: &[u8], from: usize) -> Option<usize> {
    let parens = LOW * 0x28;
    scan(
        bytes,
        from,
        |x| bytes_below(x, b'#') | bytes_below(x ^ parens, 2),
        |b| CLASS[usize::from(b)] & DELIMITER != 0,
    )
}

impl<'a> Parser<'a> {
    /// 1-based line and column (in characters) of a byte offset.
    fn position(&self, offset: usize) -> (u32, u32) {
        let before = self.text.get(..offset).unwrap_or(self.text);
        let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before.get(line_start..).map_or(0, |s| s.chars().count()) + 1;
        (
            u32::try_from(line).unwrap_or(u32::MAX),
            u32::try_from(column).unwrap_or(u32::MAX),
        )
    }

    fn describe(token: &Token<'_>) -> String {
        fn clip(s: &str) -> String {
            let mut clipped: String = s.chars().take(40).collect();
            if clipped.len() < s.len() {
                clipped.push_str("...");
            }
            clipped
        }
        match token.kind {
            Kind::Open => "`(`".to_owned(),
            Kind::Close => "`)`".to_owned(),
            Kind::Word(word) => format!("`{}`", clip(word)),
            Kind::Quoted(body) | Kind::Escaped(body) => format!("string \"{}\"", clip(body)),
            Kind::ByteString(bytes) => format!("byte string of {} bytes", bytes.len()),
            Kind::End => "end of input".to_owned(),
        }
    }

    fn syntax(&self, token: &Token<'_>, expected: &'static str) -> Error {
        let (line, column) = self.position(token.start);
        Error::Syntax {
            line,
            column,
            expected,
            found: Self::describe(token),
        }
    }

    fn invalid_value(&self, token: &Token<'_>, param: &str, source: Error) -> Error {
        let (line, column) = self.position(token.start);
        Error::InvalidValue {
            line,
            column,
            param: param.to_owned(),
            source: source.into(),
        }
    }

    /// The next token; at the end of input, `Kind::End` (repeatedly).
    #[inline(always)]
    fn next(&mut self) -> Result<Token<'a>, Error> {
        let bytes = self.text.as_bytes();
        while bytes
            .get(self.pos)
            .is_some_and(|&b| CLASS[usize::from(b)] & WHITESPACE != 0)
        {
            self.pos += 1;
        }
        let start = self.pos;
        let Some(&first) = bytes.get(start) else {
            return Ok(Token {
                kind: Kind::End,
                start,
            });
        };
        let kind = match first {
            b'(' => {
                self.pos += 1;
                Kind::Open
            }
            b')' => {
                self.pos += 1;
                Kind::Close
            }
            b'"' => self.quoted(start)?,
            b'#' => match self.byte_string(start)? {
                Some(kind) => kind,
                None => self.word(start)?,
            },
            _ => self.word(start)?,
        };
        Ok(Token { kind, start })
    }

    #[inline(always)]
    fn word(&mut self, start: usize) -> Result<Kind<'a>, Error> {
        let bytes = self.text.as_bytes();
        self.pos = find_delimiter(bytes, start).unwrap_or(bytes.len());
        self.slice(start, self.pos).map(Kind::Word)
    }

    /// `text[from..to]`, or an error if a byte string left the position inside a character.
    fn slice(&self, from: usize, to: usize) -> Result<&'a str, Error> {
        self.text.get(from..to).ok_or_else(|| {
            let (line, column) = self.position(from);
            Error::Syntax {
                line,
                column,
                expected: "UTF-8 text after a byte string",
                found: "a split character".to_owned(),
            }
        })
    }

    /// A `"..."` string. Standard: a backslash takes the next character with it. JADE (a
    /// longest-match JavaCC token `"` (~["\""] | "\\\"")* `"`): the string ends at the first
    /// quote not right after a backslash, or failing one, at the last quote of the input.
    fn quoted(&mut self, start: usize) -> Result<Kind<'a>, Error> {
        let bytes = self.text.as_bytes();
        let body_start = start + 1;
        let mut escaped = false;
        let mut i = body_start;
        let end = match self.escaping {
            Escaping::Standard => loop {
                match find_either(bytes, i, b'"', b'\\') {
                    Some(j) if bytes[j] == b'"' => break Some(j),
                    Some(j) => {
                        escaped = true;
                        i = j + 2;
                    }
                    None => break None,
                }
            },
            Escaping::Jade => {
                let mut last_escaped_quote = None;
                loop {
                    let Some(j) = find_either(bytes, i, b'"', b'\\') else {
                        break last_escaped_quote;
                    };
                    if bytes[j] == b'\\' {
                        escaped = true;
                    } else if bytes[j - 1] != b'\\' {
                        // `j - 1` is at least the opening quote.
                        break Some(j);
                    } else {
                        last_escaped_quote = Some(j);
                    }
                    i = j + 1;
                }
            }
        };
        let Some(end) = end else {
            let (line, column) = self.position(start);
            return Err(Error::Syntax {
                line,
                column,
                expected: "a closing `\"` for this string",
                found: "end of input".to_owned(),
            });
        };
        self.pos = end + 1;
        let body = self.slice(body_start, end)?;
        Ok(if escaped {
            Kind::Escaped(body)
        } else {
            Kind::Quoted(body)
        })
    }

    /// `#N"` + N bytes; `None` when the `#` does not start one (it is then a word).
    fn byte_string(&mut self, start: usize) -> Result<Option<Kind<'a>>, Error> {
        let bytes = self.text.as_bytes();
        let digits = bytes[start + 1..]
            .iter()
            .take_while(|b| b.is_ascii_digit())
            .count();
        let quote = start + 1 + digits;
        if digits == 0 || bytes.get(quote) != Some(&b'"') {
            return Ok(None);
        }
        let len_text = self.slice(start + 1, quote)?;
        let body_start = quote + 1;
        let end = len_text
            .parse::<usize>()
            .ok()
            .and_then(|len| body_start.checked_add(len))
            .filter(|&end| end <= bytes.len());
        let Some(end) = end else {
            let (line, column) = self.position(start);
            return Err(Error::Syntax {
                line,
                column,
                expected: "as many bytes as the byte string's length",
                found: format!("{} bytes to the end of input", bytes.len() - body_start),
            });
        };
        self.pos = end;
        Ok(Some(Kind::ByteString(&bytes[body_start..end])))
    }

    #[inline(always)]
    fn expect_open(&mut self, expected: &'static str) -> Result<Token<'a>, Error> {
        let token = self.next()?;
        match token.kind {
            Kind::Open => Ok(token),
            _ => Err(self.syntax(&token, expected)),
        }
    }

    #[inline(always)]
    fn expect_keyword(
        &mut self,
        keyword: &'static str,
        expected: &'static str,
    ) -> Result<(), Error> {
        let token = self.next()?;
        match token.kind {
            Kind::Word(word) if is_keyword(word, keyword) => Ok(()),
            _ => Err(self.syntax(&token, expected)),
        }
    }

    /// `(PERFORMATIVE :param value ...)`.
    fn message<B: Build<'a>>(&mut self, builder: &mut B) -> Result<B::Message, Error> {
        self.expect_open("`(` opening an ACL message")?;
        let token = self.next()?;
        let Kind::Word(word) = token.kind else {
            return Err(self.syntax(&token, "a performative such as REQUEST"));
        };
        let performative = Performative::from_fipa_name(word).ok_or_else(|| {
            let (line, column) = self.position(token.start);
            Error::UnknownPerformative {
                line,
                column,
                word: word.to_owned(),
            }
        })?;
        let mut message = builder.message(performative);
        let mut seen = 0u16;
        // The text content and its token, and JADE's byte-content marker, for the Base64 check.
        let mut text_content = None;
        let mut jade_encoding = None;
        let mut user_params = None;
        loop {
            let token = self.next()?;
            let name = match token.kind {
                Kind::Close => break,
                Kind::Word(word) if word.len() > 1 && word.starts_with(':') => &word[1..],
                _ => return Err(self.syntax(&token, "a parameter such as `:receiver`, or `)`")),
            };
            if is_user_param(name) {
                let value_token = self.next()?;
                let value = self.text_value(&value_token)?;
                let params = user_params.get_or_insert_with(|| builder.user_params());
                let key = self.insert_user_param(builder, params, &token, name, value)?;
                if key == JADE_ENCODING_PARAM {
                    jade_encoding = Some(value);
                }
                continue;
            }
            let Some(param) = Param::lookup(name) else {
                let (line, column) = self.position(token.start);
                return Err(Error::UnknownParameter {
                    line,
                    column,
                    name: name.to_owned(),
                });
            };
            let bit = 1u16 << param as u16;
            if seen & bit != 0 {
                let (line, column) = self.position(token.start);
                return Err(Error::DuplicateParameter {
                    line,
                    column,
                    name: name.to_owned(),
                });
            }
            seen |= bit;
            match param {
                Param::Sender => {
                    let open = self.expect_open("`(agent-identifier ...)`")?;
                    let sender = self.agent_id(builder, &open, 0)?;
                    builder.agent_param(&mut message, param, sender);
                }
                Param::Receiver | Param::ReplyTo => self.agent_set(builder, &mut message, param)?,
                Param::Content => {
                    let value = self.next()?;
                    let content = match value.kind {
                        Kind::ByteString(bytes) => RawContent::Bytes(bytes),
                        _ => {
                            let text = self.text_value(&value)?;
                            text_content = Some((value, text));
                            RawContent::Text(text)
                        }
                    };
                    builder.content(&mut message, content);
                }
                Param::ReplyBy => {
                    let value = self.next()?;
                    let text = self.text_value(&value)?.into_cow();
                    let deadline = text
                        .parse::<FipaDateTime>()
                        .map_err(|err| self.invalid_value(&value, name, err))?;
                    builder.reply_by(&mut message, deadline);
                }
                Param::Language
                | Param::Encoding
                | Param::Ontology
                | Param::Protocol
                | Param::ConversationId
                | Param::ReplyWith
                | Param::InReplyTo => {
                    let value = self.next_text()?;
                    builder.text_param(&mut message, param, value);
                }
            }
        }
        if let Some(params) = user_params {
            builder.message_params(&mut message, params);
        }
        // JADE's byte content: `:X-JADE-Encoding Base64` turns the text content into bytes.
        if jade_encoding
            .is_some_and(|marker: RawText<'_>| marker.into_cow().eq_ignore_ascii_case("Base64"))
        {
            builder.remove_jade_marker(&mut message);
            if let Some((token, text)) = text_content {
                builder
                    .base64_content(&mut message, text)
                    .map_err(|err| self.invalid_value(&token, "content", err))?;
            }
        }
        Ok(message)
    }

    /// Checks a user parameter's key and hands it to the builder; returns the key (without `X-`).
    fn insert_user_param<B: Build<'a>>(
        &self,
        builder: &mut B,
        params: &mut B::UserParams,
        name_token: &Token<'_>,
        name: &'a str,
        value: RawText<'a>,
    ) -> Result<&'a str, Error> {
        let key = user_key(name);
        if key.is_empty() {
            let (line, column) = self.position(name_token.start);
            return Err(Error::UnknownParameter {
                line,
                column,
                name: name.to_owned(),
            });
        }
        if !builder.user_param(params, key, value) {
            let (line, column) = self.position(name_token.start);
            return Err(Error::DuplicateParameter {
                line,
                column,
                name: name.to_owned(),
            });
        }
        Ok(key)
    }

    #[inline(always)]
    fn next_text(&mut self) -> Result<RawText<'a>, Error> {
        let token = self.next()?;
        self.text_value(&token)
    }

    /// A word (not a `:parameter`), a string, or a UTF-8 byte string.
    #[inline(always)]
    fn text_value(&self, token: &Token<'a>) -> Result<RawText<'a>, Error> {
        match token.kind {
            Kind::Word(word) if !word.starts_with(':') => Ok(RawText::plain(word)),
            Kind::Quoted(body) => Ok(RawText::plain(body)),
            Kind::Escaped(body) => Ok(RawText::escaped(body, self.escaping)),
            Kind::ByteString(bytes) => std::str::from_utf8(bytes)
                .map(RawText::plain)
                .map_err(|_| self.syntax(token, "UTF-8 text (only `:content` may hold raw bytes)")),
            _ => Err(self.syntax(token, "a word or a quoted string")),
        }
    }

    /// `(set (agent-identifier ...) ...)`, each member handed to the builder as `param`.
    fn agent_set<B: Build<'a>>(
        &mut self,
        builder: &mut B,
        message: &mut B::Message,
        param: Param,
    ) -> Result<(), Error> {
        self.expect_open("`(set (agent-identifier ...) ...)`")?;
        self.expect_keyword("set", "`set` (agent identifiers come as `(set ...)`)")?;
        loop {
            let token = self.next()?;
            match token.kind {
                Kind::Close => return Ok(()),
                Kind::Open => {
                    let agent = self.agent_id(builder, &token, 0)?;
                    builder.agent_param(message, param, agent);
                }
                _ => {
                    return Err(
                        self.syntax(&token, "`(agent-identifier ...)` or `)` closing the set")
                    );
                }
            }
        }
    }

    /// The rest of `(agent-identifier :name ... )` after its `(`.
    fn agent_id<B: Build<'a>>(
        &mut self,
        builder: &mut B,
        open: &Token<'a>,
        depth: usize,
    ) -> Result<B::Agent, Error> {
        if depth >= self.max_depth {
            let (line, column) = self.position(open.start);
            return Err(Error::TooDeep {
                line,
                column,
                limit: self.max_depth,
            });
        }
        self.expect_keyword("agent-identifier", "`agent-identifier`")?;
        let mut name = None;
        let mut agent = builder.agent();
        let mut user_params = None;
        let (mut seen_addresses, mut seen_resolvers) = (false, false);
        loop {
            let token = self.next()?;
            let slot = match token.kind {
                Kind::Close => break,
                Kind::Word(word) if word.len() > 1 && word.starts_with(':') => &word[1..],
                _ => {
                    return Err(self.syntax(
                        &token,
                        "`:name`, `:addresses`, `:resolvers`, `:X-...` or `)`",
                    ));
                }
            };
            let duplicate = if is_keyword(slot, "name") {
                name.replace(self.next_text()?).is_some()
            } else if is_keyword(slot, "addresses") {
                self.sequence(|parser, token| {
                    builder.address(&mut agent, parser.text_value(token)?);
                    Ok(())
                })?;
                std::mem::replace(&mut seen_addresses, true)
            } else if is_keyword(slot, "resolvers") {
                self.sequence(|parser, token| match token.kind {
                    Kind::Open => {
                        let resolver = parser.agent_id(builder, token, depth + 1)?;
                        builder.resolver(&mut agent, resolver);
                        Ok(())
                    }
                    _ => Err(parser.syntax(token, "`(agent-identifier ...)` in the resolvers")),
                })?;
                std::mem::replace(&mut seen_resolvers, true)
            } else if is_user_param(slot) {
                let value_token = self.next()?;
                let value = self.text_value(&value_token)?;
                let params = user_params.get_or_insert_with(|| builder.user_params());
                self.insert_user_param(builder, params, &token, slot, value)?;
                false
            } else {
                let (line, column) = self.position(token.start);
                return Err(Error::UnknownParameter {
                    line,
                    column,
                    name: slot.to_owned(),
                });
            };
            if duplicate {
                let (line, column) = self.position(token.start);
                return Err(Error::DuplicateParameter {
                    line,
                    column,
                    name: slot.to_owned(),
                });
            }
        }
        let Some(name) = name else {
            let (line, column) = self.position(open.start);
            return Err(Error::MissingAgentName { line, column });
        };
        if let Some(params) = user_params {
            builder.agent_params(&mut agent, params);
        }
        builder.agent_name(&mut agent, name);
        Ok(agent)
    }

    /// `(sequence item*)`, each item read by `item` from its first token.
    fn sequence(
        &mut self,
        mut item: impl FnMut(&mut Self, &Token<'a>) -> Result<(), Error>,
    ) -> Result<(), Error> {
        self.expect_open("`(sequence ...)`")?;
        self.expect_keyword("sequence", "`sequence`")?;
        loop {
            let token = self.next()?;
            if matches!(token.kind, Kind::Close) {
                return Ok(());
            }
            item(self, &token)?;
        }
    }
}

/// Builds the owned [`AclMessage`] of [`parse_with`].
struct MessageBuilder;

impl<'a> Build<'a> for MessageBuilder {
    type Message = AclMessage;
    type Agent = AgentId;
    type UserParams = BTreeMap<String, String>;

    fn message(&mut self, performative: Performative) -> AclMessage {
        AclMessage::new(performative)
    }

    fn agent(&mut self) -> AgentId {
        AgentId::default()
    }

    fn user_params(&mut self) -> Self::UserParams {
        BTreeMap::new()
    }

    fn message_params(&mut self, message: &mut AclMessage, params: Self::UserParams) {
        message.user_params = params;
    }

    fn agent_params(&mut self, agent: &mut AgentId, params: Self::UserParams) {
        agent.user_params = params;
    }

    fn user_param(
        &mut self,
        params: &mut Self::UserParams,
        key: &'a str,
        value: RawText<'a>,
    ) -> bool {
        params.insert(key.to_owned(), value.into_string()).is_none()
    }

    fn agent_param(&mut self, message: &mut AclMessage, param: Param, agent: AgentId) {
        match param {
            Param::Sender => message.sender = Some(agent),
            Param::Receiver => message.receivers.push(agent),
            _ => message.reply_to.push(agent),
        }
    }

    fn text_param(&mut self, message: &mut AclMessage, param: Param, value: RawText<'a>) {
        let slot = match param {
            Param::Language => &mut message.language,
            Param::Encoding => &mut message.encoding,
            Param::Ontology => &mut message.ontology,
            Param::Protocol => &mut message.protocol,
            Param::ConversationId => &mut message.conversation_id,
            Param::ReplyWith => &mut message.reply_with,
            _ => &mut message.in_reply_to,
        };
        *slot = Some(value.into_string());
    }

    fn content(&mut self, message: &mut AclMessage, content: RawContent<'a>) {
        message.content = Some(match content {
            RawContent::Text(text) => Content::Text(text.into_string()),
            RawContent::Bytes(bytes) => Content::Bytes(bytes.to_vec()),
        });
    }

    fn reply_by(&mut self, message: &mut AclMessage, deadline: FipaDateTime) {
        message.reply_by = Some(deadline);
    }

    fn remove_jade_marker(&mut self, message: &mut AclMessage) {
        message.user_params.remove(JADE_ENCODING_PARAM);
    }

    fn base64_content(
        &mut self,
        message: &mut AclMessage,
        _content: RawText<'a>,
    ) -> Result<(), Error> {
        // The text was unescaped into the message already.
        if let Some(Content::Text(text)) = &message.content {
            message.content = Some(Content::Bytes(decode_base64(text)?));
        }
        Ok(())
    }

    fn agent_name(&mut self, agent: &mut AgentId, name: RawText<'a>) {
        agent.name = name.into_string();
    }

    fn address(&mut self, agent: &mut AgentId, address: RawText<'a>) {
        agent.addresses.push(address.into_string());
    }

    fn resolver(&mut self, agent: &mut AgentId, resolver: AgentId) {
        agent.resolvers.push(resolver);
    }
}

/// A string body with its escapes undone.
fn unescape(body: &str, escaping: Escaping) -> String {
    let mut out = String::with_capacity(body.len());
    let mut chars = body.chars().peekable();
    while let Some(c) = chars.next() {
        if c != '\\' {
            out.push(c);
            continue;
        }
        match (escaping, chars.peek()) {
            // JADE deletes exactly the backslashes that precede a quote.
            (Escaping::Jade, Some('"')) => {}
            (Escaping::Jade, _) => out.push('\\'),
            (Escaping::Standard, Some(&next @ ('"' | '\\'))) => {
                out.push(next);
                chars.next();
            }
            (Escaping::Standard, _) => out.push('\\'),
        }
    }
    out
}

/// Whether [`unescape`] changes `body`: it holds `\"` or (standard escaping) `\\`. Every such
/// pair either starts an escape or follows one.
fn unescaping_changes(body: &str, escaping: Escaping) -> bool {
    body.as_bytes().windows(2).any(|pair| {
        pair[0] == b'\\'
            && (pair[1] == b'"' || (pair[1] == b'\\' && escaping == Escaping::Standard))
    })
}

/// `word` is `keyword` in any case (the usual lower case compared first: it is the hot path).
fn is_keyword(word: &str, keyword: &str) -> bool {
    word == keyword || word.eq_ignore_ascii_case(keyword)
}

/// `X-...` (any case) names a user-defined parameter.
fn is_user_param(name: &str) -> bool {
    name.len() >= 2 && name.as_bytes()[..2].eq_ignore_ascii_case(b"x-")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::ParseOptions;

    #[test]
    fn parses_a_full_message() {
        let text = "(request :sender (agent-identifier :name a@P :addresses (sequence http://h:1/acc))\n \
                    :receiver (set (AGENT-IDENTIFIER :name b@P) (agent-identifier :name c@P :resolvers (sequence (agent-identifier :name r))))\n \
                    :content \"(x \\\"y\\\")\" :reply-by 20991231T235959000Z :X-battery 87 :conversation-id c1)";
        let m = parse(text).unwrap();
        assert_eq!(m.performative, Performative::Request);
        assert_eq!(m.sender.as_ref().unwrap().addresses, ["http://h:1/acc"]);
        assert_eq!(m.receivers.len(), 2);
        assert_eq!(m.receivers[1].resolvers[0].name, "r");
        assert_eq!(m.content_text(), Some("(x \"y\")"));
        assert_eq!(m.reply_by.unwrap().to_string(), "20991231T235959000Z");
        assert_eq!(m.user_param("battery"), Some("87"));
        assert_eq!(m.conversation_id.as_deref(), Some("c1"));
    }

    #[test]
    fn escaping_modes_differ_only_on_backslashes() {
        let text = r#"(INFORM :content "a\\b \"q\" \\\" c\d")"#;
        assert_eq!(
            parse(text).unwrap().content_text(),
            Some(r#"a\b "q" \" c\d"#)
        );
        let jade = parse_with(text, &ParseOptions::jade()).unwrap();
        assert_eq!(jade.content_text(), Some(r#"a\\b "q" \\" c\d"#));
    }

    #[test]
    fn errors_say_where_and_what() {
        let err = parse("(INFORM\n  :content \"x\" oops)").unwrap_err();
        assert_eq!(
            err,
            Error::Syntax {
                line: 2,
                column: 16,
                expected: "a parameter such as `:receiver`, or `)`",
                found: "`oops`".into()
            }
        );
        assert!(matches!(
            parse("(INFORMS)"),
            Err(Error::UnknownPerformative {
                line: 1,
                column: 2,
                ..
            })
        ));
        assert!(matches!(
            parse("(INFORM :conversationID c)"),
            Err(Error::UnknownParameter { .. })
        ));
        assert!(matches!(
            parse("(INFORM :content \"a\" :content \"b\")"),
            Err(Error::DuplicateParameter { .. })
        ));
        assert!(matches!(
            parse("(INFORM :content \"abc"),
            Err(Error::Syntax {
                line: 1,
                column: 18,
                ..
            })
        ));
        assert!(matches!(
            parse("(INFORM :sender (agent-identifier))"),
            Err(Error::MissingAgentName { .. })
        ));
        assert!(matches!(
            parse("(INFORM :reply-by 2099)"),
            Err(Error::InvalidValue { .. })
        ));
        assert!(matches!(
            parse("(INFORM) (INFORM)"),
            Err(Error::Syntax { .. })
        ));
        assert!(matches!(parse(""), Err(Error::Syntax { .. })));
    }

    #[test]
    fn size_and_depth_are_limited() {
        let err = parse_with("(INFORM)", &ParseOptions::default().with_max_len(4)).unwrap_err();
        assert_eq!(err, Error::TooLarge { len: 8, limit: 4 });
        let mut nested = String::from("(INFORM :sender ");
        for _ in 0..20 {
            nested.push_str("(agent-identifier :name a :resolvers (sequence ");
        }
        assert!(matches!(parse(&nested), Err(Error::TooDeep { .. })));
    }

    #[test]
    fn byte_content_in_both_wire_forms() {
        let jade = parse("(INFORM :X-JADE-Encoding Base64 :content \"AAEC/yJc\")").unwrap();
        assert_eq!(
            jade.content,
            Some(Content::Bytes(vec![0, 1, 2, 255, 0x22, 0x5c]))
        );
        assert!(jade.user_params.is_empty());
        let fipa = parse("(INFORM :content #3\"a\"b :language x)").unwrap();
        assert_eq!(fipa.content, Some(Content::Bytes(b"a\"b".to_vec())));
        assert!(matches!(
            parse("(INFORM :content #9\"ab)"),
            Err(Error::Syntax { .. })
        ));
        assert!(matches!(
            parse("(INFORM :X-JADE-Encoding Base64 :content \"***\")"),
            Err(Error::InvalidValue { .. })
        ));
    }

    #[test]
    fn a_value_that_does_not_decode_keeps_the_decoders_error() {
        use std::error::Error as _;
        let err = parse("(INFORM :X-JADE-Encoding Base64 :content \"***\")").unwrap_err();
        let inner = err
            .source()
            .and_then(|s| s.downcast_ref::<Error>())
            .unwrap_or_else(|| panic!("no value error under `{err}`"));
        assert!(matches!(inner, Error::InvalidBase64 { .. }), "{inner}");
        let base64 = inner
            .source()
            .and_then(|s| s.downcast_ref::<base64::DecodeError>())
            .unwrap_or_else(|| panic!("no Base64 error under `{inner}`"));
        assert!(err.to_string().contains(&base64.to_string()), "{err}");
    }

    #[test]
    fn fast_scans_agree_with_plain_searches() {
        let text = "abcdefgh\"ijklmnopqrs\\tuvwxyz0123456789\"é\\\"";
        let bytes = text.as_bytes();
        for from in 0..=bytes.len() + 2 {
            let naive = bytes
                .get(from..)
                .and_then(|rest| rest.iter().position(|&b| b == b'"' || b == b'\\'))
                .map(|p| from + p);
            assert_eq!(find_either(bytes, from, b'"', b'\\'), naive, "from {from}");
        }
        assert_eq!(
            find_either(&[0x80, 0x22 + 1, 0x01, 0x22], 0, b'"', b'"'),
            Some(3)
        );
        let words = "a!b\x01c\u{80}(d)e f\"g\th\ni-j:k@l#m!!!!!!!!!!!!!!!!)";
        let bytes = words.as_bytes();
        for from in 0..=bytes.len() {
            let naive = bytes[from..]
                .iter()
                .position(|&b| CLASS[usize::from(b)] & DELIMITER != 0)
                .map(|p| from + p);
            assert_eq!(find_delimiter(bytes, from), naive, "from {from}");
        }
    }

    #[test]
    fn unescaping_changes_exactly_when_unescape_does() {
        let mut bodies = vec![String::new()];
        for _ in 0..5 {
            let longer: Vec<String> = bodies
                .iter()
                .flat_map(|body| ["\\", "\"", "a"].map(|c| format!("{body}{c}")))
                .collect();
            bodies.extend(longer);
        }
        for body in &bodies {
            for escaping in [Escaping::Standard, Escaping::Jade] {
                assert_eq!(
                    unescaping_changes(body, escaping),
                    unescape(body, escaping) != *body,
                    "{body:?} {escaping:?}"
                );
            }
        }
    }

    #[test]
    fn byte_string_ending_inside_a_character_is_an_error_not_a_panic() {
        assert!(parse("(INFORM :content #1\"é)").is_err());
    }
}
