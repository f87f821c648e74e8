//! The co-simulation loop: wires reference, sensors, controller, hydraulics and plant.
//!
//! One fixed step of size `dt` from `t_k` (pseudocode):
//!
//! ```text
//! pred = plant.piston_predictor()                       // leg: local piston model; bench: none
//! x[xc, vc] = pred's position and velocity at t_k
//! if sampled mode and t_k is a sample instant:          // zero-order hold
//!     y      = sensors.sample(truth(t_k))                // noise, A/D, delay, differences
//!     F_pd   = outer knee PD from y (gait cascade)
//!     u_hold = controller.output(t_k, ref(t_k), y, s)
//!     s      = controller.discrete_update(s, Ts, ...)    // firmware-style update
//! else F_pd = outer knee PD from the plant's knee state
//! record(t_k, ...)
//! w1 = human interaction from the force error at t_k    // held over the step
//! integrate x = [F_L, x_v, r, xc, vc, p_mean, s...] over [t_k, t_k+dt] (euler/ode3/rk4);
//! at every stage tau:
//!     piston = pred ? (xc, vc + lead*a, a = a_free + (F_L - F_f(vc))/m_eff) : plant.piston_at(tau)
//!     x2     = dF_L/dt from the force channel (linear ODE or two chambers; no u needed)
//!     u      = continuous ? controller.output(tau, ref(tau), ideal y, s) : u_hold
//!     u      = clamp(u, valve limit)                     // the controller is told (anti-windup)
//!     derivatives of the force channel (+ controller state in continuous mode),
//!     with x_v and F_L (or the chamber pressures) held at their limits
//! F_cyl  = pred ? impulse-average force of the predictor : F_L - F_f   (or prescribed / 0)
//! stroke = plant.advance(t_k, dt, F_cyl, w1, hip target)
//! F_L   -= n2 * (stroke - predicted stroke)              // oil spring sees the geometric stroke
//! check every state is finite (else Error::Diverged naming the state and time)
//! ```
//! After the last step the final state is recorded, so a run has `steps + 1` rows.

use crate::control::{
    self, ControlOutput, Controller, ControllerGains, Measurement, NominalModel, MAX_CONTROLLER_STATES,
};
use crate::disturbance::{Disturbances, CHANNEL_FORCE_ACCEL, CHANNEL_FORCE_RATE, CHANNEL_SPOOL};
use crate::error::{Error, Result};
use crate::human::{HumanMode, HumanParams};
use crate::hydraulics::{
    ActuatorMode, ActuatorParams, Coefficients, ForceChannelInput, ForceChannelState, ForceSource, FrictionParams,
    HydraulicModel, TwoChamber,
};
use crate::leg::LegModel;
use crate::metrics::{self, Summary};
use crate::plant::{Bench, LegPlant, LegStart, PistonMotion, PistonPredictor, Plant, PlantInputs, PlantKind};
use crate::reference::{KneeForceReference, RefSample, Sine};
use crate::scenario::{ReferenceKind, Scenario};
use crate::sensors::{SampledSensors, Truth};

