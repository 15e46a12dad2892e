//! The world ontology: how a chair's body talks to the shared world of a deployment (the world
//! container), so virtual, mixed and real chairs of different processes share one simulator
//! (thesis 3.3, 3.5).
//!
//! Every value is one SL0 atomic formula whose first argument names the chair:
//! - `(attach "chair-0" simulated (pose ...))`: put this chair's body in the world at the pose
//!   (`simulated`: the world drives it; `tracked`: a real chair that reports its pose);
//! - `(wheel-speeds "chair-0" 0.3 0.25)`: left and right wheel references, m/s;
//! - `(body-pose "chair-0" (pose ...))`: where a real or mixed chair is (map frame);
//! - `(sensor-frame "chair-0" (frame :time-ns N :left L :right R :sonar (sequence ...) :laser
//!   (sequence ...) :pose (pose ...)))`: what the body senses; a sonar without echo reads `-1`;
//!   `:laser` holds the scanner's ranges to the millimetre (absent: no laser); `:pose` is the
//!   body's true pose, for re-attaching it where it stood if the world restarts;
//! - `(door "office" true)`: open (`true`) or close (`false`) a door of the map.

use iw_sl::{Content, ContentExpression, Formula, Level, Term};
use serde::{Deserialize, Serialize};

use crate::concept::{Concept, Frame, FrameBuilder, number_of, shown, text_of};
use crate::error::OntologyError;
use crate::wheelchair::Pose;

/// The `:ontology` name of this ontology.
pub const ONTOLOGY: &str = "IntellWheels-World";

/// How a chair's body is in the world.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BodyLink {
    /// The world drives it from wheel speeds.
    Simulated,
    /// A real chair: placed where it reports, sensed by the others.
    Tracked,
}

impl BodyLink {
    fn word(self) -> &'static str {
        match self {
            Self::Simulated => "simulated",
            Self::Tracked => "tracked",
        }
    }
}

/// One sensing of a body in the world.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyFrame {
    /// World time of the reading, ns.
    pub time_ns: u64,
    /// Cumulative encoder ticks, left wheel.
    pub left_ticks: i64,
    /// Cumulative encoder ticks, right wheel.
    pub right_ticks: i64,
    /// Sonar ranges, m; `None`: no echo.
    pub sonar_m: Vec<Option<f64>>,
    /// Laser ranges, m, one per beam (empty: no laser). Sent to the millimetre: the scanner's
    /// noise is ten times that, and a 271-beam scan then fits in under 2 KB of SL.
    pub laser_m: Vec<f64>,
    /// The body's true pose in the world.
    pub pose: Pose,
}

impl Concept for BodyFrame {
    fn to_term(&self) -> Term {
        let sonar = self
            .sonar_m
            .iter()
            .map(|r| Term::float(r.unwrap_or(-1.0)))
            .collect();
        let laser = self
            .laser_m
            .iter()
            .map(|r| Term::float((r * 1000.0).round() / 1000.0))
            .collect();
        FrameBuilder::new("frame")
            .term("time-ns", Term::integer(self.time_ns as i64))
            .term("left", Term::integer(self.left_ticks))
            .term("right", Term::integer(self.right_ticks))
            .list("sonar", iw_sl::Collection::Sequence, sonar)
            .list("laser", iw_sl::Collection::Sequence, laser)
            .term("pose", self.pose.to_term())
            .build()
    }

    fn from_term(term: &Term) -> Result<Self, OntologyError> {
        let f = Frame::read(term, "frame")?;
        let time_ns =
            u64::try_from(f.required_integer("time-ns")?).map_err(|_| OntologyError::BadValue {
                concept: "frame",
                slot: "time-ns",
                value: f.get("time-ns").map(shown).unwrap_or_default(),
                reason: "expected a time in ns, not negative",
            })?;
        let sonar_m = f
            .list("sonar")
            .unwrap_or(&[])
            .iter()
            .map(|t| match number_of(t) {
                Some(r) if r.is_finite() && r >= 0.0 => Ok(Some(r)),
                Some(r) if r < 0.0 => Ok(None),
                _ => Err(OntologyError::BadValue {
                    concept: "frame",
                    slot: "sonar",
                    value: shown(t),
                    reason: "expected ranges in metres (-1: no echo)",
                }),
            })
            .collect::<Result<_, _>>()?;
        let laser_m = f
            .list("laser")?
            .iter()
            .map(|t| match number_of(t) {
                Some(r) if r.is_finite() && r >= 0.0 => Ok(r),
                _ => Err(OntologyError::BadValue {
                    concept: "frame",
                    slot: "laser",
                    value: shown(t),
                    reason: "expected ranges in metres, finite and not negative",
                }),
            })
            .collect::<Result<_, _>>()?;
        Ok(Self {
            time_ns,
            left_ticks: f.required_integer("left")?,
            right_ticks: f.required_integer("right")?,
            sonar_m,
            laser_m,
            pose: Pose::from_term(f.require("pose")?)?,
        })
    }
}

