//! [`Roster`]: a deployment's container identities pinned in advance, so that no id is bound to
//! whoever claims it first.
//!
//! The file is text, one container per line, `ID NAME PUBLIC_KEY`: the container id (decimal),
//! its name (the part after `@` in its agents' names, `control@chair-0` for `chair-0`) and its
//! Ed25519 public key (64 hex digits, the identity its control sessions are agreed under).
//! Blank lines and lines starting with `#` are ignored. Ids, names and keys are each unique: one
//! key speaks for one container only.

use std::collections::BTreeMap;
use std::path::Path;

use hex::FromHex;
use iw_layer_security::PublicKey;

use crate::{ContainerError, ContainerId};

/// Largest roster file read, bytes (a line is under 100 bytes: room for thousands of chairs).
pub const MAX_ROSTER_BYTES: u64 = 1 << 20;

/// One container as the roster pins it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Pin {
    /// Its name: its agents are named `ROLE@NAME`.
    pub name: String,
    /// The only key its control frames, and its agents' entries, may carry.
    pub key: PublicKey,
}

impl Pin {
    /// Whether agent `agent` is one of this container's (`ROLE@NAME`, `ROLE` not empty).
    pub fn hosts(&self, agent: &str) -> bool {
        agent
            .rsplit_once('@')
            .is_some_and(|(role, container)| !role.is_empty() && container == self.name)
    }
}

/// The pinned identities of a deployment's containers, by id.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Roster {
    /// Where it was read (named in errors and warnings).
    source: String,
    pins: BTreeMap<ContainerId, Pin>,
}

impl Roster {
    /// A roster of `pins`, called `source` in messages; refuses a repeated id, name or key and a
    /// name that is not a container name.
    pub fn new(
        source: &str,
        pins: impl IntoIterator<Item = (ContainerId, Pin)>,
    ) -> Result<Roster, ContainerError> {
        let mut roster = Roster {
            source: source.into(),
            pins: BTreeMap::new(),
        };
        for (i, (id, pin)) in pins.into_iter().enumerate() {
            roster
                .add(id, pin)
                .map_err(|reason| roster.error(Some(i + 1), reason))?;
        }
        Ok(roster)
    }

    /// Parses roster text; `source` (the file) is named in errors with the line.
    pub fn parse(text: &str, source: &str) -> Result<Roster, ContainerError> {
        let mut roster = Roster {
            source: source.into(),
            pins: BTreeMap::new(),
        };
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let (id, pin) = parse_line(line).map_err(|bad| match bad {
                BadLine::Shape(reason) => roster.error(Some(n + 1), reason),
                BadLine::Value { what, source } => ContainerError::RosterValue {
                    file: roster.source.clone(),
                    line: n + 1,
                    what,
                    source,
                },
            })?;
            roster
                .add(id, pin)
                .map_err(|reason| roster.error(Some(n + 1), reason))?;
        }
        if roster.pins.is_empty() {
            return Err(roster.error(None, "lists no container".into()));
        }
        Ok(roster)
    }

    /// Reads and parses the roster file at `path` (at most [`MAX_ROSTER_BYTES`]).
    pub fn load(path: &Path) -> Result<Roster, ContainerError> {
        let source = path.display().to_string();
        // A FIFO, device or folder (refused unread) and an oversize file are rosters that cannot
        // be; any other failure keeps its `io::Error`.
        let text = iw_file::read_text(path, MAX_ROSTER_BYTES).map_err(|e| {
            if iw_file::is_refusal(&e) {
                ContainerError::Roster {
                    file: source.clone(),
                    line: None,
                    reason: e.to_string(),
                }
            } else {
                ContainerError::RosterRead {
                    file: source.clone(),
                    source: e,
                }
            }
        })?;
        Roster::parse(&text, &source)
    }

    /// Where the roster was read.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The pin of container `id`.
    pub fn get(&self, id: ContainerId) -> Option<&Pin> {
        self.pins.get(&id)
    }

    /// The pins, by id.
    pub fn pins(&self) -> impl Iterator<Item = (ContainerId, &Pin)> {
        self.pins.iter().map(|(id, p)| (*id, p))
    }

    /// Checks that this roster lists container `id` under `key` (and, when given, as `name`): a
    /// container whose own identity is not the pinned one must not run (every other container
    /// would refuse it).
    pub fn check_own(
        &self,
        id: ContainerId,
        name: Option<&str>,
        key: &PublicKey,
    ) -> Result<(), ContainerError> {
        let this = name.map_or_else(|| "this container".to_string(), |n| format!("`{n}`"));
        let reason = match self.pins.get(&id) {
            None => format!("lists no container id {} ({this})", id.0),
            Some(pin) if name.is_some_and(|n| n != pin.name) => format!(
                "names container id {} `{}`, but this container is {this}",
                id.0, pin.name
            ),
            Some(pin) if pin.key != *key => format!(
                "pins container id {} ({this}) to key {}, but this container's identity key is {} \
                 (give the identity key file the roster was made from, or make the roster again)",
                id.0,
                hex::encode(pin.key),
                hex::encode(key)
            ),
            Some(_) => return Ok(()),
        };
        Err(self.error(None, reason))
    }

    fn add(&mut self, id: ContainerId, pin: Pin) -> Result<(), String> {
        if pin.name.is_empty()
            || pin.name.contains('@')
            || pin.name.chars().any(char::is_whitespace)
        {
            return Err(format!(
                "`{}` is not a container name (not empty, no `@`, no spaces)",
                pin.name
            ));
        }
        if self.pins.contains_key(&id) {
            return Err(format!("container id {} is listed twice", id.0));
        }
        if let Some((other, _)) = self.pins.iter().find(|(_, p)| p.name == pin.name) {
            return Err(format!(
                "name `{}` is already container id {}'s",
                pin.name, other.0
            ));
        }
        if let Some((other, _)) = self.pins.iter().find(|(_, p)| p.key == pin.key) {
            return Err(format!(
                "the key of `{}` is already container id {}'s (one key speaks for one container)",
                pin.name, other.0
            ));
        }
        self.pins.insert(id, pin);
        Ok(())
    }

    fn error(&self, line: Option<usize>, reason: String) -> ContainerError {
        ContainerError::Roster {
            file: self.source.clone(),
            line,
            reason,
        }
    }
}

