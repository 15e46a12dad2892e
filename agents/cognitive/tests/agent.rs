//! The cognitive agent alone on an in-process bus with a mock clock; scripted door, control and
//! watcher agents answer its real ACL requests.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_bus::{MockController, Time};
use iw_cognitive::agent::{
    BUILDING_DOMAIN, BuildingMap, CANCEL_CONFIRM_TIMEOUT, CognitiveAgent, CognitiveConfig,
    DoorPassage, LANDMARK_UNCERTAINTY_M2, LandmarkStop, worst_variance_m2,
};
use iw_cognitive::{Domain, NarrowPassage, OccupancyGrid};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{
    Fact, GoalInFlight, Pose, SensorState, SensorUse, WheelchairAction, WheelchairContent,
};
use nalgebra::{Matrix3, Point2};

type Log = Arc<Mutex<Vec<AclMessage>>>;
type Script = Box<dyn FnMut(&AclMessage) -> Vec<AclMessage> + Send>;

/// Logs what it receives, answers with its script, sends what the test queues.
struct Scripted {
    inbox: Log,
    outbox: Log,
    script: Script,
}

impl Agent for Scripted {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        for reply in (self.script)(&message) {
            ctx.send(reply).unwrap();
        }
        self.inbox.lock().unwrap().push(message);
    }
    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_millis(1))
    }
    fn tick(&mut self, ctx: &mut Context<'_>) {
        for m in self.outbox.lock().unwrap().drain(..) {
            ctx.send(m).unwrap();
        }
    }
}

fn action_of(m: &AclMessage) -> WheelchairAction {
    match WheelchairContent::from_message(m).unwrap() {
        WheelchairContent::Request { action, .. } => action,
        other => panic!("not a request: {other:?}"),
    }
}

fn agree_then(m: &AclMessage, last: Performative) -> Vec<AclMessage> {
    let agree = m.create_reply().with_performative(Performative::Agree);
    let mut end = m.create_reply().with_performative(last);
    if last == Performative::Inform
        && let WheelchairContent::Request { actor, action } =
            WheelchairContent::from_message(m).unwrap()
    {
        end = WheelchairContent::Done { actor, action }.fill(end);
    }
    vec![agree, end]
}

struct Rig {
    host: AgentHost,
    /// The perception stand-in: it gets the pose subscription and sends poses in it.
    perception: (Log, Log),
    clock: MockController,
    user: (Log, Log),
    door: Log,
    control: Log,
    watcher: Log,
}

/// A at the west, B at the east, C in the north; door d1 joins A and B directly, door d2 joins
/// A and C, and C opens onto B; the narrow passage `gap` runs 2 m west to east through d1.
/// A 10 m x 10 m empty floor.
fn rig(door_answers: Script, control_answers: Script) -> Rig {
    rig_with_watcher(door_answers, control_answers, Box::new(|_| Vec::new()))
}

fn rig_with_watcher(door_answers: Script, control_answers: Script, watcher_answers: Script) -> Rig {
    rig_with(
        door_answers,
        control_answers,
        watcher_answers,
        Setup::default(),
    )
}

/// What a rig's map and threshold are.
struct Setup {
    /// The landmark detour's threshold, m².
    uncertainty_m2: f64,
    /// How many of the map's two landmarks it keeps.
    landmarks: usize,
    /// Whether the narrow passage `gap` is on the map (a drive across it stops short of it).
    gap: bool,
}

impl Default for Setup {
    fn default() -> Self {
        Setup {
            uncertainty_m2: 0.5,
            landmarks: 2,
            gap: true,
        }
    }
}

/// A rig whose control agent agrees to every drive and never finishes one, so that the motion
/// under way is re-issued when the chair detours.
fn driving(setup: Setup) -> Rig {
    rig_with(
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(|m| vec![m.create_reply().with_performative(Performative::Agree)]),
        Box::new(|_| Vec::new()),
        setup,
    )
}

