//! The assistant alone on an in-process bus with a mock clock; a scripted cognitive agent.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_assistant::{AssistantAgent, AssistantConfig};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Stack, Time};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

type Mailbag = Arc<Mutex<Vec<AclMessage>>>;

/// Staff sends its queue at setup; the cognitive stand-in agrees and reports done.
struct Peer {
    inbox: Mailbag,
    outbox: Vec<AclMessage>,
    answer: bool,
}

impl Agent for Peer {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        for m in self.outbox.drain(..) {
            ctx.send(m).unwrap();
        }
    }
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if self.answer {
            ctx.send(
                message
                    .create_reply()
                    .with_performative(Performative::Agree),
            )
            .unwrap();
            if let Ok(WheelchairContent::Request { actor, action }) =
                WheelchairContent::from_message(&message)
            {
                ctx.send(
                    WheelchairContent::Done { actor, action }.fill(
                        message
                            .create_reply()
                            .with_performative(Performative::Inform),
                    ),
                )
                .unwrap();
            }
        }
        self.inbox.lock().unwrap().push(message);
    }
}

fn goal(chair: &str, conversation: &str) -> AclMessage {
    WheelchairContent::Request {
        actor: AgentId::new(chair),
        action: WheelchairAction::GoTo {
            place: "dining-hall".into(),
        },
    }
    .fill(
        AclMessage::new(Performative::Request)
            .with_receiver(AgentId::new("assistant"))
            .with_conversation_id(conversation),
    )
}

#[test]
fn staff_goals_reach_the_chairs_cognitive_agent_and_outcomes_come_back() {
    let network = InProcNetwork::new();
    let (clock, controller) = Clock::mock(Time::from_ns(1_000_000_000));
    let bus = Bus::start(
        Stack::new(),
        Arc::new(network.endpoint("c1").unwrap()),
        clock,
        BusConfig::default(),
    )
    .unwrap();
    let mut host = AgentHost::new(Arc::new(bus));
    let config = AssistantConfig {
        chairs: [("chair1".to_string(), AgentId::new("cognitive-chair1"))].into(),
        staff: ["nurse".to_string()].into(),
    };
    host.add(
        AgentId::new("assistant"),
        Box::new(AssistantAgent::new(config)),
    )
    .unwrap();
    let (cognitive, nurse, visitor): (Mailbag, Mailbag, Mailbag) = Default::default();
    host.add(
        AgentId::new("cognitive-chair1"),
        Box::new(Peer {
            inbox: Arc::clone(&cognitive),
            outbox: vec![],
            answer: true,
        }),
    )
    .unwrap();
    host.add(
        AgentId::new("nurse"),
        Box::new(Peer {
            inbox: Arc::clone(&nurse),
            outbox: vec![goal("chair1", "n1"), goal("chair9", "n2")],
            answer: false,
        }),
    )
    .unwrap();
    host.add(
        AgentId::new("visitor"),
        Box::new(Peer {
            inbox: Arc::clone(&visitor),
            outbox: vec![goal("chair1", "v1")],
            answer: false,
        }),
    )
    .unwrap();
    host.step(controller.now());
    controller.advance(Duration::from_millis(10));
    host.step(controller.now());

    let forwarded = cognitive.lock().unwrap();
    assert_eq!(
        forwarded.len(),
        1,
        "only the staff goal for a known chair is forwarded"
    );
    assert_eq!(
        WheelchairContent::from_message(&forwarded[0]).unwrap(),
        WheelchairContent::Request {
            actor: AgentId::new("cognitive-chair1"),
            action: WheelchairAction::GoTo {
                place: "dining-hall".into()
            }
        }
    );
    let seen = |bag: &Mailbag| -> Vec<(String, Performative)> {
        bag.lock()
            .unwrap()
            .iter()
            .map(|m| (m.conversation_id.clone().unwrap(), m.performative))
            .collect()
    };
    assert_eq!(
        seen(&nurse),
        [
            ("n1".into(), Performative::Agree),
            ("n2".into(), Performative::Refuse),
            ("n1".into(), Performative::Inform)
        ]
    );
    assert_eq!(seen(&visitor), [("v1".into(), Performative::Refuse)]);
}
