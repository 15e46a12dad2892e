//! The mapping between typed values and SL terms, and helpers to read and build frames
//! (`(symbol :slot value ...)`).

use iw_sl::{Arguments, Collection, Constant, Parameter, Term};

use crate::error::OntologyError;

/// A value with an SL term form: an ontology concept (`agent-identifier`, `pose`, ...).
pub trait Concept: Sized {
    /// The SL term for this value.
    fn to_term(&self) -> Term;
    /// The value an SL term denotes, or why it denotes none.
    fn from_term(term: &Term) -> Result<Self, OntologyError>;
}

/// A parsed frame: a functional term whose symbol matched, with its named slots.
pub(crate) struct Frame<'a> {
    pub concept: &'static str,
    params: &'a [Parameter],
    positional: &'a [Term],
}

/// The term printed as SL, for error messages.
pub(crate) fn shown(term: &Term) -> String {
    term.to_string()
}

/// Whether `term` is a functional term named `symbol` (ASCII case-insensitive, as in JADE).
pub(crate) fn is_frame(term: &Term, symbol: &str) -> bool {
    matches!(term, Term::Functional { symbol: s, .. } if s.eq_ignore_ascii_case(symbol))
}

impl<'a> Frame<'a> {
    /// Reads `term` as `(concept ...)`.
    pub fn read(term: &'a Term, concept: &'static str) -> Result<Self, OntologyError> {
        match term {
            Term::Functional { symbol, args } if symbol.eq_ignore_ascii_case(concept) => {
                let (params, positional): (&[Parameter], &[Term]) = match args {
                    Arguments::Named(p) => (p, &[]),
                    Arguments::Positional(t) => (&[], t),
                };
                // A bare `:X-` would be dropped as neither a known nor a user slot: refuse it, as
                // the ACL codec does, rather than lose the value.
                if let Some(p) = params.iter().find(|p| p.name.eq_ignore_ascii_case("x-")) {
                    return Err(OntologyError::BadValue {
                        concept,
                        slot: "X-",
                        value: shown(&p.value),
                        reason: "a user-defined slot needs a name after `X-`",
                    });
                }
                Ok(Self {
                    concept,
                    params,
                    positional,
                })
            }
            _ => Err(OntologyError::UnexpectedTerm {
                expected: concept,
                found: shown(term),
            }),
        }
    }

    /// The positional arguments (`(search desc constraints)`).
    pub fn positional(&self) -> &'a [Term] {
        self.positional
    }

    /// The `n`-th positional argument, required.
    pub fn arg(&self, n: usize, slot: &'static str) -> Result<&'a Term, OntologyError> {
        self.positional.get(n).ok_or(OntologyError::MissingSlot {
            concept: self.concept,
            slot,
        })
    }

    /// The value of `:slot`, if present.
    pub fn get(&self, slot: &str) -> Option<&'a Term> {
        self.params
            .iter()
            .find(|p| p.name.eq_ignore_ascii_case(slot))
            .map(|p| &p.value)
    }

    /// The value of `:slot`, required.
    pub fn require(&self, slot: &'static str) -> Result<&'a Term, OntologyError> {
        self.get(slot).ok_or(OntologyError::MissingSlot {
            concept: self.concept,
            slot,
        })
    }

    /// Every `:X-...` slot, in order (user-defined slots).
    pub fn user_slots(&self) -> impl Iterator<Item = &'a Parameter> {
        self.params
            .iter()
            .filter(|p| p.name.len() > 2 && p.name[..2].eq_ignore_ascii_case("x-"))
    }

    fn bad(&self, slot: &'static str, value: &Term, reason: &'static str) -> OntologyError {
        OntologyError::BadValue {
            concept: self.concept,
            slot,
            value: shown(value),
            reason,
        }
    }

    /// `:slot` as text (any constant, written as its text).
    pub fn text(&self, slot: &'static str) -> Result<Option<String>, OntologyError> {
        self.get(slot)
            .map(|t| text_of(t).ok_or_else(|| self.bad(slot, t, "expected a word or string")))
            .transpose()
    }

    /// `:slot` as text, required.
    pub fn required_text(&self, slot: &'static str) -> Result<String, OntologyError> {
        let t = self.require(slot)?;
        text_of(t).ok_or_else(|| self.bad(slot, t, "expected a word or string"))
    }

    /// `:slot` as a number, required.
    pub fn required_number(&self, slot: &'static str) -> Result<f64, OntologyError> {
        let t = self.require(slot)?;
        number_of(t).ok_or_else(|| self.bad(slot, t, "expected a number"))
    }

    /// `:slot` as an integer.
    pub fn integer(&self, slot: &'static str) -> Result<Option<i64>, OntologyError> {
        self.get(slot)
            .map(|t| match t.as_constant() {
                Some(Constant::Integer(i)) => Ok(*i),
                _ => Err(self.bad(slot, t, "expected an integer")),
            })
            .transpose()
    }

    /// `:slot` as an integer, required.
    pub fn required_integer(&self, slot: &'static str) -> Result<i64, OntologyError> {
        self.integer(slot)?.ok_or(OntologyError::MissingSlot {
            concept: self.concept,
            slot,
        })
    }

    /// `:slot` as a set or sequence; empty when absent.
    pub fn list(&self, slot: &'static str) -> Result<&'a [Term], OntologyError> {
        match self.get(slot) {
            None => Ok(&[]),
            Some(t) => match t.collection() {
                Some((_, items)) => Ok(items),
                None => Err(self.bad(slot, t, "expected a set or sequence")),
            },
        }
    }

    /// `:slot` as a set or sequence of texts.
    pub fn texts(&self, slot: &'static str) -> Result<Vec<String>, OntologyError> {
        self.list(slot)?
            .iter()
            .map(|t| text_of(t).ok_or_else(|| self.bad(slot, t, "expected words or strings")))
            .collect()
    }

    /// `:slot` as a set or sequence of concepts.
    pub fn concepts<C: Concept>(&self, slot: &'static str) -> Result<Vec<C>, OntologyError> {
        self.list(slot)?.iter().map(C::from_term).collect()
    }
}

