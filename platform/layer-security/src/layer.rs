//! The security layer state machine: sealing, opening, key agreement, pre-shared sessions.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use aes_gcm::aead::AeadInPlace;
use aes_gcm::{Aes256Gcm, KeyInit};
use iw_bus::{Envelope, Flags, IdGen, Layer, Reason, SIGNATURE_LEN, Time, Verdict, write_aad};
use ring::aead::{AES_256_GCM, Aad, LessSafeKey, Nonce, UnboundKey};
use ring::hkdf;
use ring::rand::{SecureRandom, SystemRandom};
use rustc_hash::FxHashMap;
use snow::HandshakeState;

use crate::SecurityError;
use crate::identity::{Identity, KeyDirectory, signed_bytes, verify};

/// Session id length (public-key mode), bytes.
pub(crate) const SID_LEN: usize = 8;
/// Session salt length (pre-shared mode), bytes.
const SALT_LEN: usize = 16;
pub(crate) const NONCE_LEN: usize = 12;
pub(crate) const TAG_LEN: usize = 16;
pub(crate) const HELLO: u8 = 1;
pub(crate) const REPLY: u8 = 2;
pub(crate) const REKEY: u8 = 3;
/// The Noise protocol of the key agreement: IX (both static keys travel, two messages: the
/// hello and its reply), X25519, AES-256-GCM, SHA-256.
pub(crate) const NOISE_PARAMS: &str = "Noise_IX_25519_AESGCM_SHA256";
/// Largest Noise handshake message accepted or written (IX: 2 keys, a signature, 2 tags).
pub(crate) const NOISE_MAX: usize = 256;
/// Hellos remembered (sender, session id) to refuse a replayed one.
const HELLOS_KEPT: usize = 4096;
/// Send sessions kept after their receiver asked for a new key, to take back the frames still
/// in flight under them (see `Layer::reclaim`).
const RETIRED_KEPT: usize = 64;

/// A 256-bit pre-shared key.
pub type PreSharedKey = [u8; 32];

/// Settings of the security layer.
#[derive(Debug, Clone)]
pub struct SecurityConfig {
    /// Peers (agent names) reached in pre-shared-key mode, with their key; every other peer is
    /// reached in public-key mode. Both ends list each other with the same key.
    pub pre_shared: HashMap<String, PreSharedKey>,
    /// A key shared by a closed group (e.g. the containers of one deployment, for their control
    /// traffic): every peer not in `pre_shared` is reached and accepted in pre-shared-key mode
    /// with it. `None` (default): public-key mode for them.
    pub group_key: Option<PreSharedKey>,
    /// Sign every message so third parties can verify it.
    pub sign_all: bool,
    /// Receivers whose messages are signed even when `sign_all` is off.
    pub sign_for: HashSet<String>,
    /// Unanswered key agreement is started again after this long (default 1 s).
    pub handshake_timeout: Duration,
    /// Messages held per peer while a key agreement runs; more are dropped (default 1024).
    pub max_queued: usize,
    /// Receive sessions kept per sender and receiver (older ones are forgotten; default 4).
    pub sessions_kept: usize,
    /// A hello stamped further than this from the receiver's clock, either way, is refused as
    /// stale (a replay from the past; default 30 s, far above hosts' clock differences).
    pub handshake_max_age: Duration,
}

impl Default for SecurityConfig {
    fn default() -> Self {
        SecurityConfig {
            pre_shared: HashMap::new(),
            group_key: None,
            sign_all: false,
            sign_for: HashSet::new(),
            handshake_timeout: Duration::from_secs(1),
            max_queued: 1024,
            sessions_kept: 4,
            handshake_max_age: Duration::from_secs(30),
        }
    }
}

/// Where a sealed frame's AEAD key and nonce came from, read back from its payload (tests use
/// it to prove that no (key, nonce) pair repeats).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct SealInfo {
    /// The key: session id (public-key mode) or session salt (pre-shared mode), with the mode.
    pub key_id: Vec<u8>,
    /// The 96-bit nonce.
    pub nonce: [u8; NONCE_LEN],
}

impl SealInfo {
    /// Reads the key id and nonce of a sealed envelope; `None` if it is not sealed or too short.
    pub fn of(env: &Envelope) -> Option<SealInfo> {
        let f = env.header.flags;
        if !f.contains(Flags::SEALED) {
            return None;
        }
        let id_len = if f.contains(Flags::PRE_SHARED) {
            SALT_LEN
        } else {
            SID_LEN
        };
        let mut key_id = vec![u8::from(f.contains(Flags::PRE_SHARED))];
        key_id.extend_from_slice(env.payload.get(..id_len)?);
        let nonce = env
            .payload
            .get(id_len..id_len + NONCE_LEN)?
            .try_into()
            .ok()?;
        Some(SealInfo { key_id, nonce })
    }
}

/// Frames a re-key request may point at: the last this many a send session sealed.
pub(crate) const REKEY_WINDOW: u64 = 64;

/// A session agreed for sending: the data plane's and the control channel's alike.
pub(crate) struct SendSession {
    pub(crate) id: [u8; SID_LEN],
    pub(crate) key: LessSafeKey,
    counter: u64,
    /// The tags of the last [`REKEY_WINDOW`] frames sealed, by counter modulo the window: a
    /// re-key request must echo one (with its counter), which only someone who saw that frame
    /// can; the session id alone, in clear in every frame, is not enough.
    tags: Box<[[u8; TAG_LEN]; REKEY_WINDOW as usize]>,
}

