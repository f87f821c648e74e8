//! Discrete-time ZNN force control for 1 kHz firmware (`controller.kind = "dtznn"`), the design
//! of `shared/spec/DISCRETE.md`:
//!
//! ```text
//! model   x = [F, x_v, q, D (, r1, r2)]       dF/dt = n1 x_v - n2 v - n3 F + q (+ r1)
//!                                             dx_v/dt = (k_s u - x_v)/tau,  dq/dt = D,  dD/dt = 0
//!                                             (resonator: r1' = r2, r2' = -w_r^2 r1)
//! sampled exactly at h: u held (ZOH), the piston velocity v ramped (first-order hold,
//!         extrapolated linearly from the last two readings)
//! estimate x(t_{k-d}) with a steady-state Kalman gain L (DARE) from the d-samples-old force
//!         (and spool) readings, then predict d samples ahead with the stored commands
//! preview u_ff = (F_d(t_{k+1}) - Phi_FF F_d(t_k) - Phi_Fx xv_r - G_F(v)) / Gamma_F;
//!         xv_r <- Phi_xx xv_r + Gamma_x u_ff      (the reference state of the sampled model)
//! Zhang   s = c . (x_hat - x_ref), c = [gamma - n3, n1, 1, 0 (, 1, 0)];  s_{k+1} = exp(-gamma h) s_k
//!         u = u_ff - K (x_hat - x_ref),  K = (c Phi - exp(-gamma h) c) / (c Gamma)
//! ```
//! The controller never differences the load cell: the rate comes from the model state. The q,
//! D (and resonator) entries of K cancel the estimated disturbance. With
//! `controller.observer = "fdo"` the disturbance derivative D comes instead from a discrete
//! fixed-time observer on the estimated q (its cubic gain capped at 300 1/s), for comparison.

use super::discretize::{kalman_gain, SampledLti as SampledModel};
use super::{
    ControlOutput, ControlStop, DiscreteController, EstimatorKind, Fdo, NominalModel, SampleInput, ValveLimit,
};
use nalgebra::{DMatrix, DVector};

use std::collections::VecDeque;

/// What the firmware knows of its sensors (for the Kalman measurement noise).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorModel {
    /// Load-cell standard deviation (N): noise and quantisation (LSB/sqrt(12)).
    pub force_sd_n: f64,
    /// Spool sensor standard deviation (m), None without a spool sensor.
    pub spool_sd_m: Option<f64>,
}

/// Settings of `dtznn`.
#[derive(Debug, Clone, PartialEq)]
pub struct DtZnnSettings {
    /// ZNN design parameter gamma (1/s): closed-loop poles near exp(-gamma h).
    pub gamma: f64,
    /// Sample period h (s).
    pub period_s: f64,
    /// Delay (samples) the controller assumes in its readings.
    pub delay_samples: usize,
    /// Process noise spectral densities of [F, x_v, q, D] (units^2/s).
    pub process_noise: [f64; 4],
    /// Internal model of a periodic reference at this frequency (Hz), 0 = off.
    pub resonator_hz: f64,
    /// Disturbance estimator.
    pub estimator: EstimatorKind,
    /// The sensors.
    pub sensors: SensorModel,
    /// Valve command limit.
    pub limit: ValveLimit,
}

/// The dtznn controller (a [`DiscreteController`]).
#[derive(Debug, Clone)]
pub struct DtZnn {
    model: SampledModel,
    n: usize,
    c_meas: DMatrix<f64>,
    l: DMatrix<f64>,
    k: DVector<f64>,
    lambda: f64,
    s: DtZnnSettings,
    nominal: NominalModel,
    fdo: Option<(Fdo, f64)>,
    // -- state --
    prior: Option<DVector<f64>>,
    delayed: DVector<f64>,
    estimate: DVector<f64>,
    commands: VecDeque<f64>,
    /// The d-step prediction in closed form (cost independent of the delay).
    ahead: Ahead,
    v_prev: Option<f64>,
    xv_ref: f64,
    iterations: usize,
    /// Vectors a sample reuses (no allocation per sample).
    scratch: Scratch,
}

