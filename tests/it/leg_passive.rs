//! Test 1 (and 3 for the second URDF): passive release from 30 deg, zero actuator force.
use crate::common::leg_reference::*;

use exoleg::leg::*;

fn passive_check(urdf: &str) {
    let path = manifest(urdf);
    let model = LegSpec::from_urdf_file(&path, "knee").unwrap();
    let r = RefModel::from_file(&path);
    let th0 = 30f64.to_radians();
    let dt = 1e-3;
    let t_end = 5.0;

    // Reference: exact closed-chain EOM reduced to the knee angle, RK4 at 0.1 ms.
    let ref_samples = r.simulate(th0, 1e-4, t_end);
    let (t_ref, n_ref) = mean_period(&ref_samples);

    // Oscillation energy scale: V(theta0) - min V over the swing.
    let vmin = ref_samples.iter().map(|&(_, q)| r.potential(q)).fold(f64::INFINITY, f64::min);
    let de_osc = r.potential(th0) - vmin;

    let mut leg = Leg::new(&model, th0, dt).unwrap();
    let e0 = leg.total_energy_j();
    assert!(
        (e0 - r.potential(th0)).abs() < 1e-9 * e0.abs().max(1.0),
        "initial energy {e0} vs reference {}",
        r.potential(th0)
    );
    let mut samples = vec![(0.0, leg.knee_angle_rad())];
    let mut max_gap: f64 = leg.loop_gap_m();
    let mut max_de: f64 = 0.0;
    let mut max_marm_err: f64 = 0.0;
    let mut max_vel_err: f64 = 0.0;
    let steps = (t_end / dt).round() as usize;
    for _ in 0..steps {
        let q_before = leg.knee_angle_rad();
        let l_before = leg.cylinder_length_m();
        leg.step(0.0, None);
        let q = leg.knee_angle_rad();
        samples.push((leg.time_s(), q));
        max_gap = max_gap.max(leg.loop_gap_m());
        max_de = max_de.max((leg.total_energy_j() - e0).abs());
        // Moment arm from the simulation: finite difference of measured length vs knee angle.
        let dq = q - q_before;
        if dq.abs() > 1e-3 {
            let marm_sim = (leg.cylinder_length_m() - l_before) / dq;
            let marm_ref = r.moment_arm(0.5 * (q + q_before));
            max_marm_err = max_marm_err.max(((marm_sim - marm_ref) / marm_ref).abs());
            let v_ref = marm_ref * leg.knee_velocity_geometric_rad_s();
            max_vel_err = max_vel_err.max(((leg.cylinder_velocity_m_s() - v_ref) / v_ref).abs());
        }
    }
    let (t_sim, n_sim) = mean_period(&samples);
    let period_err = (t_sim - t_ref) / t_ref;
    println!(
        "[{urdf}] period ref {t_ref:.6} s ({n_ref} maxima), sim {t_sim:.6} s ({n_sim} maxima), rel err {:.4}%",
        100.0 * period_err
    );
    println!("[{urdf}] max loop gap {max_gap:.3e} m");
    println!(
        "[{urdf}] max |E-E0| {max_de:.3e} J = {:.4}% of oscillation energy {de_osc:.4} J ({:.2e} of |E0| {:.3} J)",
        100.0 * max_de / de_osc,
        max_de / e0.abs(),
        e0
    );
    println!(
        "[{urdf}] moment arm (sim FD vs law of cosines) max rel err {:.3e}; cylinder velocity max rel err {:.3e}",
        max_marm_err, max_vel_err
    );
    // Measured (exo_leg / exo_leg_small): period -5.8e-6 / -1.3e-5, gap 6.8e-8 / 8.6e-8 m,
    // energy excursion 0.19 % / 0.26 % of the swing energy, moment arm and cylinder velocity
    // within 1.2e-5 / 1.1e-5.
    assert!(period_err.abs() < 3e-5, "period error {period_err}");
    assert!(max_gap < 2e-7, "gap {max_gap}");
    assert!(max_de / de_osc < 0.006, "energy drift {max_de} J vs oscillation energy {de_osc} J");
    assert!(max_marm_err < 3e-5, "moment arm error {max_marm_err}");
    assert!(max_vel_err < 3e-5, "cylinder velocity error {max_vel_err}");
}

#[test]
fn passive_release_exo_leg() {
    passive_check("urdf/exo_leg.urdf");
}

#[test]
fn passive_release_second_urdf() {
    passive_check("urdf/exo_leg_small.urdf");
}