impl SendSession {
    pub(crate) fn new(id: [u8; SID_LEN], key: LessSafeKey) -> Self {
        Self {
            id,
            key,
            counter: 0,
            tags: Box::new([[0; TAG_LEN]; REKEY_WINDOW as usize]),
        }
    }

    /// The counter (nonce) of the next frame to seal.
    pub(crate) fn next_counter(&mut self) -> u64 {
        let counter = self.counter;
        self.counter += 1;
        counter
    }

    /// Remembers the tag frame `counter` was sealed with.
    pub(crate) fn sealed(&mut self, counter: u64, tag: &[u8]) {
        if let Ok(tag) = tag.try_into() {
            self.tags[(counter % REKEY_WINDOW) as usize] = tag;
        }
    }

    /// Whether `tag` is the one frame `counter`, among the last [`REKEY_WINDOW`] sealed, was
    /// sealed with (compared in constant time).
    pub(crate) fn sealed_recently(&self, counter: u64, tag: &[u8]) -> bool {
        let recent = counter < self.counter && self.counter - counter <= REKEY_WINDOW;
        let kept = &self.tags[(counter % REKEY_WINDOW) as usize];
        let differ = kept.iter().zip(tag).fold(0u8, |acc, (a, b)| acc | (a ^ b));
        recent && tag.len() == TAG_LEN && differ == 0
    }
}

struct PskSend {
    salt: [u8; SALT_LEN],
    cipher: Aes256Gcm,
    counter: u64,
}

/// A session being agreed, on the initiator's side, with what waits for it (`Q`: an envelope
/// here, a control frame in [`crate::peer`]).
pub(crate) struct Agreeing<Q> {
    pub(crate) id: [u8; SID_LEN],
    /// The initiator's Noise state after the hello; `None` once a reply used it up.
    pub(crate) noise: Option<HandshakeState>,
    pub(crate) queued: VecDeque<Q>,
    pub(crate) started: Time,
}

type Pending = Agreeing<Envelope>;

/// Per (sender, receiver) state. Entries are only ever made for local senders or for peers
/// that authenticated (a signed key agreement, a pre-shared key), so a fast unkeyed hash is
/// safe here: outsiders cannot choose the keys.
type Nested<V> = FxHashMap<String, FxHashMap<String, V>>;

fn nested<'a, V: Default>(m: &'a mut Nested<V>, a: &str, b: &str) -> &'a mut V {
    if !m.contains_key(a) {
        m.insert(a.to_string(), FxHashMap::default());
    }
    let inner = m
        .get_mut(a)
        .unwrap_or_else(|| unreachable!("inserted above"));
    if !inner.contains_key(b) {
        inner.insert(b.to_string(), V::default());
    }
    inner
        .get_mut(b)
        .unwrap_or_else(|| unreachable!("inserted above"))
}

fn nested_get<'a, V>(m: &'a Nested<V>, a: &str, b: &str) -> Option<&'a V> {
    m.get(a).and_then(|x| x.get(b))
}

pub(crate) fn nonce_bytes(counter: u64) -> [u8; NONCE_LEN] {
    let mut n = [0u8; NONCE_LEN];
    n[4..].copy_from_slice(&counter.to_be_bytes());
    n
}

fn nested_get_mut<'a, V>(m: &'a mut Nested<V>, a: &str, b: &str) -> Option<&'a mut V> {
    m.get_mut(a).and_then(|x| x.get_mut(b))
}

/// Replaces the contents of `aad` (a buffer kept between messages) with the associated data of
/// `header`.
fn write_aad_into(header: &iw_bus::Header, aad: &mut Vec<u8>) {
    aad.clear();
    // Names over 255 bytes never get this far (the codec refuses them); if one did, the
    // shorter associated data would still be identical on both ends of a local loop.
    let _ = write_aad(header, aad);
}

/// Sets the flags, signs if asked (the signature is sealed after the payload), and writes the
/// associated data of the sealed header into `aad`.
fn prepare(
    config: &SecurityConfig,
    identity: &Identity,
    aad: &mut Vec<u8>,
    env: &mut Envelope,
    mode: Flags,
) -> Option<[u8; SIGNATURE_LEN]> {
    let mut flags = env.header.flags.with(Flags::SEALED).with(mode);
    let wants_signature = config.sign_all
        || (!config.sign_for.is_empty() && config.sign_for.contains(&env.header.receiver));
    let sig = if wants_signature {
        flags = flags.with(Flags::SIGNED);
        Some(identity.sign(&signed_bytes(env)))
    } else {
        None
    };
    env.header.flags = flags;
    env.signature = None;
    write_aad_into(&env.header, aad);
    sig
}

/// A sealed payload, built in one allocation: key id, nonce, then `plain` and the signature
/// sealed in place by `seal` (which returns the tag), then the tag.
fn sealed_payload(
    key_id: &[u8],
    nonce: &[u8; NONCE_LEN],
    plain: &[u8],
    sig: Option<&[u8; SIGNATURE_LEN]>,
    seal: impl FnOnce(&mut [u8]) -> Result<[u8; TAG_LEN], SecurityError>,
) -> Result<Vec<u8>, SecurityError> {
    let sig_len = sig.map_or(0, |s| s.len());
    let mut out = Vec::with_capacity(key_id.len() + NONCE_LEN + plain.len() + sig_len + TAG_LEN);
    out.extend_from_slice(key_id);
    out.extend_from_slice(nonce);
    out.extend_from_slice(plain);
    if let Some(sig) = sig {
        out.extend_from_slice(sig);
    }
    let tag = seal(&mut out[key_id.len() + NONCE_LEN..])?;
    out.extend_from_slice(&tag);
    Ok(out)
}

