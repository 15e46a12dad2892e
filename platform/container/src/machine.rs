//! The container state machine: heartbeats, leases, lowest-id election and list distribution.
//! Pure: it is driven by `on_message`/`on_tick` with an explicit [`Time`] and returns the frames
//! to send, so every behaviour is tested in simulated time.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use std::time::Duration;

use iw_bus::Time;
use iw_bus::transport::PeerAddr;
use iw_layer_security::PublicKey;

use crate::lists::{AgentEntry, GlobalAgentList, LocalAgentList, Part, VersionVector};
use crate::vetting::{Claim, Vetting, speaker};
use crate::{Authenticated, ContainerError, ContainerId, Roster};

/// What containers say to each other.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ContainerMsg {
    /// "I am alive": sent to every known container every heartbeat period while the lists are
    /// settling, every idle period once they agree, and at once after a change.
    Heartbeat {
        /// Sender.
        id: ContainerId,
        /// The sender's incarnation: a higher one from the same address is a restart.
        incarnation: u32,
        /// Whom the sender takes for leader.
        leader: ContainerId,
        /// The sender's LAL generation.
        lal_generation: u64,
        /// What the sender's GAL holds (a follower: only what it took from the leader it names,
        /// and its own part).
        gal_versions: VersionVector,
    },
    /// A follower's LAL, sent to the leader when the leader's GAL lacks its latest generation.
    Lal {
        /// Sender.
        id: ContainerId,
        /// Its list.
        part: Part,
    },
    /// The leader's GAL as far as a follower lacks it, sent when the follower's heartbeat
    /// shows it differs: the follower mirrors `versions` from the parts it holds and `gal`.
    Gal {
        /// The leader.
        leader: ContainerId,
        /// What the leader's whole list holds.
        versions: VersionVector,
        /// The parts the follower lacks (as many as fit one frame; the rest follow its next
        /// heartbeat).
        gal: GlobalAgentList,
    },
    /// "Container `id` is already live at `holder`": sent to a container whose heartbeat claims
    /// an id another live container holds (from another address or under another key). The
    /// newcomer refuses to run (see [`Container::refusal`]); the holder is not disturbed.
    Duplicate {
        /// The contested id.
        id: ContainerId,
        /// Where the live holder of `id` is heard.
        holder: PeerAddr,
        /// The holder's incarnation.
        holder_incarnation: u32,
        /// How long the holder has run (told by the holder itself) or been heard (told by a
        /// third party), ms: when two containers claim one id, the one running longer keeps it.
        holder_uptime_ms: u64,
    },
}

impl ContainerMsg {
    /// Encodes for a frame transport (JSON: control traffic is small and rare).
    pub fn encode(&self) -> Result<Vec<u8>, ContainerError> {
        serde_json::to_vec(self).map_err(|source| ContainerError::Encode { source })
    }

    /// Decodes a frame; anything else is [`ContainerError::BadMessage`].
    pub fn decode(frame: &[u8]) -> Result<Self, ContainerError> {
        serde_json::from_slice(frame).map_err(|source| ContainerError::BadMessage {
            len: frame.len(),
            source,
        })
    }
}

/// A frame to send.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outgoing {
    /// Destination container.
    pub to: PeerAddr,
    /// What to say.
    pub msg: ContainerMsg,
}

/// Settings of one container.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ContainerConfig {
    /// This container's id; the lowest live id leads.
    pub id: ContainerId,
    /// Its incarnation (e.g. boot time, s): must grow across restarts so its LAL supersedes.
    pub incarnation: u32,
    /// The Ed25519 public key of the identity its control sessions are agreed with
    /// ([`crate::ContainerNode::start`] sets it from that identity).
    pub key: PublicKey,
    /// Where it listens for container traffic.
    pub addr: PeerAddr,
    /// Other containers' addresses to greet (the ids are learnt from their heartbeats).
    pub seeds: Vec<PeerAddr>,
    /// Heartbeat period while the lists settle (default 50 ms). Once they agree a container
    /// heartbeats every [`ContainerConfig::idle_heartbeat`] instead.
    pub heartbeat: Duration,
    /// A container not heard for this long is taken for dead (default 250 ms; several
    /// heartbeats).
    pub lease: Duration,
    /// The deployment's pinned identities (default none: ids are bound to keys first come,
    /// first served, the weaker mode). With a roster, a frame speaks for an id only under that
    /// id's pinned key, an id it does not list is nobody's, list entries must be named for
    /// their container, and a `Duplicate` is believed only under this container's own pinned
    /// key.
    pub roster: Option<Arc<Roster>>,
}