/// The vectors one sample works in: the measurement `y`, a measurement-sized product, and
/// three state-sized ones.
#[derive(Debug, Clone)]
struct Scratch {
    y: DVector<f64>,
    ym: DVector<f64>,
    n1: DVector<f64>,
    n2: DVector<f64>,
    n3: DVector<f64>,
}

impl Scratch {
    fn new(m: usize, n: usize) -> Self {
        Self {
            y: DVector::zeros(m),
            ym: DVector::zeros(m),
            n1: DVector::zeros(n),
            n2: DVector::zeros(n),
            n3: DVector::zeros(n),
        }
    }
}

/// Continuous model matrices (A, B, E) of the controller's state.
fn continuous_model(
    c: &crate::hydraulics::Coefficients,
    resonator_hz: f64,
) -> (DMatrix<f64>, DVector<f64>, DVector<f64>) {
    let n = if resonator_hz > 0.0 { 6 } else { 4 };
    let mut a = DMatrix::zeros(n, n);
    a[(0, 0)] = -c.n3;
    a[(0, 1)] = c.n1;
    a[(0, 2)] = 1.0;
    a[(1, 1)] = -1.0 / c.tau_s;
    a[(2, 3)] = 1.0;
    if n == 6 {
        let w = std::f64::consts::TAU * resonator_hz;
        a[(0, 4)] = 1.0;
        a[(4, 5)] = 1.0;
        a[(5, 4)] = -w * w;
    }
    let mut b = DVector::zeros(n);
    b[1] = c.k_s / c.tau_s;
    let mut e = DVector::zeros(n);
    e[0] = -c.n2;
    (a, b, e)
}

impl DtZnn {
    /// Design the controller from its nominal model: sampled model, Kalman gain, Zhang gain.
    /// Errors when the design is impossible (the Riccati iteration does not converge).
    pub fn new(nominal: NominalModel, s: DtZnnSettings) -> Result<Self, String> {
        let c = &nominal.c;
        let (a, b, e) = continuous_model(c, s.resonator_hz);
        let n = a.nrows();
        let h = s.period_s;
        let model = SampledModel::new(&a, &b, &e, h);
        // Measurements: force, and spool when there is a sensor.
        let m = if s.sensors.spool_sd_m.is_some() { 2 } else { 1 };
        let mut c_meas = DMatrix::zeros(m, n);
        c_meas[(0, 0)] = 1.0;
        let mut r = DMatrix::zeros(m, m);
        r[(0, 0)] = s.sensors.force_sd_n.max(1e-6).powi(2);
        if let Some(sd) = s.sensors.spool_sd_m {
            c_meas[(1, 1)] = 1.0;
            r[(1, 1)] = sd.max(1e-12).powi(2);
        }
        let mut qd = vec![s.process_noise[0], s.process_noise[1], s.process_noise[2], s.process_noise[3]];
        if s.estimator == EstimatorKind::Fdo {
            qd[3] = 0.0; // D comes from the FDO, not from the Kalman filter
        }
        if n == 6 {
            qd.extend([0.0, s.process_noise[3]]);
        }
        let q = DMatrix::from_diagonal(&DVector::from_vec(qd)) * h;
        let (l, _, iterations) =
            kalman_gain(&model.phi, &c_meas, &q, &r, 200).ok_or("the Kalman (Riccati) iteration did not converge")?;
        let mut cz = DVector::zeros(n);
        cz[0] = s.gamma - c.n3;
        cz[1] = c.n1;
        cz[2] = 1.0;
        if n == 6 {
            cz[4] = 1.0;
        }
        let lambda = (-s.gamma * h).exp();
        let cg = cz.dot(&model.gamma);
        if cg.abs() < 1e-300 {
            return Err("the valve does not reach the force within one sample (c . Gamma = 0)".into());
        }
        let k = (model.phi.transpose() * &cz - &cz * lambda) / cg;
        let fdo = (s.estimator == EstimatorKind::Fdo).then(|| (Fdo::new(super::ObserverParams::default()), 0.0));
        let commands = VecDeque::from(vec![0.0; s.delay_samples]);
        let ahead = Ahead::new(&model, s.delay_samples);
        Ok(Self {
            model,
            n,
            c_meas,
            l,
            k,
            lambda,
            s,
            nominal,
            fdo,
            prior: None,
            delayed: DVector::zeros(n),
            estimate: DVector::zeros(n),
            commands,
            ahead,
            v_prev: None,
            xv_ref: 0.0,
            iterations,
            scratch: Scratch::new(m, n),
        })
    }

