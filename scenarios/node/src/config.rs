//! The spawn configuration: one TOML file (every key documented in `deploy/default.toml`),
//! overridden by command-line flags.

use std::path::Path;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::NodeError;
use iw_wiring::BodyKind;

/// Everything one container process needs. Every section and key has a default, so an empty
/// file is a valid configuration.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpawnConfig {
    /// The container itself.
    pub container: ContainerSection,
    /// How it reaches the others.
    pub transport: TransportSection,
    /// Its identity and the bus layers.
    pub security: SecuritySection,
    /// The map the virtual bodies and the planner use.
    pub world: WorldSection,
    /// A chair's body.
    pub body: BodySection,
    /// What the service container does.
    pub services: ServicesSection,
    /// The services container's dashboard.
    pub dashboard: DashboardSection,
    /// Message transports to other FIPA platforms.
    pub mtp: MtpSection,
}

/// The container: name, id, periods.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContainerSection {
    /// Lowest id leads the Global Agent List; 0 derives it from the name (services 1, chairs
    /// 1000 and up).
    pub id: u64,
    /// Heartbeat period between containers (key `heartbeat_ms`).
    #[serde(rename = "heartbeat_ms", with = "iw_bus::millis")]
    pub heartbeat: Duration,
    /// A container not heard for this long is taken for gone (key `lease_ms`).
    #[serde(rename = "lease_ms", with = "iw_bus::millis")]
    pub lease: Duration,
    /// Agent step period, real time (key `step_ms`).
    #[serde(rename = "step_ms", with = "iw_bus::millis")]
    pub step: Duration,
    /// On SIGTERM, how long the deregistration is given to reach the leader (key
    /// `shutdown_grace_ms`).
    #[serde(rename = "shutdown_grace_ms", with = "iw_bus::millis")]
    pub shutdown_grace: Duration,
}

impl Default for ContainerSection {
    fn default() -> Self {
        ContainerSection {
            id: 0,
            heartbeat: Duration::from_millis(50),
            // 20 heartbeats: a container process on a loaded host (a CI runner, a chair's
            // computer busy with vision) misses 250 ms windows, and each miss drops its agents
            // from every GAL. Safety does not wait on the lease: the wheel and world-link
            // watchdogs stop a chair within 500 ms.
            lease: Duration::from_millis(1000),
            step: Duration::from_millis(20),
            shutdown_grace: Duration::from_millis(300),
        }
    }
}

/// Which transport carries the frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TransportKind {
    /// UDP datagrams between hosts (or on loopback).
    #[default]
    Udp,
    /// Length-prefixed frames over TCP connections (where UDP is filtered).
    Tcp,
    /// iceoryx2 shared memory between processes of one host.
    Iceoryx2,
}

impl std::str::FromStr for TransportKind {
    type Err = NodeError;
    fn from_str(s: &str) -> Result<Self, NodeError> {
        match s {
            "udp" => Ok(TransportKind::Udp),
            "tcp" => Ok(TransportKind::Tcp),
            "iceoryx2" => Ok(TransportKind::Iceoryx2),
            other => Err(NodeError::Flag {
                flag: "--transport",
                value: other.into(),
                reason: "expected `udp`, `tcp` or `iceoryx2`".into(),
            }),
        }
    }
}

/// Addresses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TransportSection {
    /// `udp`, `tcp` or `iceoryx2`.
    pub kind: TransportKind,
    /// Where the agent bus listens: `host:port` (udp, tcp) or an inbox name (iceoryx2). The
    /// container control channel uses the next port (udp, tcp) or the name with `-ctl`
    /// (iceoryx2).
    pub listen: String,
    /// The address the others reach this bus at (empty: `listen`); set it when listening on
    /// `0.0.0.0`.
    pub advertise: String,
    /// Other containers' bus addresses to greet (at least the service container's).
    pub peers: Vec<String>,
}

impl Default for TransportSection {
    fn default() -> Self {
        TransportSection {
            kind: TransportKind::Udp,
            listen: "127.0.0.1:7700".into(),
            advertise: String::new(),
            peers: Vec::new(),
        }
    }
}