fn rig_with(
    door_answers: Script,
    control_answers: Script,
    watcher_answers: Script,
    setup: Setup,
) -> Rig {
    let (mut host, controller) = AgentHost::on_a_mock_clock(Time::from_ns(1_000_000_000));
    let places = [
        ("a", Point2::new(1.0, 5.0)),
        ("b", Point2::new(9.0, 5.0)),
        ("c", Point2::new(5.0, 9.0)),
    ];
    let map = BuildingMap {
        places: places.iter().map(|(n, p)| (n.to_string(), *p)).collect(),
        connections: vec![("c".into(), "b".into())],
        doors: vec![
            DoorPassage {
                name: "d1".into(),
                a: "a".into(),
                b: "b".into(),
                at: Point2::new(5.0, 5.0),
            },
            DoorPassage {
                name: "d2".into(),
                a: "a".into(),
                b: "c".into(),
                at: Point2::new(3.0, 7.0),
            },
        ],
        landmarks: vec![
            LandmarkStop {
                at: Point2::new(2.0, 2.0),
                from: Some(Point2::new(3.0, 2.0)),
            },
            LandmarkStop {
                at: Point2::new(8.0, 8.0),
                from: None,
            },
        ]
        .into_iter()
        .take(setup.landmarks)
        .collect(),
        passages: vec![NarrowPassage {
            name: "gap".into(),
            a: Point2::new(4.0, 5.0),
            b: Point2::new(6.0, 5.0),
            width_m: 1.2,
        }]
        .into_iter()
        .filter(|_| setup.gap)
        .collect(),
    };
    let grid = OccupancyGrid::new(100, 100, 0.1, Point2::origin(), vec![false; 10_000]).unwrap();
    let config = CognitiveConfig {
        chair: "chair1".into(),
        control: AgentId::new("control"),
        door: AgentId::new("door"),
        perception: Some(AgentId::new("perception")),
        watcher: Some(AgentId::new("watcher")),
        pass_wait: Duration::from_secs(5),
        domain: Domain::parse(BUILDING_DOMAIN).unwrap(),
        map,
        grid,
        chair_radius_m: 0.3,
        start_place: "a".into(),
        uncertainty_m2: setup.uncertainty_m2,
        max_states: 10_000,
    };
    host.add(
        AgentId::new("cognitive"),
        Box::new(CognitiveAgent::new(config).unwrap()),
    )
    .unwrap();
    let mut scripted = |name: &str, script: Script| {
        let (inbox, outbox): (Log, Log) = (Arc::default(), Arc::default());
        host.add(
            AgentId::new(name),
            Box::new(Scripted {
                inbox: Arc::clone(&inbox),
                outbox: Arc::clone(&outbox),
                script,
            }),
        )
        .unwrap();
        (inbox, outbox)
    };
    let user = scripted("user", Box::new(|_| Vec::new()));
    let door = scripted("door", door_answers).0;
    let control = scripted("control", control_answers).0;
    let watcher = scripted("watcher", watcher_answers).0;
    let perception = scripted("perception", Box::new(|_| Vec::new()));
    Rig {
        perception,
        host,
        clock: controller,
        user,
        door,
        control,
        watcher,
    }
}

impl Rig {
    fn goal(&self, place: &str) {
        let goal = WheelchairContent::Request {
            actor: AgentId::new("cognitive"),
            action: WheelchairAction::GoTo {
                place: place.into(),
            },
        };
        let m = goal.fill(
            AclMessage::new(Performative::Request)
                .with_receiver(AgentId::new("cognitive"))
                .with_protocol("fipa-request")
                .with_conversation_id("goal-1"),
        );
        self.user.1.lock().unwrap().push(m);
    }
    /// Sends `pose` as the perception agent does: a notification in the agent's subscription.
    fn pose(&self, pose: Fact) {
        let inbox = self.perception.0.lock().unwrap();
        let subscription = inbox
            .iter()
            .find(|m| m.performative == Performative::Subscribe)
            .expect("the cognitive agent subscribes to its pose at setup");
        let notification = WheelchairContent::Inform(pose).fill(
            subscription
                .create_reply()
                .with_performative(Performative::Inform),
        );
        self.perception.1.lock().unwrap().push(notification);
    }
    /// What the cognitive agent sent the watcher, in order.
    fn watcher_acts(&self) -> Vec<Performative> {
        let sent = self.watcher.lock().unwrap();
        sent.iter().map(|m| m.performative).collect()
    }
    fn run(&mut self, steps: usize) {
        for _ in 0..steps {
            self.host.step(self.clock.now());
            self.clock.advance(Duration::from_millis(10));
        }
    }
}

fn waypoints(action: &WheelchairAction) -> Vec<(f64, f64)> {
    let WheelchairAction::Sequence { steps } = action else {
        panic!("not a sequence: {action:?}")
    };
    steps
        .iter()
        .map(|s| match s {
            WheelchairAction::GotoXy { x_m, y_m } => (*x_m, *y_m),
            other => panic!("{other:?}"),
        })
        .collect()
}