fn length_prefixed(parts: &[&[u8]]) -> Vec<u8> {
    let mut out = Vec::new();
    for p in parts {
        out.extend_from_slice(&(p.len() as u32).to_be_bytes());
        out.extend_from_slice(p);
    }
    out
}

struct KeyLen;
impl hkdf::KeyType for KeyLen {
    fn len(&self) -> usize {
        32
    }
}

fn hkdf32(salt: &[u8], ikm: &[u8], info: &[u8]) -> Result<[u8; 32], SecurityError> {
    let mut out = [0u8; 32];
    hkdf::Salt::new(hkdf::HKDF_SHA256, salt)
        .extract(ikm)
        .expand(&[info], KeyLen)
        .and_then(|okm| okm.fill(&mut out))
        .map_err(|_| SecurityError::KeyDerivation)?;
    Ok(out)
}

fn ring_key(k: &[u8; 32]) -> Result<LessSafeKey, SecurityError> {
    UnboundKey::new(&AES_256_GCM, k)
        .map(LessSafeKey::new)
        .map_err(|_| SecurityError::KeyDerivation)
}

fn psk_cipher(
    psk: &PreSharedKey,
    salt: &[u8],
    sender: &str,
    receiver: &str,
) -> Result<Aes256Gcm, SecurityError> {
    let info = length_prefixed(&[b"iw-psk-v1", sender.as_bytes(), receiver.as_bytes()]);
    let key = hkdf32(salt, psk, &info)?;
    Aes256Gcm::new_from_slice(&key).map_err(|_| SecurityError::KeyDerivation)
}

/// The Noise prologue both ends mix in: the session id and both names, so a handshake cannot be
/// moved to another pair of agents or session.
pub(crate) fn prologue(id: &[u8], a: &str, b: &str) -> Vec<u8> {
    length_prefixed(&[b"iw-noise-v1", id, a.as_bytes(), b.as_bytes()])
}

/// What the initiator's identity signs in the hello: its Noise static key, bound to the session,
/// both names and the hello's time (a replay later than `handshake_max_age` is stale).
pub(crate) fn hello_binding(id: &[u8], a: &str, b: &str, static_a: &[u8], at: u64) -> Vec<u8> {
    length_prefixed(&[
        b"iw-noise-hello-v1",
        id,
        a.as_bytes(),
        b.as_bytes(),
        static_a,
        &at.to_be_bytes(),
    ])
}

/// What the responder's identity signs in the reply: its Noise static key, bound to the
/// session, both names and the handshake hash after the hello (so to that very hello).
pub(crate) fn reply_binding(id: &[u8], a: &str, b: &str, static_b: &[u8], hash: &[u8]) -> Vec<u8> {
    length_prefixed(&[
        b"iw-noise-reply-v1",
        id,
        a.as_bytes(),
        b.as_bytes(),
        static_b,
        hash,
    ])
}

pub(crate) fn noise_err(_: snow::Error) -> SecurityError {
    SecurityError::KeyDerivation
}

/// A Noise handshake state for `NOISE_PARAMS`, with `ring` for hashing, AES-GCM and randomness and
/// curve25519-dalek for X25519 (ring offers only ephemeral X25519, and IX needs static keys).
pub(crate) fn noise(
    static_private: &[u8],
    prologue: &[u8],
    initiator: bool,
) -> Result<HandshakeState, SecurityError> {
    let params = NOISE_PARAMS.parse().map_err(noise_err)?;
    let builder = snow::Builder::new(params)
        .local_private_key(static_private)
        .and_then(|b| b.prologue(prologue))
        .map_err(noise_err)?;
    if initiator {
        builder.build_initiator()
    } else {
        builder.build_responder()
    }
    .map_err(noise_err)
}

/// The AEAD key of the initiator-to-responder direction, the only one a session uses (the
/// other direction agrees its own session). Raw, because frames carry their header as
/// associated data, which snow's transport messages do not take.
pub(crate) fn split_key(hs: &mut HandshakeState) -> Result<LessSafeKey, SecurityError> {
    let (to_responder, _) = hs.dangerously_get_raw_split();
    ring_key(&to_responder)
}

/// A hello's parts: session id, time stamped, Noise message.
pub(crate) fn split_hello(payload: &[u8]) -> Option<([u8; SID_LEN], u64, &[u8])> {
    let id = payload.get(1..1 + SID_LEN)?.try_into().ok()?;
    let at = payload.get(1 + SID_LEN..1 + SID_LEN + 8)?.try_into().ok()?;
    let noise = payload.get(1 + SID_LEN + 8..)?;
    (noise.len() <= NOISE_MAX).then_some((id, u64::from_be_bytes(at), noise))
}

