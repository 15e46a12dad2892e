//! The wheelchair ontology: what IntellWheels agents tell and ask each other, as SL content.
//!
//! Requests are FIPA action expressions `((action (agent-identifier :name nav@P) (goto-xy :x 1.0
//! :y 2.0)))`; facts are predicates `((at-pose (agent-identifier ...) (pose :x .. :y .. :theta ..
//! :covariance (sequence c00 .. c22))))`. Units are SI (metres, radians); integers carry their
//! unit in the slot name (`:duration-ms`).

use iw_acl::AgentId;
use iw_sl::{
    ActionExpression, ActionOp, ActionOperand, Arguments, Collection, Content, ContentExpression,
    Formula, Level, Term,
};
use nalgebra::{Isometry2, Matrix3, Vector2};
use serde::{Deserialize, Serialize};

use crate::concept::{
    Concept, Frame, FrameBuilder, is_frame, number_of, shown, text_of, word_enum, word_value,
};
use crate::error::OntologyError;

/// The `:ontology` name of this ontology.
pub const ONTOLOGY: &str = "IntellWheels-Wheelchair";

/// Planar pose of the wheelchair base in the map frame, with its uncertainty.
///
/// SL: `(pose :x 1.0 :y 2.0 :theta 0.5 :covariance (sequence c00 c01 c02 c10 .. c22))`, the
/// covariance of (x, y, theta) row by row in m² / m·rad / rad².
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// x of the base in the map frame, metres.
    pub x_m: f64,
    /// y of the base in the map frame, metres.
    pub y_m: f64,
    /// Heading of the base in the map frame, radians.
    pub theta_rad: f64,
    /// Covariance of (x, y, theta).
    pub covariance: Matrix3<f64>,
}

/// A pose whose x or y variance is at least this says the chair does not know where it is on
/// the map (it is searching for its pose): agents must not plan from it.
pub const NOT_LOCALIZED_VARIANCE_M2: f64 = 100.0;

impl Pose {
    /// Whether the pose says the chair knows where it is ([`NOT_LOCALIZED_VARIANCE_M2`]).
    pub fn localized(&self) -> bool {
        self.covariance[(0, 0)] < NOT_LOCALIZED_VARIANCE_M2
            && self.covariance[(1, 1)] < NOT_LOCALIZED_VARIANCE_M2
    }

    /// `t_map_base`: maps base coordinates into the map frame.
    pub fn t_map_base(&self) -> Isometry2<f64> {
        Isometry2::new(Vector2::new(self.x_m, self.y_m), self.theta_rad)
    }
}

impl Concept for Pose {
    fn to_term(&self) -> Term {
        // Row-major on the wire; nalgebra stores columns, so walk the transpose.
        let cov = self
            .covariance
            .transpose()
            .iter()
            .map(|&c| Term::float(c))
            .collect();
        FrameBuilder::new("pose")
            .float("x", self.x_m)
            .float("y", self.y_m)
            .float("theta", self.theta_rad)
            .list("covariance", Collection::Sequence, cov)
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "pose")?;
        let cov = f.list("covariance")?;
        let values: Option<Vec<f64>> = cov.iter().map(number_of).collect();
        let covariance = match values {
            Some(v) if v.len() == 9 => Matrix3::from_row_slice(&v),
            Some(v) if v.is_empty() => Matrix3::zeros(),
            _ => {
                return Err(OntologyError::BadValue {
                    concept: "pose",
                    slot: "covariance",
                    value: f.get("covariance").map(shown).unwrap_or_default(),
                    reason: "expected 9 numbers (3x3, row by row)",
                });
            }
        };
        Ok(Self {
            x_m: f.required_number("x")?,
            y_m: f.required_number("y")?,
            theta_rad: f.required_number("theta")?,
            covariance,
        })
    }
}

/// A sensor reading.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum SensorReading {
    /// `(sonar-reading :ranges (sequence r0 r1 ...))`: one range per sonar, metres, in the
    /// body's sonar order.
    Sonar {
        /// Ranges, metres.
        ranges_m: Vec<f64>,
    },
    /// `(encoder-reading :left n :right m)`: cumulative wheel encoder ticks.
    Encoders {
        /// Left wheel ticks.
        left_ticks: i64,
        /// Right wheel ticks.
        right_ticks: i64,
    },
}

