//! The agent runtime: what an agent is, what it may do, and the host that runs many of them in
//! one container on one [`Bus`].
//!
//! Organization:
//! - [`Agent`]: the trait every agent implements (JADE's `setup` / message handling / `takeDown`,
//!   plus a periodic `tick` for control loops). Handlers are short and never block.
//! - [`Context`]: an agent's view of the platform: its [`AgentId`], the time, `send`, and the
//!   replies that carry a reason ([`Context::refuse`], [`Context::failure`],
//!   [`Context::not_understood`]), and the DF registration ([`Context::df_registration`]).
//! - [`AgentHost`]: owns the agents of a container; [`AgentHost::step`] runs them once at a
//!   given time (simulated time: scenarios run faster than real time and deterministically), and
//!   [`AgentHost::run_until`] paces steps with the bus clock (real time).
//! - [`conversation`]: FIPA interaction protocols for agents: [`Initiated`] conversations an
//!   agent opened, and [`Context::accept`] / [`Context::answer`] for the ones it answers.
//! - [`gateway`]: a [`GatewayAgent`] that lets code outside the agent world (tests, the CLI, the
//!   dashboard) speak as an agent through a [`GatewayHandle`].
//! - [`Tap`]: sees every message the host's agents send (the logger agent's copies are made
//!   from it), installed with [`AgentHost::set_tap`].
//!
//! Guarantees: agents only meet through ACL messages on the bus (an agent never holds another);
//! a message that is not well-formed ACL is counted and answered with nothing (its sender cannot
//! be trusted); a step delivers every message that local agents send each other during it, up
//! to [`MAX_ROUNDS_PER_STEP`] rounds, so a step is a consistent instant; within a round an agent
//! gets the messages waiting for it in sender order (each sender's in the order sent), so the
//! outcome of a step does not hang on the arrival order of frames from different containers.
#![warn(missing_docs)]

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_bus::{
    Bus, BusConfig, BusError, Clock, InProcNetwork, Mailbox, MockController, Stack, Time,
};
use iw_ontology::OntologyContent;
use iw_ontology::fipa::{
    AgentDescription, DfAgentDescription, ManagementAction, ManagementContent, ManagementRequest,
    ServiceDescription,
};
use iw_ontology::wheelchair::WheelchairContent;

pub mod conversation;
pub mod gateway;
pub use conversation::{Initiated, Progress, TypedContent};
pub use gateway::{GatewayAgent, GatewayHandle};
pub use iw_interaction::{EventKind, Protocol, Responder};

/// Rounds of local delivery within one [`AgentHost::step`]; a longer chain continues next step.
pub const MAX_ROUNDS_PER_STEP: usize = 16;

/// Why an agent could not be added or a message not sent.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AgentError {
    /// The bus refused (name taken, no route, transport failure).
    #[error("agent `{agent}`: {source}")]
    Bus {
        /// The agent concerned.
        agent: String,
        /// The bus error.
        #[source]
        source: BusError,
    },
    /// A message without receivers.
    #[error("agent `{agent}` sent a {performative} with no receiver")]
    NoReceiver {
        /// The sender.
        agent: String,
        /// Its performative.
        performative: Performative,
    },
    /// The interaction protocol does not allow this act now (or cannot open this
    /// conversation).
    #[error("agent `{agent}`: {source}")]
    Protocol {
        /// The agent concerned.
        agent: String,
        /// What the protocol refused.
        #[source]
        source: iw_interaction::Error,
    },
}