/// A reply's parts: session id, Noise message.
pub(crate) fn split_reply(payload: &[u8]) -> Option<([u8; SID_LEN], &[u8])> {
    let id = payload.get(1..1 + SID_LEN)?.try_into().ok()?;
    let noise = payload.get(1 + SID_LEN..)?;
    (noise.len() <= NOISE_MAX).then_some((id, noise))
}

/// The security layer of one node (agent or container identity).
pub struct SecurityLayer {
    identity: Arc<Identity>,
    directory: Arc<dyn KeyDirectory>,
    config: SecurityConfig,
    rng: SystemRandom,
    ids: IdGen,
    send: Nested<Option<SendSession>>,
    pending: Nested<Option<Pending>>,
    recv: Nested<VecDeque<([u8; SID_LEN], LessSafeKey)>>,
    psk_send: Nested<Option<PskSend>>,
    psk_recv: Nested<VecDeque<([u8; SALT_LEN], Aes256Gcm)>>,
    outbox: VecDeque<Envelope>,
    /// Associated data of the frame being sealed or opened (kept to save an allocation each).
    aad: Vec<u8>,
    /// No pending key agreement times out before this (a lower bound, exact after each scan);
    /// `None`: none pending.
    restart_due: Option<Time>,
    /// Send sessions whose receiver lost them (re-key request), newest last: frames sealed
    /// under them and still held below are opened again and re-sealed under a new session.
    retired: VecDeque<([u8; SID_LEN], LessSafeKey)>,
    /// Receivers that asked for a new key, not yet reported to the stack.
    lost: VecDeque<String>,
    /// This layer's Noise static X25519 key pair, made at the first key agreement: it lives
    /// as long as the layer, and every handshake binds it to the Ed25519 identity by a signature.
    noise_static: Option<snow::Keypair>,
    /// Hellos accepted (sender, session id), oldest first, at most `HELLOS_KEPT`: a replayed
    /// one is refused even after its session was forgotten.
    hellos: VecDeque<(String, [u8; SID_LEN])>,
    hellos_seen: HashSet<(String, [u8; SID_LEN])>,
}

impl SecurityLayer {
    /// A layer speaking for `identity`, looking peers' keys up in `directory`.
    pub fn new(
        identity: Arc<Identity>,
        directory: Arc<dyn KeyDirectory>,
        config: SecurityConfig,
    ) -> SecurityLayer {
        SecurityLayer {
            identity,
            directory,
            config,
            rng: SystemRandom::new(),
            ids: IdGen::new(),
            send: FxHashMap::default(),
            pending: FxHashMap::default(),
            recv: FxHashMap::default(),
            psk_send: FxHashMap::default(),
            psk_recv: FxHashMap::default(),
            outbox: VecDeque::new(),
            aad: Vec::with_capacity(64),
            restart_due: None,
            retired: VecDeque::new(),
            lost: VecDeque::new(),
            noise_static: None,
            hellos: VecDeque::new(),
            hellos_seen: HashSet::new(),
        }
    }

    /// The Noise static key pair, made on first use.
    fn noise_static(&mut self) -> Result<&snow::Keypair, SecurityError> {
        if self.noise_static.is_none() {
            let params = NOISE_PARAMS.parse().map_err(noise_err)?;
            let pair = snow::Builder::new(params)
                .generate_keypair()
                .map_err(noise_err)?;
            self.noise_static = Some(pair);
        }
        self.noise_static.as_ref().ok_or(SecurityError::Rng)
    }

    fn random<const N: usize>(&self) -> Result<[u8; N], SecurityError> {
        let mut b = [0u8; N];
        self.rng.fill(&mut b).map_err(|_| SecurityError::Rng)?;
        Ok(b)
    }

    /// The pre-shared key `peer` is reached with, if any.
    fn psk_of(&self, peer: &str) -> Option<PreSharedKey> {
        if self.config.pre_shared.is_empty() {
            return self.config.group_key;
        }
        self.config
            .pre_shared
            .get(peer)
            .copied()
            .or(self.config.group_key)
    }

    /// Seals `env` in place under the pre-shared key `psk`.
    fn seal_psk(&mut self, env: &mut Envelope, psk: PreSharedKey) -> Result<(), SecurityError> {
        let (s, r) = (env.header.sender.as_str(), env.header.receiver.as_str());
        if nested_get(&self.psk_send, s, r).is_none_or(Option::is_none) {
            let salt = self.random::<SALT_LEN>()?;
            let cipher = psk_cipher(&psk, &salt, s, r)?;
            *nested(&mut self.psk_send, s, r) = Some(PskSend {
                salt,
                cipher,
                counter: 0,
            });
        }
        let sess = nested_get_mut(&mut self.psk_send, &env.header.sender, &env.header.receiver)
            .and_then(Option::as_mut)
            .ok_or(SecurityError::KeyDerivation)?;
        let sig = prepare(
            &self.config,
            &self.identity,
            &mut self.aad,
            env,
            Flags::PRE_SHARED,
        );
        let nonce = nonce_bytes(sess.counter);
        sess.counter += 1;
        let cipher = &sess.cipher;
        let aad = &self.aad[..];
        env.payload = sealed_payload(&sess.salt, &nonce, &env.payload, sig.as_ref(), |in_out| {
            cipher
                .encrypt_in_place_detached(aes_gcm::Nonce::from_slice(&nonce), aad, in_out)
                .map(|tag| tag.into())
                .map_err(|_| SecurityError::KeyDerivation)
        })?;
        Ok(())
    }

