//! Recursive-descent parser: one grammar, gated by [`Level`].

use crate::ast::{
    ActionExpression, ActionOperand, Arguments, Constant, Content, ContentExpression, DateTime,
    Formula, IdentifyingExpression, Parameter, Term,
};
use crate::error::SlError;
use crate::level::{Feature, Level};
use crate::lexer::{Keyword, Lexer, Tok, Token, line_column, unescape};

/// Deepest parenthesis nesting accepted; deeper input is refused instead of exhausting the stack.
pub const MAX_DEPTH: usize = 128;

/// Longest content accepted, bytes: the size of the largest record the logger stores (1 MiB),
/// far above any content the platform's agents exchange. Larger input is refused before
/// lexing: a tree of 10 MB of SL took gigabytes.
pub const MAX_INPUT_BYTES: usize = 1 << 20;

/// Most tokens (words, numbers, strings, parentheses) accepted in one content: bounds the tree
/// built, whatever the input's shape.
pub const MAX_TOKENS: usize = 100_000;

/// Parses SL content (the `(expr+)` tuple an ACL `:content` carries) at `level`.
///
/// Refuses what JADE's codec for that level refuses ([`Level`] lists it). Like JADE, reading
/// stops at the parenthesis closing the content: text after it is not examined (JADE's own test
/// content has a stray `)` there).
/// Input longer than [`MAX_INPUT_BYTES`] or of more than [`MAX_TOKENS`] tokens is refused.
pub fn parse(input: &str, level: Level) -> Result<Content, SlError> {
    if input.len() > MAX_INPUT_BYTES {
        return Err(SlError::TooLarge {
            bytes: input.len(),
            limit: MAX_INPUT_BYTES,
        });
    }
    Parser {
        lexer: Lexer::new(input),
        peeked: None,
        level,
        depth: 0,
        tokens: 0,
    }
    .content()
}

struct Parser<'a> {
    lexer: Lexer<'a>,
    peeked: Option<Token<'a>>,
    level: Level,
    depth: usize,
    tokens: usize,
}

const TERM: &str = "a term: word, string, number, date, byte string, ?variable or \"(\"";
const FORMULA: &str = "a formula: proposition symbol, ??meta or \"(\"";

