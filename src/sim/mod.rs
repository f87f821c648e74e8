//! The co-simulation loop: wires reference, sensors, controller, hydraulics and plant.
//!
//! [`Simulation::new`] builds the mutable parts of a run (plant, controller, sensors) from a
//! [`Model`] (the immutable model, MuJoCo's `mjModel`); [`Simulation::step`]
//! advances one fixed step of size `dt` from `t_k` and hands the row of `t_k` to a
//! [`RecordSink`]; [`Simulation::finish`] records the final state. In pseudocode, exactly as
//! [`Simulation::step`] does it:
//!
//! ```text
//! pred = plant.piston_predictor()                  // leg + hydraulic actuator; else none
//! x.piston = pred's position and velocity at t_k
//! if k == 0: start()                               // hydraulics on the gait trajectory; continuous
//!                                                  // controller state from the first ideal reading
//! if sampled and k is a sample instant:            // zero-order hold (sensors::ZeroOrderHold)
//!     y      = sensors.sample(truth(t_k))           // noise, A/D, delay, differences
//!     F_pd   = knee_pd(y)                           // gait cascade's outer loop
//!     u_hold = controller.update(y, F_d(t_k), F_d(t_k+Ts))   // firmware step, valve limit applied
//! else if continuous: F_pd = knee_pd(plant's knee state)
//! s0  = evaluate(t_k, x)                           // see below
//! w1  = human.interaction(F_L - F_d, s0.x2 - dF_d/dt)  // once per step, held over it
//! sink.row(record(t_k, x, s0, w1))
//! x   = integrate x over [t_k, t_k + dt] (euler | ode3 | rk4) with evaluate(tau, x).dx
//! F_cyl  = pred ? impulse-average force of the predictor : F_L - F_f   (or prescribed / 0)
//! stroke = plant.advance(t_k, dt, F_cyl, cuff w1, hip target at t_k + dt)
//! cylinder.apply_stroke(stroke - predicted stroke)  // oil spring sees the geometric stroke
//! cylinder.clamp(x)                                 // hard stops
//! stop if a state is non-finite or the spool is past 1 m (Error::Diverged, naming the state)
//! ```
//! `evaluate(tau, x)`, at every integrator stage: piston motion (predictor states with
//! Rapier's substep lead, or the bench's prescribed motion); F_d(tau) + held F_pd;
//! disturbances; x2 = dF_L/dt from the cylinder (0 past a force bound); u = the held output,
//! or in continuous mode `valve_limit(controller.output(tau, F_d, ideal y, s))` with the
//! controller state's derivative; the cylinder's derivatives with its hard stops.
//! After the last step the final state is recorded, so a run has `steps + 1` rows.

pub mod integrator;
mod model;
mod stage;
mod state;

pub use integrator::Integrator;
pub use model::Model;
pub use state::{KneeState, Packed, PistonState, State};

use crate::control::{
    self, ControlOutput, Controller, DiscreteController, Measurement, SampleInput, Sampled, ValveLimit,
};
use crate::error::{Error, Result};
use crate::human::HumanMode;
use crate::hydraulics::ActuatorMode;
use crate::metrics::{Summary, SummaryBuilder, WalkingMetrics};
use crate::plant::PlantSetup;
use crate::plant::{Bench, LegPlant, PistonPredictor, Plant, PlantInputs, ReducedLegPlant};
use crate::record::{Layout, MemoryRecord, RecordSink, Tee};
use crate::sensors::{SampledSensors, ZeroOrderHold};
use stage::Dynamics;
use std::sync::Arc;

/// Spool travel (m) past which a run is declared unstable.
const MAX_PLAUSIBLE_SPOOL_M: f64 = 1.0;
/// Most substeps of the hydraulic states per fixed step; a stiffer state stops the run.
pub const MAX_SUBSTEPS: usize = 1000;
/// Fraction of the integrator's stability limit a substep may use.
const STABILITY_MARGIN: f64 = 0.5;

/// What is held over one step: the leg's piston predictor, the outer-loop force of the knee
/// cascade, and (sampled mode) the controller output.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Held {
    pub predictor: Option<PistonPredictor>,
    pub pd_force_n: f64,
    /// Cuff force over the step (N, `human.mode = "cuff"`), for coupled mechanics.
    pub cuff_force_n: f64,
    pub output: Option<ControlOutput>,
}

