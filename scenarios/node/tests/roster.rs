//! `security.roster`: writing a deployment's keys and roster, and the errors a container gives
//! at start for a bad roster or an identity the roster does not pin. All refusals come before
//! anything is bound.

use std::path::Path;
use std::sync::mpsc::channel;

use iw_node::{Role, Runtime, SpawnConfig, write_roster};

fn config(key: &Path, roster: &Path) -> SpawnConfig {
    let mut c = SpawnConfig::default();
    c.security.insecure_dev = true;
    c.security.identity_key = key.display().to_string();
    c.security.roster = roster.display().to_string();
    c
}

fn start_error(role: Role, config: SpawnConfig) -> String {
    let (tx, _rx) = channel();
    Runtime::start(&role, config, tx)
        .err()
        .expect("refused")
        .to_string()
}

fn members(names: &[&str]) -> Vec<(String, u64)> {
    names.iter().map(|n| (n.to_string(), 0)).collect()
}

#[test]
fn a_written_roster_keeps_existing_keys_and_pins_derived_ids() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("roster");
    let first = write_roster(&path, dir.path(), &members(&["services", "chair-0"])).unwrap();
    let key = std::fs::read(dir.path().join("chair-0.pk8")).unwrap();
    let second = write_roster(
        &path,
        dir.path(),
        &[
            ("services".into(), 0),
            ("chair-0".into(), 0),
            ("world".into(), 0),
        ],
    )
    .unwrap();
    assert_eq!(std::fs::read(dir.path().join("chair-0.pk8")).unwrap(), key);
    let ids: Vec<u64> = second.pins().map(|(id, _)| id.0).collect();
    assert_eq!(&ids[..2], &[1, 2], "services 1, world 2, then the chair");
    for (id, pin) in first.pins() {
        assert_eq!(second.get(id), Some(pin), "kept: {}", pin.name);
    }
    let read = iw_container::Roster::load(&path).unwrap();
    assert_eq!(read.pins().count(), 3);
    let err = write_roster(&path, dir.path(), &members(&["../escape"]))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("--member") && err.contains("../escape"),
        "{err}"
    );
}

#[test]
fn a_bad_roster_file_is_refused_naming_the_key_the_file_and_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let roster = dir.path().join("roster");
    write_roster(&roster, dir.path(), &members(&["services"])).unwrap();
    let key = dir.path().join("services.pk8");
    let text = std::fs::read_to_string(&roster).unwrap();
    std::fs::write(&roster, format!("{text}7 chair-7 not-a-key\n")).unwrap();
    let err = start_error(Role::Services, config(&key, &roster));
    let line = text.lines().count() + 1;
    assert!(
        err.contains("security.roster")
            && err.contains(&roster.display().to_string())
            && err.contains(&format!("line {line}"))
            && err.contains("64 hex digits"),
        "{err}"
    );
    let missing = dir.path().join("absent");
    let err = start_error(Role::Services, config(&key, &missing));
    assert!(
        err.contains("security.roster") && err.contains("absent"),
        "{err}"
    );
}

#[test]
fn a_container_whose_identity_is_not_pinned_refuses_to_start() {
    let dir = tempfile::tempdir().unwrap();
    let roster = dir.path().join("roster");
    write_roster(&roster, dir.path(), &members(&["services", "chair-0"])).unwrap();
    let shown = roster.display().to_string();
    // chair-0 started with the services' key
    let err = start_error(
        Role::Chair {
            name: "chair-0".into(),
        },
        config(&dir.path().join("services.pk8"), &roster),
    );
    assert!(
        err.contains(&shown) && err.contains("container id") && err.contains("identity key"),
        "{err}"
    );
    // the world, which the roster does not list
    let err = start_error(
        Role::World,
        config(&dir.path().join("services.pk8"), &roster),
    );
    assert!(
        err.contains(&shown) && err.contains("lists no container id 2"),
        "{err}"
    );
    // an id configured by hand that the roster gives another container
    let mut c = config(&dir.path().join("services.pk8"), &roster);
    c.container.id = 1;
    let err = start_error(
        Role::Chair {
            name: "chair-0".into(),
        },
        c,
    );
    assert!(
        err.contains(&shown) && err.contains("names container id 1 `services`"),
        "{err}"
    );
}
