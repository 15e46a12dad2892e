//! [`PeerSessions`]: the agents' Noise sessions for a channel of byte frames between
//! identities that are known by their address, not by an agent name (the containers' control
//! channel).
//!
//! The handshake is the data plane's (`Noise_IX_25519_AESGCM_SHA256`, each static key bound to
//! the Ed25519 identity by a signature over it, the session id, and the hello's time or the
//! handshake hash); the one difference is that the identity's public key travels in the
//! handshake payload beside its signature, since here the peer's identity is what a frame
//! speaks for (its receiver judges it, e.g. against a roster), not looked up by name.
//!
//! Datagrams: `IWN1`, a kind byte, the session id (8 bytes), then
//! - hello: the time it was stamped (8, big-endian ns) and Noise's first message;
//! - reply: Noise's second message;
//! - re-key: the counter and tag of the frame the receiver could not open (a receiver that
//!   does not hold the session names it, and proves it saw one of its last frames);
//! - data: the frame counter (8, big-endian, the AES-256-GCM nonce) and the sealed frame, with
//!   everything before it as associated data.
//!
//! Guarantees: a frame opens only under a session agreed with the identity it is reported
//! from, once (the counter must grow within a session: a replayed or reordered frame is
//! refused), unaltered. A session goes one way (sender to receiver), and is agreed once per
//! peer, then each frame costs one AEAD seal and open. A new session from the same identity and
//! address (a restarted peer) drops the older ones, so no frame of an earlier life opens again.
//! Memory is bounded whatever arrives: at most 4096 peers sent to, 4096 receive sessions (a few
//! per address) and 4096 hellos remembered, and frames held per peer while agreeing are capped.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use iw_bus::{Reason, Time};
use ring::aead::{Aad, LessSafeKey, Nonce};
use ring::rand::{SecureRandom, SystemRandom};

use crate::identity::{Identity, PublicKey, verify};
use crate::layer::{
    Agreeing, HELLO, NOISE_MAX, NOISE_PARAMS, REKEY, REPLY, SID_LEN, SendSession, TAG_LEN,
    hello_binding, noise, noise_err, nonce_bytes, prologue, reply_binding, split_key,
};
use crate::{SecurityConfig, SecurityError};

const MAGIC: &[u8; 4] = b"IWN1";
const DATA: u8 = 4;
/// Magic, kind, session id.
const HEAD: usize = MAGIC.len() + 1 + SID_LEN;
/// Magic, kind, session id, counter: a data frame's associated data.
const DATA_HEAD: usize = HEAD + 8;
/// The handshake payload: the identity's public key and its signature.
const BINDING_LEN: usize = 32 + 64;
/// The names the handshake bindings carry for both ends: a control session is between
/// identities, not agents (no agent name has no `@`, so no data-plane binding is ever one of
/// these).
const INITIATOR: &str = "#control-initiator";
const RESPONDER: &str = "#control-responder";
/// Receive sessions kept in all (the oldest go first), whoever the peers.
const SESSIONS_MAX: usize = 4096;
/// Hellos remembered by session id, to refuse a replayed one.
const HELLOS_KEPT: usize = 4096;
/// Peers sent to at most (agreed or agreeing): beyond it, agreements unanswered for the
/// handshake timeout are forgotten first, then a new peer waits.
const PEERS_MAX: usize = 4096;

/// A frame opened under a session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Opened {
    /// The Ed25519 public key of the identity the session was agreed with.
    pub key: PublicKey,
    /// The frame.
    pub frame: Vec<u8>,
}

/// Boxed: a Noise state is large, and a hundred peers each hold one or the other.
enum Outbound {
    Agreeing(Box<Agreeing<Vec<u8>>>),
    Agreed(Box<SendSession>),
}

struct Inbound {
    key: LessSafeKey,
    /// The identity the session was agreed with.
    peer: PublicKey,
    /// Where its hello came from.
    from: String,
    /// The highest counter opened; the next must be above it.
    last: Option<u64>,
}

