//! The co-simulation loop: wires reference, sensors, controller, hydraulics and plant.
//!
//! [`Simulation::new`] builds the mutable parts of a run (plant, controller, sensors) from a
//! [`Model`] (the immutable model, MuJoCo's `mjModel`); [`Simulation::with_controller`] puts
//! the caller's [`DiscreteController`] in the loop instead, and [`Simulation::external`]
//! leaves the controller to the caller (who owns the loop). A sampled run splits the step
//! where control happens (MuJoCo's `mj_step1`/`mj_step2`): [`Simulation::sample`] reads the
//! sensors at a sample instant, [`Simulation::hold`] applies a command, and
//! [`Simulation::advance`] integrates one fixed step of size `dt` from `t_k`, handing the row
//! of `t_k` to a [`RecordSink`]. [`Simulation::step`] is the three with the run's own
//! controller (the built-in sampled controllers take the same path).
//! [`Simulation::finish`] records the final state. In pseudocode, as [`Simulation::step`]
//! does it:
//!
//! ```text
//! begin:  pred = plant.piston_predictor()          // leg + hydraulic actuator; else none
//!         x.piston = pred's position and velocity at t_k
//!         if k == 0: start()                       // hydraulics on the gait trajectory
//! sample (sampled mode, k a sample instant; ZeroOrderHold):
//!         y, counts = sensors.sample(truth(t_k))   // noise, A/D, delay, differences
//!         F_pd = knee_pd(y)                        // gait cascade's outer loop
//!         input = (y, counts, F_d(t_k), F_d(t_k+Ts), valve limit)
//! hold:   u_hold = valve_limit(controller.update(input))   // or the caller's command
//! advance:
//!     continuous: F_pd = knee_pd(plant's knee state); at k == 0 the controller state from
//!                 the first ideal reading
//!     s0  = evaluate(t_k, x)                       // see below
//!     w1  = human.interaction(F_L - F_d, s0.x2 - dF_d/dt)  // once per step, held over it
//!     sink.row(record(t_k, x, s0, w1))
//!     x   = integrate x over [t_k, t_k + dt] (euler | ode3 | rk4) with evaluate(tau, x).dx
//!     F_cyl  = pred ? impulse-average force of the predictor : F_L - F_f   (or prescribed / 0)
//!     stroke = plant.advance(t_k, F_cyl, cuff w1)     // a driven hip follows its trajectory
//!     cylinder.end_step(stroke - predicted stroke)  // oil spring sees the geometric stroke,
//!                                                   // then the hard stops
//!     stop if a state is non-finite or the spool is past 1 m (Error::Diverged, naming the state)
//! ```
//! `evaluate(tau, x)`, at every integrator stage: piston motion (predictor states with
//! Rapier's substep lead, or the bench's prescribed motion); F_d(tau) + held F_pd;
//! disturbances; the cylinder's rates (x2 = dF_L/dt, 0 past a force bound); u = the held
//! output, or in continuous mode `valve_limit(controller.output(tau, F_d, ideal y, s))` with the
//! controller state's derivative; the cylinder's derivatives with its hard stops.
//! After the last step the final state is recorded, so a run has `steps + 1` rows.

mod compute;
mod faults;
pub mod learn;
mod model;
mod stage;
mod state;

pub use crate::integrator::Integrator;
pub use compute::{ComputeModel, ComputeSummary};
pub use model::{is_walking, Model};
pub use state::{PistonState, State, PLANT_LEN};

use crate::control::{ControlOutput, Controller, DiscreteController, Measurement, SampleInput, MAX_LOGGED};
use crate::error::{Error, Result};
use crate::human::HumanMode;
use crate::hydraulics::ActuatorMode;
use crate::plant::{Bench, LegPlant, PistonPredictor, Plant, PlantInputs, ReducedLegPlant, WalkerPlant};
use crate::plant::{PlantSetup, CONTACT_MARGIN};
use crate::record::{Layout, RecordSink, Row};
use crate::sensors::{DeviceSensors, SampledSensors, ZeroOrderHold};
use stage::{Dynamics, Extra, ExtraMut, MAX_MECH};
use std::sync::Arc;

/// Spool travel (m) past which a run is declared unstable.
const MAX_PLAUSIBLE_SPOOL_M: f64 = 1.0;
/// Most substeps of the hydraulic states per fixed step; a stiffer state stops the run.
pub const MAX_SUBSTEPS: usize = 1000;
/// Fraction of the integrator's stability limit a substep may use.
const STABILITY_MARGIN: f64 = 0.5;

/// What is held over one step: the leg's piston predictor, the outer loop of the knee cascade
/// (its force and its integral), the cuff force, and (sampled mode) the controller output.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Held {
    pub predictor: Option<PistonPredictor>,
    pub pd_force_n: f64,
    /// The outer loop's knee-error integral (rad s).
    pub knee_integral_rad_s: f64,
    /// Cuff force over the step (N, `human.mode = "cuff"`), for coupled mechanics.
    pub cuff_force_n: f64,
    pub output: Option<ControlOutput>,
    /// The leg's stance and swing from its contact (loaded walking on the ground).
    pub events: Option<crate::human::GaitEvents>,
    /// The body's forces on the carriage over the step (from the body's state at its start).
    pub body: Option<crate::human::BodyForces>,
    /// What faults do to the valve and the cylinder over the step.
    pub valve: crate::hydraulics::ValveFaults,
}

/// The sampled controller's side of the loop: sensors, hold, and the controller (or none when
/// the caller brings the commands).
struct SampledLoop {
    ctrl: Option<Box<dyn DiscreteController>>,
    sensors: SampledSensors,
    /// The device's own sensors.
    device: Option<DeviceSensors>,
    /// The sensor faults and their state.
    sensor_faults: crate::sensors::SensorFaults,
    hold: ZeroOrderHold<ControlOutput>,
    /// The step whose sample was taken and still needs its command (`hold`).
    awaiting: Option<usize>,
    /// The step whose sample was taken (so `advance` knows the sample is done).
    sampled: Option<usize>,
    log_names: Vec<String>,
    log: [f64; MAX_LOGGED],
}

