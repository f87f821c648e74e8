//! ZNN force controller (paper Eq. 7-15), optionally with ARBFNN + FDO (paper Eq. 30).

use super::{ControlOutput, Controller, Fdo, Measurement, NominalModel, RbfNetwork, ValveLimit, RBF_NODES};
use crate::reference::RefSample;

/// ZNN with linear activation. With `compensation = Some(..)` it is ARBFNN-FDO-ZNN.
///
/// ```text
/// e1 = x1 - x_d,  e2 = x2 - xd_dot + gamma*e1   (de_i/dt = -gamma*e_i)
/// u  = tau/(n1*k_s) * [ -gamma^2*x1 + (n3 - 2*gamma)*x2 + gamma^2*x_d + 2*gamma*xd_dot
///                       + xd_ddot + n2*xc_ddot + n1*x3/tau - comp ]
/// comp = g_hat + D_hat  (0 for plain ZNN)
/// ```
/// With a perfect model the closed loop is `e1'' + 2*gamma*e1' + gamma^2*e1 = 0`.
/// MODEL.md explains the sign of `comp` (the paper prints `+`).
/// State (ARBFNN-FDO-ZNN only): `[z, W_1..W_7]`.
pub struct Znn {
    model: NominalModel,
    gamma: f64,
    compensation: Option<(RbfNetwork, Fdo)>,
}

impl Znn {
    /// A ZNN controller with design parameter `gamma` (1/s).
    pub fn new(model: NominalModel, gamma: f64, compensation: Option<(RbfNetwork, Fdo)>) -> Self {
        Self { model, gamma, compensation }
    }

    /// The desired dx2/dt of the ZNN design: xd_ddot - 2*gamma*(x2 - xd_dot) - gamma^2*(x1 - x_d).
    fn desired_accel(&self, r: &RefSample, y: &Measurement) -> f64 {
        let g = self.gamma;
        r.accel - 2.0 * g * (y.force_rate_n_per_s - r.rate) - g * g * (y.force_n - r.value)
    }

    fn rbf_input(r: &RefSample, y: &Measurement) -> [f64; 4] {
        let e1 = y.force_n - r.value;
        let e1_dot = y.force_rate_n_per_s - r.rate;
        [y.force_n, y.force_rate_n_per_s, e1, e1_dot]
    }

    /// The output, and with compensation the terms its state derivatives share with it.
    fn output_with(&self, r: &RefSample, y: &Measurement, s: &[f64]) -> (ControlOutput, Option<Shared>) {
        let (comp, g_hat, shared) = match &self.compensation {
            None => (0.0, 0.0, None),
            Some((rbf, fdo)) => {
                let h = rbf.activations(&Self::rbf_input(r, y));
                let g_hat = rbf.output(&h, &s[1..=RBF_NODES]);
                let xi = y.force_rate_n_per_s - s[0];
                let estimate = fdo.estimate(xi);
                (g_hat + estimate, g_hat, Some(Shared { h, xi, estimate }))
            }
        };
        let u = self.model.invert(self.desired_accel(r, y) - comp, y);
        let o = ControlOutput {
            saturated: false,
            valve_command: u,
            disturbance_estimate_n_per_s2: comp,
            rbf_output_n_per_s2: g_hat,
        };
        (o, shared)
    }

    /// The observer's and the weights' rates for output `u`.
    fn compensation_rates(&self, rbf: &RbfNetwork, y: &Measurement, u: &ControlOutput, sh: &Shared, ds: &mut [f64]) {
        // dz/dt = [n1*dx3/dt - n3*x2 - n2*xc_ddot + g_hat] + L*psi(Xi)   (paper Eq. 27)
        ds[0] = self.model.force_accel(u.valve_command, y) + u.rbf_output_n_per_s2 + sh.estimate;
        if u.saturated {
            ds[1..=RBF_NODES].fill(0.0);
        } else {
            rbf.weight_rates(&sh.h, sh.xi, &mut ds[1..=RBF_NODES]);
        }
    }
}

