//! Checks each [`Assertion`] over the typed [`Observation`]s of a run, the same way in both
//! modes.

use iw_acl::Performative;

use crate::ScenarioError;
use crate::observe::{Observation, Totals, door_answers};
use crate::report::{ChairSummary, Outcome};
use crate::schema::{Assertion, Scenario};

/// Slack on deadlines, s (a deadline is inclusive).
const EPS: f64 = 1e-9;
/// Below this a chair counts as stopped, m/s.
const STOPPED_MPS: f64 = 0.02;

/// The outcome of every assertion of `scenario` over `seen`, `totals` and the chairs at the end.
pub fn check(
    scenario: &Scenario,
    seen: &[Observation],
    totals: &Totals,
    chairs: &[ChairSummary],
) -> Vec<Outcome> {
    let door_agent = iw_fleet::compose::agent_id("door", iw_fleet::SERVICES).name;
    let answers = door_answers(seen, &door_agent);
    scenario
        .assertions
        .iter()
        .map(|assertion| {
            let (passed, detail) = match assertion {
                Assertion::NoCollision { chair } => {
                    let hits: Vec<String> = chairs
                        .iter()
                        .filter(|c| chair.as_ref().is_none_or(|n| n == &c.name) && c.collisions > 0)
                        .map(|c| format!("{} {}", c.name, c.collisions))
                        .collect();
                    if hits.is_empty() {
                        (true, "no contact".into())
                    } else {
                        (false, format!("contacts: {}", hits.join(", ")))
                    }
                }
                Assertion::GoalReached {
                    chair,
                    by_s,
                    within_m,
                } => {
                    let reached = reached_at(seen, chair, *within_m).filter(|t| *t <= by_s + EPS);
                    let done = answer_at(seen, chair, Performative::Inform, *by_s);
                    let detail = match (reached, done) {
                        (Some(t), Some(d)) => {
                            format!("within tolerance at {t:.2} s, done reported at {d:.2} s")
                        }
                        (Some(t), None) => {
                            format!("within tolerance at {t:.2} s but no done reported by {by_s} s")
                        }
                        (None, _) => format!("not within tolerance by {by_s} s"),
                    };
                    (reached.is_some() && done.is_some(), detail)
                }
                Assertion::GoalFailed { chair, by_s } => {
                    let no_path = seen.iter().find_map(|o| match o {
                        Observation::NoPath { time_s, chair: c }
                            if c == chair && *time_s <= by_s + EPS =>
                        {
                            Some(*time_s)
                        }
                        _ => None,
                    });
                    match (
                        answer_at(seen, chair, Performative::Failure, *by_s),
                        no_path,
                    ) {
                        (Some(t), _) => (true, format!("failure reported at {t:.2} s")),
                        (None, Some(t)) => (true, format!("no path at {t:.2} s")),
                        (None, None) => (false, format!("no failure reported by {by_s} s")),
                    }
                }
                Assertion::Stopped { chair, from_s } => {
                    let fastest = seen
                        .iter()
                        .filter_map(|o| match o {
                            Observation::Body {
                                time_s,
                                chair: c,
                                speed_mps,
                                ..
                            } if c == chair && *time_s >= *from_s => Some(*speed_mps),
                            _ => None,
                        })
                        .fold(0.0, f64::max);
                    (
                        fastest < STOPPED_MPS,
                        format!("highest speed afterwards {fastest:.3} m/s"),
                    )
                }
                Assertion::LandmarkVisited {
                    chair,
                    from_s,
                    by_s,
                    within_m,
                } => match landmark_stops(scenario) {
                    Ok(stops) => {
                        let visit = seen.iter().find_map(|o| match o {
                            Observation::Body {
                                time_s,
                                chair: c,
                                pose,
                                ..
                            } if c == chair && *time_s >= from_s - EPS && *time_s <= by_s + EPS => {
                                stops
                                    .iter()
                                    .find(|s| (pose[0] - s[0]).hypot(pose[1] - s[1]) <= *within_m)
                                    .map(|s| (*time_s, *s))
                            }
                            _ => None,
                        });
                        match visit {
                            Some((t, s)) => (
                                true,
                                format!(
                                    "at the landmark stop ({:.2}, {:.2}) at {t:.2} s",
                                    s[0], s[1]
                                ),
                            ),
                            None => (
                                false,
                                format!(
                                    "at none of {} landmark stops from {from_s} s to {by_s} s",
                                    stops.len()
                                ),
                            ),
                        }
                    }
                    Err(why) => (false, format!("no landmark stops: {why}")),
                },
                Assertion::MessagesDropped { at_least } => (
                    totals.dropped >= *at_least,
                    format!("{} dropped", totals.dropped),
                ),
                Assertion::DoorRefused { chair, door } => {
                    let requester = iw_fleet::compose::agent_id("cognitive", chair).name;
                    let name = iw_fleet::compose::door_name(door);
                    let refusals: Vec<_> = answers
                        .iter()
                        .filter(|a| a.performative == Performative::Refuse)
                        .collect();
                    match refusals
                        .iter()
                        .find(|a| a.requester == requester && a.door == name)
                    {
                        Some(a) => (
                            true,
                            format!("refused: {}", a.reason.as_deref().unwrap_or("no reason")),
                        ),
                        None => (
                            false,
                            format!(
                                "{} refusals, none of `{name}` for {requester}",
                                refusals.len()
                            ),
                        ),
                    }
                }
                Assertion::DoorFailed { door } => {
                    let name = iw_fleet::compose::door_name(door);
                    let failures = answers
                        .iter()
                        .filter(|a| a.performative == Performative::Failure && a.door == name)
                        .count();
                    (
                        failures > 0,
                        format!("{failures} FAILURE answers about `{name}`"),
                    )
                }
                Assertion::AllMessagesLogged => (
                    totals.sent > 0 && totals.logged == totals.sent,
                    format!(
                        "{} messages sent, {} in the log",
                        totals.sent, totals.logged
                    ),
                ),
            };
            Outcome {
                assertion: serde_json::to_string(assertion).unwrap_or_default(),
                passed,
                detail,
            }
        })
        .collect()
}

