//! The co-simulation loop: wires reference, sensors, controller, hydraulics and plant.
//!
//! One fixed step of size `dt` from `t_k` (pseudocode):
//!
//! ```text
//! if sampled mode and t_k is a sample instant:          // zero-order hold
//!     y      = sensors.sample(truth(t_k))                // plant -> controller
//!     u_hold = controller.output(t_k, ref(t_k), y, s)
//!     s     += Ts * controller.derivatives(...)          // firmware: forward Euler
//! integrate x = [F_L, x_v, r, s...] over [t_k, t_k+dt] with the chosen RK scheme;
//! at every stage tau:
//!     piston = plant.piston_at(tau)                      // prescribed or held from the leg
//!     x2     = dF_L/dt from the force ODE (no u needed)
//!     u      = continuous ? controller.output(tau, ref(tau), ideal y, s) : u_hold
//!     derivatives of the force channel (+ controller state in continuous mode)
//! F_f = friction(piston velocity);  plant.advance(t_k, dt, F_L - F_f)
//! check every state is finite (else Error::Diverged naming the state and time)
//! record(t_{k+1}, ...)
//! ```
//! Row 0 of the record is the initial state at t = 0, so a run has `steps + 1` rows.

use crate::control::{
    self, ControlOutput, Controller, ControllerGains, Measurement, NominalModel, MAX_CONTROLLER_STATES,
};
use crate::disturbance::{Disturbances, CHANNEL_FORCE_ACCEL, CHANNEL_FORCE_RATE, CHANNEL_SPOOL};
use crate::error::{Error, Result};
use crate::human::{HumanMode, HumanParams};
use crate::hydraulics::{Coefficients, ForceChannelInput, ForceChannelState, FrictionParams};
use crate::metrics::{self, Summary};
use crate::plant::{Bench, Plant, PlantKind};
use crate::reference::{RefSample, Sine};
use crate::scenario::{ReferenceKind, Scenario};
use crate::sensors::{SampledSensors, Truth};

/// Hydraulic states in the integrated vector: F_L, x_v, r.
const NH: usize = 3;
/// Length of the integrated state vector.
const NX: usize = NH + MAX_CONTROLLER_STATES;
type X = [f64; NX];

/// Recorded time series, one entry per row (column-major). Units in the field names.
#[derive(Debug, Clone, Default)]
pub struct Record {
    /// Time (s).
    pub t_s: Vec<f64>,
    /// Desired force F_d (N).
    pub ref_force_n: Vec<f64>,
    /// dF_d/dt (N/s).
    pub ref_force_rate_n_per_s: Vec<f64>,
    /// Load force F_L (N).
    pub load_force_n: Vec<f64>,
    /// Tracking error F_L - F_d (N).
    pub force_error_n: Vec<f64>,
    /// True dF_L/dt (N/s).
    pub force_rate_n_per_s: Vec<f64>,
    /// Valve command u (held value in sampled mode).
    pub valve_command: Vec<f64>,
    /// Spool position x_v (m).
    pub spool_m: Vec<f64>,
    /// Piston position x_c (m).
    pub piston_m: Vec<f64>,
    /// Piston velocity (m/s).
    pub piston_velocity_m_s: Vec<f64>,
    /// Friction force (N), with the sign of the piston velocity.
    pub friction_force_n: Vec<f64>,
    /// Controller's disturbance estimate g_hat + D_hat (N/s^2).
    pub disturbance_estimate_n_per_s2: Vec<f64>,
    /// RBF network output g_hat (N/s^2).
    pub rbf_output_n_per_s2: Vec<f64>,
    /// True lumped disturbance on dx2/dt relative to the controller's nominal model (N/s^2):
    /// what a perfect observer would estimate.
    pub lumped_disturbance_n_per_s2: Vec<f64>,
}