#[test]
fn a_refused_door_makes_it_replan_through_the_other_door() {
    let doors: Script = Box::new(|m| match action_of(m) {
        WheelchairAction::OpenDoor { door } if door == "d1" => {
            vec![m.create_reply().with_performative(Performative::Refuse)]
        }
        _ => agree_then(m, Performative::Inform),
    });
    let mut rig = rig(doors, Box::new(|m| agree_then(m, Performative::Inform)));
    rig.goal("b");
    rig.run(20);
    let door_requests: Vec<_> = rig.door.lock().unwrap().iter().map(action_of).collect();
    assert_eq!(
        door_requests,
        [
            WheelchairAction::OpenDoor { door: "d1".into() },
            WheelchairAction::OpenDoor { door: "d2".into() }
        ]
    );
    let control: Vec<_> = rig.control.lock().unwrap().iter().map(action_of).collect();
    assert_eq!(
        control.len(),
        2,
        "pass d2 to c, then move to b (not through the gap): {control:?}"
    );
    let first = waypoints(&control[0]);
    assert!(
        first
            .iter()
            .any(|p| (p.0 - 3.0).abs() < 0.11 && (p.1 - 7.0).abs() < 0.11),
        "through d2's doorway: {first:?}"
    );
    assert_eq!(*first.last().unwrap(), (5.0, 9.0));
    assert_eq!(*waypoints(&control[1]).last().unwrap(), (9.0, 5.0));
    let user = rig.user.0.lock().unwrap();
    let answers: Vec<_> = user.iter().map(|m| m.performative).collect();
    assert_eq!(answers, [Performative::Agree, Performative::Inform]);
    assert_eq!(
        WheelchairContent::from_message(&user[1]).unwrap(),
        WheelchairContent::Done {
            actor: AgentId::new("cognitive"),
            action: WheelchairAction::GoTo { place: "b".into() }
        }
    );
}

#[test]
fn no_route_left_is_a_failure_and_unknown_places_are_refused() {
    let refuse_all: Script =
        Box::new(|m| vec![m.create_reply().with_performative(Performative::Refuse)]);
    let blocked: Script = Box::new(|m| agree_then(m, Performative::Failure));
    let mut rig = rig(refuse_all, blocked);
    rig.goal("nowhere");
    rig.run(5);
    rig.goal("b");
    rig.run(20);
    let user = rig.user.0.lock().unwrap();
    let answers: Vec<_> = user.iter().map(|m| m.performative).collect();
    assert_eq!(
        answers,
        [
            Performative::Refuse,
            Performative::Agree,
            Performative::Failure
        ]
    );
    assert_eq!(rig.door.lock().unwrap().len(), 2, "both doors tried");
}

#[test]
fn growing_uncertainty_routes_the_chair_past_the_nearest_landmark() {
    // The control agent agrees and never finishes, so the first motion stays pending.
    let mut rig = rig(
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(|m| vec![m.create_reply().with_performative(Performative::Agree)]),
    );
    rig.goal("b");
    rig.run(10);
    let pose = |var: f64| Fact::AtPose {
        agent: AgentId::new("chair1"),
        pose: Pose {
            x_m: 2.5,
            y_m: 4.0,
            theta_rad: 0.0,
            covariance: Matrix3::from_diagonal_element(var),
        },
    };
    rig.pose(pose(0.01));
    rig.run(10);
    assert_eq!(
        rig.control.lock().unwrap().len(),
        1,
        "small uncertainty: no detour"
    );
    rig.pose(pose(1.0));
    rig.run(10);
    let control = rig.control.lock().unwrap();
    assert_eq!(control.len(), 2, "re-issued via a landmark");
    let detour = waypoints(&action_of(&control[1]));
    let at = |p: (f64, f64)| detour.iter().position(|q| *q == p);
    // in on the marker's axis: its approach point, then the landmark, then on
    assert!(
        matches!((at((3.0, 2.0)), at((2.0, 2.0))), (Some(a), Some(b)) if a < b),
        "nearest landmark first, from its approach point: {detour:?}"
    );
    assert!(!waypoints(&action_of(&control[0])).contains(&(2.0, 2.0)));
}

/// A pose at (2.5, 4) whose x-y covariance has variances `major_m2` and `minor_m2` along axes
/// turned `angle_rad` from the map's.
fn elongated(major_m2: f64, minor_m2: f64, angle_rad: f64) -> Fact {
    let r = nalgebra::Rotation2::new(angle_rad).into_inner();
    let xy = r * nalgebra::Matrix2::new(major_m2, 0.0, 0.0, minor_m2) * r.transpose();
    let mut covariance = Matrix3::from_diagonal_element(1e-4);
    covariance.fixed_view_mut::<2, 2>(0, 0).copy_from(&xy);
    Fact::AtPose {
        agent: AgentId::new("chair1"),
        pose: Pose {
            x_m: 2.5,
            y_m: 4.0,
            theta_rad: 0.0,
            covariance,
        },
    }
}

