//! The door agent: opens and closes the building's doors on request and enforces restricted
//! areas: only authorised chairs get a restricted door opened; every other request is refused
//! and recorded.
//!
//! Organization:
//! - [`DoorActuator`]: what moves a door (the composer implements it for the simulator's world
//!   or for real door controllers); [`ActuatorFault`] when it cannot (a jammed door).
//! - [`DoorConfig`] / [`DoorPolicy`]: the doors this agent manages and who may open which.
//! - [`DoorAgent::new`] takes both and a [`RefusalLog`] handle the composer keeps to report refusals.
//!
//! # Messages
//! All `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`, `:protocol fipa-request`.
//! - REQUEST `((action (agent-identifier :name DOOR) (open-door :door D)))` or `(close-door :door
//!   D)`: AGREE, then INFORM `((done (action DOOR (open-door :door D))))` once the actuator moved
//!   it, or FAILURE `((error-message "..."))` when the actuator faults. REFUSE
//!   `((error-message "..."))` for an unknown door or when `D` is restricted and the sender is not
//!   among its authorised agents (the sender is authenticated by the bus's security layer); the
//!   refusal is logged (tracing, warn) and appended to the [`RefusalLog`].
//! - QUERY-REF of a door's state is answered with INFORM `((door-state D open|closed))`; content
//!   is `((door-state D ?state))`.
//! - Anything else: NOT-UNDERSTOOD.
//!
//! Both run on the interaction protocols' state machines (`iw_agent::Responder`), so no answer
//! is sent that fipa-request or fipa-query does not allow.
#![warn(missing_docs)]

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};

use iw_acl::{AclMessage, Performative};
use iw_agent::{Agent, Context, Responder};
use iw_ontology::wheelchair::{DoorState, Fact, WheelchairAction, WheelchairContent};

/// A door that could not be moved.
///
/// It reaches the requester as the text of a FAILURE's `error-message` (SL content carries
/// no typed errors), so its message ends with the cause's; up to that boundary the cause is
/// kept whole as [`std::error::Error::source`], for the composer's logs and tests.
#[derive(Debug, thiserror::Error)]
#[error("door `{door}` could not be moved: {reason}{}", cause_text(.source))]
pub struct ActuatorFault {
    /// The door.
    pub door: String,
    /// Why (jammed, no power, unknown to the world, world unreachable).
    pub reason: String,
    /// The error underneath, when something below the actuator failed (the bus to the world,
    /// the simulator).
    #[source]
    pub source: Option<Box<dyn std::error::Error + Send + Sync + 'static>>,
}

impl ActuatorFault {
    /// A fault with nothing underneath (a jammed door, a door the world does not have).
    pub fn new(door: &str, reason: impl Into<String>) -> Self {
        ActuatorFault {
            door: door.to_string(),
            reason: reason.into(),
            source: None,
        }
    }

    /// A fault caused by `source` (e.g. the bus refusing the message to the world).
    pub fn caused(
        door: &str,
        reason: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        ActuatorFault {
            door: door.to_string(),
            reason: reason.into(),
            source: Some(Box::new(source)),
        }
    }
}

/// `: <cause>` when there is one, so the message alone loses nothing.
fn cause_text(source: &Option<Box<dyn std::error::Error + Send + Sync + 'static>>) -> String {
    source
        .as_ref()
        .map(|e| format!(": {e}"))
        .unwrap_or_default()
}

/// What moves doors.
pub trait DoorActuator: Send {
    /// Drives `door` to `open` (true) or closed, returning when it is there.
    fn set(&mut self, door: &str, open: bool) -> Result<(), ActuatorFault>;
}

/// Who may open one door.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DoorPolicy {
    /// Whether only `authorised` agents may open it.
    pub restricted: bool,
    /// Agent names allowed to open it when restricted (e.g. `cognitive-chair1`).
    pub authorised: BTreeSet<String>,
}

/// The doors the agent manages.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DoorConfig {
    /// Door name to policy; every door starts closed.
    pub doors: BTreeMap<String, DoorPolicy>,
}

/// One refused request.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    /// Bus time, ns.
    pub time_ns: u64,
    /// Who asked.
    pub requester: String,
    /// Which door.
    pub door: String,
    /// Why it was refused.
    pub reason: String,
}