impl Concept for SensorReading {
    fn to_term(&self) -> Term {
        match self {
            Self::Sonar { ranges_m } => FrameBuilder::new("sonar-reading")
                .term(
                    "ranges",
                    Term::sequence(ranges_m.iter().map(|&r| Term::float(r)).collect()),
                )
                .build(),
            Self::Encoders {
                left_ticks,
                right_ticks,
            } => FrameBuilder::new("encoder-reading")
                .term("left", Term::integer(*left_ticks))
                .term("right", Term::integer(*right_ticks))
                .build(),
        }
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        if is_frame(term, "sonar-reading") {
            let f = Frame::read(term, "sonar-reading")?;
            let ranges = f.list("ranges")?;
            let ranges_m = ranges.iter().map(|t| {
                number_of(t).ok_or_else(|| OntologyError::BadValue {
                    concept: "sonar-reading",
                    slot: "ranges",
                    value: shown(t),
                    reason: "expected ranges in metres",
                })
            });
            return Ok(Self::Sonar {
                ranges_m: ranges_m.collect::<Result<_, _>>()?,
            });
        }
        let f =
            Frame::read(term, "encoder-reading").map_err(|_| OntologyError::UnexpectedTerm {
                expected: "sonar-reading or encoder-reading",
                found: shown(term),
            })?;
        Ok(Self::Encoders {
            left_ticks: f.required_integer("left")?,
            right_ticks: f.required_integer("right")?,
        })
    }
}

/// What a wheelchair (or the agent driving it) can be asked to do.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum WheelchairAction {
    /// `(goto-xy :x 1.0 :y 2.0)`: drive to a point of the map frame, metres.
    GotoXy {
        /// Target x, metres.
        x_m: f64,
        /// Target y, metres.
        y_m: f64,
    },
    /// `(go-to :place kitchen)`: a goal; the planner chooses the route to the named place.
    GoTo {
        /// A place of the building map.
        place: String,
    },
    /// `(follow-line)`: follow the floor line.
    FollowLine,
    /// `(follow-left-wall :distance 0.5)`: keep the wall on the left at this distance, metres.
    FollowLeftWall {
        /// Distance to keep, metres.
        distance_m: f64,
    },
    /// `(follow-right-wall :distance 0.5)`.
    FollowRightWall {
        /// Distance to keep, metres.
        distance_m: f64,
    },
    /// `(spin :angle 1.57)`: turn in place to this heading of the map frame, radians.
    Spin {
        /// Target heading, radians.
        angle_rad: f64,
    },
    /// `(wait :duration-ms 500)`: stay still.
    Wait {
        /// How long, milliseconds.
        duration_ms: i64,
    },
    /// `(stop)`: stop now.
    Stop,
    /// `(drive :linear 0.4 :angular -0.2)`: one command of a manual drive stream, the user's
    /// wish before shared control: linear speed along the chair's heading, m/s (forward
    /// positive), and turn rate, rad/s (counter-clockwise positive). A stream is one
    /// conversation; the control agent stops the chair when the stream falls silent.
    Drive {
        /// Linear speed, m/s.
        linear_mps: f64,
        /// Angular speed, rad/s.
        angular_radps: f64,
    },
    /// `(open-door :door d1)`: asked of a door agent.
    OpenDoor {
        /// The door.
        door: String,
    },
    /// `(close-door :door d1)`.
    CloseDoor {
        /// The door.
        door: String,
    },
    /// `(pass :passage corridor :direction forward)`: asked of the watcher agent, to drive
    /// through a door or narrow passage that chairs share in one direction at a time.
    Pass {
        /// The passage, as the map names it.
        passage: String,
        /// Which way the chair crosses it (`forward` along the passage's axis or `backward`).
        direction: String,
    },
    /// `(action-sequence :steps (sequence a1 a2 ...))`: the steps one after the other.
    Sequence {
        /// The steps, in order.
        steps: Vec<WheelchairAction>,
    },
}

