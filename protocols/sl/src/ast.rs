//! The one abstract syntax tree for every SL level.
//!
//! The shapes follow SC00008's grammar: a [`Content`] is a tuple of content expressions; each is a
//! [`Formula`], an [`ActionExpression`] or an [`IdentifyingExpression`]. Keywords are enums
//! (`BinaryOp::And`), so callers never compare operator strings.

use serde::{Deserialize, Serialize};
use time::{Date, Month, OffsetDateTime, PrimitiveDateTime, Time};

/// SL content: the parenthesised tuple `(expr+)` an ACL `:content` carries.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Content {
    /// The content expressions, in order (at least one in parsed content).
    pub expressions: Vec<ContentExpression>,
}

impl Content {
    /// Content made of a single expression (the usual case: one request, one inform).
    pub fn single(expression: impl Into<ContentExpression>) -> Self {
        Self {
            expressions: vec![expression.into()],
        }
    }
}

/// One element of a content tuple.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", content = "value", rename_all = "kebab-case")]
pub enum ContentExpression {
    /// A proposition (what `inform` carries).
    Formula(Formula),
    /// An action (what `request` carries).
    Action(ActionExpression),
    /// `iota`/`any`/`all` (what `query-ref` carries).
    Identifying(IdentifyingExpression),
}

impl From<Formula> for ContentExpression {
    fn from(f: Formula) -> Self {
        Self::Formula(f)
    }
}

impl From<ActionExpression> for ContentExpression {
    fn from(a: ActionExpression) -> Self {
        Self::Action(a)
    }
}

impl From<IdentifyingExpression> for ContentExpression {
    fn from(i: IdentifyingExpression) -> Self {
        Self::Identifying(i)
    }
}

/// A well-formed formula.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Formula {
    /// A proposition symbol written bare: `true`, `false`, `already-registered`.
    Symbol {
        /// The symbol.
        name: String,
    },
    /// A JADE meta symbol `??name` standing for a formula (a template placeholder).
    Meta {
        /// The name, with its `??`.
        name: String,
    },
    /// `(predicate term+)`: at least one argument (a bare symbol is [`Formula::Symbol`]).
    Atomic {
        /// Predicate symbol, e.g. `result`, `=`, `at`.
        predicate: String,
        /// Arguments in order.
        args: Vec<Term>,
    },
    /// `(not φ)` (SL1 and up).
    Not {
        /// The negated formula.
        formula: Box<Formula>,
    },
    /// `(and φ ψ)`, `(or ...)`, `(implies ...)`, `(equiv ...)` (SL1 and up).
    Binary {
        /// The connective.
        op: BinaryOp,
        /// First operand.
        left: Box<Formula>,
        /// Second operand.
        right: Box<Formula>,
    },
    /// `(forall ?x φ)`, `(exists ?x φ)` (SL2 and up).
    Quantified {
        /// The quantifier.
        quantifier: Quantifier,
        /// The bound variable's name (without `?`).
        variable: String,
        /// The quantified formula.
        formula: Box<Formula>,
    },
    /// `(B agent φ)`, `(U ...)`, `(PG ...)`, `(I ...)` (SL2 and up).
    Modal {
        /// The modal operator.
        op: ModalOp,
        /// The agent holding the attitude (usually an `agent-identifier`).
        agent: Term,
        /// The formula believed, intended, ...
        formula: Box<Formula>,
    },
    /// `(done α [φ])`, `(feasible α [φ])`.
    ActionCondition {
        /// `done` or `feasible`.
        op: ActionOp,
        /// The action.
        action: Box<ActionOperand>,
        /// The optional condition.
        condition: Option<Box<Formula>>,
    },
}

/// Binary logical connectives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BinaryOp {
    /// `and`
    And,
    /// `or`
    Or,
    /// `implies`
    Implies,
    /// `equiv`
    Equiv,
}

/// Quantifiers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Quantifier {
    /// `forall`
    Forall,
    /// `exists`
    Exists,
}

/// Modal operators of the FIPA SL semantics.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ModalOp {
    /// `B`: belief.
    B,
    /// `U`: uncertainty.
    U,
    /// `PG`: persistent goal.
    PG,
    /// `I`: intention.
    I,
}

/// Operators turning an action into a formula.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ActionOp {
    /// `done`: the action has happened.
    Done,
    /// `feasible`: the action can happen.
    Feasible,
}

/// Referential operators of identifying expressions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReferentialOp {
    /// `iota`: the unique object satisfying the formula.
    Iota,
    /// `any`: any object satisfying it.
    Any,
    /// `all`: the set of all objects satisfying it.
    All,
}

/// Arithmetic function symbols `+ - * / %`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ArithmeticOp {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
    /// `%`
    Rem,
}

