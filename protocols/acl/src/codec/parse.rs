//! The SC00070 reader: a byte-level tokenizer feeding a recursive-descent parser. Tokens borrow
//! the input; only the values kept in the message are copied, and strings without backslashes
//! are copied without unescaping.

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
    if text.len() > options.max_len {
        return Err(Error::TooLarge { len: text.len(), limit: options.max_len });
    }
    let mut parser = Parser { text, pos: 0, escaping: options.escaping, max_depth: options.max_depth };
    let message = parser.message()?;
    let end = parser.next()?;
    if !matches!(end.kind, Kind::End) {
        return Err(parser.syntax(&end, "end of input after the message's closing `)`"));
    }
    Ok(message)
}

/// The message parameters SC00061 defines, in the order the printer writes them.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Param {
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
        exact.or_else(|| Self::ALL.iter().find(|(_, n)| is_keyword(name, n))).map(|&(p, _)| p)
    }
}

#[derive(Clone, Copy)]
enum Kind<'a> {
    Open,
    Close,
    /// A run of characters other than whitespace, parentheses and `"`.
    Word(&'a str),
    /// A `"..."` string's body, still escaped; `escaped` says whether it holds a backslash.
    Quoted { body: &'a str, escaped: bool },
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
fn scan(bytes: &[u8], from: usize, flags: impl Fn(u64) -> u64, is_hit: impl Fn(u8) -> bool) -> Option<usize> {
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
    bytes.get(i..)?.iter().position(|&b| is_hit(b)).map(|p| i + p)
}

/// The first index at or after `from` holding `a` or `b`.
fn find_either(bytes: &[u8], from: usize, a: u8, b: u8) -> Option<usize> {
    let (splat_a, splat_b) = (LOW * u64::from(a), LOW * u64::from(b));
    scan(bytes, from, |x| bytes_below(x ^ splat_a, 1) | bytes_below(x ^ splat_b, 1), |x| x == a || x == b)
}

/// The first delimiter (whitespace, parenthesis, quote) at or after `from`. Candidates are the
/// bytes below `#` (whitespace, `"`, also `!` and controls) and `(`/`)`.
fn find_delimiter(bytes: &[u8], from: usize) -> Option<usize> {
    let parens = LOW * 0x28;
    scan(bytes, from, |x| bytes_below(x, b'#') | bytes_below(x ^ parens, 2), |b| CLASS[usize::from(b)] & DELIMITER != 0)
}

impl<'a> Parser<'a> {
    /// 1-based line and column (in characters) of a byte offset.
    fn position(&self, offset: usize) -> (u32, u32) {
        let before = self.text.get(..offset).unwrap_or(self.text);
        let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before.get(line_start..).map_or(0, |s| s.chars().count()) + 1;
        (u32::try_from(line).unwrap_or(u32::MAX), u32::try_from(column).unwrap_or(u32::MAX))
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
            Kind::Quoted { body, .. } => format!("string \"{}\"", clip(body)),
            Kind::ByteString(bytes) => format!("byte string of {} bytes", bytes.len()),
            Kind::End => "end of input".to_owned(),
        }
    }

    fn syntax(&self, token: &Token<'_>, expected: &'static str) -> Error {
        let (line, column) = self.position(token.start);
        Error::Syntax { line, column, expected, found: Self::describe(token) }
    }

    fn invalid_value(&self, token: &Token<'_>, param: &str, reason: String) -> Error {
        let (line, column) = self.position(token.start);
        Error::InvalidValue { line, column, param: param.to_owned(), reason }
    }

    /// The next token; at the end of input, `Kind::End` (repeatedly).
    fn next(&mut self) -> Result<Token<'a>, Error> {
        let bytes = self.text.as_bytes();
        while bytes.get(self.pos).is_some_and(|&b| CLASS[usize::from(b)] & WHITESPACE != 0) {
            self.pos += 1;
        }
        let start = self.pos;
        let Some(&first) = bytes.get(start) else {
            return Ok(Token { kind: Kind::End, start });
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

    fn word(&mut self, start: usize) -> Result<Kind<'a>, Error> {
        let bytes = self.text.as_bytes();
        self.pos = find_delimiter(bytes, start).unwrap_or(bytes.len());
        self.slice(start, self.pos).map(Kind::Word)
    }

    /// `text[from..to]`, or an error if a byte string left the position inside a character.
    fn slice(&self, from: usize, to: usize) -> Result<&'a str, Error> {
        self.text.get(from..to).ok_or_else(|| {
            let (line, column) = self.position(from);
            Error::Syntax { line, column, expected: "UTF-8 text after a byte string", found: "a split character".to_owned() }
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
                    let Some(j) = find_either(bytes, i, b'"', b'\\') else { break last_escaped_quote };
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
            return Err(Error::Syntax { line, column, expected: "a closing `\"` for this string", found: "end of input".to_owned() });
        };
        self.pos = end + 1;
        let body = self.slice(body_start, end)?;
        Ok(Kind::Quoted { body, escaped })
    }

    /// `#N"` + N bytes; `None` when the `#` does not start one (it is then a word).
    fn byte_string(&mut self, start: usize) -> Result<Option<Kind<'a>>, Error> {
        let bytes = self.text.as_bytes();
        let digits = bytes[start + 1..].iter().take_while(|b| b.is_ascii_digit()).count();
        let quote = start + 1 + digits;
        if digits == 0 || bytes.get(quote) != Some(&b'"') {
            return Ok(None);
        }
        let len_text = self.slice(start + 1, quote)?;
        let body_start = quote + 1;
        let end = len_text.parse::<usize>().ok().and_then(|len| body_start.checked_add(len)).filter(|&end| end <= bytes.len());
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

    fn unescape(&self, body: &str, escaped: bool) -> String {
        if !escaped {
            return body.to_owned();
        }
        let mut out = String::with_capacity(body.len());
        let mut chars = body.chars().peekable();
        while let Some(c) = chars.next() {
            if c != '\\' {
                out.push(c);
                continue;
            }
            match (self.escaping, chars.peek()) {
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

    fn expect_open(&mut self, expected: &'static str) -> Result<Token<'a>, Error> {
        let token = self.next()?;
        match token.kind {
            Kind::Open => Ok(token),
            _ => Err(self.syntax(&token, expected)),
        }
    }

    fn expect_keyword(&mut self, keyword: &'static str, expected: &'static str) -> Result<(), Error> {
        let token = self.next()?;
        match token.kind {
            Kind::Word(word) if is_keyword(word, keyword) => Ok(()),
            _ => Err(self.syntax(&token, expected)),
        }
    }

    /// `(PERFORMATIVE :param value ...)`.
    fn message(&mut self) -> Result<AclMessage, Error> {
        self.expect_open("`(` opening an ACL message")?;
        let token = self.next()?;
        let Kind::Word(word) = token.kind else {
            return Err(self.syntax(&token, "a performative such as REQUEST"));
        };
        let performative = Performative::from_fipa_name(word).ok_or_else(|| {
            let (line, column) = self.position(token.start);
            Error::UnknownPerformative { line, column, word: word.to_owned() }
        })?;
        let mut message = AclMessage::new(performative);
        let mut seen = 0u16;
        let mut content_token = None;
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
                self.insert_user_param(&mut message.user_params, &token, name, value)?;
                continue;
            }
            let Some(param) = Param::lookup(name) else {
                let (line, column) = self.position(token.start);
                return Err(Error::UnknownParameter { line, column, name: name.to_owned() });
            };
            let bit = 1u16 << param as u16;
            if seen & bit != 0 {
                let (line, column) = self.position(token.start);
                return Err(Error::DuplicateParameter { line, column, name: name.to_owned() });
            }
            seen |= bit;
            match param {
                Param::Sender => {
                    let open = self.expect_open("`(agent-identifier ...)`")?;
                    message.sender = Some(self.agent_id(&open, 0)?);
                }
                Param::Receiver => message.receivers = self.agent_set()?,
                Param::ReplyTo => message.reply_to = self.agent_set()?,
                Param::Content => {
                    let value = self.next()?;
                    content_token = Some(value);
                    message.content = Some(match value.kind {
                        Kind::ByteString(bytes) => Content::Bytes(bytes.to_vec()),
                        _ => Content::Text(self.text_value(&value)?),
                    });
                }
                Param::ReplyBy => {
                    let value = self.next()?;
                    let text = self.text_value(&value)?;
                    let deadline = text.parse::<FipaDateTime>().map_err(|err| self.invalid_value(&value, name, err.to_string()))?;
                    message.reply_by = Some(deadline);
                }
                Param::Language => message.language = Some(self.next_text()?),
                Param::Encoding => message.encoding = Some(self.next_text()?),
                Param::Ontology => message.ontology = Some(self.next_text()?),
                Param::Protocol => message.protocol = Some(self.next_text()?),
                Param::ConversationId => message.conversation_id = Some(self.next_text()?),
                Param::ReplyWith => message.reply_with = Some(self.next_text()?),
                Param::InReplyTo => message.in_reply_to = Some(self.next_text()?),
            }
        }
        self.decode_jade_bytes(&mut message, content_token.as_ref())?;
        Ok(message)
    }

    /// JADE's byte content: `:X-JADE-Encoding Base64` turns the text content into bytes.
    fn decode_jade_bytes(&self, message: &mut AclMessage, content_token: Option<&Token<'_>>) -> Result<(), Error> {
        let Some(marker) = message.user_params.get(JADE_ENCODING_PARAM) else {
            return Ok(());
        };
        if !marker.eq_ignore_ascii_case("Base64") {
            return Ok(());
        }
        message.user_params.remove(JADE_ENCODING_PARAM);
        if let (Some(Content::Text(text)), Some(token)) = (&message.content, content_token) {
            let bytes = decode_base64(text).map_err(|err| self.invalid_value(token, "content", err.to_string()))?;
            message.content = Some(Content::Bytes(bytes));
        }
        Ok(())
    }

    fn insert_user_param(
        &self,
        params: &mut BTreeMap<String, String>,
        name_token: &Token<'_>,
        name: &str,
        value: String,
    ) -> Result<(), Error> {
        let key = user_key(name);
        if key.is_empty() {
            let (line, column) = self.position(name_token.start);
            return Err(Error::UnknownParameter { line, column, name: name.to_owned() });
        }
        if params.insert(key.to_owned(), value).is_some() {
            let (line, column) = self.position(name_token.start);
            return Err(Error::DuplicateParameter { line, column, name: name.to_owned() });
        }
        Ok(())
    }

    fn next_text(&mut self) -> Result<String, Error> {
        let token = self.next()?;
        self.text_value(&token)
    }

    /// A word (not a `:parameter`), a string, or a UTF-8 byte string, as an owned value.
    fn text_value(&self, token: &Token<'a>) -> Result<String, Error> {
        match token.kind {
            Kind::Word(word) if !word.starts_with(':') => Ok(word.to_owned()),
            Kind::Quoted { body, escaped } => Ok(self.unescape(body, escaped)),
            Kind::ByteString(bytes) => std::str::from_utf8(bytes)
                .map(str::to_owned)
                .map_err(|_| self.syntax(token, "UTF-8 text (only `:content` may hold raw bytes)")),
            _ => Err(self.syntax(token, "a word or a quoted string")),
        }
    }

    /// `(set (agent-identifier ...) ...)`.
    fn agent_set(&mut self) -> Result<Vec<AgentId>, Error> {
        self.expect_open("`(set (agent-identifier ...) ...)`")?;
        self.expect_keyword("set", "`set` (agent identifiers come as `(set ...)`)")?;
        let mut agents = Vec::new();
        loop {
            let token = self.next()?;
            match token.kind {
                Kind::Close => return Ok(agents),
                Kind::Open => agents.push(self.agent_id(&token, 0)?),
                _ => return Err(self.syntax(&token, "`(agent-identifier ...)` or `)` closing the set")),
            }
        }
    }

    /// The rest of `(agent-identifier :name ... )` after its `(`.
    fn agent_id(&mut self, open: &Token<'a>, depth: usize) -> Result<AgentId, Error> {
        if depth >= self.max_depth {
            let (line, column) = self.position(open.start);
            return Err(Error::TooDeep { line, column, limit: self.max_depth });
        }
        self.expect_keyword("agent-identifier", "`agent-identifier`")?;
        let mut name = None;
        let mut aid = AgentId::default();
        let (mut seen_addresses, mut seen_resolvers) = (false, false);
        loop {
            let token = self.next()?;
            let slot = match token.kind {
                Kind::Close => break,
                Kind::Word(word) if word.len() > 1 && word.starts_with(':') => &word[1..],
                _ => return Err(self.syntax(&token, "`:name`, `:addresses`, `:resolvers`, `:X-...` or `)`")),
            };
            let duplicate = if is_keyword(slot, "name") {
                name.replace(self.next_text()?).is_some()
            } else if is_keyword(slot, "addresses") {
                aid.addresses = self.sequence(|parser, token| parser.text_value(token))?;
                std::mem::replace(&mut seen_addresses, true)
            } else if is_keyword(slot, "resolvers") {
                aid.resolvers = self.sequence(|parser, token| match token.kind {
                    Kind::Open => parser.agent_id(token, depth + 1),
                    _ => Err(parser.syntax(token, "`(agent-identifier ...)` in the resolvers")),
                })?;
                std::mem::replace(&mut seen_resolvers, true)
            } else if is_user_param(slot) {
                let value_token = self.next()?;
                let value = self.text_value(&value_token)?;
                self.insert_user_param(&mut aid.user_params, &token, slot, value)?;
                false
            } else {
                let (line, column) = self.position(token.start);
                return Err(Error::UnknownParameter { line, column, name: slot.to_owned() });
            };
            if duplicate {
                let (line, column) = self.position(token.start);
                return Err(Error::DuplicateParameter { line, column, name: slot.to_owned() });
            }
        }
        let Some(name) = name else {
            let (line, column) = self.position(open.start);
            return Err(Error::MissingAgentName { line, column });
        };
        aid.name = name;
        Ok(aid)
    }

    /// `(sequence item*)`, each item read by `item` from its first token.
    fn sequence<T>(&mut self, mut item: impl FnMut(&mut Self, &Token<'a>) -> Result<T, Error>) -> Result<Vec<T>, Error> {
        self.expect_open("`(sequence ...)`")?;
        self.expect_keyword("sequence", "`sequence`")?;
        let mut items = Vec::new();
        loop {
            let token = self.next()?;
            if matches!(token.kind, Kind::Close) {
                return Ok(items);
            }
            items.push(item(self, &token)?);
        }
    }
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
        assert_eq!(parse(text).unwrap().content_text(), Some(r#"a\b "q" \" c\d"#));
        let jade = parse_with(text, &ParseOptions::jade()).unwrap();
        assert_eq!(jade.content_text(), Some(r#"a\\b "q" \\" c\d"#));
    }

    #[test]
    fn errors_say_where_and_what() {
        let err = parse("(INFORM\n  :content \"x\" oops)").unwrap_err();
        assert_eq!(
            err,
            Error::Syntax { line: 2, column: 16, expected: "a parameter such as `:receiver`, or `)`", found: "`oops`".into() }
        );
        assert!(matches!(parse("(INFORMS)"), Err(Error::UnknownPerformative { line: 1, column: 2, .. })));
        assert!(matches!(parse("(INFORM :conversationID c)"), Err(Error::UnknownParameter { .. })));
        assert!(matches!(parse("(INFORM :content \"a\" :content \"b\")"), Err(Error::DuplicateParameter { .. })));
        assert!(matches!(parse("(INFORM :content \"abc"), Err(Error::Syntax { line: 1, column: 18, .. })));
        assert!(matches!(parse("(INFORM :sender (agent-identifier))"), Err(Error::MissingAgentName { .. })));
        assert!(matches!(parse("(INFORM :reply-by 2099)"), Err(Error::InvalidValue { .. })));
        assert!(matches!(parse("(INFORM) (INFORM)"), Err(Error::Syntax { .. })));
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
        assert_eq!(jade.content, Some(Content::Bytes(vec![0, 1, 2, 255, 0x22, 0x5c])));
        assert!(jade.user_params.is_empty());
        let fipa = parse("(INFORM :content #3\"a\"b :language x)").unwrap();
        assert_eq!(fipa.content, Some(Content::Bytes(b"a\"b".to_vec())));
        assert!(matches!(parse("(INFORM :content #9\"ab)"), Err(Error::Syntax { .. })));
        assert!(matches!(parse("(INFORM :X-JADE-Encoding Base64 :content \"***\")"), Err(Error::InvalidValue { .. })));
    }

    #[test]
    fn fast_scans_agree_with_plain_searches() {
        let text = "abcdefgh\"ijklmnopqrs\\tuvwxyz0123456789\"é\\\"";
        let bytes = text.as_bytes();
        for from in 0..=bytes.len() + 2 {
            let naive = bytes.get(from..).and_then(|rest| rest.iter().position(|&b| b == b'"' || b == b'\\')).map(|p| from + p);
            assert_eq!(find_either(bytes, from, b'"', b'\\'), naive, "from {from}");
        }
        assert_eq!(find_either(&[0x80, 0x22 + 1, 0x01, 0x22], 0, b'"', b'"'), Some(3));
        let words = "a!b\x01c\u{80}(d)e f\"g\th\ni-j:k@l#m!!!!!!!!!!!!!!!!)";
        let bytes = words.as_bytes();
        for from in 0..=bytes.len() {
            let naive = bytes[from..].iter().position(|&b| CLASS[usize::from(b)] & DELIMITER != 0).map(|p| from + p);
            assert_eq!(find_delimiter(bytes, from), naive, "from {from}");
        }
    }

    #[test]
    fn byte_string_ending_inside_a_character_is_an_error_not_a_panic() {
        assert!(parse("(INFORM :content #1\"é)").is_err());
    }
}
