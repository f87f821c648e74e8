//! Gait-trajectory runs: joint-angle and force tracking tested together (shipped scenarios).

use crate::common::{run_scenario, shipped as scenario, Out};
use std::path::Path;

fn run(file: &str, sets: &[&str]) -> Out {
    run_scenario(&scenario(file, sets)).unwrap()
}

#[test]
fn comfortable_walking_tracks_knee_and_force_without_saturation() {
    let s = scenario("gait_walk.toml", &[]);
    assert_eq!(s.file.metrics.settle_s, 1.10, "settle window = one stride");
    let out = run_scenario(&s).unwrap().summary;
    let (rms, max) = (out.knee_rms_error_deg.unwrap(), out.knee_max_abs_error_deg.unwrap());
    println!(
        "comfortable: knee RMS {rms:.4} deg, max {max:.4} deg; force RMS {:.3} N, max {:.3} N; peak force {:.1} N, power {:.1} W",
        out.rms_force_error_after_settle_n,
        out.max_abs_force_error_after_settle_n,
        out.peak_cylinder_force_n,
        out.peak_power_w
    );
    // Measured: knee RMS 0.0089 deg, max 0.0278 deg; force RMS 0.935 N, max 3.857 N.
    assert!(rms < 0.025 && max < 0.07, "knee RMS {rms} max {max}");
    assert!(out.rms_force_error_after_settle_n < 2.5 && out.max_abs_force_error_after_settle_n < 10.0);
    assert_eq!(out.valve_saturation_fraction, 0.0);
    assert_eq!(out.force_limit_fraction, 0.0);
    assert_eq!(out.strides.len(), 5);
    // The actuator does real work: measured peak 568 N (inverse dynamics of the swing).
    assert!((540.0..600.0).contains(&out.peak_cylinder_force_n), "{}", out.peak_cylinder_force_n);
}

#[test]
fn fast_walking_keeps_the_knee_within_5_deg() {
    let out = run("gait_walk_fast.toml", &[]).summary;
    let max = out.knee_max_abs_error_deg.unwrap();
    println!(
        "fast: knee RMS {:.4} deg, max {max:.4} deg; force RMS {:.3} N, max {:.3} N",
        out.knee_rms_error_deg.unwrap(),
        out.rms_force_error_after_settle_n,
        out.max_abs_force_error_after_settle_n
    );
    // Measured: 0.0329 deg.
    assert!(max < 0.09, "knee max {max}");
}