/// `(action agent term)`, or the action composition operators of full SL.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ActionExpression {
    /// `(action agent act)`: `agent` performs `act` (a functional term such as `(search ...)`).
    Action {
        /// Who acts (usually an `agent-identifier`).
        agent: Term,
        /// What is done.
        act: Term,
    },
    /// `(| α β)`: one of the two (full SL).
    Alternative {
        /// First alternative.
        first: Box<ActionOperand>,
        /// Second alternative.
        second: Box<ActionOperand>,
    },
    /// `(; α β)`: α then β (full SL).
    Sequence {
        /// Done first.
        first: Box<ActionOperand>,
        /// Done second.
        second: Box<ActionOperand>,
    },
}

/// Where SL needs an action: a parenthesised action expression or a `??meta` placeholder.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", content = "value", rename_all = "kebab-case")]
pub enum ActionOperand {
    /// An action expression.
    Expression(ActionExpression),
    /// A JADE meta symbol `??name`.
    Meta(String),
}

/// `(iota term φ)`, `(any ...)`, `(all ...)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IdentifyingExpression {
    /// Which object(s) the expression denotes.
    pub op: ReferentialOp,
    /// The term to identify (usually a variable such as `?x`).
    pub term: Term,
    /// The condition the object satisfies.
    pub formula: Formula,
}

/// A term: something that denotes an object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Term {
    /// `?name` (the name is stored without `?`).
    Variable {
        /// Variable name.
        name: String,
    },
    /// JADE meta symbol `??name` standing for a term (stored with its `??`).
    Meta {
        /// The name, with its `??`.
        name: String,
    },
    /// A literal.
    Constant {
        /// The value.
        value: Constant,
    },
    /// `(f t*)` or `(f :slot t ...)`: a function application, i.e. an ontology concept. The
    /// aggregates `(set t*)` and `(sequence t*)` are functional terms too (their spelling is kept;
    /// see [`Term::collection`]).
    Functional {
        /// Function symbol, e.g. `agent-identifier`.
        symbol: String,
        /// Arguments, positional or named (SL forbids mixing them).
        args: Arguments,
    },
    /// `(+ a b)` and the other arithmetic symbols.
    Arithmetic {
        /// The operator.
        op: ArithmeticOp,
        /// Left operand.
        left: Box<Term>,
        /// Right operand.
        right: Box<Term>,
    },
    /// An action expression used as a term (the `:action` of `done`, `result`, ...).
    Action {
        /// The action.
        action: Box<ActionExpression>,
    },
    /// An identifying expression used as a term (`(= (iota ...) 87)`).
    Identifying {
        /// The expression.
        expression: Box<IdentifyingExpression>,
    },
}

impl Term {
    /// A string constant (a word or a quoted string on the wire).
    pub fn string(s: impl Into<String>) -> Self {
        Self::Constant {
            value: Constant::String(s.into()),
        }
    }

    /// An integer constant.
    pub fn integer(i: i64) -> Self {
        Self::Constant {
            value: Constant::Integer(i),
        }
    }

    /// A float constant.
    pub fn float(x: f64) -> Self {
        Self::Constant {
            value: Constant::Float(x),
        }
    }

    /// A boolean constant.
    pub fn boolean(b: bool) -> Self {
        Self::Constant {
            value: Constant::Boolean(b),
        }
    }

    /// A variable `?name`.
    pub fn variable(name: impl Into<String>) -> Self {
        Self::Variable { name: name.into() }
    }

    /// A functional term with named slots, `(symbol :a x :b y)`.
    pub fn named(symbol: impl Into<String>, params: Vec<Parameter>) -> Self {
        Self::Functional {
            symbol: symbol.into(),
            args: Arguments::Named(params),
        }
    }

    /// A functional term with positional arguments, `(symbol x y)`; `(symbol)` when empty.
    pub fn positional(symbol: impl Into<String>, args: Vec<Term>) -> Self {
        Self::Functional {
            symbol: symbol.into(),
            args: Arguments::Positional(args),
        }
    }

    /// `(set elements...)`: an unordered collection.
    pub fn set(elements: Vec<Term>) -> Self {
        Self::positional("set", elements)
    }

    /// `(sequence elements...)`: an ordered collection.
    pub fn sequence(elements: Vec<Term>) -> Self {
        Self::positional("sequence", elements)
    }

    /// The kind and elements if this term is a `set` or `sequence` (any ASCII case).
    pub fn collection(&self) -> Option<(Collection, &[Term])> {
        let Self::Functional {
            symbol,
            args: Arguments::Positional(elements),
        } = self
        else {
            return None;
        };
        Collection::from_symbol(symbol).map(|kind| (kind, elements.as_slice()))
    }

    /// The constant inside, if this term is one.
    pub fn as_constant(&self) -> Option<&Constant> {
        match self {
            Self::Constant { value } => Some(value),
            _ => None,
        }
    }
}

/// The two SL aggregates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Collection {
    /// `set`: order is not significant.
    Set,
    /// `sequence`: order is significant.
    Sequence,
}

impl Collection {
    /// The aggregate named by a function symbol (`set`, `SEQUENCE`, ...), if it is one.
    pub fn from_symbol(symbol: &str) -> Option<Self> {
        if symbol.eq_ignore_ascii_case("set") {
            Some(Self::Set)
        } else if symbol.eq_ignore_ascii_case("sequence") {
            Some(Self::Sequence)
        } else {
            None
        }
    }
}

