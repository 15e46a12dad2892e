//! The control agent alone on an in-process bus with a mock clock: real ACL in, real replies out.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::AgentHost;
use iw_agent::gateway::{GatewayHandle, gateway};
use iw_body::TRACK_M;
use iw_body::{Body, BodyError, SensorFrame, WheelSpeeds};
use iw_bus::{MockController, Time};
use iw_control::{ControlAgent, ControlConfig, LaserMount};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, Pose, WheelchairAction, WheelchairContent};

/// A body that records every command and integrates them into a pose (unicycle).
#[derive(Clone, Default)]
struct Recorder {
    commands: Arc<Mutex<Vec<WheelSpeeds>>>,
    /// The sonar ranges every read returns.
    sonar_m: Arc<Mutex<[Option<f64>; iw_body::SONAR_COUNT]>>,
    /// How many of the next reads time out, as a silent serial link does.
    failing_reads: Arc<Mutex<u32>>,
    /// How many of the next wheel commands (stops included) fail.
    failing_commands: Arc<Mutex<u32>>,
    /// Wheel commands refused so far.
    refused_commands: Arc<Mutex<u32>>,
    /// The laser ranges every read returns.
    laser_m: Arc<Mutex<Vec<f64>>>,
}

/// A silent serial link's timeout when `failing` still counts failures (one used up).
fn fails(failing: &Mutex<u32>) -> Result<(), BodyError> {
    let mut failing = failing.lock().unwrap();
    if *failing == 0 {
        return Ok(());
    }
    *failing -= 1;
    Err(BodyError::Timeout {
        port: "/dev/test".into(),
        timeout: Duration::from_millis(200),
        received: 0,
        skipped: 0,
    })
}

impl Body for Recorder {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        fails(&self.failing_reads)?;
        Ok(SensorFrame {
            sonar_m: *self.sonar_m.lock().unwrap(),
            laser_m: self.laser_m.lock().unwrap().clone(),
            ..SensorFrame::empty(0)
        })
    }
    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        if let Err(err) = fails(&self.failing_commands) {
            *self.refused_commands.lock().unwrap() += 1;
            return Err(err);
        }
        self.commands.lock().unwrap().push(speeds);
        Ok(())
    }
}

struct Rig {
    host: AgentHost,
    clock: MockController,
    probe: GatewayHandle,
    received: Vec<AclMessage>,
    body: Recorder,
    /// Other drivers, by name: `other` (of this chair), `staff` (staff), `stranger@far`.
    others: Vec<(String, GatewayHandle)>,
    others_received: Vec<(String, AclMessage)>,
}

/// A manual drive command (m/s, rad/s) to the control agent, as the interface sends it.
fn drive(linear_mps: f64, angular_radps: f64) -> AclMessage {
    WheelchairContent::Request {
        actor: AgentId::new("control"),
        action: WheelchairAction::Drive {
            linear_mps,
            angular_radps,
        },
    }
    .fill(AclMessage::new(Performative::Request).with_protocol("fipa-request"))
}

fn rig() -> Rig {
    rig_with(|_| {})
}

/// A rig whose control agent's configuration `adjust` changed.
fn rig_with(adjust: impl FnOnce(&mut ControlConfig)) -> Rig {
    let (mut host, controller) = AgentHost::on_a_mock_clock(Time::from_ns(1_000_000_000));
    let body = Recorder::default();
    let mut config = ControlConfig::prototype(Some(AgentId::new("probe"))).unwrap();
    config.staff = vec!["staff".into()];
    adjust(&mut config);
    host.add(
        AgentId::new("control"),
        Box::new(ControlAgent::new(config, Box::new(body.clone())).unwrap()),
    )
    .unwrap();
    let (agent, probe) = gateway(Duration::from_millis(1));
    host.add(AgentId::new("probe"), Box::new(agent)).unwrap();
    let others = ["other", "staff", "stranger@far"]
        .into_iter()
        .map(|name| {
            let (agent, handle) = gateway(Duration::from_millis(1));
            host.add(AgentId::new(name), Box::new(agent)).unwrap();
            (name.to_string(), handle)
        })
        .collect();
    Rig {
        host,
        clock: controller,
        probe,
        received: Vec::new(),
        body,
        others,
        others_received: Vec::new(),
    }
}

