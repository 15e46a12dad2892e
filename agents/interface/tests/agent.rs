//! The interface agent on an in-process bus: a mixed sequence sends a goal to the cognitive
//! agent, a homogeneous one a stop to the control agent, bad input is refused; a held stick
//! streams `drive` and a release, a broken reading or a silent device stops it. (The stream
//! against the real control agent and the simulator is in the fleet's tests.)

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_bus::Time;
use iw_interface::sequence::DEFAULT_MAX_GAP;
use iw_interface::{
    Command, Device, InputSequence, InterfaceAgent, InterfaceConfig, RawInput, Recognizer,
    ReliabilityTest,
};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

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
    let mut test = ReliabilityTest::new(seq, 5, 4, DEFAULT_MAX_GAP).unwrap();
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

/// Adds `interface@c1` (cognitive and control `@c1`) with `recognizer`; its input queue and
/// display.
fn add_interface(
    host: &mut AgentHost,
    recognizer: Recognizer<Command>,
) -> (iw_interface::InputQueue, Arc<Mutex<iw_interface::Display>>) {
    let inputs = iw_interface::InputQueue::default();
    let display = Arc::new(Mutex::new(iw_interface::Display::default()));
    let config = InterfaceConfig::new(AgentId::new("cognitive@c1"), AgentId::new("control@c1"));
    let agent = InterfaceAgent::new(config, recognizer, inputs.clone(), display.clone());
    host.add(AgentId::new("interface@c1"), Box::new(agent))
        .unwrap();
    (inputs, display)
}

/// A host on an in-process bus with a mock clock at 0.
fn host() -> (AgentHost, iw_bus::MockController) {
    AgentHost::on_a_mock_clock(Time::from_ns(0))
}

#[test]
fn sequences_become_acl_requests() {
    let (mut host, controller) = host();
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

    let mut recognizer = Recognizer::new(DEFAULT_MAX_GAP);
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
            Command::Stop,
        )
        .unwrap();
    let (inputs, display) = add_interface(&mut host, recognizer);

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
    let stops = control.lock().unwrap();
    assert_eq!(stops.len(), 1);
    assert_eq!(
        WheelchairContent::from_message(&stops[0]).unwrap(),
        WheelchairContent::Request {
            actor: AgentId::new("control@c1"),
            action: WheelchairAction::Stop
        }
    );
    let display = display.lock().unwrap();
    assert_eq!(display.refused_inputs, 1);
    assert_eq!(display.last_command, Some(Command::Stop));
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

/// Records what it receives and answers nothing (the stream's answers are the control agent's
/// business; the fleet's tests run the real one).
struct Sink(Arc<Mutex<Vec<(Time, AclMessage)>>>);
impl Agent for Sink {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        self.0.lock().unwrap().push((ctx.now(), message));
    }
}

/// (time ms, conversation, linear, angular) of every drive the control side received.
fn drives(sink: &Arc<Mutex<Vec<(Time, AclMessage)>>>) -> Vec<(u64, String, f64, f64)> {
    sink.lock()
        .unwrap()
        .iter()
        .filter_map(|(t, m)| match WheelchairContent::from_message(m) {
            Ok(WheelchairContent::Request {
                action:
                    WheelchairAction::Drive {
                        linear_mps,
                        angular_radps,
                    },
                ..
            }) => Some((
                t.0 / 1_000_000,
                m.conversation_id.clone().unwrap_or_default(),
                linear_mps,
                angular_radps,
            )),
            _ => None,
        })
        .collect()
}