/// Plant-side states in the integrated vector: F_L, x_v, r, the predicted piston position
/// and velocity inside the step (leg plant; unused for a prescribed piston), and the mean
/// chamber pressure (two-chamber model; unused by the linear one).
const NH: usize = 6;
/// Length of the integrated state vector.
const NX: usize = NH + MAX_CONTROLLER_STATES;
type X = [f64; NX];
/// Spool travel (m) past which a run is declared unstable.
const MAX_PLAUSIBLE_SPOOL_M: f64 = 1.0;

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
    /// Valve command u as applied (after the valve limit; the held value in sampled mode).
    pub valve_command: Vec<f64>,
    /// 1 when the valve command was clipped, else 0.
    pub valve_saturated: Vec<f64>,
    /// Spool position x_v (m).
    pub spool_m: Vec<f64>,
    /// 1 when F_L is at the supply-pressure limit, else 0.
    pub force_limited: Vec<f64>,
    /// Piston position x_c (m).
    pub piston_m: Vec<f64>,
    /// Piston velocity (m/s).
    pub piston_velocity_m_s: Vec<f64>,
    /// Friction force (N), with the sign of the piston velocity.
    pub friction_force_n: Vec<f64>,
    /// Net force applied along the cylinder (N): F_L - F_f, or the prescribed force.
    pub cylinder_force_n: Vec<f64>,
    /// Human interaction force w1 (N in cuff mode, N/s^2 in paper mode).
    pub interaction_force: Vec<f64>,
    /// Controller's disturbance estimate g_hat + D_hat (N/s^2).
    pub disturbance_estimate_n_per_s2: Vec<f64>,
    /// RBF network output g_hat (N/s^2).
    pub rbf_output_n_per_s2: Vec<f64>,
    /// True lumped disturbance on dx2/dt relative to the controller's nominal model (N/s^2):
    /// what a perfect observer would estimate.
    pub lumped_disturbance_n_per_s2: Vec<f64>,
    /// Desired knee angle (deg), when the reference is a knee trajectory (else empty).
    pub ref_knee_deg: Vec<f64>,
    /// Stride time (s) of a gait reference, for per-stride figures.
    pub stride_s: Option<f64>,
    /// Names of the plant-specific columns (with units).
    pub extra_names: Vec<&'static str>,
    /// Plant-specific columns (knee angle, cylinder length, ...), same order as `extra_names`.
    pub extra: Vec<Vec<f64>>,
}

impl Record {
    fn with_capacity(n: usize, extra_names: Vec<&'static str>) -> Self {
        let v = || Vec::with_capacity(n);
        Record {
            t_s: v(),
            ref_force_n: v(),
            ref_force_rate_n_per_s: v(),
            load_force_n: v(),
            force_error_n: v(),
            force_rate_n_per_s: v(),
            valve_command: v(),
            valve_saturated: v(),
            spool_m: v(),
            force_limited: v(),
            piston_m: v(),
            piston_velocity_m_s: v(),
            friction_force_n: v(),
            cylinder_force_n: v(),
            interaction_force: v(),
            disturbance_estimate_n_per_s2: v(),
            rbf_output_n_per_s2: v(),
            lumped_disturbance_n_per_s2: v(),
            ref_knee_deg: Vec::new(),
            stride_s: None,
            extra: extra_names.iter().map(|_| v()).collect(),
            extra_names,
        }
    }

    /// The columns with their CSV header names, in output order.
    pub fn columns(&self) -> Vec<(&'static str, &[f64])> {
        let mut c: Vec<(&'static str, &[f64])> = vec![
            ("t_s", &self.t_s),
            ("ref_force_n", &self.ref_force_n),
            ("ref_force_rate_n_per_s", &self.ref_force_rate_n_per_s),
            ("load_force_n", &self.load_force_n),
            ("force_error_n", &self.force_error_n),
            ("force_rate_n_per_s", &self.force_rate_n_per_s),
            ("valve_command", &self.valve_command),
            ("valve_saturated", &self.valve_saturated),
            ("spool_m", &self.spool_m),
            ("force_limited", &self.force_limited),
            ("piston_m", &self.piston_m),
            ("piston_velocity_m_s", &self.piston_velocity_m_s),
            ("friction_force_n", &self.friction_force_n),
            ("cylinder_force_n", &self.cylinder_force_n),
            ("interaction_force", &self.interaction_force),
            ("disturbance_estimate_n_per_s2", &self.disturbance_estimate_n_per_s2),
            ("rbf_output_n_per_s2", &self.rbf_output_n_per_s2),
            ("lumped_disturbance_n_per_s2", &self.lumped_disturbance_n_per_s2),
        ];
        if !self.ref_knee_deg.is_empty() {
            c.push(("ref_knee_angle_deg", &self.ref_knee_deg));
        }
        c.extend(self.extra_names.iter().copied().zip(self.extra.iter().map(|v| v.as_slice())));
        c
    }

