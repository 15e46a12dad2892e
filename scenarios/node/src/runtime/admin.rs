//! The admin path: commands the parent process gives a running container on its stdin
//! (`intellwheels spawn --admin-stdin`), one JSON object per line. The scenario runner plays a
//! scenario's goals, agent faults, blinded lasers and failed sensors through it.
//!
//! It is not a network path: only the process holding the pipe (the parent that started the
//! container) can write to it, so nothing on the bus or the control channel can reach it.

use std::collections::BTreeMap;
use std::sync::PoisonError;
use std::sync::mpsc::Receiver;

use iw_bus::Time;
use iw_wiring::world_link::{BodyRoster, FailedSensor, FrameFaults, WorldFaults};
use serde::Deserialize;

use super::Runtime;
use crate::Event;

/// Longest admin line, bytes; a longer one is refused whole.
pub const MAX_ADMIN_LINE: usize = 4096;

/// One admin command. The `admin` field names the variant.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(tag = "admin", rename_all = "kebab-case", deny_unknown_fields)]
pub enum AdminCommand {
    /// Services only: the staff console asks the assistant to send `chair` to `place` (a place
    /// of the map); the answers are reported as `goal` events.
    Goal {
        /// The chair.
        chair: String,
        /// A place of the map.
        place: String,
    },
    /// Removes this container's agent `agent` (its role: `control`, `watcher`, ...) as if it
    /// crashed after its take-down.
    KillAgent {
        /// The agent's role.
        agent: String,
    },
    /// World only: blinds chair `chair`'s laser (`blind`: its frames carry no ranges, the
    /// encoders and sonars read on) or gives it back.
    LaserBlind {
        /// A chair whose body is in this world.
        chair: String,
        /// Blind, or seeing again.
        blind: bool,
    },
    /// World only: fails chair `chair`'s `sensor` (`failed`: its frames carry garbage for that
    /// sensor's readings, the rest reads on) or restores it. `all` is refused: no frame says
    /// that every read fails (a world that sends nothing is an outage the chair waits out).
    SensorFailure {
        /// A chair whose body is in this world.
        chair: String,
        /// `laser` or `sonars`.
        sensor: FailedSensor,
        /// Failed, or restored.
        failed: bool,
    },
}

/// Hands `chair`'s goal `place` to the console under conversation number `conversations + 1`,
/// remembered in `given` so its answers are reported.
pub(super) fn give(
    desk: &mut iw_wiring::Desk,
    conversations: &mut u64,
    given: &mut BTreeMap<String, (String, String)>,
    chair: String,
    place: String,
) {
    *conversations += 1;
    let conversation = format!("goal-{chair}-{conversations}");
    desk.outbox
        .push_back((conversation.clone(), chair.clone(), place.clone()));
    given.insert(conversation, (chair, place));
}

impl Runtime {
    /// Takes admin commands from `commands` (checked every step) from now on.
    /// A command the reader could not take arrives as `Err(why)` and is reported as refused.
    pub fn with_admin(mut self, commands: Receiver<Result<AdminCommand, String>>) -> Runtime {
        self.admin = Some(commands);
        self
    }

    /// Carries out the admin commands that arrived; reports each as an `admin` event.
    pub(super) fn obey(&mut self, now: Time) {
        let Some(commands) = &self.admin else {
            return;
        };
        let commands: Vec<_> = commands.try_iter().collect();
        for command in commands {
            let (done, error) = match command {
                Err(why) => ("unreadable command".into(), Some(why)),
                Ok(AdminCommand::Goal { chair, place }) => {
                    let done = format!("goal {chair} {place}");
                    match &mut self.services {
                        Some(services) => {
                            give(
                                &mut iw_wiring::desk(&services.desk),
                                &mut services.conversations,
                                &mut services.given,
                                chair,
                                place,
                            );
                            (done, None)
                        }
                        None => (done, Some("only the services container gives goals".into())),
                    }
                }
                Ok(AdminCommand::LaserBlind { chair, blind }) => {
                    let done = format!("laser-blind {chair} {blind}");
                    let world = self.world.as_ref().map(|w| (&w.roster, &w.faults));
                    let set = frame_fault(world, &chair, "blinds a laser", |f| {
                        f.laser_blind = blind;
                    });
                    (done, set.err())
                }
                Ok(AdminCommand::SensorFailure {
                    chair,
                    sensor,
                    failed,
                }) => {
                    let done = format!("sensor-failure {chair} {sensor} {failed}");
                    let world = self.world.as_ref().map(|w| (&w.roster, &w.faults));
                    (done, fail_sensor(world, &chair, sensor, failed).err())
                }
                Ok(AdminCommand::KillAgent { agent }) => {
                    let name = iw_wiring::agent_id(&agent, &self.name).name;
                    let removed = self.host.remove(&name, now);
                    (
                        format!("kill-agent {name}"),
                        (!removed).then(|| format!("no agent `{name}` here")),
                    )
                }
            };
            let _ = self.events.send(Event::Admin {
                container: self.name.clone(),
                done,
                error,
            });
        }
    }
}

