//! The Local Agent List (one container's agents) and the Global Agent List (everyone's), merged
//! by a version vector: one generation number per container, newest wins.

use std::collections::BTreeMap;

use iw_bus::transport::PeerAddr;

use crate::ContainerId;

/// One agent as the lists carry it: name, public key and where its container's bus listens.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct AgentEntry {
    /// The agent's name (its FIPA agent identifier's `:name`).
    pub name: String,
    /// The public key its messages are verified with (Ed25519, raw bytes): its container's
    /// identity key, which its control sessions are also agreed under, so a list is taken only
    /// if each entry carries the key of the container it is listed under.
    pub public_key: Vec<u8>,
    /// The bus address of its container.
    pub addr: PeerAddr,
}

/// The agents one container hosts, with a generation bumped on every change.
///
/// The generation starts at `incarnation << 32`, so a restarted container (higher incarnation)
/// supersedes what the others remember of its previous life.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LocalAgentList {
    generation: u64,
    agents: BTreeMap<String, AgentEntry>,
}

impl LocalAgentList {
    /// An empty list for a container in its `incarnation`-th life (e.g. boot time in seconds).
    pub fn new(incarnation: u32) -> Self {
        Self {
            generation: u64::from(incarnation) << 32,
            agents: BTreeMap::new(),
        }
    }

    /// Adds or replaces an agent.
    pub fn insert(&mut self, entry: AgentEntry) {
        self.agents.insert(entry.name.clone(), entry);
        self.generation += 1;
    }

    /// Removes an agent; `false` if it was not there (the generation is unchanged then).
    pub fn remove(&mut self, name: &str) -> bool {
        let removed = self.agents.remove(name).is_some();
        if removed {
            self.generation += 1;
        }
        removed
    }

    /// The agent named `name`.
    pub fn get(&self, name: &str) -> Option<&AgentEntry> {
        self.agents.get(name)
    }

    /// Current generation.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// The agents, by name.
    pub fn entries(&self) -> impl Iterator<Item = &AgentEntry> {
        self.agents.values()
    }

    /// This list as a part of the global list.
    pub fn to_part(&self) -> Part {
        Part {
            generation: self.generation,
            agents: self.agents.values().cloned().collect(),
        }
    }
}

/// One container's contribution to the global list, as of `generation`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Part {
    /// The container's LAL generation this part reflects.
    pub generation: u64,
    /// Its agents.
    pub agents: Vec<AgentEntry>,
}

impl Part {
    /// About how many bytes of JSON this part takes (a public key's bytes as numbers).
    fn wire_size(&self) -> usize {
        32 + self
            .agents
            .iter()
            .map(|a| a.name.len() + a.addr.0.len() + 4 * a.public_key.len() + 48)
            .sum::<usize>()
    }
}

/// Generations per container: what a global list knows.
pub type VersionVector = BTreeMap<ContainerId, u64>;

/// Every container's agents, one [`Part`] per container; merging keeps the newest part of each.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct GlobalAgentList {
    parts: BTreeMap<ContainerId, Part>,
}

impl GlobalAgentList {
    /// Takes `part` for container `id` if it is newer than what is held; returns whether it was.
    pub fn merge_part(&mut self, id: ContainerId, part: Part) -> bool {
        match self.parts.get(&id) {
            Some(held) if held.generation >= part.generation => false,
            _ => {
                self.parts.insert(id, part);
                true
            }
        }
    }

    /// Sets container `id`'s part to `part` whatever generation was held: the container itself
    /// (heard at its own address) is the authority on its list, so a part injected with a
    /// higher generation (up to `u64::MAX`) cannot pin it. Returns whether it changed.
    pub fn set_part(&mut self, id: ContainerId, part: Part) -> bool {
        if self.parts.get(&id) == Some(&part) {
            return false;
        }
        self.parts.insert(id, part);
        true
    }

    /// The parts a list holding `has` lacks or holds at another generation, except `skip`'s (the
    /// receiver's own), in container order, as many as fit about `budget` bytes of JSON (at
    /// least one): the rest follow in the next exchange. Returns them and whether all did fit.
    pub fn delta(
        &self,
        has: &VersionVector,
        skip: ContainerId,
        budget: usize,
    ) -> (GlobalAgentList, bool) {
        let mut out = GlobalAgentList::default();
        let mut used = 0;
        for (id, part) in &self.parts {
            if *id == skip || has.get(id) == Some(&part.generation) {
                continue;
            }
            let size = part.wire_size();
            if !out.parts.is_empty() && used + size > budget {
                return (out, false);
            }
            used += size;
            out.parts.insert(*id, part.clone());
        }
        (out, true)
    }

