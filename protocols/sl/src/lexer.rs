//! Tokens of SL text.
//!
//! Like JADE's token manager the lexer has two states: right after `(` it is in *operator* state
//! and recognises the keywords (`action`, `not`, `iota`, `B`, `+`, ...) besides words, strings and
//! `??meta` symbols; everywhere else it recognises terms (variables, numbers, dates, byte strings,
//! `:parameters`). Within a state the longest match wins, ties go to the earlier token kind, and
//! keywords match in any ASCII case (so `Born-Agent` is a word, `born` too, but `b` is `B`).

use crate::ast::{ActionOp, ArithmeticOp, BinaryOp, ModalOp, Quantifier, ReferentialOp};
use crate::error::SlError;

/// Keywords, recognised only right after `(`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Keyword {
    Action,
    Referential(ReferentialOp),
    Modal(ModalOp),
    Arithmetic(ArithmeticOp),
    ActionOp(ActionOp),
    Alternative,
    Sequence,
    Not,
    Binary(BinaryOp),
    Quantifier(Quantifier),
}

/// Keyword spellings, in JADE's token order (earlier wins a tie with a word of equal length).
const KEYWORDS: [(&str, Keyword); 24] = [
    ("action", Keyword::Action),
    ("iota", Keyword::Referential(ReferentialOp::Iota)),
    ("any", Keyword::Referential(ReferentialOp::Any)),
    ("all", Keyword::Referential(ReferentialOp::All)),
    ("B", Keyword::Modal(ModalOp::B)),
    ("U", Keyword::Modal(ModalOp::U)),
    ("PG", Keyword::Modal(ModalOp::PG)),
    ("I", Keyword::Modal(ModalOp::I)),
    ("+", Keyword::Arithmetic(ArithmeticOp::Add)),
    ("-", Keyword::Arithmetic(ArithmeticOp::Sub)),
    ("*", Keyword::Arithmetic(ArithmeticOp::Mul)),
    ("/", Keyword::Arithmetic(ArithmeticOp::Div)),
    ("%", Keyword::Arithmetic(ArithmeticOp::Rem)),
    ("feasible", Keyword::ActionOp(ActionOp::Feasible)),
    ("done", Keyword::ActionOp(ActionOp::Done)),
    ("|", Keyword::Alternative),
    (";", Keyword::Sequence),
    ("not", Keyword::Not),
    ("and", Keyword::Binary(BinaryOp::And)),
    ("or", Keyword::Binary(BinaryOp::Or)),
    ("implies", Keyword::Binary(BinaryOp::Implies)),
    ("equiv", Keyword::Binary(BinaryOp::Equiv)),
    ("forall", Keyword::Quantifier(Quantifier::Forall)),
    ("exists", Keyword::Quantifier(Quantifier::Exists)),
];

/// The keyword spelled `s` (any ASCII case), if it is one.
pub(crate) fn keyword(s: &str) -> Option<Keyword> {
    KEYWORDS
        .iter()
        .find(|(k, _)| k.eq_ignore_ascii_case(s))
        .map(|&(_, kw)| kw)
}