#[test]
fn the_detour_is_decided_on_the_worst_direction_not_the_trace() {
    let mut rig = driving(Setup {
        uncertainty_m2: LANDMARK_UNCERTAINTY_M2,
        ..Setup::default()
    });
    rig.goal("b");
    rig.run(10);
    // round, 8.9 cm each way: a trace of 0.016 m², but no direction past 0.01 m²
    rig.pose(elongated(0.008, 0.008, 0.0));
    rig.run(10);
    assert_eq!(rig.control.lock().unwrap().len(), 1, "round: no detour");
    // long and thin along a corridor turned 30 degrees: a trace of 0.0124 m² (under the trace's
    // old 0.04 m²), x and y variances each under 0.01 m², but 11 cm along the axis
    rig.pose(elongated(0.012, 0.0004, 30f64.to_radians()));
    rig.run(10);
    let control = rig.control.lock().unwrap();
    assert_eq!(control.len(), 2, "elongated: re-issued via a landmark");
    assert!(via_the_landmark(&control[1]));
}

#[test]
fn the_worst_variance_is_the_larger_eigenvalue_and_nan_stays_nan() {
    let Fact::AtPose { pose, .. } = elongated(0.012, 0.0004, 30f64.to_radians()) else {
        unreachable!()
    };
    assert!((worst_variance_m2(&pose) - 0.012).abs() < 1e-12);
    let Fact::AtPose { mut pose, .. } = pose_at(0.0, 0.0, 0.003) else {
        unreachable!()
    };
    assert!((worst_variance_m2(&pose) - 0.003).abs() < 1e-15);
    // a sender's not quite symmetric matrix counts by its symmetric part
    pose.covariance[(0, 1)] = 0.002;
    assert!((worst_variance_m2(&pose) - 0.004).abs() < 1e-12);
    pose.covariance[(1, 1)] = f64::NAN;
    assert!(worst_variance_m2(&pose).is_nan());
}

/// Whether `request` to the control agent goes past the test map's nearest landmark, coming
/// in on the marker's axis (its approach point, then the landmark).
fn via_the_landmark(request: &AclMessage) -> bool {
    let points = waypoints(&action_of(request));
    let at = |p: (f64, f64)| points.iter().position(|q| *q == p);
    matches!((at((3.0, 2.0)), at((2.0, 2.0))), (Some(a), Some(b)) if a < b)
}

/// The perception agent's word on a range sensor (`laser` or `sonars`).
fn sensor(name: &str, usage: SensorUse) -> Fact {
    Fact::Sensor {
        agent: AgentId::new("chair1"),
        state: SensorState {
            sensor: name.into(),
            usage,
            reason: "silent: no readings".into(),
        },
    }
}

fn pose_at(x_m: f64, y_m: f64, var: f64) -> Fact {
    Fact::AtPose {
        agent: AgentId::new("chair1"),
        pose: Pose {
            x_m,
            y_m,
            theta_rad: 0.0,
            covariance: Matrix3::from_diagonal_element(var),
        },
    }
}

#[test]
fn a_silent_laser_routes_the_chair_past_a_landmark_once() {
    // The control agent agrees and never finishes, so the motion stays pending.
    let mut rig = rig(
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(|m| vec![m.create_reply().with_performative(Performative::Agree)]),
    );
    rig.goal("b");
    rig.run(10);
    rig.pose(pose_at(2.5, 4.0, 0.0001));
    rig.run(10);
    rig.pose(sensor("laser", SensorUse::InUse));
    rig.run(10);
    assert_eq!(
        rig.control.lock().unwrap().len(),
        1,
        "a laser in use: no detour"
    );
    // dropped sonars leave the laser to localize: no detour either
    rig.pose(sensor("sonars", SensorUse::Dropped));
    rig.run(10);
    rig.pose(sensor("sonars", SensorUse::InUse));
    rig.run(10);
    assert_eq!(
        rig.control.lock().unwrap().len(),
        1,
        "dropped sonars: no detour"
    );
    rig.pose(sensor("laser", SensorUse::Dropped));
    rig.run(10);
    {
        let control = rig.control.lock().unwrap();
        assert_eq!(control.len(), 2, "re-issued via a landmark");
        assert!(
            via_the_landmark(&control[1]),
            "{:?}",
            waypoints(&action_of(&control[1]))
        );
        assert!(!via_the_landmark(&control[0]));
    }
    // told again (a new subscription, a repeat): the chair is on its way already
    rig.pose(sensor("laser", SensorUse::Dropped));
    rig.run(10);
    assert_eq!(rig.control.lock().unwrap().len(), 2);
}

