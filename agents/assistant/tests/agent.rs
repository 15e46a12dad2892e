//! The assistant alone on an in-process bus with a mock clock; a scripted cognitive agent.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_assistant::{AssistantAgent, AssistantConfig};
use iw_bus::Time;
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

type Mailbag = Arc<Mutex<Vec<AclMessage>>>;

/// How the cognitive stand-in answers a goal.
#[derive(Clone, Copy, PartialEq)]
enum Answer {
    /// Staff: never answers.
    Silent,
    /// AGREE, then INFORM done.
    Done,
    /// REFUSE with a reason, then (out of protocol) an INFORM done.
    RefuseThenStray,
}

/// Staff sends its queue at setup; the cognitive stand-in answers as told.
struct Peer {
    inbox: Mailbag,
    outbox: Vec<AclMessage>,
    answer: Answer,
}

impl Agent for Peer {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        for m in self.outbox.drain(..) {
            ctx.send(m).unwrap();
        }
    }
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if self.answer == Answer::RefuseThenStray {
            ctx.refuse(&message, "no route to the dining hall").unwrap();
        }
        if self.answer == Answer::Done {
            ctx.send(
                message
                    .create_reply()
                    .with_performative(Performative::Agree),
            )
            .unwrap();
        }
        if self.answer != Answer::Silent
            && let Ok(WheelchairContent::Request { actor, action }) =
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

/// A host with the assistant (chair1's cognitive agent answering as `answer`), the nurse
/// (staff) sending `nurse_goals` and a visitor sending `visitor_goals`, run for two steps.
fn run(
    answer: Answer,
    nurse_goals: Vec<AclMessage>,
    visitor_goals: Vec<AclMessage>,
) -> [Mailbag; 3] {
    let (mut host, controller) = AgentHost::on_a_mock_clock(Time::from_ns(1_000_000_000));
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
            answer,
        }),
    )
    .unwrap();
    host.add(
        AgentId::new("nurse"),
        Box::new(Peer {
            inbox: Arc::clone(&nurse),
            outbox: nurse_goals,
            answer: Answer::Silent,
        }),
    )
    .unwrap();
    host.add(
        AgentId::new("visitor"),
        Box::new(Peer {
            inbox: Arc::clone(&visitor),
            outbox: visitor_goals,
            answer: Answer::Silent,
        }),
    )
    .unwrap();
    host.step(controller.now());
    controller.advance(Duration::from_millis(10));
    host.step(controller.now());
    [cognitive, nurse, visitor]
}

fn seen(bag: &Mailbag) -> Vec<(String, Performative)> {
    bag.lock()
        .unwrap()
        .iter()
        .map(|m| (m.conversation_id.clone().unwrap(), m.performative))
        .collect()
}

#[test]
fn staff_goals_reach_the_chairs_cognitive_agent_and_outcomes_come_back() {
    let [cognitive, nurse, visitor] = run(
        Answer::Done,
        vec![goal("chair1", "n1"), goal("chair9", "n2")],
        vec![goal("chair1", "v1")],
    );
    let forwarded = cognitive.lock().unwrap();
    assert_eq!(
        forwarded.len(),
        1,
        "only the staff goal for a known chair is forwarded"
    );
    // In a conversation named after the assistant's start (1 s on the mock clock): an
    // answer to what an earlier life of it forwarded is not taken for this one's.
    assert_eq!(
        forwarded[0].conversation_id.as_deref(),
        Some("assistant-1000-1")
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

/// The assistant has agreed before it forwards, so fipa-request lets it relay a chair's REFUSE
/// only as a FAILURE (with the chair's reason); an answer after the end is not relayed.
#[test]
fn a_chairs_refusal_reaches_staff_as_a_failure_with_its_reason_and_stray_answers_are_dropped() {
    let [_, nurse, _] = run(Answer::RefuseThenStray, vec![goal("chair1", "n1")], vec![]);
    assert_eq!(
        seen(&nurse),
        [
            ("n1".into(), Performative::Agree),
            ("n1".into(), Performative::Failure)
        ]
    );
    let failure = nurse.lock().unwrap()[1].clone();
    assert_eq!(
        WheelchairContent::from_message(&failure).unwrap(),
        WheelchairContent::error("no route to the dining hall")
    );
}