    /// The ZNN design parameter gamma (1/s).
    pub fn gamma(&self) -> f64 {
        self.s.gamma
    }

    /// Start: the state estimate from the first reading, the reference state consistent with
    /// the reference's rate (`xv_r = (dF_d/dt + n3 F_d + n2 v)/n1`).
    fn start(&mut self, inp: &SampleInput, v: f64) {
        let c = &self.nominal.c;
        self.xv_ref = (inp.r.rate + c.n3 * inp.r.value + c.n2 * v) / c.n1;
        let mut x = DVector::zeros(self.n);
        x[0] = inp.y.force_n;
        x[1] = if self.s.sensors.spool_sd_m.is_some() { inp.y.spool_m } else { self.xv_ref };
        // Before t = 0 the valve was held where it is: the commands in flight hold the spool.
        let hold = x[1] / c.k_s;
        self.commands.iter_mut().for_each(|u| *u = hold);
        self.ahead.reset(&self.model, &self.commands);
        self.prior = Some(x);
    }

    /// Correct the prior of x(t_{k-d}) with the readings, predict to t_k; keep the next prior.
    /// In place, with the products and sums in the order of the expressions
    /// `innovation = y - C prior`, `delayed = prior + L innovation` (the same bits).
    fn estimate(&mut self, inp: &SampleInput, v: f64, slope: f64) {
        let sc = &mut self.scratch;
        sc.y[0] = inp.y.force_n;
        if sc.y.len() > 1 {
            sc.y[1] = inp.y.spool_m;
        }
        let prior = self.prior.get_or_insert_with(|| DVector::zeros(self.n));
        self.c_meas.mul_to(prior, &mut sc.ym);
        for (i, y) in sc.y.iter().enumerate() {
            sc.ym[i] = y - sc.ym[i];
        }
        self.l.mul_to(&sc.ym, &mut sc.n1);
        for (i, p) in prior.iter().enumerate() {
            self.delayed[i] = p + sc.n1[i];
        }
        if let Some((fdo, z)) = &mut self.fdo {
            // Discrete FDO on q: D_hat = L psi(Xi), Xi = q_hat - z, backward-Euler-free capped gain.
            let xi = self.delayed[2] - *z;
            let d_hat = capped_estimate(fdo, xi);
            *z += self.s.period_s * d_hat;
            self.delayed[3] = d_hat;
        }
        self.ahead.predict_into(&self.model, &self.delayed, v, slope, self.s.period_s, &mut self.estimate, sc);
    }
}

/// The state d samples ahead of the delayed estimate, with the d commands in flight and the
/// piston velocity ramped: `Phi^d x + S_u + A (G0 v + G1 slope) + B G0 slope h`, where
/// `S_u = sum_j Phi^(d-1-j) Gamma u_j` (oldest command first), `A = sum_m Phi^m` and
/// `B = sum_m (d-1-m) Phi^m` (m < d). `S_u` is kept by the recurrence
/// `S_u' = Phi S_u - Phi^d Gamma u_oldest + Gamma u_new` and recomputed exactly every d
/// samples, so a sample costs the same for any delay (d up to 100,000).
#[derive(Debug, Clone)]
struct Ahead {
    d: usize,
    phi_d: DMatrix<f64>,
    phi_d_gamma: DVector<f64>,
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    s_u: DVector<f64>,
    since_exact: usize,
}

impl Ahead {
    fn new(m: &SampledModel, d: usize) -> Self {
        let n = m.phi.nrows();
        let (mut a, mut b) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        let mut p = DMatrix::<f64>::identity(n, n);
        for k in 0..d {
            a += &p;
            b += &p * (d - 1 - k) as f64;
            p = &m.phi * p;
        }
        let phi_d_gamma = &p * &m.gamma;
        Self { d, phi_d: p, phi_d_gamma, a, b, s_u: DVector::zeros(n), since_exact: 0 }
    }