impl<'a> Parser<'a> {
    fn peek(&mut self) -> Result<Token<'a>, SlError> {
        match self.peeked {
            Some(t) => Ok(t),
            None => {
                let t = self.lexer.next_token()?;
                self.tokens += 1;
                if self.tokens > MAX_TOKENS {
                    let (line, column) = line_column(self.lexer.src(), t.offset);
                    return Err(SlError::TooManyTokens {
                        line,
                        column,
                        limit: MAX_TOKENS,
                    });
                }
                self.peeked = Some(t);
                Ok(t)
            }
        }
    }

    fn next(&mut self) -> Result<Token<'a>, SlError> {
        let t = self.peek()?;
        self.peeked = None;
        Ok(t)
    }

    fn unexpected(&self, t: Token<'_>, expected: &'static str) -> SlError {
        let (line, column) = line_column(self.lexer.src(), t.offset);
        SlError::Syntax {
            line,
            column,
            found: t.tok.describe(),
            expected,
        }
    }

    fn open(&mut self) -> Result<(), SlError> {
        let t = self.next()?;
        if t.tok != Tok::LParen {
            return Err(self.unexpected(t, "\"(\""));
        }
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            let (line, column) = line_column(self.lexer.src(), t.offset);
            return Err(SlError::TooDeep {
                line,
                column,
                limit: MAX_DEPTH,
            });
        }
        Ok(())
    }

    fn close(&mut self) -> Result<(), SlError> {
        let t = self.next()?;
        if t.tok != Tok::RParen {
            return Err(self.unexpected(t, "\")\""));
        }
        self.depth = self.depth.saturating_sub(1);
        Ok(())
    }

    fn require(&self, t: Token<'_>, feature: Feature, construct: &str) -> Result<(), SlError> {
        if self.level.allows(feature) {
            return Ok(());
        }
        let (line, column) = line_column(self.lexer.src(), t.offset);
        Err(SlError::NotAllowed {
            line,
            column,
            construct: construct.to_owned(),
            level: self.level,
            needs: Level::lowest_allowing(feature),
        })
    }

    fn content(&mut self) -> Result<Content, SlError> {
        self.open()?;
        let mut expressions = vec![self.content_expression()?];
        while self.peek()?.tok != Tok::RParen {
            expressions.push(self.content_expression()?);
        }
        self.close()?;
        Ok(Content { expressions })
    }

    fn content_expression(&mut self) -> Result<ContentExpression, SlError> {
        let t = self.peek()?;
        match t.tok {
            Tok::LParen => {
                self.open()?;
                let k = self.peek()?;
                let e = match k.tok {
                    Tok::Keyword(Keyword::Referential(_)) => {
                        ContentExpression::Identifying(self.identifying_nobrace()?)
                    }
                    Tok::Keyword(Keyword::Action | Keyword::Alternative | Keyword::Sequence) => {
                        ContentExpression::Action(self.action_nobrace()?)
                    }
                    _ => ContentExpression::Formula(self.formula_nobrace()?),
                };
                self.close()?;
                Ok(e)
            }
            _ => Ok(ContentExpression::Formula(self.formula()?)),
        }
    }

    fn identifying_nobrace(&mut self) -> Result<IdentifyingExpression, SlError> {
        let t = self.next()?;
        let Tok::Keyword(Keyword::Referential(op)) = t.tok else {
            return Err(self.unexpected(t, "iota, any or all"));
        };
        self.require(
            t,
            Feature::Higher,
            "an identifying expression (iota/any/all)",
        )?;
        let term = self.term()?;
        let formula = self.formula()?;
        Ok(IdentifyingExpression { op, term, formula })
    }

    fn action_nobrace(&mut self) -> Result<ActionExpression, SlError> {
        let t = self.next()?;
        match t.tok {
            Tok::Keyword(Keyword::Action) => {
                let agent = self.term()?;
                let act = self.term()?;
                Ok(ActionExpression::Action { agent, act })
            }
            Tok::Keyword(k @ (Keyword::Alternative | Keyword::Sequence)) => {
                self.require(t, Feature::Higher, "an action composition (| or ;)")?;
                let first = Box::new(self.action_operand()?);
                let second = Box::new(self.action_operand()?);
                Ok(if k == Keyword::Alternative {
                    ActionExpression::Alternative { first, second }
                } else {
                    ActionExpression::Sequence { first, second }
                })
            }
            _ => Err(self.unexpected(t, "action, | or ;")),
        }
    }

    fn action_operand(&mut self) -> Result<ActionOperand, SlError> {
        let t = self.peek()?;
        match t.tok {
            Tok::Meta(name) => {
                self.next()?;
                Ok(ActionOperand::Meta(name.to_owned()))
            }
            Tok::LParen => {
                self.open()?;
                let a = self.action_nobrace()?;
                self.close()?;
                Ok(ActionOperand::Expression(a))
            }
            _ => Err(self.unexpected(t, "an action expression \"(action ...)\" or ??meta")),
        }
    }

    fn formula(&mut self) -> Result<Formula, SlError> {
        let t = self.peek()?;
        match t.tok {
            Tok::Word(_) | Tok::Quoted(_) => Ok(Formula::Symbol {
                name: self.string()?,
            }),
            Tok::Meta(name) => {
                self.next()?;
                Ok(Formula::Meta {
                    name: name.to_owned(),
                })
            }
            Tok::LParen => {
                self.open()?;
                let f = self.formula_nobrace()?;
                self.close()?;
                Ok(f)
            }
            _ => Err(self.unexpected(t, FORMULA)),
        }
    }

    fn formula_nobrace(&mut self) -> Result<Formula, SlError> {
        let t = self.peek()?;
        let Tok::Keyword(k) = t.tok else {
            if !matches!(t.tok, Tok::Word(_) | Tok::Quoted(_)) {
                return Err(self.unexpected(t, "a predicate symbol or an operator"));
            }
            let predicate = self.string()?;
            let mut args = vec![self.term()?];
            while self.starts_term()? {
                args.push(self.term()?);
            }
            return Ok(Formula::Atomic { predicate, args });
        };
        self.next()?;
        match k {
            Keyword::Not => {
                self.require(t, Feature::Connectives, "the connective \"not\"")?;
                Ok(Formula::Not {
                    formula: Box::new(self.formula()?),
                })
            }
            Keyword::Binary(op) => {
                self.require(
                    t,
                    Feature::Connectives,
                    "a binary connective (and/or/implies/equiv)",
                )?;
                let left = Box::new(self.formula()?);
                let right = Box::new(self.formula()?);
                Ok(Formula::Binary { op, left, right })
            }
            Keyword::Quantifier(quantifier) => {
                self.require(t, Feature::Higher, "a quantifier (forall/exists)")?;
                let v = self.next()?;
                let Tok::Variable(name) = v.tok else {
                    return Err(self.unexpected(v, "a ?variable after the quantifier"));
                };
                let formula = Box::new(self.formula()?);
                Ok(Formula::Quantified {
                    quantifier,
                    variable: variable_name(name),
                    formula,
                })
            }
            Keyword::Modal(op) => {
                self.require(t, Feature::Higher, "a modal operator (B/U/PG/I)")?;
                let agent = self.term()?;
                let formula = Box::new(self.formula()?);
                Ok(Formula::Modal { op, agent, formula })
            }
            Keyword::ActionOp(op) => {
                let action = Box::new(self.action_operand()?);
                let next = self.peek()?.tok;
                let condition = if matches!(
                    next,
                    Tok::Word(_) | Tok::Quoted(_) | Tok::Meta(_) | Tok::LParen
                ) {
                    Some(Box::new(self.formula()?))
                } else {
                    None
                };
                Ok(Formula::ActionCondition {
                    op,
                    action,
                    condition,
                })
            }
            _ => Err(self.unexpected(t, "a predicate symbol or a formula operator")),
        }
    }

    fn starts_term(&mut self) -> Result<bool, SlError> {
        Ok(matches!(
            self.peek()?.tok,
            Tok::LParen
                | Tok::Word(_)
                | Tok::Quoted(_)
                | Tok::Variable(_)
                | Tok::Meta(_)
                | Tok::Integer(_)
                | Tok::Hex(_)
                | Tok::Float(_)
                | Tok::DateTime(_)
                | Tok::Bytes(_)
        ))
    }

    /// A word or quoted string, as text.
    fn string(&mut self) -> Result<String, SlError> {
        let t = self.next()?;
        match t.tok {
            Tok::Word(w) => Ok(w.to_owned()),
            Tok::Quoted(q) => Ok(unescape(q)),
            _ => Err(self.unexpected(t, "a word or a quoted string")),
        }
    }

    fn term(&mut self) -> Result<Term, SlError> {
        let t = self.next()?;
        let constant = |value| Ok(Term::Constant { value });
        match t.tok {
            Tok::Variable(name) => Ok(Term::Variable {
                name: variable_name(name),
            }),
            Tok::Meta(name) => Ok(Term::Meta {
                name: name.to_owned(),
            }),
            Tok::Word(w) if w.eq_ignore_ascii_case("true") => constant(Constant::Boolean(true)),
            Tok::Word(w) if w.eq_ignore_ascii_case("false") => constant(Constant::Boolean(false)),
            Tok::Word(w) => constant(Constant::String(w.to_owned())),
            Tok::Quoted(q) => constant(Constant::String(unescape(q))),
            Tok::Integer(s) => constant(
                s.parse()
                    .map_or_else(|_| Constant::String(s.to_owned()), Constant::Integer),
            ),
            Tok::Hex(s) => constant(Constant::String(s.to_owned())),
            // Like an integer beyond i64, a float beyond f64 keeps its text: an infinity has
            // no SL spelling to print back.
            Tok::Float(s) => constant(
                s.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .map_or_else(|| Constant::String(s.to_owned()), Constant::Float),
            ),
            Tok::DateTime(s) => constant(
                parse_datetime(s)
                    .map_or_else(|| Constant::String(s.to_owned()), Constant::DateTime),
            ),
            Tok::Bytes(b) => constant(Constant::ByteString(b.to_owned())),
            Tok::LParen => {
                self.peeked = Some(t);
                self.open()?;
                let term = self.term_nobrace()?;
                self.close()?;
                Ok(term)
            }
            _ => Err(self.unexpected(t, TERM)),
        }
    }

    fn term_nobrace(&mut self) -> Result<Term, SlError> {
        let t = self.peek()?;
        match t.tok {
            Tok::Keyword(Keyword::Arithmetic(op)) => {
                self.next()?;
                let left = Box::new(self.term()?);
                let right = Box::new(self.term()?);
                Ok(Term::Arithmetic { op, left, right })
            }
            Tok::Keyword(Keyword::Action | Keyword::Alternative | Keyword::Sequence) => {
                Ok(Term::Action {
                    action: Box::new(self.action_nobrace()?),
                })
            }
            Tok::Keyword(Keyword::Referential(_)) => Ok(Term::Identifying {
                expression: Box::new(self.identifying_nobrace()?),
            }),
            Tok::Word(_) | Tok::Quoted(_) => {
                let symbol = self.string()?;
                let args = if let Tok::Param(_) = self.peek()?.tok {
                    let mut params = vec![];
                    while let Tok::Param(name) = self.peek()?.tok {
                        self.next()?;
                        let name = if name.starts_with('"') {
                            unescape(name)
                        } else {
                            name.to_owned()
                        };
                        params.push(Parameter {
                            name,
                            value: self.term()?,
                        });
                    }
                    Arguments::Named(params)
                } else {
                    let mut args = vec![];
                    while self.starts_term()? {
                        args.push(self.term()?);
                    }
                    Arguments::Positional(args)
                };
                Ok(Term::Functional { symbol, args })
            }
            _ => Err(self.unexpected(
                t,
                "a function symbol, action, iota/any/all or an arithmetic operator",
            )),
        }
    }
}

