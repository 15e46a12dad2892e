//! FIPA-Agent-Management values survive value -> SL text -> value at the level they need.

use iw_acl::AgentId;
use iw_ontology::fipa::{
    AgentDescription, AgentState, AmsAgentDescription, DfAgentDescription, FipaError,
    ManagementAction, ManagementContent, ManagementRequest, Property, SearchConstraints,
    ServiceDescription,
};
use iw_sl::{ActionExpression, Term};
use proptest::prelude::*;

fn word() -> impl Strategy<Value = String> {
    prop_oneof!["[a-z][a-z0-9.-]{0,10}", "[ -~]{1,10}[ -\\[\\]-~]"]
}

fn agent() -> impl Strategy<Value = AgentId> {
    (
        "[a-z][a-z0-9]{0,6}@[A-Z][a-zA-Z]{0,6}",
        prop::collection::vec("http://[a-z0-9.:]{1,12}/acc", 0..3),
        // A second letter keeps `X-` + key from collapsing to `X-X-` (an empty key).
        prop::option::of(("[A-Z][a-z][a-z-]{0,7}", word())),
    )
        .prop_map(|(n, addrs, user)| {
            let aid = addrs
                .into_iter()
                .fold(AgentId::new(n), AgentId::with_address);
            match user {
                Some((k, v)) => aid.with_user_param(&format!("X-{k}"), v),
                None => aid,
            }
        })
}

fn service() -> impl Strategy<Value = ServiceDescription> {
    (
        prop::option::of(word()),
        prop::option::of(word()),
        prop::collection::vec(word(), 0..3),
        prop::option::of(word()),
        prop::collection::vec((word(), -1e3..1e3f64), 0..3),
    )
        .prop_map(
            |(name, service_type, protocols, ownership, props)| ServiceDescription {
                name,
                service_type,
                protocols,
                ownership,
                properties: props
                    .into_iter()
                    .map(|(name, v)| Property {
                        name,
                        value: Term::float(v),
                    })
                    .collect(),
                ..ServiceDescription::default()
            },
        )
}

fn description() -> impl Strategy<Value = AgentDescription> {
    prop_oneof![
        (
            prop::option::of(agent()),
            prop::collection::vec(service(), 0..3),
            prop::collection::vec(word(), 0..3)
        )
            .prop_map(|(name, services, languages)| AgentDescription::Df(
                DfAgentDescription {
                    name,
                    services,
                    languages,
                    ..DfAgentDescription::default()
                }
            )),
        (
            prop::option::of(agent()),
            prop::option::of(word()),
            prop::option::of(prop_oneof![
                Just(AgentState::Active),
                Just(AgentState::Suspended)
            ])
        )
            .prop_map(|(name, ownership, state)| AgentDescription::Ams(
                AmsAgentDescription {
                    name,
                    ownership,
                    state
                }
            )),
    ]
}

fn request() -> impl Strategy<Value = ManagementRequest> {
    let action = prop_oneof![
        description().prop_map(|description| ManagementAction::Register { description }),
        description().prop_map(|description| ManagementAction::Deregister { description }),
        description().prop_map(|description| ManagementAction::Modify { description }),
        (
            description(),
            prop::option::of(-1i64..100),
            prop::option::of(0i64..5)
        )
            .prop_map(|(description, r, d)| {
                ManagementAction::Search {
                    description,
                    constraints: SearchConstraints {
                        max_results: r,
                        max_depth: d,
                        search_id: None,
                    },
                }
            }),
        Just(ManagementAction::GetDescription),
    ];
    (agent(), action).prop_map(|(actor, action)| ManagementRequest { actor, action })
}

fn content() -> impl Strategy<Value = ManagementContent> {
    prop_oneof![
        request().prop_map(ManagementContent::Request),
        request().prop_map(ManagementContent::Done),
        request().prop_map(ManagementContent::Subscribe),
        (request(), prop::collection::vec(description(), 0..3)).prop_map(
            |(request, descriptions)| ManagementContent::Result {
                request,
                descriptions
            }
        ),
        (request(), prop::collection::vec(description(), 0..3)).prop_map(
            |(request, descriptions)| ManagementContent::Notification {
                request,
                descriptions
            }
        ),
        (request(), agent(), word()).prop_map(|(r, receiver, message)| {
            ManagementContent::Failure {
                action: r.to_action(),
                reason: FipaError::MtsError {
                    receiver,
                    reason: Box::new(FipaError::InternalError { message }),
                },
            }
        }),
        (request(), word(), word()).prop_map(|(r, object, parameter)| ManagementContent::Failure {
            action: r.to_action(),
            reason: FipaError::MissingParameter { object, parameter },
        }),
        request().prop_map(|r| ManagementContent::Failure {
            action: r.to_action(),
            reason: FipaError::NotRegistered
        }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn management_content_round_trips(msg in content()) {
        let text = msg.to_content().to_string();
        prop_assert_eq!(ManagementContent::parse(&text, msg.level()), Ok(msg), "{}", text);
    }
}

#[test]
fn failure_keeps_actions_outside_the_ontology() {
    let text = "((action (agent-identifier :name a@P) (ACLMessage)) (internal-error \"boom\"))";
    let msg = ManagementContent::parse(text, iw_sl::Level::Sl0).unwrap();
    let ManagementContent::Failure {
        action: ActionExpression::Action { act, .. },
        ..
    } = &msg
    else {
        panic!("{msg:?}")
    };
    assert_eq!(act.to_string(), "(ACLMessage)");
    // Printed canonically: the quotes around a plain word go.
    assert_eq!(
        msg.to_content().to_string(),
        text.replace("\"boom\"", "boom")
    );
}

#[test]
fn nameless_user_slot_is_refused_not_dropped() {
    let text =
        "((done (action (agent-identifier :name a@A :X- a) (register (df-agent-description)))))";
    let err = ManagementContent::parse(text, iw_sl::Level::Sl0).unwrap_err();
    assert!(err.to_string().contains("needs a name after `X-`"), "{err}");
}