impl ContainerConfig {
    /// Default periods for container `id` at `addr` greeting `seeds`.
    pub fn new(id: ContainerId, addr: PeerAddr, seeds: Vec<PeerAddr>) -> Self {
        Self {
            id,
            incarnation: 0,
            key: [0; 32],
            addr,
            seeds,
            heartbeat: Duration::from_millis(50),
            lease: Duration::from_millis(250),
            roster: None,
        }
    }

    /// The heartbeat period once the lists agree: a fifth of the lease (five heartbeats per
    /// lease, as the defaults' 50/250 ms), never shorter than `heartbeat`.
    pub fn idle_heartbeat(&self) -> Duration {
        (self.lease / 5).max(self.heartbeat)
    }
}

/// `versions` without container `id`'s entry.
fn others(versions: &VersionVector, id: ContainerId) -> impl Iterator<Item = (&ContainerId, &u64)> {
    versions.iter().filter(move |(c, _)| **c != id)
}

/// About how many bytes of agent entries one [`ContainerMsg::Gal`] carries: half the largest UDP
/// datagram, so a frame with its session's seal and the group key's always fits one.
const LIST_FRAME_BUDGET: usize = 32 * 1024;

/// What is known of a live peer.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Peer {
    addr: PeerAddr,
    /// The identity key its frames come under: a live id is bound to it.
    key: PublicKey,
    incarnation: u32,
    /// The highest sequence number taken from it in this incarnation (replays are refused).
    seq: u64,
    /// When this incarnation was first heard.
    since: Time,
    last_heard: Time,
    leader: ContainerId,
    gal_versions: VersionVector,
    /// The last list sent to it (leader only): what our list and its list held then, and when.
    /// The same answer is not repeated within two heartbeats (its heartbeat crossed the list in
    /// flight).
    answered: Option<(VersionVector, VersionVector, Time)>,
}

/// One container: its LAL, its copy of the GAL, the live peers and the elected leader.
///
/// Election: every container takes the lowest id among itself and the peers whose lease holds
/// (bully order, decided locally from heartbeats, so no extra round trips). The leader merges
/// the LALs into the GAL and sends the GAL to any follower whose heartbeat shows it differs; a
/// follower sends its LAL when the leader's heartbeat lacks its generation. Losing the leader or
/// the network never touches the LAL: local agents keep resolving; a partition elects its own
/// leader and the lists converge again when it heals.
///
/// Cost: a container heartbeats to its seeds and to the peers that heartbeat to it, so where
/// chairs greet the services only (every deployment of this repository) the leader hears N
/// containers and each chair one. A list goes as a delta: the parts the follower's heartbeat
/// shows it lacks, at most 32 KiB a frame. Heartbeats go every `heartbeat` while anything
/// differs and every [`ContainerConfig::idle_heartbeat`] once the lists agree; a change (a new
/// peer, a list taken) is told at the next tick.
///
/// Who may say what (the control channel's own rules, beneath its group key). Every message
/// comes [`Authenticated`] by a session agreed with its sender's Ed25519 identity, and:
/// - a live peer is bound to the identity key its heartbeats come under and the address they
///   come from:
///   a heartbeat claiming a live id under another key or from another address is answered with
///   [`ContainerMsg::Duplicate`] and otherwise ignored; one claiming our own id likewise. A higher
///   incarnation under the same key from the same address is a restart; a sequence number not
///   above the last one taken from that life is a replay, ignored;
/// - a LAL is taken only by the leader, only under its container's bound key and address and
///   current incarnation, and replaces that container's part (the container is the authority on
///   it);
/// - a GAL is taken only under the bound key and address of the container we elected, and a
///   follower mirrors it (keeping its own part), so no generation, however high, pins a route;
/// - of two containers claiming one id, the one that has run longer keeps it: told by the holder
///   itself, a container that ran a lease longer than the holder answers in kind (so the younger
///   refuses), and otherwise refuses.
/// - beneath these, a list part is taken only if each entry carries its container's key; and
///   with a roster ([`ContainerConfig::roster`]) a frame speaks for an id only under its pinned
///   key, a part carries only agents named for its container, and a `Duplicate` is believed only
///   under this container's own pinned key (see the crate docs).
#[derive(Debug)]
pub struct Container {
    config: ContainerConfig,
    lal: LocalAgentList,
    gal: GlobalAgentList,
    peers: BTreeMap<ContainerId, Peer>,
    leader: ContainerId,
    elections: u64,
    next_heartbeat: Time,
    /// When the last heartbeat went: a change is told one heartbeat period after it at most.
    last_heartbeat: Time,
    /// The leader whose list this GAL mirrors: held parts are trusted only from it. Leading
    /// alone for a while (its lease missed) does not change it, so the same leader back needs
    /// to send only what changed.
    gal_from: ContainerId,
    /// Bumped on every change of the GAL, the live peers or the leader.
    revision: u64,
    refusal: Option<String>,
    /// When this container first ran (its first tick or message).
    started: Option<Time>,
    /// When a duplicate id was last reported per contested id (one WARN per lease, not per frame).
    duplicate_warned: BTreeMap<ContainerId, Time>,
    /// The roster's and the list entries' checks, with their rejection counters.
    vetting: Vetting,
}

