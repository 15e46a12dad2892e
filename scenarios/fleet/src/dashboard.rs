//! The fleet as the dashboard shows it and what the page asks of it: the adapter between
//! [`Fleet`] and `iw-dashboard` that the in-process demo (`intellwheels demo`) and the drive
//! bench use. The container processes have their own, fed from the platform's traffic
//! (`iw-node`).

use std::collections::BTreeMap;

use iw_dashboard::{
    ChairDisplay, ChairView, ContainerView, DriveInput, MessageView, PageAction, State, round_cm,
};
use nalgebra::Point2;

use crate::{BodyKind, Exchange, Fleet, FleetError};

/// Carries out what the page asked, as staff would: goals through the assistant (to the place
/// nearest the click), doors and faults on the fleet. Returns a notice for the page.
pub fn apply(
    fleet: &mut Fleet,
    action: &PageAction,
    goal_places: &mut BTreeMap<String, String>,
) -> Result<Option<String>, FleetError> {
    match action {
        PageAction::Goal { chair, x, y } => {
            if !(x.is_finite() && y.is_finite()) {
                return Err(FleetError::Plan {
                    reason: format!("goal ({x}, {y}) is not a point"),
                });
            }
            let click = Point2::new(*x, *y);
            let place = fleet
                .building()
                .destinations()
                .min_by(|a, b| (a.1 - click).norm().total_cmp(&(b.1 - click).norm()))
                .map(|(n, _)| n.clone())
                .ok_or_else(|| FleetError::Plan {
                    reason: "the building has no places".into(),
                })?;
            let conversation = fleet.goal_place(chair, &place)?;
            goal_places.insert(chair.clone(), place.clone());
            Ok(Some(format!("{chair} -> {place}: request {conversation}")))
        }
        PageAction::Door { door, open } => {
            fleet.set_door(door, *open)?;
            Ok(Some(format!(
                "door {door}: asked to {}",
                if *open { "open" } else { "close" }
            )))
        }
        PageAction::Fault { chair, failed } => {
            fleet.set_sensor_failure(
                chair,
                crate::compose::world_link::FailedSensor::All,
                *failed,
            )?;
            Ok(Some(format!(
                "{chair}: sensors {}",
                if *failed { "failed" } else { "restored" }
            )))
        }
        PageAction::Drive { chair, input } => {
            push_drive(fleet, chair, *input)?;
            Ok(None)
        }
        PageAction::Pause { .. } | PageAction::Step => Ok(None),
    }
}

/// Hands a drive panel input to `chair`'s interface agent, where a device driver's readings go;
/// the agent streams it as `drive` to its control agent.
pub fn push_drive(fleet: &Fleet, chair: &str, input: DriveInput) -> Result<(), FleetError> {
    let t_ms = (fleet.time_s() * 1000.0) as u64;
    fleet
        .inputs(chair)?
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .push_back((iw_wiring::view::raw_input(input), t_ms));
    Ok(())
}

/// Sonar range below which the display warns that shared control steers away (the thesis'
/// 27-80 cm safety perimeter), m.
const WARN_RANGE_M: f64 = 0.8;

/// The fleet as the page shows it.
pub fn state(
    fleet: &Fleet,
    paused: bool,
    goal_places: &BTreeMap<String, String>,
    notices: Vec<String>,
) -> State {
    let snapshot = fleet.snapshot();
    let chairs = snapshot
        .chairs
        .iter()
        .map(|c| {
            let kind = fleet.body_kind(&c.name).unwrap_or_default();
            let display = fleet.display(&c.name).ok();
            let drive = fleet.drive_status(&c.name).unwrap_or_default();
            let pt = |p: &[f64; 2]| [round_cm(p[0]), round_cm(p[1])];
            ChairView {
                n: c.name.clone(),
                k: body_kind_name(kind),
                p: [
                    round_cm(c.pose[0]),
                    round_cm(c.pose[1]),
                    round_cm(c.pose[2]),
                ],
                v: [round_cm(c.twist[0]), round_cm(c.twist[1])],
                s: c.sonar_m.iter().map(|r| r.map_or(-1.0, round_cm)).collect(),
                g: c.goal.as_ref().map(pt),
                path: c.path.iter().map(pt).collect(),
                // the world's pose is ground truth for a virtual chair; a real or mixed one is
                // dead-reckoned: 1 % of the distance driven as its drift bound
                u: if kind == BodyKind::Virtual {
                    0.0
                } else {
                    round_cm(0.01 * c.distance_m)
                },
                c: c.collisions,
                d: ChairDisplay {
                    action: display
                        .as_ref()
                        .and_then(|d| d.last_command.as_ref())
                        .map_or_else(
                            || {
                                if c.twist[0].abs() > 0.01 || c.twist[1].abs() > 0.01 {
                                    "driving".to_string()
                                } else {
                                    "idle".to_string()
                                }
                            },
                            |cmd| format!("{cmd:?}"),
                        ),
                    goal: goal_places.get(&c.name).cloned(),
                    warn: c.twist[0].abs() > 0.01
                        && c.sonar_m.iter().flatten().any(|r| *r < WARN_RANGE_M),
                    seq: display.as_ref().and_then(|d| d.progress),
                    user: display
                        .as_ref()
                        .and_then(|d| d.drive)
                        .map(|d| [round_cm(d.linear_mps), round_cm(d.angular_radps)]),
                    answer: display.and_then(|d| d.last_answer),
                    applied: drive
                        .applied
                        .map(|v| [round_cm(v.linear_mps), round_cm(v.angular_radps)]),
                },
            }
        })
        .collect();
    let mut containers: Vec<ContainerView> = snapshot
        .chairs
        .iter()
        .map(|c| ContainerView {
            name: c.name.clone(),
            agents: c.agents.clone(),
        })
        .collect();
    containers.push(ContainerView {
        name: "services".into(),
        agents: snapshot.services.clone(),
    });
    State {
        t: snapshot.time_s as f32,
        paused,
        chairs,
        doors: snapshot.doors.clone(),
        containers,
        msgs: snapshot.recent.iter().map(message_view).collect(),
        notices,
        sent: fleet.messages_sent(),
        features: None,
        sec: Default::default(),
    }
}

/// The sniffer line of one frame: its performative and conversation read off the ACL text.
fn message_view(e: &Exchange) -> MessageView {
    let act = e
        .acl
        .trim_start()
        .trim_start_matches('(')
        .split_whitespace()
        .next()
        .unwrap_or("")
        .to_ascii_lowercase();
    let conv = e
        .acl
        .split(":conversation-id")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .map(|c| c.trim_matches(|ch| ch == '"' || ch == ')').to_string())
        .unwrap_or_default();
    MessageView {
        from: e.sender.clone(),
        to: e.receiver.clone(),
        act,
        conv,
        dropped: e.dropped,
    }
}

/// A body kind as the page and the demo print it (`virtual`, `real`, `mixed`).
pub fn body_kind_name(kind: BodyKind) -> String {
    match kind {
        BodyKind::Virtual => "virtual",
        BodyKind::Real => "real",
        BodyKind::Mixed => "mixed",
    }
    .to_owned()
}
