//! SL text from the tree: `Display` for every node.
//!
//! Output is canonical (single spaces, no redundant quotes) and reads back as the same tree at
//! any level that allows its constructs. Words are quoted when they would read back as something
//! else (`"true"`, `"12"`, `"not"`, `"a b"`); inside quotes only `"` is escaped (`\"`), as SL and
//! JADE define. Two values have no exact SL spelling: a string ending in a backslash is written
//! as a byte string `#N"...`, and a non-finite float as the quoted `"NaN"`/`"Infinity"`.

use std::fmt::{self, Display, Formatter, Write};

use crate::ast::{
    ActionExpression, ActionOp, ActionOperand, Arguments, ArithmeticOp, BinaryOp, Constant,
    Content, ContentExpression, DateTime, Formula, IdentifyingExpression, ModalOp, Quantifier,
    ReferentialOp, Term,
};
use crate::jade::java_double;
use crate::lexer::is_bare_word;

/// Writes `s` bare if it reads back as the same word, quoted otherwise.
fn write_symbol(f: &mut Formatter<'_>, s: &str) -> fmt::Result {
    if is_bare_word(s) {
        f.write_str(s)
    } else {
        write_quoted(f, s)
    }
}

fn write_quoted(f: &mut Formatter<'_>, s: &str) -> fmt::Result {
    f.write_char('"')?;
    for c in s.chars() {
        if c == '"' {
            f.write_str("\\\"")?;
        } else {
            f.write_char(c)?;
        }
    }
    f.write_char('"')
}

/// Writes a string constant so that it reads back as the same string (not a boolean, number...).
fn write_string_constant(f: &mut Formatter<'_>, s: &str) -> fmt::Result {
    let is_bool = s.eq_ignore_ascii_case("true") || s.eq_ignore_ascii_case("false");
    if is_bare_word(s) && !is_bool {
        f.write_str(s)
    } else if s.ends_with('\\') {
        write!(f, "#{}\"{s}", s.len())
    } else {
        write_quoted(f, s)
    }
}

fn write_list<T: Display>(f: &mut Formatter<'_>, items: &[T]) -> fmt::Result {
    for item in items {
        write!(f, " {item}")?;
    }
    Ok(())
}

impl Display for Content {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        f.write_char('(')?;
        for (i, e) in self.expressions.iter().enumerate() {
            if i > 0 {
                f.write_char(' ')?;
            }
            write!(f, "{e}")?;
        }
        f.write_char(')')
    }
}

impl Display for ContentExpression {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            ContentExpression::Formula(x) => x.fmt(f),
            ContentExpression::Action(x) => x.fmt(f),
            ContentExpression::Identifying(x) => x.fmt(f),
        }
    }
}

impl Display for Formula {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Formula::Symbol { name } => write_symbol(f, name),
            Formula::Meta { name } => f.write_str(name),
            // `(p)` is not SL: a predicate without arguments is a proposition symbol.
            Formula::Atomic { predicate, args } if args.is_empty() => write_symbol(f, predicate),
            Formula::Atomic { predicate, args } => {
                f.write_char('(')?;
                write_symbol(f, predicate)?;
                write_list(f, args)?;
                f.write_char(')')
            }
            Formula::Not { formula } => write!(f, "(not {formula})"),
            Formula::Binary { op, left, right } => write!(f, "({} {left} {right})", op.keyword()),
            Formula::Quantified {
                quantifier,
                variable,
                formula,
            } => {
                write!(f, "({} ", quantifier.keyword())?;
                write_variable(f, variable)?;
                write!(f, " {formula})")
            }
            Formula::Modal { op, agent, formula } => {
                write!(f, "({} {agent} {formula})", op.keyword())
            }
            Formula::ActionCondition {
                op,
                action,
                condition,
            } => {
                write!(f, "({} {action}", op.keyword())?;
                if let Some(c) = condition {
                    write!(f, " {c}")?;
                }
                f.write_char(')')
            }
        }
    }
}

fn write_variable(f: &mut Formatter<'_>, name: &str) -> fmt::Result {
    f.write_char('?')?;
    write_symbol(f, name)
}

impl Display for ActionExpression {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            ActionExpression::Action { agent, act } => write!(f, "(action {agent} {act})"),
            ActionExpression::Alternative { first, second } => write!(f, "(| {first} {second})"),
            ActionExpression::Sequence { first, second } => write!(f, "(; {first} {second})"),
        }
    }
}

impl Display for ActionOperand {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            ActionOperand::Expression(a) => a.fmt(f),
            ActionOperand::Meta(name) => f.write_str(name),
        }
    }
}

impl Display for IdentifyingExpression {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        write!(f, "({} {} {})", self.op.keyword(), self.term, self.formula)
    }
}

impl Display for Term {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Term::Variable { name } => write_variable(f, name),
            Term::Meta { name } => f.write_str(name),
            Term::Constant { value } => value.fmt(f),
            Term::Functional { symbol, args } => {
                f.write_char('(')?;
                write_symbol(f, symbol)?;
                match args {
                    Arguments::Positional(terms) => write_list(f, terms)?,
                    Arguments::Named(params) => {
                        for p in params {
                            f.write_str(" :")?;
                            write_symbol(f, &p.name)?;
                            write!(f, " {}", p.value)?;
                        }
                    }
                }
                f.write_char(')')
            }
            Term::Arithmetic { op, left, right } => write!(f, "({} {left} {right})", op.keyword()),
            Term::Action { action } => action.fmt(f),
            Term::Identifying { expression } => expression.fmt(f),
        }
    }
}

impl Display for Constant {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Constant::String(s) => write_string_constant(f, s),
            Constant::Integer(i) => write!(f, "{i}"),
            Constant::Float(x) if x.is_finite() => f.write_str(&java_double(*x)),
            Constant::Float(x) => write_quoted(f, &java_double(*x)),
            Constant::Boolean(b) => write!(f, "{b}"),
            Constant::DateTime(d) => d.fmt(f),
            Constant::ByteString(s) => write!(f, "#{}\"{s}", s.len()),
        }
    }
}

impl Display for DateTime {
    /// `YYYYMMDDThhmmssmmmZ` (UTC).
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let (y, mo, d, h, mi, s, ms, _) = self.to_utc_fields();
        write!(f, "{y:04}{mo:02}{d:02}T{h:02}{mi:02}{s:02}{ms:03}Z")
    }
}

impl BinaryOp {
    /// The SL keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            BinaryOp::And => "and",
            BinaryOp::Or => "or",
            BinaryOp::Implies => "implies",
            BinaryOp::Equiv => "equiv",
        }
    }
}

impl Quantifier {
    /// The SL keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            Quantifier::Forall => "forall",
            Quantifier::Exists => "exists",
        }
    }
}

impl ModalOp {
    /// The SL keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            ModalOp::B => "B",
            ModalOp::U => "U",
            ModalOp::PG => "PG",
            ModalOp::I => "I",
        }
    }
}

impl ActionOp {
    /// The SL keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            ActionOp::Done => "done",
            ActionOp::Feasible => "feasible",
        }
    }
}

impl ReferentialOp {
    /// The SL keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            ReferentialOp::Iota => "iota",
            ReferentialOp::Any => "any",
            ReferentialOp::All => "all",
        }
    }
}

impl ArithmeticOp {
    /// The SL symbol.
    pub fn keyword(self) -> &'static str {
        match self {
            ArithmeticOp::Add => "+",
            ArithmeticOp::Sub => "-",
            ArithmeticOp::Mul => "*",
            ArithmeticOp::Div => "/",
            ArithmeticOp::Rem => "%",
        }
    }
}
