//! The assistant alone on an in-process bus with a mock clock; a scripted cognitive agent.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_assistant::{AssistantAgent, AssistantConfig, GOAL_CHECK};
use iw_bus::{MockController, Time};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, GoalInFlight, WheelchairAction, WheelchairContent};

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

/// A host on a mock clock (at 1 s) with the assistant: chair1's cognitive agent is
/// `cognitive-chair1`, the nurse is staff.
fn with_assistant() -> (AgentHost, MockController) {
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
    (host, controller)
}

/// A host with the assistant (chair1's cognitive agent answering as `answer`), the nurse
/// (staff) sending `nurse_goals` and a visitor sending `visitor_goals`, run for two steps.
fn run(
    answer: Answer,
    nurse_goals: Vec<AclMessage>,
    visitor_goals: Vec<AclMessage>,
) -> [Mailbag; 3] {
    let (mut host, controller) = with_assistant();
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

/// A cognitive stand-in whose answers to the goal are lost: it AGREEs, then its INFORM or
/// FAILURE never reaches the assistant; asked for its goal, it tells what it knows.
struct Forgetful {
    /// The goal's outcome, as the chair keeps it (`None`: it has no record of the goal).
    record: Option<Result<(), String>>,
    /// Whether the goal is still under way when asked.
    under_way: bool,
    /// The forward's conversation, once the goal came.
    forward: Option<String>,
    queries: Mailbag,
}

impl Agent for Forgetful {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Request => {
                self.forward = message.conversation_id.clone();
                ctx.send(
                    message
                        .create_reply()
                        .with_performative(Performative::Agree),
                )
                .unwrap();
                // the INFORM or FAILURE it then sends is lost on the way
            }
            Performative::QueryRef => {
                let told = |outcome| {
                    Box::new(GoalInFlight {
                        place: "dining-hall".into(),
                        requester: AgentId::new("assistant"),
                        conversation: self.forward.clone().unwrap(),
                        outcome,
                    })
                };
                let (goal, ended) = if self.under_way {
                    (Some(told(None)), None)
                } else {
                    (None, self.record.clone().map(|r| told(Some(r))))
                };
                let answer = WheelchairContent::Inform(Fact::CurrentGoal {
                    agent: ctx.aid().clone(),
                    goal,
                    ended,
                });
                ctx.send(
                    answer.fill(
                        message
                            .create_reply()
                            .with_performative(Performative::Inform),
                    ),
                )
                .unwrap();
                self.queries.lock().unwrap().push(message);
            }
            _ => {}
        }
    }
}

/// The nurse's goal to a [`Forgetful`] chair, run `seconds` of the mock clock in 100 ms steps:
/// what the nurse got, and the queries the chair was asked.
fn lost_answer(record: Option<Result<(), String>>, under_way: bool, seconds: u64) -> [Mailbag; 2] {
    let (mut host, controller) = with_assistant();
    let (queries, nurse): (Mailbag, Mailbag) = Default::default();
    host.add(
        AgentId::new("cognitive-chair1"),
        Box::new(Forgetful {
            record,
            under_way,
            forward: None,
            queries: Arc::clone(&queries),
        }),
    )
    .unwrap();
    host.add(
        AgentId::new("nurse"),
        Box::new(Peer {
            inbox: Arc::clone(&nurse),
            outbox: vec![goal("chair1", "n1")],
            answer: Answer::Silent,
        }),
    )
    .unwrap();
    for _ in 0..seconds * 10 {
        host.step(controller.now());
        controller.advance(Duration::from_millis(100));
    }
    [nurse, queries]
}

/// The chair's INFORM (goal done) was lost on the way: the assistant asks the chair about the
/// goal once it went unanswered for GOAL_CHECK, and staff get the INFORM from its answer.
#[test]
fn a_goal_whose_done_was_lost_is_answered_to_staff_from_the_chairs_answer_to_a_query() {
    let check = GOAL_CHECK.as_secs();
    let [nurse, queries] = lost_answer(Some(Ok(())), false, check / 2);
    assert_eq!(seen(&nurse), [("n1".into(), Performative::Agree)]);
    assert!(queries.lock().unwrap().is_empty(), "not asked too early");

    let [nurse, queries] = lost_answer(Some(Ok(())), false, check * 2);
    assert_eq!(
        seen(&nurse),
        [
            ("n1".into(), Performative::Agree),
            ("n1".into(), Performative::Inform)
        ]
    );
    assert_eq!(queries.lock().unwrap().len(), 1, "asked once: answered");
    assert_eq!(
        WheelchairContent::from_message(&nurse.lock().unwrap()[1]).unwrap(),
        WheelchairContent::Done {
            actor: AgentId::new("cognitive-chair1"),
            action: WheelchairAction::GoTo {
                place: "dining-hall".into()
            }
        }
    );
}

/// A lost FAILURE reaches staff with the chair's reason; a goal the chair has no record of
/// ends in a FAILURE that says so; one still under way is left running and asked about again.
#[test]
fn a_lost_failure_or_a_goal_the_chair_forgot_ends_in_a_failure_and_one_under_way_runs_on() {
    let check = GOAL_CHECK.as_secs();
    let reason = |bag: &Mailbag| {
        WheelchairContent::from_message(&bag.lock().unwrap()[1])
            .unwrap()
            .reason()
            .unwrap()
            .to_string()
    };
    let [nurse, _] = lost_answer(Some(Err("blocked: no progress".into())), false, check * 2);
    assert_eq!(seen(&nurse)[1], ("n1".into(), Performative::Failure));
    assert_eq!(reason(&nurse), "blocked: no progress");

    let [nurse, _] = lost_answer(None, false, check * 2);
    assert_eq!(seen(&nurse)[1], ("n1".into(), Performative::Failure));
    let why = reason(&nurse);
    assert!(
        why.contains("cognitive-chair1 has no record of this goal") && why.contains("no goal"),
        "{why}"
    );

    let [nurse, queries] = lost_answer(None, true, check * 3 + 1);
    assert_eq!(seen(&nurse), [("n1".into(), Performative::Agree)]);
    assert!(
        queries.lock().unwrap().len() >= 2,
        "asked again while it runs"
    );
}
