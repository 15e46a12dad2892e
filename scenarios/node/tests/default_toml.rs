//! `deploy/default.toml` documents every configuration key with its default: it must parse into
//! the configuration and equal `SpawnConfig::default()`, and name every key the code has.

use iw_node::SpawnConfig;

const DEFAULT_TOML: &str = include_str!("../../../deploy/default.toml");

/// Dotted paths of every key in a TOML table.
fn keys(value: &toml::Value, prefix: &str, out: &mut Vec<String>) {
    if let toml::Value::Table(table) = value {
        for (k, v) in table {
            let path = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            if v.is_table() {
                keys(v, &path, out);
            } else {
                out.push(path);
            }
        }
    }
    out.sort();
}

#[test]
fn default_toml_is_the_code_default_and_documents_every_key() {
    let parsed = SpawnConfig::parse(DEFAULT_TOML, "deploy/default.toml")
        .expect("deploy/default.toml parses");
    assert_eq!(
        parsed,
        SpawnConfig::default(),
        "deploy/default.toml differs from SpawnConfig::default()"
    );
    let (mut documented, mut in_code) = (Vec::new(), Vec::new());
    keys(
        &toml::from_str::<toml::Value>(DEFAULT_TOML).unwrap(),
        "",
        &mut documented,
    );
    keys(
        &toml::Value::try_from(SpawnConfig::default()).unwrap(),
        "",
        &mut in_code,
    );
    assert_eq!(
        documented, in_code,
        "deploy/default.toml must list every key of SpawnConfig, and only those"
    );
}
