//! Properties: printing then parsing gives the same tree; no input makes the parser panic.

use iw_sl::{
    ActionExpression, ActionOp, ActionOperand, Arguments, ArithmeticOp, BinaryOp, Constant,
    Content, ContentExpression, DateTime, Formula, IdentifyingExpression, Level, ModalOp,
    Parameter, Quantifier, ReferentialOp, SlError, Term, parse,
};
use proptest::prelude::*;

/// Text SL can quote: anything not ending in a backslash (see the printer's documentation).
fn text() -> impl Strategy<Value = String> {
    prop_oneof![
        "[a-zA-Z][a-zA-Z0-9@:/._-]{0,12}",
        "[ -~]{0,10}[ -\\[\\]-~]",
        "\\PC{0,6}[a-z]",
        Just("true".to_owned()),
        Just("not".to_owned()),
        Just("12".to_owned()),
        Just("+5".to_owned()),
        Just(".5".to_owned()),
    ]
}

fn word() -> impl Strategy<Value = String> {
    "[a-zA-Z][a-zA-Z0-9_-]{0,8}"
}

fn constant() -> impl Strategy<Value = Constant> {
    prop_oneof![
        text().prop_map(Constant::String),
        any::<i64>().prop_map(Constant::Integer),
        any::<f64>()
            .prop_filter("finite", |x| x.is_finite())
            .prop_map(Constant::Float),
        any::<bool>().prop_map(Constant::Boolean),
        (
            0i64..=9999,
            1u32..=12,
            1u32..=28,
            0u32..24,
            0u32..60,
            0u32..60,
            0u32..1000
        )
            .prop_map(|(y, mo, d, h, mi, s, ms)| Constant::DateTime(
                DateTime::from_utc(y, mo, d, h, mi, s, ms).unwrap()
            )),
        "\\PC{0,8}".prop_map(Constant::ByteString),
    ]
}

fn term() -> impl Strategy<Value = Term> {
    let leaf = prop_oneof![
        constant().prop_map(|value| Term::Constant { value }),
        text().prop_map(|name| Term::Variable { name }),
        word().prop_map(|w| Term::Meta {
            name: format!("??{w}")
        }),
    ];
    leaf.prop_recursive(4, 24, 4, |inner| {
        prop_oneof![
            (text(), prop::collection::vec(inner.clone(), 0..4)).prop_map(|(s, args)| {
                Term::Functional {
                    symbol: s,
                    args: Arguments::Positional(args),
                }
            }),
            (text(), prop::collection::vec((text(), inner.clone()), 1..4)).prop_map(|(s, ps)| {
                let params = ps.into_iter().map(|(n, v)| Parameter::new(n, v)).collect();
                Term::Functional {
                    symbol: s,
                    args: Arguments::Named(params),
                }
            }),
            prop::collection::vec(inner.clone(), 0..4).prop_map(Term::set),
            (inner.clone(), inner.clone()).prop_map(|(l, r)| Term::Arithmetic {
                op: ArithmeticOp::Mul,
                left: Box::new(l),
                right: Box::new(r)
            }),
            (inner.clone(), inner.clone()).prop_map(|(agent, act)| Term::Action {
                action: Box::new(ActionExpression::Action { agent, act })
            }),
        ]
    })
}

fn formula() -> impl Strategy<Value = Formula> {
    let leaf = prop_oneof![
        text().prop_map(|name| Formula::Symbol { name }),
        word().prop_map(|w| Formula::Meta {
            name: format!("??{w}")
        }),
        (text(), prop::collection::vec(term(), 1..3))
            .prop_map(|(predicate, args)| Formula::Atomic { predicate, args }),
    ];
    leaf.prop_recursive(3, 16, 2, |inner| {
        prop_oneof![
            inner.clone().prop_map(|f| Formula::Not {
                formula: Box::new(f)
            }),
            (inner.clone(), inner.clone()).prop_map(|(l, r)| Formula::Binary {
                op: BinaryOp::Implies,
                left: Box::new(l),
                right: Box::new(r)
            }),
            (word(), inner.clone()).prop_map(|(v, f)| Formula::Quantified {
                quantifier: Quantifier::Exists,
                variable: v,
                formula: Box::new(f)
            }),
            (term(), inner.clone()).prop_map(|(agent, f)| Formula::Modal {
                op: ModalOp::PG,
                agent,
                formula: Box::new(f)
            }),
            (term(), term(), prop::option::of(inner.clone())).prop_map(|(agent, act, c)| {
                Formula::ActionCondition {
                    op: ActionOp::Done,
                    action: Box::new(ActionOperand::Expression(ActionExpression::Action {
                        agent,
                        act,
                    })),
                    condition: c.map(Box::new),
                }
            }),
        ]
    })
}