impl Rig {
    fn run(&mut self, ms: u64) {
        for _ in 0..ms / 10 {
            self.host.step(self.clock.now());
            self.clock.advance(Duration::from_millis(10));
        }
        self.received.extend(self.probe.take_received());
        assert!(self.probe.take_send_errors().is_empty());
        for (name, handle) in &self.others {
            let got = handle.take_received();
            self.others_received
                .extend(got.into_iter().map(|m| (name.clone(), m)));
        }
    }
    /// Sends `m` to the control agent as `from` (one of [`Rig::others`]).
    fn send_as(&self, from: &str, m: AclMessage) {
        let (_, handle) = self.others.iter().find(|(n, _)| n == from).unwrap();
        handle.send(m.with_receiver(AgentId::new("control")));
    }
    /// What `name` received: performative and error reason (empty when none).
    fn answers_to(&self, name: &str) -> Vec<(Performative, String)> {
        self.others_received
            .iter()
            .filter(|(n, _)| n == name)
            .map(|(_, m)| (m.performative, reason(m)))
            .collect()
    }
    /// Sends a pose notification in the control agent's pose subscription (made at setup: one
    /// step runs first if it has not happened yet).
    fn send_pose(&mut self, x: f64, y: f64, theta: f64) {
        if !self
            .received
            .iter()
            .any(|m| m.performative == Performative::Subscribe)
        {
            self.run(10);
        }
        let subscription = self
            .received
            .iter()
            .find(|m| m.performative == Performative::Subscribe)
            .expect("the control agent subscribes at setup")
            .clone();
        let mut notification = pose(x, y, theta);
        notification.receivers = vec![AgentId::new("control")];
        notification.conversation_id = subscription.conversation_id.clone();
        notification.in_reply_to = subscription.reply_with.clone();
        notification.protocol = subscription.protocol.clone();
        self.probe.send(notification);
    }
    fn send(&self, m: AclMessage) {
        self.probe.send(m.with_receiver(AgentId::new("control")));
    }
    fn last_wheels(&self) -> WheelSpeeds {
        *self.body.commands.lock().unwrap().last().unwrap()
    }
    fn performatives(&self) -> Vec<Performative> {
        self.received.iter().map(|m| m.performative).collect()
    }
}

/// The `error-message` or `body-fault` of a reply, empty when it has none.
fn reason(m: &AclMessage) -> String {
    WheelchairContent::from_message(m)
        .ok()
        .and_then(|c| c.reason().map(str::to_string))
        .unwrap_or_default()
}

/// A pose notification as the perception agent sends it: an INFORM in the control agent's
/// subscription (see [`Rig::send_pose`]).
fn pose(x: f64, y: f64, theta: f64) -> AclMessage {
    let fact = Fact::AtPose {
        agent: AgentId::new("probe"),
        pose: Pose {
            x_m: x,
            y_m: y,
            theta_rad: theta,
            covariance: nalgebra::Matrix3::zeros(),
        },
    };
    WheelchairContent::Inform(fact).fill(AclMessage::new(Performative::Inform))
}

#[test]
fn subscribes_to_perception_at_setup() {
    let mut rig = rig();
    rig.run(20);
    let inbox = &rig.received;
    assert_eq!(inbox[0].performative, Performative::Subscribe);
    assert_eq!(inbox[0].protocol.as_deref(), Some("fipa-subscribe"));
}

