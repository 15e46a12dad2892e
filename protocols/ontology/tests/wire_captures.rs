//! FIPA-Agent-Management against JADE's wire captures (`fipa/wire/`): what we send decodes to
//! what we meant, and JADE's answers decode and re-encode to JADE's exact text.

use iw_acl::AgentId;
use iw_ontology::OntologyError;
use iw_ontology::fipa::{
    AgentDescription, AgentState, DfAgentDescription, FipaError, ManagementAction,
    ManagementContent, ManagementRequest, Property, SearchConstraints, ServiceDescription,
};
use iw_sl::{Level, Term};

/// The `:content` of an ACL string message (JADE escapes only `"`).
fn acl_content(test: &str, relative: &str) -> Option<(String, Level)> {
    let path = iw_testdata::require(test, relative)?;
    let raw = String::from_utf8_lossy(&std::fs::read(path).unwrap()).into_owned();
    let start = raw.find(":content").expect("message has :content") + ":content".len();
    let rest = raw[start..]
        .trim_start()
        .strip_prefix('"')
        .expect("quoted content");
    let mut content = String::new();
    let mut chars = rest.chars();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.clone().next() == Some('"') => {
                content.push('"');
                chars.next();
            }
            '"' => break,
            c => content.push(c),
        }
    }
    let level = if raw.contains(":language  fipa-sl0") || raw.contains(":language fipa-sl0") {
        Level::Sl0
    } else {
        Level::Full
    };
    Some((content, level))
}

fn df(name: &str) -> AgentId {
    AgentId::new(name)
}

fn search_for(service_type: &str) -> ManagementRequest {
    ManagementRequest {
        actor: df("df@WheelchairTest"),
        action: ManagementAction::Search {
            description: AgentDescription::Df(DfAgentDescription {
                services: vec![ServiceDescription {
                    service_type: Some(service_type.into()),
                    ..ServiceDescription::default()
                }],
                ..DfAgentDescription::default()
            }),
            constraints: SearchConstraints {
                max_results: Some(-1),
                ..SearchConstraints::default()
            },
        },
    }
}

fn wheelchair1_registration() -> DfAgentDescription {
    DfAgentDescription {
        name: Some(
            AgentId::new("wheelchair1@RustPlatform").with_address("http://127.0.0.1:9000/acc"),
        ),
        services: vec![ServiceDescription {
            name: Some("nav".into()),
            service_type: Some("wheelchair-navigation".into()),
            ownership: Some("RustPlatform".into()),
            properties: vec![Property {
                name: "max-speed".into(),
                value: Term::float(1.5),
            }],
            ..ServiceDescription::default()
        }],
        protocols: vec!["fipa-request".into()],
        languages: vec!["fipa-sl".into()],
        ..DfAgentDescription::default()
    }
}

/// Decodes `relative`'s content, checks it against `expected`, and checks the re-encoding:
/// byte-identical when `exact` (JADE's own text), same decoded value otherwise.
fn check(test: &str, relative: &str, expected: &ManagementContent, exact: bool) {
    let Some((text, level)) = acl_content(test, relative) else {
        return;
    };
    let decoded =
        ManagementContent::parse(&text, level).unwrap_or_else(|e| panic!("{relative}: {e}"));
    assert_eq!(&decoded, expected, "{relative}");
    let encoded = decoded.to_content().to_string();
    if exact {
        assert_eq!(
            encoded, text,
            "{relative}: re-encoding differs from JADE's text"
        );
    } else {
        assert_eq!(
            ManagementContent::parse(&encoded, level).unwrap(),
            decoded,
            "{relative}"
        );
        assert_eq!(
            iw_sl::parse(&encoded, level).unwrap(),
            expected.to_content()
        );
    }
    assert!(
        decoded.level() <= level,
        "{relative}: needs {}",
        decoded.level()
    );
}