/// One agent. Every method gets the agent's [`Context`]; none may block.
pub trait Agent: Send {
    /// Called once, before the first message or tick (JADE's `setup`).
    fn setup(&mut self, _ctx: &mut Context<'_>) {}
    /// Handles one message addressed to this agent.
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage);
    /// Periodic work (control loops, timeouts), every [`Agent::tick_period`].
    fn tick(&mut self, _ctx: &mut Context<'_>) {}
    /// How often [`Agent::tick`] runs; `None` for purely reactive agents.
    fn tick_period(&self) -> Option<Duration> {
        None
    }
    /// Called once when the agent is removed (JADE's `takeDown`).
    fn take_down(&mut self, _ctx: &mut Context<'_>) {}
}

/// Called with every message an agent of the host sent (after the bus accepted it for at
/// least one receiver) and the time of the step; it must not block.
pub type Tap = Box<dyn FnMut(&AclMessage, Time) + Send>;

/// An agent's view of the platform during one call.
pub struct Context<'a> {
    aid: &'a AgentId,
    bus: &'a Bus,
    now: Time,
    sent: &'a mut u64,
    failed: &'a mut u64,
    tap: &'a mut Option<Tap>,
}

impl Context<'_> {
    /// This agent's identifier.
    pub fn aid(&self) -> &AgentId {
        self.aid
    }

    /// This agent's name on the bus.
    pub fn name(&self) -> &str {
        &self.aid.name
    }

    /// The time of this step.
    pub fn now(&self) -> Time {
        self.now
    }

    /// Sends `message` to each of its receivers, as this agent (the sender is set here, so an
    /// agent cannot speak for another). Failures are returned and counted in [`HostStats`].
    pub fn send(&mut self, mut message: AclMessage) -> Result<(), AgentError> {
        message.sender = Some(self.aid.clone());
        if message.receivers.is_empty() {
            let err = AgentError::NoReceiver {
                agent: self.aid.name.clone(),
                performative: message.performative,
            };
            return Err(self.keep(err));
        }
        let text = iw_acl::codec::print(&message);
        for (i, receiver) in message.receivers.iter().enumerate() {
            if let Err(source) =
                self.bus
                    .send(&self.aid.name, &receiver.name, text.clone().into_bytes())
            {
                if i > 0 {
                    self.tapped(&message);
                }
                let err = AgentError::Bus {
                    agent: self.aid.name.clone(),
                    source,
                };
                return Err(self.keep(err));
            }
            *self.sent += 1;
        }
        self.tapped(&message);
        Ok(())
    }

    /// The fipa-request that registers this agent's service `name` of type `service_type` with
    /// its platform's DF (`df@PLATFORM`), so other platforms' agents (JADE's) find it with a DF
    /// search; `None` when this agent's name names no platform. Conversation
    /// `df-register-AGENT`.
    pub fn df_registration(&self, name: &str, service_type: &str) -> Option<AclMessage> {
        let df = AgentId::new(format!("df@{}", self.aid.platform()?));
        let description = DfAgentDescription {
            name: Some(self.aid.clone()),
            services: vec![ServiceDescription {
                name: Some(name.into()),
                service_type: Some(service_type.into()),
                ..ServiceDescription::default()
            }],
            ..DfAgentDescription::default()
        };
        let register = ManagementContent::Request(ManagementRequest {
            actor: df.clone(),
            action: ManagementAction::Register {
                description: AgentDescription::Df(description),
            },
        });
        let request = AclMessage::new(Performative::Request)
            .with_receiver(df)
            .with_protocol(Protocol::Request.fipa_name())
            .with_conversation_id(format!("df-register-{}", self.name()));
        Some(register.fill(request))
    }

    /// Replies NOT-UNDERSTOOD to `message` with a reason, as FIPA asks of an agent that cannot
    /// process what it received.
    pub fn not_understood(&mut self, message: &AclMessage, reason: &str) -> Result<(), AgentError> {
        self.explain(message, Performative::NotUnderstood, reason)
    }

    /// Replies REFUSE to `message` with a reason: understood, but this agent will not do it.
    pub fn refuse(&mut self, message: &AclMessage, reason: &str) -> Result<(), AgentError> {
        self.explain(message, Performative::Refuse, reason)
    }

    /// Replies FAILURE to `message` with a reason: agreed to, but it could not be done.
    pub fn failure(&mut self, message: &AclMessage, reason: &str) -> Result<(), AgentError> {
        self.explain(message, Performative::Failure, reason)
    }

    /// The reply to `message` with `performative` and `((error-message "reason"))` content (in
    /// the wheelchair ontology, which defines the fact).
    fn explain(
        &mut self,
        message: &AclMessage,
        performative: Performative,
        reason: &str,
    ) -> Result<(), AgentError> {
        let reply = WheelchairContent::error(reason)
            .fill(message.create_reply().with_performative(performative));
        self.send(reply)
    }