#[test]
fn manual_driving_moves_the_chair_and_the_watchdog_stops_it() {
    let mut rig = rig();
    for _ in 0..20 {
        rig.send(drive(0.4, 0.0));
        rig.run(100);
    }
    let moving = rig.last_wheels();
    assert!(
        moving.left_mps > 0.3 && moving.right_mps > 0.3,
        "{moving:?}"
    );
    // Commands stop arriving: within the 0.5 s watchdog plus the ramp the wheels are at zero.
    rig.run(2000);
    assert_eq!(rig.last_wheels(), WheelSpeeds::STOP);
    assert!(
        rig.performatives()
            .iter()
            .all(|p| *p != Performative::NotUnderstood)
    );
}

#[test]
fn goto_is_agreed_driven_and_reported_done() {
    let mut rig = rig();
    let action = WheelchairAction::GotoXy { x_m: 1.0, y_m: 0.0 };
    let request = WheelchairContent::Request {
        actor: AgentId::new("control"),
        action: action.clone(),
    }
    .fill(
        AclMessage::new(Performative::Request)
            .with_protocol("fipa-request")
            .with_conversation_id("g1"),
    );
    rig.send_pose(0.0, 0.0, 0.0);
    rig.send(request);
    rig.run(200);
    assert!(
        rig.performatives().contains(&Performative::Agree),
        "{:?}",
        rig.performatives()
    );
    assert!(rig.last_wheels().left_mps > 0.0, "drives toward the goal");
    rig.send_pose(0.98, 0.0, 0.0);
    rig.run(200);
    let inbox = &rig.received;
    let done = inbox
        .iter()
        .find(|m| m.performative == Performative::Inform)
        .expect("inform done");
    assert_eq!(done.conversation_id.as_deref(), Some("g1"));
    assert_eq!(
        WheelchairContent::from_message(done).unwrap(),
        WheelchairContent::Done {
            actor: AgentId::new("control"),
            action
        }
    );
}

#[test]
fn a_chair_that_cannot_progress_reports_failure_and_non_driving_actions_are_refused() {
    let mut rig = rig();
    let goto = WheelchairContent::Request {
        actor: AgentId::new("control"),
        action: WheelchairAction::GotoXy { x_m: 5.0, y_m: 0.0 },
    }
    .fill(AclMessage::new(Performative::Request).with_conversation_id("g2"));
    let door = WheelchairContent::Request {
        actor: AgentId::new("control"),
        action: WheelchairAction::OpenDoor { door: "d1".into() },
    }
    .fill(AclMessage::new(Performative::Request).with_conversation_id("g3"));
    rig.send_pose(0.0, 0.0, 0.0);
    rig.send(goto);
    rig.send(door);
    rig.send(AclMessage::new(Performative::Request).with_content("((nonsense"));
    rig.run(10_000);
    let got = rig.performatives();
    assert!(got.contains(&Performative::Refuse), "{got:?}");
    assert!(got.contains(&Performative::NotUnderstood), "{got:?}");
    let inbox = &rig.received;
    assert!(
        inbox.iter().any(|m| m.performative == Performative::Failure
            && m.conversation_id.as_deref() == Some("g2"))
    );
    assert_eq!(rig.last_wheels(), WheelSpeeds::STOP);
}

#[test]
fn a_short_body_fault_stops_the_wheels_and_the_task_resumes_from_rest() {
    let mut rig = rig();
    rig.send_pose(0.0, 0.0, 0.0);
    rig.send(goto_far("g4"));
    rig.run(3000);
    let cruising = rig.last_wheels();
    assert!(cruising.left_mps > 0.4, "{cruising:?}");
    // Four control periods (200 ms) without a sensor frame: under the 500 ms the task survives.
    *rig.body.failing_reads.lock().unwrap() = 4;
    let before = rig.body.commands.lock().unwrap().len();
    rig.run(200);
    assert_eq!(
        rig.last_wheels(),
        WheelSpeeds::STOP,
        "the first failed read stops the wheels"
    );
    rig.run(100);
    let after: Vec<WheelSpeeds> = rig.body.commands.lock().unwrap()[before..].to_vec();
    let resumed = after
        .iter()
        .find(|w| w.left_mps > 0.0)
        .expect("the task drives again");
    // 1.5 m/s^2 over one 50 ms period from rest, not the cruising speed again.
    assert!(
        resumed.left_mps <= 0.08,
        "resumed at {resumed:?} after {after:?}"
    );
    assert!(!failed(&rig, "g4"), "{:?}", rig.performatives());
}

