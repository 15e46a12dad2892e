//! The tree as JADE shows it: `AbsContentElement.toString()` of JADE's SL codec at a level.
//!
//! This is the oracle's representation in `sl-decode.jsonl` (the `abs` field), so matching it
//! string for string checks that our tree carries what JADE's does. JADE names positional slots
//! after its per-level ontology (`(and :left .. :right ..)` from SL1 up, `(implies :left ..)` from
//! SL2 up) and `_JADE.UNNAMEDi` otherwise; it renders primitives with Java's `toString`
//! (doubles as `1500.0`, dates as `Sun Nov 22 01:41:40 UTC 2026`, byte arrays as `[B@hash`).

use std::fmt::Write;

use crate::ast::{
    ActionExpression, ActionOp, ActionOperand, Arguments, Collection, Constant, Content,
    ContentExpression, DateTime, Formula, IdentifyingExpression, Term,
};
use crate::level::Level;

/// JADE's rendering of `content` as parsed by its codec for `level`.
pub fn jade_tree(content: &Content, level: Level) -> String {
    let mut r = Renderer {
        tier: level.ontology_tier(),
        out: String::new(),
    };
    match content.expressions.as_slice() {
        [single] => r.content_expression(single),
        many => {
            r.out.push_str("(ContentElementList");
            for (i, e) in many.iter().enumerate() {
                let _ = write!(r.out, " #{i} ");
                r.content_expression(e);
            }
            r.out.push(')');
        }
    }
    r.out
}

/// Slot names JADE's ontology gives positional arguments of `symbol` at ontology `tier`.
fn slot_names(symbol: &str, tier: u8) -> &'static [&'static str] {
    let s = symbol.to_ascii_lowercase();
    match s.as_str() {
        "action" => &["actor", "action"],
        "done" => &["action", "condition"],
        "result" => &["action", "value"],
        "=" => &["left", "right"],
        "agent-identifier" => &["name", "addresses", "resolvers"],
        "property" => &["name", "value"],
        "and" | "or" if tier >= 1 => &["left", "right"],
        "not" if tier >= 1 => &["what"],
        "implies" | "equiv" if tier >= 2 => &["left", "right"],
        "forall" | "exists" if tier >= 2 => &["what", "condition"],
        "b" | "u" | "pg" | "i" if tier >= 2 => &["agent", "condition"],
        "feasible" if tier >= 2 => &["action", "condition"],
        "|" | ";" if tier >= 2 => &["first", "second"],
        _ => &[],
    }
}

/// Concepts JADE's basic ontology knows: it renames them to their canonical spelling.
fn canonical_concept(symbol: &str) -> &str {
    ["agent-identifier", "property"]
        .into_iter()
        .find(|c| c.eq_ignore_ascii_case(symbol))
        .unwrap_or(symbol)
}

struct Renderer {
    tier: u8,
    out: String,
}

impl Renderer {
    /// `(name :slot value ...)` with positional slots named by the ontology.
    fn positional<T>(&mut self, name: &str, args: &[T], each: impl Fn(&mut Self, &T)) {
        let names = slot_names(name, self.tier);
        self.out.push('(');
        self.out.push_str(name);
        for (i, a) in args.iter().enumerate() {
            match names.get(i) {
                Some(n) => {
                    let _ = write!(self.out, " :{n} ");
                }
                None => {
                    let _ = write!(self.out, " :_JADE.UNNAMED{i} ");
                }
            }
            each(self, a);
        }
        self.out.push(')');
    }

    fn content_expression(&mut self, e: &ContentExpression) {
        match e {
            ContentExpression::Formula(f) => self.formula(f),
            ContentExpression::Action(a) => self.action(a),
            ContentExpression::Identifying(i) => self.identifying(i),
        }
    }

    fn formula(&mut self, f: &Formula) {
        match f {
            Formula::Symbol { name } | Formula::Meta { name } => {
                let _ = write!(self.out, "({name})");
            }
            Formula::Atomic { predicate, args } => self.positional(predicate, args, Self::term),
            Formula::Not { formula } => self.positional("not", &[formula], |r, f| r.formula(f)),
            Formula::Binary { op, left, right } => {
                self.positional(op.keyword(), &[left, right], |r, f| r.formula(f));
            }
            Formula::Quantified {
                quantifier,
                variable,
                formula,
            } => {
                let var = Term::Variable {
                    name: variable.clone(),
                };
                self.positional(quantifier.keyword(), &[0, 1], |r, &i| {
                    if i == 0 {
                        r.term(&var)
                    } else {
                        r.formula(formula)
                    }
                });
            }
            Formula::Modal { op, agent, formula } => {
                self.positional(op.keyword(), &[0, 1], |r, &i| {
                    if i == 0 {
                        r.term(agent)
                    } else {
                        r.formula(formula)
                    }
                });
            }
            Formula::ActionCondition {
                op,
                action,
                condition,
            } => {
                let name = match op {
                    ActionOp::Done => "done",
                    ActionOp::Feasible => "feasible",
                };
                let n = if condition.is_some() { 2 } else { 1 };
                self.positional(name, &[0, 1][..n], |r, &i| match (i, condition) {
                    (1, Some(c)) => r.formula(c),
                    _ => r.operand(action),
                });
            }
        }
    }