impl Container {
    /// A container alone, leading itself until it hears lower ids.
    pub fn new(config: ContainerConfig) -> Self {
        let lal = LocalAgentList::new(config.incarnation);
        let mut gal = GlobalAgentList::default();
        gal.merge_part(config.id, lal.to_part());
        Self {
            leader: config.id,
            gal_from: config.id,
            lal,
            gal,
            peers: BTreeMap::new(),
            elections: 0,
            next_heartbeat: Time::ZERO,
            last_heartbeat: Time::ZERO,
            revision: 0,
            refusal: None,
            started: None,
            duplicate_warned: BTreeMap::new(),
            vetting: Vetting::new(config.roster.clone()),
            config,
        }
    }

    /// Why this container must not run: another live container holds its id. Once set, the
    /// container says nothing more (no heartbeats, no lists).
    pub fn refusal(&self) -> Option<&str> {
        self.refusal.as_deref()
    }

    /// Sets the key of the identity this container's control sessions are agreed with.
    pub(crate) fn set_key(&mut self, key: PublicKey) {
        self.config.key = key;
    }

    /// The roster this container checks identities against, if any.
    pub fn roster(&self) -> Option<&Roster> {
        self.vetting.roster()
    }

    /// Control frames refused, per reason: by the sessions (`not_sealed`, `bad_tag`,
    /// `unknown_session`, `duplicate`, `bad_handshake`, `bad_signature`, `stale`, and
    /// `malformed` for a frame that is no container message), or for whose identity they came
    /// under or what their lists carry (`unknown_peer`: an id the roster does not list;
    /// `mismatch`: a key not pinned for its id, a list entry not its container's, a `Duplicate`
    /// not under the pinned key).
    pub fn counters(&self) -> &iw_bus::Counters {
        self.vetting.counters()
    }

    /// Counts a control datagram the sessions refused.
    pub(crate) fn refused(&mut self, reason: iw_bus::Reason) {
        self.vetting.count(reason);
    }

    /// This container's id.
    pub fn id(&self) -> ContainerId {
        self.config.id
    }

    /// The container taken for leader now.
    pub fn leader(&self) -> ContainerId {
        self.leader
    }

    /// How many times the leader changed.
    pub fn elections(&self) -> u64 {
        self.elections
    }

    /// When [`Container::on_tick`] next has something to do: the next heartbeat, or the
    /// earliest lease to expire. Until then a tick only costs its wake-up.
    pub fn next_due(&self) -> Time {
        let lease = self.config.lease;
        self.peers
            .values()
            .map(|p| p.last_heard.plus(lease))
            .fold(self.next_heartbeat, Time::min)
    }

    /// A number that grows whenever the GAL, the live peers or the leader change: a reader of
    /// the lists need not look again while it stands.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Live peers' ids.
    pub fn live_peers(&self) -> BTreeSet<ContainerId> {
        self.peers.keys().copied().collect()
    }

    /// The Local Agent List.
    pub fn lal(&self) -> &LocalAgentList {
        &self.lal
    }

    /// This container's copy of the Global Agent List.
    pub fn gal(&self) -> &GlobalAgentList {
        &self.gal
    }

    /// Hosts an agent here (replacing one of the same name).
    pub fn register(&mut self, entry: AgentEntry) {
        self.lal.insert(entry);
        self.gal.merge_part(self.config.id, self.lal.to_part());
        self.changed();
    }