#[test]
fn a_body_unreadable_beyond_the_fault_window_fails_the_task() {
    let mut rig = rig();
    rig.send_pose(0.0, 0.0, 0.0);
    rig.send(goto_far("g5"));
    rig.run(1000);
    *rig.body.failing_reads.lock().unwrap() = 20;
    rig.run(1000);
    let failure = rig
        .received
        .iter()
        .find(|m| m.performative == Performative::Failure)
        .expect("the task fails");
    assert_eq!(failure.conversation_id.as_deref(), Some("g5"));
    // A body fault, not an error of the way: the cognitive agent retries rather than re-plans.
    match WheelchairContent::from_message(failure) {
        Ok(WheelchairContent::Inform(Fact::BodyFault { reason })) => {
            assert!(reason.contains("no sensor frame"), "{reason}")
        }
        other => panic!("not a body fault: {other:?}"),
    }
    rig.run(1000);
    assert_eq!(
        rig.last_wheels(),
        WheelSpeeds::STOP,
        "no task, no motion after the link returns"
    );
}

#[test]
fn a_wheel_stop_that_fails_fails_the_task_at_once_and_is_retried() {
    let mut rig = rig();
    rig.send_pose(0.0, 0.0, 0.0);
    rig.send(goto_far("g6"));
    rig.run(1000);
    assert!(rig.last_wheels().left_mps > 0.0);
    // The link drops: reads fail and the board takes no command, not even a stop.
    *rig.body.failing_reads.lock().unwrap() = 1_000;
    *rig.body.failing_commands.lock().unwrap() = 1_000;
    rig.run(100);
    let failure = rig
        .received
        .iter()
        .find(|m| m.performative == Performative::Failure)
        .expect("the task fails at once, not after the fault window");
    assert_eq!(failure.conversation_id.as_deref(), Some("g6"));
    assert!(reason(failure).contains("wheel stop failed"), "{failure:?}");
    let refused = *rig.body.refused_commands.lock().unwrap();
    assert!(refused >= 2, "the stop is retried ({refused} attempts)");
    // The stop keeps being retried every period until the board takes it.
    rig.run(200);
    assert!(*rig.body.refused_commands.lock().unwrap() > refused);
    *rig.body.failing_commands.lock().unwrap() = 0;
    rig.run(100);
    assert_eq!(rig.last_wheels(), WheelSpeeds::STOP);
}

/// Sends the pose every 100 ms for `ms` while the chair turns through `headings` (cycled).
fn hold_pose(rig: &mut Rig, ms: u64, headings: &[f64]) {
    for k in 0..ms / 100 {
        rig.send_pose(0.0, 0.0, headings[k as usize % headings.len()]);
        rig.run(100);
    }
}

fn goto_far(id: &str) -> AclMessage {
    WheelchairContent::Request {
        actor: AgentId::new("control"),
        action: WheelchairAction::GotoXy { x_m: 5.0, y_m: 0.0 },
    }
    .fill(AclMessage::new(Performative::Request).with_conversation_id(id))
}

fn failed(rig: &Rig, id: &str) -> bool {
    rig.received.iter().any(|m| {
        m.performative == Performative::Failure && m.conversation_id.as_deref() == Some(id)
    })
}