/// Refusals the composer (and scenario assertions) can read while the agent runs.
pub type RefusalLog = Arc<Mutex<Vec<Refusal>>>;

/// The door agent.
pub struct DoorAgent {
    config: DoorConfig,
    actuator: Box<dyn DoorActuator>,
    open: BTreeSet<String>,
    refusals: RefusalLog,
}

impl DoorAgent {
    /// A door agent driving `actuator`, recording refusals in `refusals`.
    pub fn new(config: DoorConfig, actuator: Box<dyn DoorActuator>, refusals: RefusalLog) -> Self {
        DoorAgent {
            config,
            actuator,
            open: BTreeSet::new(),
            refusals,
        }
    }

    fn refuse(
        &mut self,
        ctx: &mut Context<'_>,
        request: &mut Responder,
        door: &str,
        reason: String,
    ) {
        let requester = request
            .initiator()
            .map(|s| s.name.clone())
            .unwrap_or_default();
        tracing::warn!(door, requester = %requester, reason = %reason, "door request refused");
        if let Ok(mut log) = self.refusals.lock() {
            log.push(Refusal {
                time_ns: ctx.now().0,
                requester,
                door: door.to_string(),
                reason: reason.clone(),
            });
        }
        let _ = ctx.answer_error(request, Performative::Refuse, &reason);
    }

    fn on_request(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let Some((actor, action)) = ctx.understand(
            &message,
            "expected ((action door (open-door :door D)))",
            |c| match c {
                WheelchairContent::Request { actor, action } => Some((actor, action)),
                _ => None,
            },
        ) else {
            return;
        };
        let Some(mut request) = ctx.accept(&message) else {
            return;
        };
        let (door, open) = match &action {
            WheelchairAction::OpenDoor { door } => (door.clone(), true),
            WheelchairAction::CloseDoor { door } => (door.clone(), false),
            _ => {
                let _ = ctx.answer_error(
                    &mut request,
                    Performative::Refuse,
                    "the door agent only opens and closes doors",
                );
                return;
            }
        };
        let Some(policy) = self.config.doors.get(&door) else {
            self.refuse(ctx, &mut request, &door, format!("unknown door `{door}`"));
            return;
        };
        let requester = message
            .sender
            .as_ref()
            .map(|s| s.name.as_str())
            .unwrap_or_default();
        if open && policy.restricted && !policy.authorised.contains(requester) {
            let reason =
                format!("`{requester}` is not authorised to open restricted door `{door}`");
            self.refuse(ctx, &mut request, &door, reason);
            return;
        }
        let asked = WheelchairContent::Request {
            actor: actor.clone(),
            action: action.clone(),
        };
        if ctx
            .answer(&mut request, Performative::Agree, &asked)
            .is_err()
        {
            return;
        }
        match self.actuator.set(&door, open) {
            Ok(()) => {
                if open {
                    self.open.insert(door);
                } else {
                    self.open.remove(&door);
                }
                let done = WheelchairContent::Done { actor, action };
                let _ = ctx.answer(&mut request, Performative::Inform, &done);
            }
            Err(fault) => {
                tracing::warn!(error = %fault, "door actuator fault");
                let _ = ctx.answer_error(&mut request, Performative::Failure, &fault.to_string());
            }
        }
    }

    fn on_query(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let text = message.content_text().unwrap_or_default();
        let door = self.config.doors.keys().find(|d| {
            text.split(|c: char| c.is_whitespace() || c == '(' || c == ')')
                .any(|w| w == d.as_str())
        });
        let Some(door) = door.cloned() else {
            let _ = ctx.not_understood(
                &message,
                "query ((door-state D ?state)) for a door this agent manages",
            );
            return;
        };
        let Some(mut query) = ctx.accept(&message) else {
            return;
        };
        let state = if self.open.contains(&door) {
            DoorState::Open
        } else {
            DoorState::Closed
        };
        let fact = WheelchairContent::Inform(Fact::Door { door, state });
        let _ = ctx.answer(&mut query, Performative::Inform, &fact);
    }
}

impl Agent for DoorAgent {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Request => self.on_request(ctx, message),
            Performative::QueryRef => self.on_query(ctx, message),
            _ => {
                let _ = ctx.not_understood(&message, "the door agent takes requests and query-ref");
            }
        }
    }
}