    /// `S_u` of the commands in flight, summed exactly.
    fn reset(&mut self, m: &SampledModel, commands: &VecDeque<f64>) {
        let mut s = DVector::zeros(m.phi.nrows());
        for u in commands {
            s = &m.phi * s + &m.gamma * *u;
        }
        self.s_u = s;
        self.since_exact = 0;
    }

    /// The oldest command `old` left the queue and `new` entered it (`commands` is the queue now).
    fn shift(&mut self, m: &SampledModel, old: f64, new: f64, commands: &VecDeque<f64>, tmp: &mut DVector<f64>) {
        self.since_exact += 1;
        if self.since_exact >= self.d {
            self.reset(m, commands);
        } else {
            // S_u = Phi S_u - Phi^d Gamma old + Gamma new, in that order.
            m.phi.mul_to(&self.s_u, tmp);
            for i in 0..tmp.len() {
                self.s_u[i] = (tmp[i] - self.phi_d_gamma[i] * old) + m.gamma[i] * new;
            }
        }
    }

    /// Into `out`: the state d samples after `x` (the delayed estimate) with velocity `v`
    /// ramped at `slope`, `Phi^d x + S_u + A w + B (G0 slope h)` with `w = G0 v + G1 slope`,
    /// summed left to right.
    #[allow(clippy::too_many_arguments)]
    fn predict_into(
        &self,
        m: &SampledModel,
        x: &DVector<f64>,
        v: f64,
        slope: f64,
        h: f64,
        out: &mut DVector<f64>,
        sc: &mut Scratch,
    ) {
        if self.d == 0 {
            out.copy_from(x);
            return;
        }
        for i in 0..sc.n1.len() {
            sc.n1[i] = m.g0[i] * v + m.g1[i] * slope;
            sc.n2[i] = m.g0[i] * (slope * h);
        }
        self.a.mul_to(&sc.n1, &mut sc.n3);
        self.b.mul_to(&sc.n2, &mut sc.n1);
        self.phi_d.mul_to(x, out);
        for i in 0..out.len() {
            out[i] = ((out[i] + self.s_u[i]) + sc.n3[i]) + sc.n1[i];
        }
    }
}

/// The FDO's estimate with the local gain of its cubic term capped at 300 1/s: beyond
/// |Xi| = 10 the cubic continues along its tangent.
fn capped_estimate(fdo: &Fdo, xi: f64) -> f64 {
    const XI_CAP: f64 = 10.0;
    if xi.abs() <= XI_CAP {
        return fdo.estimate(xi);
    }
    let edge = XI_CAP.copysign(xi);
    fdo.estimate(edge) + fdo.estimate_slope(edge) * (xi - edge)
}

impl DiscreteController for DtZnn {
    fn kind(&self) -> &str {
        "dtznn"
    }

    fn update(&mut self, inp: &SampleInput) -> Result<ControlOutput, ControlStop> {
        let h = self.s.period_s;
        let d = self.s.delay_samples as f64;
        // The piston velocity reading is d samples old; extrapolate it linearly.
        let v = inp.y.piston_velocity_m_s;
        let slope = self.v_prev.map_or(0.0, |p| (v - p) / h);
        self.v_prev = Some(v);
        if self.prior.is_none() {
            self.start(inp, v + slope * d * h);
        }
        self.estimate(inp, v, slope);
        // Reference preview through the sampled model.
        let v_now = v + slope * d * h;
        let (phi, gam) = (&self.model.phi, &self.model.gamma);
        let g_v = self.model.g0[0] * v_now + self.model.g1[0] * slope;
        let u_ff = (inp.r_next.value - phi[(0, 0)] * inp.r.value - phi[(0, 1)] * self.xv_ref - g_v) / gam[0];
        let eps = &mut self.scratch.n1;
        eps.copy_from(&self.estimate);
        eps[0] -= inp.r.value;
        eps[1] -= self.xv_ref;
        let u = self.s.limit.apply(ControlOutput { valve_command: u_ff - self.k.dot(eps), ..Default::default() });
        self.xv_ref = phi[(1, 1)] * self.xv_ref + gam[1] * u_ff;
        // The next prior: x(t_{k-d+1}) from the command applied over [t_{k-d}, t_{k-d+1}).
        let oldest = match self.commands.pop_front() {
            Some(old) => {
                self.commands.push_back(u.valve_command);
                self.ahead.shift(&self.model, old, u.valve_command, &self.commands, &mut self.scratch.n2);
                old
            }
            None => u.valve_command,
        };
        let prior = self.prior.get_or_insert_with(|| DVector::zeros(self.n));
        self.model.step_into(&self.delayed, oldest, v, slope, prior);
        // The lumped disturbance on dx2/dt the model estimates: D (+ r2 with the resonator).
        let d_hat = self.estimate[3] + if self.n == 6 { self.estimate[5] } else { 0.0 };
        Ok(ControlOutput { disturbance_estimate_n_per_s2: d_hat, rbf_output_n_per_s2: 0.0, ..u })
    }

