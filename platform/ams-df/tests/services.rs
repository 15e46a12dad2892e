//! The AMS and DF driven with real ACL messages on an in-process bus, their answers compared
//! with JADE's in the wire captures (`fipa/wire/`) where a capture exists.

use std::sync::Arc;

use iw_acl::codec::{ParseOptions, parse_with, print};
use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_ams_df::{Ams, Df, WhitePages};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Mailbox, MockController, Stack, Time};
use iw_ontology::OntologyContent;
use iw_ontology::fipa::{
    AgentDescription, AgentState, AmsAgentDescription, DfAgentDescription, FipaError,
    ManagementAction, ManagementContent, ManagementRequest, SearchConstraints, ServiceDescription,
};

const AMS: &str = "ams@WheelchairTest";
const DF: &str = "df@WheelchairTest";
const ME: &str = "wheelchair1@RustPlatform";

/// Does nothing: stands for JADE's echo agent in the AMS's list.
struct Idle;
impl Agent for Idle {
    fn handle(&mut self, _ctx: &mut Context<'_>, _message: AclMessage) {}
}

struct Platform {
    host: AgentHost,
    clock: MockController,
    pages: WhitePages,
}

impl Platform {
    fn new() -> Self {
        let network = InProcNetwork::new();
        let (clock, controller) = Clock::mock(Time::from_ns(1_000_000_000));
        let transport = Arc::new(network.endpoint("main").unwrap());
        let bus = Bus::start(Stack::new(), transport, clock, BusConfig::default()).unwrap();
        let mut host = AgentHost::new(Arc::new(bus));
        let pages = WhitePages::new();
        pages
            .host(
                &mut host,
                AgentId::new(AMS),
                Box::new(Ams::new(pages.clone())),
            )
            .unwrap();
        pages
            .host(&mut host, AgentId::new(DF), Box::new(Df::new()))
            .unwrap();
        pages
            .host(
                &mut host,
                AgentId::new("echo@WheelchairTest"),
                Box::new(Idle),
            )
            .unwrap();
        Self {
            host,
            clock: controller,
            pages,
        }
    }

    /// A mailbox standing for an agent that talks to the services.
    fn client(&self, name: &str) -> Mailbox {
        self.host.bus().register(name).unwrap()
    }