fn expression() -> impl Strategy<Value = ContentExpression> {
    prop_oneof![
        formula().prop_map(ContentExpression::Formula),
        (term(), term()).prop_map(|(agent, act)| ContentExpression::Action(
            ActionExpression::Sequence {
                first: Box::new(ActionOperand::Expression(ActionExpression::Action {
                    agent,
                    act
                })),
                second: Box::new(ActionOperand::Meta("??next".into())),
            }
        )),
        (term(), formula()).prop_map(|(term, formula)| ContentExpression::Identifying(
            IdentifyingExpression {
                op: ReferentialOp::All,
                term,
                formula
            }
        )),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn printed_content_parses_back_to_itself(exprs in prop::collection::vec(expression(), 1..3)) {
        let content = Content { expressions: exprs };
        let text = content.to_string();
        prop_assert_eq!(parse(&text, Level::Full), Ok(content), "{}", text);
    }

    #[test]
    fn arbitrary_text_never_panics(s in "\\PC{0,80}") {
        for level in Level::ALL {
            let _ = parse(&s, level);
        }
    }

    #[test]
    fn sl_like_soup_reprints_stably(parts in prop::collection::vec(prop_oneof![
        Just("("), Just(")"), Just(" "), Just("action"), Just("not"), Just("and"), Just("?x"),
        Just("??m"), Just("iota"), Just("done"), Just(":name"), Just("\"q\\\" s\""), Just("12"),
        Just("-1.5e3"), Just("#2\"ab"), Just("set"), Just("B"), Just("p"), Just("|"),
        Just("20261122T014140823Z"),
    ], 0..40)) {
        let s: String = parts.concat();
        for level in Level::ALL {
            if let Ok(content) = parse(&s, level) {
                let again = parse(&content.to_string(), level);
                prop_assert_eq!(again, Ok(content), "{}", s);
            }
        }
    }
}

#[test]
fn errors_say_where_and_what() {
    let e = parse("((cfp-item :price (+ 10 5)))", Level::Full).unwrap_err();
    assert!(
        matches!(
            e,
            SlError::Syntax {
                line: 1,
                column: 12,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("expected a term"), "{e}");
    let e = parse("(\n  (forall ?x (p ?x)))", Level::Sl0).unwrap_err();
    assert!(
        matches!(
            e,
            SlError::NotAllowed {
                line: 2,
                column: 4,
                level: Level::Sl0,
                needs: Level::Sl1,
                ..
            }
        ),
        "{e}"
    );
    let e = parse("((p \"open", Level::Full).unwrap_err();
    assert!(matches!(e, SlError::Lexical { column: 5, .. }), "{e}");
    assert!(matches!(
        parse("", Level::Full),
        Err(SlError::Syntax { .. })
    ));
    assert!(matches!(
        parse("()", Level::Full),
        Err(SlError::Syntax { .. })
    ));
}

#[test]
fn deep_nesting_is_refused_not_overflowed() {
    let deep = format!("((p {}x{}))", "(f ".repeat(100_000), ")".repeat(100_000));
    assert!(matches!(
        parse(&deep, Level::Full),
        Err(SlError::TooDeep { .. })
    ));
    let ok = format!("((p {}x{}))", "(f ".repeat(50), ")".repeat(50));
    assert!(parse(&ok, Level::Full).is_ok());
}

#[test]
fn strings_that_sl_cannot_quote_become_byte_strings() {
    let c = Content::single(Formula::Atomic {
        predicate: "p".into(),
        args: vec![Term::string("a b\\")],
    });
    assert_eq!(c.to_string(), "((p #4\"a b\\))");
    let back = parse(&c.to_string(), Level::Sl0).unwrap();
    assert_eq!(back.to_string(), c.to_string());
}

/// Found by `cargo fuzz run parse_print`: a float literal beyond f64 parsed as infinity, which
/// prints as the string `"Infinity"` and read back as a different tree.
#[test]
fn a_float_beyond_f64_keeps_its_text_and_round_trips() {
    let content = parse("((p 4e444444444 -4e999 1e3))", Level::Full).unwrap();
    let printed = content.to_string();
    assert_eq!(parse(&printed, Level::Full).unwrap(), content, "{printed}");
    assert!(
        printed.contains("\"4e444444444\"")
            && printed.contains("\"-4e999\"")
            && printed.contains("1000"),
        "{printed}"
    );
}