    /// Stops hosting `name`; `false` if it was not hosted here.
    pub fn deregister(&mut self, name: &str) -> bool {
        let removed = self.lal.remove(name);
        if removed {
            self.gal.merge_part(self.config.id, self.lal.to_part());
            self.changed();
        }
        removed
    }

    /// Finds an agent: local first (always available), then the GAL.
    pub fn resolve(&self, name: &str) -> Option<&AgentEntry> {
        self.lal
            .get(name)
            .or_else(|| self.gal.lookup(name).map(|(_, e)| e))
    }

    /// Handles one message from `from`, whose sender identity its session authenticated
    /// ([`crate::ControlChannel::open`]).
    pub fn on_message(
        &mut self,
        from: &PeerAddr,
        message: Authenticated,
        now: Time,
    ) -> Vec<Outgoing> {
        let mut out = Vec::new();
        self.started.get_or_insert(now);
        if self.refusal.is_some() {
            return out;
        }
        let Authenticated { key, seq, msg } = message;
        let claim = |id| Claim {
            id,
            key: &key,
            from,
        };
        if let Some(id) = speaker(&msg)
            && !self.vetting.speaks_for(claim(id), now)
        {
            return out;
        }
        match msg {
            ContainerMsg::Heartbeat {
                id,
                incarnation,
                leader,
                lal_generation: _,
                gal_versions,
            } => {
                if id == self.config.id {
                    if *from != self.config.addr
                        || key != self.config.key
                        || incarnation != self.config.incarnation
                    {
                        // Someone else claims our id: we hold it, we stay; tell the newcomer.
                        self.report_duplicate(id, from, now, &mut out);
                    }
                    return out; // else our own heartbeat, looped back by a seed list naming us
                }
                let mut since = now;
                let mut answered = None;
                let known = self.peers.get(&id);
                if let Some(held) = known {
                    if held.addr != *from || held.key != key {
                        self.report_duplicate(id, from, now, &mut out);
                        return out;
                    }
                    if incarnation < held.incarnation
                        || (incarnation == held.incarnation && seq <= held.seq)
                    {
                        tracing::debug!(container = %id, incarnation, seq, held = held.incarnation, "heartbeat of an older life or replayed, ignored");
                        return out;
                    }
                    if incarnation == held.incarnation {
                        since = held.since;
                        answered.clone_from(&held.answered);
                    }
                }
                if known.is_none() {
                    // A newcomer hears at once whom we take for leader (it elects before the
                    // next heartbeat), and everybody hears of it at the next tick.
                    out.push(Outgoing {
                        to: from.clone(),
                        msg: self.heartbeat(),
                    });
                    self.changed();
                }
                self.peers.insert(
                    id,
                    Peer {
                        addr: from.clone(),
                        key,
                        incarnation,
                        seq,
                        since,
                        last_heard: now,
                        leader,
                        gal_versions,
                        answered,
                    },
                );
                self.elect();
                let versions = self.gal.versions();
                self.sync_with(id, now, &versions, &mut out);
            }
            ContainerMsg::Lal { id, part } => {
                let from_owner = self.take(id, from, &key, seq)
                    && self
                        .peers
                        .get(&id)
                        .is_some_and(|p| part.generation >> 32 == u64::from(p.incarnation));
                if self.leader == self.config.id && id != self.config.id && from_owner {
                    if self.vetting.vet_part(id, Some(&key), &part, from, now)
                        && self.gal.set_part(id, part)
                    {
                        self.changed();
                    }
                } else if !from_owner {
                    tracing::debug!(container = %id, %from, "agent list not under its container's identity, ignored");
                }
            }
            ContainerMsg::Gal {
                leader,
                versions,
                gal,
            } => {
                if leader == self.leader
                    && leader != self.config.id
                    && self.take(leader, from, &key, seq)
                {
                    let peers = &self.peers;
                    let gal =
                        self.vetting
                            .vet_gal(gal, |id| peers.get(&id).map(|p| p.key), from, now);
                    let held_from_leader = self.gal_from == leader;
                    self.gal_from = leader;
                    if self
                        .gal
                        .adopt_delta(&versions, &gal, self.config.id, held_from_leader)
                    {
                        self.changed();
                    }
                    if let Some(p) = self.peers.get_mut(&leader) {
                        p.gal_versions = versions;
                    }
                } else {
                    tracing::debug!(claimed = %leader, elected = %self.leader, %from, "global agent list not under the elected leader's identity, ignored");
                }
            }
            ContainerMsg::Duplicate {
                id,
                holder,
                holder_incarnation,
                holder_uptime_ms,
            } => {
                if id != self.config.id || holder == self.config.addr {
                    return out;
                }
                if !self.vetting.believes_duplicate(claim(id), now) {
                    // Under a roster only a holder of this container's own identity can hold
                    // its id: greet the named holder, which, if it is one, answers itself.
                    let period = self.config.heartbeat;
                    if self.vetting.probe_due(now, period) {
                        out.push(Outgoing {
                            to: holder,
                            msg: self.heartbeat(),
                        });
                    }
                    return out;
                }
                // Told by a third party: it knew the holder first. Told by the holder itself:
                // the one running longer keeps the id, each measured on its own clock (no two
                // clocks need agree). We keep it only if we ran a lease longer than the holder
                // says: then our answer, which says so, makes the holder refuse however late it
                // comes; in a near tie we are the one who refuses.
                let uptime_ms = self.uptime_ms(now);
                let elder = Duration::from_millis(holder_uptime_ms)
                    .saturating_add(self.config.lease)
                    > Duration::from_millis(uptime_ms);
                if *from != holder || elder {
                    let reason = format!(
                        "container id {} is already held by a live container at {holder} (incarnation {holder_incarnation}, up {holder_uptime_ms} ms), as {from} reports; this one ({}, incarnation {}, up {uptime_ms} ms) refuses to run",
                        id.0, self.config.addr, self.config.incarnation
                    );
                    tracing::error!("{reason}");
                    self.refusal = Some(reason);
                } else {
                    // We ran first: the holder that told us is the newcomer; tell it in kind.
                    self.report_duplicate(id, from, now, &mut out);
                }
            }
        }
        out
    }

