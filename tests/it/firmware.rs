//! Issue 13: `dtznn` as 1 kHz firmware (zero-order hold, 16-bit sensors, one sample of delay)
//! on the bench and on the leg.

use crate::common::{run_scenario, shipped};
use exoleg::metrics::Summary;

/// The firmware conditions of the issue on the bench.
const FW: [&str; 6] = [
    "sim.dt_s=0.0001",
    "controller.sample_period_s=0.001",
    "sensors.preset=\"adc16\"",
    "sensors.delay_samples=1",
    "metrics.settle_s=0.5",
    "controller.kind=\"dtznn\"",
];
const CASES: [&str; 4] =
    ["paper_2hz_gamma100.toml", "paper_2hz_gamma200.toml", "paper_10hz_gamma200.toml", "paper_10hz_gamma300.toml"];

fn bench(case: &str, extra: &[&str]) -> exoleg::Result<Summary> {
    run_scenario(&shipped(case, &[&FW[..], extra].concat())).map(|o| o.summary)
}

#[test]
fn the_four_paper_cases_as_firmware() {
    // (whole-run max, max after 0.5 s, RMS) limits of the issue; measured 9.229/0.050/1.252,
    // 4.579/0.086/0.439, 22.986/0.082/2.205, 15.335/0.097/1.201 N (DISCRETE.md's prototype:
    // 9.23/0.050/1.25, 4.58/0.086/0.44, 22.99/0.082/2.21, 15.33/0.097/1.20).
    let limits = [(9.4, 0.15, 1.3), (4.7, 0.15, 0.45), (23.5, 0.15, 2.25), (15.7, 0.15, 1.25)];
    for (case, (max, after, rms)) in CASES.iter().zip(limits) {
        let s = bench(case, &[]).unwrap();
        assert!(s.max_abs_force_error_n <= max, "{case}: max {}", s.max_abs_force_error_n);
        assert!(
            s.max_abs_force_error_after_settle_n <= after,
            "{case}: after {}",
            s.max_abs_force_error_after_settle_n
        );
        assert!(s.rms_force_error_n <= rms, "{case}: RMS {}", s.rms_force_error_n);
    }
}

#[test]
fn a_disturbance_step_with_the_wrong_beta_is_taken_out() {
    // Measured: 0.064 N after 1 s (DISCRETE.md: 0.05 N).
    let s = bench(
        CASES[0],
        &[
            "controller.nominal.beta_pa=1.6687e9",
            "disturbance.force_accel=[{kind=\"step\",amplitude=5000.0}]",
            "sim.duration_s=2.0",
            "metrics.settle_s=1.0",
        ],
    )
    .unwrap();
    assert!(s.max_abs_force_error_after_settle_n <= 0.1, "{}", s.max_abs_force_error_after_settle_n);
}

/// The 14 plants: beta, V0 and K_q each -20 % / +20 % (8 corners) and one at a time (6 axes).
fn plants() -> Vec<[f64; 3]> {
    let mut p: Vec<[f64; 3]> = (0..8).map(|i| [0, 1, 2].map(|b| if i >> b & 1 == 1 { 0.2 } else { -0.2 })).collect();
    for axis in 0..3 {
        for sign in [-0.2, 0.2] {
            let mut v = [0.0; 3];
            v[axis] = sign;
            p.push(v);
        }
    }
    p
}

fn worst_over_plants(case: &str, extra: &[&str]) -> f64 {
    plants()
        .iter()
        .map(|[b, v, k]| {
            let sets = [
                format!("hydraulics.beta_pa={:?}", 1.517e9 * (1.0 + b)),
                format!("hydraulics.v0_m3={:?}", 1e-4 * (1.0 + v)),
                format!("hydraulics.k_q={:?}", 18.2e-3 * (1.0 + k)),
                "controller.nominal.beta_pa=1.517e9".into(),
                "controller.nominal.v0_m3=1e-4".into(),
                "controller.nominal.k_q=18.2e-3".into(),
            ];
            let mut all: Vec<&str> = sets.iter().map(|s| s.as_str()).collect();
            all.extend_from_slice(extra);
            let s = bench(case, &all).unwrap_or_else(|e| panic!("{case} at {b} {v} {k}: {e}"));
            s.max_abs_force_error_after_settle_n
        })
        .fold(0.0, f64::max)
}

#[test]
fn plus_minus_20_percent_plants_stay_stable() {
    // Measured worst after 0.5 s over the 14 plants: 1.024, 0.417, 8.74, 5.28 N (DISCRETE.md:
    // 1.0, 0.41, 8.7, 5.3); the limits at 2 Hz are 1.5 and 0.6 N.
    let w: Vec<f64> = CASES.iter().map(|c| worst_over_plants(c, &[])).collect();
    println!("dtznn, +-20 % beta/V0/K_q, worst max after 0.5 s: {w:.3?} N");
    assert!(w[0] <= 1.5 && w[1] <= 0.6, "{w:?}");
    assert!(w[2] < 20.0 && w[3] < 12.0, "10 Hz: {w:?}");
    // The resonator at the reference frequency cuts the 10 Hz cases by an order of magnitude
    // (measured 0.287 and 0.277 N: 30x and 19x).
    let r2 = worst_over_plants(CASES[2], &["controller.resonator_hz=10.0"]);
    let r3 = worst_over_plants(CASES[3], &["controller.resonator_hz=10.0"]);
    println!("with the 10 Hz resonator: {r2:.3} N, {r3:.3} N");
    assert!(r2 < 0.1 * w[2] && r3 < 0.1 * w[3], "{r2} {r3}");
}

