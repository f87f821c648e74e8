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
    // Measured: knee RMS 0.0098 deg, max 0.0280 deg; force RMS 1.034 N, max 3.150 N.
    assert!(rms < 0.025 && max < 0.07, "knee RMS {rms} max {max}");
    assert!(out.rms_force_error_after_settle_n < 2.5 && out.max_abs_force_error_after_settle_n < 10.0);
    assert_eq!(out.valve_saturation_fraction, 0.0);
    assert_eq!(out.force_limit_fraction, 0.0);
    assert_eq!(out.strides.len(), 5);
    // The actuator does real work: measured peak 559 N (inverse dynamics of the swing).
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
    // Measured: 0.0358 deg.
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
    // Measured: knee 0.00979 vs 0.00522 deg (1.88x), force 1.0337 vs 0.1445 N (7.2x).
    assert!(k(&base) > 1.4 * k(&strong), "weaker coupling should move the knee more");
    assert!(f(&base) > 2.5 * f(&strong));
    // The paper's disturbances on dx2/dt are tiny next to gait forces (about 60 N/s^2 against
    // gamma^2 = 40,000 1/s^2: 1.5 mN of force error): they move plain ZNN's force RMS by less
    // than 0.01 N. Measured: 1.46890 -> 1.46910 N (0.2 mN).
    assert!((f(&znn_paper) - f(&znn_base)).abs() < 0.01, "{} vs {}", f(&znn_paper), f(&znn_base));
    // A 20,000 N/s^2 step adds up to D/gamma^2 = 0.5 N without an observer. Measured: the RMS
    // after the first stride rises by 0.0708 N (1.46890 -> 1.53972).
    let added = f(&znn_step) - f(&znn_base);
    assert!((0.03..0.2).contains(&added), "the step adds {added} N");
    assert!(k(&znn_step) > k(&znn_base));
    // The observer takes the same step out: its force error moves by far less.
    // Measured: 0.0080 N against 0.0708 N (0.11 of it).
    assert!((f(&full_step) - f(&base)).abs() < 0.3 * added);
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
    // Measured: 0.0137 deg.
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

/// Issue 12.5: the cascade's feedforward is the inverse dynamics (Fourier-fitted) plus the
/// seal friction added in closed form; against the exact sum at any instant it is off by the
/// fit error of the smooth part only. (Fitting the sum, as before, was off by up to 29 N at the
/// friction's near-steps.)
#[test]
fn feedforward_is_inverse_dynamics_plus_exact_friction() {
    let sc = scenario("gait_walk.toml", &[]).resolve(&exoleg::Resources::new()).unwrap();
    let exoleg::reference::ForceReference::Gait(k) = &sc.model.reference else { panic!("gait") };
    let leg = sc.model.leg().unwrap();
    // The cascade's friction model: the plant's levels with its own smooth sign (5 mm/s).
    let fr = &exoleg::hydraulics::FrictionParams { smoothing_velocity_m_s: 0.005, ..sc.model.friction.clone() };
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    let (mut worst_rate, mut worst_accel) = (0.0f64, 0.0f64);
    let exact_at = |t: f64| {
        let (q, h) = (k.gait.knee_at(t), k.gait.hip_at(t));
        let tau =
            exoleg::leg::knee_inverse_dynamics(&leg.model, (h.value, h.rate, h.accel), (q.value, q.rate, q.accel))
                .unwrap();
        let arm = exoleg::leg::moment_arm_at(&leg.model, q.value);
        tau / arm + fr.force_n(arm * q.rate)
    };
    let fr_plant = &sc.model.friction;
    let exact_plant = |t: f64| {
        let (q, h) = (k.gait.knee_at(t), k.gait.hip_at(t));
        let tau =
            exoleg::leg::knee_inverse_dynamics(&leg.model, (h.value, h.rate, h.accel), (q.value, q.rate, q.accel))
                .unwrap();
        let arm = exoleg::leg::moment_arm_at(&leg.model, q.value);
        tau / arm + fr_plant.force_n(arm * q.rate)
    };
    // The old way: fit the sum (1024 samples, 48 harmonics).
    let ts: Vec<f64> = (0..1024).map(|i| i as f64 * 1.1 / 1024.0).collect();
    let old =
        exoleg::reference::FourierSeries::fit(&ts, &ts.iter().map(|t| exact_plant(*t)).collect::<Vec<_>>(), 1.1, 48);
    let mut worst_old = 0.0f64;
    for i in 0..2000 {
        let t = i as f64 * 1.1 / 2000.0 + 1e-4;
        let exact = exact_at(t);
        worst_old = worst_old.max((old.eval(t).0 - exact_plant(t)).abs());
        let ff = k.feedforward_at(t, None);
        worst = worst.max((ff.value - exact).abs());
        peak = peak.max(exact.abs());
        // The friction's derivatives against central differences of the friction alone.
        // (fourth-order central differences)
        let dt = 2e-6;
        let d = |g: &dyn Fn(f64) -> f64| {
            (8.0 * (g(t + dt) - g(t - dt)) - (g(t + 2.0 * dt) - g(t - 2.0 * dt))) / (12.0 * dt)
        };
        let f0 = k.friction_at(t);
        worst_rate = worst_rate.max((d(&|x| k.friction_at(x).value) - f0.rate).abs() / f0.rate.abs().max(100.0));
        worst_accel = worst_accel.max((d(&|x| k.friction_at(x).rate) - f0.accel).abs() / f0.accel.abs().max(1e4));
    }
    println!(
        "feedforward vs exact sum: {worst:.3e} N of a {peak:.1} N peak (fitting the sum: {worst_old:.2} N); \
         friction rate/accel rel. {worst_rate:.1e}/{worst_accel:.1e}"
    );
    // Measured: 6.2e-5 N of a 566 N peak; fitting the sum was off by 29.2 N (5.2 %);
    // derivatives within 4.9e-10 / 3.9e-10 of fourth-order differences.
    assert!(worst < 2e-4, "{worst} N");
    assert!(worst_old > 10.0, "the old fit was off by {worst_old} N");
    assert!(worst_rate < 1.5e-9 && worst_accel < 1.2e-9, "{worst_rate} {worst_accel}");
}