    /// Whether a list from `from` under `key` with `seq` speaks for live container `id`: its
    /// bound key and address, and a sequence number above the last taken (then recorded).
    fn take(&mut self, id: ContainerId, from: &PeerAddr, key: &PublicKey, seq: u64) -> bool {
        match self.peers.get_mut(&id) {
            Some(p) if p.addr == *from && p.key == *key && seq > p.seq => {
                p.seq = seq;
                true
            }
            _ => false,
        }
    }

    fn uptime_ms(&self, now: Time) -> u64 {
        self.started.map_or(0, |t| {
            now.since(t).as_millis().try_into().unwrap_or(u64::MAX)
        })
    }

    /// Tells `newcomer`, which claims `id`, who holds it; warns once per lease per id.
    fn report_duplicate(
        &mut self,
        id: ContainerId,
        newcomer: &PeerAddr,
        now: Time,
        out: &mut Vec<Outgoing>,
    ) {
        let (holder, holder_incarnation, holder_uptime_ms) = match self.peers.get(&id) {
            Some(p) if id != self.config.id => (
                p.addr.clone(),
                p.incarnation,
                now.since(p.since)
                    .as_millis()
                    .try_into()
                    .unwrap_or(u64::MAX),
            ),
            _ => (
                self.config.addr.clone(),
                self.config.incarnation,
                self.uptime_ms(now),
            ),
        };
        let lease = self.config.lease;
        let due = self
            .duplicate_warned
            .get(&id)
            .is_none_or(|t| now.since(*t) >= lease);
        if due {
            tracing::warn!(container = %id, %newcomer, %holder, "a second container claims a live id: refused");
            self.duplicate_warned.insert(id, now);
        }
        out.push(Outgoing {
            to: newcomer.clone(),
            msg: ContainerMsg::Duplicate {
                id,
                holder,
                holder_incarnation,
                holder_uptime_ms,
            },
        });
    }