/// One identity's sessions with its peers, sans I/O: [`PeerSessions::seal`] gives the
/// datagrams to send, [`PeerSessions::open`] takes a datagram received and gives the frame it
/// carries and the datagrams to send back.
pub struct PeerSessions {
    identity: Arc<Identity>,
    config: SecurityConfig,
    rng: SystemRandom,
    noise_static: snow::Keypair,
    /// By destination, as the caller names it.
    send: HashMap<String, Outbound>,
    /// By session id; `order` holds the ids oldest first.
    recv: HashMap<[u8; SID_LEN], Inbound>,
    order: VecDeque<[u8; SID_LEN]>,
    hellos: VecDeque<[u8; SID_LEN]>,
    hellos_seen: HashSet<[u8; SID_LEN]>,
}

impl std::fmt::Debug for PeerSessions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PeerSessions")
            .field("identity", &self.identity)
            .field("sending_to", &self.send.len())
            .field("receiving", &self.recv.len())
            .finish_non_exhaustive()
    }
}

impl PeerSessions {
    /// Sessions speaking for `identity`, with `config`'s handshake timeout and maximum age,
    /// frames held per peer while agreeing (`max_queued`) and sessions kept per address
    /// (`sessions_kept`).
    pub fn new(identity: Arc<Identity>, config: SecurityConfig) -> Result<Self, SecurityError> {
        let params = NOISE_PARAMS.parse().map_err(noise_err)?;
        let noise_static = snow::Builder::new(params)
            .generate_keypair()
            .map_err(noise_err)?;
        Ok(Self {
            identity,
            config,
            rng: SystemRandom::new(),
            noise_static,
            send: HashMap::new(),
            recv: HashMap::new(),
            order: VecDeque::new(),
            hellos: VecDeque::new(),
            hellos_seen: HashSet::new(),
        })
    }

    /// The datagrams that carry `frame` to `peer` now: the frame sealed under the session, or,
    /// with none agreed yet (or an agreement unanswered for the handshake timeout), a hello;
    /// the frame then waits for the reply ([`PeerSessions::open`] sends it).
    pub fn seal(
        &mut self,
        peer: &str,
        frame: &[u8],
        now: Time,
    ) -> Result<Vec<Vec<u8>>, SecurityError> {
        let timeout = self.config.handshake_timeout;
        let max_queued = self.config.max_queued.max(1);
        match self.send.get_mut(peer) {
            Some(Outbound::Agreed(session)) => return Ok(vec![seal_data(session, frame)?]),
            Some(Outbound::Agreeing(pending)) if now.since(pending.started) < timeout => {
                queue(&mut pending.queued, frame, max_queued);
                return Ok(Vec::new());
            }
            _ => {}
        }
        if self.send.len() >= PEERS_MAX && !self.send.contains_key(peer) {
            self.send.retain(|_, s| match s {
                Outbound::Agreeing(a) => now.since(a.started) < timeout,
                Outbound::Agreed(_) => true,
            });
            if self.send.len() >= PEERS_MAX {
                tracing::debug!(%peer, "too many control peers: frame not sent");
                return Ok(Vec::new());
            }
        }
        let mut queued = match self.send.remove(peer) {
            Some(Outbound::Agreeing(pending)) => pending.queued,
            _ => VecDeque::new(),
        };
        queue(&mut queued, frame, max_queued);
        let id = self.random()?;
        let at = now.0;
        let static_pub = self.noise_static.public.clone();
        let mut hs = noise(
            &self.noise_static.private,
            &prologue(&id, INITIATOR, RESPONDER),
            true,
        )?;
        let binding = self.binding(&hello_binding(&id, INITIATOR, RESPONDER, &static_pub, at));
        let mut msg = [0u8; NOISE_MAX];
        let n = hs.write_message(&binding, &mut msg).map_err(noise_err)?;
        let hello = [&head(HELLO, &id)[..], &at.to_be_bytes(), &msg[..n]].concat();
        self.send.insert(
            peer.to_string(),
            Outbound::Agreeing(Box::new(Agreeing {
                id,
                noise: Some(hs),
                queued,
                started: now,
            })),
        );
        Ok(vec![hello])
    }