/// The controller as the loop runs it.
enum ControlBlock {
    /// Evaluated at every integrator stage; its state is integrated with the plant's.
    Continuous(Box<dyn Controller>),
    /// Firmware: sensors sampled, output computed and held, every `hold` period.
    Sampled(Box<SampledLoop>),
}

/// Where a run's controller comes from.
pub enum ControllerSource {
    /// Built from the model (`controller.kind`).
    Model,
    /// The caller's sampled controller (any [`DiscreteController`]).
    Discrete(Box<dyn DiscreteController>),
    /// None: the caller reads [`Simulation::sample`] and gives [`Simulation::hold`] a command
    /// at every sample instant.
    External,
}

/// A running simulation (MuJoCo's `mjData` with the step that advances it).
pub struct Simulation {
    sc: Arc<Model>,
    plant: Box<dyn Plant>,
    control: ControlBlock,
    controller_names: Vec<String>,
    state: State,
    /// The continuous controller's state (sized when it is built).
    controller_state: Vec<f64>,
    /// The coupled mechanics' state (reduced engine with the hydraulic actuator; else empty)
    /// and its names.
    mech_state: Vec<f64>,
    mech_names: &'static [&'static str],
    /// The desired forces this step has evaluated.
    ref_memo: std::cell::RefCell<stage::RefMemo>,
    /// The integrator's packed vector and scratch, allocated once.
    packed: Vec<f64>,
    first: Vec<f64>,
    work: Vec<f64>,
    held: Held,
    k: usize,
    /// The slope of a substep's start (substeps after the first).
    scratch_k1: Vec<f64>,
    /// The first substep starts from the recorded evaluation (`first`).
    reuse_first: bool,
    /// The step whose start (predictor, t = 0 hydraulics) is done.
    begun: Option<usize>,
    max_substeps: usize,
    substepped_steps: usize,
    /// The run's faults as they happen.
    faults: faults::FaultRun,
    /// The controller's modelled computation as it goes.
    compute: compute::ComputeRun,
    /// The wearer's muscle analysis (`wearer.muscles`).
    muscles: Option<crate::muscles::analysis::Analysis>,
    /// The leg's muscles' metabolic rate over the last step recorded (W), with muscles.
    muscles_metabolic_w: Option<f64>,
    /// The muscle wearer (`wearer.model = "muscles"`).
    wearer: Option<crate::human::MuscleWearer>,
}

/// Build the plant of a model.
fn build_plant(sc: &Model) -> Result<Box<dyn Plant>> {
    Ok(match &sc.plant {
        PlantSetup::Bench(b) => Box::new(Bench::new(b.clone(), sc.dt_s)),
        PlantSetup::Leg(l) => match (&l.walker, &l.reduced) {
            (Some(w), _) => Box::new(WalkerPlant::new(l, w.clone(), sc.reference.clone(), sc.dt_s)?),
            (None, Some(r)) => Box::new(ReducedLegPlant::new(l, r.clone(), sc.reference.clone(), sc.dt_s)?),
            (None, None) => Box::new(LegPlant::new(l, sc.reference.clone(), sc.dt_s, &sc.source_name)?),
        },
    })
}

impl Simulation {
    /// Build a run with every block from the model: plant at its initial state, controller,
    /// sensors.
    pub fn new(sc: Arc<Model>) -> Result<Self> {
        Self::build(sc, ControllerSource::Model)
    }

    /// Build a run with the caller's sampled controller in the loop (the model's
    /// `controller.sample_period_s` must be > 0; its `controller.kind` is not used).
    pub fn with_controller(sc: Arc<Model>, ctrl: Box<dyn DiscreteController>) -> Result<Self> {
        Self::build(sc, ControllerSource::Discrete(ctrl))
    }

    /// Build a run whose commands the caller gives at every sample instant
    /// ([`Self::sample`], [`Self::hold`], [`Self::advance`]).
    pub fn external(sc: Arc<Model>) -> Result<Self> {
        Self::build(sc, ControllerSource::External)
    }

    /// Build a run with the controller from `source`.
    pub fn build(sc: Arc<Model>, source: ControllerSource) -> Result<Self> {
        let plant = build_plant(&sc)?;
        let outside = !matches!(source, ControllerSource::Model);
        let control = match (sc.sample_every, source) {
            (None, _) if outside => {
                return Err(Error::input(
                    &sc.source_name,
                    "controller.sample_period_s",
                    "a controller from outside runs sampled: set controller.sample_period_s > 0",
                ))
            }
            (None, _) if !sc.desired_force && sc.controller.needs_reference() => return Err(Self::no_reference(&sc)),
            (None, _) => ControlBlock::Continuous(sc.controller.continuous(sc.nominal)),
            (Some(every), source) => {
                let ctrl = match source {
                    ControllerSource::Model if !sc.desired_force && sc.controller.needs_reference() => {
                        return Err(Self::no_reference(&sc))
                    }
                    ControllerSource::Model => Some(
                        sc.controller
                            .discrete(sc.nominal, sc.valve_limit)
                            .map_err(|m| Error::input(&sc.source_name, "controller.plugin", m))?,
                    ),
                    ControllerSource::Discrete(c) => Some(c),
                    ControllerSource::External => None,
                };
                ControlBlock::Sampled(Box::new(SampledLoop::new(&sc, every, ctrl)))
            }
        };
        let controller_names = match &control {
            ControlBlock::Continuous(c) => c.state_names(),
            ControlBlock::Sampled(_) => Vec::new(),
        };
        let mech_names = match (sc.actuator.mode, plant.coupled()) {
            (ActuatorMode::Hydraulic, Some(c)) => c.state_names(),
            _ => &[],
        };
        if mech_names.len() > MAX_MECH {
            return Err(Error::Usage(format!("coupled mechanics of {} states: at most {MAX_MECH}", mech_names.len())));
        }
        let n = PLANT_LEN + mech_names.len() + controller_names.len();
        let state = State { hyd: sc.cylinder.initial_state(), ..Default::default() };
        let output = matches!(control, ControlBlock::Sampled(_)).then(ControlOutput::default);
        let held = Held { output, events: Self::gait_events(&sc), ..Default::default() };
        let wearer = sc.muscle_wearer.clone().map(crate::human::MuscleWearer::new);
        // The muscle wearer's own muscles are the analysis (no static optimisation of moments
        // it already makes).
        let muscles = sc.muscles.clone().filter(|_| wearer.is_none()).map(crate::muscles::analysis::Analysis::new);
        Ok(Self {
            faults: faults::FaultRun::new(&sc.faults, sc.seed),
            compute: compute::ComputeRun::new(sc.seed),
            controller_state: vec![0.0; controller_names.len()],
            mech_state: vec![0.0; mech_names.len()],
            mech_names,
            ref_memo: Default::default(),
            packed: vec![0.0; n],
            first: vec![0.0; n],
            work: vec![0.0; crate::integrator::SCRATCH_VECTORS * n],
            scratch_k1: vec![0.0; n],
            reuse_first: false,
            sc,
            plant,
            control,
            controller_names,
            state,
            held,
            k: 0,
            begun: None,
            max_substeps: 1,
            substepped_steps: 0,
            muscles,
            muscles_metabolic_w: None,
            wearer,
        })
    }

