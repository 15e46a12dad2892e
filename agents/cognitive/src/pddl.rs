//! PDDL domains and problems, the STRIPS subset with typing and negative preconditions.
//!
//! ```text
//! (define (domain building)
//!   (:requirements :strips :typing :negative-preconditions)
//!   (:types room - place  chair)
//!   (:predicates (at ?c - chair ?p - place) (connected ?a ?b - place) (locked ?a ?b - place))
//!   (:action move
//!     :parameters (?c - chair ?from ?to - place)
//!     :precondition (and (at ?c ?from) (connected ?from ?to) (not (locked ?from ?to)))
//!     :effect (and (not (at ?c ?from)) (at ?c ?to))))
//! ```
//!
//! Names are case-insensitive, as in PDDL, and kept in lower case.

use std::collections::BTreeMap;

/// Nesting deeper than this is refused rather than risking the stack.
const MAX_DEPTH: usize = 64;

/// Where and why a domain or problem could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}, column {column}: {message}")]
pub struct PddlError {
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub column: usize,
    /// What was expected or what is wrong.
    pub message: String,
}

/// A term in an atom: a `?variable` of an action schema or an object name.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Term {
    /// `?name`.
    Var(String),
    /// An object or constant.
    Const(String),
}

/// `(predicate term ...)`.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Atom {
    /// Predicate name.
    pub predicate: String,
    /// Arguments.
    pub args: Vec<Term>,
}

/// An atom or its negation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Literal {
    /// False for `(not atom)`.
    pub positive: bool,
    /// The atom.
    pub atom: Atom,
}

/// An action schema.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ActionSchema {
    /// Action name.
    pub name: String,
    /// `(variable, type)`; the type is `object` when untyped.
    pub parameters: Vec<(String, String)>,
    /// Conjunction of literals that must hold.
    pub precondition: Vec<Literal>,
    /// Atoms made true.
    pub add: Vec<Atom>,
    /// Atoms made false.
    pub delete: Vec<Atom>,
}

/// A planning domain.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Domain {
    /// Domain name.
    pub name: String,
    /// Each declared type and its parent (`object` at the root).
    pub types: BTreeMap<String, String>,
    /// Predicate name and arity.
    pub predicates: BTreeMap<String, usize>,
    /// Domain constants and their types.
    pub constants: Vec<(String, String)>,
    /// Action schemas.
    pub actions: Vec<ActionSchema>,
}

/// A planning problem over a [`Domain`].
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Problem {
    /// Problem name.
    pub name: String,
    /// The domain it names.
    pub domain: String,
    /// Objects and their types.
    pub objects: Vec<(String, String)>,
    /// Ground atoms true initially (everything else is false).
    pub init: Vec<Atom>,
    /// Conjunction of ground literals to reach.
    pub goal: Vec<Literal>,
}