/// A world's bodies and the faults it plays in their frames (`None`: not the world container).
type WorldSide<'a> = Option<(&'a BodyRoster, &'a WorldFaults)>;

/// Fails (or restores) `sensor` of `chair`'s body in this world.
fn fail_sensor(
    world: WorldSide<'_>,
    chair: &str,
    sensor: FailedSensor,
    failed: bool,
) -> Result<(), String> {
    if sensor == FailedSensor::All {
        return Err(
            "a failure of every read (`all`) cannot be sent in a frame: a chair whose \
             world sends nothing waits it out as an outage; fail `laser` or `sonars`"
                .into(),
        );
    }
    frame_fault(world, chair, "fails a sensor", |f| {
        f.set_garbage(sensor, failed)
    })
}

/// Changes the faults of `chair`'s frames with `change`, if this is the world (`what` it does,
/// for the refusal elsewhere) and `chair` has a body in it.
fn frame_fault(
    world: WorldSide<'_>,
    chair: &str,
    what: &str,
    change: impl FnOnce(&mut FrameFaults),
) -> Result<(), String> {
    let Some((roster, faults)) = world else {
        return Err(format!("only the world container {what}"));
    };
    let attached = roster
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .contains_key(chair);
    if !attached {
        return Err(format!("no body of chair `{chair}` in this world"));
    }
    let mut faults = faults.lock().unwrap_or_else(PoisonError::into_inner);
    let mut now = faults.get(chair).copied().unwrap_or_default();
    change(&mut now);
    if now.none() {
        faults.remove(chair);
    } else {
        faults.insert(chair.to_string(), now);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The world's side of `laser-blind` and `sensor-failure`: a chair's faults are set and
    /// cleared one by one; every refusal says why.
    #[test]
    fn the_world_fails_a_chairs_sensors_and_refuses_with_the_reason() {
        let roster = BodyRoster::default();
        let faults = WorldFaults::default();
        roster
            .lock()
            .unwrap()
            .insert("chair1".into(), iw_sim::ChairId(0));
        let side = Some((&roster, &faults));
        let of = |chair: &str| faults.lock().unwrap().get(chair).copied();

        fail_sensor(side, "chair1", FailedSensor::Laser, true).unwrap();
        let laser = FrameFaults {
            laser_garbage: true,
            ..FrameFaults::default()
        };
        assert_eq!(of("chair1"), Some(laser));
        frame_fault(side, "chair1", "blinds a laser", |f| f.laser_blind = true).unwrap();
        fail_sensor(side, "chair1", FailedSensor::Sonars, true).unwrap();
        fail_sensor(side, "chair1", FailedSensor::Laser, false).unwrap();
        assert_eq!(
            of("chair1"),
            Some(FrameFaults {
                laser_blind: true,
                sonar_garbage: true,
                ..FrameFaults::default()
            })
        );
        fail_sensor(side, "chair1", FailedSensor::Sonars, false).unwrap();
        frame_fault(side, "chair1", "blinds a laser", |f| f.laser_blind = false).unwrap();
        assert_eq!(of("chair1"), None, "a chair with no fault left is dropped");

        // refused, each with its reason, and nothing changed
        let all = fail_sensor(side, "chair1", FailedSensor::All, true).unwrap_err();
        assert!(all.contains("`all`") && all.contains("outage"), "{all}");
        let nobody = fail_sensor(side, "chair9", FailedSensor::Laser, true).unwrap_err();
        assert_eq!(nobody, "no body of chair `chair9` in this world");
        let elsewhere = fail_sensor(None, "chair1", FailedSensor::Laser, true).unwrap_err();
        assert_eq!(elsewhere, "only the world container fails a sensor");
        assert!(faults.lock().unwrap().is_empty());
    }
}