/// A token kind; slices borrow the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Tok<'a> {
    LParen,
    RParen,
    Keyword(Keyword),
    /// A bare word.
    Word(&'a str),
    /// A quoted string, quotes included (unescape with [`unescape`]).
    Quoted(&'a str),
    /// `?name` (text after `?`, possibly quoted).
    Variable(&'a str),
    /// `??name`, with its `??`.
    Meta(&'a str),
    Integer(&'a str),
    Hex(&'a str),
    Float(&'a str),
    DateTime(&'a str),
    /// Payload of `#N"...`.
    Bytes(&'a str),
    /// `:name` (text after `:`, possibly quoted).
    Param(&'a str),
    Eof,
}

impl Tok<'_> {
    /// How the token reads in an error message.
    pub(crate) fn describe(&self) -> String {
        match self {
            Tok::LParen => "\"(\"".into(),
            Tok::RParen => "\")\"".into(),
            Tok::Keyword(k) => {
                let name = KEYWORDS
                    .iter()
                    .find(|(_, kw)| kw == k)
                    .map_or("?", |(s, _)| s);
                format!("keyword {name:?}")
            }
            Tok::Word(s) => format!("word {s:?}"),
            Tok::Quoted(s) => format!("string {s}"),
            Tok::Variable(s) => format!("variable \"?{s}\""),
            Tok::Meta(s) => format!("meta symbol {s:?}"),
            Tok::Integer(s) | Tok::Hex(s) | Tok::Float(s) => format!("number {s:?}"),
            Tok::DateTime(s) => format!("date {s:?}"),
            Tok::Bytes(_) => "byte string".into(),
            Tok::Param(s) => format!("parameter \":{s}\""),
            Tok::Eof => "end of input".into(),
        }
    }
}

/// A token and its byte offset.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Token<'a> {
    pub tok: Tok<'a>,
    pub offset: usize,
}

/// The SL lexer.
pub(crate) struct Lexer<'a> {
    src: &'a str,
    pos: usize,
    operator_state: bool,
}

/// 1-based (line, column in characters) of byte `offset` in `src`.
pub(crate) fn line_column(src: &str, offset: usize) -> (usize, usize) {
    let before = src.get(..offset).unwrap_or(src);
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before.get(line_start..).map_or(0, |s| s.chars().count()) + 1;
    (line, column)
}

fn is_word_start(b: u8) -> bool {
    b > 0x20
        && !matches!(
            b,
            b'(' | b')' | b'"' | b'#' | b'0'..=b'9' | b':' | b'-' | b'?'
        )
}

fn is_word_rest(b: u8) -> bool {
    b > 0x20 && !matches!(b, b'(' | b')' | b'"')
}

/// Length of a WORD at the start of `s` (0 if none).
pub(crate) fn word_len(s: &[u8]) -> usize {
    match s.first() {
        Some(&b) if is_word_start(b) => 1 + s[1..].iter().take_while(|&&b| is_word_rest(b)).count(),
        _ => 0,
    }
}

/// Length of a string literal at the start of `s` (which starts with `"`), longest match: a quote
/// preceded by a backslash may be an escaped quote inside the string, so the literal runs to the
/// last quote reachable through escaped ones. `None` when unterminated.
pub(crate) fn quoted_len(s: &[u8]) -> Option<usize> {
    let mut end = None;
    let mut i = 1;
    while i < s.len() {
        if s[i] == b'"' {
            end = Some(i + 1);
            if s[i - 1] != b'\\' {
                break;
            }
        }
        i += 1;
    }
    end
}

/// The text of a quoted literal: quotes dropped, `\"` turned into `"`, nothing else unescaped
/// (the inverse of the printer's escaping, and exactly what JADE does).
pub(crate) fn unescape(quoted: &str) -> String {
    let bytes = quoted.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 1;
    // Like JADE, the look-ahead may see the closing quote: `"a\"` reads as `a"`.
    while i + 1 < bytes.len() {
        if bytes[i] == b'\\' && bytes[i + 1] == b'"' {
            out.push(b'"');
            i += 2;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    // Only ASCII bytes were replaced, so the result is still UTF-8.
    String::from_utf8(out).unwrap_or_default()
}

fn digits(s: &[u8]) -> usize {
    s.iter().take_while(|b| b.is_ascii_digit()).count()
}

fn sign(s: &[u8]) -> usize {
    usize::from(matches!(s.first(), Some(b'+' | b'-')))
}

fn integer_len(s: &[u8]) -> usize {
    let sg = sign(s);
    match digits(&s[sg..]) {
        0 => 0,
        d => sg + d,
    }
}

fn hex_len(s: &[u8]) -> usize {
    let sg = sign(s);
    let rest = &s[sg..];
    if rest.len() >= 3 && rest[0] == b'0' && matches!(rest[1], b'x' | b'X') {
        match rest[2..]
            .iter()
            .take_while(|b| b.is_ascii_hexdigit())
            .count()
        {
            0 => 0,
            h => sg + 2 + h,
        }
    } else {
        0
    }
}

fn exponent_len(s: &[u8]) -> usize {
    if !matches!(s.first(), Some(b'e' | b'E')) {
        return 0;
    }
    let sg = sign(&s[1..]);
    match digits(&s[1 + sg..]) {
        0 => 0,
        d => 1 + sg + d,
    }
}

/// FLOATONE (with a point) or FLOATTWO (digits and exponent): the longer.
fn float_len(s: &[u8]) -> usize {
    let sg = sign(s);
    let int = digits(&s[sg..]);
    let mut best = 0;
    if s.get(sg + int) == Some(&b'.') {
        let frac = digits(&s[sg + int + 1..]);
        if int + frac > 0 {
            let end = sg + int + 1 + frac;
            best = end + exponent_len(&s[end..]);
        }
    }
    if int > 0 {
        let e = exponent_len(&s[sg + int..]);
        if e > 0 {
            best = best.max(sg + int + e);
        }
    }
    best
}

/// Whether `s` can be written bare, reading back as the same word both right after `(` and
/// elsewhere: a whole WORD token, no keyword, not readable as a number.
pub(crate) fn is_bare_word(s: &str) -> bool {
    let b = s.as_bytes();
    !b.is_empty()
        && word_len(b) == b.len()
        && keyword(s).is_none()
        && integer_len(b).max(hex_len(b)).max(float_len(b)) < b.len()
}

fn datetime_len(s: &[u8]) -> usize {
    let ok = s.len() >= 18
        && s[..8].iter().all(u8::is_ascii_digit)
        && matches!(s[8], b't' | b'T')
        && s[9..18].iter().all(u8::is_ascii_digit);
    if !ok {
        return 0;
    }
    18 + usize::from(s.get(18).is_some_and(u8::is_ascii_alphabetic))
}

impl<'a> Lexer<'a> {
    pub(crate) fn new(src: &'a str) -> Self {
        Self {
            src,
            pos: 0,
            operator_state: false,
        }
    }

    pub(crate) fn src(&self) -> &'a str {
        self.src
    }

    fn lexical(&self, at: usize, reason: &'static str) -> SlError {
        let (line, column) = line_column(self.src, at);
        let found = self
            .src
            .get(at..)
            .and_then(|s| s.chars().next())
            .unwrap_or('\0');
        SlError::Lexical {
            line,
            column,
            found,
            reason,
        }
    }

    /// The next token (state changes as in JADE: `(` enters operator state, anything else leaves).
    pub(crate) fn next_token(&mut self) -> Result<Token<'a>, SlError> {
        let bytes = self.src.as_bytes();
        while let Some(b' ' | b'\t' | b'\n' | b'\r') = bytes.get(self.pos) {
            self.pos += 1;
        }
        let start = self.pos;
        let rest = &bytes[start..];
        let Some(&first) = rest.first() else {
            return Ok(Token {
                tok: Tok::Eof,
                offset: start,
            });
        };
        let (tok, len) = if first == b'(' {
            (Tok::LParen, 1)
        } else if first == b')' {
            (Tok::RParen, 1)
        } else if self.operator_state {
            self.operator_token(start, rest)?
        } else {
            self.term_token(start, rest)?
        };
        self.operator_state = tok == Tok::LParen;
        self.pos = start + len;
        Ok(Token { tok, offset: start })
    }

    fn slice(&self, start: usize, len: usize) -> &'a str {
        self.src.get(start..start + len).unwrap_or("")
    }

    fn operator_token(&self, start: usize, rest: &[u8]) -> Result<(Tok<'a>, usize), SlError> {
        if rest.starts_with(b"??") {
            return match word_len(&rest[2..]) {
                0 => Err(self.lexical(start, "`??` must be followed by a word")),
                w => Ok((Tok::Meta(self.slice(start, 2 + w)), 2 + w)),
            };
        }
        if rest[0] == b'"' {
            let len = quoted_len(rest).ok_or_else(|| self.lexical(start, "unterminated string"))?;
            return Ok((Tok::Quoted(self.slice(start, len)), len));
        }
        let word = word_len(rest);
        // The longest keyword spelled at this point (`implies`, not `I`).
        let kw = KEYWORDS
            .iter()
            .filter(|(k, _)| {
                rest.len() >= k.len() && rest[..k.len()].eq_ignore_ascii_case(k.as_bytes())
            })
            .max_by_key(|(k, _)| k.len());
        match kw {
            Some(&(k, kw)) if k.len() >= word => Ok((Tok::Keyword(kw), k.len())),
            _ if word > 0 => Ok((Tok::Word(self.slice(start, word)), word)),
            _ => Err(self.lexical(
                start,
                "after \"(\" expected an operator, a word, a quoted string or a ??meta symbol",
            )),
        }
    }

    fn term_token(&self, start: usize, rest: &[u8]) -> Result<(Tok<'a>, usize), SlError> {
        match rest[0] {
            b'?' => {
                let body = &rest[1..];
                if body.first() == Some(&b'?') {
                    return match word_len(&body[1..]) {
                        0 => Err(self.lexical(start, "`??` must be followed by a word")),
                        w => Ok((Tok::Meta(self.slice(start, 2 + w)), 2 + w)),
                    };
                }
                let len = self.name_len(
                    start + 1,
                    body,
                    "`?` must be followed by a word or a string",
                )?;
                Ok((Tok::Variable(self.slice(start + 1, len)), 1 + len))
            }
            b':' => {
                let body = &rest[1..];
                let len =
                    self.name_len(start + 1, body, "`:` must be followed by a parameter name")?;
                Ok((Tok::Param(self.slice(start + 1, len)), 1 + len))
            }
            b'"' => {
                let len =
                    quoted_len(rest).ok_or_else(|| self.lexical(start, "unterminated string"))?;
                Ok((Tok::Quoted(self.slice(start, len)), len))
            }
            b'#' => self.byte_string(start, rest),
            _ => {
                // Longest match; on a tie the earlier kind in JADE's order wins.
                let candidates = [
                    (integer_len(rest), 0u8),
                    (hex_len(rest), 1),
                    (float_len(rest), 2),
                    (word_len(rest), 3),
                    (datetime_len(rest), 4),
                ];
                let (len, kind) = candidates
                    .into_iter()
                    .fold((0, 0), |best, c| if c.0 > best.0 { c } else { best });
                if len == 0 {
                    return Err(self.lexical(
                        start,
                        "expected a term: word, number, string, variable, date or \"(\"",
                    ));
                }
                let text = self.slice(start, len);
                let tok = match kind {
                    0 => Tok::Integer(text),
                    1 => Tok::Hex(text),
                    2 => Tok::Float(text),
                    3 => Tok::Word(text),
                    _ => Tok::DateTime(text),
                };
                Ok((tok, len))
            }
        }
    }

    /// A word or a quoted string after `?` or `:`.
    fn name_len(&self, at: usize, body: &[u8], reason: &'static str) -> Result<usize, SlError> {
        if body.first() == Some(&b'"') {
            return quoted_len(body).ok_or_else(|| self.lexical(at, "unterminated string"));
        }
        match word_len(body) {
            0 => Err(self.lexical(at, reason)),
            w => Ok(w),
        }
    }

    /// `#N"` then exactly N bytes.
    fn byte_string(&self, start: usize, rest: &[u8]) -> Result<(Tok<'a>, usize), SlError> {
        let n_len = integer_len(&rest[1..]);
        if n_len == 0 || rest.get(1 + n_len) != Some(&b'"') {
            return Err(self.lexical(start, "a byte string is #<length>\"<bytes>"));
        }
        let count_text = self.slice(start + 1, n_len);
        let count: usize = count_text
            .parse::<i64>()
            .ok()
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| {
                self.lexical(start, "byte string length must be a non-negative integer")
            })?;
        let body_start = start + 1 + n_len + 1;
        let body_end = body_start
            .checked_add(count)
            .filter(|&e| e <= self.src.len())
            .ok_or_else(|| self.lexical(start, "byte string shorter than its length prefix"))?;
        let body = self
            .src
            .get(body_start..body_end)
            .ok_or_else(|| self.lexical(start, "byte string length splits a UTF-8 character"))?;
        Ok((Tok::Bytes(body), body_end - start))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(src: &str) -> Vec<Tok<'_>> {
        let mut lx = Lexer::new(src);
        let mut out = vec![];
        loop {
            let t = lx.next_token().unwrap();
            if t.tok == Tok::Eof {
                return out;
            }
            out.push(t.tok);
        }
    }

    #[test]
    fn longest_match_and_states() {
        assert_eq!(
            kinds("(B Born b ?x 12abc .5 .5x -.5 0x1F 1e-3 20261122T014140823Z)"),
            vec![
                Tok::LParen,
                Tok::Keyword(Keyword::Modal(ModalOp::B)),
                Tok::Word("Born"),
                Tok::Word("b"),
                Tok::Variable("x"),
                Tok::Integer("12"),
                Tok::Word("abc"),
                Tok::Float(".5"),
                Tok::Word(".5x"),
                Tok::Float("-.5"),
                Tok::Hex("0x1F"),
                Tok::Float("1e-3"),
                Tok::DateTime("20261122T014140823Z"),
                Tok::RParen,
            ]
        );
        assert_eq!(
            kinds("(Born)"),
            vec![Tok::LParen, Tok::Word("Born"), Tok::RParen]
        );
        assert_eq!(
            kinds("(+x)"),
            vec![Tok::LParen, Tok::Word("+x"), Tok::RParen]
        );
    }

    #[test]
    fn strings_and_bytes() {
        assert_eq!(
            kinds(r#"(p "a \"b\"" #3"x y)"#)[2],
            Tok::Quoted(r#""a \"b\"""#)
        );
        assert_eq!(kinds(r#"(p #3"x y)"#)[2], Tok::Bytes("x y"));
        assert_eq!(unescape(r#""a \"b\" \\ c""#), r#"a "b" \\ c"#);
        assert!(Lexer::new("(p #9\"ab)").next_token().is_ok());
        let mut lx = Lexer::new("(p #9\"ab)");
        lx.next_token().unwrap();
        lx.next_token().unwrap();
        assert!(matches!(
            lx.next_token(),
            Err(SlError::Lexical { column: 4, .. })
        ));
    }
}