impl Concept for WheelchairAction {
    fn to_term(&self) -> Term {
        match self {
            Self::GotoXy { x_m, y_m } => FrameBuilder::new("goto-xy")
                .float("x", *x_m)
                .float("y", *y_m)
                .build(),
            Self::GoTo { place } => FrameBuilder::new("go-to")
                .text("place", Some(place))
                .build(),
            Self::FollowLine => FrameBuilder::new("follow-line").build(),
            Self::FollowLeftWall { distance_m } => FrameBuilder::new("follow-left-wall")
                .float("distance", *distance_m)
                .build(),
            Self::FollowRightWall { distance_m } => FrameBuilder::new("follow-right-wall")
                .float("distance", *distance_m)
                .build(),
            Self::Spin { angle_rad } => {
                FrameBuilder::new("spin").float("angle", *angle_rad).build()
            }
            Self::Wait { duration_ms } => FrameBuilder::new("wait")
                .term("duration-ms", Term::integer(*duration_ms))
                .build(),
            Self::Stop => FrameBuilder::new("stop").build(),
            Self::Drive {
                linear_mps,
                angular_radps,
            } => FrameBuilder::new("drive")
                .float("linear", *linear_mps)
                .float("angular", *angular_radps)
                .build(),
            Self::OpenDoor { door } => FrameBuilder::new("open-door")
                .text("door", Some(door))
                .build(),
            Self::CloseDoor { door } => FrameBuilder::new("close-door")
                .text("door", Some(door))
                .build(),
            Self::Pass { passage, direction } => FrameBuilder::new("pass")
                .text("passage", Some(passage))
                .text("direction", Some(direction))
                .build(),
            Self::Sequence { steps } => FrameBuilder::new("action-sequence")
                .term(
                    "steps",
                    Term::sequence(steps.iter().map(Concept::to_term).collect()),
                )
                .build(),
        }
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        const EXPECTED: &str = "a wheelchair action (goto-xy, go-to, follow-line, follow-left-wall, \
                                follow-right-wall, spin, wait, stop, drive, open-door, close-door, pass, action-sequence)";
        let Term::Functional { symbol, .. } = term else {
            return Err(OntologyError::UnexpectedTerm {
                expected: EXPECTED,
                found: shown(term),
            });
        };
        let name = symbol.to_ascii_lowercase();
        let frame = |concept| Frame::read(term, concept);
        Ok(match name.as_str() {
            "goto-xy" => {
                let f = frame("goto-xy")?;
                Self::GotoXy {
                    x_m: f.required_number("x")?,
                    y_m: f.required_number("y")?,
                }
            }
            "go-to" => Self::GoTo {
                place: frame("go-to")?.required_text("place")?,
            },
            "follow-line" => Self::FollowLine,
            "follow-left-wall" => Self::FollowLeftWall {
                distance_m: frame("follow-left-wall")?.required_number("distance")?,
            },
            "follow-right-wall" => Self::FollowRightWall {
                distance_m: frame("follow-right-wall")?.required_number("distance")?,
            },
            "spin" => Self::Spin {
                angle_rad: frame("spin")?.required_number("angle")?,
            },
            "wait" => Self::Wait {
                duration_ms: frame("wait")?.required_integer("duration-ms")?,
            },
            "stop" => Self::Stop,
            "drive" => {
                let f = frame("drive")?;
                Self::Drive {
                    linear_mps: f.required_number("linear")?,
                    angular_radps: f.required_number("angular")?,
                }
            }
            "open-door" => Self::OpenDoor {
                door: frame("open-door")?.required_text("door")?,
            },
            "close-door" => Self::CloseDoor {
                door: frame("close-door")?.required_text("door")?,
            },
            "pass" => {
                let f = frame("pass")?;
                Self::Pass {
                    passage: f.required_text("passage")?,
                    direction: f.required_text("direction")?,
                }
            }
            "action-sequence" => Self::Sequence {
                steps: frame("action-sequence")?.concepts("steps")?,
            },
            _ => {
                return Err(OntologyError::UnexpectedTerm {
                    expected: EXPECTED,
                    found: shown(term),
                });
            }
        })
    }
}