    fn operand(&mut self, a: &ActionOperand) {
        match a {
            ActionOperand::Expression(e) => self.action(e),
            ActionOperand::Meta(name) => self.variable(name),
        }
    }

    fn action(&mut self, a: &ActionExpression) {
        match a {
            ActionExpression::Action { agent, act } => {
                self.positional("action", &[agent, act], |r, t| r.term(t));
            }
            ActionExpression::Alternative { first, second } => {
                self.positional("|", &[first, second], |r, o| r.operand(o));
            }
            ActionExpression::Sequence { first, second } => {
                self.positional(";", &[first, second], |r, o| r.operand(o));
            }
        }
    }

    fn identifying(&mut self, i: &IdentifyingExpression) {
        let _ = write!(self.out, "({} :Variable ", i.op.keyword());
        self.term(&i.term);
        self.out.push_str(" :Proposition ");
        self.formula(&i.formula);
        self.out.push(')');
    }

    fn variable(&mut self, name: &str) {
        let _ = write!(self.out, "(Variable :Name {name})");
    }

    fn term(&mut self, t: &Term) {
        match t {
            Term::Variable { name } | Term::Meta { name } => self.variable(name),
            Term::Constant { value } => self.constant(value),
            Term::Functional {
                symbol,
                args: Arguments::Positional(elements),
            } if Collection::from_symbol(symbol).is_some() => {
                self.out.push('(');
                self.out.push_str(symbol);
                for (i, e) in elements.iter().enumerate() {
                    let _ = write!(self.out, " #{i} ");
                    self.term(e);
                }
                self.out.push(')');
            }
            Term::Functional { symbol, args } => {
                let name = canonical_concept(symbol);
                match args {
                    Arguments::Positional(terms) => self.positional(name, terms, Self::term),
                    Arguments::Named(params) => {
                        self.out.push('(');
                        self.out.push_str(name);
                        for p in params {
                            let _ = write!(self.out, " :{} ", p.name);
                            self.term(&p.value);
                        }
                        self.out.push(')');
                    }
                }
            }
            Term::Arithmetic { op, left, right } => {
                self.positional(op.keyword(), &[left, right], |r, t| r.term(t));
            }
            Term::Action { action } => self.action(action),
            Term::Identifying { expression } => self.identifying(expression),
        }
    }

    fn constant(&mut self, c: &Constant) {
        match c {
            Constant::String(s) => self.out.push_str(s),
            Constant::Integer(i) => {
                let _ = write!(self.out, "{i}");
            }
            Constant::Float(x) => self.out.push_str(&java_double(*x)),
            Constant::Boolean(b) => {
                let _ = write!(self.out, "{b}");
            }
            Constant::DateTime(d) => self.out.push_str(&java_date(*d)),
            Constant::ByteString(s) => {
                // Java prints a byte[] as its identity hash; we print a content hash in its place.
                let h = s.bytes().fold(0x811c_9dc5_u32, |h, b| {
                    (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
                });
                let _ = write!(self.out, "[B@{h:x}");
            }
        }
    }
}

/// Java's `Double.toString`: plain with at least one decimal in [1e-3, 1e7), else `d.dddE±n`.
pub(crate) fn java_double(x: f64) -> String {
    if x.is_nan() {
        return "NaN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 {
            "Infinity".into()
        } else {
            "-Infinity".into()
        };
    }
    let a = x.abs();
    if a == 0.0 || (1e-3..1e7).contains(&a) {
        let s = format!("{x}");
        return if s.contains('.') { s } else { format!("{s}.0") };
    }
    // Rust's shortest round-trip digits in scientific form: `1.5e-5`, `1e7`.
    let s = format!("{x:e}");
    let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
    let mantissa = if mantissa.contains('.') {
        mantissa.to_owned()
    } else {
        format!("{mantissa}.0")
    };
    format!("{mantissa}E{exponent}")
}

/// Java's `Date.toString` in UTC: `Sun Nov 22 01:41:40 UTC 2026`.
fn java_date(d: DateTime) -> String {
    const DAYS: [&str; 7] = ["Sun", "Mon", "Tue", "Wed", "Thu", "Fri", "Sat"];
    const MONTHS: [&str; 12] = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    let (y, mo, day, h, mi, s, _, wd) = d.to_utc_fields();
    let weekday = DAYS.get(wd as usize).copied().unwrap_or("?");
    let month = (mo as usize)
        .checked_sub(1)
        .and_then(|i| MONTHS.get(i))
        .copied()
        .unwrap_or("?");
    format!("{weekday} {month} {day:02} {h:02}:{mi:02}:{s:02} UTC {y}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn java_double_matches_java() {
        for (x, s) in [
            (1500.0, "1500.0"),
            (0.001, "0.001"),
            (-0.5, "-0.5"),
            (1.5, "1.5"),
            (1e7, "1.0E7"),
            (1.25e-4, "1.25E-4"),
            (0.0, "0.0"),
            (-12.23, "-12.23"),
            (f64::INFINITY, "Infinity"),
        ] {
            assert_eq!(java_double(x), s, "{x}");
        }
    }
}