    fn first_non_finite(&self) -> Option<(String, f64)> {
        let names = [
            "estimate_force_n",
            "estimate_spool_m",
            "estimate_q_n_per_s",
            "estimate_d_n_per_s2",
            "resonator_1",
            "resonator_2",
        ];
        let i = self.estimate.iter().position(|v| !v.is_finite())?;
        Some((names[i].to_string(), self.estimate[i]))
    }

    fn design(&self) -> Option<serde_json::Value> {
        let v = |x: &DVector<f64>| x.iter().copied().collect::<Vec<f64>>();
        let l: Vec<Vec<f64>> = (0..self.l.ncols()).map(|j| self.l.column(j).iter().copied().collect()).collect();
        let states = ["F (N)", "x_v (m)", "q (N/s)", "D (N/s^2)", "resonator r1 (N/s)", "resonator r2 (N/s^2)"];
        Some(serde_json::json!({
            "states": &states[..self.n],
            "sample_period_s": self.s.period_s,
            "delay_samples": self.s.delay_samples,
            "estimator": self.s.estimator,
            "zhang_pole": self.lambda,
            "zhang_gain_k": v(&self.k),
            "kalman_gain_l_per_measurement": l,
            "measurements": if self.c_meas.nrows() == 2 { vec!["force", "spool"] } else { vec!["force"] },
            "riccati_iterations": self.iterations,
            "phi": (0..self.n).map(|i| self.model.phi.row(i).iter().copied().collect::<Vec<f64>>()).collect::<Vec<_>>(),
            "gamma": v(&self.model.gamma),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hydraulics::HydraulicParams;

    /// The closed-form d-step prediction equals the step-by-step one, also after many shifts
    /// of the command queue (the recurrence and its periodic exact reset).
    #[test]
    fn prediction_ahead_matches_stepping() {
        let c = HydraulicParams::default().coefficients();
        let (a, b, e) = continuous_model(&c, 0.0);
        let m = SampledModel::new(&a, &b, &e, 1e-3);
        let d = 37;
        let mut q: VecDeque<f64> = (0..d).map(|j| 1e-4 * ((j as f64) * 0.7).sin()).collect();
        let mut ahead = Ahead::new(&m, d);
        ahead.reset(&m, &q);
        let x0 = DVector::from_vec(vec![120.0, 2e-5, 300.0, -5.0]);
        let (v, slope, h) = (0.02, -0.3, 1e-3);
        let direct = |q: &VecDeque<f64>| {
            let mut x = x0.clone();
            for (j, u) in q.iter().enumerate() {
                x = m.step(&x, *u, v + slope * j as f64 * h, slope);
            }
            x
        };
        let close = |a: &DVector<f64>, b: &DVector<f64>| (a - b).amax() <= 1e-9 * b.amax();
        let mut sc = Scratch::new(1, 4);
        let mut predict = |ahead: &Ahead| {
            let mut out = DVector::zeros(4);
            ahead.predict_into(&m, &x0, v, slope, h, &mut out, &mut sc);
            out
        };
        assert!(close(&predict(&ahead), &direct(&q)));
        let mut tmp = DVector::zeros(4);
        for k in 0..100 {
            let new = 1e-4 * (k as f64 * 0.3).cos();
            let old = q.pop_front().unwrap();
            q.push_back(new);
            ahead.shift(&m, old, new, &q, &mut tmp);
            assert!(close(&predict(&ahead), &direct(&q)), "after {} shifts", k + 1);
        }
    }
}
