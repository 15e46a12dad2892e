//! The interface agent itself.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::conversation::answers_a_conversation;
use iw_agent::{Agent, Context, EventKind, Initiated, Progress, Protocol, Responder};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

use crate::drive::{DriveCommand, DriveMapping};
use crate::input::RawInput;
use crate::sequence::Recognizer;

/// What a recognised sequence asks for: a high-level action (driving by hand is proportional,
/// see [`crate::drive`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum Command {
    /// A goal for the cognitive agent: go to a named place.
    Goal {
        /// A place of the building map.
        place: String,
    },
    /// Stop now (control agent).
    Stop,
}

/// Readings waiting for the agent, pushed by device drivers or the dashboard (cloning shares).
pub type InputQueue = Arc<Mutex<VecDeque<(RawInput, u64)>>>;

/// What the on-chair display shows.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Display {
    /// The last command a sequence sent.
    pub last_command: Option<Command>,
    /// The user's proportional command being streamed to the control agent, if any.
    pub drive: Option<DriveCommand>,
    /// Steps entered / steps of the sequence being recognised.
    pub progress: Option<(usize, usize)>,
    /// The last answer of the cognitive or control agent (performative and sender).
    pub last_answer: Option<String>,
    /// Inputs refused (bad symbols) so far.
    pub refused_inputs: u64,
}

/// Who the interface talks to.
#[derive(Debug, Clone)]
pub struct InterfaceConfig {
    /// The cognitive agent (goals).
    pub cognitive: AgentId,
    /// The control agent (manual commands).
    pub control: AgentId,
    /// How often queued inputs are processed, and drive commands streamed while an input is
    /// held (at most 100 ms: the stream must beat the control agent's watchdog several times).
    pub tick: Duration,
    /// Device readings to velocity commands.
    pub mapping: DriveMapping,
    /// A held input whose device has sent nothing for this long counts as released, ms (a
    /// browser tab closed, a cable pulled).
    pub hold: Duration,
    /// Agents of other containers that may drive this chair through this agent with `drive`
    /// requests (a dashboard's drive panel, relayed by the staff console); everyone else is
    /// refused.
    pub remote_drivers: Vec<String>,
}

impl InterfaceConfig {
    /// Talks to `cognitive` and `control`; 50 ms tick (20 Hz stream), default mapping, 300 ms
    /// hold.
    pub fn new(cognitive: AgentId, control: AgentId) -> Self {
        InterfaceConfig {
            cognitive,
            control,
            tick: Duration::from_millis(50),
            mapping: DriveMapping::default(),
            hold: Duration::from_millis(300),
            remote_drivers: Vec::new(),
        }
    }
}

/// The drive stream to the control agent while an input is held.
#[derive(Debug)]
struct Held {
    command: DriveCommand,
    /// When the device last reported, ns of the bus clock.
    seen_ns: u64,
    /// The stream's conversation (in [`InterfaceAgent::streams`]), from its first command on.
    conversation: Option<String>,
    /// The control agent refused or ended the stream: nothing is sent until the user lets go.
    stopped: bool,
    /// Who holds the input: `None` for this chair's own devices, else the remote driver and
    /// its drive stream (agreed once; it judges which later commands are the stream's).
    remote: Option<(String, Responder)>,
}

/// The interface agent: inputs in, ACL requests out.
pub struct InterfaceAgent {
    config: InterfaceConfig,
    recognizer: Recognizer<Command>,
    inputs: InputQueue,
    display: Arc<Mutex<Display>>,
    /// The requests recognised sequences sent (goals, stops).
    requests: Initiated<()>,
    /// The drive streams to the control agent, one per hold.
    streams: Initiated<()>,
    held: Option<Held>,
}

impl InterfaceAgent {
    /// An agent recognising the sequences bound in `recognizer`, reading `inputs`; the display
    /// state is shared through `display`.
    pub fn new(
        config: InterfaceConfig,
        recognizer: Recognizer<Command>,
        inputs: InputQueue,
        display: Arc<Mutex<Display>>,
    ) -> Self {
        InterfaceAgent {
            config,
            recognizer,
            inputs,
            display,
            requests: Initiated::new(),
            streams: Initiated::new(),
            held: None,
        }
    }

    /// `action` asked of `actor` (the conversation's protocol and id are the caller's).
    fn request(actor: &AgentId, action: WheelchairAction) -> AclMessage {
        WheelchairContent::Request {
            actor: actor.clone(),
            action,
        }
        .fill(AclMessage::new(Performative::Request).with_receiver(actor.clone()))
    }

    fn command_request(&self, command: &Command) -> AclMessage {
        match command {
            Command::Goal { place } => Self::request(
                &self.config.cognitive,
                WheelchairAction::GoTo {
                    place: place.clone(),
                },
            ),
            Command::Stop => Self::request(&self.config.control, WheelchairAction::Stop),
        }
    }