word_enum! {
    /// The state of a door.
    pub enum DoorState {
        /// `open`
        Open => "open",
        /// `closed`
        Closed => "closed",
        /// `opening`
        Opening => "opening",
        /// `closing`
        Closing => "closing",
    }
}

word_enum! {
    /// Whether a chair's range sensor feeds its pose estimate.
    pub enum SensorUse {
        /// `in-use`
        InUse => "in-use",
        /// `dropped`: silent, garbage or contradicting the map; the pose goes on without it.
        Dropped => "dropped",
    }
}

/// A chair's range sensor as its perception agent uses it.
///
/// SL: `(sensor-state :sensor laser :use dropped :reason "silent: no readings")`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorState {
    /// The sensor: `laser` or `sonars` (the ring).
    pub sensor: String,
    /// In use or dropped.
    pub usage: SensorUse,
    /// Why it was dropped, for a person to read (empty when in use).
    pub reason: String,
}

impl Concept for SensorState {
    fn to_term(&self) -> Term {
        FrameBuilder::new("sensor-state")
            .text("sensor", Some(&self.sensor))
            .term("use", Term::string(self.usage.name()))
            .text(
                "reason",
                (!self.reason.is_empty()).then_some(self.reason.as_str()),
            )
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "sensor-state")?;
        Ok(Self {
            sensor: f.required_text("sensor")?,
            usage: word_value(
                f.require("use")?,
                "sensor-state",
                "use",
                SensorUse::from_word,
                "expected in-use or dropped",
            )?,
            reason: f.text("reason")?.unwrap_or_default(),
        })
    }
}

word_enum! {
    /// How a goal ended, as the `:outcome` slot of a [`GoalInFlight`] writes it.
    pub enum GoalOutcome {
        /// `reached`
        Reached => "reached",
        /// `failed` (the `:reason` slot says why)
        Failed => "failed",
    }
}

/// A goal a chair's cognitive agent is carrying out, as it answers a query for its current
/// goal: where to, and the conversation it will answer (who asked, under which id), so that
/// whoever asks can tell a goal it follows from one nobody follows any more.
///
/// SL: `(goal :place P :requester (agent-identifier ...) :conversation "id")`, with
/// `:outcome reached` or `:outcome failed :reason "why"` once it ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GoalInFlight {
    /// The place of the map the chair is going to.
    pub place: String,
    /// Who gave the goal: the agent the outcome is answered to.
    pub requester: AgentId,
    /// The conversation the outcome is answered in.
    pub conversation: String,
    /// How it ended, for a goal that did: `Ok` reached, `Err` failed with the reason.
    pub outcome: Option<Result<(), String>>,
}

impl Concept for GoalInFlight {
    fn to_term(&self) -> Term {
        let (outcome, reason) = match &self.outcome {
            None => (None, None),
            Some(Ok(())) => (Some(GoalOutcome::Reached.name()), None),
            Some(Err(why)) => (Some(GoalOutcome::Failed.name()), Some(why.as_str())),
        };
        FrameBuilder::new("goal")
            .text("place", Some(&self.place))
            .term("requester", self.requester.to_term())
            .text("conversation", Some(&self.conversation))
            .text("outcome", outcome)
            .text("reason", reason)
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "goal")?;
        let outcome = match f.get("outcome") {
            None => None,
            Some(word) => Some(
                match word_value(
                    word,
                    "goal",
                    "outcome",
                    GoalOutcome::from_word,
                    "expected reached or failed",
                )? {
                    GoalOutcome::Reached => Ok(()),
                    GoalOutcome::Failed => Err(f.text("reason")?.unwrap_or_default()),
                },
            ),
        };
        Ok(Self {
            place: f.required_text("place")?,
            requester: AgentId::from_term(f.require("requester")?)?,
            conversation: f.required_text("conversation")?,
            outcome,
        })
    }
}