impl Record {
    fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        Record {
            t_s: v(),
            ref_force_n: v(),
            ref_force_rate_n_per_s: v(),
            load_force_n: v(),
            force_error_n: v(),
            force_rate_n_per_s: v(),
            valve_command: v(),
            spool_m: v(),
            piston_m: v(),
            piston_velocity_m_s: v(),
            friction_force_n: v(),
            disturbance_estimate_n_per_s2: v(),
            rbf_output_n_per_s2: v(),
            lumped_disturbance_n_per_s2: v(),
        }
    }

    /// The columns with their CSV header names, in output order.
    pub fn columns(&self) -> Vec<(&'static str, &[f64])> {
        vec![
            ("t_s", &self.t_s),
            ("ref_force_n", &self.ref_force_n),
            ("ref_force_rate_n_per_s", &self.ref_force_rate_n_per_s),
            ("load_force_n", &self.load_force_n),
            ("force_error_n", &self.force_error_n),
            ("force_rate_n_per_s", &self.force_rate_n_per_s),
            ("valve_command", &self.valve_command),
            ("spool_m", &self.spool_m),
            ("piston_m", &self.piston_m),
            ("piston_velocity_m_s", &self.piston_velocity_m_s),
            ("friction_force_n", &self.friction_force_n),
            ("disturbance_estimate_n_per_s2", &self.disturbance_estimate_n_per_s2),
            ("rbf_output_n_per_s2", &self.rbf_output_n_per_s2),
            ("lumped_disturbance_n_per_s2", &self.lumped_disturbance_n_per_s2),
        ]
    }
}

/// A finished run.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// The time series.
    pub record: Record,
    /// Metrics and run facts.
    pub summary: Summary,
}

/// Everything one evaluation of the continuous dynamics produces.
struct Eval {
    dx: X,
    out: ControlOutput,
    x2: f64,
    lumped_d: f64,
}

/// The immutable model of a run, built once from a scenario.
struct Model<'a> {
    coeffs: Coefficients,
    nominal: NominalModel,
    controller: Box<dyn Controller>,
    reference: Sine,
    dist: &'a Disturbances,
    human: &'a HumanParams,
    friction: &'a FrictionParams,
    seed: u64,
}