    /// The part of `message`'s ontology content that `pick` wants, or `None` after answering
    /// NOT-UNDERSTOOD: with the parse error, or with `expected` when the content is of another
    /// kind than `pick` takes.
    pub fn understand<C: OntologyContent, T>(
        &mut self,
        message: &AclMessage,
        expected: &str,
        pick: impl FnOnce(C) -> Option<T>,
    ) -> Option<T> {
        let why = match C::from_message(message) {
            Ok(content) => match pick(content) {
                Some(wanted) => return Some(wanted),
                None => expected.to_string(),
            },
            Err(err) => err.to_string(),
        };
        let _ = self.not_understood(message, &why);
        None
    }

    fn tapped(&mut self, message: &AclMessage) {
        if let Some(tap) = self.tap.as_mut() {
            tap(message, self.now);
        }
    }

    fn keep(&mut self, err: AgentError) -> AgentError {
        tracing::warn!(agent = %self.aid.name, error = %err, "send failed");
        *self.failed += 1;
        err
    }
}

struct Slot {
    aid: AgentId,
    agent: Box<dyn Agent>,
    mailbox: Mailbox,
    started: bool,
    next_tick: Option<Time>,
}

/// Counts of what the host did, for reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HostStats {
    /// Messages handed to agents.
    pub delivered: u64,
    /// Messages agents sent.
    pub sent: u64,
    /// Payloads that were not well-formed ACL.
    pub malformed: u64,
    /// Sends that failed (no route, no receiver, transport error).
    pub send_failures: u64,
}

/// The agents of one container, run on one bus.
pub struct AgentHost {
    bus: Arc<Bus>,
    slots: Vec<Slot>,
    stats: HostStats,
    tap: Option<Tap>,
}

impl AgentHost {
    /// A host with no agents on `bus`.
    pub fn new(bus: Arc<Bus>) -> AgentHost {
        AgentHost {
            bus,
            slots: Vec::new(),
            stats: HostStats::default(),
            tap: None,
        }
    }

    /// A host with no agents, alone on an in-process bus (container `c1`, no layers), whose clock
    /// starts at `start` and moves only when the returned controller advances it: how an agent
    /// is tested step by step, with a [`gateway`] speaking to it.
    pub fn on_a_mock_clock(start: Time) -> (AgentHost, MockController) {
        let (clock, controller) = Clock::mock(start);
        let endpoint = InProcNetwork::new()
            .endpoint("c1")
            .expect("a fresh in-process network has no endpoint named c1");
        let bus = Bus::start(
            Stack::new(),
            Arc::new(endpoint),
            clock,
            BusConfig::default(),
        )
        .expect("a bus starts on an in-process endpoint");
        (AgentHost::new(Arc::new(bus)), controller)
    }

    /// Shows every message the agents send from now on to `tap` (replacing any earlier one).
    pub fn set_tap(&mut self, tap: Tap) {
        self.tap = Some(tap);
    }

    /// The bus the agents talk on.
    pub fn bus(&self) -> &Arc<Bus> {
        &self.bus
    }

    /// Registers `agent` under `aid` (its name is its bus address); it starts at the next step.
    pub fn add(&mut self, aid: AgentId, agent: Box<dyn Agent>) -> Result<(), AgentError> {
        let mailbox = self
            .bus
            .register(&aid.name)
            .map_err(|source| AgentError::Bus {
                agent: aid.name.clone(),
                source,
            })?;
        self.slots.push(Slot {
            aid,
            agent,
            mailbox,
            started: false,
            next_tick: None,
        });
        Ok(())
    }

    /// Removes an agent (its `take_down` runs); returns whether it was here.
    pub fn remove(&mut self, name: &str, now: Time) -> bool {
        let Some(index) = self.slots.iter().position(|s| s.aid.name == name) else {
            return false;
        };
        let mut slot = self.slots.remove(index);
        let mut sent = 0;
        let mut ctx = Context {
            aid: &slot.aid,
            bus: &self.bus,
            now,
            sent: &mut sent,
            failed: &mut self.stats.send_failures,
            tap: &mut self.tap,
        };
        slot.agent.take_down(&mut ctx);
        self.stats.sent += sent;
        self.bus.deregister(name);
        true
    }