/// The controller as the loop runs it.
enum ControlBlock {
    /// Evaluated at every integrator stage; its state is integrated with the plant's.
    Continuous(Box<dyn Controller>),
    /// Firmware: sensors sampled, output computed and held, every `hold` period.
    Sampled { ctrl: Box<dyn DiscreteController>, sensors: Box<SampledSensors>, hold: ZeroOrderHold<ControlOutput> },
}

/// A running simulation (MuJoCo's `mjData` with the step that advances it).
pub struct Simulation {
    sc: Arc<Model>,
    plant: Box<dyn Plant>,
    control: ControlBlock,
    controller_names: Vec<String>,
    state: State,
    held: Held,
    k: usize,
    max_substeps: usize,
    substepped_steps: usize,
    /// The outer loop's knee-error integral (rad s).
    knee_integral_rad_s: f64,
}

/// Build the continuous-time controller a scenario asks for.
pub fn build_controller(sc: &Model) -> Box<dyn Controller> {
    control::build(&sc.controller, sc.nominal)
}

impl Simulation {
    /// Build a run: plant at its initial state, controller, sensors.
    pub fn new(sc: Arc<Model>) -> Result<Self> {
        let plant: Box<dyn Plant> = match &sc.plant {
            PlantSetup::Bench(b) => Box::new(Bench::new(b.clone())),
            PlantSetup::Leg(l) => match &l.reduced {
                Some(r) => Box::new(ReducedLegPlant::new(l, r.clone(), sc.reference.clone())?),
                None => Box::new(LegPlant::new(l, sc.dt_s, &sc.source_name)?),
            },
        };
        let ctrl = build_controller(&sc);
        let controller_names = ctrl.state_names();
        let control = match sc.sample_every {
            None => ControlBlock::Continuous(ctrl),
            Some(every) => ControlBlock::Sampled {
                ctrl: match &sc.dtznn {
                    Some(d) => Box::new(d.clone()),
                    None => Box::new(Sampled::new(ctrl, ValveLimit(sc.actuator.valve_command_limit))),
                },
                sensors: Box::new(SampledSensors::new(&sc.sensors, sc.controller.sample_period_s, sc.seed)),
                hold: ZeroOrderHold::new(every, ControlOutput::default()),
            },
        };
        let state = State { hyd: sc.cylinder.initial_state(), ..Default::default() };
        let output = matches!(control, ControlBlock::Sampled { .. }).then(ControlOutput::default);
        let held = Held { output, ..Default::default() };
        Ok(Self {
            sc,
            plant,
            control,
            controller_names,
            state,
            held,
            k: 0,
            max_substeps: 1,
            substepped_steps: 0,
            knee_integral_rad_s: 0.0,
        })
    }

    /// The column layout of this run's record.
    pub fn layout(&self) -> Layout {
        Layout {
            knee_reference: self.sc.reference.knee_at(0.0).is_some(),
            leg: self.plant.leg_row().is_some(),
            contact: self.plant.contact_row().is_some(),
        }
    }

    /// Design figures of a sampled controller (gains computed at start), if it has any.
    pub fn controller_design(&self) -> Option<serde_json::Value> {
        match &self.control {
            ControlBlock::Sampled { ctrl, .. } => ctrl.design(),
            ControlBlock::Continuous(_) => None,
        }
    }

    /// Number of steps taken.
    pub fn steps_taken(&self) -> usize {
        self.k
    }

