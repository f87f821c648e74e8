//! The leg through the whole simulator (scenario -> sim loop -> record), checked against the
//! independent reduced closed-chain model of `common::leg_reference` (built from the URDF's
//! own numbers, not from Rapier).

use crate::common::leg_reference::{manifest, mean_period, RefModel};
use crate::common::{self, knee_deg, leg_run, Out};

fn knee_samples(out: &Out) -> Vec<(f64, f64)> {
    out.record.rows.iter().map(|r| (r.t_s, r.leg.unwrap().knee_angle_deg.to_radians())).collect()
}

fn check_free_and_hold(builtin: &str, file: &str) {
    let r = RefModel::from_file(&manifest(file));
    // Passive release from 8 deg, no actuator force, no damping: the swing to -8 deg stays
    // within the knee's range (hyperextension to -10 deg), so no end stop acts.
    let out = leg_run(&[
        &format!("leg.urdf=\"{builtin}\""),
        "actuator.mode=\"free\"",
        "leg.initial_knee_deg=8.0",
        "sim.duration_s=5.0",
    ]);
    assert!(out.summary.end_stops.is_some_and(|s| s.is_clear()), "{builtin}: {:?}", out.summary.end_stops);
    let (t_sim, n_sim) = mean_period(&knee_samples(&out));
    let (t_ref, _) = mean_period(&r.simulate(8f64.to_radians(), 1e-4, 5.0));
    let err = (t_sim - t_ref) / t_ref;
    assert!(n_sim >= 3, "{builtin}: {n_sim} maxima");
    // Measured: -5.0e-7 (exo_leg), -1.1e-6 (exo_leg_small).
    assert!(err.abs() < 3e-6, "{builtin}: period {t_sim} vs reference {t_ref} ({:.4}%)", 100.0 * err);
    let gap = out.summary.loop_closure_max_gap_m.unwrap();
    // Measured: 1.1e-8 m, 2.4e-8 m.
    assert!(gap < 6e-8, "{builtin}: loop gap {gap}");

    // Statics: the reference holding force, applied in `force` mode, keeps the knee still.
    for deg in [0.0f64, 30.0, 60.0, 90.0] {
        let f = r.holding_force(deg.to_radians());
        let out = leg_run(&[
            &format!("leg.urdf=\"{builtin}\""),
            "actuator.mode=\"force\"",
            &format!("actuator.force_n={f:?}"),
            &format!("leg.initial_knee_deg={deg:?}"),
        ]);
        let q = knee_deg(&out);
        let dev = q.iter().fold(0.0f64, |m, x| m.max((x - deg).abs()));
        // Measured: at most 1.6e-4 deg over 1 s.
        assert!(dev < 4e-4, "{builtin} at {deg} deg with {f} N: knee moved {dev} deg");
        // ... and 5% less force does not (the check can fail).
        let out = leg_run(&[
            &format!("leg.urdf=\"{builtin}\""),
            "actuator.mode=\"force\"",
            &format!("actuator.force_n={:?}", 0.95 * f),
            &format!("leg.initial_knee_deg={deg:?}"),
        ]);
        let q = knee_deg(&out);
        // Measured: 0.041 deg (exo_leg_small at 0 deg, holding force 1.07 N) to 15.5 deg.
        let dev = q.iter().fold(0.0f64, |m, x| m.max((x - deg).abs()));
        assert!(dev > 0.02, "{builtin} {deg}: 95% of the force also held ({dev} deg)");
    }
}

#[test]
fn free_release_period_and_statics_match_the_reference_through_the_simulator() {
    check_free_and_hold("builtin:exo_leg", "urdf/exo_leg.urdf");
}

#[test]
fn a_second_urdf_passes_the_same_checks() {
    check_free_and_hold("builtin:exo_leg_small", "urdf/exo_leg_small.urdf");
}

#[test]
fn urdf_from_a_file_path_works() {
    let out = leg_run(&[&format!("leg.urdf=\"{}\"", manifest("urdf/exo_leg_small.urdf")), "sim.duration_s=0.2"]);
    let builtin = leg_run(&["leg.urdf=\"builtin:exo_leg_small\"", "sim.duration_s=0.2"]);
    // The file and the embedded copy are the same URDF: the same run, bit for bit.
    assert_eq!(out.record.rows, builtin.record.rows);
}