    /// A proportional reading arrived (`None`: a broken one, which counts as letting go).
    fn on_drive_input(&mut self, ctx: &mut Context<'_>, command: Option<DriveCommand>) {
        let now_ns = ctx.now().0;
        match command {
            Some(command) if !command.is_stop() => {
                let held = self.held.get_or_insert(Held {
                    command,
                    seen_ns: now_ns,
                    conversation: None,
                    stopped: false,
                    remote: None,
                });
                held.command = command;
                held.seen_ns = now_ns;
            }
            _ => self.release(ctx),
        }
    }

    /// The user let go (or the device went silent or broke): one stop in the stream, which
    /// ends it; the control agent answers INFORM done once its watchdog sees the silence.
    fn release(&mut self, ctx: &mut Context<'_>) {
        let Some(held) = self.held.take() else { return };
        self.display().drive = None;
        if let (Some(conversation), false) = (held.conversation, held.stopped) {
            self.send_drive(ctx, 0.0, 0.0, Some(&conversation));
        }
    }

    /// One command of the drive stream: the first opens its conversation (returned), the
    /// others go on in `conversation`. `None` back when the control agent already ended it.
    fn send_drive(
        &mut self,
        ctx: &mut Context<'_>,
        linear_mps: f64,
        angular_radps: f64,
        conversation: Option<&str>,
    ) -> Option<String> {
        let drive = Self::request(
            &self.config.control,
            WheelchairAction::Drive {
                linear_mps,
                angular_radps,
            },
        );
        let sent = match conversation {
            Some(id) => self
                .streams
                .stream(ctx, id, &drive)
                .map(|open| open.then(|| id.to_string())),
            None => self
                .streams
                .open(ctx, Protocol::Request, drive, ())
                .map(Some),
        };
        sent.unwrap_or_else(|err| {
            tracing::warn!("could not send a drive command: {err}");
            conversation.map(str::to_string)
        })
    }

    /// Streams the held command, one per tick; a device silent past the hold counts as
    /// released.
    fn stream(&mut self, ctx: &mut Context<'_>) {
        let now_ns = ctx.now().0;
        let Some(held) = &self.held else { return };
        let hold_ns = u64::try_from(self.config.hold.as_nanos()).unwrap_or(u64::MAX);
        if now_ns.saturating_sub(held.seen_ns) > hold_ns {
            tracing::info!("drive input silent past the hold; releasing");
            self.release(ctx);
            return;
        }
        if held.stopped {
            return;
        }
        let command = held.command;
        let conversation = held.conversation.clone();
        self.display().drive = Some(command);
        let now = self.send_drive(
            ctx,
            command.linear_mps,
            command.angular_radps,
            conversation.as_deref(),
        );
        if let Some(held) = &mut self.held {
            // ended by the control agent before its answer came: quiet until the user lets go
            held.stopped = conversation.is_some() && now.is_none();
            held.conversation = now.or(conversation);
        }
    }

    /// An answer in one of this agent's conversations: shown, and a drive stream the control
    /// agent refused or ended stops sending. `false` when it belongs to none of them.
    fn on_answer(&mut self, ctx: &Context<'_>, message: &AclMessage, from: &str) -> bool {
        let in_stream = self.streams.handle(ctx, message);
        let is_stream = in_stream.is_some();
        let Some(answer) = in_stream.or_else(|| self.requests.handle(ctx, message)) else {
            return false;
        };
        match answer {
            Err(err) => {
                tracing::debug!(error = %err, "out-of-protocol answer");
                return true;
            }
            Ok(Progress::Ended(event, ())) if is_stream && event.kind != EventKind::Informed => {
                if let Some(held) = &mut self.held
                    && held.conversation.is_some()
                    && held.conversation == message.conversation_id
                {
                    // Refused or ended by the control agent: quiet until the user lets go.
                    held.stopped = true;
                }
            }
            Ok(_) => {}
        }
        let why = match WheelchairContent::from_message(message) {
            Ok(content) => content.reason().map(|r| format!(": {r}")),
            Err(_) => None,
        }
        .unwrap_or_default();
        self.display().last_answer = Some(format!("{} from {from}{why}", message.performative));
        true
    }