    /// Seals `env` in place under the session from its sender to its receiver, if there is one
    /// (`false`, and `env` untouched, otherwise).
    fn seal_pk(&mut self, env: &mut Envelope) -> Result<bool, SecurityError> {
        let Some(sess) = nested_get_mut(&mut self.send, &env.header.sender, &env.header.receiver)
            .and_then(Option::as_mut)
        else {
            return Ok(false);
        };
        let sig = prepare(
            &self.config,
            &self.identity,
            &mut self.aad,
            env,
            Flags::NONE,
        );
        let counter = sess.next_counter();
        let nonce = nonce_bytes(counter);
        let key = &sess.key;
        let aad = &self.aad[..];
        env.payload = sealed_payload(&sess.id, &nonce, &env.payload, sig.as_ref(), |in_out| {
            let tag = key
                .seal_in_place_separate_tag(
                    Nonce::assume_unique_for_key(nonce),
                    Aad::from(aad),
                    in_out,
                )
                .map_err(|_| SecurityError::KeyDerivation)?;
            tag.as_ref()
                .try_into()
                .map_err(|_| SecurityError::KeyDerivation)
        })?;
        let tag_at = env.payload.len() - TAG_LEN;
        sess.sealed(counter, &env.payload[tag_at..]);
        Ok(true)
    }

    fn handshake_env(
        &mut self,
        sender: &str,
        receiver: &str,
        payload: Vec<u8>,
        now: Time,
    ) -> Envelope {
        let mut env = Envelope::new(self.ids.next_id(), sender, receiver, payload);
        env.header.flags = Flags::HANDSHAKE;
        env.header.timestamp = now;
        env
    }

    /// Starts (or restarts) key agreement from `a` to `b`, keeping messages already queued: a
    /// Noise IX hello whose payload is `a`'s identity signature over its static key.
    fn start_handshake(&mut self, a: &str, b: &str, now: Time) -> Result<(), SecurityError> {
        let id = self.random::<SID_LEN>()?;
        let at = now.0;
        let pair = self.noise_static()?;
        let static_pub = pair.public.clone();
        let mut hs = noise(&pair.private, &prologue(&id, a, b), true)?;
        let sig = self
            .identity
            .sign(&hello_binding(&id, a, b, &static_pub, at));
        let mut msg = [0u8; NOISE_MAX];
        let n = hs.write_message(&sig, &mut msg).map_err(noise_err)?;
        let payload = [&[HELLO][..], &id, &at.to_be_bytes(), &msg[..n]].concat();
        let hello = self.handshake_env(a, b, payload, now);
        self.outbox.push_back(hello);
        let slot = nested(&mut self.pending, a, b);
        let queued = slot.take().map(|p| p.queued).unwrap_or_default();
        *slot = Some(Pending {
            id,
            noise: Some(hs),
            queued,
            started: now,
        });
        let due = now.plus(self.config.handshake_timeout);
        self.restart_due = Some(self.restart_due.map_or(due, |d| d.min(due)));
        Ok(())
    }

    fn outbound_pk(&mut self, env: &mut Envelope, now: Time) -> Result<Verdict, SecurityError> {
        if self.seal_pk(env)? {
            return Ok(Verdict::Pass);
        }
        let (a, b) = (env.header.sender.as_str(), env.header.receiver.as_str());
        if self.directory.public_key(b).is_none() {
            return Ok(Verdict::Drop(Reason::UnknownPeer));
        }
        let (a, b) = (a.to_string(), b.to_string());
        if nested_get(&self.pending, &a, &b).is_none_or(Option::is_none) {
            self.start_handshake(&a, &b, now)?;
        }
        let max = self.config.max_queued;
        let Some(p) = nested(&mut self.pending, &a, &b).as_mut() else {
            return Err(SecurityError::KeyDerivation);
        };
        if p.queued.len() >= max {
            tracing::warn!(sender = %a, receiver = %b, "key agreement pending, queue full");
            return Ok(Verdict::Drop(Reason::UnknownPeer));
        }
        // Held until the key is agreed: taken from the caller, who is told it was consumed.
        p.queued.push_back(std::mem::take(env));
        Ok(Verdict::Consumed)
    }

