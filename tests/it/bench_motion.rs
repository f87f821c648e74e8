//! The n2*xc_dot path of the force ODE, exercised by the bench's prescribed piston motion.

use crate::common;
use exoleg::hydraulics::{ForceChannelInput, ForceChannelState, HydraulicParams};
use exoleg::sim::Integrator;

/// Open loop (u = 0, spool centred), piston moving x_c = a sin(wt): the force obeys
/// dF/dt = -n2 a w cos(wt) - n3 F, whose exact solution is checked at t = 1 s.
#[test]
fn open_loop_force_from_piston_motion_matches_the_exact_solution() {
    let c = HydraulicParams::default().coefficients();
    let (a, w) = (1e-3, std::f64::consts::TAU * 1.0);
    let dt = 1e-4;
    let mut x = [0.0, 0.0, 0.0];
    for k in 0..10_000 {
        x = Integrator::Rk4.step(k as f64 * dt, dt, &x, |t, x| {
            let s = ForceChannelState { force_n: x[0], spool_m: x[1], accel_dist_n_per_s: x[2] };
            let inp = ForceChannelInput { piston_velocity_m_s: a * w * (w * t).cos(), ..Default::default() };
            let d = c.derivatives(&s, &inp);
            [d.force_n, d.spool_m, d.accel_dist_n_per_s]
        });
    }
    // F(t) = -n2 a w [n3 cos wt + w sin wt - n3 e^{-n3 t}] / (n3^2 + w^2)
    let t = 1.0;
    let exact =
        -c.n2 * a * w * (c.n3 * (w * t).cos() + w * (w * t).sin() - c.n3 * (-c.n3 * t).exp()) / (c.n3 * c.n3 + w * w);
    // Measured: 3.5e-10 N off a -22.46 N exact value (RK4 at 0.1 ms).
    assert!((x[0] - exact).abs() < 1e-9, "{} vs {exact}", x[0]);
    assert!(exact.abs() > 10.0, "the motion must load the channel: {exact} N");
}

/// With the piston moving, ZNN's n2*xc_ddot feed-forward keeps tracking as good as on a
/// still bench; a controller that is told the wrong piston area cannot.
#[test]
fn znn_compensates_piston_motion() {
    let moving = [
        "bench.motion=\"sine\"",
        "bench.amplitude_m=1e-3",
        "bench.frequency_hz=2.0",
        "controller.kind=\"znn\"",
        "metrics.settle_s=0.2",
    ];
    let still = common::run(&["controller.kind=\"znn\"", "metrics.settle_s=0.2"]).summary;
    let m = common::run(&moving).summary;
    // Measured: 0.00115 N moving vs 0.00114 N still (+1 %).
    let (mv, st) = (m.max_abs_force_error_after_settle_n, still.max_abs_force_error_after_settle_n);
    assert!(mv < 1.03 * st, "moving {mv} vs still {st}");
    let wrong = common::run(&[&moving[..], &["controller.nominal.a2_m2=1.5e-4"]].concat()).summary;
    // Measured: 17.4 N with A2 27 % low: the n2*xc_ddot feed-forward is what tracks the motion.
    assert!(wrong.max_abs_force_error_after_settle_n > 7.0, "{}", wrong.max_abs_force_error_after_settle_n);
}