impl Domain {
    /// Whether `ty` is `ancestor` or one of its subtypes.
    pub fn is_subtype(&self, ty: &str, ancestor: &str) -> bool {
        let mut current = ty;
        for _ in 0..=self.types.len() {
            if current == ancestor {
                return true;
            }
            match self.types.get(current) {
                Some(parent) => current = parent,
                None => return ancestor == "object",
            }
        }
        false
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Pos {
    line: usize,
    column: usize,
}

#[derive(Debug, Clone)]
enum Sexp {
    Sym(String, Pos),
    List(Vec<Sexp>, Pos),
}

impl Sexp {
    fn pos(&self) -> Pos {
        match self {
            Sexp::Sym(_, p) | Sexp::List(_, p) => *p,
        }
    }
}

fn error(pos: Pos, message: impl Into<String>) -> PddlError {
    PddlError {
        line: pos.line,
        column: pos.column,
        message: message.into(),
    }
}

/// Reads the whole text as one s-expression.
fn read(text: &str) -> Result<Sexp, PddlError> {
    let mut chars = text.chars().peekable();
    let mut pos = Pos { line: 1, column: 1 };
    let mut stack: Vec<(Vec<Sexp>, Pos)> = Vec::new();
    let mut done: Option<Sexp> = None;
    let advance = |c: char, pos: &mut Pos| {
        if c == '\n' {
            pos.line += 1;
            pos.column = 1;
        } else {
            pos.column += 1;
        }
    };
    while let Some(&c) = chars.peek() {
        let here = pos;
        if c.is_whitespace() {
            chars.next();
            advance(c, &mut pos);
            continue;
        }
        if c == ';' {
            while let Some(&c) = chars.peek() {
                if c == '\n' {
                    break;
                }
                chars.next();
                advance(c, &mut pos);
            }
            continue;
        }
        if done.is_some() {
            return Err(error(here, "unexpected text after the closing parenthesis"));
        }
        let item = match c {
            '(' => {
                chars.next();
                advance(c, &mut pos);
                if stack.len() >= MAX_DEPTH {
                    return Err(error(
                        here,
                        format!("nesting deeper than {MAX_DEPTH} levels"),
                    ));
                }
                stack.push((Vec::new(), here));
                continue;
            }
            ')' => {
                chars.next();
                advance(c, &mut pos);
                let (items, start) = stack
                    .pop()
                    .ok_or_else(|| error(here, "`)` without a matching `(`"))?;
                Sexp::List(items, start)
            }
            _ => {
                let mut symbol = String::new();
                while let Some(&c) = chars.peek() {
                    if c.is_whitespace() || c == '(' || c == ')' || c == ';' {
                        break;
                    }
                    symbol.extend(c.to_lowercase());
                    chars.next();
                    advance(c, &mut pos);
                }
                Sexp::Sym(symbol, here)
            }
        };
        match stack.last_mut() {
            Some((items, _)) => items.push(item),
            None if matches!(item, Sexp::List(..)) => done = Some(item),
            None => return Err(error(here, "expected `(define ...)`")),
        }
    }
    if let Some((_, start)) = stack.last() {
        return Err(error(*start, "`(` is never closed"));
    }
    done.ok_or_else(|| error(pos, "empty input: expected `(define ...)`"))
}

fn list(s: &Sexp, what: &str) -> Result<Vec<Sexp>, PddlError> {
    match s {
        Sexp::List(items, _) => Ok(items.clone()),
        Sexp::Sym(sym, p) => Err(error(*p, format!("expected {what}, found `{sym}`"))),
    }
}

fn symbol<'a>(s: &'a Sexp, what: &str) -> Result<&'a str, PddlError> {
    match s {
        Sexp::Sym(sym, _) => Ok(sym),
        Sexp::List(_, p) => Err(error(*p, format!("expected {what}, found a list"))),
    }
}

/// Splits `(define (KIND name) sections...)` and checks KIND.
fn define(text: &str, kind: &str) -> Result<(String, Vec<Sexp>), PddlError> {
    let top = read(text)?;
    let items = list(&top, "`(define ...)`")?;
    let [head, name_list, sections @ ..] = items.as_slice() else {
        return Err(error(
            top.pos(),
            format!("expected `(define ({kind} NAME) ...)`"),
        ));
    };
    if symbol(head, "`define`")? != "define" {
        return Err(error(head.pos(), "expected `define`"));
    }
    let name_items = list(name_list, &format!("`({kind} NAME)`"))?;
    match name_items.as_slice() {
        [k, n] if symbol(k, kind)? == kind => {
            Ok((symbol(n, "a name")?.to_string(), sections.to_vec()))
        }
        _ => Err(error(name_list.pos(), format!("expected `({kind} NAME)`"))),
    }
}

/// Splits a section `(:key items...)`.
fn section(s: &Sexp) -> Result<(String, Vec<Sexp>, Pos), PddlError> {
    let items = list(s, "a `(:section ...)`")?;
    let (key, rest) = items
        .split_first()
        .ok_or_else(|| error(s.pos(), "empty section"))?;
    Ok((
        symbol(key, "a section keyword")?.to_string(),
        rest.to_vec(),
        s.pos(),
    ))
}

/// `a b - t c - u d` into `[(a,t),(b,t),(c,u),(d,object)]`.
fn typed_list(items: &[Sexp], vars: bool) -> Result<Vec<(String, String)>, PddlError> {
    let mut out = Vec::new();
    let mut pending: Vec<String> = Vec::new();
    let mut iter = items.iter();
    while let Some(item) = iter.next() {
        let name = symbol(item, "a name")?;
        if name == "-" {
            let ty = iter
                .next()
                .ok_or_else(|| error(item.pos(), "expected a type after `-`"))?;
            let ty = symbol(ty, "a type name")?;
            if pending.is_empty() {
                return Err(error(item.pos(), "`-` with no names before it"));
            }
            out.extend(pending.drain(..).map(|n| (n, ty.to_string())));
            continue;
        }
        if vars != name.starts_with('?') {
            let want = if vars {
                "a `?variable`"
            } else {
                "a name (not a `?variable`)"
            };
            return Err(error(
                item.pos(),
                format!("expected {want}, found `{name}`"),
            ));
        }
        pending.push(name.to_string());
    }
    out.extend(pending.into_iter().map(|n| (n, "object".to_string())));
    Ok(out)
}

