//! Serialising one dashboard frame for 100 chairs (what is sent at 10 Hz), against the fleet
//! snapshot's own JSON for the same chairs as a peer (full names, f64, every field).

use criterion::{Criterion, criterion_group, criterion_main};
use iw_dashboard::{ChairDisplay, ChairView, MessageView, State, round_cm};
use std::hint::black_box;

fn state(chairs: usize) -> State {
    State {
        t: 123.45,
        chairs: (0..chairs)
            .map(|i| {
                let x = 1.0 + i as f64 * 0.237;
                ChairView {
                    n: format!("chair-{i}"),
                    k: "virtual".into(),
                    p: [round_cm(x), round_cm(5.0 + x.sin()), round_cm(x.cos())],
                    v: [round_cm(0.537), round_cm(-0.1234)],
                    s: (0..16)
                        .map(|s| {
                            if s % 3 == 0 {
                                -1.0
                            } else {
                                round_cm(1.0 + s as f64 * 0.137)
                            }
                        })
                        .collect(),
                    g: Some([round_cm(20.51), round_cm(7.25)]),
                    path: (0..20)
                        .map(|k| [round_cm(x + k as f64 * 0.5), round_cm(5.25)])
                        .collect(),
                    u: round_cm(0.1234),
                    c: 0,
                    d: ChairDisplay {
                        action: "goal".into(),
                        goal: Some("dining-hall".into()),
                        warn: i % 7 == 0,
                        seq: None,
                        answer: Some("agree".into()),
                        user: None,
                        applied: None,
                    },
                }
            })
            .collect(),
        doors: (0..10).map(|i| (format!("door-{i}"), i % 2 == 0)).collect(),
        msgs: (0..30)
            .map(|i| MessageView {
                from: "cognitive@chair-1".into(),
                to: "control@chair-1".into(),
                act: "request".into(),
                conv: format!("goal-chair-1-{i}"),
                dropped: false,
            })
            .collect(),
        ..State::default()
    }
}

/// The same chairs as plain f64 records with long names, as a serde peer.
#[derive(serde::Serialize)]
struct Verbose {
    name: String,
    pose: [f64; 3],
    twist: [f64; 2],
    sonar_m: Vec<Option<f64>>,
    goal: Option<[f64; 2]>,
    path: Vec<[f64; 2]>,
}

fn bench(c: &mut Criterion) {
    let s = state(100);
    let verbose: Vec<Verbose> = (0..100)
        .map(|i| {
            let x = 1.0 + i as f64 * 0.237;
            Verbose {
                name: format!("chair-{i}"),
                pose: [x, 5.0 + x.sin(), x.cos()],
                twist: [0.537, -0.1234],
                sonar_m: (0..16)
                    .map(|s| {
                        if s % 3 == 0 {
                            None
                        } else {
                            Some(1.0 + s as f64 * 0.137)
                        }
                    })
                    .collect(),
                goal: Some([20.51, 7.25]),
                path: (0..20).map(|k| [x + k as f64 * 0.5, 5.25]).collect(),
            }
        })
        .collect();
    let compact = serde_json::to_string(&s).map(|t| t.len()).unwrap_or(0);
    let full = serde_json::to_string(&verbose)
        .map(|t| t.len())
        .unwrap_or(0);
    println!("100 chairs: dashboard frame {compact} bytes; verbose f64 peer {full} bytes");
    let mut group = c.benchmark_group("dashboard_frame_100_chairs");
    group.bench_function("compact_state", |b| {
        b.iter(|| serde_json::to_string(black_box(&s)).map(|t| t.len()))
    });
    group.bench_function("verbose_f64_peer", |b| {
        b.iter(|| serde_json::to_string(black_box(&verbose)).map(|t| t.len()))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