/// Facts agents inform each other of.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Fact {
    /// `(at-pose agent (pose ...))`: where `agent`'s wheelchair is.
    AtPose {
        /// The wheelchair's agent.
        agent: AgentId,
        /// Its pose.
        pose: Pose,
    },
    /// `(sensor-reading agent (sonar-reading ...))`.
    Reading {
        /// The wheelchair's agent.
        agent: AgentId,
        /// What its sensor read.
        reading: SensorReading,
    },
    /// `(sensor-health agent (sensor-state ...))`: the perception agent of `agent`'s chair
    /// dropped a range sensor from its pose, or took it back. A chair whose laser went silent
    /// dead-reckons, so its cognitive agent routes it past a landmark.
    Sensor {
        /// The wheelchair's agent.
        agent: AgentId,
        /// The sensor and its use.
        state: SensorState,
    },
    /// `(door-state d1 open)`.
    Door {
        /// The door.
        door: String,
        /// Its state.
        state: DoorState,
    },
    /// `(drive-applied agent (drive :linear V :angular W))`: what shared control made of the
    /// user's drive command at the control tick, as `agent` (a chair's control agent) handed
    /// it to the wheels: what a remote driver's screen shows beside the command it sent.
    Applied {
        /// The control agent.
        agent: AgentId,
        /// Linear speed, m/s.
        linear_mps: f64,
        /// Angular speed, rad/s.
        angular_radps: f64,
    },
    /// `(error-message "why")`: the reason a REFUSE, FAILURE or NOT-UNDERSTOOD carries.
    ErrorMessage {
        /// The reason, for a person to read.
        reason: String,
    },
    /// `(body-fault "why")`: the reason of a FAILURE that came from the chair's body (its
    /// sensors unreadable, its world link down), not from the way ahead: the action may succeed
    /// when the body is back, so it says nothing about the route.
    BodyFault {
        /// The reason, for a person to read.
        reason: String,
    },
    /// `(current-goal agent (set (goal ...) ...))`: the goal `agent` (a chair's cognitive
    /// agent) is carrying out, and the last one that ended and was not told yet (with its
    /// `:outcome`: its answer may have gone where no one hears it any more); the set is empty
    /// when it has neither. The answer to [`WheelchairContent::GoalQuery`].
    CurrentGoal {
        /// The cognitive agent.
        agent: AgentId,
        /// Its goal under way, if any (no outcome).
        goal: Option<Box<GoalInFlight>>,
        /// The last goal that ended, not told before (with its outcome).
        ended: Option<Box<GoalInFlight>>,
    },
}

impl Fact {
    fn to_formula(&self) -> Formula {
        let (predicate, args) = match self {
            Self::ErrorMessage { reason } => ("error-message", vec![Term::string(reason.as_str())]),
            Self::BodyFault { reason } => ("body-fault", vec![Term::string(reason.as_str())]),
            Self::AtPose { agent, pose } => ("at-pose", vec![agent.to_term(), pose.to_term()]),
            Self::Reading { agent, reading } => {
                ("sensor-reading", vec![agent.to_term(), reading.to_term()])
            }
            Self::Sensor { agent, state } => {
                ("sensor-health", vec![agent.to_term(), state.to_term()])
            }
            Self::CurrentGoal { agent, goal, ended } => (
                "current-goal",
                vec![
                    agent.to_term(),
                    Term::set(goal.iter().chain(ended).map(|g| g.to_term()).collect()),
                ],
            ),
            Self::Door { door, state } => (
                "door-state",
                vec![Term::string(door.as_str()), Term::string(state.name())],
            ),
            Self::Applied {
                agent,
                linear_mps,
                angular_radps,
            } => (
                "drive-applied",
                vec![
                    agent.to_term(),
                    WheelchairAction::Drive {
                        linear_mps: *linear_mps,
                        angular_radps: *angular_radps,
                    }
                    .to_term(),
                ],
            ),
        };
        Formula::Atomic {
            predicate: predicate.into(),
            args,
        }
    }