    /// The error of a built-in controller that tracks a desired force in a run without one.
    fn no_reference(sc: &Model) -> Error {
        Error::input(
            &sc.source_name,
            "controller.kind",
            "this controller tracks a desired force, and reference.force = \"none\" has none: use a controller that decides the assistance (a plugin, open_loop, or your own)",
        )
    }

    /// The column layout of this run's record.
    pub fn layout(&self) -> Layout {
        Layout {
            knee_reference: self.sc.reference.knee_at(0.0).is_some(),
            leg: self.plant.leg_row().is_some(),
            contact: self.plant.contact_row().is_some(),
            device: self.sc.device_columns,
            faults: !self.sc.faults.is_empty() || self.sc.on_stop == crate::control::OnStop::Failsafe,
            log: self.log_names(),
            muscles: match (&self.sc.muscles, self.sc.muscle_columns) {
                (Some(m), true) => m.column_names(),
                _ => Vec::new(),
            },
        }
    }

    /// The names of the channels the controller logs: what an outside controller says now
    /// (asked when the record starts), or what the caller set with [`Self::set_log_names`].
    pub fn log_names(&self) -> Vec<String> {
        match &self.control {
            ControlBlock::Sampled(l) => match &l.ctrl {
                Some(c) => c.log_names(),
                None => l.log_names.clone(),
            },
            ControlBlock::Continuous(_) => Vec::new(),
        }
    }

    /// The model this run was built from.
    pub fn model(&self) -> &Arc<Model> {
        &self.sc
    }

    /// Design figures of a sampled controller (gains computed at start), if it has any.
    pub fn controller_design(&self) -> Option<serde_json::Value> {
        match &self.control {
            ControlBlock::Sampled(l) => l.ctrl.as_ref().and_then(|c| c.design()),
            ControlBlock::Continuous(_) => None,
        }
    }

    /// How many samples the controller flagged with a warning, and the last warning's text.
    pub fn controller_warnings(&self) -> (usize, Option<String>) {
        match &self.control {
            ControlBlock::Sampled(l) => l.ctrl.as_ref().map_or((0, None), |c| c.warnings()),
            ControlBlock::Continuous(_) => (0, None),
        }
    }

    /// The controller's measured compute times (`summary.json`'s `controller_compute`) and
    /// its link's figures (`controller_link`), when it has them.
    pub fn controller_timing(&self) -> (Option<serde_json::Value>, Option<serde_json::Value>) {
        match &self.control {
            ControlBlock::Sampled(l) => l.ctrl.as_ref().map_or((None, None), |c| {
                (crate::control::timing::TimingStats::json(c.compute_times_s()), c.link_report())
            }),
            ControlBlock::Continuous(_) => (None, None),
        }
    }

    /// Number of steps taken.
    pub fn steps_taken(&self) -> usize {
        self.k
    }

    /// Simulated time now (s): the start of the next step.
    pub fn t_s(&self) -> f64 {
        self.k as f64 * self.sc.dt_s
    }

    /// True when the run has taken all its steps (only [`Self::finish`] is left).
    pub fn done(&self) -> bool {
        self.k >= self.sc.steps
    }

    /// The true force error F_L - F_d (N) now (the state, not a reading).
    pub fn force_error_n(&self) -> f64 {
        self.state.hyd.force_n - self.dynamics().reference_at(self.t_s(), &self.held).value
    }

    /// The wearer's gross metabolic rate over the last step (W/kg of the subject): this leg's
    /// muscles' rate for both legs plus the basal 1.2 W/kg, as `summary.json`'s
    /// `gross_w_per_kg` averages it; None without the wearer's muscles (`wearer.model =
    /// "muscles"` or `wearer.muscles = true`) or before the first step.
    pub fn gross_metabolic_w_per_kg(&self) -> Option<f64> {
        let w = self.muscles_metabolic_w?;
        let mass_kg = self.sc.muscles.as_ref().map(|m| m.body_mass_kg)?;
        Some(crate::muscles::metabolics::gross_w_per_kg(w, mass_kg))
    }

    /// True when the next step starts at a sample instant of a sampled controller.
    pub fn is_sample_step(&self) -> bool {
        matches!(&self.control, ControlBlock::Sampled(l) if l.hold.is_sample(self.k))
    }