/// The text of a constant term (strings as they are, numbers and booleans as written).
pub(crate) fn text_of(term: &Term) -> Option<String> {
    match term.as_constant()? {
        Constant::String(s) | Constant::ByteString(s) => Some(s.clone()),
        other => Some(other.to_string()),
    }
}

/// The value of a numeric constant.
pub(crate) fn number_of(term: &Term) -> Option<f64> {
    match term.as_constant()? {
        Constant::Float(x) => Some(*x),
        Constant::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// An enum whose values are SL words (`active`, `open`): derives, the word of each value and
/// the value of a word (any ASCII case).
macro_rules! word_enum {
    ($(#[$meta:meta])* pub enum $name:ident { $($(#[$vmeta:meta])* $variant:ident => $word:literal,)+ }) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
        #[serde(rename_all = "kebab-case")]
        pub enum $name {
            $($(#[$vmeta])* $variant,)+
        }

        impl $name {
            /// The SL word.
            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$variant => $word,)+
                }
            }

            /// The value written `word` (any ASCII case).
            pub fn from_word(word: &str) -> Option<Self> {
                [$(Self::$variant,)+].into_iter().find(|v| v.name().eq_ignore_ascii_case(word))
            }
        }
    };
}
pub(crate) use word_enum;

/// Reads a word-valued slot through `from_word`.
pub(crate) fn word_value<T>(
    term: &Term,
    concept: &'static str,
    slot: &'static str,
    from_word: fn(&str) -> Option<T>,
    reason: &'static str,
) -> Result<T, OntologyError> {
    text_of(term)
        .and_then(|w| from_word(&w))
        .ok_or_else(|| OntologyError::BadValue {
            concept,
            slot,
            value: shown(term),
            reason,
        })
}

/// Builds `(symbol :slot value ...)`, leaving out absent and empty slots.
pub(crate) struct FrameBuilder {
    symbol: &'static str,
    params: Vec<Parameter>,
}

impl FrameBuilder {
    pub fn new(symbol: &'static str) -> Self {
        Self {
            symbol,
            params: Vec::new(),
        }
    }

    pub fn term(mut self, slot: &str, value: Term) -> Self {
        self.params.push(Parameter::new(slot, value));
        self
    }

    pub fn opt_term(self, slot: &str, value: Option<Term>) -> Self {
        match value {
            Some(v) => self.term(slot, v),
            None => self,
        }
    }

    pub fn text(self, slot: &str, value: Option<&str>) -> Self {
        self.opt_term(slot, value.map(Term::string))
    }

    pub fn float(self, slot: &str, value: f64) -> Self {
        self.term(slot, Term::float(value))
    }

    pub fn list(self, slot: &str, kind: Collection, items: Vec<Term>) -> Self {
        if items.is_empty() {
            return self;
        }
        let t = match kind {
            Collection::Set => Term::set(items),
            Collection::Sequence => Term::sequence(items),
        };
        self.term(slot, t)
    }

    pub fn texts(self, slot: &str, kind: Collection, items: &[String]) -> Self {
        self.list(
            slot,
            kind,
            items.iter().map(|s| Term::string(s.as_str())).collect(),
        )
    }

    pub fn concepts<C: Concept>(self, slot: &str, kind: Collection, items: &[C]) -> Self {
        self.list(slot, kind, items.iter().map(Concept::to_term).collect())
    }

    /// The frame; `(symbol)` when no slot is set.
    pub fn build(self) -> Term {
        if self.params.is_empty() {
            Term::positional(self.symbol, vec![])
        } else {
            Term::named(self.symbol, self.params)
        }
    }
}
