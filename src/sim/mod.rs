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

mod advance;
mod compute;
mod control;
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
///
/// A loop you own: at each sample instant read the sensors ([`Simulation::sample`]), give a
/// command ([`Simulation::hold`]), then step to the next instant ([`Simulation::advance`]).
///
/// ```
/// use exoleg::control::ControlOutput;
/// use std::sync::Arc;
/// let sets = ["plant.kind=\"bench\"", "sim.duration_s=0.1", "controller.sample_period_s=0.001"];
/// let sc = exoleg::load(None, &sets).unwrap();
/// let mut sim = exoleg::Simulation::external(Arc::clone(&sc.model)).unwrap();
/// let mut sink = exoleg::record::NullSink;
/// while !sim.done() {
///     if sim.is_sample_step() {
///         let s = sim.sample().unwrap();
///         let e = s.r.value - s.y.force_n; // desired minus measured load force (N)
///         sim.hold(ControlOutput::command(1e-4 * e)).unwrap();
///     }
///     sim.advance(&mut sink).unwrap();
/// }
/// assert!((sim.t_s() - 0.1).abs() < 1e-9);
/// ```
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