    /// A plant-specific column by name.
    pub fn extra_column(&self, name: &str) -> Option<&[f64]> {
        self.extra_names.iter().position(|n| *n == name).map(|i| self.extra[i].as_slice())
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
    force_limited: bool,
}

/// The immutable model of a run, built once from a scenario.
struct Model<'a> {
    coeffs: Coefficients,
    nominal: NominalModel,
    controller: Box<dyn Controller>,
    reference: ForceRef,
    dist: &'a Disturbances,
    human: &'a HumanParams,
    friction: &'a FrictionParams,
    act: &'a ActuatorParams,
    /// Load-force bounds (N): [-p_s*A2, p_s*A1], or infinite.
    force_bounds: (f64, f64),
    /// The two-chamber plant, when `hydraulics.model = "two_chamber"`.
    two_chamber: Option<TwoChamber>,
    seed: u64,
}

/// The desired load force: a sine, or the knee cascade's feedforward plus its held PD part.
enum ForceRef {
    Sine(Sine),
    Knee(Box<(KneeForceReference, LegModel)>),
}

/// What is held over one step: the sampled-mode controller output, the leg's piston
/// predictor, and the outer-loop PD force of the knee cascade.
#[derive(Clone, Copy, Default)]
struct StepCtx {
    held: Option<ControlOutput>,
    pred: Option<PistonPredictor>,
    pd_force_n: f64,
}