/// What bodies and the world tell each other.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum WorldContent {
    /// Put `chair`'s body in the world (or keep it, if it is there).
    Attach {
        /// The chair.
        chair: String,
        /// Driven by the world or placed by the chair.
        link: BodyLink,
        /// Where it is.
        pose: Pose,
    },
    /// Wheel speed references for `chair`'s simulated body, m/s.
    WheelSpeeds {
        /// The chair.
        chair: String,
        /// Left wheel, m/s.
        left_mps: f64,
        /// Right wheel, m/s.
        right_mps: f64,
    },
    /// Where real chair `chair` is.
    BodyPose {
        /// The chair.
        chair: String,
        /// Its pose.
        pose: Pose,
    },
    /// What `chair`'s body senses.
    SensorFrame {
        /// The chair.
        chair: String,
        /// The sensing.
        frame: BodyFrame,
    },
    /// Open or close door `door`.
    Door {
        /// The map's door id.
        door: String,
        /// Open (true) or closed.
        open: bool,
    },
}

impl WorldContent {
    /// The SL level needed: everything here is SL0.
    pub const LEVEL: Level = Level::Sl0;

    /// As SL content.
    pub fn to_content(&self) -> Content {
        let name = |n: &str| Term::string(n);
        let (predicate, args) = match self {
            Self::Attach { chair, link, pose } => (
                "attach",
                vec![name(chair), Term::string(link.word()), pose.to_term()],
            ),
            Self::WheelSpeeds {
                chair,
                left_mps,
                right_mps,
            } => (
                "wheel-speeds",
                vec![name(chair), Term::float(*left_mps), Term::float(*right_mps)],
            ),
            Self::BodyPose { chair, pose } => ("body-pose", vec![name(chair), pose.to_term()]),
            Self::SensorFrame { chair, frame } => {
                ("sensor-frame", vec![name(chair), frame.to_term()])
            }
            Self::Door { door, open } => (
                "door",
                vec![
                    name(door),
                    Term::string(if *open { "true" } else { "false" }),
                ],
            ),
        };
        Content::single(Formula::Atomic {
            predicate: predicate.into(),
            args,
        })
    }