/// Whether `request` to the control agent goes past the test map's other landmark, (8, 8).
fn via_the_far_landmark(request: &AclMessage) -> bool {
    waypoints(&action_of(request)).contains(&(8.0, 8.0))
}

#[test]
fn past_its_landmark_a_chair_detours_again_elsewhere_never_back_to_it() {
    // no passage on the way to the far landmark, where a drive would stop to ask the watcher
    let mut rig = driving(Setup {
        gap: false,
        ..Setup::default()
    });
    rig.goal("b");
    rig.run(10);
    rig.pose(pose_at(2.5, 4.0, 1.0));
    rig.run(10);
    assert_eq!(
        rig.control.lock().unwrap().len(),
        2,
        "re-issued via a landmark"
    );
    assert!(via_the_landmark(&rig.control.lock().unwrap()[1]));
    // at the landmark the marker is read: the uncertainty drops, and counts from there
    rig.pose(pose_at(2.1, 2.0, 0.3));
    rig.run(5);
    rig.pose(pose_at(2.2, 2.1, 0.01));
    rig.run(5);
    // the same drive goes on; 0.5 m² more than at the landmark is past the threshold
    rig.pose(pose_at(2.6, 2.6, 0.3));
    rig.run(10);
    assert_eq!(
        rig.control.lock().unwrap().len(),
        2,
        "0.29 m² more: no detour"
    );
    // a few metres on the error grows fast again (a dropped laser): the landmark just behind is
    // still the shortest detour, but going back there would shuttle the chair between the two
    // points for ever; it goes on, past the other one
    rig.pose(pose_at(3.0, 3.0, 0.6));
    rig.run(10);
    {
        let control = rig.control.lock().unwrap();
        assert_eq!(control.len(), 3, "0.59 m² more: via a landmark again");
        let points = waypoints(&action_of(&control[2]));
        assert!(
            !via_the_landmark(&control[2]) && !points.contains(&(2.0, 2.0)),
            "back to the landmark visited last: {points:?}"
        );
        assert!(via_the_far_landmark(&control[2]), "{points:?}");
    }
    // at the far one, and past it: the next detour may go back to the first (no longer the last)
    rig.pose(pose_at(8.0, 8.0, 0.01));
    rig.run(10);
    rig.pose(pose_at(7.0, 7.0, 0.8));
    rig.run(10);
    let control = rig.control.lock().unwrap();
    assert_eq!(control.len(), 4, "0.79 m² more: via a landmark again");
    assert!(!via_the_far_landmark(&control[3]));
    assert!(via_the_landmark(&control[3]));
}

#[test]
fn with_one_landmark_a_chair_visited_it_goes_on_without_a_detour() {
    let mut rig = driving(Setup {
        landmarks: 1,
        ..Setup::default()
    });
    rig.goal("b");
    rig.run(10);
    rig.pose(pose_at(2.5, 4.0, 1.0));
    rig.run(10);
    assert!(via_the_landmark(&rig.control.lock().unwrap()[1]));
    rig.pose(pose_at(2.1, 2.0, 0.01));
    rig.run(10);
    rig.pose(pose_at(3.0, 3.0, 1.0));
    rig.run(10);
    assert_eq!(
        rig.control.lock().unwrap().len(),
        2,
        "the only landmark is the one just visited: no detour back to it"
    );
}

/// A rig whose goal `b` lies through the gap, the watcher answering with `watcher`: the
/// control agent finishes the drive to the wait point, then keeps driving.
fn through_the_gap(watcher: Script) -> Rig {
    let mut drives = 0;
    let mut rig = rig_with_watcher(
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(move |m| {
            drives += 1;
            if drives == 1 {
                agree_then(m, Performative::Inform)
            } else {
                vec![m.create_reply().with_performative(Performative::Agree)]
            }
        }),
        watcher,
    );
    rig.goal("b");
    rig.run(20);
    rig
}

/// A pose 0.8 m past the gap: the chair is clear of it.
fn clear_of_the_gap(rig: &mut Rig) {
    rig.pose(Fact::AtPose {
        agent: AgentId::new("chair1"),
        pose: Pose {
            x_m: 6.7,
            y_m: 5.0,
            theta_rad: 0.0,
            covariance: Matrix3::zeros(),
        },
    });
    rig.run(5);
}