    fn from_formula(formula: &Formula) -> Result<Self, OntologyError> {
        let bad = || OntologyError::UnexpectedTerm {
            expected: "(at-pose agent pose), (sensor-reading agent reading), (sensor-health agent \
                       (sensor-state ...)), (door-state door state), (drive-applied agent \
                       (drive ...)), (current-goal agent (set goal...)), (error-message reason) or \
                       (body-fault reason)",
            found: formula.to_string(),
        };
        let Formula::Atomic { predicate, args } = formula else {
            return Err(bad());
        };
        for (name, fact) in [
            (
                "error-message",
                (|reason| Self::ErrorMessage { reason }) as fn(String) -> Self,
            ),
            ("body-fault", |reason| Self::BodyFault { reason }),
        ] {
            if predicate.eq_ignore_ascii_case(name) {
                let [reason] = args.as_slice() else {
                    return Err(bad());
                };
                return Ok(fact(text_of(reason).ok_or_else(bad)?));
            }
        }
        let [first, second] = args.as_slice() else {
            return Err(bad());
        };
        match predicate.to_ascii_lowercase().as_str() {
            "at-pose" => Ok(Self::AtPose {
                agent: AgentId::from_term(first)?,
                pose: Pose::from_term(second)?,
            }),
            "sensor-reading" => Ok(Self::Reading {
                agent: AgentId::from_term(first)?,
                reading: SensorReading::from_term(second)?,
            }),
            "sensor-health" => Ok(Self::Sensor {
                agent: AgentId::from_term(first)?,
                state: SensorState::from_term(second)?,
            }),
            "current-goal" => {
                let bad = || OntologyError::BadValue {
                    concept: "current-goal",
                    slot: "goal",
                    value: shown(second),
                    reason: "expected a set of at most one goal under way and one ended",
                };
                let items = second.collection().ok_or_else(bad)?.1;
                let (mut goal, mut ended) = (None, None);
                for item in items {
                    let g = GoalInFlight::from_term(item)?;
                    let slot = if g.outcome.is_some() {
                        &mut ended
                    } else {
                        &mut goal
                    };
                    if slot.replace(Box::new(g)).is_some() {
                        return Err(bad());
                    }
                }
                Ok(Self::CurrentGoal {
                    agent: AgentId::from_term(first)?,
                    goal,
                    ended,
                })
            }
            "drive-applied" => match WheelchairAction::from_term(second)? {
                WheelchairAction::Drive {
                    linear_mps,
                    angular_radps,
                } => Ok(Self::Applied {
                    agent: AgentId::from_term(first)?,
                    linear_mps,
                    angular_radps,
                }),
                _ => Err(bad()),
            },
            "door-state" => Ok(Self::Door {
                door: text_of(first).ok_or_else(bad)?,
                state: word_value(
                    second,
                    "door-state",
                    "state",
                    DoorState::from_word,
                    "expected open, closed, opening or closing",
                )?,
            }),
            _ => Err(bad()),
        }
    }
}

word_enum! {
    /// A kind of fact a chair's agents notify their subscribers of.
    pub enum Topic {
        /// `(at-pose ?agent ?pose)`, from the perception agent.
        AtPose => "at-pose",
        /// `(sensor-reading ?agent ?reading)`, from the perception agent.
        SensorReading => "sensor-reading",
        /// `(drive-applied ?agent ?command)`, from the control agent.
        DriveApplied => "drive-applied",
    }
}

impl Topic {
    /// The pattern's variables: the agent, then the fact's value.
    fn variables(self) -> [&'static str; 2] {
        match self {
            Self::AtPose => ["agent", "pose"],
            Self::SensorReading => ["agent", "reading"],
            Self::DriveApplied => ["agent", "command"],
        }
    }
}

/// SUBSCRIBE content (fipa-subscribe): the facts wanted, one pattern each,
/// `((at-pose ?agent ?pose) (sensor-reading ?agent ?reading))`. A pattern may name its agent
/// instead of `?agent`; any two arguments are read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Subscription {
    /// The facts wanted, in the order written.
    pub topics: Vec<Topic>,
}

impl Subscription {
    /// A subscription to `topics`.
    pub fn to(topics: impl IntoIterator<Item = Topic>) -> Self {
        Self {
            topics: topics.into_iter().collect(),
        }
    }