#[test]
fn df_search_request_and_jade_result() {
    let request = search_for("wheelchair-echo");
    check(
        "df_search",
        "fipa/wire/acl/03-df-search.acl",
        &ManagementContent::Request(request.clone()),
        true,
    );
    let echo = DfAgentDescription {
        name: Some(AgentId::new("echo@WheelchairTest").with_address("http://127.0.0.1:7778/acc")),
        services: vec![ServiceDescription {
            name: Some("echo-service".into()),
            service_type: Some("wheelchair-echo".into()),
            ..ServiceDescription::default()
        }],
        ..DfAgentDescription::default()
    };
    let answer = ManagementContent::Result {
        request,
        descriptions: vec![AgentDescription::Df(echo)],
    };
    check(
        "df_search",
        "fipa/wire/from-jade/03-df-search-result-inform.raw",
        &answer,
        true,
    );
}

#[test]
fn ams_search_request_and_jade_result() {
    let Some((text, _)) = acl_content(
        "ams_search",
        "fipa/wire/from-jade/04-ams-search-result-inform.raw",
    ) else {
        return;
    };
    let decoded = ManagementContent::parse(&text, Level::Sl0).unwrap();
    let ManagementContent::Result {
        request,
        descriptions,
    } = &decoded
    else {
        panic!("{decoded:?}")
    };
    assert!(matches!(
        request.action,
        ManagementAction::Search {
            description: AgentDescription::Ams(_),
            ..
        }
    ));
    assert_eq!(descriptions.len(), 3);
    let AgentDescription::Ams(first) = &descriptions[0] else {
        panic!()
    };
    let name = first.name.as_ref().unwrap();
    assert_eq!(name.name, "df@WheelchairTest");
    assert_eq!(
        name.user_params
            .get("JADE-agent-classname")
            .map(String::as_str),
        Some("jade.domain.df")
    );
    assert_eq!(first.state, Some(AgentState::Active));
    assert_eq!(first.ownership.as_deref(), Some("NONE"));
    assert_eq!(
        decoded.to_content().to_string(),
        text,
        "re-encoding differs from JADE's text"
    );
    check(
        "ams_search",
        "fipa/wire/acl/04-ams-search.acl",
        &ManagementContent::Request(request.clone()),
        true,
    );
}

#[test]
fn unknown_receiver_failure_from_the_ams() {
    let Some((text, level)) = acl_content(
        "ams_failure",
        "fipa/wire/from-jade/05-ams-failure-unknown-receiver.raw",
    ) else {
        return;
    };
    let decoded = ManagementContent::parse(&text, level).unwrap();
    let ManagementContent::Failure { reason, .. } = &decoded else {
        panic!("{decoded:?}")
    };
    let FipaError::MtsError { receiver, reason } = reason else {
        panic!("{reason:?}")
    };
    assert_eq!(receiver.name, "nobody@WheelchairTest");
    assert_eq!(receiver.addresses, ["http://127.0.0.1:7778/acc"]);
    assert_eq!(
        **reason,
        FipaError::InternalError {
            message: "Agent not found: getContainerID() failed to find agent nobody@WheelchairTest"
                .into()
        }
    );
    // JADE's spacing is irregular: compare the trees.
    assert_eq!(decoded.to_content(), iw_sl::parse(&text, level).unwrap());
}

#[test]
fn df_register_request_and_jade_done() {
    let register = ManagementRequest {
        actor: df("df@WheelchairTest"),
        action: ManagementAction::Register {
            description: AgentDescription::Df(wheelchair1_registration()),
        },
    };
    // Our captured request lists the slots in another order and quotes a word: same value.
    check(
        "df_register",
        "fipa/wire/acl/06-df-register.acl",
        &ManagementContent::Request(register.clone()),
        false,
    );
    check(
        "df_register",
        "fipa/wire/from-jade/06-df-register-inform-done.raw",
        &ManagementContent::Done(register),
        true,
    );
}

#[test]
fn df_subscription_and_jade_notification() {
    let request = search_for("wheelchair-navigation");
    check(
        "df_subscribe",
        "fipa/wire/acl/07-df-subscribe.acl",
        &ManagementContent::Subscribe(request.clone()),
        true,
    );
    let notification = ManagementContent::Notification {
        request,
        descriptions: vec![AgentDescription::Df(wheelchair1_registration())],
    };
    check(
        "df_subscribe",
        "fipa/wire/from-jade/07-df-subscribe-notification-inform.raw",
        &notification,
        true,
    );
    assert_eq!(notification.level(), Level::Full);
}

