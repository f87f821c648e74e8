//! Whole-loop speed in simulated seconds per wall-clock second (issue 41): the figures
//! `scripts/bench` prints beside MuJoCo's walking leg. A benchmark, not a test.
//!
//! ```sh
//! cargo run --release --example speed -- --repeats 5            # every case, a table
//! cargo run --release --example speed -- --case treadmill_reduced --repeats 3 --json
//! ```
//! Cases (each run as `exoleg run --out` runs it: `timeseries.csv` streamed to a temporary
//! folder, `summary.json` and the plots after the loop):
//! - `treadmill_reduced`: `gait_treadmill.toml` on the reduced engine at 1 ms (dtznn at 1 kHz,
//!   the device's truth columns; 6.6 s: a stride of run-in and five).
//! - `treadmill_analysis`: the same with `wearer.muscles = true` (issue 39: static
//!   optimisation and the metabolic rate of the impedance wearer's moments each step; the
//!   issue's budget: at most 50 % more wall time than `treadmill_reduced`).
//! - `treadmill_muscles`: the same with `wearer.model = "muscles"` (issue 40): the nervous
//!   system, static optimisation over the nine muscles and their activation dynamics each
//!   millisecond. Its `whole` includes the 3-stride learning run of the impedance wearer.
//! - `treadmill_rapier`: the shipped `gait_treadmill.toml` (Rapier, 0.25 ms).
//! - `stand_reduced`: `stand.toml` on the reduced engine at 1 ms with the actuator free, 6 s
//!   (the passive standing leg, MuJoCo's `stand_*` cases; the controller runs, its command
//!   drives nothing).
//!
//! Per case: `loop` = simulated seconds over the loop's wall time (the steps, the rows into
//! the writer thread and the online metrics: `summary.json`'s `steps_per_second` times the
//! step), `whole` = simulated seconds over the wall time of the whole run (setup, loop, the
//! last rows written and synced, the summary, the plots). The median of `--repeats` runs.

use std::path::{Path, PathBuf};
use std::time::Instant;

/// One case: its name, scenario file and overrides.
struct Case {
    name: &'static str,
    file: &'static str,
    sets: &'static [&'static str],
}

const CASES: [Case; 5] = [
    Case {
        name: "treadmill_reduced",
        file: "gait_treadmill.toml",
        sets: &["leg.engine=\"reduced\"", "sim.dt_s=0.001"],
    },
    Case {
        name: "treadmill_analysis",
        file: "gait_treadmill.toml",
        sets: &["leg.engine=\"reduced\"", "sim.dt_s=0.001", "wearer.muscles=true"],
    },
    Case {
        name: "treadmill_muscles",
        file: "gait_treadmill.toml",
        sets: &["leg.engine=\"reduced\"", "sim.dt_s=0.001", "wearer.model=\"muscles\""],
    },
    Case { name: "treadmill_rapier", file: "gait_treadmill.toml", sets: &[] },
    Case {
        name: "stand_reduced",
        file: "stand.toml",
        sets: &["leg.engine=\"reduced\"", "sim.dt_s=0.001", "actuator.mode=\"free\"", "sim.duration_s=6.0"],
    },
];

/// The simulated seconds per wall second of one run of `case`: (loop, whole).
fn run_once(case: &Case, out: &Path) -> (f64, f64) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let t0 = Instant::now();
    let sc = exoleg::load(Some(&dir.join(case.file)), case.sets).expect("scenario");
    let report = exoleg::study::RunBuilder::new(&sc).write_to(out).expect("run");
    let whole = t0.elapsed().as_secs_f64();
    let sim_s = sc.model.steps as f64 * sc.model.dt_s;
    (report.summary.steps_per_second * sc.model.dt_s, sim_s / whole)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |k: &str| args.iter().position(|a| a == k).and_then(|i| args.get(i + 1)).cloned();
    let repeats: usize = arg("--repeats").map_or(5, |r| r.parse().expect("--repeats N"));
    let only = arg("--case");
    let json = args.iter().any(|a| a == "--json");
    let tmp = tempfile::tempdir().expect("temporary folder");
    let cases: Vec<&Case> = CASES.iter().filter(|c| only.as_deref().is_none_or(|o| o == c.name)).collect();
    assert!(!cases.is_empty(), "no case {only:?}: {:?}", CASES.iter().map(|c| c.name).collect::<Vec<_>>());
    let mut results: Vec<(Vec<f64>, Vec<f64>)> = vec![(Vec::new(), Vec::new()); cases.len()];
    for round in 0..repeats {
        for (i, c) in cases.iter().enumerate() {
            let out: PathBuf = tmp.path().join(format!("{}_{round}", c.name));
            let (l, w) = run_once(c, &out);
            results[i].0.push(l);
            results[i].1.push(w);
            let _ = std::fs::remove_dir_all(&out);
        }
    }
    let mut obj = serde_json::Map::new();
    for (c, (l, w)) in cases.iter().zip(&mut results) {
        let (lm, wm) = (median(l), median(w));
        if json {
            obj.insert(
                c.name.into(),
                serde_json::json!({"loop_sim_s_per_s": lm, "whole_sim_s_per_s": wm, "loop_runs": l, "whole_runs": w}),
            );
        } else {
            println!("{:<20} loop {:>8.1} sim s/s   whole run {:>8.1} sim s/s   ({} runs)", c.name, lm, wm, l.len());
        }
    }
    if json {
        println!("{}", serde_json::Value::Object(obj));
    }
}
