//! A container's errors keep their cause: the message names what failed and where, ends with
//! what the cause said, and `source()` hands the cause itself over (a caller can downcast it).

use std::error::Error;
use std::sync::mpsc::channel;

use iw_node::{NodeError, Role, Runtime, SpawnConfig, write_identity};

/// The cause of `err`, as a `T`.
fn cause<T: Error + 'static>(err: &NodeError) -> &T {
    err.source()
        .and_then(|s| s.downcast_ref::<T>())
        .unwrap_or_else(|| panic!("no {} under `{err}`", std::any::type_name::<T>()))
}

#[test]
fn an_identity_key_that_cannot_be_written_keeps_the_os_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no-such-dir").join("key.pk8");
    let err = write_identity(&path).unwrap_err();
    let io = cause::<std::io::Error>(&err);
    assert_eq!(io.kind(), std::io::ErrorKind::NotFound);
    let text = err.to_string();
    assert!(
        text.starts_with(&format!("identity key {}: ", path.display()))
            && text.ends_with(&io.to_string()),
        "{text}"
    );
}

#[test]
fn a_configuration_that_does_not_parse_keeps_the_toml_error() {
    let err = SpawnConfig::parse("[transport]\nkind = 3\n", "spawn.toml").unwrap_err();
    let toml = cause::<toml::de::Error>(&err);
    assert!(toml.span().is_some(), "the cause still knows where: {toml}");
    assert!(
        err.to_string().starts_with("configuration spawn.toml: "),
        "{err}"
    );
}

#[test]
fn an_unknown_layer_keeps_the_bus_error() {
    let mut config = SpawnConfig::default();
    config.security.insecure_dev = true;
    config.security.layers = "comm,telepathy".into();
    let err = Runtime::start(&Role::World, config, channel().0)
        .err()
        .expect("refused before anything is bound");
    cause::<iw_bus::BusError>(&err);
    assert!(
        err.to_string()
            .starts_with("configuration security.layers: "),
        "{err}"
    );
}
