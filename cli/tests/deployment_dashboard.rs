//! The dashboard on a live deployment: the world, the services (serving the dashboard, with a
//! token) and three virtual chairs as `intellwheels spawn` processes on loopback UDP, and Debian's
//! headless chromium on the services' dashboard (cli/tests/browser/deployment.mjs):
//! - the staff view, fed from the platform's traffic, shows all three chairs move: chair-a and
//!   chair-b under goals the services give, chair-c driven from its own view with the on-screen
//!   joystick, then released, after which it stands still;
//! - while driven, chair-c's view shows the command sent, what shared control applied (its
//!   control agent's `drive-applied` informs) and its sonar picture (its perception agent's
//!   readings), all from the bus;
//! - the drive went over the bus: the logger's log holds the staff console's `drive` requests
//!   to `interface@chair-c` and the interface agent's stream to `control@chair-c`;
//! - a request without the token gets 401.
//!
//! Chromium, node and playwright-core are required: the test fails without them (CI installs
//! them) unless `INTELLWHEELS_NO_BROWSER=1` says to skip it, which it then prints.

mod common;

use std::io::{Read, Write};
use std::net::TcpStream;

use common::{Deployment, Proc, is};

/// Name, start (x, y, heading in degrees), goal place.
const CHAIRS: [(&str, [f64; 3], Option<&str>); 3] = [
    ("chair-a", [1.0, 6.0, 0.0], Some("dining-hall")),
    ("chair-b", [17.5, 6.0, 180.0], Some("therapy")),
    // in bedroom 2, facing its doorway: driven by hand
    ("chair-c", [7.5, 8.5, -90.0], None),
];

const TOKEN: &str = "deployment-test-token";

/// The status line of a GET of `path` on `addr`.
fn status_of(addr: &str, path: &str) -> String {
    let mut stream = TcpStream::connect(addr).expect("connect to the dashboard");
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut answer = String::new();
    let _ = stream.read_to_string(&mut answer);
    answer.lines().next().unwrap_or_default().to_string()
}

#[test]
fn a_browser_on_the_services_dashboard_sees_three_chair_processes_move_and_drives_one() {
    let test = "a_browser_on_the_services_dashboard_sees_three_chair_processes_move_and_drives_one";
    let (chromium, browser_dir) = match common::browser_tools() {
        Ok(tools) => tools,
        Err(why) if std::env::var_os("INTELLWHEELS_NO_BROWSER").is_some() => {
            iw_testdata::skip(test, why);
            return;
        }
        Err(why) => panic!("{why} (set INTELLWHEELS_NO_BROWSER=1 to skip this test)"),
    };

    let net = Deployment::new();
    let log = net.dir.path().join("agents.log");
    let goals: String = CHAIRS
        .iter()
        .filter_map(|(name, _, goal)| {
            goal.map(|g| format!("{{ chair = \"{name}\", place = \"{g}\" }},"))
        })
        .collect();
    let dashboard = format!(
        "127.0.0.1:{}",
        std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port()
    );
    let config = net.file(
        "services.toml",
        &format!(
            "[services]\nchairs = [\"chair-c\"]\ngoals = [{goals}]\nlog = \"{}\"\n\n[dashboard]\nlisten = \"{dashboard}\"\ntoken = \"{TOKEN}\"\n",
            log.display()
        ),
    );
    let mut services = net.services().config(&config).spawn();
    let serving = services.wait_for("the dashboard served", |e| {
        is(e, "serving", "service", "dashboard")
    });
    let url = serving["url"].as_str().unwrap().to_string();
    assert_eq!(url, format!("http://{dashboard}/?token={TOKEN}"));
    assert!(
        status_of(&dashboard, "/map.json").contains(" 401 "),
        "without the token"
    );
    assert!(
        status_of(&dashboard, &format!("/map.json?token={TOKEN}")).contains(" 200 "),
        "with the token"
    );
    let mut world = net.world().ready();
    let mut chairs: Vec<Proc> = CHAIRS
        .iter()
        .map(|(name, [x, y, deg], _)| net.chair(name).start(&format!("{x},{y},{deg}")).ready())
        .collect();
    println!("dashboard at {url}");

    common::run_browser_script(&browser_dir, &chromium, "deployment.mjs", &url);

    for chair in &mut chairs {
        chair.stop();
    }
    services.stop();
    world.stop();
    // The drive crossed the bus: console to interface, interface to control.
    let records = iw_logger::read_records(&log, iw_logger::DEFAULT_MAX_RECORD_LEN).unwrap();
    let drives = |from: &str, to: &str| {
        records
            .iter()
            .map(|r| String::from_utf8_lossy(&r.payload).into_owned())
            .filter(|p| p.contains(from) && p.contains(to) && p.contains("drive"))
            .count()
    };
    let relayed = drives("staff@services", "interface@chair-c");
    let streamed = drives("interface@chair-c", "control@chair-c");
    println!(
        "log: {} records; {relayed} drive requests relayed to interface@chair-c, {streamed} streamed to control@chair-c",
        records.len()
    );
    assert!(
        relayed >= 3 && streamed >= 3,
        "{relayed} relayed, {streamed} streamed"
    );
}