    /// Mirrors a leader's list sent as `versions` (the whole list's) and `delta` (parts this
    /// list lacked), except for container `own`'s part (kept from `self`). A part is kept at
    /// the leader's generation only: from `delta`, or held already when `held_from_leader`
    /// (the held parts came from this leader). Anything else is dropped, so a bogus generation
    /// another container once held is gone as soon as the leader speaks, and a part missing
    /// here is asked for again by the next heartbeat. Returns whether anything changed.
    pub fn adopt_delta(
        &mut self,
        versions: &VersionVector,
        delta: &GlobalAgentList,
        own: ContainerId,
        held_from_leader: bool,
    ) -> bool {
        let mut parts: BTreeMap<ContainerId, Part> = versions
            .iter()
            .filter(|(id, _)| **id != own)
            .filter_map(|(id, generation)| {
                let at = |p: &&Part| p.generation == *generation;
                let sent = delta.parts.get(id).filter(at);
                let held = || self.parts.get(id).filter(at).filter(|_| held_from_leader);
                sent.or_else(held).map(|p| (*id, p.clone()))
            })
            .collect();
        if let Some(mine) = self.parts.get(&own) {
            parts.insert(own, mine.clone());
        }
        let changed = parts != self.parts;
        self.parts = parts;
        changed
    }

    /// Keeps only the parts `keep` accepts.
    pub(crate) fn retain_parts(&mut self, mut keep: impl FnMut(ContainerId, &Part) -> bool) {
        self.parts.retain(|id, part| keep(*id, part));
    }

    /// Merges every part of `other`; returns whether anything changed. Commutative, idempotent.
    pub fn merge(&mut self, other: &GlobalAgentList) -> bool {
        let mut changed = false;
        for (id, part) in &other.parts {
            changed |= self.merge_part(*id, part.clone());
        }
        changed
    }

    /// The generation held per container.
    pub fn versions(&self) -> VersionVector {
        self.parts
            .iter()
            .map(|(id, p)| (*id, p.generation))
            .collect()
    }

    /// The agent named `name` and the container hosting it (lowest container id if two claim it).
    pub fn lookup(&self, name: &str) -> Option<(ContainerId, &AgentEntry)> {
        self.parts
            .iter()
            .find_map(|(id, p)| p.agents.iter().find(|a| a.name == name).map(|a| (*id, a)))
    }

    /// All agents with their containers.
    pub fn entries(&self) -> impl Iterator<Item = (ContainerId, &AgentEntry)> {
        self.parts
            .iter()
            .flat_map(|(id, p)| p.agents.iter().map(move |a| (*id, a)))
    }

    /// Number of agents.
    pub fn len(&self) -> usize {
        self.parts.values().map(|p| p.agents.len()).sum()
    }

