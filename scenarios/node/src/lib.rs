//! One container per process (thesis 3.3.3): a chair's agents, or the service agents, on
//! an agent bus over a real transport (UDP or iceoryx2 shared memory) with the platform's four
//! layers, joined to the other containers through the Global Agent List. This is what
//! `intellwheels spawn` runs and what `deploy/` packages.
//!
//! # Organization
//! - [`SpawnConfig`] and its sections: the TOML configuration (`deploy/default.toml` documents
//!   every key), overridden by flags.
//! - [`Role`]: a chair (`--chair NAME`), the services (`--services`) or the world (`--world`).
//! - [`Runtime`]: binds the transports, loads the identity key, builds the stack, hosts the
//!   agents the wiring (`iw-wiring`) composes for the role, exactly those of the in-process fleet
//!   (a chair: perception, control, cognitive, interface; the services: AMS, DF, door, logger,
//!   watcher, assistant and the staff console, which gives the configured goals), runs the container (heartbeats, election, list sync) and steps the agents in real
//!   time until asked to stop; then shuts down cleanly.
//! - [`Event`]: what a running container reports, one JSON line each.
//! - The services' dashboard (`[dashboard] listen`): the staff view and the chair views fed
//!   from the platform's traffic; its drive panel drives a chair through its interface agent.
//! - The services' FIPA HTTP MTP gateway (`[mtp.http] listen`): foreign platforms (JADE) reach
//!   the service agents (`df@services`, `assistant@services`, ...) over HTTP.
//! - [`http_platform`]: [`HttpPlatform`](http_platform::HttpPlatform), the AMS, the DF and given
//!   agents on an in-process bus behind an HTTP MTP gateway in one call, and
//!   [`Echo`](http_platform::Echo), the echo agent of the JADE captures.
//! - [`AdminCommand`]: what the parent process may ask of a running container on its stdin
//!   (`--admin-stdin`: a goal, a killed agent, a blinded laser, a failed sensor); not reachable
//!   from the network.
//! - [`write_identity`]: a new identity key file; [`write_roster`]: a deployment's identity
//!   keys and the roster that pins them (`security.roster`).
//!
//! # Design
//! - Two endpoints per container: the agent bus at `transport.listen` and the container
//!   control channel next to it (UDP: the next port; iceoryx2: the name with `-ctl`).
//! - One world container owns the simulator: virtual chairs' bodies live in it and are driven
//!   over the platform (`body@CHAIR` to `world@world`, same bus and layers as any traffic); real
//!   and mixed chairs report their pose there, and a mixed chair senses the other chairs and the
//!   virtual obstacles. The door agent moves the world's doors. See `iw_wiring::world_link`.
//! - A body without its world stops: the world stops a simulated body it hears no wheel command
//!   from, and a body that hears no frame fails its reads (the control agent stops the chair)
//!   while it asks to attach again; a restarted world takes the chairs back where they were.
//! - Agents of another container are routed, and their keys trusted, only while the GAL lists
//!   them and their container is live in this container's view; the service container (id 1)
//!   leads, so it sees every chair come and go.
//! - Every message an agent sends is copied to `logger@services` (a host tap), from every
//!   container.
//!
//! # Guarantees
//! - No input from a configuration file, a flag or a socket panics: errors name the key, the
//!   file or the address.
//! - On stop, every agent's take-down runs (the control agent stops the body), the body gets a
//!   last zero speed, and the container deregisters its agents and lets the leader hear it
//!   before it leaves. A chair killed outright is stopped by its board's watchdog; the others
//!   see its lease expire and drop its agents.
//! - The identity key file is written with mode 0600 and fsynced.
#![warn(missing_docs)]

mod config;
mod dashboard;
mod event;
pub mod http_platform;
mod mtp;
mod probe;
mod runtime;

pub use config::{
    BodySection, ContainerSection, DashboardSection, GoalSpec, HttpMtpSection, MtpSection,
    SecuritySection, ServicesSection, SpawnConfig, TransportKind, TransportSection, WorldSection,
};
pub use event::Event;
pub use runtime::{
    AdminCommand, MAX_ADMIN_LINE, Runtime, control_addr, write_identity, write_roster,
};

/// What a chair's body is (`[body] kind`), the fleet's own type.
pub use iw_wiring::BodyKind;
/// The service container's name.
pub use iw_wiring::SERVICES;