    /// Takes a datagram from `from`: a data frame opens to what it carries; a handshake message
    /// gives nothing (`Ok(None)`). What must go back to `from` is appended to `back` (a reply
    /// to its hello, the frames that waited for its reply, or a re-key request for a session
    /// this end does not hold). A refusal says why.
    pub fn open(
        &mut self,
        from: &str,
        datagram: &[u8],
        now: Time,
        back: &mut Vec<Vec<u8>>,
    ) -> Result<Option<Opened>, Reason> {
        if datagram.len() < HEAD || &datagram[..MAGIC.len()] != MAGIC {
            return Err(Reason::NotSealed);
        }
        let mut id = [0u8; SID_LEN];
        id.copy_from_slice(&datagram[MAGIC.len() + 1..HEAD]);
        let body = &datagram[HEAD..];
        match datagram[MAGIC.len()] {
            DATA => self.on_data(from, &id, datagram, back).map(Some),
            HELLO => self.on_hello(from, id, body, now, back).map(|()| None),
            REPLY => self.on_reply(id, body, back).map(|()| None),
            REKEY => self.on_rekey(&id, body).map(|()| None),
            _ => Err(Reason::BadHandshake),
        }
    }

    /// Forgets the session agreed under `id` (if it is one of ours): the next frame for its
    /// peer starts a new agreement. Asked by a receiver that lost it, so it cannot be sealed;
    /// it is bound to the session instead: `body` echoes the counter and tag of one of the last
    /// [`crate::layer::REKEY_WINDOW`] frames sealed under it, which only someone who saw that
    /// frame knows. Naming the session without such a frame is refused; a session not ours
    /// (an earlier life's, one already forgotten) changes nothing.
    fn on_rekey(&mut self, id: &[u8; SID_LEN], body: &[u8]) -> Result<(), Reason> {
        if body.len() != 8 + TAG_LEN {
            return Err(Reason::BadHandshake);
        }
        let (counter, tag) = body.split_at(8);
        let mut c = [0u8; 8];
        c.copy_from_slice(counter);
        let Some((peer, session)) = self.send.iter().find_map(|(p, s)| match s {
            Outbound::Agreed(a) if a.id == *id => Some((p.clone(), a)),
            _ => None,
        }) else {
            return Ok(());
        };
        if !session.sealed_recently(u64::from_be_bytes(c), tag) {
            return Err(Reason::BadHandshake);
        }
        tracing::info!(%peer, "control peer lost our session (restarted?): agreeing a new one");
        self.send.remove(&peer);
        Ok(())
    }

    fn on_data(
        &mut self,
        from: &str,
        id: &[u8; SID_LEN],
        datagram: &[u8],
        back: &mut Vec<Vec<u8>>,
    ) -> Result<Opened, Reason> {
        let Some(session) = self.recv.get_mut(id) else {
            if let Some(tag) = datagram
                .len()
                .checked_sub(TAG_LEN)
                .filter(|&t| t >= DATA_HEAD)
            {
                // names the session and echoes the frame: see `on_rekey`
                back.push(
                    [
                        &head(REKEY, id)[..],
                        &datagram[HEAD..DATA_HEAD],
                        &datagram[tag..],
                    ]
                    .concat(),
                );
            }
            return Err(Reason::UnknownSession);
        };
        if datagram.len() < DATA_HEAD + TAG_LEN {
            return Err(Reason::BadTag);
        }
        let mut counter = [0u8; 8];
        counter.copy_from_slice(&datagram[HEAD..DATA_HEAD]);
        let counter = u64::from_be_bytes(counter);
        if session.last.is_some_and(|last| counter <= last) {
            return Err(Reason::Duplicate);
        }
        let (aad, sealed) = datagram.split_at(DATA_HEAD);
        let mut frame = sealed.to_vec();
        let len = session
            .key
            .open_in_place(
                Nonce::assume_unique_for_key(nonce_bytes(counter)),
                Aad::from(aad),
                &mut frame,
            )
            .map_err(|_| Reason::BadTag)?
            .len();
        frame.truncate(len);
        session.last = Some(counter);
        if session.from != from {
            // The session is bound to the identity, not the path; the receiver judges the
            // address (a container binds a live id to both).
            tracing::debug!(agreed_from = %session.from, %from, "control session frame from another address");
        }
        Ok(Opened {
            key: session.peer,
            frame,
        })
    }