    /// A `drive` request from another container: a remote driver's proportional command,
    /// held and streamed like a device's. Refused (with the reason): a sender not in
    /// [`InterfaceConfig::remote_drivers`], a command not finite or beyond the mapping's
    /// speeds (the chair stops), a second driver while another holds the chair. The first
    /// command of a conversation is agreed; a stop releases.
    fn on_remote_drive(&mut self, ctx: &mut Context<'_>, message: AclMessage, from: String) {
        let drive = match WheelchairContent::from_message(&message) {
            Ok(WheelchairContent::Request {
                actor,
                action:
                    WheelchairAction::Drive {
                        linear_mps,
                        angular_radps,
                    },
            }) => Ok((actor, linear_mps, angular_radps)),
            Ok(_) => Err("expected ((action actor (drive :linear V :angular W)))".to_string()),
            Err(err) => Err(err.to_string()),
        };
        let (actor, linear_mps, angular_radps) = match drive {
            Ok(drive) => drive,
            Err(why) => {
                // a broken command from the driver stops the chair (a NaN does not even parse)
                let holds = self
                    .held
                    .as_ref()
                    .and_then(|h| h.remote.as_ref())
                    .is_some_and(|(driver, _)| *driver == from);
                if holds {
                    self.release(ctx);
                    self.display().refused_inputs += 1;
                }
                let _ = ctx.not_understood(&message, &why);
                return;
            }
        };
        if !self.config.remote_drivers.contains(&from) {
            let _ = ctx.refuse(
                &message,
                &format!("`{from}` may not drive this chair through its interface"),
            );
            return;
        }
        let holder = self.held.as_ref().map(|h| h.remote.as_ref().map(|r| &r.0));
        if let Some(holder) = holder
            && holder != Some(&from)
        {
            let by = holder.map_or("this chair's own input device", String::as_str);
            let _ = ctx.refuse(&message, &format!("the chair is driven by {by}"));
            return;
        }
        let mapping = self.config.mapping;
        if !(linear_mps.is_finite() && angular_radps.is_finite())
            || linear_mps.abs() > mapping.max_linear_mps
            || angular_radps.abs() > mapping.max_angular_radps
        {
            self.release(ctx);
            self.display().refused_inputs += 1;
            let _ = ctx.refuse(
                &message,
                &format!(
                    "drive command out of range or not finite: linear {linear_mps} m/s \
                     (|v| <= {}), angular {angular_radps} rad/s (|w| <= {}); chair stopped",
                    mapping.max_linear_mps, mapping.max_angular_radps
                ),
            );
            return;
        }
        let known = self
            .held
            .as_mut()
            .and_then(|h| h.remote.as_mut())
            .is_some_and(|(_, stream)| ctx.continues(stream, &message));
        // A new conversation is a new stream; one that cannot open (NOT-UNDERSTOOD) moves nothing.
        let opened = if known {
            None
        } else {
            let Some(stream) = ctx.accept(&message) else {
                return;
            };
            Some(stream)
        };
        let command = DriveCommand {
            device: crate::Device::Remote,
            linear_mps,
            angular_radps,
        };
        self.on_drive_input(ctx, Some(command));
        if let (Some(held), Some(mut stream)) = (&mut self.held, opened) {
            let request = WheelchairContent::Request {
                actor,
                action: WheelchairAction::Drive {
                    linear_mps,
                    angular_radps,
                },
            };
            let _ = ctx.answer(&mut stream, Performative::Agree, &request);
            held.remote = Some((from, stream));
        }
    }

    fn display(&self) -> std::sync::MutexGuard<'_, Display> {
        self.display.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Agent for InterfaceAgent {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let from = message
            .sender
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default();
        if self.on_answer(ctx, &message, &from) {
            return;
        }
        match message.performative {
            act if answers_a_conversation(act) => {
                tracing::debug!(performative = %act, %from, "answer in no conversation of ours");
            }
            Performative::Request => self.on_remote_drive(ctx, message, from),
            _ => {
                let _ = ctx.not_understood(
                    &message,
                    "the interface agent takes answers to its requests and `drive` requests",
                );
            }
        }
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let pending: Vec<(RawInput, u64)> = self
            .inputs
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .drain(..)
            .collect();
        for (raw, t_ms) in pending {
            if let Some(mapped) = self.config.mapping.command(&raw) {
                let command = match mapped {
                    Ok(command) => Some(command),
                    Err(err) => {
                        tracing::warn!("drive input refused, chair stopped: {err}");
                        self.display().refused_inputs += 1;
                        None
                    }
                };
                self.on_drive_input(ctx, command);
                // the chair's own device takes the chair from a remote driver
                if let Some(held) = &mut self.held {
                    held.remote = None;
                }
                continue;
            }
            let events = match raw.normalise(t_ms) {
                Ok(events) => events,
                Err(err) => {
                    tracing::warn!("input refused: {err}");
                    self.display().refused_inputs += 1;
                    continue;
                }
            };
            for event in events {
                if let Some(command) = self.recognizer.feed(event) {
                    let message = self.command_request(&command);
                    if let Err(err) = self.requests.open(ctx, Protocol::Request, message, ()) {
                        tracing::warn!("could not send {command:?}: {err}");
                    }
                    self.display().last_command = Some(command);
                }
            }
        }
        self.stream(ctx);
        let progress = self.recognizer.progress();
        self.display().progress = progress;
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(self.config.tick)
    }
}