/// The roster as its file holds it (what [`Roster::parse`] reads back).
impl std::fmt::Display for Roster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "# Container roster: ID NAME PUBLIC_KEY (Ed25519, hex), one container per line."
        )?;
        for (id, pin) in &self.pins {
            writeln!(f, "{} {} {}", id.0, pin.name, hex::encode(pin.key))?;
        }
        Ok(())
    }
}

/// What is wrong with one roster line: its shape, or a value whose parser said why.
enum BadLine {
    Shape(String),
    Value {
        what: String,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

fn parse_line(line: &str) -> Result<(ContainerId, Pin), BadLine> {
    let fields: Vec<&str> = line.split_whitespace().collect();
    let [id, name, key] = fields[..] else {
        return Err(BadLine::Shape(format!(
            "expected `ID NAME PUBLIC_KEY`, found {} fields",
            fields.len()
        )));
    };
    let id = id.parse::<u64>().map_err(|e| BadLine::Value {
        what: format!("container id `{id}`"),
        source: e.into(),
    })?;
    if key.len() != 64 {
        return Err(BadLine::Shape(format!(
            "the key of `{name}` is not 64 hex digits ({} characters)",
            key.chars().count()
        )));
    }
    let bytes = PublicKey::from_hex(key).map_err(|e| BadLine::Value {
        what: format!("the key of `{name}` is not 64 hex digits"),
        source: e.into(),
    })?;
    Ok((
        ContainerId(id),
        Pin {
            name: name.into(),
            key: bytes,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Any text (a damaged or hostile file) parses or is refused naming the file, never a
        /// panic.
        #[test]
        fn any_text_parses_or_is_refused_naming_the_file(text in "(?s).{0,400}") {
            if let Err(e) = Roster::parse(&text, "deploy.roster") {
                prop_assert!(e.to_string().starts_with("roster deploy.roster"), "{}", e);
            }
        }

        /// Whatever a roster writes it reads back the same.
        #[test]
        fn a_written_roster_parses_back(
            pins in proptest::collection::btree_map(
                any::<u64>(),
                ("[a-z][a-z0-9-]{0,12}", any::<[u8; 32]>()),
                1..8,
            )
        ) {
            let pins = pins
                .into_iter()
                .map(|(id, (name, key))| (ContainerId(id), Pin { name, key }));
            // a drawn repeat of a name or key is refused by `new`, and is not this property's
            let Ok(roster) = Roster::new("r", pins) else {
                return Ok(());
            };
            prop_assert_eq!(Roster::parse(&roster.to_string(), "r").unwrap(), roster);
        }
    }

    fn key(b: u8) -> String {
        hex::encode([b; 32])
    }

    #[test]
    fn a_roster_reads_back_what_it_writes() {
        let text = format!(
            "# a deployment\n\n1 services {}\n  1042 chair-0 {}  \n",
            key(1),
            key(2)
        );
        let roster = Roster::parse(&text, "r").unwrap();
        assert_eq!(roster.get(ContainerId(1)).unwrap().name, "services");
        assert_eq!(roster.get(ContainerId(1042)).unwrap().key, [2; 32]);
        assert!(roster.get(ContainerId(2)).is_none());
        assert_eq!(Roster::parse(&roster.to_string(), "r").unwrap(), roster);
    }

    /// A value that does not parse keeps its parser's error as the source.
    #[test]
    fn a_bad_value_keeps_the_parsers_error() {
        use std::error::Error as _;
        let err = Roster::parse(&format!("# ids\nx services {}", key(1)), "r").unwrap_err();
        assert!(
            matches!(err, ContainerError::RosterValue { line: 2, .. }),
            "{err}"
        );
        assert!(
            err.source()
                .is_some_and(|s| s.is::<std::num::ParseIntError>()),
            "{err}"
        );
        let err = Roster::parse(&format!("1 services {}", "g".repeat(64)), "r").unwrap_err();
        assert!(
            err.source().is_some_and(|s| s.is::<hex::FromHexError>()),
            "{err}"
        );
    }

    #[test]
    fn a_bad_roster_is_refused_naming_the_file_and_line() {
        for (text, want) in [
            (format!("1 services {}\n2 world", key(1)), "line 2"),
            (format!("x services {}", key(1)), "container id `x`"),
            ("1 services abc".to_string(), "not 64 hex digits"),
            (
                format!("1 services {}", "g".repeat(64)),
                "Invalid character 'g' at position 0",
            ),
            (
                format!("1 services {}\n1 world {}", key(1), key(2)),
                "listed twice",
            ),
            (
                format!("1 services {}\n2 services {}", key(1), key(2)),
                "already container id 1",
            ),
            (
                format!("1 services {}\n2 world {}", key(1), key(1)),
                "one key speaks for one container",
            ),
            (format!("1 a@b {}", key(1)), "not a container name"),
            ("# nothing\n".to_string(), "lists no container"),
        ] {
            let err = Roster::parse(&text, "deploy/roster")
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("deploy/roster") && err.contains(want),
                "{text}: {err}"
            );
        }
        let err = Roster::parse(&format!("1 s {}\n\n3 w", key(1)), "f")
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 3"), "{err}");
    }

    #[test]
    fn a_missing_or_huge_file_is_a_clear_error() {
        let dir = std::env::temp_dir().join(format!("iw-roster-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("missing");
        let err = Roster::load(&missing).unwrap_err();
        assert!(err.to_string().contains("missing"), "{err}");
        let cause = std::error::Error::source(&err)
            .and_then(|s| s.downcast_ref::<std::io::Error>())
            .unwrap_or_else(|| panic!("no io::Error under `{err}`"));
        assert_eq!(cause.kind(), std::io::ErrorKind::NotFound);
        let huge = dir.join("huge");
        std::fs::write(&huge, vec![b'#'; MAX_ROSTER_BYTES as usize + 2]).unwrap();
        let err = Roster::load(&huge).unwrap_err().to_string();
        assert!(err.contains("larger than"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_fifo_or_a_folder_is_refused_not_waited_on() {
        let dir = std::env::temp_dir().join(format!("iw-roster-fifo-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("roster.fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        let mut paths = vec![dir.clone()];
        if made.is_ok_and(|s| s.success()) {
            paths.push(fifo);
        } else {
            println!("SKIP: mkfifo is not available; only the folder was tried");
        }
        for path in paths {
            // On a thread: before the check, opening the FIFO blocked for good.
            let (tx, rx) = std::sync::mpsc::channel();
            let p = path.clone();
            std::thread::spawn(move || {
                tx.send(Roster::load(&p).map(|_| ()).map_err(|e| e.to_string()))
            });
            let got = rx.recv_timeout(std::time::Duration::from_secs(20));
            let err = got
                .unwrap_or_else(|_| panic!("{}: still waiting", path.display()))
                .unwrap_err();
            assert!(err.contains("not a regular file"), "{err}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn own_identity_must_be_the_pinned_one() {
        let roster = Roster::parse(&format!("7 chair-0 {}", key(7)), "r.txt").unwrap();
        roster
            .check_own(ContainerId(7), Some("chair-0"), &[7; 32])
            .unwrap();
        roster.check_own(ContainerId(7), None, &[7; 32]).unwrap();
        for (id, name, k, want) in [
            (8, "chair-0", [7; 32], "lists no container id 8"),
            (7, "chair-1", [7; 32], "this container is `chair-1`"),
            (7, "chair-0", [9; 32], "identity key"),
        ] {
            let err = roster
                .check_own(ContainerId(id), Some(name), &k)
                .unwrap_err()
                .to_string();
            assert!(err.contains("r.txt") && err.contains(want), "{err}");
        }
    }

    #[test]
    fn a_pin_hosts_only_its_own_agents() {
        let pin = Pin {
            name: "chair-0".into(),
            key: [0; 32],
        };
        assert!(pin.hosts("control@chair-0"));
        for other in [
            "control@chair-01",
            "assistant@services",
            "@chair-0",
            "chair-0",
        ] {
            assert!(!pin.hosts(other), "{other}");
        }
    }
}
