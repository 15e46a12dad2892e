//! The wheelchair ontology: every value survives value -> SL text -> value, and the SL it
//! produces is what the documentation shows.

use iw_acl::AgentId;
use iw_ontology::wheelchair::{
    DoorState, Fact, GoalInFlight, Pose, SensorReading, SensorState, SensorUse, WheelchairAction,
    WheelchairContent,
};
use iw_ontology::{Concept, OntologyError};
use nalgebra::Matrix3;
use proptest::prelude::*;

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e6..1e6f64,
        any::<f64>().prop_filter("finite", |x| x.is_finite())
    ]
}

fn name() -> impl Strategy<Value = String> {
    prop_oneof!["[a-z][a-z0-9-]{0,10}", "[ -~]{1,12}[ -\\[\\]-~]"]
}

fn agent() -> impl Strategy<Value = AgentId> {
    (
        "[a-z][a-z0-9]{0,6}@[A-Z][a-zA-Z]{0,6}",
        prop::collection::vec("http://[a-z0-9.:]{1,12}/acc", 0..2),
    )
        .prop_map(|(n, addrs)| {
            addrs
                .into_iter()
                .fold(AgentId::new(n), AgentId::with_address)
        })
}

fn pose() -> impl Strategy<Value = Pose> {
    (
        finite(),
        finite(),
        -4.0..4.0f64,
        prop::array::uniform9(finite()),
    )
        .prop_map(|(x, y, t, c)| Pose {
            x_m: x,
            y_m: y,
            theta_rad: t,
            covariance: Matrix3::from_row_slice(&c),
        })
}

fn action() -> impl Strategy<Value = WheelchairAction> {
    let leaf = prop_oneof![
        (finite(), finite()).prop_map(|(x_m, y_m)| WheelchairAction::GotoXy { x_m, y_m }),
        name().prop_map(|place| WheelchairAction::GoTo { place }),
        Just(WheelchairAction::FollowLine),
        finite().prop_map(|distance_m| WheelchairAction::FollowLeftWall { distance_m }),
        finite().prop_map(|distance_m| WheelchairAction::FollowRightWall { distance_m }),
        finite().prop_map(|angle_rad| WheelchairAction::Spin { angle_rad }),
        any::<i64>().prop_map(|duration_ms| WheelchairAction::Wait { duration_ms }),
        Just(WheelchairAction::Stop),
        (finite(), finite()).prop_map(|(linear_mps, angular_radps)| WheelchairAction::Drive {
            linear_mps,
            angular_radps
        }),
        name().prop_map(|door| WheelchairAction::OpenDoor { door }),
        name().prop_map(|door| WheelchairAction::CloseDoor { door }),
        (name(), name())
            .prop_map(|(passage, direction)| WheelchairAction::Pass { passage, direction }),
    ];
    leaf.prop_recursive(3, 16, 4, |inner| {
        prop::collection::vec(inner, 0..4).prop_map(|steps| WheelchairAction::Sequence { steps })
    })
}

