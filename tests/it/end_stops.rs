//! End stops (issue 22): the knee's URDF limits (and the stroke ends through the loop) hold the
//! leg on both engines, with the time at a stop and the deepest penetration in `summary.json`
//! and a warning; a driven hip with ground contact no longer panics inside Rapier, and a run
//! that fails inside a sweep is a failed line while the others complete.

use crate::common::exe;
use std::path::Path;
use std::process::Command;

fn run(out: &Path, sets: &[&str]) -> (serde_json::Value, String) {
    let mut args = vec!["run", "--quiet", "--out", out.to_str().unwrap()];
    for s in sets {
        args.extend(["--set", s]);
    }
    let o = Command::new(exe()).args(&args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{sets:?}: {err}");
    let s = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    (s, err)
}

/// +-2000 N on the cylinder and a free release from 30 deg, on both engines: the knee stays
/// within its URDF range [-10, 100] deg plus at most 1 deg, the time at the stop is reported,
/// and the CLI warns.
#[test]
fn the_knee_stops_at_its_limits_on_both_engines() {
    let tmp = tempfile::tempdir().unwrap();
    // (engine, extra sets, which limit, seconds at it at least).
    let cases: [(&str, &[&str], &str, f64); 6] = [
        ("rapier", &["actuator.mode=\"force\"", "actuator.force_n=-2000.0"], "knee_upper_s", 2.5),
        ("rapier", &["actuator.mode=\"force\"", "actuator.force_n=2000.0"], "knee_lower_s", 2.5),
        ("rapier", &["actuator.mode=\"free\""], "knee_lower_s", 0.001),
        ("reduced", &["actuator.mode=\"force\"", "actuator.force_n=-2000.0"], "knee_upper_s", 2.5),
        ("reduced", &["actuator.mode=\"force\"", "actuator.force_n=2000.0"], "knee_lower_s", 2.5),
        ("reduced", &["actuator.mode=\"free\""], "knee_lower_s", 0.001),
    ];
    for (i, (engine, sets, side, at_least)) in cases.iter().enumerate() {
        let eng = format!("leg.engine=\"{engine}\"");
        let all: Vec<&str> = [&[eng.as_str(), "sim.duration_s=3.0"][..], sets].concat();
        let (s, err) = run(&tmp.path().join(format!("c{i}")), &all);
        let [lo, hi] = [s["knee_range_deg"][0].as_f64().unwrap(), s["knee_range_deg"][1].as_f64().unwrap()];
        let stops = &s["end_stops"];
        let deepest = stops["max_penetration_deg"].as_f64().unwrap();
        println!("{engine} {sets:?}: knee {lo:.3}..{hi:.3} deg, {side} {} s, deepest {deepest:.4} deg", stops[side]);
        // Measured (Rapier / reduced): -2000 N 0.187 / 0.214 deg past 100; +2000 N 0.024 /
        // 0.478 deg past -10; the free release 0.0006 / 0.0035 deg past -10. The limit is the
        // issue's documented stop penetration, 1 deg.
        assert!(lo > -11.0 && hi < 101.0, "{engine} {sets:?}: knee {lo}..{hi} deg");
        assert!(deepest > 0.0 && deepest < 1.0, "{engine} {sets:?}: {deepest} deg");
        assert!(stops[side].as_f64().unwrap() >= *at_least, "{engine} {sets:?}: {stops}");
        assert!(err.contains("end stops"), "{engine} {sets:?}: no warning in {err:?}");
    }
}

/// The walking leg on the carriage (`stand.toml` with the wearer's knee off and friction on
/// the floor) driven into both knee stops by +-3000 N on the cylinder, on both engines: the
/// knee holds at its URDF range plus less than 1 deg, the time at the stop is reported, the CLI
/// warns.
#[test]
fn the_walking_leg_stops_at_its_limits_on_both_engines() {
    let tmp = tempfile::tempdir().unwrap();
    let stand = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/stand.toml");
    let free = ["ground.friction=0.8", "wearer.knee_stiffness_nm_per_rad=0"];
    // (engine, force, which limit, seconds at it at least). Measured (Rapier / reduced): -3000 N
    // 0.144 / 0.299 deg past 100 for 2.93 / 2.93 s; +3000 N 0.065 / 0.097 deg past -10 for
    // 2.92 / 2.92 s (the reduced walking leg's stops are spring-dampers at every stage, in its
    // substeps; held over the step like Rapier's they yielded 0.66 / 0.23 deg).
    let cases = [
        ("rapier", -3000.0, "knee_upper_s", 2.5),
        ("rapier", 3000.0, "knee_lower_s", 2.5),
        ("reduced", -3000.0, "knee_upper_s", 2.5),
        ("reduced", 3000.0, "knee_lower_s", 2.5),
    ];
    for (i, (engine, force, side, at_least)) in cases.into_iter().enumerate() {
        let out = tmp.path().join(format!("w{i}"));
        let sets = [
            format!("leg.engine=\"{engine}\""),
            "actuator.mode=\"force\"".to_string(),
            format!("actuator.force_n={force:?}"),
            "wearer.knee_damping_nm_s_per_rad=0".to_string(),
        ];
        let mut args = vec!["run".to_string(), stand.display().to_string(), "--quiet".into(), "--out".into()];
        args.push(out.display().to_string());
        for s in sets.iter().map(String::as_str).chain(free) {
            args.extend(["--set".to_string(), s.to_string()]);
        }
        let o = Command::new(exe()).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(o.status.success(), "{engine} {force}: {err}");
        let s: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
        let [lo, hi] = [s["knee_range_deg"][0].as_f64().unwrap(), s["knee_range_deg"][1].as_f64().unwrap()];
        let stops = &s["end_stops"];
        let deepest = stops["max_penetration_deg"].as_f64().unwrap();
        assert!(lo > -11.0 && hi < 101.0, "{engine} {force}: knee {lo}..{hi} deg");
        assert!(deepest > 0.0 && deepest < 1.0, "{engine} {force}: {deepest} deg");
        assert!(stops[side].as_f64().unwrap() >= at_least, "{engine} {force}: {stops}");
        assert!(err.contains("end stops"), "{engine} {force}: no warning in {err:?}");
    }
}

/// The shipped runs never touch a stop (the paper tables and the leg tests are unchanged).
#[test]
fn the_shipped_leg_runs_touch_no_stop() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    for name in ["default", "gait_walk", "stand", "gait_treadmill"] {
        let out = tmp.path().join(name);
        let o = Command::new(exe())
            .args(["run", "--quiet", "--out", out.to_str().unwrap()])
            .arg(dir.join(format!("{name}.toml")))
            .args(["--set", "sim.duration_s=2.2", "--set", "metrics.settle_s=1.1"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        assert!(!String::from_utf8_lossy(&o.stderr).contains("end stops"));
        let s: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(s["end_stops"]["max_penetration_deg"], 0.0, "{name}");
    }
}

/// A gait on a driven hip with ground contact: the combination that panicked inside Rapier
/// (its joint-limit constraint under a kinematic hip) runs with ERL-SMC; in a sweep over the
/// controller, ARBFNN-FDO-ZNN's divergence on the loaded leg is a failed line and the other runs
/// complete.
#[test]
fn a_driven_hip_on_the_ground_runs_and_a_failing_run_cannot_sink_a_sweep() {
    let tmp = tempfile::tempdir().unwrap();
    let gait = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/gait_walk.toml");
    let o = Command::new(exe())
        .arg("sweep")
        .arg(&gait)
        .args(["--grid", "controller.kind=\"erl_smc\",\"arbfnn_fdo_znn\",\"znn\"", "--quiet", "--jobs", "2"])
        .args(["--set", "hip.mode=\"driven\"", "--set", "ground.enabled=true"])
        .args(["--set", "sim.duration_s=1.2", "--set", "metrics.settle_s=0.6", "--out"])
        .arg(tmp.path().join("s"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(tmp.path().join("s/runs.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert!(lines[0]["error"].is_null() && lines[2]["error"].is_null(), "{:?}", lines);
    assert!(lines[1]["error"].as_str().unwrap().contains("diverged"), "{:?}", lines[1]);
    let agg = std::fs::read_to_string(tmp.path().join("s/aggregate.csv")).unwrap();
    assert!(agg.contains("failed_runs,1,"), "{agg}");
}
