//! A lockstep world (`WorldAgent::lockstep`) over real buses: two bodies on their own buses,
//! driven by a controller that answers each sensor frame, trace the same trajectory in two runs
//! with the same seed, though the two runs answer with different, random delays (a loaded host).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use iw_agent::AgentHost;
use iw_body::{Body, SensorFrame, WheelSpeeds};
use iw_bus::transport::PeerAddr;
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Stack};
use iw_wiring::agent_id;
use iw_wiring::world_link::{WORLD, WorldAgent, WorldBody, body_endpoint, world_agent};
use nalgebra::{Isometry2, Vector2};

/// Frames compared per body.
const STEPS: usize = 60;

/// The controller: a function of the frame alone (wheel ticks and the noisy sonars), so a
/// body's command at each step is fixed by what the world sent it.
fn command(frame: &SensorFrame) -> WheelSpeeds {
    let mean = |range: std::ops::Range<usize>| {
        let n = range.len() as f64;
        range.map(|i| frame.sonar_m[i].unwrap_or(3.0)).sum::<f64>() / n
    };
    let half = frame.sonar_m.len() / 2;
    let steer = 0.05 * (mean(0..half) - mean(half..frame.sonar_m.len())).tanh()
        + 0.03 * (frame.left_ticks as f64 * 0.003).sin();
    WheelSpeeds {
        left_mps: 0.3 - steer,
        right_mps: 0.3 + steer,
    }
}

/// xorshift, for the delays (no dependency needed).
fn next(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

/// One run: the world (seed 7) on its own thread, stepped every 2 ms of real time, and two
/// bodies that answer every frame after a random delay of up to `max_delay_ms`. Returns both
/// bodies' true poses (x, y, heading) at each of the world's first [`STEPS`] steps with both in
/// it, as the world thread saw them.
fn run(lockstep: bool, delay_seed: u64, max_delay_ms: u64) -> Vec<[[f64; 3]; 2]> {
    let network = InProcNetwork::new();
    let clock = Clock::system();
    let bus = |name: &str| {
        Arc::new(
            Bus::start(
                Stack::new(),
                Arc::new(network.endpoint(name).unwrap()),
                clock.clone(),
                BusConfig::default(),
            )
            .unwrap(),
        )
    };
    let world_bus = bus(WORLD);
    let chairs = [("c1", 7.5, 6.0, 0.0), ("c2", 1.0, 6.0, 0.0)];
    let mut bodies = Vec::new();
    for (name, x, y, heading) in chairs {
        let chair_bus = bus(name);
        world_bus.add_route(&body_endpoint(name).name, PeerAddr(name.into()));
        chair_bus.add_route(&world_agent().name, PeerAddr(WORLD.into()));
        let start = Isometry2::new(Vector2::new(x, y), heading);
        bodies.push(
            WorldBody::open(chair_bus, name, start)
                .unwrap()
                .lockstep(lockstep),
        );
    }
    let map = iw_sim::Map::parse(
        include_str!("../../maps/sample-building.map"),
        "sample-building.map",
    )
    .unwrap();
    let agent = WorldAgent::new(
        iw_sim::shared(iw_sim::World::new(map, 7)),
        agent_id("door", "services"),
    )
    .lockstep(lockstep);
    let (world, roster) = agent.reports();
    // the world agent is there before any body asks to attach
    let mut host = AgentHost::new(world_bus);
    host.add(world_agent(), Box::new(agent)).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let world_thread = {
        let stop = stop.clone();
        let clock = clock.clone();
        std::thread::spawn(move || {
            let mut trace = Vec::new();
            let mut last_ns = None;
            while !stop.load(Ordering::Relaxed) && trace.len() < STEPS {
                host.step(clock.now());
                let ids: Vec<_> = ["c1", "c2"]
                    .iter()
                    .filter_map(|c| roster.lock().unwrap().get(*c).copied())
                    .collect();
                let world = world.lock().unwrap();
                if ids.len() == 2 && last_ns != Some(world.time_ns()) {
                    last_ns = Some(world.time_ns());
                    let pose = |i: usize| {
                        let p = world.pose(ids[i]).unwrap();
                        [p.translation.x, p.translation.y, p.rotation.angle()]
                    };
                    trace.push([pose(0), pose(1)]);
                }
                drop(world);
                std::thread::sleep(Duration::from_millis(2));
            }
            trace
        })
    };

    let mut rng = delay_seed;
    let deadline = Instant::now() + Duration::from_secs(120);
    // Attach in a fixed order (a body's noise is seeded by its place in the world), both before
    // either drives: a lockstep world waits for both before it steps.
    let mut framed = [false; 2];
    while !framed.iter().all(|f| *f) {
        assert!(Instant::now() < deadline, "never attached");
        for (i, body) in bodies.iter_mut().enumerate() {
            framed[i] |= body.read().is_ok();
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    while !world_thread.is_finished() {
        assert!(Instant::now() < deadline, "stalled");
        for body in &mut bodies {
            let Ok(frame) = body.read() else { continue };
            std::thread::sleep(Duration::from_millis(next(&mut rng) % (max_delay_ms + 1)));
            // fails only once the world thread, done, has dropped its bus
            let _ = body.command(command(&frame));
        }
    }
    stop.store(true, Ordering::Relaxed);
    world_thread.join().unwrap()
}

#[test]
fn two_lockstep_runs_with_the_same_seed_trace_the_same_trajectory_under_different_delays() {
    let quick = run(true, 0x9e37_79b9_7f4a_7c15, 3);
    let slow = run(true, 0x2545_f491_4f6c_dd1d, 40);
    assert_eq!((quick.len(), slow.len()), (STEPS, STEPS));
    for (chair, (a, b)) in quick[0].iter().zip(&quick[STEPS - 1]).enumerate() {
        // the bodies moved: the runs do not compare two chairs standing still
        let travel = (b[0] - a[0]).hypot(b[1] - a[1]);
        assert!(travel > 0.3, "body {chair} moved {travel} m");
    }
    for (k, (p, q)) in quick.iter().zip(&slow).enumerate() {
        let same = p
            .iter()
            .flatten()
            .zip(q.iter().flatten())
            .all(|(u, v)| (u - v).abs() < 1e-9);
        assert!(
            same,
            "step {k}: {p:?} in the quick run, {q:?} in the slow one"
        );
    }
}