/// Identity and layers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SecuritySection {
    /// The container's Ed25519 identity, a PKCS#8 file (`intellwheels spawn --keygen FILE`
    /// writes one). Empty: a fresh key each start (development only).
    pub identity_key: String,
    /// The deployment's group key for container control traffic (join, heartbeat, election,
    /// GAL): a file of 64 hex digits that every container shares (`intellwheels spawn
    /// --keygen-control FILE` writes one). Required unless `insecure_dev`.
    pub control_key: String,
    /// Run without a control key: control traffic is not authenticated (development only).
    pub insecure_dev: bool,
    /// The deployment's roster of container identities (`ID NAME PUBLIC_KEY` per line;
    /// `intellwheels spawn --keygen-roster FILE --member NAME ...` writes one with the keys):
    /// a control frame then speaks for an id only under the key pinned for it. Empty: ids are
    /// bound to keys first come, first served (the weaker mode).
    pub roster: String,
    /// Bus layers: `all`, `none`, or a comma list of `comm`, `security`, `temporal`, `parser`.
    pub layers: String,
}

impl Default for SecuritySection {
    fn default() -> Self {
        SecuritySection {
            identity_key: String::new(),
            control_key: String::new(),
            insecure_dev: false,
            roster: String::new(),
            layers: "all".into(),
        }
    }
}

/// The map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WorldSection {
    /// A map file (docs/map-format.md); empty: the embedded sample care building.
    pub map: String,
    /// Seed of the simulator's sensor noise.
    pub seed: u64,
    /// For tests: the world steps by a fixed 50 ms once every virtual body it hears from has sent
    /// wheel speeds since the last step (one silent for 500 ms is no longer waited for), and each
    /// virtual chair's body sends one wheel command per frame, so the world's trajectory does not
    /// depend on the host's load (`iw_wiring::world_link`). Give it to the world and the chairs
    /// alike. Off: the world steps in real time.
    pub lockstep: bool,
}

impl Default for WorldSection {
    fn default() -> Self {
        WorldSection {
            map: String::new(),
            seed: 1,
            lockstep: false,
        }
    }
}

/// A chair's body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BodySection {
    /// `virtual`, `serial` (also read as `real`, the scenario's word) or `mixed`.
    pub kind: BodyKind,
    /// The serial port of the interface board (serial and mixed).
    pub port: String,
    /// Serial line speed, baud.
    pub baud: u32,
    /// Longest wait for a board reply (key `timeout_ms`).
    #[serde(rename = "timeout_ms", with = "iw_bus::millis")]
    pub timeout: Duration,
    /// Where the chair starts in the map frame: x (m), y (m), heading (deg).
    pub start: [f64; 3],
    /// A virtual body's perception agent also runs LSAC-SURF RGB-D visual odometry on a camera
    /// rendered from the map at the body's true pose the world sends (as the in-process fleet
    /// renders it), fused with the wheels; costs a render and a detection per control period.
    pub visual_odometry: bool,
    /// How long a virtual body's task waits, wheels stopped, for its world link to come back
    /// before it fails with the link's reason (key `reattach_wait_ms`;
    /// `iw_wiring::world_link::REATTACH_WAIT` by default: a world restart with room for a
    /// loaded host).
    #[serde(rename = "reattach_wait_ms", with = "iw_bus::millis")]
    pub reattach_wait: Duration,
}

impl Default for BodySection {
    fn default() -> Self {
        BodySection {
            kind: BodyKind::Virtual,
            port: String::new(),
            baud: 115_200,
            timeout: Duration::from_millis(200),
            start: [1.0, 6.0, 0.0],
            visual_odometry: false,
            reattach_wait: iw_wiring::world_link::REATTACH_WAIT,
        }
    }
}

/// One goal the service container gives a chair as soon as it joins.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GoalSpec {
    /// The chair's name.
    pub chair: String,
    /// A place of the map, or `x,y` in metres (map frame).
    pub place: String,
}

/// The service container.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ServicesSection {
    /// The deployment's chairs, which the assistant may direct (besides those named in goals
    /// and restricted doors).
    pub chairs: Vec<String>,
    /// Goals to give chairs when they join.
    pub goals: Vec<GoalSpec>,
    /// Restricted doors (map door id) and the chairs allowed through each; other doors open
    /// for anyone.
    pub restricted: std::collections::BTreeMap<String, Vec<String>>,
    /// The logger agent's log file; empty: a fresh file in the temporary directory.
    pub log: String,
    /// How often a chair's pose is reported on stdout (key `pose_report_ms`).
    #[serde(rename = "pose_report_ms", with = "iw_bus::millis")]
    pub pose_report: Duration,
}

impl Default for ServicesSection {
    fn default() -> Self {
        ServicesSection {
            chairs: Vec::new(),
            goals: Vec::new(),
            restricted: std::collections::BTreeMap::new(),
            log: String::new(),
            pose_report: Duration::from_millis(1000),
        }
    }
}

/// The dashboard the services container serves (staff view and chair views), fed from the
/// platform's traffic.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DashboardSection {
    /// Where it listens, `ip:port`; empty: no dashboard.
    pub listen: String,
    /// Its access token, which every request must carry (`?token=` or `Authorization: Bearer`);
    /// required when `listen` is not a loopback address, as for `intellwheels demo --token`.
    pub token: String,
}

