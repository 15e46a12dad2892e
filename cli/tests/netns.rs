//! Off loopback: the world, the services and two chairs each in their own network namespace with
//! their own address, joined by veth pairs to a bridge that lives in a fifth namespace (a small
//! LAN). Every container runs through `ip netns exec`.
//!
//! - chair-a is sent to the therapy room and reaches it (INFORM), its body driven in the world
//!   container across the bridge;
//! - chair-b is cut off (its link on the bridge set down): the services see its agents leave;
//!   healed (link up), they see them join again, and chair-b lists the services' agents again.
//!
//! Needs root and `ip` (iproute2): where namespaces cannot be made, the test prints a loud SKIP
//! with the reason. Namespaces are deleted on every exit path (a guard's drop, and stale ones of
//! dead test runs at the start).

mod common;

use std::process::Command;

use common::{Deployment, is};

/// Namespace names start with this and the test process id.
const PREFIX: &str = "iwnt-";

/// Runs `ip ARGS`; the error names the command and its stderr.
fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("`ip {}`: {e}", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "`ip {}`: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// The namespaces of this run; deleted (with everything in them) when dropped.
struct Lan {
    bridge: String,
    nodes: Vec<String>,
}

impl Lan {
    /// The bridge namespace and one namespace per node at 10.77.0.(2+i)/24.
    fn make(nodes: &[&str]) -> Result<Lan, String> {
        let pid = std::process::id();
        let mut lan = Lan {
            bridge: format!("{PREFIX}{pid}-br"),
            nodes: Vec::new(),
        };
        ip(&["netns", "add", &lan.bridge])?;
        let br = lan.bridge.clone();
        ip(&["-n", &br, "link", "add", "br0", "type", "bridge"])?;
        ip(&["-n", &br, "link", "set", "br0", "up"])?;
        ip(&["-n", &br, "link", "set", "lo", "up"])?;
        for (i, node) in nodes.iter().enumerate() {
            let ns = format!("{PREFIX}{pid}-{node}");
            ip(&["netns", "add", &ns])?;
            lan.nodes.push(ns.clone());
            let port = format!("v-{node}");
            ip(&[
                "-n", &br, "link", "add", &port, "type", "veth", "peer", "name", "eth0", "netns",
                &ns,
            ])?;
            ip(&["-n", &br, "link", "set", &port, "master", "br0", "up"])?;
            ip(&["-n", &ns, "link", "set", "lo", "up"])?;
            ip(&[
                "-n",
                &ns,
                "addr",
                "add",
                &format!("10.77.0.{}/24", i + 2),
                "dev",
                "eth0",
            ])?;
            ip(&["-n", &ns, "link", "set", "eth0", "up"])?;
        }
        Ok(lan)
    }

    fn ns(&self, node: &str) -> String {
        format!("{PREFIX}{}-{node}", std::process::id())
    }

    /// Sets `node`'s link on the bridge `up` or `down`.
    fn link(&self, node: &str, state: &str) {
        ip(&[
            "-n",
            &self.bridge,
            "link",
            "set",
            &format!("v-{node}"),
            state,
        ])
        .unwrap();
    }
}

impl Drop for Lan {
    fn drop(&mut self) {
        for ns in self.nodes.iter().chain([&self.bridge]) {
            if let Err(e) = ip(&["netns", "del", ns]) {
                eprintln!("netns test: could not delete namespace {ns}: {e}");
            }
        }
    }
}

/// Deletes namespaces a killed earlier run left behind (their process is gone).
fn delete_stale() {
    let Ok(out) = Command::new("ip").args(["netns", "list"]).output() else {
        return;
    };
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let name = line.split_whitespace().next().unwrap_or_default();
        let Some(pid) = name
            .strip_prefix(PREFIX)
            .and_then(|rest| rest.split('-').next())
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if !std::path::Path::new(&format!("/proc/{pid}")).exists() {
            let _ = ip(&["netns", "del", name]);
        }
    }
}

fn skip(reason: &str) {
    eprintln!("\n***** SKIP netns test: {reason} *****\n");
}

#[test]
fn world_services_and_chairs_in_their_own_namespaces_run_a_goal_and_rejoin_after_a_partition() {
    // SAFETY: geteuid has no preconditions
    if unsafe { libc::geteuid() } != 0 {
        return skip("not root: network namespaces need CAP_SYS_ADMIN (CI runs as root)");
    }
    if Command::new("ip").arg("-V").output().is_err() {
        return skip("no `ip` command (install iproute2)");
    }
    delete_stale();
    let lan = match Lan::make(&["services", "world", "chair-a", "chair-b"]) {
        Ok(lan) => lan,
        Err(e) => return skip(&format!("cannot make the namespaces: {e}")),
    };
    let net = Deployment::new().services_at("10.77.0.2:7700");
    let via = |node: &str| {
        [
            "ip".to_string(),
            "netns".into(),
            "exec".into(),
            lan.ns(node),
        ]
    };
    let mut services = net
        .services()
        .goal("chair-a:therapy")
        .via(&via("services"))
        .ready();
    let mut world = net
        .world()
        .listen("10.77.0.3:7700")
        .via(&via("world"))
        .ready();
    let chair = |node: &str, addr: &str, start: &str| {
        net.chair(node)
            .start(start)
            .listen(addr)
            .via(&via(node))
            .ready()
    };
    let _a = chair("chair-a", "10.77.0.4:7700", "15.75,6.0,-90");
    let mut b = chair("chair-b", "10.77.0.5:7700", "7.0,6.0,0");

    // The goal crosses three namespaces: services to chair-a, chair-a's body in the world.
    let answer = services.wait_for("chair-a's goal answered", |e| {
        is(e, "goal", "chair", "chair-a") && e["performative"] != "AGREE"
    });
    assert_eq!(answer["performative"], "INFORM", "{answer}");
    // (reports are taken in order: the one showing the drive may still be queued)
    world.wait_for("chair-a's body driven into the therapy room", |e| {
        is(e, "body", "chair", "chair-a") && e["y_m"].as_f64().unwrap() < 4.5
    });
    services.wait_for("chair-b joined", |e| {
        is(e, "joined", "agent", "cognitive@chair-b")
    });

    // Partition chair-b: the services drop its agents; heal: they take them back, and chair-b
    // lists the services' agents again.
    lan.link("chair-b", "down");
    services.wait_new("chair-b's agents left", |e| {
        is(e, "left", "agent", "cognitive@chair-b")
    });
    b.wait_new("chair-b lost the services", |e| {
        is(e, "left", "agent", "assistant@services")
    });
    lan.link("chair-b", "up");
    services.wait_new("chair-b rejoined", |e| {
        is(e, "joined", "agent", "cognitive@chair-b")
    });
    b.wait_new("chair-b sees the services again", |e| {
        is(e, "joined", "agent", "assistant@services")
    });
}