    /// Expires leases, re-elects, and sends heartbeats when due.
    pub fn on_tick(&mut self, now: Time) -> Vec<Outgoing> {
        self.started.get_or_insert(now);
        let lease = self.config.lease;
        let before = self.peers.len();
        self.peers.retain(|id, p| {
            let alive = now.since(p.last_heard) < lease;
            if !alive {
                tracing::info!(container = %id, "lease expired");
            }
            alive
        });
        if self.peers.len() != before {
            self.changed();
            self.elect();
        }
        let mut out = Vec::new();
        if self.refusal.is_some() {
            return out;
        }
        if now >= self.next_heartbeat {
            let period = if self.settled() {
                self.config.idle_heartbeat()
            } else {
                self.config.heartbeat
            };
            self.next_heartbeat = now.plus(period);
            self.last_heartbeat = now;
            let heartbeat = self.heartbeat();
            let mut targets: BTreeSet<&PeerAddr> = self.config.seeds.iter().collect();
            targets.extend(self.peers.values().map(|p| &p.addr));
            targets.remove(&self.config.addr);
            out.extend(targets.into_iter().map(|to| Outgoing {
                to: to.clone(),
                msg: heartbeat.clone(),
            }));
            let ids: Vec<ContainerId> = self.peers.keys().copied().collect();
            let versions = self.gal.versions();
            for id in ids {
                self.sync_with(id, now, &versions, &mut out);
            }
        }
        out
    }

    /// "I am alive", as of now.
    fn heartbeat(&self) -> ContainerMsg {
        // A follower tells what it took from the leader it names (a list mirrored from an
        // earlier leader is not vouched for): that leader then sends it everything else.
        let gal_versions = if self.gal_from == self.leader || self.leader == self.config.id {
            self.gal.versions()
        } else {
            self.gal
                .versions()
                .into_iter()
                .filter(|(id, _)| *id == self.config.id)
                .collect()
        };
        ContainerMsg::Heartbeat {
            id: self.config.id,
            incarnation: self.config.incarnation,
            leader: self.leader,
            lal_generation: self.lal.generation(),
            gal_versions,
        }
    }

    /// Whether the lists agree as far as this container can tell: a leader's every peer holds
    /// its list; a follower holds its leader's list and the leader holds its part.
    fn settled(&self) -> bool {
        let versions = self.gal.versions();
        if self.leader == self.config.id {
            self.peers.values().all(|p| p.gal_versions == versions)
        } else {
            self.gal_from == self.leader
                && self
                    .peers
                    .get(&self.leader)
                    .is_some_and(|l| l.gal_versions == versions)
        }
    }

    /// Notes a change of the lists, the peers or the leader: readers look again, and peers hear
    /// of it at the next tick.
    fn changed(&mut self) {
        self.revision += 1;
        let soon = self.last_heartbeat.plus(self.config.heartbeat);
        if soon < self.next_heartbeat {
            self.next_heartbeat = soon;
        }
    }

    fn elect(&mut self) {
        let lowest = self
            .peers
            .keys()
            .next()
            .copied()
            .map_or(self.config.id, |p| p.min(self.config.id));
        if lowest != self.leader {
            tracing::info!(container = %self.config.id, old = %self.leader, new = %lowest, "leader elected");
            self.leader = lowest;
            self.elections += 1;
            self.changed();
        }
    }

    /// Sends `id` what it lacks: the parts of the GAL it lacks if we lead and it is behind
    /// (not the same answer again within two heartbeats), our LAL if it leads and lacks our
    /// generation.
    fn sync_with(
        &mut self,
        id: ContainerId,
        now: Time,
        versions: &VersionVector,
        out: &mut Vec<Outgoing>,
    ) {
        let repeat = 2 * self.config.heartbeat;
        let leading = self.leader == self.config.id;
        let Some(peer) = self.peers.get_mut(&id) else {
            return;
        };
        // its own part is its to send, not ours
        let behind = leading && others(&peer.gal_versions, id).ne(others(versions, id));
        let answered_lately = peer.answered.as_ref().is_some_and(|(ours, has, at)| {
            ours == versions && *has == peer.gal_versions && now.since(*at) < repeat
        });
        if behind && !answered_lately {
            let (gal, _) = self.gal.delta(&peer.gal_versions, id, LIST_FRAME_BUDGET);
            peer.answered = Some((versions.clone(), peer.gal_versions.clone(), now));
            out.push(Outgoing {
                to: peer.addr.clone(),
                msg: ContainerMsg::Gal {
                    leader: self.config.id,
                    versions: versions.clone(),
                    gal,
                },
            });
        }
        let peer = &self.peers[&id];
        if id == self.leader
            && peer.gal_versions.get(&self.config.id).copied() != Some(self.lal.generation())
        {
            out.push(Outgoing {
                to: peer.addr.clone(),
                msg: ContainerMsg::Lal {
                    id: self.config.id,
                    part: self.lal.to_part(),
                },
            });
        }
    }
}