/// What the output and the state derivatives of ARBFNN-FDO-ZNN share at one stage: the RBF
/// activations, the observer's Xi = x2 - z (N/s) and its estimate L*psi(Xi) (N/s^2).
struct Shared {
    h: [f64; RBF_NODES],
    xi: f64,
    estimate: f64,
}

impl Controller for Znn {
    fn kind(&self) -> &'static str {
        if self.compensation.is_some() {
            "arbfnn_fdo_znn"
        } else {
            "znn"
        }
    }

    fn state_len(&self) -> usize {
        if self.compensation.is_some() {
            1 + RBF_NODES
        } else {
            0
        }
    }

    fn state_names(&self) -> Vec<String> {
        if self.compensation.is_some() {
            std::iter::once("observer_z".to_string())
                .chain((1..=RBF_NODES).map(|i| format!("rbf_weight_{i}")))
                .collect()
        } else {
            Vec::new()
        }
    }

    fn init(&self, y: &Measurement, _r: &RefSample, s: &mut [f64]) {
        if self.compensation.is_some() {
            // Xi(0) = x2(0) - z(0) = 0: the observer starts from the first reading; W_hat(0) = 0.
            s[0] = y.force_rate_n_per_s;
            s[1..=RBF_NODES].fill(0.0);
        }
    }

    fn output(&self, _t_s: f64, r: &RefSample, y: &Measurement, s: &[f64]) -> ControlOutput {
        self.output_with(r, y, s).0
    }

    fn output_and_derivatives(
        &self,
        _t_s: f64,
        r: &RefSample,
        y: &Measurement,
        s: &[f64],
        limit: ValveLimit,
        ds: &mut [f64],
    ) -> ControlOutput {
        let (o, shared) = self.output_with(r, y, s);
        let o = limit.apply(o);
        if let (Some((rbf, _)), Some(sh)) = (&self.compensation, shared) {
            self.compensation_rates(rbf, y, &o, &sh, ds);
        }
        o
    }

    /// The observer's `dz/dt` falls with z at `L dpsi/dXi`: its linear, cubic and sigmoid
    /// parts (the `sig(Xi)^r` part is not Lipschitz at 0; explicit steps only chatter on it).
    fn stiffness_per_s(&self, force_rate_n_per_s: f64, s: &[f64]) -> f64 {
        self.compensation.as_ref().map_or(0.0, |(_, fdo)| fdo.lipschitz_slope(force_rate_n_per_s - s[0]))
    }

    fn derivatives(&self, _t_s: f64, r: &RefSample, y: &Measurement, s: &[f64], u: &ControlOutput, ds: &mut [f64]) {
        if let Some((rbf, fdo)) = &self.compensation {
            let xi = y.force_rate_n_per_s - s[0];
            let sh = Shared { h: rbf.activations(&Self::rbf_input(r, y)), xi, estimate: fdo.estimate(xi) };
            self.compensation_rates(rbf, y, u, &sh, ds);
        }
    }

    /// Sampled mode. The observer's `sig(Xi)^(1/r)` term (cubic for r = 1/3) makes forward
    /// Euler unstable as soon as `Ts*L*dpsi/dXi > 2`, which a half-sample lag in the
    /// differentiated load-cell signal reaches within milliseconds at 1 kHz. So the observer
    /// state is advanced with backward Euler (solved by Newton's method; psi is monotonic, so
    /// the solution is unique), as careful firmware would; the weights use the new Xi.
    fn discrete_update(
        &self,
        _t_s: f64,
        ts_s: f64,
        r: &RefSample,
        y: &Measurement,
        s: &mut [f64],
        u: &ControlOutput,
        _scratch: &mut [f64],
    ) {
        let Some((rbf, fdo)) = &self.compensation else { return };
        let x2 = y.force_rate_n_per_s;
        let a = self.model.force_accel(u.valve_command, y) + u.rbf_output_n_per_s2;
        // Solve z1 = z0 + Ts*(a + L*psi(x2 - z1)) for z1.
        let z0 = s[0];
        let mut z = z0 + ts_s * (a + fdo.estimate(x2 - z0));
        for _ in 0..50 {
            let res = z - z0 - ts_s * (a + fdo.estimate(x2 - z));
            let jac = 1.0 + ts_s * fdo.estimate_slope(x2 - z);
            let step = res / jac;
            z -= step;
            if step.abs() <= 1e-12 * (1.0 + z.abs()) {
                break;
            }
        }
        s[0] = z;
        if u.saturated {
            return;
        }
        let xi = x2 - z;
        let h = rbf.activations(&Self::rbf_input(r, y));
        let mut dw = [0.0; RBF_NODES];
        rbf.weight_rates(&h, xi, &mut dw);
        for (w, d) in s[1..=RBF_NODES].iter_mut().zip(dw) {
            *w += ts_s * d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::{ObserverParams, RbfParams};
    use crate::hydraulics::HydraulicParams;

    /// The sampled observer update is backward Euler: the new z satisfies
    /// `z1 = z0 + Ts*(a + L*psi(x2 - z1))` to round-off, even where forward Euler would blow up.
    /// One stage through `output_and_derivatives` gives exactly the output and the rates of the
    /// two separate calls, clipped or not.
    #[test]
    fn shared_stage_equals_the_separate_calls() {
        let model = NominalModel { c: HydraulicParams::default().coefficients() };
        let fdo = Fdo::new(ObserverParams::default());
        let c = Znn::new(model, 100.0, Some((RbfNetwork::new(RbfParams::default()), fdo)));
        let y = Measurement { force_n: 120.0, force_rate_n_per_s: 900.0, spool_m: 1e-5, ..Default::default() };
        let r = RefSample { value: 100.0, rate: 800.0, accel: 30.0 };
        let s = [850.0, 0.3, -0.2, 0.1, 0.0, 0.05, -0.4, 0.2];
        let free = c.output(0.0, &r, &y, &s).valve_command.abs();
        for limit in [ValveLimit(0.0), ValveLimit(0.5 * free)] {
            let (mut d1, mut d2) = ([0.0; 8], [0.0; 8]);
            let o1 = limit.apply(c.output(0.0, &r, &y, &s));
            c.derivatives(0.0, &r, &y, &s, &o1, &mut d1);
            let o2 = c.output_and_derivatives(0.0, &r, &y, &s, limit, &mut d2);
            assert_eq!(o1, o2);
            assert_eq!(d1, d2);
            assert_eq!(o2.saturated, limit.0 > 0.0);
            // The weights move unless the valve saturated.
            assert_eq!(d2[1] == 0.0, o2.saturated);
        }
    }

    #[test]
    fn sampled_observer_step_is_backward_euler() {
        let model = NominalModel { c: HydraulicParams::default().coefficients() };
        let fdo = Fdo::new(ObserverParams::default());
        let c = Znn::new(model, 100.0, Some((RbfNetwork::new(RbfParams::default()), fdo.clone())));
        let y = Measurement { force_n: 120.0, force_rate_n_per_s: 900.0, spool_m: 1e-5, ..Default::default() };
        let r = RefSample { value: 100.0, rate: 800.0, accel: 0.0 };
        let mut s = [0.0; 8];
        c.init(&y, &r, &mut s);
        s[0] -= 60.0; // Xi = 60: forward Euler at 1 ms would take ts*3*L*Xi^2 = 10.8 > 2 (unstable).
        let u = c.output(0.0, &r, &y, &s);
        let (ts, z0) = (1e-3, s[0]);
        c.discrete_update(0.0, ts, &r, &y, &mut s, &u, &mut [0.0; 8]);
        let a = model.force_accel(u.valve_command, &y) + u.rbf_output_n_per_s2;
        let residual = s[0] - z0 - ts * (a + fdo.estimate(y.force_rate_n_per_s - s[0]));
        assert!(residual.abs() < 1e-9 * (1.0 + s[0].abs()), "residual {residual}");
        // Forward Euler's step would not satisfy the implicit equation (so the check can fail).
        let z_fe = z0 + ts * (a + fdo.estimate(y.force_rate_n_per_s - z0));
        let residual_fe = z_fe - z0 - ts * (a + fdo.estimate(y.force_rate_n_per_s - z_fe));
        assert!(residual_fe.abs() > 1.0, "forward Euler residual {residual_fe}");
    }
}