    fn dynamics(&self) -> Dynamics<'_> {
        let continuous = match &self.control {
            ControlBlock::Continuous(c) => Some(c.as_ref()),
            ControlBlock::Sampled { .. } => None,
        };
        Dynamics { sc: &self.sc, controller: continuous }
    }

    fn hydraulic(&self) -> bool {
        self.sc.actuator.mode == ActuatorMode::Hydraulic
    }

    /// Step start: the leg's local piston model for this step (None for a prescribed piston).
    fn take_predictor(&mut self) {
        self.held.predictor = if self.hydraulic() { self.plant.piston_predictor() } else { None };
        if let Some(p) = &self.held.predictor {
            self.state.piston = PistonState { position_m: p.position_m, velocity_m_s: p.velocity_m_s };
            if self.plant.coupled().is_some() {
                self.state.knee =
                    KneeState { angle_rad: self.plant.knee_rad(), rate_rad_s: self.plant.knee_rate_rad_s() };
            }
        }
    }

    /// Step 0: put the hydraulics on the gait trajectory when the run starts on it.
    fn start_hydraulics(&mut self) {
        let on_traj = self.sc.leg().is_some_and(|l| l.start_on_trajectory);
        if on_traj && self.hydraulic() {
            let d = self.dynamics();
            let r = d.reference_at(0.0, &self.held);
            let v = d.piston(0.0, &self.state, self.plant.as_ref(), &self.held).velocity_m_s;
            self.sc.cylinder.start_on_trajectory(&mut self.state.hyd, r.value, r.rate, v);
        }
    }

    /// The controller's turn at `t`: a firmware sample, or (continuous) the outer loop from the
    /// plant's knee state and, at step 0, the controller state from the first ideal reading.
    fn control(&mut self, t: f64) {
        let sample_period = self.sc.controller.sample_period_s;
        match &mut self.control {
            ControlBlock::Sampled { ctrl, sensors, hold } => {
                if !hold.is_sample(self.k) {
                    return;
                }
                let d = Dynamics { sc: &self.sc, controller: None };
                let s0 = d.evaluate(t, &self.state, self.plant.as_ref(), &self.held);
                let y =
                    sensors.sample(&d.truth(&self.state, s0.force_rate_n_per_s, self.plant.as_ref(), t, &self.held));
                // The outer loop compares each reading with the reference at the reading's time,
                // and takes the knee rate from the piston-velocity sensor when there is one
                // (v / (dL/dq): no differencing lag), else from the encoder's difference.
                let t_reading = (t - self.sc.sensors.delay_samples as f64 * sample_period).max(0.0);
                let knee_rate = match self.sc.leg() {
                    Some(leg) if self.sc.sensors.piston_velocity.enabled => {
                        y.piston_velocity_m_s / crate::leg::moment_arm_at(&leg.model, y.knee_rad)
                    }
                    _ => y.knee_rate_rad_s,
                };
                self.knee_integral_rad_s =
                    d.pd_integral(t_reading, self.knee_integral_rad_s, y.knee_rad, sample_period);
                self.held.pd_force_n = d.pd_force(t_reading, y.knee_rad, knee_rate, self.knee_integral_rad_s);
                let r = d.reference_at(t, &self.held);
                let r_next = d.reference_at(t + sample_period, &self.held);
                let out = ctrl.update(&SampleInput { t_s: t, period_s: sample_period, y: &y, r, r_next });
                hold.set(out);
                self.held.output = Some(out);
            }
            ControlBlock::Continuous(_) => {
                let d = self.dynamics();
                let q = self.plant.knee_rad();
                self.knee_integral_rad_s = d.pd_integral(t, self.knee_integral_rad_s, q, self.sc.dt_s);
                let d = self.dynamics();
                let pd = d.pd_force(t, q, self.plant.knee_rate_rad_s(), self.knee_integral_rad_s);
                self.held.pd_force_n = pd;
                if self.k == 0 {
                    let init = Held { output: Some(ControlOutput::default()), ..self.held };
                    let d = self.dynamics();
                    let s0 = d.evaluate(0.0, &self.state, self.plant.as_ref(), &init);
                    let y0: Measurement =
                        d.truth(&self.state, s0.force_rate_n_per_s, self.plant.as_ref(), 0.0, &init).ideal();
                    let r0 = d.reference_at(0.0, &self.held);
                    let mut s = self.state.controller;
                    if let ControlBlock::Continuous(c) = &self.control {
                        c.init(&y0, &r0, &mut s);
                    }
                    self.state.controller = s;
                }
            }
        }
    }

    /// The interaction force w1 at a stage's force error and rate (0 with the human off).
    fn interaction(&self, t: f64, force_rate_n_per_s: f64) -> f64 {
        let h = &self.sc.human;
        match h.mode {
            HumanMode::Cuff | HumanMode::Paper => {
                let r = self.dynamics().reference_at(t, &self.held);
                h.interaction(self.state.hyd.force_n - r.value, force_rate_n_per_s - r.rate)
            }
            HumanMode::Off => 0.0,
        }
    }

    /// Advance one step; the row of the step's start goes to `sink`.
    pub fn step(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        let dt = self.sc.dt_s;
        let t = self.k as f64 * dt;
        self.take_predictor();
        if self.k == 0 {
            self.start_hydraulics();
        }
        self.control(t);
        let s0 = self.dynamics().evaluate(t, &self.state, self.plant.as_ref(), &self.held);
        let w1 = self.interaction(t, s0.force_rate_n_per_s);
        sink.row(&self.dynamics().row(t, &self.state, &s0, w1, self.plant.as_ref(), &self.held))?;
        let cuff_force_n = if self.sc.human.mode == HumanMode::Cuff { w1 } else { 0.0 };
        // The integrator's first stage is s0 unless coupled mechanics now see another cuff force.
        let first = s0.derivative.pack();
        let reuse_first = self.plant.coupled().is_none() || self.held.cuff_force_n == cuff_force_n;
        self.held.cuff_force_n = cuff_force_n;
        let start = self.state;
        let v0 = self.plant.piston_at(t).velocity_m_s;
        let r0 = self.dynamics().reference_at(t, &self.held);
        if self.hydraulic() {
            let n = self.substeps(t, s0.force_rate_n_per_s)?;
            let d = self.dynamics();
            let (plant, held, h) = (self.plant.as_ref(), &self.held, dt / n as f64);
            let mut x = start.pack();
            for i in 0..n {
                let f = |tau: f64, xs: &Packed| d.evaluate(tau, &State::unpack(xs), plant, held).derivative.pack();
                let ti = t + i as f64 * h;
                x = match (i, reuse_first) {
                    (0, true) => self.sc.integrator.step_from(ti, h, &x, &first, f),
                    _ => self.sc.integrator.step(ti, h, &x, f),
                };
            }
            self.state = State::unpack(&x);
        }
        let cylinder_force_n = match &self.held.predictor {
            Some(p) => {
                p.effective_mass_kg
                    * ((self.state.piston.velocity_m_s - start.piston.velocity_m_s) / dt - p.free_accel_m_s2)
            }
            None => self.dynamics().cylinder_force(&start, v0, &r0),
        };
        let inputs = PlantInputs {
            cylinder_force_n,
            cuff_force_n,
            hip_target_rad: self.sc.reference.hip_at(t + dt).map(|h| h.value),
            knee_end: (self.held.predictor.is_some() && self.plant.coupled().is_some())
                .then_some((self.state.knee.angle_rad, self.state.knee.rate_rad_s)),
        };
        let stroke = self.plant.advance(t, dt, &inputs)?;
        if self.hydraulic() {
            let seen = match &self.held.predictor {
                Some(_) => self.state.piston.position_m - start.piston.position_m,
                None => self.plant.piston_at(t + dt).position_m - self.plant.piston_at(t).position_m,
            };
            let xc = self.plant.piston_at(t + dt).position_m;
            self.sc.cylinder.apply_stroke(&mut self.state.hyd, xc, stroke - seen);
        }
        self.sc.cylinder.clamp(&mut self.state.hyd);
        self.k += 1;
        self.check(t + dt)
    }

    /// Substeps the hydraulic states need over this step: the local stiffness (force-channel or
    /// chamber-pressure rate, spool, piston friction over the effective mass, oil column) must
    /// stay within half the integrator's stability limit. More than [`MAX_SUBSTEPS`] stops the
    /// run with [`Error::Stiff`] naming the state and the step it needs.
    fn substeps(&mut self, t: f64, force_rate_n_per_s: f64) -> Result<usize> {
        let dt = self.sc.dt_s;
        let xc = match &self.held.predictor {
            Some(_) => self.state.piston.position_m,
            None => self.plant.piston_at(t).position_m,
        };
        let (rate, k_oil) = self.sc.cylinder.local_stiffness(&self.state.hyd, xc);
        let (mut real, mut real_state, mut omega) = (rate, "hydraulic pressure / load force", 0.0);
        if let Some(p) = &self.held.predictor {
            let fric = self.sc.friction.slope_n_s_per_m(self.state.piston.velocity_m_s) / p.effective_mass_kg;
            if fric > real {
                (real, real_state) = (fric, "piston velocity (seal friction)");
            }
            omega = (k_oil / p.effective_mass_kg).sqrt();
        }
        if let (ControlBlock::Continuous(c), true) = (&self.control, self.sc.substep_controller) {
            let n = self.controller_names.len();
            let k = c.stiffness_per_s(force_rate_n_per_s, &self.state.controller[..n]);
            if k > real {
                (real, real_state) = (k, "controller observer (FDO)");
            }
        }
        let (lim_re, lim_im) = self.sc.integrator.stability_limits();
        let n_real = real * dt / (STABILITY_MARGIN * lim_re);
        let n_imag = if lim_im > 0.0 { omega * dt / (STABILITY_MARGIN * lim_im) } else { 0.0 };
        let need = n_real.max(n_imag).ceil().max(1.0);
        if need > MAX_SUBSTEPS as f64 || !need.is_finite() {
            let (state, rate, lim) =
                if n_real >= n_imag { (real_state, real, lim_re) } else { ("oil column (piston)", omega, lim_im) };
            return Err(Error::Stiff {
                time_s: t,
                state: state.into(),
                step_s: dt,
                rate_per_s: rate,
                needed_step_s: STABILITY_MARGIN * lim / rate,
            });
        }
        let n = need as usize;
        self.max_substeps = self.max_substeps.max(n);
        self.substepped_steps += usize::from(n > 1);
        Ok(n)
    }

    /// Sensor readings that clipped at full scale, by channel (sampled mode).
    pub fn sensor_clips(&self) -> Vec<(&'static str, usize)> {
        match &self.control {
            ControlBlock::Sampled { sensors, .. } => sensors.clipped(),
            ControlBlock::Continuous(_) => Vec::new(),
        }
    }

    /// Most substeps of the hydraulic states in one step so far, and how many steps needed
    /// more than one.
    pub fn substep_stats(&self) -> (usize, usize) {
        (self.max_substeps, self.substepped_steps)
    }

    /// Stop on a non-finite state or an implausible spool.
    fn check(&self, t: f64) -> Result<()> {
        let bad = self.state.first_non_finite(&self.controller_names).or_else(|| match &self.control {
            ControlBlock::Sampled { ctrl, .. } => ctrl.first_non_finite(),
            ControlBlock::Continuous(_) => None,
        });
        if let Some((state, value)) = bad {
            return Err(Error::Diverged { time_s: t, state, value });
        }
        // No valve spool travels a metre: a run whose spool does has gone unstable even if the
        // numbers are still finite (e.g. held against a pressure limit).
        let xv = self.state.hyd.spool_m;
        if xv.abs() > MAX_PLAUSIBLE_SPOOL_M {
            return Err(Error::Diverged { time_s: t, state: "spool_m (beyond 1 m)".into(), value: xv });
        }
        Ok(())
    }

    /// Record the final state, evaluated the way the next step would see it.
    pub fn finish(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        let t_end = self.k as f64 * self.sc.dt_s;
        self.take_predictor();
        let d = self.dynamics();
        let s = d.evaluate(t_end, &self.state, self.plant.as_ref(), &self.held);
        let w1 = self.interaction(t_end, s.force_rate_n_per_s);
        sink.row(&d.row(t_end, &self.state, &s, w1, self.plant.as_ref(), &self.held))
    }
}

