//! How much the `shared` result depends on what thesis 3.6 leaves open: units of `D` and `Sp`,
//! the activation threshold and bounds, where C is, and the mapping from `F_t` to speeds.

use std::path::Path;

use iw_shared_control::{FieldCentre, ThesisFieldParams};
use iw_sim::Map;
use iw_stats::Wilcoxon;

use crate::output::{bar_chart, compare, summary_of};
use crate::{Config, ExperimentError, Mode, Trial, run_modes};

/// One reading of the open assumptions.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Variant {
    /// Short name (plot label).
    pub name: &'static str,
    /// What differs from the default reading.
    pub what: &'static str,
    /// The field's parameters.
    pub params: ThesisFieldParams,
}

/// The readings swept: the default first, then one assumption changed at a time.
pub fn variants() -> Vec<Variant> {
    let base = ThesisFieldParams::default();
    let constants = base.constants;
    vec![
        Variant {
            name: "default",
            what: "D in cm, Sp in m/s, epsilon 5 %, range 27-80 cm, C at the footprint centre",
            params: base,
        },
        Variant {
            name: "D in m",
            what: "D in metres",
            params: ThesisFieldParams {
                distance_unit_m: 1.0,
                ..base
            },
        },
        Variant {
            name: "D in mm",
            what: "D in millimetres",
            params: ThesisFieldParams {
                distance_unit_m: 0.001,
                ..base
            },
        },
        Variant {
            name: "Sp in km/h",
            what: "Sp in km/h",
            params: ThesisFieldParams {
                speed_unit_mps: 1.0 / 3.6,
                ..base
            },
        },
        Variant {
            name: "eps 1 %",
            what: "activation where the force falls to 1 % of |F_a|",
            params: ThesisFieldParams {
                constants: iw_shared_control::PotentialFieldParams {
                    epsilon: 0.01,
                    ..constants
                },
                ..base
            },
        },
        Variant {
            name: "eps 20 %",
            what: "activation where the force falls to 20 % of |F_a|",
            params: ThesisFieldParams {
                constants: iw_shared_control::PotentialFieldParams {
                    epsilon: 0.2,
                    ..constants
                },
                ..base
            },
        },
        Variant {
            name: "range 0-3 m",
            what: "activation range not bounded to the 27-80 cm perimeter (1 cm - 3 m)",
            params: ThesisFieldParams {
                constants: iw_shared_control::PotentialFieldParams {
                    min_safety_range_m: 0.01,
                    max_safety_range_m: 3.0,
                    ..constants
                },
                ..base
            },
        },
        Variant {
            name: "no reverse",
            what: "F_t may not reverse a forward command",
            params: ThesisFieldParams {
                allow_reverse: false,
                ..base
            },
        },
        Variant {
            name: "cap |F_a|",
            what: "|F_t| capped at |F_a| and no reverse",
            params: ThesisFieldParams {
                allow_reverse: false,
                cap_at_user: true,
                ..base
            },
        },
        Variant {
            name: "C at axle",
            what: "C at the drive axle's centre",
            params: ThesisFieldParams {
                centre: FieldCentre::Axle,
                ..base
            },
        },
    ]
}

/// The outcome of one reading against manual driving by the same drivers.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SweepRow {
    /// Variant name.
    pub name: String,
    /// What differs.
    pub what: String,
    /// Collisions per lap attempted.
    pub collisions_per_lap: f64,
    /// Laps finished.
    pub laps_completed: usize,
    /// Laps attempted.
    pub laps_attempted: usize,
    /// Mean finished-lap time, s.
    pub mean_lap_time_s: Option<f64>,
    /// 1 - variant / manual collisions per lap.
    pub collision_reduction: Option<f64>,
    /// Manual > variant, one-tailed, paired per driver.
    pub wilcoxon: Wilcoxon,
}

/// Runs manual driving once, every [`variants`] reading of the `shared` field and the
/// arc-chord mapping, the same drivers each time; the manual row comes first.
pub fn sweep(
    map: &Map,
    config: &Config,
    on_trial: impl Fn(&Trial) + Sync,
) -> Result<Vec<SweepRow>, ExperimentError> {
    let manual_report = run_modes(map, config, &[Mode::Manual], &on_trial)?;
    let manual = summary_of(&manual_report, Mode::Manual)?;
    let row = |name: &str, what: &str, mode: Mode, config: &Config| {
        let report = run_modes(map, config, &[mode], &on_trial)?;
        let s = summary_of(&report, mode)?;
        let c = compare(&manual, &s)?;
        Ok::<_, ExperimentError>(SweepRow {
            name: name.into(),
            what: what.into(),
            collisions_per_lap: s.collisions_per_lap,
            laps_completed: s.laps_completed,
            laps_attempted: s.laps_attempted,
            mean_lap_time_s: s.mean_lap_time_s,
            collision_reduction: c.collision_reduction,
            wilcoxon: c.wilcoxon,
        })
    };
    let mut rows = vec![SweepRow {
        name: "manual".into(),
        what: "no assistance".into(),
        collisions_per_lap: manual.collisions_per_lap,
        laps_completed: manual.laps_completed,
        laps_attempted: manual.laps_attempted,
        mean_lap_time_s: manual.mean_lap_time_s,
        collision_reduction: None,
        wilcoxon: compare(&manual, &manual)?.wilcoxon,
    }];
    for v in variants() {
        let config = Config {
            field: v.params,
            ..config.clone()
        };
        rows.push(row(v.name, v.what, Mode::Shared, &config)?);
    }
    rows.push(row(
        "arc-chord",
        "the arc-chord mapping (C at the axle, no reverse)",
        Mode::SharedChord,
        config,
    )?);
    Ok(rows)
}

/// Trials [`sweep`] runs for `drivers` drivers (for progress bars).
pub fn sweep_trials(drivers: usize) -> usize {
    drivers * (variants().len() + 2)
}

/// Writes `sweep.json` and `sweep.png` into `out_dir`.
pub fn write_sweep(
    rows: &[SweepRow],
    map_name: &str,
    out_dir: &Path,
) -> Result<(), ExperimentError> {
    crate::output::create_dir(out_dir)?;
    crate::output::write_file(
        &out_dir.join("sweep.json"),
        serde_json::to_string_pretty(rows)?.as_bytes(),
    )?;
    let names: Vec<String> = rows.iter().map(|r| r.name.clone()).collect();
    bar_chart(
        &out_dir.join("sweep.png"),
        &format!("{map_name}: the shared field under each reading of thesis 3.6"),
        "reading",
        &names,
        &[(
            "collisions per lap".into(),
            rows.iter().map(|r| r.collisions_per_lap).collect(),
        )],
    )
}