#[test]
fn a_passage_is_waited_for_driven_through_and_released_once_clear() {
    let mut rig = through_the_gap(Box::new(|m| {
        if m.performative == Performative::Subscribe {
            agree_then(m, Performative::Inform)
        } else {
            Vec::new()
        }
    }));
    let control: Vec<_> = rig
        .control
        .lock()
        .unwrap()
        .iter()
        .map(|m| waypoints(&action_of(m)))
        .collect();
    assert_eq!(
        control.len(),
        2,
        "to the wait point, then through the gap and on to b without stopping: {control:?}"
    );
    let wait = control[0].last().unwrap();
    assert!(
        (wait.0 - 3.0).abs() < 0.1 && (wait.1 - 5.0).abs() < 0.1,
        "stops 1 m before the gap: {control:?}"
    );
    assert_eq!(*control[1].last().unwrap(), (9.0, 5.0));
    let pass = WheelchairAction::Pass {
        passage: "gap".into(),
        direction: "forward".into(),
    };
    let asked = |rig: &Rig| -> Vec<_> {
        rig.watcher
            .lock()
            .unwrap()
            .iter()
            .map(|m| (m.performative, action_of(m)))
            .collect()
    };
    assert_eq!(
        asked(&rig),
        [(Performative::Subscribe, pass.clone())],
        "granted, not yet released"
    );
    clear_of_the_gap(&mut rig);
    assert_eq!(
        asked(&rig),
        [
            (Performative::Subscribe, pass.clone()),
            (Performative::Cancel, pass)
        ]
    );
    let watcher = rig.watcher.lock().unwrap();
    assert_eq!(
        watcher[0].conversation_id, watcher[1].conversation_id,
        "the cancel releases that grant"
    );
}

/// A `MakeWriter` that keeps what the agent logs, for a test to read.
#[derive(Clone, Default)]
struct Logged(Arc<Mutex<Vec<u8>>>);

