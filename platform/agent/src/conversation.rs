//! Conversations run by the FIPA interaction protocols (`iw-interaction`), so agents never match
//! replies or pick the next act by hand.
//!
//! - [`Initiated`]: the conversations an agent opened (fipa-request, fipa-query,
//!   fipa-subscribe, ...), each with the agent's own data `T`. Replies are matched by
//!   conversation id and `in-reply-to`, checked against the protocol's state table, and come
//!   back as a typed [`Progress`].
//! - [`Context::accept`] and [`Context::answer`]: the participant's side. A
//!   [`Responder`] only lets the agent send what its protocol allows
//!   next (no INFORM before a REQUEST is agreed or refused, nothing after the end).
//!
//! Time is the step's time ([`Context::now`]), as Unix milliseconds on the protocol side.

use std::collections::BTreeMap;

use iw_acl::{AclMessage, Performative};
use iw_bus::Time;
use iw_interaction::{Event, Initiator, Protocol, Responder};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::WheelchairContent;

use crate::{AgentError, Context};

/// `time` as the Unix milliseconds the protocol engines take.
fn unix_ms(time: Time) -> i64 {
    i64::try_from(time.as_ns() / 1_000_000).unwrap_or(i64::MAX)
}

/// Content an agent answers with, typed: every ontology's SL values ([`OntologyContent`]), and
/// the few contents that are not SL (the logger's JSON log-query result), which name their own
/// `:language`. Filling sets `:content`, `:language` and `:ontology` together, so no agent
/// writes them by hand.
pub trait TypedContent {
    /// `message` carrying this content, its language and its ontology.
    fn fill_into(&self, message: AclMessage) -> AclMessage;
}

impl<C: OntologyContent> TypedContent for C {
    fn fill_into(&self, message: AclMessage) -> AclMessage {
        self.fill(message)
    }
}

/// Whether `act` answers a conversation (AGREE, REFUSE, INFORM, FAILURE, NOT-UNDERSTOOD) rather
/// than opening one. An agent does not answer a stray answer: NOT-UNDERSTOOD back to a stray
/// NOT-UNDERSTOOD would never end.
pub fn answers_a_conversation(act: Performative) -> bool {
    matches!(
        act,
        Performative::Agree
            | Performative::Refuse
            | Performative::Inform
            | Performative::Failure
            | Performative::NotUnderstood
    )
}

/// What an answer did to an initiated conversation.
#[derive(Debug)]
pub enum Progress<T> {
    /// The conversation goes on (an AGREE, a subscription's notification).
    Continues(Event),
    /// It ended (result, refusal, failure, not understood, cancel confirmed); the agent's data
    /// for it comes back.
    Ended(Event, T),
}

/// The conversations an agent initiated and has not seen end, keyed by conversation id.
#[derive(Debug)]
pub struct Initiated<T> {
    open: BTreeMap<String, (Initiator, T)>,
    opened: u64,
}

impl<T> Default for Initiated<T> {
    fn default() -> Self {
        Self {
            open: BTreeMap::new(),
            opened: 0,
        }
    }
}

impl<T> Initiated<T> {
    /// No conversations yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Opens a `protocol` conversation with `opening`'s receivers and sends the opening act,
    /// one copy per receiver with its own `reply-with`. The conversation id is `opening`'s, or
    /// a fresh `AGENT-cN`. Returns the id.
    pub fn open(
        &mut self,
        ctx: &mut Context<'_>,
        protocol: Protocol,
        mut opening: AclMessage,
        data: T,
    ) -> Result<String, AgentError> {
        self.opened += 1;
        let id = opening
            .conversation_id
            .clone()
            .unwrap_or_else(|| format!("{}-c{}", ctx.name(), self.opened));
        opening.protocol = Some(protocol.fipa_name().to_owned());
        opening.conversation_id = Some(id.clone());
        opening.sender = Some(ctx.aid().clone());
        let (initiator, messages) =
            Initiator::start(opening, unix_ms(ctx.now())).map_err(|source| {
                AgentError::Protocol {
                    agent: ctx.name().to_owned(),
                    source,
                }
            })?;
        // Registered before sending, so a local participant's answer within the same step
        // finds its conversation.
        self.open.insert(id.clone(), (initiator, data));
        for message in messages {
            ctx.send(message)?;
        }
        Ok(id)
    }