    /// Sends `message` from its sender to its first receiver and runs the platform once.
    fn send(&mut self, message: &AclMessage) {
        let from = &message.sender.as_ref().unwrap().name;
        self.host
            .bus()
            .send(
                from,
                &message.receivers[0].name,
                print(message).into_bytes(),
            )
            .unwrap();
        self.host.step(self.clock.now());
    }
}

fn next(mailbox: &mut Mailbox) -> Option<AclMessage> {
    mailbox
        .try_recv()
        .map(|e| iw_acl::codec::parse(e.payload_str().unwrap()).unwrap())
}

fn content(message: &AclMessage) -> ManagementContent {
    ManagementContent::from_message(message).unwrap_or_else(|e| panic!("{e}: {message:?}"))
}

/// The ACL payload of a captured post (the last multipart part), or of a bare `.acl` file.
fn captured(test: &str, relative: &str) -> Option<AclMessage> {
    let path = iw_testdata::require(test, relative)?;
    let raw = String::from_utf8(std::fs::read(path).unwrap()).unwrap();
    let acl = match raw.find("Content-Type: application/text\r\n\r\n") {
        Some(start) => {
            let body = &raw[start + 34..];
            &body[..body.find("\r\n--").unwrap()]
        }
        None => raw.as_str(),
    };
    Some(parse_with(acl, &ParseOptions::jade()).unwrap())
}

fn request(sender: &str, receiver: &str, content: &ManagementContent) -> AclMessage {
    let message = AclMessage::new(Performative::Request)
        .with_sender(AgentId::new(sender))
        .with_receiver(AgentId::new(receiver))
        .with_protocol("fipa-request")
        .with_conversation_id(format!("c-{sender}"))
        .with_reply_with("r1");
    content.fill(message)
}

fn df_action(action: ManagementAction) -> ManagementContent {
    ManagementContent::Request(ManagementRequest {
        actor: AgentId::new(DF),
        action,
    })
}

fn registration(name: &str, service_type: &str) -> DfAgentDescription {
    DfAgentDescription {
        name: Some(AgentId::new(name)),
        services: vec![ServiceDescription {
            service_type: Some(service_type.into()),
            ..ServiceDescription::default()
        }],
        ..DfAgentDescription::default()
    }
}

fn reason(message: &AclMessage) -> FipaError {
    match content(message) {
        ManagementContent::Failure { reason, .. } => reason,
        other => panic!("{other:?}"),
    }
}

#[test]
fn df_register_and_search_answer_like_jade() {
    let Some(register) = captured("df_register", "fipa/wire/acl/06-df-register.acl") else {
        return;
    };
    let Some(jade_done) = captured(
        "df_register",
        "fipa/wire/from-jade/06-df-register-inform-done.raw",
    ) else {
        return;
    };
    let mut platform = Platform::new();
    let mut me = platform.client(ME);
    platform.send(&register);
    let done = next(&mut me).expect("the DF answers");
    assert_eq!(done.performative, Performative::Inform);
    assert_eq!(
        done.content_text(),
        jade_done.content_text(),
        "same text as JADE's DF"
    );
    for (ours, jade) in [
        (&done.language, &jade_done.language),
        (&done.ontology, &jade_done.ontology),
        (&done.protocol, &jade_done.protocol),
        (&done.in_reply_to, &jade_done.in_reply_to),
        (&done.conversation_id, &jade_done.conversation_id),
    ] {
        assert_eq!(ours, jade);
    }
    assert_eq!(done.sender.unwrap().name, DF);

    platform.send(&register);
    let again = next(&mut me).unwrap();
    assert_eq!(
        (again.performative, reason(&again)),
        (Performative::Failure, FipaError::AlreadyRegistered)
    );

    // JADE's echo registered itself with its address; the captured search then finds it.
    let Some(search) = captured("df_search", "fipa/wire/acl/03-df-search.acl") else {
        return;
    };
    let Some(jade_result) = captured(
        "df_search",
        "fipa/wire/from-jade/03-df-search-result-inform.raw",
    ) else {
        return;
    };
    let mut echo = platform.client("echo-client@WheelchairTest");
    let echo_entry = DfAgentDescription {
        name: Some(AgentId::new("echo-client@WheelchairTest")),
        services: vec![ServiceDescription {
            name: Some("echo-service".into()),
            service_type: Some("wheelchair-echo".into()),
            ..ServiceDescription::default()
        }],
        ..DfAgentDescription::default()
    };
    platform.send(&request(
        "echo-client@WheelchairTest",
        DF,
        &df_action(ManagementAction::Register {
            description: AgentDescription::Df(echo_entry),
        }),
    ));
    assert_eq!(next(&mut echo).unwrap().performative, Performative::Inform);
    platform.send(&search);
    let result = next(&mut me).unwrap();
    assert_eq!(result.performative, Performative::Inform);
    let jade_text = jade_result.content_text().unwrap().replace(
        "(agent-identifier :name echo@WheelchairTest :addresses (sequence http://127.0.0.1:7778/acc))",
        "(agent-identifier :name echo-client@WheelchairTest)",
    );
    assert_eq!(result.content_text().unwrap(), jade_text);
}

#[test]
fn df_constraints_authorisation_modify_and_deregister() {
    let mut platform = Platform::new();
    let mut clients: Vec<Mailbox> = (0..3)
        .map(|i| platform.client(&format!("a{i}@P")))
        .collect();
    for (i, client) in clients.iter_mut().enumerate() {
        let name = format!("a{i}@P");
        let register = ManagementAction::Register {
            description: AgentDescription::Df(registration(&name, "nav")),
        };
        platform.send(&request(&name, DF, &df_action(register)));
        assert_eq!(next(client).unwrap().performative, Performative::Inform);
    }
    let search = |max_results, service_type: &str| {
        df_action(ManagementAction::Search {
            description: AgentDescription::Df(DfAgentDescription {
                services: vec![ServiceDescription {
                    service_type: Some(service_type.into()),
                    ..ServiceDescription::default()
                }],
                ..DfAgentDescription::default()
            }),
            constraints: SearchConstraints {
                max_results,
                ..SearchConstraints::default()
            },
        })
    };
    let found =
        |platform: &mut Platform, clients: &mut [Mailbox], content: ManagementContent| -> usize {
            platform.send(&request("a0@P", DF, &content));
            match self::content(&next(&mut clients[0]).unwrap()) {
                ManagementContent::Result { descriptions, .. } => descriptions.len(),
                other => panic!("{other:?}"),
            }
        };
    assert_eq!(
        found(&mut platform, &mut clients, search(Some(-1), "nav")),
        3
    );
    assert_eq!(
        found(&mut platform, &mut clients, search(Some(2), "nav")),
        2
    );
    assert_eq!(found(&mut platform, &mut clients, search(None, "map")), 0);

    // a0 may not deregister a1; a1 may modify and deregister itself, once.
    let deregister_a1 = df_action(ManagementAction::Deregister {
        description: AgentDescription::Df(registration("a1@P", "nav")),
    });
    platform.send(&request("a0@P", DF, &deregister_a1));
    let refused = next(&mut clients[0]).unwrap();
    assert_eq!(
        (refused.performative, reason(&refused)),
        (Performative::Refuse, FipaError::Unauthorised)
    );
    let modify = df_action(ManagementAction::Modify {
        description: AgentDescription::Df(registration("a1@P", "map")),
    });
    platform.send(&request("a1@P", DF, &modify));
    assert_eq!(
        next(&mut clients[1]).unwrap().performative,
        Performative::Inform
    );
    assert_eq!(found(&mut platform, &mut clients, search(None, "map")), 1);
    platform.send(&request("a1@P", DF, &deregister_a1));
    assert_eq!(
        next(&mut clients[1]).unwrap().performative,
        Performative::Inform
    );
    platform.send(&request("a1@P", DF, &deregister_a1));
    let twice = next(&mut clients[1]).unwrap();
    assert_eq!(
        (twice.performative, reason(&twice)),
        (Performative::Failure, FipaError::NotRegistered)
    );
    platform.send(&request("a1@P", DF, &modify));
    assert_eq!(
        reason(&next(&mut clients[1]).unwrap()),
        FipaError::NotRegistered
    );
    assert_eq!(found(&mut platform, &mut clients, search(None, "map")), 0);

    // A description without a name, an AMS description, get-description: refused.
    let nameless = DfAgentDescription {
        name: None,
        ..registration("x", "nav")
    };
    for action in [
        ManagementAction::Register {
            description: AgentDescription::Df(nameless),
        },
        ManagementAction::Register {
            description: AgentDescription::Ams(AmsAgentDescription::default()),
        },
        ManagementAction::GetDescription,
    ] {
        platform.send(&request("a2@P", DF, &df_action(action)));
        let answer = next(&mut clients[2]).unwrap();
        assert_eq!(answer.performative, Performative::Refuse, "{answer:?}");
        assert!(matches!(
            reason(&answer),
            FipaError::MissingParameter { .. }
                | FipaError::UnexpectedArgument { .. }
                | FipaError::UnsupportedFunction { .. }
        ));
    }
}

#[test]
fn df_subscription_notifies_like_jade_until_cancelled() {
    let Some(subscribe) = captured("df_subscribe", "fipa/wire/acl/07-df-subscribe.acl") else {
        return;
    };
    let Some(register) = captured("df_subscribe", "fipa/wire/acl/06-df-register.acl") else {
        return;
    };
    let Some(jade_note) = captured(
        "df_subscribe",
        "fipa/wire/from-jade/07-df-subscribe-notification-inform.raw",
    ) else {
        return;
    };
    let mut platform = Platform::new();
    let mut me = platform.client(ME);
    platform.send(&subscribe);
    assert!(
        next(&mut me).is_none(),
        "nothing matches yet, so nothing is said (as JADE's DF)"
    );
    platform.send(&register);
    assert_eq!(
        next(&mut me).unwrap().performative,
        Performative::Inform,
        "done"
    );
    let note = next(&mut me).expect("a notification");
    assert_eq!(
        note.content_text(),
        jade_note.content_text(),
        "same text as JADE's notification"
    );
    assert_eq!(
        (
            &note.language,
            &note.protocol,
            &note.in_reply_to,
            &note.conversation_id
        ),
        (
            &jade_note.language,
            &jade_note.protocol,
            &jade_note.in_reply_to,
            &jade_note.conversation_id
        )
    );

    // A second subscriber hears of the existing match at once; another service type is silent.
    let mut other = platform.client("other@P");
    let mut late = subscribe.clone();
    late.sender = Some(AgentId::new("other@P"));
    platform.send(&late);
    assert!(
        matches!(content(&next(&mut other).unwrap()), ManagementContent::Notification { descriptions, .. } if descriptions.len() == 1)
    );
    let unrelated = ManagementAction::Register {
        description: AgentDescription::Df(registration("other@P", "coffee")),
    };
    platform.send(&request("other@P", DF, &df_action(unrelated)));
    assert_eq!(
        next(&mut other).unwrap().performative,
        Performative::Inform,
        "done"
    );
    assert!(next(&mut other).is_none() && next(&mut me).is_none());

    // Deregistration is announced by the bare name; after CANCEL nothing more comes.
    let deregister = df_action(ManagementAction::Deregister {
        description: AgentDescription::Df(registration(ME, "x")),
    });
    platform.send(&request(ME, DF, &deregister));
    assert_eq!(
        next(&mut me).unwrap().performative,
        Performative::Inform,
        "done"
    );
    let gone = next(&mut me).unwrap();
    match content(&gone) {
        ManagementContent::Notification { descriptions, .. } => {
            assert_eq!(
                descriptions,
                [AgentDescription::Df(DfAgentDescription {
                    name: Some(AgentId::new(ME).with_address("http://127.0.0.1:9000/acc")),
                    ..DfAgentDescription::default()
                })]
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(
        next(&mut other).is_some(),
        "the other subscriber hears it too"
    );
    let cancel = AclMessage::new(Performative::Cancel)
        .with_sender(AgentId::new(ME))
        .with_receiver(AgentId::new(DF))
        .with_conversation_id(subscribe.conversation_id.clone().unwrap())
        .with_content(subscribe.content_text().unwrap());
    platform.send(&cancel);
    platform.send(&register);
    assert_eq!(
        next(&mut me).unwrap().performative,
        Performative::Inform,
        "done"
    );
    assert!(next(&mut me).is_none(), "cancelled: no notification");
    assert!(next(&mut other).is_some(), "still subscribed");
}

fn ams_action(action: ManagementAction) -> ManagementContent {
    ManagementContent::Request(ManagementRequest {
        actor: AgentId::new(AMS),
        action,
    })
}

fn ams_description(name: Option<&str>, state: Option<AgentState>) -> AgentDescription {
    AgentDescription::Ams(AmsAgentDescription {
        name: name.map(AgentId::new),
        ownership: None,
        state,
    })
}

#[test]
fn ams_lists_hosted_agents_and_manages_registrations() {
    let Some(search) = captured("ams_search", "fipa/wire/acl/04-ams-search.acl") else {
        return;
    };
    let mut platform = Platform::new();
    let mut me = platform.client(ME);
    platform.send(&search);
    let result = next(&mut me).unwrap();
    assert_eq!(
        (result.performative, result.language.as_deref()),
        (Performative::Inform, Some("fipa-sl0"))
    );
    let ManagementContent::Result { descriptions, .. } = content(&result) else {
        panic!("{result:?}")
    };
    let names: Vec<String> = descriptions
        .iter()
        .map(|d| match d {
            AgentDescription::Ams(a) => {
                assert_eq!(a.state, Some(AgentState::Active));
                a.name.as_ref().unwrap().name.clone()
            }
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(
        names,
        [AMS, DF, "echo@WheelchairTest"],
        "JADE's platform lists the same three"
    );

    let register = ams_action(ManagementAction::Register {
        description: ams_description(Some(ME), None),
    });
    platform.send(&request(ME, AMS, &register));
    assert_eq!(next(&mut me).unwrap().performative, Performative::Inform);
    assert_eq!(
        platform.pages.get(ME).unwrap().state,
        Some(AgentState::Active)
    );
    platform.send(&request(ME, AMS, &register));
    assert_eq!(
        reason(&next(&mut me).unwrap()),
        FipaError::AlreadyRegistered
    );
    let suspend = ams_action(ManagementAction::Modify {
        description: ams_description(Some(ME), Some(AgentState::Suspended)),
    });
    platform.send(&request(ME, AMS, &suspend));
    assert_eq!(next(&mut me).unwrap().performative, Performative::Inform);
    let suspended = ams_action(ManagementAction::Search {
        description: ams_description(None, Some(AgentState::Suspended)),
        constraints: SearchConstraints::default(),
    });
    platform.send(&request(ME, AMS, &suspended));
    let ManagementContent::Result { descriptions, .. } = content(&next(&mut me).unwrap()) else {
        panic!()
    };
    assert_eq!(descriptions.len(), 1);

    // Acting on another agent's entry is refused; unknown entries are not registered.
    let evict_df = ams_action(ManagementAction::Deregister {
        description: ams_description(Some(DF), None),
    });
    platform.send(&request(ME, AMS, &evict_df));
    let refused = next(&mut me).unwrap();
    assert_eq!(
        (refused.performative, reason(&refused)),
        (Performative::Refuse, FipaError::Unauthorised)
    );
    let leave = ams_action(ManagementAction::Deregister {
        description: ams_description(Some(ME), None),
    });
    platform.send(&request(ME, AMS, &leave));
    assert_eq!(next(&mut me).unwrap().performative, Performative::Inform);
    platform.send(&request(ME, AMS, &leave));
    let failed = next(&mut me).unwrap();
    assert_eq!(
        (failed.performative, reason(&failed)),
        (Performative::Failure, FipaError::NotRegistered)
    );
    assert_eq!(platform.pages.len(), 3);
}

#[test]
fn services_do_not_understand_other_acts_ontologies_or_content() {
    let mut platform = Platform::new();
    let mut me = platform.client(ME);
    let base = AclMessage::new(Performative::QueryRef)
        .with_sender(AgentId::new(ME))
        .with_content("((iota ?x (p ?x)))");
    for (receiver, message, expected) in [
        (AMS, base.clone(), "(unsupported-act query-ref)"),
        (
            DF,
            base.clone().with_performative(Performative::Propose),
            "(unsupported-act propose)",
        ),
        (
            AMS,
            base.clone()
                .with_performative(Performative::Request)
                .with_ontology("other"),
            "(unrecognised-value ontology)",
        ),
        (
            DF,
            base.clone()
                .with_performative(Performative::Request)
                .with_language("klingon"),
            "(unrecognised-value language)",
        ),
        (
            DF,
            base.clone()
                .with_performative(Performative::Request)
                .with_content("((( not sl"),
            "(unrecognised-value content)",
        ),
        (
            DF,
            base.clone().with_performative(Performative::Subscribe),
            "(unrecognised-value content)",
        ),
    ] {
        platform.send(&message.with_receiver(AgentId::new(receiver)));
        let answer = next(&mut me).unwrap();
        assert_eq!(answer.performative, Performative::NotUnderstood);
        assert_eq!(answer.content_text().unwrap(), format!("({expected})"));
    }
    // Answers are never answered.
    for p in [
        Performative::Inform,
        Performative::Failure,
        Performative::NotUnderstood,
    ] {
        platform.send(
            &base
                .clone()
                .with_performative(p)
                .with_receiver(AgentId::new(DF)),
        );
        assert!(next(&mut me).is_none());
    }
}