    /// A hello from `a` to our `b`: refused unless signed by the identity the directory lists for
    /// `a` over the Noise static key it carries, fresh and never seen; answered with a reply
    /// signed likewise, and the receive session kept. Freshness and repetition are judged only
    /// once the signature holds: a stale or repeated verdict is final for the frame (the layer
    /// below keeps its id), so it must never be passed on a corrupted copy of some other frame,
    /// whose genuine retransmission would then be taken for a duplicate and lost.
    fn on_hello(&mut self, env: &Envelope, now: Time) -> Result<Verdict, SecurityError> {
        let (a, b) = (env.header.sender.as_str(), env.header.receiver.as_str());
        let Some((id, at, msg1)) = split_hello(&env.payload) else {
            return Ok(Verdict::Drop(Reason::BadHandshake));
        };
        let Some(key_a) = self.directory.public_key(a) else {
            return Ok(Verdict::Drop(Reason::UnknownPeer));
        };
        let pair = self.noise_static()?;
        let static_b = pair.public.clone();
        let mut hs = noise(&pair.private, &prologue(&id, a, b), false)?;
        let mut payload = [0u8; NOISE_MAX];
        let Ok(n) = hs.read_message(msg1, &mut payload) else {
            return Ok(Verdict::Drop(Reason::BadHandshake));
        };
        let Some(static_a) = hs.get_remote_static() else {
            return Ok(Verdict::Drop(Reason::BadHandshake));
        };
        if !verify(
            &key_a,
            &hello_binding(&id, a, b, static_a, at),
            &payload[..n],
        ) {
            return Ok(Verdict::Drop(Reason::BadSignature));
        }
        if Duration::from_nanos(now.0.abs_diff(at)) > self.config.handshake_max_age {
            return Ok(Verdict::Drop(Reason::Stale));
        }
        let seen = (a.to_string(), id);
        if self.hellos_seen.contains(&seen) {
            return Ok(Verdict::Drop(Reason::Duplicate));
        }
        self.hellos.push_back(seen.clone());
        self.hellos_seen.insert(seen);
        while self.hellos.len() > HELLOS_KEPT {
            if let Some(old) = self.hellos.pop_front() {
                self.hellos_seen.remove(&old);
            }
        }
        let sig_b = self.identity.sign(&reply_binding(
            &id,
            a,
            b,
            &static_b,
            hs.get_handshake_hash(),
        ));
        let mut msg2 = [0u8; NOISE_MAX];
        let n = hs.write_message(&sig_b, &mut msg2).map_err(noise_err)?;
        let key = split_key(&mut hs)?;
        let kept = self.config.sessions_kept.max(1);
        let q = nested(&mut self.recv, a, b);
        q.push_back((id, key));
        while q.len() > kept {
            q.pop_front();
        }
        let payload = [&[REPLY][..], &id, &msg2[..n]].concat();
        let (a, b) = (a.to_string(), b.to_string());
        let reply = self.handshake_env(&b, &a, payload, now);
        self.outbox.push_back(reply);
        Ok(Verdict::Consumed)
    }

    /// The reply to our hello: the session is agreed if the Noise handshake completes and the
    /// responder's identity signed its static key over this very handshake. A reply that fails
    /// used up the handshake state, so the agreement starts again at once.
    fn on_reply(&mut self, env: &Envelope, now: Time) -> Result<Verdict, SecurityError> {
        // The reply comes from b (the peer) to a (who started the agreement).
        let (b, a) = (env.header.sender.clone(), env.header.receiver.clone());
        let Some((id, msg2)) = split_reply(&env.payload) else {
            return Ok(Verdict::Drop(Reason::BadHandshake));
        };
        let matches = nested_get(&self.pending, &a, &b)
            .and_then(Option::as_ref)
            .is_some_and(|p| p.id == id && p.noise.is_some());
        if !matches {
            return Ok(Verdict::Drop(Reason::BadHandshake));
        }
        let Some(key_b) = self.directory.public_key(&b) else {
            return Ok(Verdict::Drop(Reason::UnknownPeer));
        };
        let Some(mut hs) = nested(&mut self.pending, &a, &b)
            .as_mut()
            .and_then(|p| p.noise.take())
        else {
            return Ok(Verdict::Drop(Reason::BadHandshake));
        };
        let hash = hs.get_handshake_hash().to_vec();
        let mut payload = [0u8; NOISE_MAX];
        let verdict = match hs.read_message(msg2, &mut payload) {
            Err(_) => Some(Reason::BadHandshake),
            Ok(n) => match hs.get_remote_static() {
                Some(static_b) if n == SIGNATURE_LEN => {
                    let binding = reply_binding(&id, &a, &b, static_b, &hash);
                    (!verify(&key_b, &binding, &payload[..n])).then_some(Reason::BadSignature)
                }
                _ => Some(Reason::BadHandshake),
            },
        };
        if let Some(reason) = verdict {
            self.start_handshake(&a, &b, now)?;
            return Ok(Verdict::Drop(reason));
        }
        let key = split_key(&mut hs)?;
        let Some(p) = nested(&mut self.pending, &a, &b).take() else {
            return Ok(Verdict::Drop(Reason::BadHandshake));
        };
        *nested(&mut self.send, &a, &b) = Some(SendSession::new(id, key));
        for mut queued in p.queued {
            if !self.seal_pk(&mut queued)? {
                return Err(SecurityError::KeyDerivation);
            }
            self.outbox.push_back(queued);
        }
        Ok(Verdict::Consumed)
    }

    fn on_rekey(&mut self, env: &Envelope) -> Verdict {
        // Sent by a receiver that lost the session (restart), so it cannot be sealed; it is
        // bound to the session instead: it names it and echoes the nonce and tag of one of its
        // last frames, which only someone who saw that frame knows. One naming the session
        // without such a frame is refused (and counted); the worst a forger on the path
        // achieves is an extra agreement.
        let (b, a) = (env.header.sender.as_str(), env.header.receiver.as_str());
        if env.payload.len() != 1 + SID_LEN + NONCE_LEN + TAG_LEN {
            return Verdict::Drop(Reason::BadHandshake);
        }
        let (id, rest) = env.payload[1..].split_at(SID_LEN);
        let (nonce, tag) = rest.split_at(NONCE_LEN);
        let mut counter = [0u8; 8];
        counter.copy_from_slice(&nonce[NONCE_LEN - 8..]);
        let counter = u64::from_be_bytes(counter);
        let Some(session) = nested_get(&self.send, a, b)
            .and_then(Option::as_ref)
            .filter(|s| s.id[..] == *id)
        else {
            // a repeat for a session already retired, or one of an earlier life of ours
            return Verdict::Consumed;
        };
        if !session.sealed_recently(counter, tag) {
            return Verdict::Drop(Reason::BadHandshake);
        }
        // A restart loses every session: retire those of all our agents towards `b`.
        for sessions in self.send.values_mut() {
            if let Some(slot) = sessions.get_mut(b)
                && let Some(old) = slot.take()
            {
                self.retired.push_back((old.id, old.key));
            }
        }
        while self.retired.len() > RETIRED_KEPT {
            self.retired.pop_front();
        }
        tracing::info!(receiver = %b, "peer lost its session (restarted?): agreeing a new key and re-sealing frames in flight");
        if !self.lost.iter().any(|p| p == b) {
            self.lost.push_back(b.to_string());
        }
        Verdict::Consumed
    }

