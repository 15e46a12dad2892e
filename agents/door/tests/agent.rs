//! The door agent alone on an in-process bus with a mock clock.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_bus::Time;
use iw_door::{ActuatorFault, DoorActuator, DoorAgent, DoorConfig, DoorPolicy, RefusalLog};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{DoorState, Fact, WheelchairAction, WheelchairContent};

type Moves = Arc<Mutex<Vec<(String, bool)>>>;

/// Records moves; `jammed` never moves.
struct World(Moves);
impl DoorActuator for World {
    fn set(&mut self, door: &str, open: bool) -> Result<(), ActuatorFault> {
        if door == "jammed" {
            return Err(ActuatorFault::new(door, "jammed"));
        }
        self.0.lock().unwrap().push((door.into(), open));
        Ok(())
    }
}

/// A chair's agent: sends its queued requests, keeps the answers.
struct Chair {
    inbox: Arc<Mutex<Vec<AclMessage>>>,
    outbox: Vec<AclMessage>,
}
impl Agent for Chair {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        for m in self.outbox.drain(..) {
            ctx.send(m).unwrap();
        }
    }
    fn handle(&mut self, _ctx: &mut Context<'_>, message: AclMessage) {
        self.inbox.lock().unwrap().push(message);
    }
}

fn request(action: WheelchairAction, conversation: &str) -> AclMessage {
    WheelchairContent::Request {
        actor: AgentId::new("door"),
        action,
    }
    .fill(
        AclMessage::new(Performative::Request)
            .with_receiver(AgentId::new("door"))
            .with_protocol("fipa-request")
            .with_conversation_id(conversation),
    )
}

#[test]
fn restricted_doors_open_only_for_authorised_chairs_and_refusals_are_logged() {
    let (mut host, controller) = AgentHost::on_a_mock_clock(Time::from_ns(1_000_000_000));
    let mut doors = BTreeMap::new();
    doors.insert(
        "lab".to_string(),
        DoorPolicy {
            restricted: true,
            authorised: ["cognitive-chair1".to_string()].into(),
        },
    );
    doors.insert("hall".to_string(), DoorPolicy::default());
    doors.insert("jammed".to_string(), DoorPolicy::default());
    let moves: Moves = Arc::default();
    let refusals: RefusalLog = Arc::default();
    host.add(
        AgentId::new("door"),
        Box::new(DoorAgent::new(
            DoorConfig { doors },
            Box::new(World(Arc::clone(&moves))),
            Arc::clone(&refusals),
        )),
    )
    .unwrap();
    let open = |d: &str| WheelchairAction::OpenDoor { door: d.into() };
    let chair1: Arc<Mutex<Vec<AclMessage>>> = Arc::default();
    let chair2: Arc<Mutex<Vec<AclMessage>>> = Arc::default();
    let query = AclMessage::new(Performative::QueryRef)
        .with_receiver(AgentId::new("door"))
        .with_conversation_id("q")
        .with_content("((door-state lab ?state))");
    host.add(
        AgentId::new("cognitive-chair1"),
        Box::new(Chair {
            inbox: Arc::clone(&chair1),
            outbox: vec![
                request(open("lab"), "a"),
                request(open("jammed"), "b"),
                query,
            ],
        }),
    )
    .unwrap();
    host.add(
        AgentId::new("cognitive-chair2"),
        Box::new(Chair {
            inbox: Arc::clone(&chair2),
            outbox: vec![
                request(open("lab"), "c"),
                request(open("hall"), "d"),
                request(open("vault"), "e"),
            ],
        }),
    )
    .unwrap();
    host.step(controller.now());
    controller.advance(Duration::from_millis(10));
    host.step(controller.now());

    let answers = |inbox: &Arc<Mutex<Vec<AclMessage>>>| -> Vec<(String, Performative)> {
        inbox
            .lock()
            .unwrap()
            .iter()
            .map(|m| (m.conversation_id.clone().unwrap(), m.performative))
            .collect()
    };
    use Performative::*;
    assert_eq!(
        answers(&chair1),
        [
            ("a".into(), Agree),
            ("a".into(), Inform),
            ("b".into(), Agree),
            ("b".into(), Failure),
            ("q".into(), Inform)
        ]
    );
    assert_eq!(
        answers(&chair2),
        [
            ("c".into(), Refuse),
            ("d".into(), Agree),
            ("d".into(), Inform),
            ("e".into(), Refuse)
        ]
    );
    assert_eq!(
        *moves.lock().unwrap(),
        [("lab".to_string(), true), ("hall".to_string(), true)],
        "the refused chair moved nothing"
    );
    let state = WheelchairContent::from_message(chair1.lock().unwrap().last().unwrap()).unwrap();
    assert_eq!(
        state,
        WheelchairContent::Inform(Fact::Door {
            door: "lab".into(),
            state: DoorState::Open
        })
    );
    let refusals = refusals.lock().unwrap();
    assert_eq!(refusals.len(), 2);
    assert_eq!(
        (refusals[0].requester.as_str(), refusals[0].door.as_str()),
        ("cognitive-chair2", "lab")
    );
    assert_eq!(refusals[1].door, "vault");
}