impl Model<'_> {
    fn reference_at(&self, t: f64, ctx: &StepCtx) -> RefSample {
        match &self.reference {
            ForceRef::Sine(s) => s.at(t),
            ForceRef::Knee(k) => {
                let mut r = k.0.feedforward_at(t);
                r.value += ctx.pd_force_n;
                r
            }
        }
    }

    /// Desired knee angle (rad) and the outer-loop PD force for a knee reading, if any.
    fn knee_reference(&self, t: f64) -> Option<RefSample> {
        match &self.reference {
            ForceRef::Knee(k) => Some(k.0.gait.knee_at(t)),
            ForceRef::Sine(_) => None,
        }
    }

    /// The driven hip's trajectory (rad), if the reference drives the hip.
    fn hip_reference(&self, t: f64) -> Option<RefSample> {
        match &self.reference {
            ForceRef::Knee(k) if k.0.drives_hip() => Some(k.0.gait.hip_at(t)),
            _ => None,
        }
    }

    fn pd_force(&self, t: f64, knee_rad: f64, knee_rate_rad_s: f64) -> f64 {
        match &self.reference {
            ForceRef::Knee(k) => k.0.pd_force_n(&k.1, t, knee_rad, knee_rate_rad_s),
            ForceRef::Sine(_) => 0.0,
        }
    }

    /// The force-channel inputs other than `u`, x2 = dF_L/dt, and d(d_F)/dt at time `t`.
    fn environment(
        &self,
        t: f64,
        h: &ForceChannelState,
        piston: &PistonMotion,
        mean_pressure_pa: f64,
        r: &RefSample,
    ) -> (ForceChannelInput, f64, f64, f64) {
        let piston_vel = piston.velocity_m_s;
        let (d_f, d_f_rate) = self.dist.force_rate.value_and_rate(t, self.seed, CHANNEL_FORCE_RATE);
        let mut inp = ForceChannelInput {
            valve_command: 0.0,
            piston_velocity_m_s: piston_vel,
            force_rate_dist_n_per_s: d_f,
            force_accel_dist_n_per_s2: 0.0,
            spool_dist_m_per_s: self.dist.spool.value(t, self.seed, CHANNEL_SPOOL),
        };
        // x2 = dF_L/dt: from the linear ODE, or from the two chambers' pressure rates.
        let (x2, d_mean) = match &self.two_chamber {
            None => (self.coeffs.force_rate(h, &inp), 0.0),
            Some(tc) => {
                let (p1, p2) = tc.pressures(h.force_n, mean_pressure_pa);
                let extra = inp.force_rate_dist_n_per_s + h.accel_dist_n_per_s;
                let (d1, d2) = tc.pressure_rates(p1, p2, h.spool_m, piston.position_m, piston_vel, extra);
                let (df, _) = tc.force_and_mean(d1, d2);
                (df, 0.5 * (d1 + d2))
            }
        };
        let mut d_acc = self.dist.force_accel.value(t, self.seed, CHANNEL_FORCE_ACCEL)
            + self.dist.state_gain_force * h.force_n
            + self.dist.state_gain_force_rate * x2;
        if self.human.mode == HumanMode::Paper {
            d_acc += self.human.interaction(h.force_n - r.value, x2 - r.rate);
        }
        inp.force_accel_dist_n_per_s2 = d_acc;
        (inp, x2, d_f_rate, d_mean)
    }

    /// Apply the valve limit to a controller output.
    fn limit(&self, mut o: ControlOutput) -> ControlOutput {
        let lim = self.act.valve_command_limit;
        if lim > 0.0 && o.valve_command.abs() > lim {
            o.valve_command = o.valve_command.clamp(-lim, lim);
            o.saturated = true;
        }
        o
    }

    fn truth(&self, x: &X, x2: f64, plant: &dyn Plant, t: f64) -> Truth {
        let p = plant.piston_at(t);
        Truth {
            force_n: x[0],
            force_rate_n_per_s: x2,
            spool_m: x[1],
            piston_m: p.position_m,
            piston_velocity_m_s: p.velocity_m_s,
            piston_accel_m_s2: p.accel_m_s2,
            knee_rad: plant.knee_rad(),
            knee_rate_rad_s: plant.knee_rate_rad_s(),
        }
    }

    /// Piston motion at a stage: prescribed by the plant, or from the predictor states.
    fn piston(&self, t: f64, x: &X, plant: &dyn Plant, pred: Option<&PistonPredictor>) -> PistonMotion {
        match pred {
            None => plant.piston_at(t),
            Some(p) => {
                // Predictor states: x[3] position, x[4] velocity v. The force ODE sees the
                // plant integrator's effective velocity v + a*lead (see PistonPredictor).
                let v = x[4];
                let a = p.free_accel_m_s2 + (x[0] - self.friction.force_n(v)) / p.effective_mass_kg;
                let v_eff = v + (a - p.lead_exempt_accel_m_s2) * p.velocity_lead_s;
                PistonMotion { position_m: x[3], velocity_m_s: v_eff, accel_m_s2: a }
            }
        }
    }

    /// Evaluate the continuous dynamics at (t, x) with what is held over the step.
    fn eval(&self, t: f64, x: &X, plant: &dyn Plant, ctx: &StepCtx) -> Eval {
        let (held, pred) = (ctx.held.as_ref(), ctx.pred.as_ref());
        let piston = self.piston(t, x, plant, pred);
        let h = ForceChannelState { force_n: x[0], spool_m: x[1], accel_dist_n_per_s: x[2] };
        let r = self.reference_at(t, ctx);
        let (mut inp, x2, d_f_rate, d_mean) = self.environment(t, &h, &piston, x[5], &r);
        // Held at a supply-pressure bound (linear model), the load force does not move: the
        // load cell's rate is 0, and that is what the controller and the record see.
        let (lo, hi) = self.force_bounds;
        let x2 =
            if self.two_chamber.is_none() && ((x[0] >= hi && x2 > 0.0) || (x[0] <= lo && x2 < 0.0)) { 0.0 } else { x2 };
        // With a predictor, the derivative of the effective velocity is a + lead*da/dt, with
        // da/dt = (dF_L/dt - F_f'(v)*a)/m_eff: that is the piston acceleration the force ODE
        // experiences, so it is what an ideal sensor reports.
        let mut piston = piston;
        let v_state = x[4];
        if let Some(p) = pred {
            let a = piston.accel_m_s2;
            let a_dot = (x2 - self.friction.slope_n_s_per_m(v_state) * a) / p.effective_mass_kg;
            piston.accel_m_s2 = a + p.velocity_lead_s * a_dot;
        }
        let y = Truth {
            force_n: h.force_n,
            force_rate_n_per_s: x2,
            spool_m: h.spool_m,
            piston_m: piston.position_m,
            piston_velocity_m_s: piston.velocity_m_s,
            piston_accel_m_s2: piston.accel_m_s2,
            knee_rad: plant.knee_rad(),
            knee_rate_rad_s: plant.knee_rate_rad_s(),
        }
        .ideal();
        let mut dx = [0.0; NX];
        let out = match held {
            Some(o) => *o,
            None => {
                let s = &x[NH..];
                let o = self.limit(self.controller.output(t, &r, &y, s));
                self.controller.derivatives(t, &r, &y, s, &o, &mut dx[NH..]);
                o
            }
        };
        inp.valve_command = out.valve_command;
        let dh = self.coeffs.derivatives(&h, &inp);
        dx[0] = x2;
        dx[1] = dh.spool_m;
        dx[2] = dh.accel_dist_n_per_s;
        dx[5] = d_mean;
        if let Some(p) = pred {
            dx[3] = piston.velocity_m_s;
            dx[4] = p.free_accel_m_s2 + (x[0] - self.friction.force_n(v_state)) / p.effective_mass_kg;
        }
        // Hard stops: spool travel and the supply-pressure force bounds.
        let sl = self.act.spool_limit_m;
        if sl > 0.0 && x[1].abs() >= sl && dx[1] * x[1] > 0.0 {
            dx[1] = 0.0;
        }
        let force_limited = match &self.two_chamber {
            None => {
                let (lo, hi) = self.force_bounds;
                if (x[0] >= hi && dx[0] > 0.0) || (x[0] <= lo && dx[0] < 0.0) {
                    dx[0] = 0.0;
                }
                x[0] <= lo || x[0] >= hi
            }
            // The chamber pressures hold themselves in [p_r, p_s].
            Some(tc) => {
                let (p1, p2) = tc.pressures(x[0], x[5]);
                p1 <= tc.p_r || p1 >= tc.p_s || p2 <= tc.p_r || p2 >= tc.p_s
            }
        };
        // True dx2/dt (linear model, analytic), and the part of it the controller's nominal
        // model does not explain. For the two-chamber model it is left to the record (NaN).
        let lumped_d = match &self.two_chamber {
            None => {
                let c = &self.coeffs;
                let dx2 =
                    c.n1 * dh.spool_m - c.n2 * piston.accel_m_s2 - c.n3 * x2 + d_f_rate + inp.force_accel_dist_n_per_s2;
                dx2 - self.nominal.force_accel(out.valve_command, &y)
            }
            Some(_) => f64::NAN,
        };
        Eval { dx, out, x2, lumped_d, force_limited }
    }

    /// Clamp the states that sit against hard stops after a step.
    fn clamp(&self, x: &mut X) {
        let sl = self.act.spool_limit_m;
        if sl > 0.0 {
            x[1] = x[1].clamp(-sl, sl);
        }
        match &self.two_chamber {
            None => x[0] = x[0].clamp(self.force_bounds.0, self.force_bounds.1),
            Some(tc) => {
                let (p1, p2) = tc.pressures(x[0], x[5]);
                let (p1, p2) = tc.clamp(p1, p2);
                (x[0], x[5]) = tc.force_and_mean(p1, p2);
            }
        }
    }

    /// Apply a piston stroke `dx` (m) at position `xc` that the force ODE did not see.
    fn apply_missed_stroke(&self, x: &mut X, xc: f64, dx: f64) {
        match &self.two_chamber {
            None => x[0] -= self.coeffs.n2 * dx,
            Some(tc) => {
                let (p1, p2) = tc.pressures(x[0], x[5]);
                let (d1, d2) = tc.pressure_change_for_stroke(xc, dx);
                (x[0], x[5]) = tc.force_and_mean(p1 + d1, p2 + d2);
            }
        }
    }

    /// The net force the actuator applies to the mechanics.
    fn cylinder_force(&self, x: &X, piston_vel: f64, r: &RefSample) -> f64 {
        match self.act.mode {
            ActuatorMode::Hydraulic => x[0] - self.friction.force_n(piston_vel),
            ActuatorMode::Force => match self.act.force_source {
                ForceSource::Constant => self.act.force_n,
                ForceSource::Reference => r.value,
            },
            ActuatorMode::Free => 0.0,
        }
    }

    fn state_name(&self, i: usize) -> String {
        match i {
            0 => "load_force_n".into(),
            1 => "spool_m".into(),
            2 => "accel_disturbance_integral_n_per_s".into(),
            3 => "predicted_piston_m".into(),
            4 => "predicted_piston_velocity_m_s".into(),
            5 => "mean_chamber_pressure_pa".into(),
            _ => self.controller.state_names().get(i - NH).cloned().unwrap_or_else(|| format!("x{i}")),
        }
    }
}

