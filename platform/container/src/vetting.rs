//! Who may speak for which container, beneath the first-come binding of [`crate::Container`]:
//! the deployment's [`Roster`] when there is one, and the rule that a list entry carries its
//! container's key. Every refusal is counted per [`Reason`] and warned at most once per
//! [`iw_bus::WARN_PERIOD`] per kind.

use std::sync::Arc;
use std::time::Duration;

use iw_bus::transport::PeerAddr;
use iw_bus::{Counters, Reason, Time, WarnEvery};
use iw_layer_security::PublicKey;

use crate::lists::{GlobalAgentList, Part};
use crate::{ContainerId, ContainerMsg, Roster};

/// The id a message speaks for: a heartbeat's or a list's sender, a global list's leader. A
/// `Duplicate` speaks about the receiver's id, not for its sender (see
/// [`Vetting::believes_duplicate`]).
pub(crate) fn speaker(msg: &ContainerMsg) -> Option<ContainerId> {
    match msg {
        ContainerMsg::Heartbeat { id, .. } | ContainerMsg::Lal { id, .. } => Some(*id),
        ContainerMsg::Gal { leader, .. } => Some(*leader),
        ContainerMsg::Duplicate { .. } => None,
    }
}

/// A frame's claim about container `id`: the identity whose session carried it and where it came
/// from.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Claim<'a> {
    /// The container the frame speaks for (or, a `Duplicate`, about).
    pub(crate) id: ContainerId,
    /// The identity bound to the session that carried it.
    pub(crate) key: &'a PublicKey,
    /// The address it came from.
    pub(crate) from: &'a PeerAddr,
}

/// A container's checks of who speaks for whom, with their counters.
#[derive(Debug)]
pub(crate) struct Vetting {
    roster: Option<Arc<Roster>>,
    counters: Counters,
    warn: WarnEvery<&'static str>,
    last_probe: Option<Time>,
}

impl Vetting {
    pub(crate) fn new(roster: Option<Arc<Roster>>) -> Self {
        Self {
            roster,
            counters: Counters::default(),
            warn: WarnEvery::new(iw_bus::WARN_PERIOD),
            last_probe: None,
        }
    }

    pub(crate) fn roster(&self) -> Option<&Roster> {
        self.roster.as_deref()
    }

    pub(crate) fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Counts a refusal that is warned elsewhere.
    pub(crate) fn count(&mut self, reason: Reason) {
        self.counters.record(reason);
    }

    /// Counts a refusal and runs `warn` (with how many were held back) when a warning of `kind`
    /// is due.
    fn refuse(&mut self, reason: Reason, kind: &'static str, now: Time, warn: impl FnOnce(u64)) {
        self.counters.record(reason);
        match self.warn.admit(kind, now) {
            Some(held_back) => warn(held_back),
            None => tracing::debug!(kind, "control frame refused"),
        }
    }

    /// Whether a frame under identity `key` may speak for container `id`: under a roster only under
    /// `id`'s pinned key (an id the roster does not list is nobody's); without one, anyone may
    /// (the container then binds a live id to the first key heard).
    pub(crate) fn speaks_for(&mut self, claim: Claim<'_>, now: Time) -> bool {
        let Claim { id, key, from } = claim;
        let Some(roster) = self.roster.clone() else {
            return true;
        };
        match roster.get(id) {
            Some(pin) if pin.key == *key => true,
            Some(pin) => {
                self.refuse(Reason::Mismatch, "unpinned-key", now, |held_back| {
                    tracing::warn!(container = %id, name = %pin.name, %from, roster = roster.source(), held_back, "control frame for a container not under the key the roster pins for it: refused (one warning per 10 s)");
                });
                false
            }
            None => {
                self.refuse(Reason::UnknownPeer, "unlisted-id", now, |held_back| {
                    tracing::warn!(container = %id, %from, roster = roster.source(), held_back, "control frame for a container id the roster does not list: refused (one warning per 10 s)");
                });
                false
            }
        }
    }

    /// Whether `part`, said to be container `id`'s, carries only that container's agents: each
    /// entry's key is the container's (its agents are verified with its identity): the pinned
    /// key under a roster, else `key` when known (the sender of its list, or the key its live
    /// id is bound to), else one key for all; and under a roster each name is `ROLE@NAME` for
    /// the pinned name.
    pub(crate) fn vet_part(
        &mut self,
        id: ContainerId,
        key: Option<&PublicKey>,
        part: &Part,
        from: &PeerAddr,
        now: Time,
    ) -> bool {
        let pin = match self.roster.clone() {
            None => None,
            Some(roster) => match roster.get(id) {
                Some(pin) => Some(pin.clone()),
                None => {
                    // a part of a container the roster does not list (in the leader's list)
                    self.refuse(Reason::UnknownPeer, "unlisted-part", now, |held_back| {
                        tracing::warn!(container = %id, %from, roster = roster.source(), held_back, "agent list part of a container id the roster does not list: refused (one warning per 10 s)");
                    });
                    return false;
                }
            },
        };
        let want: Option<Vec<u8>> = match (&pin, key) {
            (Some(pin), _) => Some(pin.key.to_vec()),
            (None, Some(key)) => Some(key.to_vec()),
            (None, None) => part.agents.first().map(|a| a.public_key.clone()),
        };
        let foreign = part.agents.iter().find(|a| {
            want.as_ref().is_some_and(|w| a.public_key != *w)
                || pin.as_ref().is_some_and(|p| !p.hosts(&a.name))
        });
        match foreign {
            None => true,
            Some(entry) => {
                let agent = entry.name.clone();
                self.refuse(Reason::Mismatch, "foreign-agent", now, |held_back| {
                    tracing::warn!(container = %id, %agent, %from, held_back, "agent list part carries an agent that is not its container's (another container's name or key): refused (one warning per 10 s)");
                });
                false
            }
        }
    }

    /// The leader's `gal` without the parts that carry agents not their container's
    /// ([`Vetting::vet_part`]); `known` gives the key a container's live id is bound to here.
    pub(crate) fn vet_gal(
        &mut self,
        mut gal: GlobalAgentList,
        known: impl Fn(ContainerId) -> Option<PublicKey>,
        from: &PeerAddr,
        now: Time,
    ) -> GlobalAgentList {
        gal.retain_parts(|id, part| self.vet_part(id, known(id).as_ref(), part, from, now));
        gal
    }

    /// Whether a `Duplicate` about this container's id `id`, under `key`, is believed:
    /// under a roster only under `id`'s pinned key (this container's own: only a second holder
    /// of its identity can hold its id), else from anyone who passed admission.
    pub(crate) fn believes_duplicate(&mut self, claim: Claim<'_>, now: Time) -> bool {
        let Claim { id, key, from } = claim;
        let Some(roster) = self.roster.clone() else {
            return true;
        };
        if roster.get(id).is_some_and(|pin| pin.key == *key) {
            return true;
        }
        self.refuse(Reason::Mismatch, "unpinned-duplicate", now, |held_back| {
            tracing::warn!(container = %id, %from, held_back, "a `Duplicate` not under this container's pinned key is not believed; its named holder is greeted instead, and answers itself if it holds this identity (one warning per 10 s)");
        });
        false
    }

    /// Whether an unbelieved `Duplicate`'s named holder may be greeted now: once per `period`,
    /// so forged reports make this container send at most one heartbeat per period.
    pub(crate) fn probe_due(&mut self, now: Time, period: Duration) -> bool {
        if self.last_probe.is_some_and(|t| now.since(t) < period) {
            return false;
        }
        self.last_probe = Some(now);
        true
    }
}
