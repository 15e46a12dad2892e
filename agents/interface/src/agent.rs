//! The interface agent itself.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

use crate::input::RawInput;
use crate::sequence::Recognizer;

/// What a recognised sequence asks for.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum Command {
    /// A goal for the cognitive agent: go to a named place.
    Goal {
        /// A place of the building map.
        place: String,
    },
    /// A manual command for the control agent, m/s and rad/s.
    Drive {
        /// Linear speed.
        linear_mps: f64,
        /// Angular speed.
        angular_radps: f64,
    },
    /// Stop now (control agent).
    Stop,
}

/// Readings waiting for the agent, pushed by device drivers or the dashboard (cloning shares).
pub type InputQueue = Arc<Mutex<VecDeque<(RawInput, u64)>>>;

/// What the on-chair display shows.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Display {
    /// The last command sent.
    pub last_command: Option<Command>,
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
    /// How often queued inputs are processed.
    pub tick: Duration,
}

/// The interface agent: inputs in, ACL requests out.
pub struct InterfaceAgent {
    config: InterfaceConfig,
    recognizer: Recognizer<Command>,
    inputs: InputQueue,
    display: Arc<Mutex<Display>>,
    conversations: u64,
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
            conversations: 0,
        }
    }

    fn request(&mut self, ctx: &Context<'_>, command: &Command) -> AclMessage {
        self.conversations += 1;
        let conversation = format!("{}-{}", ctx.name(), self.conversations);
        let base = |to: &AgentId| {
            AclMessage::new(Performative::Request)
                .with_receiver(to.clone())
                .with_protocol("fipa-request")
                .with_conversation_id(conversation.clone())
        };
        match command {
            Command::Goal { place } => {
                let actor = self.config.cognitive.clone();
                WheelchairContent::Request {
                    actor: actor.clone(),
                    action: WheelchairAction::GoTo {
                        place: place.clone(),
                    },
                }
                .fill(base(&actor))
            }
            Command::Stop => {
                let actor = self.config.control.clone();
                WheelchairContent::Request {
                    actor: actor.clone(),
                    action: WheelchairAction::Stop,
                }
                .fill(base(&actor))
            }
            Command::Drive {
                linear_mps,
                angular_radps,
            } => base(&self.config.control)
                .with_content(iw_control_agent::drive_content(
                    &self.config.control.name,
                    *linear_mps,
                    *angular_radps,
                ))
                .with_language("fipa-sl0")
                .with_ontology(iw_ontology::wheelchair::ONTOLOGY),
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
        match message.performative {
            Performative::Agree
            | Performative::Inform
            | Performative::Failure
            | Performative::Refuse
            | Performative::NotUnderstood => {
                self.display().last_answer = Some(format!("{} from {from}", message.performative));
            }
            _ => {
                let _ = ctx.not_understood(
                    &message,
                    "the interface agent only takes answers to its requests",
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
                    let message = self.request(ctx, &command);
                    if let Err(err) = ctx.send(message) {
                        tracing::warn!("could not send {command:?}: {err}");
                    }
                    self.display().last_command = Some(command);
                }
            }
        }
        let progress = self.recognizer.progress();
        self.display().progress = progress;
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(self.config.tick)
    }
}
