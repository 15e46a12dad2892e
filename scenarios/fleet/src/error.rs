//! What can go wrong composing or driving a fleet.

use iw_wiring::{StartError, WiringError};

/// What went wrong composing or driving a fleet.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FleetError {
    /// Two chairs with one name, or a name that clashes with the services.
    #[error("chair name `{name}` is used twice or reserved")]
    DuplicateChair {
        /// The name.
        name: String,
    },
    /// A chair the fleet does not have.
    #[error("no chair `{name}` in the fleet")]
    NoSuchChair {
        /// The name asked for.
        name: String,
    },
    /// A container the fleet does not have (a chair name or `services`).
    #[error("no agent `{agent}` in container `{container}`")]
    NoSuchAgent {
        /// The container.
        container: String,
        /// The agent.
        agent: String,
    },
    /// A bus, transport or agent could not be set up.
    #[error("container `{container}`: {reason}")]
    Setup {
        /// The container.
        container: String,
        /// Why.
        reason: String,
    },
    /// A part of a container (its bus, an agent, a chair's body or camera) could not start.
    #[error(transparent)]
    Start(#[from] StartError),
    /// Composing a container's agents failed otherwise.
    #[error("{source}")]
    Wiring {
        /// What the wiring said.
        #[source]
        source: WiringError,
    },
    /// The simulator refused (unknown door, door blocked).
    #[error("simulator: {source}")]
    Sim {
        /// What it said.
        #[from]
        source: iw_sim::SimError,
    },
    /// No path to a goal.
    #[error("cannot plan: {reason}")]
    Plan {
        /// Why.
        reason: String,
    },
}

impl From<WiringError> for FleetError {
    fn from(e: WiringError) -> Self {
        match e {
            WiringError::Setup { container, reason } => FleetError::Setup { container, reason },
            WiringError::Plan { reason } => FleetError::Plan { reason },
            WiringError::Start(e) => FleetError::Start(e),
            source => FleetError::Wiring { source },
        }
    }
}