#[test]
fn a_held_input_streams_drive_and_release_silence_or_nan_stop_it() {
    let (mut host, controller) = host();
    let sink = Arc::new(Mutex::new(Vec::new()));
    host.add(AgentId::new("control@c1"), Box::new(Sink(sink.clone())))
        .unwrap();
    let (inputs, display) = add_interface(&mut host, Recognizer::new(DEFAULT_MAX_GAP));
    let mut run = |ms: u64, reading: Option<RawInput>| {
        for _ in 0..ms / 10 {
            if let Some(r) = &reading
                && controller.now().0 / 1_000_000 % 100 == 0
            {
                // the device reports every 100 ms while held
                inputs.lock().unwrap().push_back((r.clone(), 0));
            }
            host.step(controller.now());
            controller.advance(Duration::from_millis(10));
        }
    };
    // Held for 1 s: full forward on the stick.
    run(1000, Some(RawInput::Joystick { x: 0.0, y: 1.0 }));
    let held = drives(&sink);
    assert!(held.len() >= 10, "at least 10 Hz: {} in 1 s", held.len());
    assert!(
        held.iter().all(|d| d.1 == held[0].1),
        "one conversation per hold"
    );
    assert!(
        held.iter().all(|d| (d.2 - 0.6).abs() < 1e-12 && d.3 == 0.0),
        "{held:?}"
    );
    assert_eq!(
        display.lock().unwrap().drive.map(|d| d.linear_mps),
        Some(0.6)
    );
    // Released: one stop in the same stream, then nothing.
    run(500, Some(RawInput::Joystick { x: 0.0, y: 0.0 }));
    let after = drives(&sink)[held.len()..].to_vec();
    assert_eq!(after.len(), 1, "{after:?}");
    assert_eq!(
        (after[0].1.as_str(), after[0].2, after[0].3),
        (held[0].1.as_str(), 0.0, 0.0)
    );
    assert_eq!(display.lock().unwrap().drive, None);

    // Head cap tilted forward, then a NaN reading: dropped, counted, and the chair stopped.
    let before = drives(&sink).len();
    run(
        300,
        Some(RawInput::HeadCap {
            pitch_rad: 0.3,
            roll_rad: 0.2,
        }),
    );
    run(
        200,
        Some(RawInput::HeadCap {
            pitch_rad: f64::NAN,
            roll_rad: 0.0,
        }),
    );
    let head = drives(&sink)[before..].to_vec();
    let (last, moving) = head.split_last().unwrap();
    assert!(
        moving.iter().all(|d| d.2 > 0.0 && d.3 < 0.0),
        "forward, right: {moving:?}"
    );
    assert_eq!((last.2, last.3), (0.0, 0.0), "{head:?}");
    assert_ne!(head[0].1, held[0].1, "a new hold, a new conversation");
    assert_eq!(
        display.lock().unwrap().refused_inputs,
        2,
        "both NaN readings"
    );

    // Arrow keys held, then the page goes silent: released after the 300 ms hold.
    let before = drives(&sink).len();
    inputs.lock().unwrap().push_back((
        RawInput::Arrows {
            up: true,
            down: false,
            left: false,
            right: false,
        },
        0,
    ));
    run(1000, None);
    let keys = drives(&sink)[before..].to_vec();
    let (last, moving) = keys.split_last().unwrap();
    assert!(
        !moving.is_empty() && moving.iter().all(|d| (d.2 - 0.3).abs() < 1e-12),
        "{keys:?}"
    );
    assert_eq!((last.2, last.3), (0.0, 0.0));
    assert!(
        last.0 - moving[0].0 <= 400,
        "released within the hold: {keys:?}"
    );
}

/// Drive requests waiting to be sent: linear (m/s), angular (rad/s), conversation.
type Outbox = Arc<Mutex<Vec<(f64, f64, &'static str)>>>;

/// Sends the `drive` requests queued in its outbox (velocity, conversation) each tick and keeps
/// the answers.
struct RemotePanel {
    outbox: Outbox,
    answers: Arc<Mutex<Vec<AclMessage>>>,
}
impl Agent for RemotePanel {
    fn handle(&mut self, _ctx: &mut Context<'_>, message: AclMessage) {
        self.answers.lock().unwrap().push(message);
    }
    fn tick(&mut self, ctx: &mut Context<'_>) {
        let pending: Vec<_> = self.outbox.lock().unwrap().drain(..).collect();
        for (linear_mps, angular_radps, conversation) in pending {
            let request = WheelchairContent::Request {
                actor: AgentId::new("interface@c1"),
                action: WheelchairAction::Drive {
                    linear_mps,
                    angular_radps,
                },
            }
            .fill(
                AclMessage::new(Performative::Request)
                    .with_receiver(AgentId::new("interface@c1"))
                    .with_protocol("fipa-request")
                    .with_conversation_id(conversation),
            );
            ctx.send(request).unwrap();
        }
    }
    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_millis(10))
    }
}