    fn on_hello(
        &mut self,
        from: &str,
        id: [u8; SID_LEN],
        body: &[u8],
        now: Time,
        back: &mut Vec<Vec<u8>>,
    ) -> Result<(), Reason> {
        let (Some(at), Some(msg1)) = (body.get(..8), body.get(8..)) else {
            return Err(Reason::BadHandshake);
        };
        let mut stamp = [0u8; 8];
        stamp.copy_from_slice(at);
        let at = u64::from_be_bytes(stamp);
        if msg1.len() > NOISE_MAX {
            return Err(Reason::BadHandshake);
        }
        if Duration::from_nanos(now.0.abs_diff(at)) > self.config.handshake_max_age {
            return Err(Reason::Stale);
        }
        if self.hellos_seen.contains(&id) {
            return Err(Reason::Duplicate);
        }
        let bad = |_| Reason::BadHandshake;
        let mut hs = noise(
            &self.noise_static.private,
            &prologue(&id, INITIATOR, RESPONDER),
            false,
        )
        .map_err(bad)?;
        let mut payload = [0u8; NOISE_MAX];
        let n = hs
            .read_message(msg1, &mut payload)
            .map_err(|_| Reason::BadHandshake)?;
        let static_a = hs.get_remote_static().ok_or(Reason::BadHandshake)?;
        let signed = hello_binding(&id, INITIATOR, RESPONDER, static_a, at);
        let peer = check_binding(&payload[..n], &signed)?;
        self.hellos.push_back(id);
        self.hellos_seen.insert(id);
        while self.hellos.len() > HELLOS_KEPT {
            if let Some(old) = self.hellos.pop_front() {
                self.hellos_seen.remove(&old);
            }
        }
        let static_b = self.noise_static.public.clone();
        let binding = self.binding(&reply_binding(
            &id,
            INITIATOR,
            RESPONDER,
            &static_b,
            hs.get_handshake_hash(),
        ));
        let mut msg2 = [0u8; NOISE_MAX];
        let n = hs
            .write_message(&binding, &mut msg2)
            .map_err(|_| Reason::BadHandshake)?;
        let key = split_key(&mut hs).map_err(bad)?;
        self.admit(
            id,
            Inbound {
                key,
                peer,
                from: from.to_string(),
                last: None,
            },
        );
        back.push([&head(REPLY, &id)[..], &msg2[..n]].concat());
        Ok(())
    }

    /// Keeps a new receive session: a restarted peer's (same identity, same address) replaces
    /// its older ones, an address keeps at most `sessions_kept`, and all at most
    /// `SESSIONS_MAX`.
    fn admit(&mut self, id: [u8; SID_LEN], session: Inbound) {
        let kept = self.config.sessions_kept.max(1);
        let mut same_address = 0;
        let recv = &self.recv;
        let mut drop: Vec<[u8; SID_LEN]> = Vec::new();
        for old in self.order.iter().rev() {
            let Some(s) = recv.get(old) else { continue };
            if s.from != session.from {
                continue;
            }
            same_address += 1;
            if s.peer == session.peer || same_address >= kept {
                drop.push(*old);
            }
        }
        for old in &drop {
            self.recv.remove(old);
        }
        self.recv.insert(id, session);
        self.order.retain(|old| !drop.contains(old));
        self.order.push_back(id);
        while self.order.len() > SESSIONS_MAX {
            if let Some(old) = self.order.pop_front() {
                self.recv.remove(&old);
            }
        }
    }