#[test]
fn known_and_wrong_delays_and_slower_sampling() {
    // A known delay of 2 and 3 samples: measured at most 0.115 N after 0.5 s.
    for d in ["2", "3"] {
        for case in CASES {
            let s = bench(case, &[&format!("sensors.delay_samples={d}")]).unwrap();
            assert!(
                s.max_abs_force_error_after_settle_n <= 0.15,
                "{case}, delay {d}: {}",
                s.max_abs_force_error_after_settle_n
            );
        }
    }
    // Reported: a wrong assumption (2 actual, 1 assumed), 500 Hz, 250 Hz. All stable.
    for (label, extra) in [
        ("2 actual, 1 assumed", vec!["sensors.delay_samples=2", "controller.delay_samples=1"]),
        ("500 Hz", vec!["controller.sample_period_s=0.002"]),
        ("250 Hz", vec!["controller.sample_period_s=0.004"]),
    ] {
        let after: Vec<f64> =
            CASES.iter().map(|c| bench(c, &extra).unwrap().max_abs_force_error_after_settle_n).collect();
        println!("dtznn {label}: max after 0.5 s {after:.3?} N");
        // Measured worst: 11.3 N (wrong delay), 0.27 N (500 Hz), 1.7 N (250 Hz).
        assert!(after.iter().all(|a| *a < 30.0), "{label}: {after:?}");
    }
}

#[test]
fn without_the_spool_sensor_it_estimates_the_spool() {
    // Measured after 0.5 s: 0.060/0.073/0.092/0.106 N without, 0.050/0.086/0.082/0.097 with.
    for case in CASES {
        let with = bench(case, &[]).unwrap().max_abs_force_error_after_settle_n;
        let without = bench(case, &["sensors.spool.enabled=false"]).unwrap().max_abs_force_error_after_settle_n;
        assert!(without <= 2.0 * with, "{case}: {without} without vs {with} with");
    }
}

#[test]
fn gait_as_firmware_on_the_leg() {
    let fw = [
        "controller.kind=\"dtznn\"",
        "controller.sample_period_s=0.001",
        "sensors.preset=\"adc16\"",
        "sensors.delay_samples=1",
    ];
    // (force RMS, force max, knee RMS, knee max) after the first stride; measured
    // comfortable 1.245 N, 9.011 N, 0.0084 deg, 0.020 deg; fast 1.648 N, 6.141 N, 0.0121 deg,
    // 0.032 deg (the limits: 2 N, 10 N, 0.03 deg, 0.1 deg).
    for (file, limits) in
        [("gait_walk.toml", [2.0, 10.0, 0.024, 0.06]), ("gait_walk_fast.toml", [2.0, 10.0, 0.03, 0.09])]
    {
        let out = run_scenario(&shipped(file, &fw)).unwrap();
        let s = &out.summary;
        let got = [
            s.rms_force_error_after_settle_n,
            s.max_abs_force_error_after_settle_n,
            s.knee_rms_error_deg.unwrap(),
            s.knee_max_abs_error_deg.unwrap(),
        ];
        println!(
            "{file} dtznn at 1 kHz: force RMS/max {:.3}/{:.3} N, knee RMS/max {:.4}/{:.4} deg",
            got[0], got[1], got[2], got[3]
        );
        assert_eq!(s.strides.len(), 5, "stable over the 5 strides");
        for (g, l) in got.iter().zip(limits) {
            assert!(*g <= l, "{file}: {got:?} vs {limits:?}");
        }
        assert!(s.sensor_clipped_readings.is_empty(), "the default ranges fit: {:?}", s.sensor_clipped_readings);
    }
}

#[test]
fn dtznn_is_discrete_only_and_reports_its_design() {
    let e = exoleg::Scenario::load(None, &["controller.kind=\"dtznn\"".into()]).unwrap_err();
    assert_eq!(e.exit_code(), 2);
    assert!(e.to_string().contains("controller.sample_period_s"), "{e}");
    let tmp = tempfile::tempdir().unwrap();
    let o = std::process::Command::new(crate::common::exe())
        .args(["run", "--quiet", "--out"])
        .arg(tmp.path().join("o"))
        .args(FW.iter().flat_map(|s| ["--set", s]))
        .args(["--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.6"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let js: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("o/summary.json")).unwrap()).unwrap();
    let d = &js["controller_design"];
    // The Zhang pole exp(-gamma h) = exp(-0.1) and a gain per state.
    assert!((d["zhang_pole"].as_f64().unwrap() - (-0.1f64).exp()).abs() < 1e-15);
    assert_eq!(d["zhang_gain_k"].as_array().unwrap().len(), 4);
    assert_eq!(d["measurements"], serde_json::json!(["force", "spool"]));
}

/// A reading beyond a sensor's range is counted and reported.
#[test]
fn clipped_readings_are_reported() {
    let s = bench(CASES[0], &["sensors.force.range=150.0"]).unwrap();
    assert!(s.sensor_clipped_readings.get("force").is_some_and(|n| *n > 100), "{:?}", s.sensor_clipped_readings);
}
