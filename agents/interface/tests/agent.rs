//! The interface agent on an in-process bus: a mixed sequence sends a goal to the cognitive
//! agent, a homogeneous one a manual command to the control agent, bad input is refused.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Stack, Time};
use iw_interface::sequence::DEFAULT_MAX_GAP_MS;
use iw_interface::{
    Command, Device, InputSequence, InterfaceAgent, InterfaceConfig, RawInput, Recognizer,
    ReliabilityTest,
};

/// Records what it receives and agrees to requests.
struct Recorder(Arc<Mutex<Vec<AclMessage>>>);
impl Agent for Recorder {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if message.performative == Performative::Request {
            let _ = ctx.send(
                message
                    .create_reply()
                    .with_performative(Performative::Agree),
            );
        }
        self.0.lock().unwrap().push(message);
    }
}

fn trained(steps: &[(Device, &str)]) -> ReliabilityTest {
    let seq = InputSequence(steps.iter().map(|(d, s)| (*d, s.to_string())).collect());
    let mut test = ReliabilityTest::new(seq, 5, 4, DEFAULT_MAX_GAP_MS).unwrap();
    for attempt in 0..5u64 {
        // the user slips once: the second attempt pauses too long
        let gap = if attempt == 1 { 10_000 } else { 300 };
        let events: Vec<_> = steps
            .iter()
            .enumerate()
            .map(|(i, (d, s))| iw_interface::InputEvent {
                device: *d,
                symbol: s.to_string(),
                t_ms: i as u64 * gap,
            })
            .collect();
        test.attempt(&events);
    }
    assert_eq!(test.verdict(), iw_interface::Verdict::Accepted);
    test
}

#[test]
fn sequences_become_acl_requests() {
    let network = InProcNetwork::new();
    let (clock, controller) = Clock::mock(Time::from_ns(0));
    let bus = Bus::start(
        Stack::new(),
        Arc::new(network.endpoint("c1").unwrap()),
        clock,
        BusConfig::default(),
    )
    .unwrap();
    let mut host = AgentHost::new(Arc::new(bus));
    let cognitive = Arc::new(Mutex::new(Vec::new()));
    let control = Arc::new(Mutex::new(Vec::new()));
    host.add(
        AgentId::new("cognitive@c1"),
        Box::new(Recorder(cognitive.clone())),
    )
    .unwrap();
    host.add(
        AgentId::new("control@c1"),
        Box::new(Recorder(control.clone())),
    )
    .unwrap();

    let mut recognizer = Recognizer::new(DEFAULT_MAX_GAP_MS);
    recognizer
        .bind(
            &trained(&[(Device::HeadGesture, "head-up"), (Device::Voice, "kitchen")]),
            Command::Goal {
                place: "kitchen".into(),
            },
        )
        .unwrap();
    recognizer
        .bind(
            &trained(&[(Device::Gamepad, "a"), (Device::Gamepad, "a")]),
            Command::Drive {
                linear_mps: 0.3,
                angular_radps: 0.0,
            },
        )
        .unwrap();
    let inputs = iw_interface::InputQueue::default();
    let display = Arc::new(Mutex::new(iw_interface::Display::default()));
    let config = InterfaceConfig {
        cognitive: AgentId::new("cognitive@c1"),
        control: AgentId::new("control@c1"),
        tick: Duration::from_millis(100),
    };
    host.add(
        AgentId::new("interface@c1"),
        Box::new(InterfaceAgent::new(
            config,
            recognizer,
            inputs.clone(),
            display.clone(),
        )),
    )
    .unwrap();

    let push = |raw: RawInput, t_ms: u64| inputs.lock().unwrap().push_back((raw, t_ms));
    push(
        RawInput::HeadGesture {
            ax_mps2: 0.1,
            ay_mps2: 4.0,
        },
        0,
    );
    push(
        RawInput::Keyboard {
            key: "not a key".into(),
        },
        10,
    );
    for _ in 0..2 {
        host.step(controller.now());
        controller.advance(Duration::from_millis(100));
    }
    assert_eq!(
        display.lock().unwrap().progress,
        Some((1, 2)),
        "half of the goal sequence entered"
    );
    push(
        RawInput::Voice {
            text: "Kitchen".into(),
        },
        400,
    );
    push(RawInput::Gamepad { button: "A".into() }, 500);
    push(RawInput::Gamepad { button: "a".into() }, 700);
    for _ in 0..3 {
        host.step(controller.now());
        controller.advance(Duration::from_millis(100));
    }

    let goals = cognitive.lock().unwrap();
    assert_eq!(goals.len(), 1);
    assert_eq!(goals[0].performative, Performative::Request);
    let content = goals[0].content_text().unwrap();
    assert!(
        content.contains("go-to") && content.contains("kitchen"),
        "{content}"
    );
    let drives = control.lock().unwrap();
    assert_eq!(drives.len(), 1);
    assert!(
        drives[0].content_text().unwrap().contains("drive"),
        "{:?}",
        drives[0].content_text()
    );
    let display = display.lock().unwrap();
    assert_eq!(display.refused_inputs, 1);
    assert_eq!(
        display.last_command,
        Some(Command::Drive {
            linear_mps: 0.3,
            angular_radps: 0.0
        })
    );
    assert!(
        display
            .last_answer
            .as_deref()
            .unwrap_or("")
            .to_ascii_lowercase()
            .starts_with("agree"),
        "{:?}",
        display.last_answer
    );
}
