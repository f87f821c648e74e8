//! Test 2 (and 3 for the second URDF): statics. The holding force F = (dV/dtheta)/(dL/dtheta)
//! from the independent reference equals (a) the library's pure-geometry answer and (b) the force
//! that gives zero knee acceleration in the Rapier simulation; applying it holds the knee still.
use crate::common::leg_reference::*;

use exoleg::leg::*;

/// Knee velocity after one step from rest at `th` with actuator force `f`.
fn one_step_vel(model: &LegSpec, th: f64, f: f64) -> f64 {
    let mut leg = Leg::new(model, th, 1e-3).unwrap();
    leg.step(f, None);
    leg.knee_velocity_rad_s()
}

fn statics_check(urdf: &str) {
    let path = manifest(urdf);
    let model = LegSpec::from_urdf_file(&path, "knee").unwrap();
    let r = RefModel::from_file(&path);
    for deg in [0.0f64, 30.0, 60.0, 90.0] {
        let th = deg.to_radians();
        // Independent reference (virtual work).
        let f_ref = r.holding_force(th);
        // Library pure helpers.
        let f_lib = holding_force_at(&model, th).unwrap();
        let marm_lib = moment_arm_at(&model, th);
        let marm_ref = r.moment_arm(th);
        // Measured: moment arm within 4.3e-10, length within 2.1e-16 (relative).
        assert!(((marm_lib - marm_ref) / marm_ref).abs() < 1e-9, "{deg} deg: moment arm lib {marm_lib} ref {marm_ref}");
        assert!(((cylinder_length_at(&model, th) - r.length(th)) / r.length(th)).abs() < 1e-15);
        // Simulation: the knee response is affine in F; solve for zero velocity after one step.
        let v0 = one_step_vel(&model, th, 0.0);
        let v1 = one_step_vel(&model, th, f_ref);
        let f_sim = f_ref * v0 / (v0 - v1);
        let err_lib = (f_lib - f_ref) / f_ref;
        let err_sim = (f_sim - f_ref) / f_ref;
        // Hold for 1 s with the reference force.
        let mut leg = Leg::new(&model, th, 1e-3).unwrap();
        let mut max_dev: f64 = 0.0;
        for _ in 0..1000 {
            leg.step(f_ref, None);
            max_dev = max_dev.max((leg.knee_angle_rad() - th).abs());
        }
        println!(
            "[{urdf}] {deg:>4} deg: dL/dth {marm_ref:+.5} m/rad, F_ref {f_ref:+.4} N, lib err {:.2e}%, sim F {f_sim:+.4} N err {:.4}%, 1 s hold max dev {:.2e} deg",
            100.0 * err_lib,
            100.0 * err_sim,
            max_dev.to_degrees()
        );
        // Measured: library within 1.7e-8, simulation within 2.3e-7 (relative), hold within
        // 1.6e-4 deg.
        assert!(err_lib.abs() < 5e-8, "library holding force error {err_lib}");
        assert!(err_sim.abs() < 6e-7, "simulated holding force error {err_sim}");
        assert!(max_dev.to_degrees() < 4e-4, "knee drifted {} deg", max_dev.to_degrees());
    }
}

#[test]
fn statics_exo_leg() {
    statics_check("urdf/exo_leg.urdf");
}

#[test]
fn statics_second_urdf() {
    statics_check("urdf/exo_leg_small.urdf");
}

/// An external force on the shank (human cuff) is balanced by the matching actuator force.
#[test]
fn cuff_force_balanced_by_actuator() {
    let path = manifest("urdf/exo_leg.urdf");
    let model = LegSpec::from_urdf_file(&path, "knee").unwrap();
    let r = RefModel::from_file(&path);
    let th = 45f64.to_radians();
    // 50 N horizontal push (+x) at a cuff 0.25 m below the knee on the shank axis.
    let p = [0.0, 0.0, -0.25];
    let f = [50.0, 0.0, 0.0];
    // Torque about the knee (+y): tau = (r x F)_y = z F_x - x F_z with r = cuff - knee in world.
    let (s, c) = th.sin_cos();
    let (rx, rz) = (p[0] * c + p[2] * s, -p[0] * s + p[2] * c);
    let tau = rz * f[0] - rx * f[2];
    let f_act = (r.dv(th) - tau) / r.moment_arm(th);
    let mut leg = Leg::new(&model, th, 1e-3).unwrap();
    let mut max_dev: f64 = 0.0;
    for _ in 0..1000 {
        leg.step(f_act, Some((p, f)));
        max_dev = max_dev.max((leg.knee_angle_rad() - th).abs());
    }
    println!("cuff: tau {tau:+.3} N m, actuator {f_act:+.2} N, max dev {:.2e} deg", max_dev.to_degrees());
    // Measured: 2.85e-3 deg.
    assert!(max_dev.to_degrees() < 7e-3, "{}", max_dev.to_degrees());
}