    /// Takes back a frame we sealed under a retired session: opens it, and queues it for a new
    /// key agreement (or seals it at once if one was agreed meanwhile).
    fn reclaim_sealed(&mut self, env: &mut Envelope, now: Time) -> Result<Verdict, SecurityError> {
        let f = env.header.flags;
        if !f.contains(Flags::SEALED) || f.contains(Flags::PRE_SHARED) {
            return Ok(Verdict::Pass); // handshakes, acknowledgements, pre-shared sessions
        }
        let Some(sid) = env.payload.get(..SID_LEN) else {
            return Ok(Verdict::Drop(Reason::BadTag));
        };
        let current = nested_get(&self.send, &env.header.sender, &env.header.receiver)
            .and_then(Option::as_ref)
            .is_some_and(|s| s.id[..] == *sid);
        if current {
            return Ok(Verdict::Pass);
        }
        let Some((_, key)) = self.retired.iter().find(|(id, _)| id[..] == *sid) else {
            return Ok(Verdict::Drop(Reason::UnknownSession));
        };
        write_aad_into(&env.header, &mut self.aad);
        let body = SID_LEN + NONCE_LEN;
        if env.payload.len() < body + TAG_LEN {
            return Ok(Verdict::Drop(Reason::BadTag));
        }
        let nonce: [u8; NONCE_LEN] = env.payload[SID_LEN..body]
            .try_into()
            .map_err(|_| SecurityError::KeyDerivation)?;
        let plain_len = match key.open_within(
            Nonce::assume_unique_for_key(nonce),
            Aad::from(&self.aad[..]),
            &mut env.payload,
            body..,
        ) {
            Ok(p) => p.len(),
            Err(_) => return Ok(Verdict::Drop(Reason::BadTag)),
        };
        // A signature is made again when the frame is sealed again.
        let sig_len = if f.contains(Flags::SIGNED) {
            SIGNATURE_LEN
        } else {
            0
        };
        env.payload.truncate(plain_len.saturating_sub(sig_len));
        env.header.flags = f.without(Flags::SEALED).without(Flags::SIGNED);
        self.outbound_pk(env, now)
    }

