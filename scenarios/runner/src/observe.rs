//! What a run saw, as typed events both modes produce: the assertions
//! ([`crate::assertions`]) are checked over these, never over printed text.
//!
//! In process an [`Observation`] comes from the fleet (its snapshot, the console's desk, the
//! lockstep network's frames); across processes from the containers' JSON events (the world's
//! `body`, the services' `goal`), the impairment relay's counters and the logger agent's log.

use iw_acl::{AclMessage, Performative};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, WheelchairAction, WheelchairContent};

/// One thing seen during a run, stamped with run time (s).
#[derive(Debug, Clone, PartialEq)]
pub enum Observation {
    /// A chair's body as the world holds it (true pose, not the chair's own estimate).
    Body {
        /// Run time, s.
        time_s: f64,
        /// The chair.
        chair: String,
        /// x m, y m, heading rad.
        pose: [f64; 3],
        /// Forward speed, m/s (absolute).
        speed_mps: f64,
        /// Distance driven so far, m.
        distance_m: f64,
        /// Contacts so far.
        collisions: u64,
    },
    /// A goal was given to a chair (the point it must reach).
    GoalGiven {
        /// Run time, s.
        time_s: f64,
        /// The chair.
        chair: String,
        /// The goal, m.
        target: [f64; 2],
    },
    /// A goal could not even be asked for: no path to it.
    NoPath {
        /// Run time, s.
        time_s: f64,
        /// The chair.
        chair: String,
    },
    /// The staff console's answer about a chair's goal (relayed by the assistant).
    Answer {
        /// Run time, s.
        time_s: f64,
        /// The chair.
        chair: String,
        /// AGREE, INFORM (done), FAILURE, REFUSE, NOT-UNDERSTOOD.
        performative: Performative,
    },
    /// A message between agents (in process: every frame between containers; across
    /// processes: every message in the logger agent's log).
    Message(Box<AclMessage>),
}

/// Counts over the whole run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Totals {
    /// Frames between containers, delivered and dropped.
    pub messages: u64,
    /// Frames lost to link faults.
    pub dropped: u64,
    /// Messages the agents sent (each once).
    pub sent: u64,
    /// Records in the logger agent's log.
    pub logged: u64,
}

/// The door agent's answer (REFUSE or FAILURE) to a request to open a door, paired with the
/// request by conversation.
#[derive(Debug, Clone, PartialEq)]
pub struct DoorAnswer {
    /// Who asked (`cognitive@CHAIR`).
    pub requester: String,
    /// The door's name as agents use it.
    pub door: String,
    /// REFUSE or FAILURE.
    pub performative: Performative,
    /// The answer's `error-message`, if it carries one.
    pub reason: Option<String>,
}

/// Every REFUSE or FAILURE `door_agent` sent about an `open-door` request among `seen`.
pub fn door_answers(seen: &[Observation], door_agent: &str) -> Vec<DoorAnswer> {
    let messages: Vec<&AclMessage> = seen
        .iter()
        .filter_map(|o| match o {
            Observation::Message(m) => Some(m.as_ref()),
            _ => None,
        })
        .collect();
    let sender = |m: &AclMessage| m.sender.as_ref().map(|s| s.name.clone());
    messages
        .iter()
        .filter(|m| {
            matches!(m.performative, Performative::Refuse | Performative::Failure)
                && sender(m).as_deref() == Some(door_agent)
        })
        .filter_map(|answer| {
            let conversation = answer.conversation_id.as_ref()?;
            let request = messages.iter().find(|m| {
                m.performative == Performative::Request
                    && m.conversation_id.as_ref() == Some(conversation)
                    && m.receivers.iter().any(|r| r.name == door_agent)
                    && answer
                        .receivers
                        .iter()
                        .any(|r| Some(&r.name) == m.sender.as_ref().map(|s| &s.name))
            })?;
            let Ok(WheelchairContent::Request {
                action: WheelchairAction::OpenDoor { door },
                ..
            }) = WheelchairContent::from_message(request)
            else {
                return None;
            };
            let reason = match WheelchairContent::from_message(answer) {
                Ok(WheelchairContent::Inform(Fact::ErrorMessage { reason })) => Some(reason),
                _ => None,
            };
            Some(DoorAnswer {
                requester: sender(request)?,
                door,
                performative: answer.performative,
                reason,
            })
        })
        .collect()
}