/// Arguments of a functional term.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", content = "value", rename_all = "kebab-case")]
pub enum Arguments {
    /// `(f a b)`; empty for `(f)`.
    Positional(Vec<Term>),
    /// `(f :x a :y b)` (at least one parameter when parsed).
    Named(Vec<Parameter>),
}

impl Arguments {
    /// The value of the named parameter `name` (ASCII case-insensitive, as SL slot names are).
    pub fn get(&self, name: &str) -> Option<&Term> {
        match self {
            Self::Named(params) => params
                .iter()
                .find(|p| p.name.eq_ignore_ascii_case(name))
                .map(|p| &p.value),
            Self::Positional(_) => None,
        }
    }
}

/// `:name value`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Parameter {
    /// Slot name without the colon.
    pub name: String,
    /// Slot value.
    pub value: Term,
}

impl Parameter {
    /// `:name value`.
    pub fn new(name: impl Into<String>, value: Term) -> Self {
        Self {
            name: name.into(),
            value,
        }
    }
}

/// Literal values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", content = "value", rename_all = "kebab-case")]
pub enum Constant {
    /// A word or quoted string. As in JADE, hexadecimal literals (`0x1F`) and integers beyond
    /// 64 bits are kept as strings (their text).
    String(String),
    /// A decimal integer literal.
    Integer(i64),
    /// A floating-point literal.
    Float(f64),
    /// `true` / `false` written as a term (any ASCII case).
    Boolean(bool),
    /// An SL date-time `YYYYMMDDThhmmssmmm[Z]`.
    DateTime(DateTime),
    /// A byte-length-encoded string `#N"...`: exactly `N` bytes (UTF-8) follow the quote. It is
    /// text because SL content travels inside a character message.
    ByteString(String),
}

/// A calendar instant with millisecond precision. SL dates without a zone letter are read as UTC
/// (JADE reads them in its local zone; the reference runs were in UTC).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct DateTime {
    /// Milliseconds since 1970-01-01T00:00:00Z.
    pub unix_ms: i64,
}

impl DateTime {
    /// From calendar fields in UTC; `None` if a field is out of range (years are SL's four
    /// digits, 0 to 9999).
    pub fn from_utc(
        year: i64,
        month: u32,
        day: u32,
        hour: u32,
        minute: u32,
        second: u32,
        milli: u32,
    ) -> Option<Self> {
        if !(0..=9999).contains(&year) {
            return None;
        }
        let month = Month::try_from(u8::try_from(month).ok()?).ok()?;
        let date =
            Date::from_calendar_date(i32::try_from(year).ok()?, month, u8::try_from(day).ok()?)
                .ok()?;
        let time = Time::from_hms_milli(
            u8::try_from(hour).ok()?,
            u8::try_from(minute).ok()?,
            u8::try_from(second).ok()?,
            u16::try_from(milli).ok()?,
        )
        .ok()?;
        let at = PrimitiveDateTime::new(date, time).assume_utc();
        Some(Self {
            unix_ms: i64::try_from(at.unix_timestamp_nanos() / 1_000_000).ok()?,
        })
    }

    /// Calendar fields in UTC: (year, month, day, hour, minute, second, milli, weekday 0=Sunday).
    /// Instants beyond the calendar's range (years past +-9999) saturate to its ends.
    pub fn to_utc_fields(self) -> (i64, u32, u32, u32, u32, u32, u32, u32) {
        let at = OffsetDateTime::from_unix_timestamp_nanos(i128::from(self.unix_ms) * 1_000_000)
            .unwrap_or(if self.unix_ms < 0 {
                PrimitiveDateTime::MIN.assume_utc()
            } else {
                PrimitiveDateTime::MAX.assume_utc()
            });
        (
            i64::from(at.year()),
            u32::from(u8::from(at.month())),
            u32::from(at.day()),
            u32::from(at.hour()),
            u32::from(at.minute()),
            u32::from(at.second()),
            u32::from(at.millisecond()),
            u32::from(at.weekday().number_days_from_sunday()),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calendar_round_trip_and_weekday() {
        let t = DateTime::from_utc(2026, 11, 22, 1, 41, 40, 823).unwrap();
        assert_eq!(t.to_utc_fields(), (2026, 11, 22, 1, 41, 40, 823, 0)); // a Sunday
        let t = DateTime::from_utc(2000, 12, 11, 10, 0, 25, 100).unwrap();
        assert_eq!(t.to_utc_fields().7, 1); // a Monday
        assert!(DateTime::from_utc(2025, 2, 29, 0, 0, 0, 0).is_none());
        assert!(DateTime::from_utc(2024, 2, 29, 0, 0, 0, 0).is_some());
        let before_epoch = DateTime::from_utc(1969, 12, 31, 23, 59, 59, 999).unwrap();
        assert_eq!(before_epoch.unix_ms, -1);
        assert_eq!(before_epoch.to_utc_fields().0, 1969);
    }
}