/// Message transports to other FIPA platforms (the services container only).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MtpSection {
    /// The FIPA HTTP MTP (SC00084), JADE's default transport.
    pub http: HttpMtpSection,
}

/// The FIPA HTTP MTP gateway: foreign agents (JADE) reach the service agents as
/// `NAME@services` at `http://LISTEN/acc`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HttpMtpSection {
    /// Where the gateway listens, `ip:port`; empty: no gateway.
    pub listen: String,
}

/// Largest configuration file [`SpawnConfig::load`] reads, bytes (deploy/default.toml is a few
/// KiB; a FIFO or `/dev/zero` given as `--config` hung or ate memory before this cap).
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

impl SpawnConfig {
    /// Parses a configuration; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<SpawnConfig, NodeError> {
        toml::from_str(text).map_err(|e: toml::de::Error| NodeError::Setting {
            file: file.into(),
            source: e.into(),
        })
    }

    /// Reads (a regular file of at most `MAX_CONFIG_BYTES`, 1 MiB) and parses a configuration file.
    pub fn load(path: &Path) -> Result<SpawnConfig, NodeError> {
        let text =
            iw_sim::file::read_text(path, MAX_CONFIG_BYTES).map_err(|e| NodeError::Setting {
                file: path.display().to_string(),
                source: e.into(),
            })?;
        SpawnConfig::parse(&text, &path.display().to_string())
    }

    /// Checks what the types cannot: periods, addresses, a port for a real body.
    pub fn validate(&self, role: &crate::Role) -> Result<(), NodeError> {
        let bad = |key: &str, reason: String| {
            Err(NodeError::Config {
                file: key.into(),
                reason,
            })
        };
        let c = &self.container;
        for (key, value) in [
            ("container.heartbeat_ms", c.heartbeat),
            ("container.step_ms", c.step),
        ] {
            if value.is_zero() || value > Duration::from_secs(10) {
                return bad(
                    key,
                    format!("{} ms is outside 1..=10000", value.as_millis()),
                );
            }
        }
        if c.lease <= c.heartbeat {
            return bad(
                "container.lease_ms",
                format!(
                    "{} ms must exceed the heartbeat period ({} ms)",
                    c.lease.as_millis(),
                    c.heartbeat.as_millis()
                ),
            );
        }
        let report = self.services.pose_report;
        if report < c.step || report > Duration::from_secs(3600) {
            return bad(
                "services.pose_report_ms",
                format!(
                    "{} ms is outside {}..=3600000 (at most one report per container step)",
                    report.as_millis(),
                    c.step.as_millis()
                ),
            );
        }
        if self.transport.listen.is_empty() {
            return bad("transport.listen", "empty".into());
        }
        if self.security.control_key.is_empty() && !self.security.insecure_dev {
            return bad(
                "security.control_key",
                "empty: container control traffic would not be authenticated; give the \
                 deployment's group key file (--control-key FILE; `intellwheels spawn \
                 --keygen-control FILE` writes one) or, for development only, --insecure-dev"
                    .into(),
            );
        }
        if !self.security.roster.is_empty() && self.security.identity_key.is_empty() {
            return bad(
                "security.identity_key",
                format!(
                    "empty, but security.roster `{}` pins this container's key: give the identity \
                     key file the roster was made from (--key FILE)",
                    self.security.roster
                ),
            );
        }
        self.security
            .layers
            .parse::<iw_bus::LayerSet>()
            .map_err(|e| NodeError::Setting {
                file: "security.layers".into(),
                source: e.into(),
            })?;
        let d = &self.dashboard;
        if !d.listen.is_empty() {
            if *role != crate::Role::Services {
                return bad(
                    "dashboard.listen",
                    "only the services container serves the dashboard".into(),
                );
            }
            match d.listen.parse::<std::net::SocketAddr>() {
                Err(e) => {
                    return Err(NodeError::Value {
                        key: "dashboard.listen".into(),
                        what: format!("`{}`", d.listen),
                        source: e.into(),
                    });
                }
                Ok(addr) if !addr.ip().is_loopback() && d.token.is_empty() => {
                    return bad(
                        "dashboard.token",
                        format!(
                            "empty, but dashboard.listen `{addr}` is not loopback: give a token \
                             or listen on 127.0.0.1"
                        ),
                    );
                }
                Ok(_) => {}
            }
        }
        let mtp = &self.mtp.http.listen;
        if !mtp.is_empty() {
            if *role != crate::Role::Services {
                return bad(
                    "mtp.http.listen",
                    "only the services container runs the HTTP MTP gateway".into(),
                );
            }
            if let Err(e) = mtp.parse::<std::net::SocketAddr>() {
                return Err(NodeError::Value {
                    key: "mtp.http.listen".into(),
                    what: format!("`{mtp}`"),
                    source: e.into(),
                });
            }
        }
        if let crate::Role::Chair { .. } = role {
            if self.body.kind != BodyKind::Virtual && self.body.port.is_empty() {
                return bad(
                    "body.port",
                    format!(
                        "a {:?} body needs the serial port of its board",
                        self.body.kind
                    ),
                );
            }
            if self.body.start.iter().any(|v| !v.is_finite()) {
                return bad("body.start", format!("{:?} is not finite", self.body.start));
            }
            let wait = self.body.reattach_wait;
            if wait.is_zero() || wait > Duration::from_secs(600) {
                return bad(
                    "body.reattach_wait_ms",
                    format!("{} ms is outside 1..=600000", wait.as_millis()),
                );
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn empty_file_is_the_default_and_unknown_keys_are_refused() {
        assert_eq!(
            SpawnConfig::parse("", "t.toml").unwrap(),
            SpawnConfig::default()
        );
        let err = SpawnConfig::parse("[container]\nheartbeat = 5\n", "t.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("t.toml") && err.contains("heartbeat"), "{err}");
        let err = SpawnConfig::parse("[body]\nkind = \"wooden\"\n", "t.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("wooden"), "{err}");
    }

    #[test]
    fn periods_are_durations_under_their_millisecond_keys() {
        let text = "[container]\nheartbeat_ms = 40\nlease_ms = 900\nstep_ms = 25\n\
                    shutdown_grace_ms = 0\n[body]\ntimeout_ms = 150\nreattach_wait_ms = 3000\n\
                    [services]\npose_report_ms = 100\n";
        let config = SpawnConfig::parse(text, "t.toml").unwrap();
        let ms = Duration::from_millis;
        let c = &config.container;
        assert_eq!(
            (c.heartbeat, c.lease, c.step, c.shutdown_grace),
            (ms(40), ms(900), ms(25), ms(0))
        );
        assert_eq!(
            (config.body.timeout, config.body.reattach_wait),
            (ms(150), ms(3000))
        );
        assert_eq!(config.services.pose_report, ms(100));
        // written back under the same keys, as integers
        let again = toml::to_string(&config).unwrap();
        for line in [
            "heartbeat_ms = 40",
            "lease_ms = 900",
            "reattach_wait_ms = 3000",
        ] {
            assert!(again.contains(line), "{again}");
        }
        // a value that is no count of milliseconds is refused naming the key and the file
        for bad in ["lease_ms = -1", "lease_ms = 2.5", "lease_ms = \"long\""] {
            let err = SpawnConfig::parse(&format!("[container]\n{bad}\n"), "t.toml")
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("t.toml") && err.contains("lease_ms"),
                "{bad}: {err}"
            );
        }
    }

    #[test]
    fn a_body_kind_reads_as_the_spawn_config_and_the_scenario_spell_it() {
        for (text, kind) in [
            ("virtual", BodyKind::Virtual),
            ("serial", BodyKind::Real),
            ("real", BodyKind::Real),
            ("mixed", BodyKind::Mixed),
        ] {
            let config =
                SpawnConfig::parse(&format!("[body]\nkind = \"{text}\""), "t.toml").unwrap();
            assert_eq!(config.body.kind, kind, "{text}");
        }
        assert!(SpawnConfig::parse("[body]\nkind = \"ghost\"", "t.toml").is_err());
    }

    #[test]
    fn validation_names_the_key() {
        let err = SpawnConfig::default()
            .validate(&crate::Role::Services)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("security.control_key") && err.contains("--insecure-dev"),
            "{err}"
        );
        // A development config with one edit is refused for `role`, naming `key`.
        let refused = |edit: fn(&mut SpawnConfig), role: crate::Role, key: &str| {
            let mut config = SpawnConfig::default();
            config.security.insecure_dev = true;
            edit(&mut config);
            let err = config.validate(&role).unwrap_err().to_string();
            assert!(err.contains(key), "{err}");
        };
        let chair = || crate::Role::Chair { name: "c".into() };
        refused(
            |c| c.container.lease = Duration::from_millis(10),
            crate::Role::Services,
            "container.lease_ms",
        );
        refused(|c| c.body.kind = BodyKind::Real, chair(), "body.port");
        refused(
            |c| c.body.reattach_wait = Duration::ZERO,
            chair(),
            "body.reattach_wait_ms",
        );
        // 0 would report every step (a stdout flood), u64::MAX never
        refused(
            |c| c.services.pose_report = Duration::ZERO,
            crate::Role::World,
            "services.pose_report_ms",
        );
        refused(
            |c| c.services.pose_report = Duration::from_millis(u64::MAX),
            crate::Role::Services,
            "services.pose_report_ms",
        );
        let mut config = SpawnConfig::default();
        config.security.insecure_dev = true;
        for (listen, token, role, key) in [
            (
                "localhost:80",
                "",
                crate::Role::Services,
                "dashboard.listen",
            ),
            ("0.0.0.0:8080", "", crate::Role::Services, "dashboard.token"),
            ("127.0.0.1:8080", "", crate::Role::World, "dashboard.listen"),
        ] {
            config.dashboard = DashboardSection {
                listen: listen.into(),
                token: token.into(),
            };
            let err = config.validate(&role).unwrap_err().to_string();
            assert!(err.contains(key), "{listen}: {err}");
        }
        config.dashboard = DashboardSection::default();
        config.mtp.http.listen = "127.0.0.1".into();
        let err = config
            .validate(&crate::Role::Services)
            .unwrap_err()
            .to_string();
        assert!(err.contains("mtp.http.listen"), "{err}");
        config.mtp.http.listen = String::new();
        config.dashboard.token = "s3cret".into();
        config.dashboard.listen = "0.0.0.0:8080".into();
        config.validate(&crate::Role::Services).unwrap();
    }

    #[test]
    fn a_roster_needs_an_identity_key() {
        let mut config = SpawnConfig::default();
        config.security.insecure_dev = true;
        config.security.roster = "deploy/keys/roster".into();
        let err = config
            .validate(&crate::Role::Services)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("security.identity_key") && err.contains("deploy/keys/roster"),
            "{err}"
        );
        config.security.identity_key = "services.pk8".into();
        config.validate(&crate::Role::Services).unwrap();
    }

    /// `v` as a TOML float (`nan`, `inf` and `-inf` included).
    fn toml_float(v: f64) -> String {
        match v {
            v if v.is_nan() => "nan".into(),
            v if v.is_infinite() => if v > 0.0 { "inf" } else { "-inf" }.into(),
            v => format!("{v:?}"),
        }
    }

    proptest! {
        /// Any numbers in the numeric keys (NaN and infinities in the start pose included): the
        /// file parses and validates for every role, or is refused naming a key, never a panic;
        /// a chair accepted has a finite start and periods within their ranges.
        #[test]
        fn any_numbers_parse_and_validate_or_are_refused_naming_the_key(
            periods in prop::array::uniform4(prop_oneof![0u64..20_000, any::<u64>()]),
            start in prop::array::uniform3(prop_oneof![any::<f64>(), -50.0f64..50.0]),
        ) {
            let [heartbeat, lease, step, reattach] = periods;
            let text = format!(
                "[container]\nheartbeat_ms = {heartbeat}\nlease_ms = {lease}\nstep_ms = {step}\n\
                 [security]\ninsecure_dev = true\n\
                 [body]\nstart = [{}, {}, {}]\nreattach_wait_ms = {reattach}\n",
                toml_float(start[0]), toml_float(start[1]), toml_float(start[2]),
            );
            let config = match SpawnConfig::parse(&text, "fuzz.toml") {
                Ok(config) => config,
                Err(e) => {
                    prop_assert!(e.to_string().contains("fuzz.toml"), "{}", e);
                    return Ok(());
                }
            };
            let roles = [
                crate::Role::Services,
                crate::Role::World,
                crate::Role::Chair { name: "c1".into() },
            ];
            for role in &roles {
                match config.validate(role) {
                    Ok(()) => {
                        prop_assert!(!config.container.heartbeat.is_zero());
                        if let crate::Role::Chair { .. } = role {
                            prop_assert!(config.body.start.iter().all(|v| v.is_finite()));
                        }
                    }
                    Err(e) => {
                        let e = e.to_string();
                        prop_assert!(
                            ["container.", "body.", "services."].iter().any(|k| e.contains(k)),
                            "{}", e
                        );
                    }
                }
            }
        }

        /// No text makes the parser panic; whatever parses re-serialises to itself.
        #[test]
        fn parse_never_panics_and_round_trips(text in "\\PC{0,200}") {
            if let Ok(config) = SpawnConfig::parse(&text, "fuzz.toml") {
                let again = toml::to_string(&config).unwrap();
                prop_assert_eq!(SpawnConfig::parse(&again, "again.toml").unwrap(), config);
            }
        }
    }
}