    fn dynamics(&self) -> Dynamics<'_> {
        let continuous = match &self.control {
            ControlBlock::Continuous(c) => Some(c.as_ref()),
            ControlBlock::Sampled(_) => None,
        };
        Dynamics { sc: &self.sc, controller: continuous, memo: &self.ref_memo }
    }

    fn hydraulic(&self) -> bool {
        self.sc.actuator.mode == ActuatorMode::Hydraulic
    }

    /// The start of step k, once: the leg's local piston model for this step (None for a
    /// prescribed piston) and, at step 0, the hydraulics on the gait trajectory.
    fn begin(&mut self) {
        if self.begun == Some(self.k) {
            return;
        }
        self.begun = Some(self.k);
        if self.sc.compute.is_some() {
            self.apply_computed();
        }
        self.held.predictor = if self.hydraulic() { self.plant.piston_predictor() } else { None };
        if let Some(p) = &self.held.predictor {
            self.state.piston = PistonState { position_m: p.position_m, velocity_m_s: p.velocity_m_s };
            if let Some(c) = self.plant.coupled() {
                c.state(&mut self.mech_state);
            }
        }
        if self.k == 0 {
            self.start_hydraulics();
        }
        let t = self.t_s();
        if let (Some(e), Some(c)) = (self.held.events.as_mut(), self.plant.contact_row()) {
            e.update(t, c.ground_reaction_vertical_n);
        }
        self.held.body = self.body_forces(t);
        if !self.sc.faults.is_empty() || self.faults.stopped.is_some() {
            self.update_faults(t);
        }
        // The stance weight may have changed with the events (and step 0's start on the
        // trajectory asked before they were read).
        self.ref_memo.borrow_mut().clear();
    }

    /// A derivative slot for the mechanics' state in `buf` (evaluations whose derivatives are
    /// not kept).
    fn mech_scratch<'a>(&self, buf: &'a mut [f64; MAX_MECH]) -> ExtraMut<'a> {
        ExtraMut { mech: &mut buf[..self.mech_state.len()], ctrl: &mut [] }
    }

    /// The contact detector of a walking run on the ground (see `human::events`).
    fn gait_events(sc: &Model) -> Option<crate::human::GaitEvents> {
        let leg = sc.leg()?;
        let body = leg.body.as_ref()?;
        let crate::human::BodyTargets::Walking(w) = &body.targets else { return None };
        leg.ground.as_ref()?;
        let p = crate::human::EventParams::for_subject(w.subject_mass_kg, w.gait.stride_s);
        Some(crate::human::GaitEvents::new(p))
    }

    /// Step 0: put the hydraulics on the gait trajectory when the run starts on it.
    fn start_hydraulics(&mut self) {
        let on_traj = self.sc.leg().is_some_and(|l| l.start_on_trajectory) && self.sc.desired_force;
        if on_traj && self.hydraulic() {
            let d = self.dynamics();
            let r = d.reference_at(0.0, &self.held);
            let v = d.piston(0.0, &self.state, &self.mech_state, self.plant.as_ref(), &self.held).velocity_m_s;
            self.sc.cylinder.start_on_trajectory(&mut self.state.hyd, r.value, r.rate, v);
        }
    }

    /// Step 1 of a sampled step (MuJoCo's `mj_step1`): at a sample instant, read the sensors
    /// and update the gait cascade's outer loop; returns what the controller gets. Then
    /// [`Self::hold`] the command and [`Self::advance`].
    pub fn sample(&mut self) -> Result<SampleInput> {
        if !self.is_sample_step() {
            return Err(Error::Usage(format!("step {} (t = {} s) is not a sample instant", self.k, self.t_s())));
        }
        self.begin();
        let t = self.t_s();
        let period = self.sc.sample_period_s;
        let d = Dynamics { sc: &self.sc, controller: None, memo: &self.ref_memo };
        let mut dmech = [0.0; MAX_MECH];
        let (x, dx) = (Extra { mech: &self.mech_state, ctrl: &[] }, self.mech_scratch(&mut dmech));
        let s0 = d.evaluate(t, &self.state, x, dx, self.plant.as_ref(), &self.held);
        let truth = d.truth(&self.state, &self.mech_state, s0.force_rate_n_per_s, self.plant.as_ref(), t, &self.held);
        let active: Vec<Option<f64>> = (0..self.sc.faults.len()).map(|i| self.fault_active(i, t)).collect();
        let at = |i: usize| active[i];
        let ControlBlock::Sampled(l) = &mut self.control else { unreachable!("is_sample_step") };
        let hook =
            (!l.sensor_faults.is_empty()).then_some((&mut l.sensor_faults, t, &at as &dyn Fn(usize) -> Option<f64>));
        let (y, counts) = l.sensors.sample_with(&truth, hook);
        l.sampled = Some(self.k);
        l.awaiting = Some(self.k);
        // The outer loop compares each reading with the reference at the reading's time,
        // and takes the knee rate from the piston-velocity sensor when there is one
        // (v / (dL/dq): no differencing lag), else from the encoder's difference.
        let t_reading = (t - self.sc.sensors.delay_samples as f64 * period).max(0.0);
        let knee_rate = match self.sc.leg() {
            Some(leg) if self.sc.sensors.piston_velocity.enabled => {
                y.piston_velocity_m_s / crate::leg::moment_arm_at(&leg.model, y.knee_rad)
            }
            _ => y.knee_rate_rad_s,
        };
        let d = Dynamics { sc: &self.sc, controller: None, memo: &self.ref_memo };
        self.held.knee_integral_rad_s = d.pd_integral(t_reading, self.held.knee_integral_rad_s, y.knee_rad, period);
        self.held.pd_force_n = d.pd_force(t_reading, y.knee_rad, knee_rate, self.held.knee_integral_rad_s);
        // The device's truth with the outer loop's force as the step will hold it (as the
        // row records it).
        let device_truth = self.device_truth(t, s0.force_rate_n_per_s);
        let ControlBlock::Sampled(l) = &mut self.control else { unreachable!("is_sample_step") };
        let hook =
            (!l.sensor_faults.is_empty()).then_some((&mut l.sensor_faults, t, &at as &dyn Fn(usize) -> Option<f64>));
        let (device, device_counts) = match (&mut l.device, device_truth) {
            (Some(dev), Some(dt)) => dev.sample_with(&dt, hook),
            _ => Default::default(),
        };
        if !self.sc.faults.is_empty() || self.faults.stopped.is_some() {
            self.sample_controller_faults(t);
        }
        let d = Dynamics { sc: &self.sc, controller: None, memo: &self.ref_memo };
        let r = d.reference_at(t, &self.held);
        // The next sample instant's time as that step will compute it (so its reference is
        // the one kept now).
        let every = self.sc.sample_every.unwrap_or(1);
        let r_next = d.reference_at((self.k + every) as f64 * self.sc.dt_s, &self.held);
        Ok(SampleInput {
            t_s: t,
            period_s: period,
            y,
            counts,
            device,
            device_counts,
            r,
            r_next,
            valve_limit: self.sc.valve_limit,
        })
    }

    /// What the device's sensors measure now (at `t`, the load cell's rate
    /// `force_rate_n_per_s`), when the run has them: the same truth the row's device columns
    /// record.
    fn device_truth(&self, t: f64, force_rate_n_per_s: f64) -> Option<crate::sensors::DeviceTruth> {
        self.sc.device.as_ref()?;
        let d = self.dynamics();
        let plant = self.plant.as_ref();
        let v = plant.piston_at(t).velocity_m_s;
        let f = d.cylinder_force(&self.state, v, &d.reference_at(t, &self.held));
        let arm = plant.leg_row().map_or(0.0, |l| l.moment_arm_m);
        let w1 = self.interaction(t, force_rate_n_per_s);
        Some(d.device_truth(&self.state, plant, f, arm, w1, true, &self.held))
    }

    /// Step 2 of a sampled step: hold the controller's output (clipped to the valve limit, and
    /// marked saturated when it was) until the next sample. A non-finite command stops the run
    /// (under `controller.on_stop = "failsafe"`: the device goes to its fail-safe state).
    pub fn hold(&mut self, out: ControlOutput) -> Result<()> {
        let t = self.t_s();
        let kind = || match &self.control {
            ControlBlock::Sampled(l) => l.ctrl.as_ref().map_or("external".to_string(), |c| c.kind().to_string()),
            ControlBlock::Continuous(_) => String::new(),
        };
        if let ControlBlock::Continuous(_) = &self.control {
            return Err(Error::Usage("hold(): the run's controller is continuous".into()));
        }
        let out = if out.valve_command.is_finite() {
            out
        } else if self.sc.on_stop == crate::control::OnStop::Failsafe {
            // A stop like any other: the device goes to its fail-safe state.
            let why = crate::control::ControlStop::command(format!("the valve command is {}", out.valve_command));
            self.go_failsafe(t, why);
            ControlOutput::default()
        } else {
            return Err(Error::ControllerStopped {
                time_s: t,
                controller: kind(),
                message: format!("the valve command is {}", out.valve_command),
            });
        };
        let out = self.sc.valve_limit.apply(out);
        let out = if self.sc.faults.is_empty() && self.faults.stopped.is_none() { out } else { self.timed_output(out) };
        if let ControlBlock::Sampled(l) = &self.control {
            if l.awaiting != Some(self.k) {
                return Err(Error::Usage(format!("hold() at step {} without sample() first", self.k)));
            }
        }
        let now = self.computed(out)?;
        let ControlBlock::Sampled(l) = &mut self.control else { return Ok(()) };
        l.awaiting = None;
        if let Some(c) = &l.ctrl {
            c.log_values(&mut l.log);
        }
        if let compute::Computed::Now(out) = now {
            l.hold.set(out);
            self.held.output = Some(out);
        }
        Ok(())
    }

    /// Record the logged values of an outside controller (the caller's loop), in the order of
    /// the names given when it was built with them.
    pub fn set_log(&mut self, values: &[f64]) {
        if let ControlBlock::Sampled(l) = &mut self.control {
            let n = MAX_LOGGED.min(values.len());
            l.log[..n].copy_from_slice(&values[..n]);
        }
    }

    /// Name the channels an outside caller logs with [`Self::set_log`] (before the first step;
    /// at most [`MAX_LOGGED`]).
    pub fn set_log_names(&mut self, names: Vec<String>) -> Result<()> {
        if names.len() > MAX_LOGGED || self.k > 0 {
            return Err(Error::Usage(format!(
                "at most {MAX_LOGGED} logged channels, named before the first step (got {})",
                names.len()
            )));
        }
        if let ControlBlock::Sampled(l) = &mut self.control {
            l.log_names = names;
        }
        Ok(())
    }

    /// The run's own controller at this step if it is a sample instant: sample, update, hold
    /// (nothing otherwise). [`Self::step`] is this and [`Self::advance`].
    pub fn control_step(&mut self) -> Result<()> {
        if !self.is_sample_step() {
            return Ok(());
        }
        let input = self.sample()?;
        let t = input.t_s;
        let skip = self.faults.skip;
        let ControlBlock::Sampled(l) = &mut self.control else { return Ok(()) };
        let Some(ctrl) = l.ctrl.as_mut() else {
            return Err(Error::Usage(format!("step {}: a sample instant needs a command (hold)", self.k)));
        };
        if skip {
            // A skipped or lost sample, or a controller in its fail-safe state: not called.
            let last = l.hold.value();
            return self.hold(last);
        }
        let out = match ctrl.update(&input) {
            Ok(out) => out,
            Err(e) if self.sc.on_stop == crate::control::OnStop::Failsafe => {
                self.go_failsafe(t, e);
                ControlOutput::default()
            }
            Err(e) => {
                return Err(Error::ControllerStopped {
                    time_s: t,
                    controller: ctrl.kind().to_string(),
                    message: e.message,
                })
            }
        };
        self.hold(out)
    }

    /// The continuous controller's turn at `t`: the outer loop from the plant's knee state and,
    /// at step 0, the controller state from the first ideal reading.
    fn control_continuous(&mut self, t: f64) {
        let d = self.dynamics();
        let q = self.plant.knee_rad();
        let integral = d.pd_integral(t, self.held.knee_integral_rad_s, q, self.sc.dt_s);
        let pd = d.pd_force(t, q, self.plant.knee_rate_rad_s(), integral);
        self.held.knee_integral_rad_s = integral;
        self.held.pd_force_n = pd;
        if self.k == 0 {
            let init = Held { output: Some(ControlOutput::default()), ..self.held };
            let d = self.dynamics();
            let mut dmech = [0.0; MAX_MECH];
            let (x, dx) = (Extra { mech: &self.mech_state, ctrl: &[] }, self.mech_scratch(&mut dmech));
            let s0 = d.evaluate(0.0, &self.state, x, dx, self.plant.as_ref(), &init);
            let mech = &self.mech_state;
            let y0: Measurement = d.truth(&self.state, mech, s0.force_rate_n_per_s, self.plant.as_ref(), 0.0, &init);
            let r0 = d.reference_at(0.0, &self.held);
            if let ControlBlock::Continuous(c) = &self.control {
                c.init(&y0, &r0, &mut self.controller_state);
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

    /// The body's forces on the carriage for the step from `t` (the human's other half, next
    /// to w1): its force laws at the body's state and the data's sample.
    fn body_forces(&mut self, t: f64) -> Option<crate::human::BodyForces> {
        let b = self.sc.leg()?.body.as_ref()?;
        let state = self.plant.body_state()?;
        let mut sample = b.targets.at(t);
        if let crate::human::BodyTargets::Walking(w) = &b.targets {
            if let Some(e) = &self.held.events {
                sample.other_share = e.other_share(t, w);
            }
            (sample.pelvis_x_m, sample.pelvis_x_rate_m_s) = w.pelvis_x_at(t, b.pelvis_drift_m_s);
        }
        let mut f = crate::human::body_forces(&b.hip, &b.wearer, &sample, &state);
        if let Some((ideal, mass_kg)) = &self.sc.ideal {
            // The data's moment is extensor positive, the knee's torque flexion positive.
            f.device_knee_torque_nm = -ideal.moment_nm(sample.knee_moment_nm, *mass_kg) - ideal.step_at(t);
        }
        if let (true, crate::human::BodyTargets::Walking(w)) = (self.wearer.is_some(), &b.targets) {
            let tilt = w.pelvic_tilt_at(t);
            let pct = w.pct_at(t);
            let x = crate::human::WearerInputs {
                joints: crate::muscles::analysis::Joints {
                    q_rad: [state.hip.0 + tilt.value, state.knee.0, state.ankle.0],
                    qd_rad_s: [state.hip.1 + tilt.rate, state.knee.1, state.ankle.1],
                    moment_nm: [0.0; 3],
                },
                body_rad: [state.hip.0, state.knee.0, state.ankle.0],
                body_rate_rad_s: [state.hip.1, state.knee.1, state.ankle.1],
                pct,
                stance_weight: w.stance_weight_at_pct(pct),
                device_torque_nm: self.device_knee_torque_nm(t) + f.device_knee_torque_nm,
            };
            let dt = self.sc.dt_s;
            let m = self.wearer.as_mut().map(|w| w.step(t, dt, &x)).unwrap_or_default();
            (f.hip_torque_nm, f.knee_torque_nm, f.ankle_torque_nm) = (m[0], m[1], m[2]);
        }
        Some(f)
    }

    /// The cylinder's torque at the knee now (N m, flexion positive: what the plant applies).
    fn device_knee_torque_nm(&self, t: f64) -> f64 {
        let d = self.dynamics();
        let v = self.plant.piston_at(t).velocity_m_s;
        let arm = self.plant.leg_row().map_or(0.0, |l| l.moment_arm_m);
        d.cylinder_force(&self.state, v, &d.reference_at(t, &self.held)) * arm
    }

    /// Advance one step with the run's own controller; the row of the step's start goes to
    /// `sink`.
    pub fn step(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        self.control_step()?;
        self.advance(sink)
    }

    /// Integrate one fixed step from `t_k` (after [`Self::sample`] and [`Self::hold`] at a
    /// sample instant); the row of `t_k` goes to `sink`.
    pub fn advance(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        if let ControlBlock::Sampled(l) = &self.control {
            if l.hold.is_sample(self.k) && (l.sampled != Some(self.k) || l.awaiting.is_some()) {
                return Err(Error::Usage(format!(
                    "step {} (t = {} s) is a sample instant: sample() and hold() come first",
                    self.k,
                    self.t_s()
                )));
            }
        }
        let dt = self.sc.dt_s;
        let t = self.t_s();
        self.begin();
        if let ControlBlock::Continuous(_) = self.control {
            self.control_continuous(t);
        }
        let s0 = self.record_start(t, sink)?;
        let start = self.state;
        let v0 = self.plant.piston_at(t).velocity_m_s;
        let r0 = self.dynamics().reference_at(t, &self.held);
        if self.hydraulic() {
            self.integrate(t, &s0)?;
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
            cuff_force_n: self.held.cuff_force_n,
            body: self.held.body,
            mech_end: (!self.mech_state.is_empty() && self.held.predictor.is_some()).then_some(&self.mech_state[..]),
        };
        let stroke = self.plant.advance(t, &inputs)?;
        // The plant's held forces changed with its step.
        self.ref_memo.borrow_mut().clear();
        let missed = self.hydraulic().then(|| {
            let seen = match &self.held.predictor {
                Some(_) => self.state.piston.position_m - start.piston.position_m,
                None => self.plant.piston_at(t + dt).position_m - self.plant.piston_at(t).position_m,
            };
            (self.plant.piston_at(t + dt).position_m, stroke - seen)
        });
        self.sc.cylinder.end_step_with(&mut self.state.hyd, missed, &self.held.valve);
        self.k += 1;
        self.check(t + dt)
    }

    /// Evaluate the step's start, hand its row to `sink`, and set the cuff force held over the
    /// step. Returns the start's evaluation with its packed derivative in `self.first`.
    fn record_start(&mut self, t: f64, sink: &mut dyn RecordSink) -> Result<stage::Stage> {
        let mut first = std::mem::take(&mut self.first);
        let (dp, dx) = first.split_at_mut(PLANT_LEN);
        let x = Extra { mech: &self.mech_state, ctrl: &self.controller_state };
        let dx = ExtraMut::split(dx, self.mech_state.len());
        let s0 = self.dynamics().evaluate(t, &self.state, x, dx, self.plant.as_ref(), &self.held);
        s0.derivative.pack_into(dp);
        self.first = first;
        let w1 = self.interaction(t, s0.force_rate_n_per_s);
        let mut row = self.dynamics().row(t, &self.state, &s0, w1, self.plant.as_ref(), &self.held);
        if let ControlBlock::Sampled(l) = &self.control {
            row.log = l.log;
        }
        row.fault_active = self.any_fault_active(t);
        row.muscles = self.muscle_sample(t);
        self.muscles_metabolic_w = row.muscles.as_ref().map(|v| v[v.len() - crate::muscles::analysis::TOTALS.len()]);
        sink.row(&row)?;
        let cuff_force_n = if self.sc.human.mode == HumanMode::Cuff { w1 } else { 0.0 };
        // The integrator's first stage is s0 unless coupled mechanics now see another cuff force.
        self.reuse_first = self.plant.coupled().is_none() || self.held.cuff_force_n == cuff_force_n;
        self.held.cuff_force_n = cuff_force_n;
        Ok(s0)
    }

    /// The wearer's muscles at `t` (with `wearer.muscles`): the joints' angles and rates (the
    /// hip's anatomical flexion, the thigh's angle plus the data's pelvic tilt) and the moments
    /// the body applies over the step.
    fn muscle_sample(&mut self, t: f64) -> Option<Arc<[f64]>> {
        if let Some(w) = &self.wearer {
            return w.sample_at(t).map(|s| Arc::from(&s.values[..]));
        }
        let a = self.muscles.as_mut()?;
        let b = self.plant.body_state()?;
        let tilt = match self.sc.leg().and_then(|l| l.body.as_ref()).map(|b| &b.targets) {
            Some(crate::human::BodyTargets::Walking(w)) => w.pelvic_tilt_at(t),
            _ => Default::default(),
        };
        let f = self.held.body.unwrap_or_default();
        let j = crate::muscles::analysis::Joints {
            q_rad: [b.hip.0 + tilt.value, b.knee.0, b.ankle.0],
            qd_rad_s: [b.hip.1 + tilt.rate, b.knee.1, b.ankle.1],
            moment_nm: [f.hip_torque_nm, f.knee_torque_nm, f.ankle_torque_nm],
        };
        Some(Arc::from(a.sample(&j).values))
    }

    /// Integrate the hydraulic (and predictor, coupled knee, continuous controller) states over
    /// the step from `t`, in as many substeps as their stiffness needs.
    fn integrate(&mut self, t: f64, s0: &stage::Stage) -> Result<()> {
        let n = self.substeps(t, s0.force_rate_n_per_s)?;
        let h = self.sc.dt_s / n as f64;
        let mut x = std::mem::take(&mut self.packed);
        let mut work = std::mem::take(&mut self.work);
        let mut k1 = std::mem::take(&mut self.scratch_k1);
        let reuse_first = self.reuse_first;
        let nm = self.mech_state.len();
        self.state.pack_into(&mut x);
        x[PLANT_LEN..PLANT_LEN + nm].copy_from_slice(&self.mech_state);
        x[PLANT_LEN + nm..].copy_from_slice(&self.controller_state);
        let d = self.dynamics();
        let (plant, held) = (self.plant.as_ref(), &self.held);
        let f = |tau: f64, xs: &[f64], dx: &mut [f64]| {
            let (xp, xe) = xs.split_at(PLANT_LEN);
            let (dp, de) = dx.split_at_mut(PLANT_LEN);
            let (xe, de) = (Extra::split(xe, nm), ExtraMut::split(de, nm));
            d.evaluate(tau, &State::unpack(xp), xe, de, plant, held).derivative.pack_into(dp);
        };
        for i in 0..n {
            let ti = t + i as f64 * h;
            if i == 0 && reuse_first {
                self.sc.integrator.step_in_place(ti, h, &mut x, &self.first, &mut work, f);
            } else {
                f(ti, &x, &mut k1);
                self.sc.integrator.step_in_place(ti, h, &mut x, &k1, &mut work, f);
            }
        }
        self.state = State::unpack(&x);
        self.mech_state.copy_from_slice(&x[PLANT_LEN..PLANT_LEN + nm]);
        self.controller_state.copy_from_slice(&x[PLANT_LEN + nm..]);
        (self.packed, self.work, self.scratch_k1) = (x, work, k1);
        Ok(())
    }

    /// Substeps the integrated states need over this step: the local stiffness (force-channel or
    /// chamber-pressure rate, spool, piston friction over the effective mass, oil column) must
    /// stay within half the integrator's stability limit, the reduced engine's contact
    /// ([`crate::plant::CoupledMechanics::stiffness`]) within [`CONTACT_MARGIN`] of it. More
    /// than [`MAX_SUBSTEPS`] stops the run with [`Error::Stiff`] naming the state and the step
    /// it needs.
    fn substeps(&mut self, t: f64, force_rate_n_per_s: f64) -> Result<usize> {
        let dt = self.sc.dt_s;
        let xc = match &self.held.predictor {
            Some(_) => self.state.piston.position_m,
            None => self.plant.piston_at(t).position_m,
        };
        let (rate, k_oil) = self.sc.cylinder.local_stiffness_with(&self.state.hyd, xc, &self.held.valve);
        // Each stiffness with the fraction of the stability limit it may use: the leg's contact
        // dampers and springs, whose modes are damped, use more of it than the hydraulics.
        let mut real = (rate, "hydraulic pressure / load force", STABILITY_MARGIN);
        let mut imag = (0.0, "oil column (piston)", STABILITY_MARGIN);
        if let Some(p) = &self.held.predictor {
            let fric = self.sc.friction.slope_n_s_per_m(self.state.piston.velocity_m_s) / p.effective_mass_kg;
            if fric > real.0 {
                real = (fric, "piston velocity (seal friction)", STABILITY_MARGIN);
            }
            imag.0 = (k_oil / p.effective_mass_kg).sqrt();
        }
        let (lim_re, lim_im) = self.sc.integrator.stability_limits();
        let n_of =
            |(rate, _, margin): (f64, &str, f64), lim: f64| if lim > 0.0 { rate * dt / (margin * lim) } else { 0.0 };
        if let (Some(c), false) = (self.plant.coupled(), self.mech_state.is_empty()) {
            let (rate, w) = c.stiffness();
            let (contact_re, contact_im) = (
                (rate, "leg contact (sole dampers)", CONTACT_MARGIN),
                (w, "leg contact (sole springs)", CONTACT_MARGIN),
            );
            if n_of(contact_re, lim_re) > n_of(real, lim_re) {
                real = contact_re;
            }
            if n_of(contact_im, lim_im) > n_of(imag, lim_im) {
                imag = contact_im;
            }
        }
        if let (ControlBlock::Continuous(c), true) = (&self.control, self.sc.substep_controller) {
            let k = c.stiffness_per_s(force_rate_n_per_s, &self.controller_state);
            let observer = (k, "controller observer (FDO)", STABILITY_MARGIN);
            if n_of(observer, lim_re) > n_of(real, lim_re) {
                real = observer;
            }
        }
        let (n_real, n_imag) = (n_of(real, lim_re), n_of(imag, lim_im));
        let need = n_real.max(n_imag).ceil().max(1.0);
        if need > MAX_SUBSTEPS as f64 || !need.is_finite() {
            let ((rate, state, margin), lim) = if n_real >= n_imag { (real, lim_re) } else { (imag, lim_im) };
            return Err(Error::Stiff {
                time_s: t,
                state: state.into(),
                step_s: dt,
                rate_per_s: rate,
                needed_step_s: margin * lim / rate,
            });
        }
        let n = need as usize;
        self.max_substeps = self.max_substeps.max(n);
        self.substepped_steps += usize::from(n > 1);
        Ok(n)
    }

    /// What the leg's end stops did so far (leg runs).
    pub fn stop_report(&self) -> Option<crate::leg::StopReport> {
        self.plant.stop_report()
    }

    /// Sensor readings that clipped at full scale, by channel (sampled mode).
    pub fn sensor_clips(&self) -> Vec<(&'static str, usize)> {
        match &self.control {
            ControlBlock::Sampled(l) => l.sensors.clipped(),
            ControlBlock::Continuous(_) => Vec::new(),
        }
    }

    /// Most substeps of the hydraulic states in one step so far, and how many steps needed
    /// more than one.
    pub fn substep_stats(&self) -> (usize, usize) {
        (self.max_substeps, self.substepped_steps)
    }

    /// Stop on a non-finite state (a stopped controller's aside) or an implausible spool.
    fn check(&self, t: f64) -> Result<()> {
        let mech = self.mech_state.iter().zip(self.mech_names).find(|(v, _)| !v.is_finite());
        let bad = mech.map(|(v, n)| (n.to_string(), *v));
        let bad =
            bad.or_else(|| self.state.first_non_finite(&self.controller_state, &self.controller_names)).or_else(|| {
                match &self.control {
                    // A stopped controller (the device in its fail-safe state) is not called
                    // again: its state no longer matters.
                    ControlBlock::Sampled(_) if self.faults.stopped.is_some() => None,
                    ControlBlock::Sampled(l) => l.ctrl.as_ref().and_then(|c| c.first_non_finite()),
                    ControlBlock::Continuous(_) => None,
                }
            });
        if let Some((state, value)) = bad {
            return Err(Error::Diverged { time_s: t, state: self.with_hint(state), value });
        }
        // No valve spool travels a metre: a run whose spool does has gone unstable even if the
        // numbers are still finite (e.g. held against a pressure limit).
        let xv = self.state.hyd.spool_m;
        if xv.abs() > MAX_PLAUSIBLE_SPOOL_M {
            return Err(Error::Diverged { time_s: t, state: self.with_hint("spool_m (beyond 1 m)".into()), value: xv });
        }
        Ok(())
    }

    /// A diverged state's name, with the likely cause when a continuous controller has a stiff
    /// observer the loop does not substep (the paper's FDO: its cubic term outruns a 1 ms step
    /// at a heel strike).
    fn with_hint(&self, state: String) -> String {
        let observer = match &self.control {
            ControlBlock::Continuous(c) => c.stiffness_per_s(0.0, &vec![0.0; self.controller_state.len()]) > 0.0,
            ControlBlock::Sampled(_) => false,
        };
        match observer && !self.sc.substep_controller {
            true => format!(
                "{state}; the controller's observer may be stiffer than sim.dt_s: try sim.substep_controller = true or a smaller step"
            ),
            false => state,
        }
    }

    /// The row of the state now, evaluated the way the next step would see it (with the
    /// command held so far): what [`Self::finish`] records, and an FMU's outputs between
    /// steps. It changes nothing the run computes.
    pub fn row_now(&mut self) -> Row {
        let t = self.t_s();
        self.begin();
        let d = self.dynamics();
        let mut dc = vec![0.0; self.controller_state.len()];
        let mut dm = vec![0.0; self.mech_state.len()];
        let x = Extra { mech: &self.mech_state, ctrl: &self.controller_state };
        let s =
            d.evaluate(t, &self.state, x, ExtraMut { mech: &mut dm, ctrl: &mut dc }, self.plant.as_ref(), &self.held);
        let w1 = self.interaction(t, s.force_rate_n_per_s);
        let mut row = d.row(t, &self.state, &s, w1, self.plant.as_ref(), &self.held);
        if let ControlBlock::Sampled(l) = &self.control {
            row.log = l.log;
        }
        row.fault_active = self.any_fault_active(t);
        row.muscles = self.muscle_sample(t);
        row
    }

    /// Record the final state, evaluated the way the next step would see it.
    pub fn finish(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        let row = self.row_now();
        sink.row(&row)
    }
}

impl SampledLoop {
    /// The sensors and hold of a sampled run every `every` steps, with `ctrl` (None: the caller
    /// gives the commands).
    fn new(sc: &Model, every: usize, ctrl: Option<Box<dyn DiscreteController>>) -> Self {
        Self {
            ctrl,
            sensors: SampledSensors::new(&sc.sensors, sc.sample_period_s, sc.seed),
            sensor_faults: crate::sensors::SensorFaults::new(&sc.faults, sc.seed),
            device: sc.device.clone().map(|d| {
                let alpha = crate::sensors::derivative_alpha(sc.sensors.derivative_cutoff_hz, sc.sample_period_s);
                DeviceSensors::new(d, sc.sample_period_s, sc.sensors.delay_samples, alpha, sc.seed)
            }),
            hold: ZeroOrderHold::new(every, ControlOutput::default()),
            awaiting: None,
            sampled: None,
            log_names: Vec::new(),
            log: [0.0; MAX_LOGGED],
        }
    }
}