#[test]
fn a_wall_on_the_right_stops_a_spin_into_it_and_leaves_driving_along_it_alone() {
    // Thesis figure 3.4, as the simulator lays the sonars out: S3-S6 (indices 2-5) look right
    // from the right bar. A wall 10 cm to the right echoes on them.
    let mut rig = rig();
    {
        let mut sonar = rig.body.sonar_m.lock().unwrap();
        for k in 2..=5 {
            sonar[k] = Some(0.1);
        }
    }
    // Driving along it sweeps nothing: the user's command reaches the wheels.
    for _ in 0..10 {
        rig.send(drive(0.4, 0.0));
        rig.run(100);
    }
    let wheels = rig.last_wheels();
    assert!(
        (wheels.left_mps - wheels.right_mps).abs() < 1e-9 && wheels.left_mps > 0.3,
        "driving along the wall is left alone: {wheels:?}"
    );
    // Spinning right would swing the front right corner (0.75 m ahead) through it.
    for _ in 0..10 {
        rig.send(drive(0.0, -0.8));
        rig.run(100);
    }
    let wheels = rig.last_wheels();
    assert!(
        wheels.left_mps - wheels.right_mps < 0.8 * TRACK_M * 0.5,
        "the spin into the wall must be held back: {wheels:?}"
    );
}

#[test]
fn wiggling_in_place_without_travel_is_blocked() {
    // The heading jitters by +-0.2 rad with no travel: no real progress, so the task fails.
    let mut rig = rig();
    rig.send_pose(0.0, 0.0, 0.0);
    rig.send(goto_far("jitter"));
    hold_pose(&mut rig, 10_000, &[0.0, 0.2, -0.2]);
    assert!(failed(&rig, "jitter"), "{:?}", rig.performatives());
}

#[test]
fn turning_in_place_is_progress() {
    // Turning steadily in place (0.2 rad/s, 2 rad in 10 s) is progress: not blocked.
    let mut rig2 = self::rig();
    rig2.send_pose(0.0, 0.0, 0.0);
    rig2.send(goto_far("turn"));
    let headings: Vec<f64> = (0..100).map(|k| -0.02 * k as f64).collect();
    hold_pose(&mut rig2, 10_000, &headings);
    assert!(!failed(&rig2, "turn"), "{:?}", rig2.performatives());
}

#[test]
fn spinning_towards_a_wall_beside_the_chair_is_held_back() {
    // A wall 10 cm to the right: a clockwise spin would swing the 0.75 m front into it. The
    // body here does not turn, so the guard keeps judging the same wall: it may let the chair
    // creep (the arc until stopped stays clear) but not spin as asked.
    let mut rig = rig();
    {
        let mut sonar = rig.body.sonar_m.lock().unwrap();
        for k in 2..=5 {
            sonar[k] = Some(0.1);
        }
    }
    for _ in 0..10 {
        rig.send(drive(0.0, -0.8));
        rig.run(100);
    }
    let wheels = rig.last_wheels();
    let clockwise_radps = (wheels.left_mps - wheels.right_mps) / TRACK_M;
    assert!(
        clockwise_radps <= 0.4,
        "the chair still spins clockwise into the wall: {wheels:?}"
    );
}

/// Streams `drive(v, w)` in conversation `id` every 100 ms for `ms`.
fn stream(rig: &mut Rig, id: &str, v: f64, w: f64, ms: u64) {
    for _ in 0..ms / 100 {
        rig.send(drive(v, w).with_conversation_id(id));
        rig.run(100);
    }
}

fn answers(rig: &Rig, id: &str) -> Vec<(Performative, String)> {
    rig.received
        .iter()
        .filter(|m| m.conversation_id.as_deref() == Some(id))
        .map(|m| (m.performative, reason(m)))
        .collect()
}