/// Build the controller a scenario asks for, with its nominal model.
pub fn build_controller(s: &Scenario) -> (Box<dyn Controller>, NominalModel) {
    let f = &s.file;
    let nominal = NominalModel { c: f.controller.nominal.apply(&f.hydraulics).coefficients() };
    let gains = ControllerGains {
        gamma: f.controller.gamma,
        k: f.controller.k,
        delta: f.controller.delta,
        zeta: f.controller.zeta,
    };
    (control::build(f.controller.kind, nominal, &gains, &f.controller.rbf, &f.controller.observer), nominal)
}

/// Run a validated scenario to the end.
pub fn run(scenario: &Scenario) -> Result<RunOutput> {
    let start = std::time::Instant::now();
    let f = &scenario.file;
    let src = &scenario.source_name;
    let (controller, nominal) = build_controller(scenario);
    let leg_model = match f.plant.kind {
        PlantKind::Leg => Some(f.leg.load_model(src, scenario.base_dir.as_deref())?),
        PlantKind::Bench => None,
    };
    let reference = match f.reference.kind {
        ReferenceKind::Sine => ForceRef::Sine(Sine {
            amplitude: f.reference.amplitude_n,
            frequency_hz: f.reference.frequency_hz,
            phase_rad: f.reference.phase_rad,
            offset: f.reference.offset_n,
        }),
        ReferenceKind::Gait => {
            let lm = leg_model
                .clone()
                .ok_or_else(|| Error::input(src, "reference.kind", "`gait` needs plant.kind = \"leg\""))?;
            let gait = f.reference.gait(src, scenario.base_dir.as_deref())?;
            let r = KneeForceReference::new(
                gait,
                &lm,
                &f.friction,
                f.reference.drive_hip,
                f.reference.knee_kp_nm_per_rad,
                f.reference.knee_kd_nm_s_per_rad,
            )?;
            ForceRef::Knee(Box::new((r, lm)))
        }
    };
    let force_bounds = if f.actuator.pressure_limit {
        (-f.hydraulics.max_pull_force_n(), f.hydraulics.max_push_force_n())
    } else {
        (f64::NEG_INFINITY, f64::INFINITY)
    };
    let model = Model {
        coeffs: f.hydraulics.coefficients(),
        nominal,
        controller,
        reference,
        dist: &f.disturbance,
        human: &f.human,
        friction: &f.friction,
        act: &f.actuator,
        force_bounds,
        two_chamber: match f.hydraulics.model {
            HydraulicModel::Linear => None,
            HydraulicModel::TwoChamber => Some(TwoChamber::new(&f.hydraulics)),
        },
        seed: f.seed,
    };
    let mut start_on_trajectory = false;
    let mut plant: Box<dyn Plant> = match leg_model {
        None => Box::new(Bench::new(f.bench.clone())),
        Some(lm) => {
            // Initial knee: at rest at the scenario's angle; else on the gait trajectory
            // (its angle and rate at t = 0); else at rest at 30 deg.
            start_on_trajectory = f.leg.initial_knee_deg.is_none() && model.knee_reference(0.0).is_some();
            let (q0, qd0) = match (f.leg.initial_knee_deg, model.knee_reference(0.0)) {
                (Some(d), _) => (d.to_radians(), 0.0),
                (None, Some(k)) => (k.value, k.rate),
                (None, None) => (30f64.to_radians(), 0.0),
            };
            let start = LegStart { knee_rad: q0, knee_rate_rad_s: qd0, hip: model.hip_reference(0.0) };
            Box::new(LegPlant::new(lm, &f.leg, start, f.sim.dt_s, (&f.human.cuff_link, f.human.cuff_xyz), src)?)
        }
    };
    let dt = f.sim.dt_s;
    let steps = scenario.steps();
    let sample_every = if f.controller.sample_period_s > 0.0 {
        Some((f.controller.sample_period_s / dt).round() as usize)
    } else {
        None
    };
    let mut sensors = sample_every.map(|_| SampledSensors::new(&f.sensors, f.controller.sample_period_s, f.seed));

    // Initial state: F_L(0) = 0, spool centred; the controller is initialised from the first
    // reading inside the loop (after the piston predictor has set the piston states).
    let mut x: X = [0.0; NX];
    if let Some(tc) = &model.two_chamber {
        // Start at the two-chamber equilibrium with F_L = 0 (pressures and balancing spool).
        let (p1, p2, xv) = tc.operating_point();
        (x[0], x[5]) = tc.force_and_mean(p1, p2);
        x[1] = xv;
    }
    let ns = model.controller.state_len();
    let mut ctx = StepCtx { held: sample_every.map(|_| ControlOutput::default()), ..Default::default() };
    let mut rec = Record::with_capacity(steps + 1, plant.extra_names());
    let mut extra = Vec::with_capacity(rec.extra_names.len());
    if let ForceRef::Knee(k) = &model.reference {
        rec.stride_s = Some(k.0.gait.stride_s);
    }

    let mut record = |t: f64, x: &X, e: &Eval, w1: f64, ctx: &StepCtx, rec: &mut Record, plant: &dyn Plant| {
        let r = model.reference_at(t, ctx);
        let p = plant.piston_at(t);
        rec.t_s.push(t);
        rec.ref_force_n.push(r.value);
        rec.ref_force_rate_n_per_s.push(r.rate);
        rec.load_force_n.push(x[0]);
        rec.force_error_n.push(x[0] - r.value);
        rec.force_rate_n_per_s.push(e.x2);
        rec.valve_command.push(e.out.valve_command);
        rec.valve_saturated.push(if e.out.saturated { 1.0 } else { 0.0 });
        rec.spool_m.push(x[1]);
        rec.force_limited.push(if e.force_limited { 1.0 } else { 0.0 });
        rec.piston_m.push(p.position_m);
        rec.piston_velocity_m_s.push(p.velocity_m_s);
        rec.friction_force_n.push(model.friction.force_n(p.velocity_m_s));
        rec.cylinder_force_n.push(model.cylinder_force(x, p.velocity_m_s, &r));
        rec.interaction_force.push(w1);
        rec.disturbance_estimate_n_per_s2.push(e.out.disturbance_estimate_n_per_s2);
        rec.rbf_output_n_per_s2.push(e.out.rbf_output_n_per_s2);
        rec.lumped_disturbance_n_per_s2.push(e.lumped_d);
        if let Some(k) = model.knee_reference(t) {
            rec.ref_knee_deg.push(k.value.to_degrees());
        }
        extra.clear();
        plant.extra_values(&mut extra);
        for (col, v) in rec.extra.iter_mut().zip(&extra) {
            col.push(*v);
        }
    };

    let hydraulic = model.act.mode == ActuatorMode::Hydraulic;
    for k in 0..steps {
        let t = k as f64 * dt;
        // The leg's local piston model for this step (None for a prescribed piston).
        ctx.pred = if hydraulic { plant.piston_predictor() } else { None };
        if let Some(p) = &ctx.pred {
            x[3] = p.position_m;
            x[4] = p.velocity_m_s;
        }
        if k == 0 && start_on_trajectory && hydraulic {
            // Start the hydraulics on the trajectory too: F_L = F_d(0) and the spool opening
            // that gives dF_L/dt = dF_d/dt(0) with the piston already moving.
            let r = model.reference_at(0.0, &ctx);
            let v = model.piston(0.0, &x, plant.as_ref(), ctx.pred.as_ref()).velocity_m_s;
            let c = &model.coeffs;
            let (lo, hi) = model.force_bounds;
            x[0] = r.value.clamp(lo, hi);
            x[1] = (r.rate + c.n2 * v + c.n3 * x[0] - c.n4) / c.n1;
        }
        match (sample_every, sensors.as_mut()) {
            (Some(m), Some(sens)) => {
                if k % m == 0 {
                    // Digital controller: sample, update the outer loop and the force controller.
                    let e = model.eval(t, &x, plant.as_ref(), &ctx);
                    let y = sens.sample(&model.truth(&x, e.x2, plant.as_ref(), t));
                    ctx.pd_force_n = model.pd_force(t, y.knee_rad, y.knee_rate_rad_s);
                    let r = model.reference_at(t, &ctx);
                    if k == 0 {
                        model.controller.init(&y, &r, &mut x[NH..]);
                    }
                    let out = model.limit(model.controller.output(t, &r, &y, &x[NH..NH + ns]));
                    let ts = f.controller.sample_period_s;
                    model.controller.discrete_update(t, ts, &r, &y, &mut x[NH..NH + ns], &out);
                    ctx.held = Some(out);
                }
            }
            _ => {
                ctx.pd_force_n = model.pd_force(t, plant.knee_rad(), plant.knee_rate_rad_s());
                if k == 0 {
                    let init_ctx = StepCtx { held: Some(ControlOutput::default()), ..ctx };
                    let e = model.eval(0.0, &x, plant.as_ref(), &init_ctx);
                    let y0: Measurement = model.truth(&x, e.x2, plant.as_ref(), 0.0).ideal();
                    model.controller.init(&y0, &model.reference_at(0.0, &ctx), &mut x[NH..]);
                }
            }
        }
        let r0 = model.reference_at(t, &ctx);
        let e0 = model.eval(t, &x, plant.as_ref(), &ctx);
        let w1 = match model.human.mode {
            HumanMode::Cuff | HumanMode::Paper => model.human.interaction(x[0] - r0.value, e0.x2 - r0.rate),
            HumanMode::Off => 0.0,
        };
        record(t, &x, &e0, w1, &ctx, &mut rec, plant.as_ref());
        let p_ref = plant.as_ref();
        let v0 = plant.piston_at(t).velocity_m_s;
        let x_start = x;
        if hydraulic {
            x = f.sim.integrator.step(t, dt, &x, |tau, xs| model.eval(tau, xs, p_ref, &ctx).dx);
        }
        // The force the mechanics get over the step: with a predictor, the impulse-average
        // force the predictor integrated; otherwise the force at the step start.
        let cylinder_force_n = match &ctx.pred {
            Some(p) => p.effective_mass_kg * ((x[4] - x_start[4]) / dt - p.free_accel_m_s2),
            None => model.cylinder_force(&x_start, v0, &r0),
        };
        let inputs = PlantInputs {
            cylinder_force_n,
            cuff_force_n: if model.human.mode == HumanMode::Cuff { w1 } else { 0.0 },
            hip_target_rad: model.hip_reference(t + dt).map(|h| h.value),
        };
        let stroke = plant.advance(t, dt, &inputs)?;
        if hydraulic {
            // Stroke the force ODE did not see: the oil spring acts on the geometric change.
            let seen = match &ctx.pred {
                Some(_) => x[3] - x_start[3],
                None => plant.piston_at(t + dt).position_m - plant.piston_at(t).position_m,
            };
            let xc = plant.piston_at(t + dt).position_m;
            model.apply_missed_stroke(&mut x, xc, stroke - seen);
        }
        model.clamp(&mut x);
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::Diverged { time_s: t + dt, state: model.state_name(i), value: x[i] });
        }
        // No valve spool travels a metre: a run whose spool does has gone unstable even if the
        // numbers are still finite (e.g. held against a pressure limit).
        if x[1].abs() > MAX_PLAUSIBLE_SPOOL_M {
            return Err(Error::Diverged { time_s: t + dt, state: "spool_m (beyond 1 m)".into(), value: x[1] });
        }
    }
    // The final row, evaluated the way the next step would see it.
    let t_end = steps as f64 * dt;
    ctx.pred = if hydraulic { plant.piston_predictor() } else { None };
    if let Some(p) = &ctx.pred {
        x[3] = p.position_m;
        x[4] = p.velocity_m_s;
    }
    let e = model.eval(t_end, &x, plant.as_ref(), &ctx);
    let r_end = model.reference_at(t_end, &ctx);
    let w1_end = match model.human.mode {
        HumanMode::Cuff | HumanMode::Paper => model.human.interaction(x[0] - r_end.value, e.x2 - r_end.rate),
        HumanMode::Off => 0.0,
    };
    record(t_end, &x, &e, w1_end, &ctx, &mut rec, plant.as_ref());
    let wall = start.elapsed().as_secs_f64();
    let summary = metrics::summarise(scenario, &rec, wall);
    Ok(RunOutput { record: rec, summary })
}