    fn on_reply(
        &mut self,
        id: [u8; SID_LEN],
        body: &[u8],
        back: &mut Vec<Vec<u8>>,
    ) -> Result<(), Reason> {
        if body.len() > NOISE_MAX {
            return Err(Reason::BadHandshake);
        }
        let Some((peer, pending)) = self.send.iter_mut().find_map(|(p, s)| match s {
            Outbound::Agreeing(a) if a.id == id => Some((p.clone(), a)),
            _ => None,
        }) else {
            return Err(Reason::BadHandshake);
        };
        // A reply that fails uses the handshake up: the next frame for this peer starts again.
        let mut hs = pending.noise.take().ok_or(Reason::BadHandshake)?;
        let hash = hs.get_handshake_hash().to_vec();
        let mut payload = [0u8; NOISE_MAX];
        let n = hs
            .read_message(body, &mut payload)
            .map_err(|_| Reason::BadHandshake)?;
        let static_b = hs.get_remote_static().ok_or(Reason::BadHandshake)?;
        check_binding(
            &payload[..n],
            &reply_binding(&id, INITIATOR, RESPONDER, static_b, &hash),
        )?;
        let key = split_key(&mut hs).map_err(|_| Reason::BadHandshake)?;
        let queued = std::mem::take(&mut pending.queued);
        let mut session = SendSession::new(id, key);
        for frame in queued {
            back.push(seal_data(&mut session, &frame).map_err(|_| Reason::BadHandshake)?);
        }
        self.send.insert(peer, Outbound::Agreed(Box::new(session)));
        Ok(())
    }

    /// The handshake payload: this identity's public key and its signature over `binding`.
    fn binding(&self, binding: &[u8]) -> Vec<u8> {
        [
            &self.identity.public_key()[..],
            &self.identity.sign(binding)[..],
        ]
        .concat()
    }

    fn random(&self) -> Result<[u8; SID_LEN], SecurityError> {
        let mut b = [0u8; SID_LEN];
        self.rng.fill(&mut b).map_err(|_| SecurityError::Rng)?;
        Ok(b)
    }
}

/// The identity a handshake payload names, if its signature over `binding` verifies.
fn check_binding(payload: &[u8], binding: &[u8]) -> Result<PublicKey, Reason> {
    if payload.len() != BINDING_LEN {
        return Err(Reason::BadHandshake);
    }
    let mut key = [0u8; 32];
    key.copy_from_slice(&payload[..32]);
    if !verify(&key, binding, &payload[32..]) {
        return Err(Reason::BadSignature);
    }
    Ok(key)
}

fn head(kind: u8, id: &[u8; SID_LEN]) -> [u8; HEAD] {
    let mut h = [0u8; HEAD];
    h[..MAGIC.len()].copy_from_slice(MAGIC);
    h[MAGIC.len()] = kind;
    h[MAGIC.len() + 1..].copy_from_slice(id);
    h
}

fn queue(queued: &mut VecDeque<Vec<u8>>, frame: &[u8], max: usize) {
    queued.push_back(frame.to_vec());
    while queued.len() > max {
        queued.pop_front();
    }
}