    /// Names of the agents hosted here (the container's Local Agent List).
    pub fn agent_names(&self) -> Vec<String> {
        self.slots.iter().map(|s| s.aid.name.clone()).collect()
    }

    /// What the host has done so far.
    pub fn stats(&self) -> HostStats {
        self.stats
    }

    /// Runs every agent once at time `now`: setup if new, every waiting message, the tick if
    /// due; then delivers what they sent each other, for up to [`MAX_ROUNDS_PER_STEP`] rounds.
    /// Returns the number of messages delivered.
    pub fn step(&mut self, now: Time) -> u64 {
        let before = self.stats.delivered;
        for round in 0..MAX_ROUNDS_PER_STEP {
            let mut activity = false;
            for slot in &mut self.slots {
                let mut sent = 0;
                let mut ctx = Context {
                    aid: &slot.aid,
                    bus: &self.bus,
                    now,
                    sent: &mut sent,
                    failed: &mut self.stats.send_failures,
                    tap: &mut self.tap,
                };
                if !slot.started {
                    slot.started = true;
                    slot.agent.setup(&mut ctx);
                    slot.next_tick = slot.agent.tick_period().map(|_| now);
                }
                // What waits is handled in sender order (stable: each sender's messages keep
                // theirs), so a step does not depend on which container's frames won a race.
                let mut waiting = Vec::new();
                while let Some(envelope) = slot.mailbox.try_recv() {
                    waiting.push(envelope);
                }
                waiting.sort_by(|a, b| a.header.sender.cmp(&b.header.sender));
                for envelope in waiting {
                    activity = true;
                    let parsed = envelope.payload_str().map(iw_acl::codec::parse);
                    match parsed {
                        Some(Ok(mut message)) => {
                            // The envelope's sender is authoritative (the parser layer checks
                            // they agree); a message that omits `:sender` can still be answered.
                            message.sender.get_or_insert_with(|| {
                                AgentId::new(envelope.header.sender.clone())
                            });
                            self.stats.delivered += 1;
                            slot.agent.handle(&mut ctx, message);
                        }
                        Some(Err(err)) => {
                            self.stats.malformed += 1;
                            tracing::warn!(agent = %slot.aid.name, error = %err, "dropped a malformed ACL message");
                        }
                        None => {
                            self.stats.malformed += 1;
                            tracing::warn!(agent = %slot.aid.name, "dropped a payload that is not UTF-8");
                        }
                    }
                }
                if round == 0
                    && let (Some(due), Some(period)) = (slot.next_tick, slot.agent.tick_period())
                    && now >= due
                {
                    slot.agent.tick(&mut ctx);
                    // Catch up at most one period late, never in a burst.
                    slot.next_tick = Some(due.plus(period).max(now));
                }
                self.stats.sent += sent;
                activity |= sent > 0;
            }
            if !activity {
                break;
            }
        }
        self.stats.delivered - before
    }

    /// Steps in real time every `period` of the bus clock until `stop` is set.
    pub fn run_until(&mut self, period: Duration, stop: &AtomicBool) {
        while !stop.load(Ordering::Acquire) {
            let now = self.bus.clock().now();
            self.step(now);
            let next = now.plus(period);
            let wait = next.since(self.bus.clock().now());
            std::thread::sleep(wait.min(period));
        }
    }

