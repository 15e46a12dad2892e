//! `intellwheels bench drive`: the time from a drive panel input to the wheel command, in one
//! process, as the demo runs it.
//!
//! The demo's pieces in real time: the sample building with one chair (fleet stepped every 50 ms
//! of wall time, as `--serve` does) and the dashboard's websocket server. A websocket client
//! sends the frame the page sends on a pointer event (`{"do":"drive","dev":"stick",...}`) and
//! notes the instant; the time is read again when the control agent's tick hands a non-zero
//! command to the wheels (the control agent's `DriveStatus` is set right before the body is
//! commanded). In between: the websocket, the demo loop's action queue, the interface agent's
//! tick, the bus, the control agent's tick with shared control. Trials alternate forward and back
//! (the chair stays in the corridor), each sent at a different phase of the 50 ms step, then
//! released and let stop.
//!
//! The peer, measured in the same run: the same input pushed straight into the interface agent's
//! queue (no websocket, no action queue), as a device driver on the chair would.

use std::time::{Duration, Instant};

use anyhow::Context as _;
use iw_dashboard::{Dashboard, DashboardConfig, DriveInput, PageAction};
use iw_fleet::{ChairConfig, Fleet};
use iw_sim::Map;
use nalgebra::{Isometry2, Vector2};

use super::demo;

const CHAIR: &str = "chair-0";
const STEP: Duration = Duration::from_millis(50);

/// One measured path.
#[derive(Debug, serde::Serialize)]
struct Row {
    path: &'static str,
    trials: usize,
    p50_ms: f64,
    p99_ms: f64,
    max_ms: f64,
}

pub fn run(trials: usize, json: bool) -> anyhow::Result<()> {
    anyhow::ensure!(trials >= 2, "--trials must be at least 2, got {trials}");
    let map = Map::parse(demo::SAMPLE_BUILDING, "sample-building.map")
        .context("embedded sample building")?;
    let view = iw_wiring::view::map_view(&map);
    let chair = ChairConfig {
        name: CHAIR.into(),
        // in the corridor, facing along it: room ahead and behind
        t_world_body: Isometry2::new(Vector2::new(7.0, 6.0), 0.0),
    };
    let mut fleet = Fleet::new(map, 7, &[chair]).context("composing the fleet")?;
    let dashboard =
        Dashboard::start(DashboardConfig::default(), &view).context("starting the dashboard")?;
    let ws_url = format!("ws://{}/ws", dashboard.addr());
    let (mut socket, _) = tungstenite::connect(ws_url.as_str()).context("connecting")?;
    let mut loop_ = Loop {
        fleet: &mut fleet,
        dashboard: &dashboard,
        next: Instant::now(),
    };
    let bar = indicatif::ProgressBar::new(2 * trials as u64);
    let mut rows = Vec::new();
    for path in ["websocket", "device queue"] {
        let mut latencies_ms = Vec::with_capacity(trials);
        for k in 0..trials {
            let y = if k % 2 == 0 { 1.0 } else { -1.0 };
            // spread the send over the step: k * 7 ms into it, modulo 50
            loop_.step()?;
            std::thread::sleep(Duration::from_millis((k as u64 * 7) % 50));
            let input = DriveInput::Stick { x: 0.0, y };
            let sent = Instant::now();
            if path == "websocket" {
                let frame = serde_json::to_string(&PageAction::Drive {
                    chair: CHAIR.into(),
                    input,
                })?;
                socket.send(tungstenite::Message::text(frame))?;
            } else {
                demo::push_drive(loop_.fleet, CHAIR, input)?;
            }
            let commanded = loop {
                loop_.step()?;
                let applied = loop_.fleet.drive_status(CHAIR)?.applied;
                if applied.is_some_and(|a| a.linear_mps * y > 0.0) {
                    break Instant::now();
                }
                anyhow::ensure!(
                    sent.elapsed() < Duration::from_secs(5),
                    "no wheel command 5 s after the input"
                );
            };
            latencies_ms.push(commanded.duration_since(sent).as_secs_f64() * 1e3);
            demo::push_drive(loop_.fleet, CHAIR, DriveInput::Stick { x: 0.0, y: 0.0 })?;
            // let it stop (watchdog 0.5 s, ramp): 1 s
            for _ in 0..20 {
                loop_.step()?;
            }
            bar.inc(1);
        }
        latencies_ms.sort_by(f64::total_cmp);
        let pct = |q: f64| latencies_ms[((latencies_ms.len() - 1) as f64 * q).round() as usize];
        rows.push(Row {
            path,
            trials,
            p50_ms: round1(pct(0.5)),
            p99_ms: round1(pct(0.99)),
            max_ms: round1(pct(1.0)),
        });
    }
    bar.finish_and_clear();
    if json {
        for row in &rows {
            println!("{}", serde_json::to_string(row)?);
        }
    } else {
        println!(
            "drive input -> wheel command, in process, fleet stepped every {} ms of wall time",
            STEP.as_millis()
        );
        println!(
            "{:14} {:>7} {:>8} {:>8} {:>8}",
            "path", "trials", "p50 ms", "p99 ms", "max ms"
        );
        for r in &rows {
            println!(
                "{:14} {:>7} {:>8.1} {:>8.1} {:>8.1}",
                r.path, r.trials, r.p50_ms, r.p99_ms, r.max_ms
            );
        }
        println!(
            "ratio websocket / device queue (p50): {:.2}",
            rows[0].p50_ms / rows[1].p50_ms.max(f64::MIN_POSITIVE)
        );
    }
    Ok(())
}

fn round1(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}

/// The demo's real-time loop: the page's actions applied, then one fleet step, every 50 ms of
/// wall time.
struct Loop<'a> {
    fleet: &'a mut Fleet,
    dashboard: &'a Dashboard,
    next: Instant,
}

impl Loop<'_> {
    fn step(&mut self) -> anyhow::Result<()> {
        std::thread::sleep(self.next.saturating_duration_since(Instant::now()));
        self.next = self.next.max(Instant::now() - STEP) + STEP;
        while let Some(action) = self.dashboard.try_action() {
            if let PageAction::Drive { chair, input } = action {
                demo::push_drive(self.fleet, &chair, input)?;
            }
        }
        self.fleet.step(STEP);
        Ok(())
    }
}