    /// Reads SL content.
    pub fn from_content(content: &Content) -> Result<Self, OntologyError> {
        let unexpected = || OntologyError::UnexpectedContent {
            expected: "one of (attach ..), (wheel-speeds ..), (body-pose ..), (sensor-frame ..), (door ..)",
            found: content.to_string(),
        };
        let [ContentExpression::Formula(Formula::Atomic { predicate, args })] =
            content.expressions.as_slice()
        else {
            return Err(unexpected());
        };
        let text = |t: &Term| text_of(t).ok_or_else(unexpected);
        let number = |t: &Term| {
            number_of(t)
                .filter(|v| v.is_finite())
                .ok_or_else(|| OntologyError::BadValue {
                    concept: "wheel-speeds",
                    slot: "speed",
                    value: shown(t),
                    reason: "expected a finite speed in m/s",
                })
        };
        match (predicate.to_ascii_lowercase().as_str(), args.as_slice()) {
            ("attach", [chair, link, pose]) => Ok(Self::Attach {
                chair: text(chair)?,
                link: match text(link)?.as_str() {
                    "simulated" => BodyLink::Simulated,
                    "tracked" => BodyLink::Tracked,
                    _ => return Err(unexpected()),
                },
                pose: Pose::from_term(pose)?,
            }),
            ("wheel-speeds", [chair, left, right]) => Ok(Self::WheelSpeeds {
                chair: text(chair)?,
                left_mps: number(left)?,
                right_mps: number(right)?,
            }),
            ("body-pose", [chair, pose]) => Ok(Self::BodyPose {
                chair: text(chair)?,
                pose: Pose::from_term(pose)?,
            }),
            ("sensor-frame", [chair, frame]) => Ok(Self::SensorFrame {
                chair: text(chair)?,
                frame: BodyFrame::from_term(frame)?,
            }),
            ("door", [door, open]) => Ok(Self::Door {
                door: text(door)?,
                open: match text(open)?.as_str() {
                    "true" => true,
                    "false" => false,
                    _ => return Err(unexpected()),
                },
            }),
            _ => Err(unexpected()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::OntologyContent;
    use nalgebra::Matrix3;
    use proptest::prelude::*;

    fn pose(x: f64, y: f64, t: f64) -> Pose {
        Pose {
            x_m: x,
            y_m: y,
            theta_rad: t,
            covariance: Matrix3::zeros(),
        }
    }

    fn values() -> impl Strategy<Value = WorldContent> {
        let chair = "[a-z][a-z0-9-]{0,8}";
        let f = -50.0..50.0f64;
        prop_oneof![
            (chair, any::<bool>(), f.clone(), f.clone(), -3.0..3.0f64).prop_map(
                |(chair, sim, x, y, t)| WorldContent::Attach {
                    chair,
                    link: if sim {
                        BodyLink::Simulated
                    } else {
                        BodyLink::Tracked
                    },
                    pose: pose(x, y, t),
                }
            ),
            (chair, f.clone(), f.clone()).prop_map(|(chair, l, r)| WorldContent::WheelSpeeds {
                chair,
                left_mps: l,
                right_mps: r,
            }),
            (
                chair,
                0..u64::MAX / 2,
                any::<i32>(),
                any::<i32>(),
                proptest::collection::vec(proptest::option::of(0.0..5.0f64), 0..16),
                // millimetres: what the frame carries
                proptest::collection::vec(0..10_000u32, 0..300),
                f.clone(),
            )
                .prop_map(|(chair, time_ns, l, r, sonar_m, laser_mm, x)| {
                    WorldContent::SensorFrame {
                        chair,
                        frame: BodyFrame {
                            time_ns,
                            left_ticks: l.into(),
                            right_ticks: r.into(),
                            sonar_m,
                            laser_m: laser_mm
                                .into_iter()
                                .map(|mm| f64::from(mm) / 1000.0)
                                .collect(),
                            pose: pose(x, -x, 0.5),
                        },
                    }
                }),
            (chair, any::<bool>()).prop_map(|(door, open)| WorldContent::Door { door, open }),
        ]
    }

    proptest! {
        /// Every value survives SL text and an ACL message.
        #[test]
        fn round_trips_through_a_message(value in values()) {
            let message = value.fill(iw_acl::AclMessage::new(iw_acl::Performative::Inform));
            prop_assert_eq!(WorldContent::from_message(&message).unwrap(), value);
        }

        /// No content text makes the reader panic.
        #[test]
        fn reading_never_panics(text in "\\PC{0,120}") {
            let _ = iw_sl::parse(&text, Level::Sl0).map(|c| WorldContent::from_content(&c));
        }
    }

    #[test]
    fn bad_values_are_named() {
        let err = WorldContent::from_content(
            &iw_sl::parse("((wheel-speeds \"c\" 0.1 walk))", Level::Sl0).unwrap(),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("walk"), "{err}");
    }

    #[test]
    fn a_laser_range_is_sent_to_the_millimetre_and_a_negative_one_is_refused() {
        let frame = |laser_m| BodyFrame {
            time_ns: 1,
            left_ticks: 0,
            right_ticks: 0,
            sonar_m: Vec::new(),
            laser_m,
            pose: pose(0.0, 0.0, 0.0),
        };
        let text = frame(vec![1.23456, 9.9999]).to_term().to_string();
        assert!(text.contains("1.235") && !text.contains("1.2345"), "{text}");
        let back = BodyFrame::from_term(&frame(vec![1.0]).to_term()).unwrap();
        assert_eq!(back.laser_m, vec![1.0]);
        let bad = frame(vec![-1.0]).to_term();
        let err = BodyFrame::from_term(&bad).unwrap_err().to_string();
        assert!(err.contains("laser"), "{err}");
    }
}