    /// Removes every agent, running their `take_down`.
    pub fn shutdown(&mut self, now: Time) {
        for name in self.agent_names() {
            self.remove(&name, now);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_bus::{BusConfig, Clock, InProcNetwork, Stack};

    /// Answers every request with an inform carrying the same content.
    struct Echo;
    impl Agent for Echo {
        fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
            if message.performative == Performative::Request {
                let content = message.content_text().unwrap_or_default().to_string();
                let reply = message
                    .create_reply()
                    .with_performative(Performative::Inform)
                    .with_content(content);
                ctx.send(reply).unwrap();
            } else {
                ctx.not_understood(&message, "only requests").unwrap();
            }
        }
    }

    /// Sends one request per tick to `echo` and counts the answers.
    struct Pinger {
        asked: u32,
        answers: Arc<std::sync::Mutex<Vec<String>>>,
    }
    impl Agent for Pinger {
        fn tick_period(&self) -> Option<Duration> {
            Some(Duration::from_millis(100))
        }
        fn tick(&mut self, ctx: &mut Context<'_>) {
            self.asked += 1;
            let request = AclMessage::new(Performative::Request)
                .with_receiver(AgentId::new("echo@c1"))
                .with_content(format!("ping {}", self.asked))
                .with_conversation_id(format!("c{}", self.asked));
            // A failure is counted by the host; the test reads it there.
            let _ = ctx.send(request);
        }
        fn handle(&mut self, _ctx: &mut Context<'_>, message: AclMessage) {
            let line = format!(
                "{} {}",
                message.performative,
                message.content_text().unwrap_or_default()
            );
            self.answers.lock().unwrap().push(line);
        }
    }

    fn host() -> (AgentHost, iw_bus::MockController) {
        let network = InProcNetwork::new();
        let (clock, controller) = Clock::mock(Time::from_ns(1_000_000_000));
        let transport = Arc::new(network.endpoint("c1").unwrap());
        let bus = Bus::start(Stack::new(), transport, clock, BusConfig::default()).unwrap();
        (AgentHost::new(Arc::new(bus)), controller)
    }

    #[test]
    fn agents_talk_only_through_acl_and_ticks_follow_simulated_time() {
        let (mut host, clock) = host();
        let answers = Arc::new(std::sync::Mutex::new(Vec::new()));
        host.add(AgentId::new("echo@c1"), Box::new(Echo)).unwrap();
        host.add(
            AgentId::new("pinger@c1"),
            Box::new(Pinger {
                asked: 0,
                answers: answers.clone(),
            }),
        )
        .unwrap();
        for _ in 0..5 {
            host.step(clock.now());
            clock.advance(Duration::from_millis(50));
        }
        // Ticks at 0, 100 and 200 ms of the 250 ms run; each answered within its own step.
        assert_eq!(
            *answers.lock().unwrap(),
            ["INFORM ping 1", "INFORM ping 2", "INFORM ping 3"]
        );
        assert_eq!(
            host.stats(),
            HostStats {
                delivered: 6,
                sent: 6,
                malformed: 0,
                send_failures: 0
            }
        );
    }

    #[test]
    fn a_gateway_speaks_for_outside_code_and_reports_refused_sends() {
        let (mut host, clock) = host();
        let (agent, handle) = gateway::gateway(Duration::from_millis(10));
        host.add(AgentId::new("echo@c1"), Box::new(Echo)).unwrap();
        host.add(AgentId::new("outside@c1"), Box::new(agent))
            .unwrap();
        handle.send(
            AclMessage::new(Performative::Request)
                .with_receiver(AgentId::new("echo@c1"))
                .with_content("hello"),
        );
        handle.send(AclMessage::new(Performative::Inform).with_content("to no one"));
        for _ in 0..3 {
            host.step(clock.now());
            clock.advance(Duration::from_millis(10));
        }
        let received = handle.take_received();
        assert_eq!(received.len(), 1);
        assert_eq!(received[0].performative, Performative::Inform);
        assert_eq!(received[0].content_text(), Some("hello"));
        assert_eq!(
            received[0].sender.as_ref().map(|s| s.name.as_str()),
            Some("echo@c1")
        );
        assert_eq!(
            received[0].receivers[0].name, "outside@c1",
            "the reply came back to the gateway"
        );
        assert!(matches!(
            handle.take_send_errors().as_slice(),
            [AgentError::NoReceiver { .. }]
        ));
        assert!(handle.take_received().is_empty(), "taken once");
    }

    #[test]
    fn wrong_performative_gets_not_understood_and_unknown_receivers_are_errors() {
        let (mut host, clock) = host();
        let answers = Arc::new(std::sync::Mutex::new(Vec::new()));
        host.add(AgentId::new("echo@c1"), Box::new(Echo)).unwrap();
        host.add(
            AgentId::new("pinger@c1"),
            Box::new(Pinger {
                asked: 0,
                answers: answers.clone(),
            }),
        )
        .unwrap();
        host.bus()
            .send(
                "pinger@c1",
                "echo@c1",
                b"(inform :content \"hello\")".to_vec(),
            )
            .unwrap();
        host.bus()
            .send("pinger@c1", "echo@c1", b"this is not ACL".to_vec())
            .unwrap();
        host.step(clock.now());
        assert!(
            answers
                .lock()
                .unwrap()
                .iter()
                .any(|a| a.starts_with("NOT-UNDERSTOOD")),
            "{answers:?}"
        );
        assert_eq!(host.stats().malformed, 1);
        assert!(
            host.add(AgentId::new("echo@c1"), Box::new(Echo)).is_err(),
            "names are unique per bus"
        );
        assert!(host.remove("echo@c1", clock.now()));
        host.step(clock.now().plus(Duration::from_millis(100)));
        assert_eq!(
            host.stats().send_failures,
            1,
            "sending to a removed agent is reported"
        );
    }

    #[test]
    fn the_tap_sees_every_message_sent_once_with_its_step_time() {
        let (mut host, clock) = host();
        let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
        let record = seen.clone();
        host.set_tap(Box::new(move |m: &AclMessage, t: Time| {
            record
                .lock()
                .unwrap()
                .push((m.performative, m.sender.clone().map(|s| s.name), t));
        }));
        let answers = Arc::new(std::sync::Mutex::new(Vec::new()));
        host.add(AgentId::new("echo@c1"), Box::new(Echo)).unwrap();
        host.add(
            AgentId::new("pinger@c1"),
            Box::new(Pinger { asked: 0, answers }),
        )
        .unwrap();
        host.step(clock.now());
        clock.advance(Duration::from_millis(100));
        host.step(clock.now());
        let seen = seen.lock().unwrap();
        assert_eq!(seen.len() as u64, host.stats().sent, "{seen:?}");
        let t0 = Time::from_ns(1_000_000_000);
        assert_eq!(
            seen[0],
            (Performative::Request, Some("pinger@c1".to_string()), t0)
        );
        assert_eq!(
            seen[1],
            (Performative::Inform, Some("echo@c1".to_string()), t0)
        );
        assert_eq!(seen[3].2, t0.plus(Duration::from_millis(100)));
    }

    /// Records the sender and content of everything it is given.
    struct Recorder(Arc<std::sync::Mutex<Vec<String>>>);
    impl Agent for Recorder {
        fn handle(&mut self, _ctx: &mut Context<'_>, message: AclMessage) {
            let from = message
                .sender
                .as_ref()
                .map(|s| s.name.clone())
                .unwrap_or_default();
            self.0.lock().unwrap().push(format!(
                "{from} {}",
                message.content_text().unwrap_or_default()
            ));
        }
    }

    #[test]
    fn a_step_hands_waiting_messages_over_in_sender_order_keeping_each_senders_order() {
        let (mut host, controller) = host();
        let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
        host.add(AgentId::new("rec@c1"), Box::new(Recorder(seen.clone())))
            .unwrap();
        // Arrival order: b, a, b, a.
        for (from, text) in [
            ("b@c1", "b1"),
            ("a@c1", "a1"),
            ("b@c1", "b2"),
            ("a@c1", "a2"),
        ] {
            let m = AclMessage::new(Performative::Inform)
                .with_sender(AgentId::new(from))
                .with_receiver(AgentId::new("rec@c1"))
                .with_content(text);
            host.bus
                .send(from, "rec@c1", iw_acl::codec::print(&m).into_bytes())
                .unwrap();
        }
        host.step(controller.now());
        assert_eq!(
            *seen.lock().unwrap(),
            ["a@c1 a1", "a@c1 a2", "b@c1 b1", "b@c1 b2"]
        );
    }
}
