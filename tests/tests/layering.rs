//! The workspace's layering, read from `cargo metadata` (not from grepping manifests):
//!
//! | a crate under | may not depend on a crate under |
//! | --- | --- |
//! | `protocols/` | anything of ours outside `protocols/` |
//! | `platform/` | `agents/`, `scenarios/`, `cli/` |
//! | `agents/` | `scenarios/`, `cli/` |
//! | `scenarios/` | `cli/` |
//!
//! Inside `platform/`, the message transports (the bus, its layers, the transports and the
//! FIPA HTTP MTP) carry messages and host no agents: they may not depend on the agent runtime
//! ([`AGENT_RUNTIME`]: agents and their host, the AMS and DF, containers). A platform that hosts
//! agents behind a transport is assembled above both (e.g. `iw-node`'s `HttpPlatform`).
//!
//! Every kind of dependency counts (normal, build and dev), except a dev-dependency on an
//! internal test helper under `tests/` that itself depends on nothing of ours (the test-data
//! locator `tests/testdata`, the benches' clock `tests/bench-clock`, the raw connections of
//! `tests/net-probe`): it cannot carry a layer upwards.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The layers, lowest first; a crate belongs to the first whose folder holds its manifest.
const LAYERS: [&str; 5] = ["protocols", "platform", "agents", "scenarios", "cli"];

/// What each layer may not depend on.
fn forbidden(layer: &str) -> &'static [&'static str] {
    match layer {
        "protocols" => &["platform", "agents", "scenarios", "cli", "stats", "tests"],
        "platform" => &["agents", "scenarios", "cli"],
        "agents" => &["scenarios", "cli"],
        "scenarios" => &["cli"],
        _ => &[],
    }
}

/// The crates under `platform/` that host agents; the rest of `platform/` may not depend on them.
const AGENT_RUNTIME: [&str; 3] = ["iw-agent", "iw-ams-df", "iw-container"];

struct Member {
    name: String,
    /// The top-level folder of the workspace that holds the crate (`platform`, `agents`, ...).
    folder: String,
    deps: Vec<(String, Option<String>)>,
}

fn workspace_members() -> Vec<Member> {
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata is JSON");
    let root = PathBuf::from(meta["workspace_root"].as_str().expect("workspace_root"));
    meta["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .map(|p| {
            let manifest = Path::new(p["manifest_path"].as_str().expect("manifest_path"));
            let folder = manifest
                .strip_prefix(&root)
                .ok()
                .and_then(|rel| rel.components().next())
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .unwrap_or_default();
            let deps = p["dependencies"]
                .as_array()
                .expect("dependencies")
                .iter()
                .map(|d| {
                    (
                        d["name"].as_str().expect("dependency name").to_owned(),
                        d["kind"].as_str().map(str::to_owned),
                    )
                })
                .collect();
            Member {
                name: p["name"].as_str().expect("name").to_owned(),
                folder,
                deps,
            }
        })
        .collect()
}

#[test]
fn no_crate_depends_on_a_layer_above_its_own() {
    let members = workspace_members();
    let folder_of = |name: &str| {
        members
            .iter()
            .find(|m| m.name == name)
            .map(|m| m.folder.as_str())
    };
    // Test helpers: crates under tests/ with no dependency of ours.
    let helpers: Vec<&str> = members
        .iter()
        .filter(|m| m.folder == "tests")
        .filter(|m| m.deps.iter().all(|(dep, _)| folder_of(dep).is_none()))
        .map(|m| m.name.as_str())
        .collect();
    let mut violations = Vec::new();
    for member in &members {
        if !LAYERS.contains(&member.folder.as_str()) {
            continue;
        }
        for (dep, kind) in &member.deps {
            let Some(dep_folder) = folder_of(dep) else {
                continue; // third party
            };
            let helper_for_tests =
                kind.as_deref() == Some("dev") && helpers.contains(&dep.as_str());
            if forbidden(&member.folder).contains(&dep_folder) && !helper_for_tests {
                violations.push(format!(
                    "{} (under {}/) depends on {} (under {}/){}",
                    member.name,
                    member.folder,
                    dep,
                    dep_folder,
                    kind.as_deref()
                        .map(|k| format!(" as a {k}-dependency"))
                        .unwrap_or_default()
                ));
            }
        }
    }
    assert!(
        violations.is_empty(),
        "layering violations:\n  {}",
        violations.join("\n  ")
    );
}

#[test]
fn message_transports_host_no_agents() {
    let members = workspace_members();
    let runtime: Vec<_> = members
        .iter()
        .filter(|m| AGENT_RUNTIME.contains(&m.name.as_str()))
        .collect();
    assert_eq!(
        runtime.len(),
        AGENT_RUNTIME.len(),
        "every crate of the agent runtime is a workspace member"
    );
    assert!(
        runtime.iter().all(|m| m.folder == "platform"),
        "the agent runtime lives under platform/"
    );
    let violations: Vec<_> = members
        .iter()
        .filter(|m| m.folder == "platform" && !AGENT_RUNTIME.contains(&m.name.as_str()))
        .flat_map(|m| {
            m.deps
                .iter()
                .filter(|(dep, _)| AGENT_RUNTIME.contains(&dep.as_str()))
                .map(move |(dep, kind)| {
                    format!(
                        "{} (a message transport) depends on {} (the agent runtime){}",
                        m.name,
                        dep,
                        kind.as_deref()
                            .map(|k| format!(" as a {k}-dependency"))
                            .unwrap_or_default()
                    )
                })
        })
        .collect();
    assert!(
        violations.is_empty(),
        "layering violations:\n  {}",
        violations.join("\n  ")
    );
}

#[test]
fn every_workspace_crate_sits_in_a_known_folder() {
    let members = workspace_members();
    let known = [
        "protocols",
        "platform",
        "agents",
        "scenarios",
        "cli",
        "stats",
        "tests",
    ];
    let strays: Vec<_> = members
        .iter()
        .filter(|m| !known.contains(&m.folder.as_str()))
        .map(|m| format!("{} in {}/", m.name, m.folder))
        .collect();
    assert!(strays.is_empty(), "crates outside the layout: {strays:?}");
}