fn atom(s: &Sexp) -> Result<Atom, PddlError> {
    let items = list(s, "an atom `(predicate ...)`")?;
    let (head, args) = items
        .split_first()
        .ok_or_else(|| error(s.pos(), "empty atom"))?;
    let predicate = symbol(head, "a predicate name")?.to_string();
    let args = args
        .iter()
        .map(|a| {
            symbol(a, "a term").map(|t| match t.strip_prefix('?') {
                Some(_) => Term::Var(t.to_string()),
                None => Term::Const(t.to_string()),
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(Atom { predicate, args })
}

/// `(and l...)`, `(not a)`, `a` or `()` into a conjunction of literals.
fn conjunction(s: &Sexp) -> Result<Vec<Literal>, PddlError> {
    let items = list(s, "a condition")?;
    match items.first() {
        None => Ok(Vec::new()),
        Some(Sexp::Sym(head, _)) if head == "and" => items[1..].iter().map(literal).collect(),
        _ => Ok(vec![literal(s)?]),
    }
}

fn literal(s: &Sexp) -> Result<Literal, PddlError> {
    let items = list(s, "a literal")?;
    match items.as_slice() {
        [Sexp::Sym(head, _), inner] if head == "not" => Ok(Literal {
            positive: false,
            atom: atom(inner)?,
        }),
        [Sexp::Sym(head, p), ..]
            if matches!(
                head.as_str(),
                "or" | "imply" | "forall" | "exists" | "when" | "and"
            ) =>
        {
            Err(error(
                *p,
                format!(
                    "`{head}` is outside the supported STRIPS subset (conjunctions of literals)"
                ),
            ))
        }
        _ => Ok(Literal {
            positive: true,
            atom: atom(s)?,
        }),
    }
}

fn check_atom(domain: &Domain, atom: &Atom, pos: Pos) -> Result<(), PddlError> {
    match domain.predicates.get(&atom.predicate) {
        None => Err(error(
            pos,
            format!("unknown predicate `{}`", atom.predicate),
        )),
        Some(&arity) if arity != atom.args.len() => Err(error(
            pos,
            format!(
                "`{}` takes {arity} arguments, found {}",
                atom.predicate,
                atom.args.len()
            ),
        )),
        Some(_) => Ok(()),
    }
}

impl Domain {
    /// Reads a domain file's text.
    pub fn parse(text: &str) -> Result<Domain, PddlError> {
        let (name, sections) = define(text, "domain")?;
        let mut domain = Domain {
            name,
            ..Domain::default()
        };
        for s in &sections {
            let (key, items, pos) = section(s)?;
            match key.as_str() {
                ":requirements" => {
                    for item in &items {
                        let req = symbol(item, "a requirement")?;
                        if !matches!(req, ":strips" | ":typing" | ":negative-preconditions") {
                            return Err(error(
                                item.pos(),
                                format!("unsupported requirement `{req}`"),
                            ));
                        }
                    }
                }
                ":types" => domain.types.extend(typed_list(&items, false)?),
                ":constants" => domain.constants = typed_list(&items, false)?,
                ":predicates" => {
                    for p in &items {
                        let parts = list(p, "a predicate declaration")?;
                        let (head, params) = parts
                            .split_first()
                            .ok_or_else(|| error(p.pos(), "empty predicate"))?;
                        let arity = typed_list(params, true)?.len();
                        domain
                            .predicates
                            .insert(symbol(head, "a predicate name")?.to_string(), arity);
                    }
                }
                ":action" => domain.actions.push(action(&items, pos)?),
                other => return Err(error(pos, format!("unknown domain section `{other}`"))),
            }
        }
        for (ty, parent) in &domain.types {
            if !domain.is_subtype(ty, "object") {
                return Err(error(
                    Pos { line: 1, column: 1 },
                    format!("type `{ty}` has a cyclic parent `{parent}`"),
                ));
            }
        }
        for a in &domain.actions {
            let pos = Pos { line: 1, column: 1 };
            for l in &a.precondition {
                check_atom(&domain, &l.atom, pos).map_err(|e| PddlError {
                    message: format!("action `{}`: {}", a.name, e.message),
                    ..e
                })?;
            }
            for at in a.add.iter().chain(&a.delete) {
                check_atom(&domain, at, pos).map_err(|e| PddlError {
                    message: format!("action `{}`: {}", a.name, e.message),
                    ..e
                })?;
            }
            let params: Vec<&str> = a.parameters.iter().map(|(v, _)| v.as_str()).collect();
            for at in a
                .precondition
                .iter()
                .map(|l| &l.atom)
                .chain(&a.add)
                .chain(&a.delete)
            {
                for t in &at.args {
                    if let Term::Var(v) = t
                        && !params.contains(&v.as_str())
                    {
                        return Err(error(
                            pos,
                            format!("action `{}` uses `{v}`, which is not a parameter", a.name),
                        ));
                    }
                }
            }
        }
        Ok(domain)
    }
}

fn action(items: &[Sexp], pos: Pos) -> Result<ActionSchema, PddlError> {
    let (name, rest) = items
        .split_first()
        .ok_or_else(|| error(pos, "expected an action name"))?;
    let mut schema = ActionSchema {
        name: symbol(name, "an action name")?.to_string(),
        parameters: Vec::new(),
        precondition: Vec::new(),
        add: Vec::new(),
        delete: Vec::new(),
    };
    let mut iter = rest.iter();
    while let Some(key) = iter.next() {
        let key_name = symbol(key, "`:parameters`, `:precondition` or `:effect`")?;
        let value = iter
            .next()
            .ok_or_else(|| error(key.pos(), format!("`{key_name}` has no value")))?;
        match key_name {
            ":parameters" => {
                schema.parameters = typed_list(&list(value, "a parameter list")?, true)?
            }
            ":precondition" => schema.precondition = conjunction(value)?,
            ":effect" => {
                for l in conjunction(value)? {
                    if l.positive {
                        schema.add.push(l.atom)
                    } else {
                        schema.delete.push(l.atom)
                    }
                }
            }
            other => return Err(error(key.pos(), format!("unknown action key `{other}`"))),
        }
    }
    Ok(schema)
}

impl Problem {
    /// Reads a problem file's text, checking it against its domain.
    pub fn parse(text: &str, domain: &Domain) -> Result<Problem, PddlError> {
        let (name, sections) = define(text, "problem")?;
        let mut problem = Problem {
            name,
            ..Problem::default()
        };
        let mut goal_pos = None;
        for s in &sections {
            let (key, items, pos) = section(s)?;
            match key.as_str() {
                ":domain" => {
                    let d = items
                        .first()
                        .ok_or_else(|| error(pos, "expected the domain name"))?;
                    problem.domain = symbol(d, "the domain name")?.to_string();
                    if problem.domain != domain.name {
                        return Err(error(
                            d.pos(),
                            format!(
                                "problem is for domain `{}`, not `{}`",
                                problem.domain, domain.name
                            ),
                        ));
                    }
                }
                ":objects" => problem.objects = typed_list(&items, false)?,
                ":init" => {
                    for a in &items {
                        let at = atom(a)?;
                        check_atom(domain, &at, a.pos())?;
                        if at.args.iter().any(|t| matches!(t, Term::Var(_))) {
                            return Err(error(
                                a.pos(),
                                "`:init` atoms must be ground (no `?variables`)",
                            ));
                        }
                        problem.init.push(at);
                    }
                }
                ":goal" => {
                    let g = items
                        .first()
                        .ok_or_else(|| error(pos, "expected a goal condition"))?;
                    problem.goal = conjunction(g)?;
                    for l in &problem.goal {
                        check_atom(domain, &l.atom, g.pos())?;
                    }
                    goal_pos = Some(g.pos());
                }
                other => return Err(error(pos, format!("unknown problem section `{other}`"))),
            }
        }
        if goal_pos.is_none() {
            return Err(error(
                Pos { line: 1, column: 1 },
                "the problem has no `:goal`",
            ));
        }
        Ok(problem)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn errors_say_where_and_why() {
        let e = Domain::parse("(define (domain d)\n  (:predicates (p ?x))\n  (:action a :parameters (?x) :effect (q ?x)))").unwrap_err();
        assert!(e.message.contains("unknown predicate `q`"), "{e}");
        let e = Domain::parse("(define (domain d)\n (:types a - b\n").unwrap_err();
        assert_eq!((e.line, e.column), (2, 2), "{e}");
        let e = Domain::parse("(define (domain d) (:action a :precondition (or (p) (q))))")
            .unwrap_err();
        assert!(
            e.message.contains("outside the supported STRIPS subset"),
            "{e}"
        );
        let e = Domain::parse(&"(".repeat(100)).unwrap_err();
        assert!(e.message.contains("nesting deeper"), "{e}");
    }

    proptest! {
        #[test]
        fn no_input_panics(text in "[()a-z?:; \\n-]{0,200}") {
            let _ = Domain::parse(&text);
            let _ = Problem::parse(&text, &Domain::default());
        }
    }
}