fn variable_name(raw: &str) -> String {
    if raw.starts_with('"') {
        unescape(raw)
    } else {
        raw.to_owned()
    }
}

/// `YYYYMMDDThhmmssmmm[letter]`, read as UTC; `None` if a field is out of range.
fn parse_datetime(s: &str) -> Option<DateTime> {
    let num = |r: std::ops::Range<usize>| s.get(r).and_then(|d| d.parse::<u32>().ok());
    DateTime::from_utc(
        i64::from(num(0..4)?),
        num(4..6)?,
        num(6..8)?,
        num(9..11)?,
        num(11..13)?,
        num(13..15)?,
        num(15..18)?,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oversize_input_is_refused_before_lexing() {
        let word = "(a)";
        let input = format!("({})", word.repeat(MAX_INPUT_BYTES / word.len() + 1));
        assert!(matches!(
            parse(&input, Level::Full),
            Err(SlError::TooLarge {
                limit: MAX_INPUT_BYTES,
                ..
            })
        ));
    }

    #[test]
    fn too_many_tokens_are_refused_with_a_position() {
        // Well under the byte limit, but a tree of more tokens than the bound.
        let input = format!("((f {}))", "1 ".repeat(MAX_TOKENS));
        assert!(input.len() < MAX_INPUT_BYTES);
        let err = parse(&input, Level::Full).unwrap_err();
        assert!(
            matches!(
                err,
                SlError::TooManyTokens {
                    line: 1,
                    limit: MAX_TOKENS,
                    ..
                }
            ),
            "{err}"
        );
        // Just under the bound still parses.
        let fits = format!("((f {}))", "1 ".repeat(MAX_TOKENS - 10));
        assert!(parse(&fits, Level::Full).is_ok());
    }
}