impl Model<'_> {
    fn reference_at(&self, t: f64) -> RefSample {
        self.reference.at(t)
    }

    /// The force-channel inputs other than `u`, and x2 = dF_L/dt, at time `t`.
    fn environment(
        &self,
        t: f64,
        h: &ForceChannelState,
        piston_vel: f64,
        r: &RefSample,
    ) -> (ForceChannelInput, f64, f64) {
        let (d_f, d_f_rate) = self.dist.force_rate.value_and_rate(t, self.seed, CHANNEL_FORCE_RATE);
        let mut inp = ForceChannelInput {
            valve_command: 0.0,
            piston_velocity_m_s: piston_vel,
            force_rate_dist_n_per_s: d_f,
            force_accel_dist_n_per_s2: 0.0,
            spool_dist_m_per_s: self.dist.spool.value(t, self.seed, CHANNEL_SPOOL),
        };
        let x2 = self.coeffs.force_rate(h, &inp);
        let mut d_acc = self.dist.force_accel.value(t, self.seed, CHANNEL_FORCE_ACCEL)
            + self.dist.state_gain_force * h.force_n
            + self.dist.state_gain_force_rate * x2;
        if self.human.mode == HumanMode::Paper {
            d_acc += self.human.interaction(h.force_n - r.value, x2 - r.rate);
        }
        inp.force_accel_dist_n_per_s2 = d_acc;
        (inp, x2, d_f_rate)
    }

    /// Evaluate the continuous dynamics at (t, x). `held` is the sampled-mode output.
    fn eval(&self, t: f64, x: &X, plant: &dyn Plant, held: Option<&ControlOutput>) -> Eval {
        let piston = plant.piston_at(t);
        let h = ForceChannelState {
            force_n: x[0],
            spool_m: x[1],
            accel_dist_n_per_s: x[2],
        };
        let r = self.reference_at(t);
        let (mut inp, x2, d_f_rate) = self.environment(t, &h, piston.velocity_m_s, &r);
        let truth = Truth {
            force_n: h.force_n,
            force_rate_n_per_s: x2,
            spool_m: h.spool_m,
            piston_m: piston.position_m,
            piston_velocity_m_s: piston.velocity_m_s,
            piston_accel_m_s2: piston.accel_m_s2,
        };
        let y = truth.ideal();
        let mut dx = [0.0; NX];
        let out = match held {
            Some(o) => *o,
            None => {
                let s = &x[NH..];
                let o = self.controller.output(t, &r, &y, s);
                self.controller.derivatives(t, &r, &y, s, &o, &mut dx[NH..]);
                o
            }
        };
        inp.valve_command = out.valve_command;
        let dh = self.coeffs.derivatives(&h, &inp);
        dx[0] = dh.force_n;
        dx[1] = dh.spool_m;
        dx[2] = dh.accel_dist_n_per_s;
        // True dx2/dt, and the part of it the controller's nominal model does not explain.
        let c = &self.coeffs;
        let dx2 = c.n1 * dh.spool_m - c.n2 * piston.accel_m_s2 - c.n3 * x2 + d_f_rate + inp.force_accel_dist_n_per_s2;
        let lumped_d = dx2 - self.nominal.force_accel(out.valve_command, &y);
        Eval { dx, out, x2, lumped_d }
    }

    fn state_name(&self, i: usize) -> String {
        match i {
            0 => "load_force_n".into(),
            1 => "spool_m".into(),
            2 => "accel_disturbance_integral_n_per_s".into(),
            _ => self
                .controller
                .state_names()
                .get(i - NH)
                .cloned()
                .unwrap_or_else(|| format!("x{i}")),
        }
    }
}

fn build_plant(s: &Scenario) -> Box<dyn Plant> {
    match s.file.plant.kind {
        PlantKind::Bench => Box::new(Bench::new(s.file.bench.clone())),
    }
}

/// Build the controller a scenario asks for, with its nominal model.
pub fn build_controller(s: &Scenario) -> (Box<dyn Controller>, NominalModel) {
    let f = &s.file;
    let nominal = NominalModel {
        c: f.controller.nominal.apply(&f.hydraulics).coefficients(),
    };
    let gains = ControllerGains {
        gamma: f.controller.gamma,
        k: f.controller.k,
        delta: f.controller.delta,
        zeta: f.controller.zeta,
    };
    (
        control::build(
            f.controller.kind,
            nominal,
            &gains,
            &f.controller.rbf,
            &f.controller.observer,
        ),
        nominal,
    )
}