    /// Whether no container has contributed agents.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(name: &str) -> AgentEntry {
        AgentEntry {
            name: name.into(),
            public_key: vec![1, 2, 3],
            addr: PeerAddr("127.0.0.1:1".into()),
        }
    }

    #[test]
    fn generations_count_changes_and_incarnations_supersede() {
        let mut lal = LocalAgentList::new(1);
        lal.insert(entry("a"));
        assert!(!lal.remove("nobody"));
        assert!(lal.remove("a"));
        assert_eq!(lal.generation(), (1 << 32) + 2);
        let mut gal = GlobalAgentList::default();
        assert!(gal.merge_part(ContainerId(7), lal.to_part()));
        let mut reborn = LocalAgentList::new(2);
        reborn.insert(entry("b"));
        assert!(gal.merge_part(ContainerId(7), reborn.to_part()));
        assert!(
            !gal.merge_part(ContainerId(7), lal.to_part()),
            "the older life is ignored"
        );
        assert_eq!(gal.lookup("b").map(|(id, _)| id), Some(ContainerId(7)));
    }

    #[test]
    fn merge_is_commutative_and_idempotent() {
        let part = |g: u64, names: &[&str]| Part {
            generation: g,
            agents: names.iter().map(|n| entry(n)).collect(),
        };
        let mut x = GlobalAgentList::default();
        x.merge_part(ContainerId(1), part(3, &["a"]));
        x.merge_part(ContainerId(2), part(1, &["b"]));
        let mut y = GlobalAgentList::default();
        y.merge_part(ContainerId(1), part(2, &["old"]));
        y.merge_part(ContainerId(3), part(5, &["c"]));
        let mut xy = x.clone();
        xy.merge(&y);
        let mut yx = y.clone();
        yx.merge(&x);
        assert_eq!(xy, yx);
        assert!(!xy.clone().merge(&yx));
        assert_eq!(xy.len(), 3);
        assert!(xy.lookup("old").is_none());
    }

    #[test]
    fn a_pinned_generation_is_replaced_by_its_owner_and_by_the_leader() {
        let part = |g: u64, names: &[&str]| Part {
            generation: g,
            agents: names.iter().map(|n| entry(n)).collect(),
        };
        let mut gal = GlobalAgentList::default();
        gal.merge_part(ContainerId(1), part(u64::MAX, &["evil"]));
        assert!(
            !gal.merge_part(ContainerId(1), part(5, &["real"])),
            "merge is pinned"
        );
        assert!(gal.set_part(ContainerId(1), part(5, &["real"])));
        assert_eq!(gal.lookup("real").map(|(id, _)| id), Some(ContainerId(1)));
        let mut follower = GlobalAgentList::default();
        follower.merge_part(ContainerId(1), part(u64::MAX, &["evil"]));
        follower.merge_part(ContainerId(9), part(2, &["mine"]));
        let mut leader = gal.clone();
        leader.merge_part(ContainerId(9), part(1, &["stale-view-of-mine"]));
        let (delta, whole) = leader.delta(&follower.versions(), ContainerId(9), usize::MAX);
        assert!(whole);
        assert!(follower.adopt_delta(&leader.versions(), &delta, ContainerId(9), true));
        assert!(follower.lookup("evil").is_none());
        assert!(follower.lookup("mine").is_some(), "own part kept");
        assert!(follower.lookup("stale-view-of-mine").is_none());
    }

    #[test]
    fn a_delta_carries_only_what_the_receiver_lacks_within_its_budget() {
        let part = |g: u64, name: &str| Part {
            generation: g,
            agents: vec![entry(name)],
        };
        let mut leader = GlobalAgentList::default();
        for id in 1..=5 {
            leader.merge_part(ContainerId(id), part(id, &format!("a{id}")));
        }
        let mut follower = GlobalAgentList::default();
        follower.merge_part(ContainerId(1), part(1, "a1"));
        follower.merge_part(ContainerId(2), part(1, "old-a2"));
        follower.merge_part(ContainerId(5), part(9, "mine"));
        let one = part(3, "a3").wire_size();
        let (delta, whole) = leader.delta(&follower.versions(), ContainerId(5), 2 * one);
        assert!(!whole, "three parts are lacking, two fit");
        assert_eq!(
            delta.versions().into_keys().collect::<Vec<_>>(),
            [ContainerId(2), ContainerId(3)]
        );
        assert!(follower.adopt_delta(&leader.versions(), &delta, ContainerId(5), true));
        assert_eq!(
            follower.lookup("a2").map(|(id, _)| id),
            Some(ContainerId(2))
        );
        assert!(
            follower.lookup("a1").is_some(),
            "held at the leader's generation"
        );
        assert!(
            follower.lookup("a4").is_none(),
            "follows in the next exchange"
        );
        assert!(follower.lookup("mine").is_some());
        let (rest, whole) = leader.delta(&follower.versions(), ContainerId(5), 2 * one);
        assert!(whole);
        assert_eq!(rest.len(), 1);
        follower.adopt_delta(&leader.versions(), &rest, ContainerId(5), true);
        assert_eq!(follower.len(), 5);
        // Held parts from another leader are not trusted: only what this one sent is kept.
        let mut other = follower.clone();
        assert!(other.adopt_delta(&leader.versions(), &rest, ContainerId(5), false));
        assert_eq!(other.len(), 2);
    }
}