    /// Takes `message` if it belongs to one of these conversations: `None` when it does not
    /// (another conversation, or none); `Some(Err)` when it does but the protocol does not allow
    /// it now (the conversation is unchanged).
    pub fn handle(
        &mut self,
        ctx: &Context<'_>,
        message: &AclMessage,
    ) -> Option<Result<Progress<T>, AgentError>> {
        let id = message.conversation_id.as_deref()?;
        let (initiator, _) = self.open.get_mut(id)?;
        let event = match initiator.handle(message, unix_ms(ctx.now())) {
            Ok(event) => event,
            Err(source) => {
                return Some(Err(AgentError::Protocol {
                    agent: ctx.name().to_owned(),
                    source,
                }));
            }
        };
        if !initiator.is_done() {
            return Some(Ok(Progress::Continues(event)));
        }
        let (_, data) = self.open.remove(id)?;
        Some(Ok(Progress::Ended(event, data)))
    }

    /// Ends the conversations whose participants did not answer by the opening's `reply-by`.
    pub fn expire(&mut self, now: Time) -> Vec<(Event, T)> {
        let now_ms = unix_ms(now);
        let mut ended = Vec::new();
        let mut timed_out = Vec::new();
        for (id, (initiator, _)) in &mut self.open {
            let events = initiator.tick(now_ms);
            if initiator.is_done() {
                timed_out.push((id.clone(), events));
            }
        }
        for (id, events) in timed_out {
            if let Some((_, data)) = self.open.remove(&id)
                && let Some(event) = events.into_iter().last()
            {
                ended.push((event, data));
            }
        }
        ended
    }

    /// Cancels the subscription `id` with each of its participants (fipa-subscribe's CANCEL);
    /// the participants' confirmations then end it.
    pub fn cancel(&mut self, ctx: &mut Context<'_>, id: &str) -> Result<(), AgentError> {
        let Some((initiator, _)) = self.open.get_mut(id) else {
            return Ok(());
        };
        let participants: Vec<String> = initiator
            .sessions()
            .iter()
            .filter(|s| !s.state().is_done())
            .map(|s| s.participant().name.clone())
            .collect();
        for participant in participants {
            let cancel = initiator
                .cancel(&participant)
                .map_err(|source| AgentError::Protocol {
                    agent: ctx.name().to_owned(),
                    source,
                })?;
            ctx.send(cancel)?;
        }
        Ok(())
    }

    /// Sends `next` as the next item of request stream `id` ([`iw_interaction::Initiator::stream`]):
    /// `false` when `id` is not open (the participant ended it), and nothing is sent.
    pub fn stream(
        &mut self,
        ctx: &mut Context<'_>,
        id: &str,
        next: &AclMessage,
    ) -> Result<bool, AgentError> {
        let Some((initiator, _)) = self.open.get(id) else {
            return Ok(false);
        };
        let messages = initiator
            .stream(next)
            .map_err(|source| AgentError::Protocol {
                agent: ctx.name().to_owned(),
                source,
            })?;
        for message in messages {
            ctx.send(message)?;
        }
        Ok(true)
    }

    /// Forgets conversation `id` without a word to its participants (the agent gave up on it;
    /// late answers are then not ours). Returns its data.
    pub fn forget(&mut self, id: &str) -> Option<T> {
        self.open.remove(id).map(|(_, data)| data)
    }

    /// Moves conversation `id`, its protocol state kept, into `to` with `data`, and returns its
    /// data here: a subscription that outlives the step that opened it (a passage asked for,
    /// then held). `None`, and nothing moves, when `id` is not open here.
    pub fn hand_over<U>(&mut self, id: &str, to: &mut Initiated<U>, data: U) -> Option<T> {
        let (initiator, old) = self.open.remove(id)?;
        to.open.insert(id.to_owned(), (initiator, data));
        Some(old)
    }