fn fact() -> impl Strategy<Value = Fact> {
    prop_oneof![
        (agent(), pose()).prop_map(|(agent, pose)| Fact::AtPose { agent, pose }),
        (agent(), prop::collection::vec(0.0..10.0f64, 0..24)).prop_map(|(agent, ranges_m)| {
            Fact::Reading {
                agent,
                reading: SensorReading::Sonar { ranges_m },
            }
        }),
        (agent(), any::<i64>(), any::<i64>()).prop_map(|(agent, left_ticks, right_ticks)| {
            Fact::Reading {
                agent,
                reading: SensorReading::Encoders {
                    left_ticks,
                    right_ticks,
                },
            }
        }),
        (
            name(),
            prop_oneof![
                Just(DoorState::Open),
                Just(DoorState::Closed),
                Just(DoorState::Opening),
                Just(DoorState::Closing)
            ]
        )
            .prop_map(|(door, state)| Fact::Door { door, state }),
        (
            agent(),
            name(),
            prop_oneof![Just(SensorUse::InUse), Just(SensorUse::Dropped)],
            "[ -~]{0,40}"
        )
            .prop_map(|(agent, sensor, usage, reason)| Fact::Sensor {
                agent,
                state: SensorState {
                    sensor,
                    usage,
                    reason,
                },
            }),
        "[ -~]{0,40}".prop_map(|reason| Fact::ErrorMessage { reason }),
        "[ -~]{0,40}".prop_map(|reason| Fact::BodyFault { reason }),
        (agent(), finite(), finite()).prop_map(|(agent, linear_mps, angular_radps)| {
            Fact::Applied {
                agent,
                linear_mps,
                angular_radps,
            }
        }),
        (
            agent(),
            prop::option::of((name(), agent(), name())),
            prop::option::of((
                name(),
                agent(),
                name(),
                prop::result::maybe_ok(Just(()), "[ -~]{0,40}")
            )),
        )
            .prop_map(|(agent, goal, ended)| Fact::CurrentGoal {
                agent,
                goal: goal.map(|(place, requester, conversation)| {
                    Box::new(GoalInFlight {
                        place,
                        requester,
                        conversation,
                        outcome: None,
                    })
                }),
                ended: ended.map(|(place, requester, conversation, outcome)| {
                    Box::new(GoalInFlight {
                        place,
                        requester,
                        conversation,
                        outcome: Some(outcome),
                    })
                }),
            }),
    ]
}