#[test]
fn a_drive_stream_is_agreed_once_and_ends_done_when_released() {
    let mut rig = rig();
    stream(&mut rig, "s1", 0.5, 0.0, 2000);
    assert!(rig.last_wheels().left_mps > 0.4, "{:?}", rig.last_wheels());
    // The user lets go: a zero command, then the interface falls silent.
    stream(&mut rig, "s1", 0.0, 0.0, 100);
    rig.run(1500);
    assert_eq!(rig.last_wheels(), WheelSpeeds::STOP);
    let got: Vec<Performative> = answers(&rig, "s1").into_iter().map(|a| a.0).collect();
    assert_eq!(
        got,
        [Performative::Agree, Performative::Inform],
        "one AGREE per stream"
    );
}

#[test]
fn a_stream_that_falls_silent_mid_drive_fails_and_the_chair_stops_within_the_watchdog() {
    let mut rig = rig();
    stream(&mut rig, "s2", 0.6, 0.0, 2000);
    let before = rig.body.commands.lock().unwrap().len();
    // 0.5 s watchdog, then the 1.5 m/s^2 ramp from 0.6 m/s: 0.4 s.
    rig.run(1000);
    assert_eq!(rig.last_wheels(), WheelSpeeds::STOP);
    let after = rig.body.commands.lock().unwrap()[before..].to_vec();
    let first_stop = after.iter().position(|w| *w == WheelSpeeds::STOP).unwrap();
    assert!(
        first_stop * 50 <= 1000,
        "stopped {} ms after silence",
        first_stop * 50
    );
    let got = answers(&rig, "s2");
    assert_eq!(got[0].0, Performative::Agree);
    assert_eq!(got[1].0, Performative::Failure);
    assert!(got[1].1.contains("watchdog"), "{got:?}");
}

#[test]
fn bad_drive_commands_are_refused_with_a_reason() {
    let mut rig = rig();
    rig.send(drive(3.0, 0.0).with_conversation_id("fast"));
    rig.send(
        AclMessage::new(Performative::Request)
            .with_conversation_id("word")
            .with_ontology("IntellWheels-Wheelchair")
            .with_language("fipa-sl0")
            .with_content(
                "((action (agent-identifier :name control) (drive :linear fast :angular 0)))",
            ),
    );
    rig.run(200);
    let fast = answers(&rig, "fast");
    assert_eq!(fast[0].0, Performative::Refuse, "{fast:?}");
    assert!(fast[0].1.contains("out of range"), "{fast:?}");
    let word = answers(&rig, "word");
    assert_eq!(word[0].0, Performative::NotUnderstood, "{word:?}");
    assert!(word[0].1.contains("linear"), "{word:?}");
    assert!(rig.last_wheels().left_mps.abs() < 1e-9, "nothing drove");
}

#[test]
fn a_broken_command_mid_stream_stops_the_chair() {
    let mut rig = rig();
    stream(&mut rig, "s3", 0.5, 0.0, 1500);
    assert!(rig.last_wheels().left_mps > 0.4);
    // SL has no infinity: `1e999` is a word, not a number, so it is not understood.
    rig.send(
        AclMessage::new(Performative::Request)
            .with_conversation_id("s3")
            .with_ontology("IntellWheels-Wheelchair")
            .with_language("fipa-sl0")
            .with_content(
                "((action (agent-identifier :name control) (drive :linear 1e999 :angular 0)))",
            ),
    );
    rig.run(100);
    let got = answers(&rig, "s3");
    assert_eq!(
        got.last().unwrap().0,
        Performative::NotUnderstood,
        "{got:?}"
    );
    // Out of range in the stream: the stream fails and the chair stops at once.
    rig.send(drive(4.0, 0.0).with_conversation_id("s3"));
    rig.run(100);
    let got = answers(&rig, "s3");
    assert_eq!(got.last().unwrap().0, Performative::Failure, "{got:?}");
    assert!(got.last().unwrap().1.contains("out of range"), "{got:?}");
    rig.run(400);
    assert_eq!(
        rig.last_wheels(),
        WheelSpeeds::STOP,
        "stopped by the ramp, not after the watchdog"
    );
}