    /// Whether `topic` is among those wanted.
    pub fn wants(&self, topic: Topic) -> bool {
        self.topics.contains(&topic)
    }

    /// As SL content.
    pub fn to_content(&self) -> Content {
        Content {
            expressions: self
                .topics
                .iter()
                .map(|t| {
                    ContentExpression::Formula(Formula::Atomic {
                        predicate: t.name().into(),
                        args: t.variables().map(Term::variable).into(),
                    })
                })
                .collect(),
        }
    }

    /// Reads SL content: one or more patterns, each of a [`Topic`].
    pub fn from_content(content: &Content) -> Result<Self, OntologyError> {
        let bad = || OntologyError::UnexpectedContent {
            expected: "patterns (at-pose ?agent ?pose), (sensor-reading ?agent ?reading) or \
                       (drive-applied ?agent ?command)",
            found: content.to_string(),
        };
        let topics = content
            .expressions
            .iter()
            .map(|e| match e {
                ContentExpression::Formula(Formula::Atomic { predicate, args })
                    if args.len() == 2 =>
                {
                    Topic::from_word(predicate).ok_or_else(bad)
                }
                _ => Err(bad()),
            })
            .collect::<Result<Vec<_>, _>>()?;
        if topics.is_empty() {
            return Err(bad());
        }
        Ok(Self { topics })
    }
}

/// The content forms of wheelchair conversations (all within `fipa-sl0`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum WheelchairContent {
    /// REQUEST: `((action actor act))`.
    Request {
        /// Who should act.
        actor: AgentId,
        /// What to do.
        action: WheelchairAction,
    },
    /// INFORM when finished: `((done (action actor act)))`.
    Done {
        /// Who acted.
        actor: AgentId,
        /// What was done.
        action: WheelchairAction,
    },
    /// INFORM confirming a CANCEL (FIPA's cancel meta-protocol, "inform-done" of the cancel):
    /// `((done (action actor (cancel (action actor act)))))`: `actor` has done the cancelling
    /// of `act`, the action the CANCEL named. Unlike [`WheelchairContent::Done`] for the same
    /// `act` (a subscription's notification, e.g. a passage granted), it ends the subscription,
    /// and the two can cross on the wire.
    Cancelled {
        /// Who cancelled (the participant that was to act).
        actor: AgentId,
        /// The action cancelled.
        action: WheelchairAction,
    },
    /// INFORM: `(fact)`.
    Inform(Fact),
    /// QUERY-REF for the goal `agent` (a chair's cognitive agent) is carrying out:
    /// `((current-goal agent ?goal))`, answered INFORM [`Fact::CurrentGoal`].
    GoalQuery {
        /// The cognitive agent asked.
        agent: AgentId,
    },
}

impl WheelchairContent {
    /// The SL level needed: everything here is SL0.
    pub const LEVEL: Level = Level::Sl0;

    /// `((error-message "reason"))`: what a REFUSE, FAILURE or NOT-UNDERSTOOD says.
    pub fn error(reason: impl Into<String>) -> Self {
        Self::Inform(Fact::ErrorMessage {
            reason: reason.into(),
        })
    }

    /// `((body-fault "reason"))`: a FAILURE because the body failed, not the way ahead.
    pub fn body_fault(reason: impl Into<String>) -> Self {
        Self::Inform(Fact::BodyFault {
            reason: reason.into(),
        })
    }

    /// The reason a REFUSE, FAILURE or NOT-UNDERSTOOD gives (`error-message` or `body-fault`).
    pub fn reason(&self) -> Option<&str> {
        match self {
            Self::Inform(Fact::ErrorMessage { reason } | Fact::BodyFault { reason }) => {
                Some(reason)
            }
            _ => None,
        }
    }