#[test]
fn a_remote_driver_streams_through_the_interface_and_others_are_refused() {
    let (mut host, controller) = host();
    let sink = Arc::new(Mutex::new(Vec::new()));
    host.add(AgentId::new("control@c1"), Box::new(Sink(sink.clone())))
        .unwrap();
    let display = Arc::new(Mutex::new(iw_interface::Display::default()));
    let mut config = InterfaceConfig::new(AgentId::new("cognitive@c1"), AgentId::new("control@c1"));
    config.remote_drivers = vec!["staff@services".into()];
    let interface = InterfaceAgent::new(
        config,
        Recognizer::new(DEFAULT_MAX_GAP),
        iw_interface::InputQueue::default(),
        display.clone(),
    );
    host.add(AgentId::new("interface@c1"), Box::new(interface))
        .unwrap();
    let mut panel = |name: &str| {
        let outbox = Arc::new(Mutex::new(Vec::new()));
        let answers = Arc::new(Mutex::new(Vec::new()));
        host.add(
            AgentId::new(name),
            Box::new(RemotePanel {
                outbox: outbox.clone(),
                answers: answers.clone(),
            }),
        )
        .unwrap();
        (outbox, answers)
    };
    let (staff, staff_answers) = panel("staff@services");
    let (evil, evil_answers) = panel("evil@x");
    let mut run = |ms: u64| {
        for _ in 0..ms / 10 {
            host.step(controller.now());
            controller.advance(Duration::from_millis(10));
        }
    };
    let said = |answers: &Arc<Mutex<Vec<AclMessage>>>| -> Vec<String> {
        answers
            .lock()
            .unwrap()
            .iter()
            .map(|m| format!("{} {:?}", m.performative, m.content))
            .collect()
    };
    // The staff's panel holds forward for 600 ms (resent every 100 ms): one AGREE, a stream.
    for _ in 0..6 {
        staff.lock().unwrap().push((0.4, 0.0, "panel-1"));
        run(100);
    }
    let streamed = drives(&sink);
    assert!(streamed.len() >= 10, "{streamed:?}");
    assert!(streamed.iter().all(|d| d.2 == 0.4 && d.1 == streamed[0].1));
    assert_eq!(said(&staff_answers).len(), 1, "{:?}", said(&staff_answers));
    assert!(said(&staff_answers)[0].starts_with("AGREE"));
    assert_eq!(
        display.lock().unwrap().drive.map(|d| d.device),
        Some(Device::Remote)
    );
    // An agent not authorised is refused, and so is a second driver; the stream goes on.
    evil.lock().unwrap().push((0.2, 0.0, "evil-1"));
    staff.lock().unwrap().push((0.4, 0.0, "panel-1"));
    run(100);
    let refused = said(&evil_answers);
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(
        refused[0].starts_with("REFUSE") && refused[0].contains("may not drive"),
        "{refused:?}"
    );
    // NaN (which SL cannot even carry): not understood, with the reason, and the chair stopped
    // at once (the stream's last drive is a stop).
    staff.lock().unwrap().push((f64::NAN, 0.0, "panel-1"));
    run(30);
    let answers = said(&staff_answers);
    assert!(
        answers.last().unwrap().starts_with("NOT-UNDERSTOOD")
            && answers.last().unwrap().contains("expected a number"),
        "{answers:?}"
    );
    let all = drives(&sink);
    assert_eq!((all.last().unwrap().2, all.last().unwrap().3), (0.0, 0.0));
    assert_eq!(display.lock().unwrap().drive, None);
    // Out of range: refused too; silence after a hold: released within the hold.
    staff.lock().unwrap().push((5.0, 0.0, "panel-2"));
    run(100);
    assert!(
        said(&staff_answers)
            .last()
            .unwrap()
            .contains("out of range")
    );
    staff.lock().unwrap().push((0.3, 0.1, "panel-3"));
    run(1000);
    let last = drives(&sink);
    let (stop, moving) = last.split_last().unwrap();
    assert_eq!((stop.2, stop.3), (0.0, 0.0));
    assert!(moving.iter().any(|d| d.2 == 0.3 && d.1 != all[0].1));
}