#[test]
fn a_second_driver_is_refused_strangers_too_and_staff_take_over_with_a_log() {
    let mut rig = rig();
    stream(&mut rig, "mine", 0.4, 0.0, 500);
    rig.send_as("other", drive(0.0, 0.5).with_conversation_id("theirs"));
    rig.send_as("stranger@far", drive(0.2, 0.0).with_conversation_id("far"));
    stream(&mut rig, "mine", 0.4, 0.0, 300);
    let other = rig.answers_to("other");
    assert_eq!(other[0].0, Performative::Refuse, "{other:?}");
    assert!(other[0].1.contains("driven by `probe`"), "{other:?}");
    let stranger = rig.answers_to("stranger@far");
    assert_eq!(stranger[0].0, Performative::Refuse, "{stranger:?}");
    assert!(stranger[0].1.contains("not a driver"), "{stranger:?}");
    // Staff take over: the user's stream fails, staff's is agreed and drives.
    for _ in 0..10 {
        rig.send_as("staff", drive(0.0, 0.6).with_conversation_id("staff-1"));
        rig.run(100);
    }
    let staff = rig.answers_to("staff");
    assert_eq!(staff.len(), 1, "{staff:?}");
    assert_eq!(staff[0].0, Performative::Agree);
    let mine = answers(&rig, "mine");
    assert_eq!(mine.last().unwrap().0, Performative::Failure, "{mine:?}");
    assert!(
        mine.last().unwrap().1.contains("overridden by staff"),
        "{mine:?}"
    );
    let w = rig.last_wheels();
    assert!(w.right_mps > w.left_mps + 0.1, "staff's turn drives: {w:?}");
}

/// Answers in no conversation of the agent's (a pose INFORM outside the subscription, a stray
/// NOT-UNDERSTOOD) get no answer: NOT-UNDERSTOOD for NOT-UNDERSTOOD would never end.
#[test]
fn answers_in_no_conversation_of_ours_are_not_answered() {
    let mut rig = rig();
    rig.run(20);
    rig.send(pose(1.0, 2.0, 0.0));
    rig.send(AclMessage::new(Performative::NotUnderstood).with_conversation_id("nobody-knows"));
    rig.run(50);
    assert_eq!(rig.performatives(), [Performative::Subscribe]);
}

#[test]
fn drive_applied_subscribers_are_told_what_shared_control_applied_while_driven_by_hand() {
    let mut rig = rig();
    let subscribe = |conversation: &str, content: &str| {
        AclMessage::new(Performative::Subscribe)
            .with_protocol("fipa-subscribe")
            .with_ontology(iw_ontology::wheelchair::ONTOLOGY)
            .with_language("fipa-sl0")
            .with_conversation_id(conversation)
            .with_content(content)
    };
    rig.send_as(
        "other",
        subscribe("applied-1", "((drive-applied ?agent ?command))"),
    );
    rig.send_as("staff", subscribe("poses", "((at-pose ?agent ?pose))"));
    rig.run(500);
    assert_eq!(
        rig.answers_to("other"),
        [(Performative::Agree, String::new())]
    );
    let refused = rig.answers_to("staff");
    assert!(
        matches!(refused.as_slice(), [(Performative::Refuse, why)] if why.contains("drive-applied")),
        "{refused:?}"
    );
    let applied = |rig: &Rig| -> Vec<(String, f64, f64)> {
        rig.others_received
            .iter()
            .filter(|(n, m)| n == "other" && m.performative == Performative::Inform)
            .map(|(_, m)| match WheelchairContent::from_message(m) {
                Ok(WheelchairContent::Inform(Fact::Applied {
                    agent,
                    linear_mps,
                    angular_radps,
                })) => (agent.name, linear_mps, angular_radps),
                other => panic!("not a drive-applied inform: {other:?}"),
            })
            .collect()
    };
    // idle: nothing to tell
    assert!(applied(&rig).is_empty());
    stream(&mut rig, "s1", 0.4, 0.0, 1000);
    let told = applied(&rig);
    // every control tick (20 Hz) while driven
    assert!(told.len() >= 15, "{} informs in 1 s", told.len());
    assert!(
        told.iter()
            .all(|(agent, v, w)| agent == "control" && *v > 0.0 && *v <= 0.4 && w.abs() < 1e-9),
        "{told:?}"
    );
    rig.send_as(
        "other",
        AclMessage::new(Performative::Cancel).with_conversation_id("applied-1"),
    );
    rig.run(100);
    let before = applied(&rig).len();
    stream(&mut rig, "s1", 0.4, 0.0, 500);
    assert_eq!(applied(&rig).len(), before, "informed after CANCEL");
}