#[test]
fn degraded_interaction_and_disturbances_make_errors_worse_but_stay_stable() {
    let k = |s: &exoleg::metrics::Summary| s.knee_rms_error_deg.unwrap();
    let f = |s: &exoleg::metrics::Summary| s.rms_force_error_after_settle_n;
    // The pilot's cuff force resists force surpluses (w1 = k_p e + k_d e_dot against the
    // surplus): a strongly coupled pilot (k_p = 4) holds the knee closer than the nominal
    // one (0.05); degrading the coupling to the nominal gains lets force errors move the knee.
    let strong = run("gait_walk.toml", &["human.k_p=4.0"]).summary;
    let base = run("gait_walk.toml", &[]).summary;
    // The paper's disturbances on dx2/dt (small next to gait forces), and a 20,000 N/s^2 step.
    let paper = [
        "disturbance.state_gain_force=0.05",
        "disturbance.state_gain_force_rate=1e-3",
        "disturbance.force_accel=[{kind=\"sine\"},{kind=\"constant\",value=1.0},{kind=\"exp_decay\",rate_per_s=0.1}]",
    ];
    let step = ["disturbance.force_accel=[{kind=\"step\",amplitude=20000.0,time_s=1.5}]"];
    let znn = ["controller.kind=\"znn\""];
    let full_step = run("gait_walk.toml", &step).summary;
    let znn_base = run("gait_walk.toml", &znn).summary;
    let znn_paper = run("gait_walk.toml", &[&znn[..], &paper].concat()).summary;
    let znn_step = run("gait_walk.toml", &[&znn[..], &step].concat()).summary;
    println!(
        "knee RMS (deg): strong pilot {:.5}, nominal {:.5}; force RMS (N): strong {:.4}, nominal {:.4}",
        k(&strong),
        k(&base),
        f(&strong),
        f(&base)
    );
    println!(
        "plain ZNN force RMS: {:.5} -> {:.5} (paper disturbances) -> {:.5} (step); ARBFNN-FDO-ZNN with the step {:.5}",
        f(&znn_base),
        f(&znn_paper),
        f(&znn_step),
        f(&full_step)
    );
    // Measured: knee 0.00892 vs 0.00502 deg (1.78x), force 0.9355 vs 0.1915 N (4.9x).
    assert!(k(&base) > 1.4 * k(&strong), "weaker coupling should move the knee more");
    assert!(f(&base) > 2.5 * f(&strong));
    // Without an observer, disturbances show up in the force error, in proportion to their size.
    assert!(f(&znn_paper) > f(&znn_base));
    // Measured: 1.4697 vs 1.3949 N (+5.4 %): a 20,000 N/s^2 step adds ~D/gamma^2 = 0.5 N at most.
    assert!(f(&znn_step) > 1.03 * f(&znn_base), "a 20,000 N/s^2 step adds ~D/gamma^2 = 0.5 N");
    assert!(k(&znn_step) > k(&znn_base));
    // The observer takes the same step out: its force error moves by far less.
    // Measured: 0.0064 N against 0.075 N (0.086 of it).
    assert!((f(&full_step) - f(&base)).abs() < 0.2 * (f(&znn_step) - f(&znn_base)));
    for s in [&strong, &base, &full_step, &znn_base, &znn_paper, &znn_step] {
        // Measured: knee RMS at most 0.0105 deg, force max at most 6 N.
        assert!(k(s) < 0.03 && s.max_abs_force_error_after_settle_n < 15.0, "stable run expected");
    }
}

#[test]
fn user_gait_csv_with_another_cadence() {
    // A user's file: 51 rows (every 2 %), its own header order, last row closing the cycle,
    // run through --set with a cadence instead of a stride time.
    let src = exoleg::reference::BUILTIN_TRIALS[2].1; // wbds01 slow
    let mut rdr = csv::Reader::from_reader(src.as_bytes());
    let mut text = String::from("knee_flexion_deg,gait_cycle_pct,hip_flexion_deg\n");
    for (i, r) in rdr.records().enumerate() {
        let r = r.unwrap();
        if i % 2 == 0 {
            text.push_str(&format!("{},{},{}\n", &r[2], &r[0], &r[1]));
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("my_walk.csv");
    std::fs::write(&path, text).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_exoleg"))
        .args([
            "run",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/gait_walk.toml").to_str().unwrap(),
            "--out",
            dir.path().join("out").to_str().unwrap(),
            "--set",
            &format!("reference.gait_file=\"{}\"", path.display()),
            "--set",
            "reference.cadence_steps_per_min=96.0",
            "--set",
            "sim.duration_s=3.75",
            "--set",
            "metrics.settle_s=1.25",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let js: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out/summary.json")).unwrap()).unwrap();
    let strides = js["strides"].as_array().unwrap();
    assert_eq!(strides.len(), 3, "3.75 s at 1.25 s per stride (96 steps/min)");
    // Measured: 0.0064 deg.
    assert!(js["knee_rms_error_deg"].as_f64().unwrap() < 0.02);
    assert!(dir.path().join("out/knee_tracking.png").is_file());

    // Without any timing the error names the key.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_exoleg"))
        .args(["run", "--out", dir.path().join("o2").to_str().unwrap()])
        .args(["--set", "reference.kind=\"gait\"", "--set", &format!("reference.gait_file=\"{}\"", path.display())])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("reference.stride_s"));
}