/// What a container process hosts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Role {
    /// Chair `name`'s agents over its body (`iw_wiring::chair_agents`).
    Chair {
        /// The chair's name (its agents are `perception@NAME`, `control@NAME`,
        /// `cognitive@NAME` and `interface@NAME`).
        name: String,
    },
    /// The service agents (`iw_wiring::service_agents`).
    Services,
    /// The world: the simulator that owns the deployment's one shared world
    /// (`iw_wiring::world_link::WorldAgent`).
    World,
}

impl Role {
    /// The role of the container called `name` (the inverse of [`Role::name`]).
    pub fn of_name(name: &str) -> Role {
        match name {
            SERVICES => Role::Services,
            n if n == iw_wiring::world_link::WORLD => Role::World,
            n => Role::Chair { name: n.into() },
        }
    }

    /// The container's name.
    pub fn name(&self) -> &str {
        match self {
            Role::Chair { name } => name,
            Role::Services => SERVICES,
            Role::World => iw_wiring::world_link::WORLD,
        }
    }
}

/// The error underneath a [`NodeError`]: what the file system, a parser, the bus or an agent
/// said, kept whole so a caller can walk the chain or downcast it.
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// What went wrong starting or running a container.
///
/// A variant with a `source` says it in its message too (`… : <source>`), as the scenario and
/// simulator errors do: a caller printing only the message loses nothing.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NodeError {
    /// A configuration file or key that is wrong (`file` is the file or the key).
    #[error("configuration {file}: {reason}")]
    Config {
        /// The file, or the key as `section.key`.
        file: String,
        /// Why.
        reason: String,
    },
    /// A configuration file or key that cannot be read, parsed or used (`file` is the file or
    /// the key).
    #[error("configuration {file}: {source}")]
    Setting {
        /// The file, or the key as `section.key`.
        file: String,
        /// What the reader, parser or service said.
        #[source]
        source: Cause,
    },
    /// A configuration value that cannot be used (`what`: the value, or what was done with it).
    #[error("configuration {key}: {what}: {source}")]
    Value {
        /// The key as `section.key`.
        key: String,
        /// The value, or what was done with it, e.g. `` `a:b` `` or `binding 0.0.0.0:1`.
        what: String,
        /// What the parser or the service said.
        #[source]
        source: Cause,
    },
    /// A command-line value that is wrong.
    #[error("{flag} `{value}`: {reason}")]
    Flag {
        /// The flag.
        flag: &'static str,
        /// The value given.
        value: String,
        /// Why.
        reason: String,
    },
    /// The identity key file cannot be read, written or used.
    #[error("identity key {path}: {source}")]
    Key {
        /// The file.
        path: String,
        /// What the file system or the key parser said.
        #[source]
        source: Cause,
    },
    /// The control group key file cannot be read or is not 64 hex digits (its message names
    /// the file; its source is the OS's or the hex decoder's error).
    #[error(transparent)]
    ControlKey(#[from] iw_stack::GroupKeyError),
    /// A transport address that cannot be derived.
    #[error("transport address `{addr}`: {reason}")]
    Transport {
        /// The address.
        addr: String,
        /// Why.
        reason: String,
    },
    /// A transport that cannot be bound or opened.
    #[error("transport address `{addr}`: {source}")]
    Bind {
        /// The address.
        addr: String,
        /// What the transport said.
        #[source]
        source: iw_bus::transport::TransportError,
    },
    /// The body cannot be opened (`what`: the part, e.g. the serial port).
    #[error("body: {what}: {source}")]
    Body {
        /// What was being opened or checked.
        what: String,
        /// What the body driver or the simulator said.
        #[source]
        source: Cause,
    },
    /// The map lacks a place a goal names.
    #[error("map {map}: {reason}")]
    Map {
        /// The map file (or `embedded sample building`).
        map: String,
        /// Why.
        reason: String,
    },
    /// A goal's place is not on the map's free space.
    #[error("map {map}: goal of {chair}: {source}")]
    Goal {
        /// The map file (or `embedded sample building`).
        map: String,
        /// The chair the goal is for.
        chair: String,
        /// What the planner said.
        #[source]
        source: iw_wiring::WiringError,
    },
    /// The map cannot be loaded, or its building cannot be planned on.
    #[error("map {map}: {source}")]
    MapLoad {
        /// The map file (or `embedded sample building`).
        map: String,
        /// What the map reader or the planner said.
        #[source]
        source: Cause,
    },
    /// The container refused to go on (its control plane's verdict, e.g. a duplicate id).
    #[error("container `{container}`: {reason}")]
    Setup {
        /// The container.
        container: String,
        /// Why.
        reason: String,
    },
    /// A part of the container (its bus, an agent, its control plane) could not start.
    #[error(transparent)]
    Start(#[from] iw_wiring::StartError),
}