/// Where the chairs stop to read a landmark's marker on the scenario's map, as their cognitive
/// agents plan it.
fn landmark_stops(scenario: &Scenario) -> Result<Vec<[f64; 2]>, ScenarioError> {
    let building =
        iw_fleet::compose::Building::from_map(scenario.load_map()?).map_err(|source| {
            ScenarioError::Plan {
                path: scenario.source.display().to_string(),
                source,
            }
        })?;
    Ok(building
        .plan
        .landmarks
        .iter()
        .map(|l| [l.at.x, l.at.y])
        .collect())
}

/// When `chair` was first within `within_m` of the goal it had been given last.
fn reached_at(seen: &[Observation], chair: &str, within_m: f64) -> Option<f64> {
    let mut goal: Option<[f64; 2]> = None;
    for o in seen {
        match o {
            Observation::GoalGiven {
                chair: c, target, ..
            } if c == chair => goal = Some(*target),
            Observation::Body {
                time_s,
                chair: c,
                pose,
                ..
            } if c == chair
                && goal.is_some_and(|g| (pose[0] - g[0]).hypot(pose[1] - g[1]) <= within_m) =>
            {
                return Some(*time_s);
            }
            _ => {}
        }
    }
    None
}

/// When the console first got `performative` about one of `chair`'s goals, by `by_s`.
fn answer_at(
    seen: &[Observation],
    chair: &str,
    performative: Performative,
    by_s: f64,
) -> Option<f64> {
    seen.iter().find_map(|o| match o {
        Observation::Answer {
            time_s,
            chair: c,
            performative: p,
        } if c == chair && *p == performative && *time_s <= by_s + EPS => Some(*time_s),
        _ => None,
    })
}