#[test]
fn paper_cases_on_the_leg_znn_beats_erl_smc_and_the_excess_is_explained() {
    let base = common::leg_scenario(&[]);
    let res = exoleg::study::compare::run_cases(&base, &[]).unwrap();
    // Released from rest at 30 deg, the piston starts with acceleration a0 = dL/dq * q_ddot.
    // Rapier's n symplectic substeps move it by a0*dt^2*(n+1)/(2n) in the first step, as if it
    // had the velocity a0*dt/(2n) at t = 0; the oil spring turns that into an initial force
    // rate -n2*a0*dt/(2n). The ZNN error law then peaks at (A*w + n2*a0*dt/(2n))/(gamma*e).
    let r = RefModel::from_file(&manifest("urdf/exo_leg.urdf"));
    let q0 = 30f64.to_radians();
    let a0 = r.moment_arm(q0) * r.accel(q0, 0.0, 0.0);
    let n2 = exoleg::hydraulics::HydraulicParams::default().coefficients().n2;
    let n = base.file.leg.solver_iterations as f64;
    let rate0 = n2 * a0 * base.file.sim.dt_s / (2.0 * n);
    for pair in res.chunks(2) {
        let (z, s) = (&pair[0], &pair[1]);
        let (ez, es) = (z.max_abs_force_error_n.unwrap(), s.max_abs_force_error_n.unwrap());
        assert!(ez < es, "{:?}: ZNN {ez} vs ERL-SMC {es}", z.case);
        let aw = 200.0 * std::f64::consts::TAU * z.case.frequency_hz;
        let predicted = (aw + rate0) / (z.case.gain * std::f64::consts::E);
        // Measured: within 0.65 % of the prediction (-0.37, -0.65, +0.20, +0.02 %).
        assert!((ez - predicted).abs() < 0.015 * predicted, "{:?}: {ez} N vs predicted {predicted} N", z.case);
    }
}

#[test]
fn coupling_error_shrinks_with_the_step() {
    // The leg-vs-bench excess is a first-order coupling error: it falls with dt.
    let e = |dt: &str| leg_run(&[&format!("sim.dt_s={dt}")]).summary.max_abs_force_error_n;
    let bench = common::run(&[]).summary.max_abs_force_error_n;
    let (e1, e025) = (e("0.001"), e("0.00025"));
    // Measured: 11.44 N at 1 ms, 9.81 N at 0.25 ms, 9.247 N on the bench: the excess shrinks
    // by 0.258 for a 4x smaller step (first order: 0.25).
    let ratio = (e025 - bench) / (e1 - bench);
    assert!(e1 > e025 && e025 > bench, "1 ms {e1}, 0.25 ms {e025}, bench {bench}");
    assert!((0.2..0.32).contains(&ratio), "not first order: {e1} {e025} {bench} (ratio {ratio})");
}

#[test]
fn cuff_interaction_moves_the_knee() {
    let base = ["sim.duration_s=0.5", "controller.kind=\"znn\""];
    let off = leg_run(&base);
    let cuff = leg_run(&[&base[..], &["human.mode=\"cuff\"", "human.k_p=2.0", "human.k_d=0.01"]].concat());
    let w = cuff.record.series(|r| r.interaction_force);
    // Measured: the cuff force reaches 73 N and moves the knee by up to 0.099 deg.
    assert!(w.iter().any(|x| x.abs() > 30.0), "interaction force stays tiny");
    let (q0, q1) = (knee_deg(&off), knee_deg(&cuff));
    let d = q0.iter().zip(&q1).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(d > 0.04, "cuff force did not change the knee trajectory ({d} deg)");
}

#[test]
fn leg_runs_are_bit_identical() {
    let a = leg_run(&["sim.duration_s=0.3"]);
    let b = leg_run(&["sim.duration_s=0.3"]);
    assert_eq!(a.record.rows, b.record.rows);
}

#[test]
fn cuff_link_must_move_with_the_shank() {
    let base = ["sim.duration_s=0.2", "controller.kind=\"znn\"", "human.mode=\"cuff\"", "human.k_p=2.0"];
    // The foot is fixed to the shank: a cuff there (40 cm below the knee in the shank frame).
    let foot = leg_run(&[&base[..], &["human.cuff_link=\"foot\"", "human.cuff_xyz=[0.0, 0.0, 0.0]"]].concat());
    let shank = leg_run(&[&base[..], &["human.cuff_link=\"shank\"", "human.cuff_xyz=[0.0, 0.0, -0.2]"]].concat());
    let (qf, qs) = (knee_deg(&foot), knee_deg(&shank));
    // Measured: the knee trajectories differ by up to 0.143 deg.
    assert!(qf.iter().zip(&qs).any(|(a, b)| (a - b).abs() > 0.05), "a longer lever must act differently");
    let e = common::run_scenario(&common::leg_scenario(&[&base[..], &["human.cuff_link=\"thigh\""]].concat()))
        .err()
        .unwrap();
    assert_eq!(e.exit_code(), 2);
    assert!(e.to_string().contains("human.cuff_link") && e.to_string().contains("fixed to it"), "{e}");
}