fn content() -> impl Strategy<Value = WheelchairContent> {
    prop_oneof![
        (agent(), action())
            .prop_map(|(actor, action)| WheelchairContent::Request { actor, action }),
        (agent(), action()).prop_map(|(actor, action)| WheelchairContent::Done { actor, action }),
        (agent(), action())
            .prop_map(|(actor, action)| WheelchairContent::Cancelled { actor, action }),
        fact().prop_map(WheelchairContent::Inform),
        agent().prop_map(|agent| WheelchairContent::GoalQuery { agent }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn every_message_round_trips_through_sl_text(msg in content()) {
        let text = msg.to_content().to_string();
        prop_assert_eq!(WheelchairContent::parse(&text), Ok(msg), "{}", text);
    }

    /// A `drive` as another implementation may write it: either slot order, any case, integer
    /// or decimal speeds; it reads as the speeds written.
    #[test]
    fn drive_text_reads_back_in_any_slot_order_and_case(
        linear in -10i32..10,
        linear_frac in 0u32..1000,
        angular in finite(),
        swapped in any::<bool>(),
        upper in any::<bool>(),
    ) {
        let linear_mps = f64::from(linear) + f64::from(linear_frac) / 1000.0;
        let linear_text = if linear_frac == 0 { linear.to_string() } else { format!("{linear_mps}") };
        let angular_text = iw_sl::Term::float(angular).to_string();
        let (a, b) = (format!(":linear {linear_text}"), format!(":angular {angular_text}"));
        let slots = if swapped { format!("{b} {a}") } else { format!("{a} {b}") };
        let verb = if upper { "DRIVE" } else { "drive" };
        let text = format!("((action (agent-identifier :name control@c) ({verb} {slots})))");
        let read = WheelchairContent::parse(&text);
        prop_assert!(
            matches!(
                read,
                Ok(WheelchairContent::Request {
                    action: WheelchairAction::Drive { linear_mps: l, angular_radps: w },
                    ..
                }) if l == linear_text.parse::<f64>().unwrap() && w == angular
            ),
            "{} read as {:?}", text, read
        );
    }

    /// A `drive` with one character deleted, inserted or replaced anywhere reads as an error or
    /// as a value that prints and reads back the same (a drive's speeds finite); it never panics.
    #[test]
    fn edited_drive_text_is_an_error_or_a_value_that_round_trips(
        linear in finite(),
        angular in finite(),
        at in any::<prop::sample::Index>(),
        edit in 0u8..3,
        ch in prop_oneof![Just('('), Just(')'), Just(':'), Just(' '), Just('-'), Just('e'), Just('.'), any::<char>()],
    ) {
        let text = WheelchairContent::Request {
            actor: AgentId::new("control@c"),
            action: WheelchairAction::Drive { linear_mps: linear, angular_radps: angular },
        }
        .to_content()
        .to_string();
        let mut chars: Vec<char> = text.chars().collect();
        let i = at.index(chars.len());
        match edit {
            0 => { chars.remove(i); }
            1 => chars.insert(i, ch),
            _ => chars[i] = ch,
        }
        let edited: String = chars.into_iter().collect();
        if let Ok(content) = WheelchairContent::parse(&edited) {
            if let WheelchairContent::Request {
                action: WheelchairAction::Drive { linear_mps, angular_radps },
                ..
            } = &content
            {
                prop_assert!(linear_mps.is_finite() && angular_radps.is_finite(), "{}", edited);
            }
            let printed = content.to_content().to_string();
            prop_assert_eq!(WheelchairContent::parse(&printed), Ok(content), "{} -> {}", edited, printed);
        }
    }

    #[test]
    fn poses_round_trip_as_terms(p in pose()) {
        prop_assert_eq!(Pose::from_term(&p.to_term()), Ok(p));
    }
}

#[test]
fn requests_read_as_documented() {
    let nav = AgentId::new("nav@IntellWheels");
    let msg = WheelchairContent::Request {
        actor: nav.clone(),
        action: WheelchairAction::Sequence {
            steps: vec![
                WheelchairAction::GotoXy { x_m: 1.0, y_m: 2.5 },
                WheelchairAction::Spin { angle_rad: 1.5 },
                WheelchairAction::Wait { duration_ms: 500 },
                WheelchairAction::FollowLeftWall { distance_m: 0.5 },
                WheelchairAction::Stop,
            ],
        },
    };
    assert_eq!(
        msg.to_content().to_string(),
        "((action (agent-identifier :name nav@IntellWheels) (action-sequence :steps (sequence \
         (goto-xy :x 1.0 :y 2.5) (spin :angle 1.5) (wait :duration-ms 500) \
         (follow-left-wall :distance 0.5) (stop)))))"
    );
    let goal = WheelchairContent::parse(
        "((action (agent-identifier :name nav@IntellWheels) (GO-TO :place \"room 2.1\")))",
    )
    .unwrap();
    assert_eq!(
        goal,
        WheelchairContent::Request {
            actor: nav,
            action: WheelchairAction::GoTo {
                place: "room 2.1".into()
            }
        }
    );
}

#[test]
fn drive_and_error_messages_read_as_documented() {
    let drive = WheelchairContent::Request {
        actor: AgentId::new("control@chair-0"),
        action: WheelchairAction::Drive {
            linear_mps: 0.4,
            angular_radps: -0.25,
        },
    };
    let text = drive.to_content().to_string();
    assert_eq!(
        text,
        "((action (agent-identifier :name control@chair-0) (drive :linear 0.4 :angular -0.25)))"
    );
    assert_eq!(WheelchairContent::parse(&text), Ok(drive));
    let error = WheelchairContent::error("lease \"A\" expired");
    let text = error.to_content().to_string();
    assert_eq!(text, r#"((error-message "lease \"A\" expired"))"#);
    assert_eq!(WheelchairContent::parse(&text), Ok(error));
    let e = WheelchairContent::parse("((action (agent-identifier :name c@P) (drive :linear 1)))")
        .unwrap_err();
    assert!(
        matches!(
            e,
            OntologyError::MissingSlot {
                concept: "drive",
                slot: "angular"
            }
        ),
        "{e}"
    );
    assert!(WheelchairContent::parse("((error-message a b))").is_err());
}

#[test]
fn facts_read_as_documented() {
    let door = WheelchairContent::Inform(Fact::Door {
        door: "d1".into(),
        state: DoorState::Open,
    });
    assert_eq!(door.to_content().to_string(), "((door-state d1 open))");
    let laser = WheelchairContent::Inform(Fact::Sensor {
        agent: AgentId::new("chair1"),
        state: SensorState {
            sensor: "laser".into(),
            usage: SensorUse::Dropped,
            reason: "silent: no readings".into(),
        },
    });
    let text = laser.to_content().to_string();
    assert_eq!(
        text,
        r#"((sensor-health (agent-identifier :name chair1) (sensor-state :sensor laser :use dropped :reason "silent: no readings")))"#
    );
    assert_eq!(WheelchairContent::parse(&text), Ok(laser));
    let e = WheelchairContent::parse(
        "((sensor-health (agent-identifier :name c) (sensor-state :sensor laser :use broken)))",
    )
    .unwrap_err();
    assert!(
        matches!(e, OntologyError::BadValue { slot: "use", ref value, .. } if value == "broken"),
        "{e}"
    );
    let pose = WheelchairContent::parse(
        "((at-pose (agent-identifier :name wheelchair1@P) (pose :x 1 :y -2.5 :theta 0.5 \
         :covariance (sequence 0.01 0 0 0 0.01 0 0 0 0.002))))",
    )
    .unwrap();
    let WheelchairContent::Inform(Fact::AtPose { pose, .. }) = pose else {
        panic!("{pose:?}")
    };
    assert_eq!((pose.x_m, pose.y_m, pose.theta_rad), (1.0, -2.5, 0.5));
    assert_eq!(pose.covariance[(2, 2)], 0.002);
    let p = pose.t_map_base() * nalgebra::Point2::new(1.0, 0.0);
    assert!(
        (p.x - (1.0 + 0.5f64.cos())).abs() < 1e-12 && (p.y - (-2.5 + 0.5f64.sin())).abs() < 1e-12
    );
}

/// A chair's cognitive agent is asked for its goal with a QUERY-REF and answers the goal it
/// carries out (or an empty set), all in SL0 as the door agent's query is.
#[test]
fn goal_queries_and_answers_read_as_documented() {
    let cognitive = AgentId::new("cognitive@chair-a");
    let query = WheelchairContent::GoalQuery {
        agent: cognitive.clone(),
    };
    let text = query.to_content().to_string();
    assert_eq!(
        text,
        "((current-goal (agent-identifier :name cognitive@chair-a) ?goal))"
    );
    assert_eq!(WheelchairContent::parse(&text), Ok(query));
    let busy = WheelchairContent::Inform(Fact::CurrentGoal {
        agent: cognitive.clone(),
        goal: Some(Box::new(GoalInFlight {
            place: "dining-hall".into(),
            requester: AgentId::new("assistant@services"),
            conversation: "assistant@services-c2".into(),
            outcome: None,
        })),
        ended: None,
    });
    let text = busy.to_content().to_string();
    assert_eq!(
        text,
        "((current-goal (agent-identifier :name cognitive@chair-a) (set (goal :place \
         dining-hall :requester (agent-identifier :name assistant@services) :conversation \
         assistant@services-c2))))"
    );
    assert_eq!(WheelchairContent::parse(&text), Ok(busy));
    let idle = WheelchairContent::Inform(Fact::CurrentGoal {
        agent: cognitive.clone(),
        goal: None,
        ended: None,
    });
    assert_eq!(
        WheelchairContent::parse(&idle.to_content().to_string()),
        Ok(idle)
    );
    // A goal that ended and was not told yet travels with its outcome.
    let ended = WheelchairContent::Inform(Fact::CurrentGoal {
        agent: cognitive,
        goal: None,
        ended: Some(Box::new(GoalInFlight {
            place: "therapy".into(),
            requester: AgentId::new("interface@chair-a"),
            conversation: "c9".into(),
            outcome: Some(Err("no route to therapy".into())),
        })),
    });
    let text = ended.to_content().to_string();
    assert!(
        text.contains(":outcome failed :reason \"no route to therapy\""),
        "{text}"
    );
    assert_eq!(WheelchairContent::parse(&text), Ok(ended));
    let two = "((current-goal (agent-identifier :name c@P) (set (goal :place a :requester \
               (agent-identifier :name r@P) :conversation x) (goal :place b :requester \
               (agent-identifier :name r@P) :conversation y))))";
    let e = WheelchairContent::parse(two).unwrap_err().to_string();
    assert!(e.contains("at most one goal under way"), "{e}");
}

#[test]
fn wrong_content_says_what_is_wrong() {
    let e = WheelchairContent::parse("((action (agent-identifier :name a@P) (goto-xy :x 1)))")
        .unwrap_err();
    assert!(
        matches!(
            e,
            OntologyError::MissingSlot {
                concept: "goto-xy",
                slot: "y"
            }
        ),
        "{e}"
    );
    let e = WheelchairContent::parse("((door-state d1 ajar))").unwrap_err();
    assert!(
        matches!(e, OntologyError::BadValue { slot: "state", ref value, .. } if value == "ajar"),
        "{e}"
    );
    let e = WheelchairContent::parse("((at-pose (agent-identifier :name a@P) (pose :x 1 :y 2 :theta 0 :covariance (sequence 1 2))))")
        .unwrap_err();
    assert!(
        matches!(
            e,
            OntologyError::BadValue {
                slot: "covariance",
                ..
            }
        ),
        "{e}"
    );
    assert!(matches!(
        WheelchairContent::parse("((not (x y)))"),
        Err(OntologyError::Sl(_))
    ));
}

#[test]
fn a_drive_reads_only_with_finite_speeds() {
    let drive = |speed: &str| {
        WheelchairContent::parse(&format!(
            "((action (agent-identifier :name c@P) (drive :linear {speed} :angular 0)))"
        ))
    };
    for speed in [
        "1e400", "-1e400", "NaN", "nan", "inf", "-inf", "Infinity", "0x10",
    ] {
        let read = drive(speed);
        assert!(read.is_err(), "{speed}: {read:?}");
    }
    for (speed, value) in [("1e-400", 0.0), ("+1", 1.0), (".5", 0.5), ("5.", 5.0)] {
        assert_eq!(
            drive(speed),
            Ok(WheelchairContent::Request {
                actor: AgentId::new("c@P"),
                action: WheelchairAction::Drive {
                    linear_mps: value,
                    angular_radps: 0.0
                }
            }),
            "{speed}"
        );
    }
}

#[test]
fn subscriptions_read_and_write_as_documented() {
    use iw_ontology::wheelchair::{Subscription, Topic};
    let read =
        |text: &str| iw_sl::parse(text, iw_sl::Level::Sl0).map(|c| Subscription::from_content(&c));
    let both = Subscription::to([Topic::AtPose, Topic::SensorReading]);
    assert_eq!(
        both.to_content().to_string(),
        "((at-pose ?agent ?pose) (sensor-reading ?agent ?reading))"
    );
    assert_eq!(
        Subscription::to([Topic::DriveApplied])
            .to_content()
            .to_string(),
        "((drive-applied ?agent ?command))"
    );
    for topics in [
        vec![Topic::AtPose],
        vec![Topic::AtPose, Topic::SensorReading],
        vec![Topic::DriveApplied],
    ] {
        let s = Subscription::to(topics);
        assert_eq!(read(&s.to_content().to_string()).unwrap(), Ok(s));
    }
    // A pattern may name its agent.
    let named = read("((AT-POSE (agent-identifier :name c@P) ?pose))")
        .unwrap()
        .unwrap();
    assert!(named.wants(Topic::AtPose) && !named.wants(Topic::SensorReading));
    for wrong in [
        "((battery-level ?agent ?x))",
        "((at-pose ?pose))",
        "((action (agent-identifier :name c@P) (stop)))",
    ] {
        assert!(
            matches!(
                read(wrong).unwrap(),
                Err(OntologyError::UnexpectedContent { .. })
            ),
            "{wrong}"
        );
    }
}

/// The confirmation of a CANCEL reads back as itself, never as the notification of the action
/// it cancels; one whose two actors differ is refused.
#[test]
fn a_cancel_confirmation_is_not_a_done_action() {
    let pass = WheelchairAction::Pass {
        passage: "d1".into(),
        direction: "forward".into(),
    };
    let watcher = AgentId::new("watcher");
    let confirmation = WheelchairContent::Cancelled {
        actor: watcher.clone(),
        action: pass.clone(),
    };
    let text = confirmation.to_content().to_string();
    assert_eq!(
        text,
        "((done (action (agent-identifier :name watcher) (cancel (action (agent-identifier :name \
         watcher) (pass :passage d1 :direction forward))))))"
    );
    assert_eq!(WheelchairContent::parse(&text), Ok(confirmation));
    let grant = WheelchairContent::Done {
        actor: watcher,
        action: pass,
    };
    assert_ne!(grant.to_content().to_string(), text);
    let mixed = text.replacen("name watcher)", "name other)", 1);
    assert!(WheelchairContent::parse(&mixed).is_err(), "{mixed}");
}