fn seal_data(session: &mut SendSession, frame: &[u8]) -> Result<Vec<u8>, SecurityError> {
    let counter = session.next_counter();
    let mut out = Vec::with_capacity(DATA_HEAD + frame.len() + TAG_LEN);
    out.extend_from_slice(&head(DATA, &session.id));
    out.extend_from_slice(&counter.to_be_bytes());
    out.extend_from_slice(frame);
    let (aad, body) = out.split_at_mut(DATA_HEAD);
    let tag = session
        .key
        .seal_in_place_separate_tag(
            Nonce::assume_unique_for_key(nonce_bytes(counter)),
            Aad::from(&aad[..]),
            body,
        )
        .map_err(|_| SecurityError::KeyDerivation)?;
    session.sealed(counter, tag.as_ref());
    out.extend_from_slice(tag.as_ref());
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sessions() -> (PeerSessions, PublicKey) {
        let identity = Arc::new(Identity::generate().unwrap());
        let key = identity.public_key();
        (
            PeerSessions::new(identity, SecurityConfig::default()).unwrap(),
            key,
        )
    }

    /// Delivers `datagrams` from `a` (at `a_addr`) to `b`, and what `b` sends back to `a`,
    /// until nothing is left; returns what `b` opened.
    fn exchange(
        a: &mut PeerSessions,
        b: &mut PeerSessions,
        a_addr: &str,
        datagrams: Vec<Vec<u8>>,
        now: Time,
    ) -> Vec<Result<Opened, Reason>> {
        let mut opened = Vec::new();
        let mut to_b = datagrams;
        while !to_b.is_empty() {
            let mut to_a = Vec::new();
            for d in to_b.drain(..) {
                match b.open(a_addr, &d, now, &mut to_a) {
                    Ok(Some(o)) => opened.push(Ok(o)),
                    Ok(None) => {}
                    Err(r) => opened.push(Err(r)),
                }
            }
            for d in to_a {
                a.open("b", &d, now, &mut to_b).unwrap();
            }
        }
        opened
    }

    const T: Time = Time(1_000_000_000);

    #[test]
    fn the_first_frame_waits_for_the_handshake_then_each_frame_is_one_seal() {
        let (mut a, a_key) = sessions();
        let (mut b, _) = sessions();
        let hello = a.seal("b", b"first", T).unwrap();
        assert_eq!(hello.len(), 1);
        assert_eq!(
            hello[0][MAGIC.len()],
            HELLO,
            "a hello goes before the first frame"
        );
        assert!(a.seal("b", b"second", T).unwrap().is_empty(), "held");
        let opened = exchange(&mut a, &mut b, "a", hello, T);
        let frames: Vec<_> = opened.into_iter().map(Result::unwrap).collect();
        assert_eq!(
            frames,
            [b"first".as_slice(), b"second"].map(|f| Opened {
                key: a_key,
                frame: f.to_vec()
            })
        );
        let third = a.seal("b", b"third", T).unwrap();
        assert_eq!(third.len(), 1);
        assert_eq!(
            third[0][MAGIC.len()],
            DATA,
            "agreed once: a data frame at once"
        );
        let opened = exchange(&mut a, &mut b, "a", third.clone(), T);
        assert_eq!(opened[0].as_ref().unwrap().frame, b"third");
        // replayed within the session, or any byte changed: refused
        let mut back = Vec::new();
        assert_eq!(b.open("a", &third[0], T, &mut back), Err(Reason::Duplicate));
        let fourth = a.seal("b", b"fourth", T).unwrap().remove(0);
        for i in 0..fourth.len() {
            let mut bad = fourth.clone();
            bad[i] ^= 1;
            assert!(
                b.open("a", &bad, T, &mut back).is_err(),
                "byte {i} flipped was taken"
            );
        }
        assert_eq!(
            b.open("a", &fourth, T, &mut back).unwrap().unwrap().frame,
            b"fourth"
        );
    }

    #[test]
    fn a_restarted_peer_agrees_a_new_session_and_its_old_frames_are_refused() {
        let identity = Arc::new(Identity::generate().unwrap());
        let mut a = PeerSessions::new(identity.clone(), SecurityConfig::default()).unwrap();
        let (mut b, _) = sessions();
        let hello = a.seal("b", b"old life", T).unwrap();
        exchange(&mut a, &mut b, "a", hello, T);
        let in_flight = a.seal("b", b"old, in flight", T).unwrap();
        // a restarts: same identity and address, sessions lost
        let mut a = PeerSessions::new(identity, SecurityConfig::default()).unwrap();
        let hello = a.seal("b", b"new life", T).unwrap();
        let opened = exchange(&mut a, &mut b, "a", hello, T);
        assert_eq!(opened[0].as_ref().unwrap().frame, b"new life");
        let mut back = Vec::new();
        assert_eq!(
            b.open("a", &in_flight[0], T, &mut back),
            Err(Reason::UnknownSession),
            "the old session was dropped"
        );
        // its re-key request names a session the new life does not hold: nothing changes
        let mut none = Vec::new();
        a.open("b", &back[0], T, &mut none).unwrap();
        let next = a.seal("b", b"next", T).unwrap();
        assert_eq!(next[0][MAGIC.len()], DATA);
    }

    #[test]
    fn a_receiver_that_lost_the_session_asks_for_a_new_one_and_gets_the_next_frames() {
        let (mut a, _) = sessions();
        let (mut b, _) = sessions();
        let hello = a.seal("b", b"one", T).unwrap();
        exchange(&mut a, &mut b, "a", hello, T);
        let (mut b, _) = sessions(); // b restarted
        let lost = a.seal("b", b"two", T).unwrap();
        let opened = exchange(&mut a, &mut b, "a", lost, T);
        assert_eq!(opened, [Err(Reason::UnknownSession)]);
        let again = a.seal("b", b"three", T).unwrap();
        assert_eq!(again[0][MAGIC.len()], HELLO, "a new agreement");
        let opened = exchange(&mut a, &mut b, "a", again, T);
        assert_eq!(opened[0].as_ref().unwrap().frame, b"three");
    }

    /// A re-key request naming the session (in clear in every frame) is refused unless it
    /// echoes the counter and tag of one of the session's last frames; the session is kept.
    #[test]
    fn a_forged_rekey_request_is_refused_and_the_session_kept() {
        let (mut a, _) = sessions();
        let (mut b, _) = sessions();
        let hello = a.seal("b", b"one", T).unwrap();
        exchange(&mut a, &mut b, "a", hello, T);
        let frame = a.seal("b", b"two", T).unwrap().remove(0);
        let id: [u8; SID_LEN] = frame[MAGIC.len() + 1..HEAD].try_into().unwrap();
        let counter = &frame[HEAD..DATA_HEAD];
        let tag = &frame[frame.len() - TAG_LEN..];
        let rekey = |parts: &[&[u8]]| [&head(REKEY, &id)[..], &parts.concat()].concat();
        let mut back = Vec::new();
        for (what, forged) in [
            ("the session id alone", rekey(&[])),
            ("a made-up tag", rekey(&[counter, &[7u8; TAG_LEN]])),
            ("another counter", rekey(&[&9u64.to_be_bytes(), tag])),
        ] {
            assert_eq!(
                a.open("b", &forged, T, &mut back),
                Err(Reason::BadHandshake),
                "{what}"
            );
        }
        let next = a.seal("b", b"three", T).unwrap();
        assert_eq!(next[0][MAGIC.len()], DATA, "the session was kept");
        // the genuine request (from the receiver that lost it) echoes the frame
        let (mut b, _) = sessions();
        assert_eq!(
            b.open("a", &frame, T, &mut back),
            Err(Reason::UnknownSession)
        );
        assert_eq!(
            back.last().map(Vec::as_slice),
            Some(&rekey(&[counter, tag])[..])
        );
        let genuine = back.pop().unwrap();
        a.open("b", &genuine, T, &mut back).unwrap();
        let again = a.seal("b", b"four", T).unwrap();
        assert_eq!(again[0][MAGIC.len()], HELLO, "a new agreement");
    }

    #[test]
    fn peers_sent_to_are_capped_and_unanswered_agreements_make_room() {
        let (mut a, _) = sessions();
        for n in 0..PEERS_MAX {
            assert_eq!(a.seal(&format!("p{n}"), b"x", T).unwrap().len(), 1);
        }
        assert!(a.seal("one more", b"x", T).unwrap().is_empty(), "waits");
        let later = T.plus(Duration::from_secs(2));
        assert_eq!(
            a.seal("one more", b"x", later).unwrap().len(),
            1,
            "room made"
        );
        assert!(a.send.len() <= PEERS_MAX);
    }

    #[test]
    fn forged_replayed_or_stale_hellos_agree_nothing() {
        let (mut a, _) = sessions();
        let (mut b, _) = sessions();
        let hello = a.seal("b", b"x", T).unwrap().remove(0);
        let mut back = Vec::new();
        // another identity's key in place of the signer's: the signature does not verify
        let at = HEAD + 8 + 64; // after the stamp and Noise's clear ephemeral and static keys
        let mut swapped = hello.clone();
        swapped[at..at + 32].copy_from_slice(&Identity::generate().unwrap().public_key());
        assert_eq!(
            b.open("a", &swapped, T, &mut back),
            Err(Reason::BadSignature)
        );
        let late = T.plus(Duration::from_secs(31));
        assert_eq!(b.open("a", &hello, late, &mut back), Err(Reason::Stale));
        assert!(b.open("a", &hello, T, &mut back).is_ok());
        assert_eq!(b.open("a", &hello, T, &mut back), Err(Reason::Duplicate));
        assert_eq!(back.len(), 1, "one reply, to the one hello taken");
        assert_eq!(
            b.open("a", b"IWC1 junk", T, &mut back),
            Err(Reason::NotSealed)
        );
    }
}