    /// The data of conversation `id`.
    pub fn get(&self, id: &str) -> Option<&T> {
        self.open.get(id).map(|(_, data)| data)
    }

    /// The data of conversation `id`, to update.
    pub fn get_mut(&mut self, id: &str) -> Option<&mut T> {
        self.open.get_mut(id).map(|(_, data)| data)
    }

    /// The open conversations' ids and data.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &T)> {
        self.open.iter().map(|(id, (_, data))| (id.as_str(), data))
    }

    /// How many conversations are open.
    pub fn len(&self) -> usize {
        self.open.len()
    }

    /// Whether none is open.
    pub fn is_empty(&self) -> bool {
        self.open.is_empty()
    }
}

impl Context<'_> {
    /// Takes up the conversation `opening` opens, as this agent. An opening that names no
    /// protocol runs the one its act opens (REQUEST: fipa-request, QUERY-IF/REF: fipa-query,
    /// SUBSCRIBE: fipa-subscribe, ...), and one without a conversation id gets one, since FIPA
    /// makes neither mandatory. When the act cannot open a conversation, or opens another
    /// protocol than named, `opening` is answered NOT-UNDERSTOOD with the reason and `None`
    /// comes back.
    pub fn accept(&mut self, opening: &AclMessage) -> Option<Responder> {
        let mut opening = opening.clone();
        if opening.protocol.is_none() {
            opening.protocol = Protocol::ALL
                .into_iter()
                .find(|p| p.is_initiating(opening.performative))
                .map(|p| p.fipa_name().to_owned());
        }
        if opening.conversation_id.is_none() {
            let sender = opening
                .sender
                .as_ref()
                .map_or("anonymous", |s| s.name.as_str());
            opening.conversation_id = Some(format!("{sender}-{}", self.now().as_ns()));
        }
        match Responder::accept(&opening, self.aid().clone(), unix_ms(self.now())) {
            Ok(responder) => Some(responder),
            Err(err) => {
                let _ = self.not_understood(&opening, &err.to_string());
                None
            }
        }
    }

    /// Whether `message` goes on with `responder`'s conversation (a request stream's next
    /// REQUEST, a CANCEL of a subscription); if so it is applied to `responder`. A message of
    /// another conversation or sender, or one the protocol does not allow now, changes nothing.
    pub fn continues(&self, responder: &mut Responder, message: &AclMessage) -> bool {
        responder.handle(message, unix_ms(self.now())).is_ok()
    }

    /// Sends `act` in `responder`'s conversation, with `content` (its ontology and language
    /// set), if the protocol allows `act` now; otherwise nothing is sent and the error says why.
    pub fn answer<C: TypedContent>(
        &mut self,
        responder: &mut Responder,
        act: Performative,
        content: &C,
    ) -> Result<(), AgentError> {
        let reply = self.reply_in(responder, act)?;
        self.send(content.fill_into(reply))
    }

    /// [`Context::answer`] with no content: an AGREE that restates nothing.
    pub fn acknowledge(
        &mut self,
        responder: &mut Responder,
        act: Performative,
    ) -> Result<(), AgentError> {
        let reply = self.reply_in(responder, act)?;
        self.send(reply)
    }

    fn reply_in(
        &self,
        responder: &mut Responder,
        act: Performative,
    ) -> Result<AclMessage, AgentError> {
        responder
            .reply(act, unix_ms(self.now()))
            .map_err(|source| AgentError::Protocol {
                agent: self.name().to_owned(),
                source,
            })
    }

    /// [`Context::answer`] with an `error-message` reason: REFUSE or FAILURE in
    /// `responder`'s conversation.
    pub fn answer_error(
        &mut self,
        responder: &mut Responder,
        act: Performative,
        reason: &str,
    ) -> Result<(), AgentError> {
        self.answer(responder, act, &WheelchairContent::error(reason))
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    use iw_acl::{AgentId, FipaDateTime};
    use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Stack};

    use super::*;
    use crate::{Agent, AgentHost};

    type Log = Arc<Mutex<Vec<String>>>;

    /// Asks `participant` once at setup (reply by 1 s) and logs what the conversation does.
    struct Asker {
        participant: &'static str,
        asked: Initiated<&'static str>,
        log: Log,
    }

    impl Agent for Asker {
        fn setup(&mut self, ctx: &mut Context<'_>) {
            let request = WheelchairContent::error("please")
                .fill(AclMessage::new(Performative::Request))
                .with_receiver(AgentId::new(self.participant))
                .with_reply_by(FipaDateTime::from_unix_ms(unix_ms(ctx.now()) + 1_000));
            self.asked
                .open(ctx, Protocol::Request, request, "errand")
                .unwrap();
        }
        fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
            let line = match self.asked.handle(ctx, &message) {
                None => format!("not ours: {}", message.performative),
                Some(Ok(Progress::Continues(e))) => format!("continues: {:?}", e.kind),
                Some(Ok(Progress::Ended(e, data))) => format!("ended: {:?} {data}", e.kind),
                Some(Err(_)) => format!("out of protocol: {}", message.performative),
            };
            self.log.lock().unwrap().push(line);
        }
        fn tick_period(&self) -> Option<Duration> {
            Some(Duration::from_millis(100))
        }
        fn tick(&mut self, ctx: &mut Context<'_>) {
            for (event, data) in self.asked.expire(ctx.now()) {
                let line = format!("ended: {:?} {data}", event.kind);
                self.log.lock().unwrap().push(line);
            }
        }
    }

    /// Answers every request with `acts` in order (through its responder), logging refusals of
    /// the protocol.
    struct Answerer {
        acts: Vec<Performative>,
        log: Log,
    }

    impl Agent for Answerer {
        fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
            let Some(mut responder) = ctx.accept(&message) else {
                return;
            };
            for act in self.acts.clone() {
                if let Err(err) = ctx.answer(&mut responder, act, &WheelchairContent::error("x")) {
                    self.log
                        .lock()
                        .unwrap()
                        .push(format!("refused {act}: {err}"));
                }
            }
        }
    }

    /// Runs an asker and an answerer answering `acts` for `ms` of simulated time.
    fn run(acts: Vec<Performative>, ms: u64) -> (Vec<String>, Vec<String>) {
        let network = InProcNetwork::new();
        let (clock, controller) = Clock::mock(Time::from_ns(1_000_000_000));
        let transport = Arc::new(network.endpoint("c1").unwrap());
        let bus = Bus::start(Stack::new(), transport, clock, BusConfig::default()).unwrap();
        let mut host = AgentHost::new(Arc::new(bus));
        let (asker_log, answerer_log) = (Log::default(), Log::default());
        let asker = Asker {
            participant: "answerer",
            asked: Initiated::new(),
            log: asker_log.clone(),
        };
        let answerer = Answerer {
            acts,
            log: answerer_log.clone(),
        };
        host.add(AgentId::new("asker"), Box::new(asker)).unwrap();
        host.add(AgentId::new("answerer"), Box::new(answerer))
            .unwrap();
        for _ in 0..ms / 50 {
            host.step(controller.now());
            controller.advance(Duration::from_millis(50));
        }
        let take = |log: Log| std::mem::take(&mut *log.lock().unwrap());
        (take(asker_log), take(answerer_log))
    }

    #[test]
    fn a_request_agreed_then_done_continues_then_ends_with_the_agents_data() {
        let (asked, answered) = run(vec![Performative::Agree, Performative::Inform], 200);
        assert_eq!(asked, ["continues: Agreed", "ended: Informed errand"]);
        assert!(answered.is_empty(), "{answered:?}");
    }

    #[test]
    fn a_responder_cannot_answer_twice_or_after_the_end() {
        let (asked, answered) = run(
            vec![
                Performative::Refuse,
                Performative::Agree,
                Performative::Inform,
            ],
            200,
        );
        assert_eq!(asked, ["ended: Refused errand"]);
        assert_eq!(answered.len(), 2, "{answered:?}");
        assert!(answered[0].starts_with("refused AGREE"), "{answered:?}");
    }

    #[test]
    fn silence_past_reply_by_times_the_conversation_out() {
        let (asked, _) = run(vec![], 1_500);
        assert_eq!(asked, ["ended: TimedOut errand"]);
    }
}