impl std::io::Write for Logged {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(bytes);
        Ok(bytes.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for Logged {
    type Writer = Logged;
    fn make_writer(&'a self) -> Logged {
        self.clone()
    }
}

/// The chair waits for the watcher's confirmation of its CANCEL (the cancel's inform-done,
/// FIPA's cancel meta-protocol): a confirmed release is quiet, a missing confirmation is logged
/// once [`CANCEL_CONFIRM_TIMEOUT`] has passed; the passage is let go at once either way.
#[test]
fn a_release_waits_for_the_watchers_confirmation_and_a_missing_one_is_logged() {
    for confirms in [true, false] {
        let logged = Logged::default();
        let subscriber = tracing_subscriber::fmt()
            .with_max_level(tracing::Level::DEBUG)
            .with_ansi(false)
            .with_writer(logged.clone())
            .finish();
        tracing::subscriber::with_default(subscriber, || {
            let mut rig = through_the_gap(Box::new(move |m| match m.performative {
                Performative::Subscribe => agree_then(m, Performative::Inform),
                Performative::Cancel if confirms => {
                    let WheelchairContent::Request { actor, action } =
                        WheelchairContent::from_message(m).unwrap()
                    else {
                        panic!("a CANCEL names the action: {m:?}");
                    };
                    vec![
                        WheelchairContent::Cancelled { actor, action }
                            .fill(m.create_reply().with_performative(Performative::Inform)),
                    ]
                }
                _ => Vec::new(),
            }));
            clear_of_the_gap(&mut rig);
            assert_eq!(
                rig.watcher_acts(),
                [Performative::Subscribe, Performative::Cancel]
            );
            // half the wait, then past it
            let half = CANCEL_CONFIRM_TIMEOUT / 2;
            rig.run((half.as_millis() / 10) as usize);
            let text = String::from_utf8(logged.0.lock().unwrap().clone()).unwrap();
            assert!(!text.contains("no confirmation of the release"), "{text}");
            assert_eq!(
                text.contains("the watcher confirmed the release"),
                confirms,
                "{text}"
            );
            rig.run((half.as_millis() / 10) as usize + 50);
        });
        let text = String::from_utf8(logged.0.lock().unwrap().clone()).unwrap();
        assert_eq!(
            text.matches("no confirmation of the release").count(),
            usize::from(!confirms),
            "{text}"
        );
        assert!(!text.contains("answer to an abandoned step"), "{text}");
    }
}

#[test]
fn a_grant_taken_back_ends_the_subscription_and_is_not_released_again() {
    // The watcher grants, then takes the grant back at once (its lease ran out): a FAILURE in
    // the subscription, which fipa-subscribe allows after a notification.
    let mut rig = through_the_gap(Box::new(|m| {
        if m.performative != Performative::Subscribe {
            return Vec::new();
        }
        let mut answers = agree_then(m, Performative::Inform);
        answers.push(
            WheelchairContent::error("lease expired")
                .fill(m.create_reply().with_performative(Performative::Failure)),
        );
        answers
    }));
    assert_eq!(
        rig.control.lock().unwrap().len(),
        2,
        "drove through on the grant"
    );
    clear_of_the_gap(&mut rig);
    assert_eq!(
        rig.watcher_acts(),
        [Performative::Subscribe],
        "a grant the watcher ended is not cancelled"
    );
}

#[test]
fn a_silent_watcher_is_given_up_on_and_the_chair_goes_on() {
    // The watcher agrees and never grants: the chair waits at the gap for `pass_wait` (5 s).
    let mut rig = rig_with_watcher(
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(|m| {
            if m.performative == Performative::Subscribe {
                vec![m.create_reply().with_performative(Performative::Agree)]
            } else {
                Vec::new()
            }
        }),
    );
    rig.goal("b");
    rig.run(300);
    assert_eq!(
        rig.control.lock().unwrap().len(),
        1,
        "still waiting before the gap after 3 s"
    );
    rig.run(300);
    assert_eq!(rig.control.lock().unwrap().len(), 2, "gone on after 5 s");
    assert_eq!(
        rig.watcher_acts(),
        [Performative::Subscribe, Performative::Cancel],
        "left the queue"
    );
    let answers: Vec<_> = rig
        .user
        .0
        .lock()
        .unwrap()
        .iter()
        .map(|m| m.performative)
        .collect();
    assert_eq!(answers, [Performative::Agree, Performative::Inform]);
}

/// FAILURE `((body-fault ...))` from the control agent: what a chair's control agent answers
/// while its world link is down.
fn body_fault(m: &AclMessage) -> Vec<AclMessage> {
    let agree = m.create_reply().with_performative(Performative::Agree);
    let failure = WheelchairContent::body_fault("body: no sensor frame from the world")
        .fill(m.create_reply().with_performative(Performative::Failure));
    vec![agree, failure]
}

fn answers(rig: &Rig) -> Vec<(Performative, String)> {
    rig.user
        .0
        .lock()
        .unwrap()
        .iter()
        .map(|m| {
            let reason = WheelchairContent::from_message(m)
                .ok()
                .and_then(|c| c.reason().map(str::to_string))
                .unwrap_or_default();
            (m.performative, reason)
        })
        .collect()
}

#[test]
fn a_body_fault_fails_the_goal_at_once_with_the_body_reason_and_no_re_plan() {
    let mut rig = rig(
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(body_fault),
    );
    rig.goal("c");
    rig.run(600);
    let got = answers(&rig);
    assert_eq!(got.len(), 2, "{got:?}");
    assert_eq!(got[1].0, Performative::Failure);
    assert!(
        got[1].1.contains("body failed") && got[1].1.contains("no sensor frame"),
        "{got:?}"
    );
    assert_eq!(rig.control.lock().unwrap().len(), 1, "not asked again");
    assert_eq!(rig.door.lock().unwrap().len(), 1, "not re-planned");
}

/// The user asks the cognitive agent what it is doing, as the services do when a chair joins.
fn ask_goal(rig: &Rig, about: &str, conversation: &str) {
    let query = WheelchairContent::GoalQuery {
        agent: AgentId::new(about),
    }
    .fill(
        AclMessage::new(Performative::QueryRef)
            .with_receiver(AgentId::new("cognitive"))
            .with_conversation_id(conversation),
    );
    rig.user.1.lock().unwrap().push(query);
}

/// The user's answers in conversation `conversation`.
fn answered_in(rig: &Rig, conversation: &str) -> Vec<AclMessage> {
    rig.user
        .0
        .lock()
        .unwrap()
        .iter()
        .filter(|m| m.conversation_id.as_deref() == Some(conversation))
        .cloned()
        .collect()
}

/// The goal under way and the ended one an answer tells.
fn told(m: &AclMessage) -> (Option<GoalInFlight>, Option<GoalInFlight>) {
    assert_eq!(m.performative, Performative::Inform, "{m:?}");
    match WheelchairContent::from_message(m).unwrap() {
        WheelchairContent::Inform(Fact::CurrentGoal { agent, goal, ended }) => {
            assert_eq!(agent.name, "cognitive");
            (goal.map(|g| *g), ended.map(|g| *g))
        }
        other => panic!("not a current goal: {other:?}"),
    }
}

fn current_goal(m: &AclMessage) -> Option<GoalInFlight> {
    told(m).0
}

#[test]
fn a_goal_query_is_answered_with_the_goal_under_way_its_requester_and_conversation() {
    // The door agent never answers: the goal stays under way.
    let mut rig = rig(Box::new(|_| Vec::new()), Box::new(|_| Vec::new()));
    ask_goal(&rig, "cognitive", "q-idle");
    rig.run(20);
    let idle = answered_in(&rig, "q-idle");
    assert_eq!(idle.len(), 1, "{idle:?}");
    assert_eq!(current_goal(&idle[0]), None);

    rig.goal("c");
    rig.run(20);
    ask_goal(&rig, "cognitive", "q-busy");
    ask_goal(&rig, "cognitive@elsewhere", "q-other");
    rig.run(20);
    let busy = answered_in(&rig, "q-busy");
    assert_eq!(busy.len(), 1, "{busy:?}");
    assert_eq!(
        current_goal(&busy[0]),
        Some(GoalInFlight {
            place: "c".into(),
            requester: AgentId::new("user"),
            conversation: "goal-1".into(),
            outcome: None,
        })
    );
    let other = answered_in(&rig, "q-other");
    assert_eq!(other.len(), 1, "{other:?}");
    assert_eq!(
        other[0].performative,
        Performative::Refuse,
        "{:?}",
        other[0]
    );

    // A query that is not one is not understood, and the goal runs on.
    let bad = AclMessage::new(Performative::QueryRef)
        .with_receiver(AgentId::new("cognitive"))
        .with_conversation_id("q-bad")
        .with_ontology(iw_ontology::wheelchair::ONTOLOGY)
        .with_language("fipa-sl0")
        .with_content("((current-goal");
    rig.user.1.lock().unwrap().push(bad);
    rig.run(20);
    let bad = answered_in(&rig, "q-bad");
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert_eq!(bad[0].performative, Performative::NotUnderstood);
    ask_goal(&rig, "cognitive", "q-still");
    rig.run(20);
    let still = answered_in(&rig, "q-still");
    assert_eq!(current_goal(&still[0]).map(|g| g.place), Some("c".into()));
}

/// A goal that ended (its answer may have gone to a requester that is gone) is told, with its
/// outcome, once to each agent that asks: the services' query on a join does not take it from
/// the assistant's check of a goal it forwarded.
#[test]
fn a_goal_that_ended_is_told_once_to_each_agent_with_its_outcome() {
    let mut rig = rig(
        Box::new(|m| agree_then(m, Performative::Inform)),
        Box::new(body_fault),
    );
    rig.goal("c");
    rig.run(600);
    ask_goal(&rig, "cognitive", "q-1");
    ask_goal(&rig, "cognitive", "q-2");
    rig.run(20);
    let (goal, ended) = told(&answered_in(&rig, "q-1")[0]);
    assert_eq!(goal, None);
    let ended = ended.expect("the failed goal is told");
    assert_eq!(
        (ended.place.as_str(), ended.conversation.as_str()),
        ("c", "goal-1")
    );
    let Some(Err(why)) = &ended.outcome else {
        panic!("{ended:?}")
    };
    assert!(why.contains("body failed"), "{why}");
    assert_eq!(
        told(&answered_in(&rig, "q-2")[0]),
        (None, None),
        "told once to the user"
    );
    // another agent asks after the user was told: it is told too, once
    for conversation in ["p-1", "p-2"] {
        let query = WheelchairContent::GoalQuery {
            agent: AgentId::new("cognitive"),
        }
        .fill(
            AclMessage::new(Performative::QueryRef)
                .with_receiver(AgentId::new("cognitive"))
                .with_conversation_id(conversation),
        );
        rig.perception.1.lock().unwrap().push(query);
    }
    rig.run(20);
    let answers = rig.perception.0.lock().unwrap().clone();
    let answer = |conversation: &str| {
        let found = answers
            .iter()
            .find(|m| m.conversation_id.as_deref() == Some(conversation))
            .unwrap_or_else(|| panic!("no answer in {conversation}: {answers:?}"));
        told(found)
    };
    let (_, ended) = answer("p-1");
    assert_eq!(
        ended.map(|g| g.conversation),
        Some("goal-1".to_string()),
        "another agent is told the ended goal"
    );
    assert_eq!(answer("p-2"), (None, None), "told once to that agent");
}