    /// Opens `env` in place (plaintext payload, flags cleared, signature restored).
    fn open(&mut self, env: &mut Envelope, now: Time) -> Result<Verdict, SecurityError> {
        write_aad_into(&env.header, &mut self.aad);
        let psk_mode = env.header.flags.contains(Flags::PRE_SHARED);
        let id_len = if psk_mode { SALT_LEN } else { SID_LEN };
        let len = env.payload.len();
        if len < id_len + NONCE_LEN + TAG_LEN {
            return Ok(Verdict::Drop(Reason::BadTag));
        }
        // Payload: key id, nonce, ciphertext, tag. Opened in place: the plaintext ends up at
        // the front of the same buffer.
        let body = id_len + NONCE_LEN;
        let nonce: [u8; NONCE_LEN] = env.payload[id_len..body]
            .try_into()
            .map_err(|_| SecurityError::KeyDerivation)?;
        let (s, r) = (env.header.sender.as_str(), env.header.receiver.as_str());
        let aad = &self.aad[..];
        if psk_mode {
            let Some(psk) = self.psk_of(s) else {
                return Ok(Verdict::Drop(Reason::UnknownPeer));
            };
            let salt: [u8; SALT_LEN] = env.payload[..SALT_LEN]
                .try_into()
                .map_err(|_| SecurityError::KeyDerivation)?;
            let cached =
                nested_get(&self.psk_recv, s, r).and_then(|q| q.iter().find(|(id, _)| *id == salt));
            let fresh = match cached {
                Some(_) => None,
                None => Some(psk_cipher(&psk, &salt, s, r)?),
            };
            let Some(cipher) = cached.map(|(_, c)| c).or(fresh.as_ref()) else {
                return Err(SecurityError::KeyDerivation);
            };
            let (ct, tag) = env.payload[body..].split_at_mut(len - body - TAG_LEN);
            if cipher
                .decrypt_in_place_detached(
                    aes_gcm::Nonce::from_slice(&nonce),
                    aad,
                    ct,
                    aes_gcm::Tag::from_slice(tag),
                )
                .is_err()
            {
                return Ok(Verdict::Drop(Reason::BadTag));
            }
            if let Some(cipher) = fresh {
                let kept = self.config.sessions_kept.max(1);
                let q = nested(&mut self.psk_recv, s, r);
                q.push_back((salt, cipher));
                while q.len() > kept {
                    q.pop_front();
                }
            }
            env.payload.truncate(len - TAG_LEN);
            env.payload.drain(..body);
        } else {
            let sid: [u8; SID_LEN] = env.payload[..SID_LEN]
                .try_into()
                .map_err(|_| SecurityError::KeyDerivation)?;
            let session =
                nested_get(&self.recv, s, r).and_then(|q| q.iter().find(|(id, _)| *id == sid));
            let Some((_, key)) = session else {
                // Names the session and the frame (nonce, tag): see `on_rekey`.
                let payload = [
                    &[REKEY][..],
                    &env.payload[..body],
                    &env.payload[len - TAG_LEN..],
                ]
                .concat();
                let (s, r) = (env.header.sender.clone(), env.header.receiver.clone());
                let rekey = self.handshake_env(&r, &s, payload, now);
                self.outbox.push_back(rekey);
                return Ok(Verdict::Drop(Reason::UnknownSession));
            };
            let plain_len = match key.open_within(
                Nonce::assume_unique_for_key(nonce),
                Aad::from(aad),
                &mut env.payload,
                body..,
            ) {
                Ok(p) => p.len(),
                Err(_) => return Ok(Verdict::Drop(Reason::BadTag)),
            };
            env.payload.truncate(plain_len);
        }
        env.header.flags = env
            .header
            .flags
            .without(Flags::SEALED)
            .without(Flags::PRE_SHARED);
        if env.header.flags.contains(Flags::SIGNED) {
            let Some(at) = env.payload.len().checked_sub(SIGNATURE_LEN) else {
                return Ok(Verdict::Drop(Reason::BadSignature));
            };
            let sig: [u8; SIGNATURE_LEN] = env.payload[at..]
                .try_into()
                .map_err(|_| SecurityError::KeyDerivation)?;
            env.payload.truncate(at);
            let Some(key) = self.directory.public_key(&env.header.sender) else {
                return Ok(Verdict::Drop(Reason::UnknownPeer));
            };
            if !verify(&key, &signed_bytes(env), &sig) {
                return Ok(Verdict::Drop(Reason::BadSignature));
            }
            env.signature = Some(Box::new(sig));
        }
        env.authenticated = Some(env.header.sender.clone());
        Ok(Verdict::Pass)
    }
}

fn or_log(r: Result<Verdict, SecurityError>) -> Verdict {
    r.unwrap_or_else(|e| {
        tracing::error!(error = %e, "security layer failure");
        Verdict::Drop(Reason::BadHandshake)
    })
}

impl Layer for SecurityLayer {
    fn name(&self) -> &'static str {
        "security"
    }

    fn outbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        match self.psk_of(&env.header.receiver) {
            Some(psk) => or_log(self.seal_psk(env, psk).map(|()| Verdict::Pass)),
            None => or_log(self.outbound_pk(env, now)),
        }
    }

    fn inbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        let flags = env.header.flags;
        if flags.contains(Flags::HANDSHAKE) {
            return match env.payload.first() {
                Some(&HELLO) => or_log(self.on_hello(env, now)),
                Some(&REPLY) => or_log(self.on_reply(env, now)),
                Some(&REKEY) => self.on_rekey(env),
                _ => Verdict::Drop(Reason::BadHandshake),
            };
        }
        if !flags.contains(Flags::SEALED) {
            return Verdict::Drop(Reason::NotSealed);
        }
        or_log(self.open(env, now))
    }

    fn poll_lost_peer(&mut self) -> Option<String> {
        self.lost.pop_front()
    }

    fn reclaim(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        or_log(self.reclaim_sealed(env, now))
    }

    fn poll_transmit(&mut self, now: Time) -> Option<Envelope> {
        // No agreement can have timed out before `restart_due` (see its field): skip the scan.
        let may_be_due = match self.restart_due {
            None => false,
            Some(due) => self.config.handshake_timeout.is_zero() || now >= due,
        };
        if self.outbox.is_empty() && may_be_due {
            let timeout = self.config.handshake_timeout;
            let stale: Vec<(String, String)> = self
                .pending
                .iter()
                .flat_map(|(a, m)| m.iter().map(move |(b, p)| (a, b, p)))
                .filter(|(_, _, p)| p.as_ref().is_some_and(|p| now.since(p.started) >= timeout))
                .map(|(a, b, _)| (a.clone(), b.clone()))
                .collect();
            for (a, b) in stale {
                tracing::debug!(sender = %a, receiver = %b, "key agreement unanswered, starting again");
                if let Err(e) = self.start_handshake(&a, &b, now) {
                    tracing::error!(error = %e, "cannot restart key agreement");
                }
            }
            self.restart_due = self
                .pending
                .values()
                .flat_map(|m| m.values())
                .filter_map(|p| p.as_ref().map(|p| p.started.plus(timeout)))
                .min();
        }
        self.outbox.pop_front()
    }

    fn next_deadline(&self) -> Option<Time> {
        if !self.outbox.is_empty() {
            return Some(Time::ZERO);
        }
        let timeout = self.config.handshake_timeout;
        self.pending
            .values()
            .flat_map(|m| m.values())
            .filter_map(|p| p.as_ref().map(|p| p.started.plus(timeout)))
            .min()
    }
}