/// Run a validated scenario to the end.
pub fn run(scenario: &Scenario) -> Result<RunOutput> {
    let start = std::time::Instant::now();
    let f = &scenario.file;
    let (controller, nominal) = build_controller(scenario);
    let reference = match f.reference.kind {
        ReferenceKind::Sine => Sine {
            amplitude: f.reference.amplitude_n,
            frequency_hz: f.reference.frequency_hz,
            phase_rad: f.reference.phase_rad,
            offset: f.reference.offset_n,
        },
    };
    let model = Model {
        coeffs: f.hydraulics.coefficients(),
        nominal,
        controller,
        reference,
        dist: &f.disturbance,
        human: &f.human,
        friction: &f.friction,
        seed: f.seed,
    };
    let mut plant = build_plant(scenario);
    let dt = f.sim.dt_s;
    let steps = scenario.steps();
    let sample_every = if f.controller.sample_period_s > 0.0 {
        Some((f.controller.sample_period_s / dt).round() as usize)
    } else {
        None
    };
    let mut sensors = sample_every.map(|_| SampledSensors::new(&f.sensors, f.controller.sample_period_s));

    // Initial state: F_L(0) = 0, spool centred, controller initialised from the first reading.
    let mut x: X = [0.0; NX];
    {
        let r0 = model.reference_at(0.0);
        let e0 = model.eval(0.0, &x, plant.as_ref(), Some(&ControlOutput::default()));
        let p0 = plant.piston_at(0.0);
        let y0 = Measurement {
            force_n: x[0],
            force_rate_n_per_s: e0.x2,
            spool_m: x[1],
            piston_m: p0.position_m,
            piston_velocity_m_s: p0.velocity_m_s,
            piston_accel_m_s2: p0.accel_m_s2,
        };
        model.controller.init(&y0, &r0, &mut x[NH..]);
    }
    let ns = model.controller.state_len();
    let mut held = ControlOutput::default();
    let mut rec = Record::with_capacity(steps + 1);

    let record = |t: f64, x: &X, e: &Eval, rec: &mut Record, plant: &dyn Plant| {
        let r = model.reference_at(t);
        let p = plant.piston_at(t);
        rec.t_s.push(t);
        rec.ref_force_n.push(r.value);
        rec.ref_force_rate_n_per_s.push(r.rate);
        rec.load_force_n.push(x[0]);
        rec.force_error_n.push(x[0] - r.value);
        rec.force_rate_n_per_s.push(e.x2);
        rec.valve_command.push(e.out.valve_command);
        rec.spool_m.push(x[1]);
        rec.piston_m.push(p.position_m);
        rec.piston_velocity_m_s.push(p.velocity_m_s);
        rec.friction_force_n.push(model.friction.force_n(p.velocity_m_s));
        rec.disturbance_estimate_n_per_s2
            .push(e.out.disturbance_estimate_n_per_s2);
        rec.rbf_output_n_per_s2.push(e.out.rbf_output_n_per_s2);
        rec.lumped_disturbance_n_per_s2.push(e.lumped_d);
    };

    for k in 0..steps {
        let t = k as f64 * dt;
        if let (Some(m), Some(sens)) = (sample_every, sensors.as_mut()) {
            if k % m == 0 {
                let p = plant.piston_at(t);
                let e = model.eval(t, &x, plant.as_ref(), Some(&held));
                let truth = Truth {
                    force_n: x[0],
                    force_rate_n_per_s: e.x2,
                    spool_m: x[1],
                    piston_m: p.position_m,
                    piston_velocity_m_s: p.velocity_m_s,
                    piston_accel_m_s2: p.accel_m_s2,
                };
                let y = sens.sample(&truth);
                let r = model.reference_at(t);
                held = model.controller.output(t, &r, &y, &x[NH..NH + ns]);
                model
                    .controller
                    .discrete_update(t, f.controller.sample_period_s, &r, &y, &mut x[NH..NH + ns], &held);
            }
        }
        if k == 0 {
            let e = model.eval(0.0, &x, plant.as_ref(), sample_every.map(|_| &held));
            record(0.0, &x, &e, &mut rec, plant.as_ref());
        }
        let hold = sample_every.map(|_| held);
        let p_ref = plant.as_ref();
        x = f
            .sim
            .integrator
            .step(t, dt, &x, |tau, xs| model.eval(tau, xs, p_ref, hold.as_ref()).dx);
        let v = plant.piston_at(t).velocity_m_s;
        plant.advance(t, dt, x[0] - model.friction.force_n(v));
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::Diverged {
                time_s: t + dt,
                state: model.state_name(i),
                value: x[i],
            });
        }
        let t1 = (k + 1) as f64 * dt;
        let e = model.eval(t1, &x, plant.as_ref(), hold.as_ref());
        record(t1, &x, &e, &mut rec, plant.as_ref());
    }
    let wall = start.elapsed().as_secs_f64();
    let summary = metrics::summarise(scenario, &rec, wall);
    Ok(RunOutput { record: rec, summary })
}
