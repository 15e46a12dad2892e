//! The admin path: commands the parent process gives a running container on its stdin
//! (`intellwheels spawn --admin-stdin`), one JSON object per line. The scenario runner plays a
//! scenario's goals, agent faults and blinded lasers through it.
//!
//! It is not a network path: only the process holding the pipe (the parent that started the
//! container) can write to it, so nothing on the bus or the control channel can reach it.

use std::collections::BTreeMap;
use std::sync::mpsc::Receiver;

use iw_bus::Time;
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
                    (done, self.blind_laser(&chair, blind).err())
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

    /// Blinds (or gives back) the laser of `chair`'s body in this world.
    fn blind_laser(&self, chair: &str, blind: bool) -> Result<(), String> {
        let Some(world) = &self.world else {
            return Err("only the world container blinds a laser".into());
        };
        let attached = world
            .roster
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .contains_key(chair);
        if !attached {
            return Err(format!("no body of chair `{chair}` in this world"));
        }
        let mut lasers = world
            .blind
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if blind {
            lasers.insert(chair.to_string());
        } else {
            lasers.remove(chair);
        }
        Ok(())
    }
}