#[test]
fn jade_error_predicates_decode() {
    let list = "(already-registered not-registered (internal-error \"Nothing was possibile\"))";
    let content = iw_sl::parse(list, Level::Sl0).unwrap();
    let errors: Vec<FipaError> = content
        .expressions
        .iter()
        .map(|e| match e {
            iw_sl::ContentExpression::Formula(f) => FipaError::from_formula(f).unwrap(),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(
        errors,
        [
            FipaError::AlreadyRegistered,
            FipaError::NotRegistered,
            FipaError::InternalError {
                message: "Nothing was possibile".into()
            }
        ]
    );
    let refuse =
        "((action (agent-identifier :name df@X) (register (df-agent-description))) unauthorised)";
    let decoded = ManagementContent::parse(refuse, Level::Sl0).unwrap();
    assert!(matches!(
        decoded,
        ManagementContent::Failure {
            reason: FipaError::Unauthorised,
            ..
        }
    ));
    assert_eq!(decoded.to_content().to_string(), refuse);
    let unsupported = ManagementContent::parse(
        "((action (agent-identifier :name df@X) (get-description)) (unsupported-function get-description))",
        Level::Sl0,
    )
    .unwrap();
    assert!(matches!(
        unsupported,
        ManagementContent::Failure {
            reason: FipaError::UnsupportedFunction { .. },
            ..
        }
    ));
}

#[test]
fn mistakes_are_reported_with_the_offending_part() {
    let e = ManagementContent::parse("((action (agent-identifier :name df@X) (fly)))", Level::Sl0)
        .unwrap_err();
    assert!(
        matches!(e, OntologyError::UnexpectedTerm { ref found, .. } if found == "(fly)"),
        "{e}"
    );
    let e = ManagementContent::parse(
        "((action (agent-identifier :addresses (sequence a)) (get-description)))",
        Level::Sl0,
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            OntologyError::MissingSlot {
                concept: "agent-identifier",
                slot: "name"
            }
        ),
        "{e}"
    );
    let e = ManagementContent::parse(
        "((action (agent-identifier :name ams@X) (modify (ams-agent-description :state flying))))",
        Level::Sl0,
    )
    .unwrap_err();
    assert!(
        matches!(e, OntologyError::BadValue { slot: "state", .. }),
        "{e}"
    );
    assert!(matches!(
        ManagementContent::parse("((p", Level::Sl0),
        Err(OntologyError::Sl(_))
    ));
}

#[test]
fn whole_acl_messages_carry_the_ontology() {
    use iw_acl::{AclMessage, Performative};
    use iw_ontology::OntologyContent;
    let Some(path) = iw_testdata::require("whole_acl_messages", "fipa/wire/acl/03-df-search.acl")
    else {
        return;
    };
    let message = iw_acl::codec::parse(&std::fs::read_to_string(path).unwrap()).unwrap();
    let content = ManagementContent::from_message(&message).unwrap();
    assert_eq!(
        content,
        ManagementContent::Request(search_for("wheelchair-echo"))
    );
    let ours = content.fill(AclMessage::new(Performative::Request));
    assert_eq!(ours.language.as_deref(), Some("fipa-sl0"));
    assert_eq!(ours.ontology.as_deref(), Some("FIPA-Agent-Management"));
    assert_eq!(ours.content_text(), message.content_text());
    let wrong = ours.clone().with_ontology("IntellWheels-Wheelchair");
    assert!(matches!(
        ManagementContent::from_message(&wrong),
        Err(OntologyError::WrongOntology { .. })
    ));
    let bytes = ours.with_byte_content(vec![1, 2]);
    assert!(matches!(
        ManagementContent::from_message(&bytes),
        Err(OntologyError::NoTextContent)
    ));
}