/// A 181-beam scan of a wall 15 cm ahead of the laser, across the front (beams more than ~78°
/// to the side see nothing).
fn wall_ahead_scan() -> Vec<f64> {
    (0..181)
        .map(|i| {
            let a = (i as f64 - 90.0).to_radians();
            if a.cos() > 0.2 { 0.15 / a.cos() } else { 10.0 }
        })
        .collect()
}

/// A laser at the chair's front, looking ahead over 180°.
fn front_laser() -> LaserMount {
    LaserMount {
        t_body_laser: nalgebra::Isometry2::new(nalgebra::Vector2::new(0.75, 0.0), 0.0),
        fov_rad: std::f64::consts::PI,
        max_range_m: 10.0,
    }
}

/// The mean wheel speed after 1 s facing that wall, with `laser` fitted or not: `start` once,
/// then `each` before every 100 ms.
fn speed_facing_a_wall(
    laser: Option<LaserMount>,
    start: impl FnOnce(&mut Rig),
    mut each: impl FnMut(&mut Rig),
) -> f64 {
    let mut rig = rig_with(|c| c.laser = laser);
    *rig.body.laser_m.lock().unwrap() = wall_ahead_scan();
    start(&mut rig);
    for _ in 0..10 {
        each(&mut rig);
        rig.run(100);
    }
    let w = rig.last_wheels();
    (w.left_mps + w.right_mps) / 2.0
}

#[test]
fn driven_by_hand_a_wall_only_the_laser_sees_holds_the_chair_back() {
    // A laser at the chair's front, 181 beams over 180 degrees, sees a wall 15 cm ahead of the
    // front that no sonar echoes (the ranges stay as the chair does not move).
    let forward = |laser| speed_facing_a_wall(laser, |_| {}, |rig| rig.send(drive(0.4, 0.0)));
    let mount = front_laser();
    let blind = forward(None);
    assert!(
        blind > 0.3,
        "without the laser the wall is not seen: {blind} m/s"
    );
    // held back: slowed (the guard may still let it turn away on a clear arc)
    let seen = forward(Some(mount));
    assert!(
        seen < 0.5 * blind,
        "with the laser the chair is held back: {seen} m/s against {blind} m/s"
    );
}

#[test]
fn a_task_is_held_back_by_a_wall_only_the_laser_sees_too() {
    // The same wall as above, 15 cm ahead of the front, no sonar echo: a go-to straight at it
    // drives on blind, and is held back when the laser is fitted (the tactical layer's path is
    // planned on the map, which need not hold a trolley or a jamb the localizer misplaced).
    let forward = |laser| {
        speed_facing_a_wall(
            laser,
            |rig| {
                rig.send_pose(0.0, 0.0, 0.0);
                rig.send(goto_far("laser-task"));
            },
            |rig| rig.send_pose(0.0, 0.0, 0.0),
        )
    };
    let mount = front_laser();
    let blind = forward(None);
    assert!(
        blind > 0.2,
        "without the laser the task drives on: {blind} m/s"
    );
    let seen = forward(Some(mount));
    assert!(
        seen < 0.5 * blind,
        "with the laser the task is held back: {seen} m/s against {blind} m/s"
    );
}