/// Run a resolved scenario to the end, streaming rows to `sink`; returns the summary.
pub fn run(sc: &Arc<Model>, sink: &mut dyn RecordSink) -> Result<Summary> {
    run_with_design(sc, sink).map(|(s, _)| s)
}

/// Like [`run`], also returning the controller's design figures (sampled controllers that
/// compute gains at start), for `summary.json`.
pub fn run_with_design(sc: &Arc<Model>, sink: &mut dyn RecordSink) -> Result<(Summary, Option<serde_json::Value>)> {
    let start = std::time::Instant::now();
    let mut sim = Simulation::new(sc.clone())?;
    let layout = sim.layout();
    let mut metrics = SummaryBuilder::new(sc.metrics);
    let mut walking = layout.contact.then(|| {
        let data = sc.leg().and_then(|l| l.body.as_ref()).and_then(|b| match &b.targets {
            crate::plant::BodyTargets::Walking(w) => Some(w.clone()),
            crate::plant::BodyTargets::Pose(_) => None,
        });
        WalkingMetrics::new(sc.metrics.settle_s, sc.metrics.stride_s, data)
    });
    let mut sinks: Vec<&mut dyn RecordSink> = vec![&mut metrics, sink];
    if let Some(w) = walking.as_mut() {
        sinks.push(w);
    }
    let mut tee = Tee(sinks);
    tee.start(&layout)?;
    for _ in 0..sc.steps {
        sim.step(&mut tee)?;
    }
    sim.finish(&mut tee)?;
    drop(tee);
    let mut summary = metrics.finish(start.elapsed().as_secs_f64());
    summary.contact = walking.map(|w| w.finish());
    summary.engine = sc.leg().map(|l| if l.reduced.is_some() { "reduced" } else { "rapier" }.to_string());
    (summary.hydraulic_substeps_max, summary.substepped_steps) = sim.substep_stats();
    summary.sensor_clipped_readings = sim.sensor_clips().into_iter().map(|(k, n)| (k.to_string(), n)).collect();
    Ok((summary, sim.controller_design()))
}

/// Run and keep the whole record in memory (tests, the library API).
pub fn run_in_memory(sc: &Arc<Model>) -> Result<(Summary, MemoryRecord)> {
    let mut rec = MemoryRecord::default();
    let summary = run(sc, &mut rec)?;
    Ok((summary, rec))
}