    /// As SL content.
    pub fn to_content(&self) -> Content {
        let action = |actor: &AgentId, act: &WheelchairAction| ActionExpression::Action {
            agent: actor.to_term(),
            act: act.to_term(),
        };
        match self {
            Self::Request { actor, action: act } => Content::single(action(actor, act)),
            Self::Done { actor, action: act } => Content::single(Formula::ActionCondition {
                op: ActionOp::Done,
                action: Box::new(ActionOperand::Expression(action(actor, act))),
                condition: None,
            }),
            Self::Cancelled { actor, action: act } => {
                let cancelled = Term::Action {
                    action: Box::new(action(actor, act)),
                };
                let cancel = ActionExpression::Action {
                    agent: actor.to_term(),
                    act: Term::positional(CANCEL, vec![cancelled]),
                };
                Content::single(Formula::ActionCondition {
                    op: ActionOp::Done,
                    action: Box::new(ActionOperand::Expression(cancel)),
                    condition: None,
                })
            }
            Self::Inform(fact) => Content::single(fact.to_formula()),
            Self::GoalQuery { agent } => Content::single(Formula::Atomic {
                predicate: "current-goal".into(),
                args: vec![agent.to_term(), Term::variable(GOAL_VARIABLE)],
            }),
        }
    }

    /// Parses SL0 text and reads it.
    pub fn parse(text: &str) -> Result<Self, OntologyError> {
        Self::from_content(&iw_sl::parse(text, Self::LEVEL)?)
    }

    /// Reads SL content.
    pub fn from_content(content: &Content) -> Result<Self, OntologyError> {
        let read_action = |a: &ActionExpression| match a {
            ActionExpression::Action { agent, act } => Ok((
                AgentId::from_term(agent)?,
                WheelchairAction::from_term(act)?,
            )),
            other => Err(OntologyError::UnexpectedTerm {
                expected: "(action actor act)",
                found: other.to_string(),
            }),
        };
        match content.expressions.as_slice() {
            [ContentExpression::Action(a)] => {
                read_action(a).map(|(actor, action)| Self::Request { actor, action })
            }
            [
                ContentExpression::Formula(Formula::ActionCondition {
                    op: ActionOp::Done,
                    action,
                    condition: None,
                }),
            ] => match action.as_ref() {
                ActionOperand::Expression(a) => match cancelled(a) {
                    Some(inner) => {
                        let (actor, action) = read_action(inner)?;
                        match a {
                            ActionExpression::Action { agent, .. }
                                if AgentId::from_term(agent)? == actor =>
                            {
                                Ok(Self::Cancelled { actor, action })
                            }
                            _ => Err(unexpected(content)),
                        }
                    }
                    None => read_action(a).map(|(actor, action)| Self::Done { actor, action }),
                },
                ActionOperand::Meta(_) => Err(unexpected(content)),
            },
            [ContentExpression::Formula(Formula::Atomic { predicate, args })]
                if predicate.eq_ignore_ascii_case("current-goal")
                    && matches!(args.as_slice(), [_, Term::Variable { .. }]) =>
            {
                Ok(Self::GoalQuery {
                    agent: AgentId::from_term(&args[0])?,
                })
            }
            [ContentExpression::Formula(f)] => Fact::from_formula(f).map(Self::Inform),
            _ => Err(unexpected(content)),
        }
    }
}

/// The act of a [`WheelchairContent::Cancelled`]: `(cancel (action actor act))`.
const CANCEL: &str = "cancel";

/// The action expression a `(cancel (action actor act))` act names, if `a` is one.
fn cancelled(a: &ActionExpression) -> Option<&ActionExpression> {
    let ActionExpression::Action {
        act: Term::Functional { symbol, args },
        ..
    } = a
    else {
        return None;
    };
    match args {
        Arguments::Positional(args) if symbol.eq_ignore_ascii_case(CANCEL) => match args.as_slice()
        {
            [Term::Action { action }] => Some(action),
            _ => None,
        },
        _ => None,
    }
}

/// The variable a [`WheelchairContent::GoalQuery`] asks for.
const GOAL_VARIABLE: &str = "goal";

fn unexpected(content: &Content) -> OntologyError {
    OntologyError::UnexpectedContent {
        expected: "((action actor act)), ((done (action actor act))), ((done (action actor \
                   (cancel (action actor act))))), ((current-goal agent ?goal)) or a wheelchair fact",
        found: content.to_string(),
    }
}
