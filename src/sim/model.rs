//! The immutable model of a run (MuJoCo's `mjModel`): every block's parameters, resolved,
//! with shared leg models. Built once by `scenario::resolve`; the loop only reads it.

use crate::control::{ControllerSetup, KneePd, NominalModel, ValveLimit};
use crate::disturbance::Disturbances;
use crate::human::HumanParams;
use crate::hydraulics::{ActuatorParams, Cylinder, FrictionParams};
use crate::integrator::Integrator;
use crate::metrics::MetricSettings;
use crate::plant::{LegSetup, PlantSetup};
use crate::reference::ForceReference;
use crate::sensors::SensorParams;

/// Everything the co-simulation loop needs, resolved and validated.
#[derive(Debug, Clone)]
pub struct Model {
    /// Where the scenario came from (for messages).
    pub source_name: String,
    /// Number of fixed steps.
    pub steps: usize,
    /// Fixed step (s).
    pub dt_s: f64,
    /// Integration scheme for the force channel, predictor and controller states.
    pub integrator: Integrator,
    /// Substep the continuous controller's stiff states too.
    pub substep_controller: bool,
    /// Seed of every random element.
    pub seed: u64,
    /// Controller sampling: every this many steps (None = continuous).
    pub sample_every: Option<usize>,
    /// Controller sample period (s), 0 = continuous.
    pub sample_period_s: f64,
    /// The plant.
    pub plant: PlantSetup,
    /// The desired force (and knee trajectory).
    pub reference: ForceReference,
    /// exoleg computes a desired force (`reference.force = "computed"`); false: the controller
    /// decides the assistance and the desired force is NaN everywhere.
    pub desired_force: bool,
    /// The gait cascade's outer knee PD (gait runs on the leg).
    pub knee_pd: Option<KneePd>,
    /// The cylinder of the plant.
    pub cylinder: Cylinder,
    /// The controller, resolved (one tagged value per kind; `dtznn` designed, a plugin
    /// loaded); a run builds its controller from it unless the caller brings one.
    pub controller: ControllerSetup,
    /// The controller's nominal model.
    pub nominal: NominalModel,
    /// Piston friction.
    pub friction: FrictionParams,
    /// Actuator mode and limits.
    pub actuator: ActuatorParams,
    /// The valve's command limit (from `actuator.valve_command_limit`).
    pub valve_limit: ValveLimit,
    /// Human-robot interaction.
    pub human: HumanParams,
    /// Injected disturbances.
    pub disturbance: Disturbances,
    /// Sensors (sampled mode).
    pub sensors: SensorParams,
    /// The device's own sensors as the chain runs them (sampled mode; None for a continuous
    /// controller).
    pub device: Option<crate::sensors::DeviceSetup>,
    /// The time series carries the device's columns (leg runs with a sampled controller).
    pub device_columns: bool,
    /// Metric settings.
    pub metrics: MetricSettings,
    /// What breaks, when (`[[faults]]`).
    pub faults: Vec<crate::faults::Fault>,
    /// What a sampled controller's stop does (`controller.on_stop`).
    pub on_stop: crate::control::OnStop,
    /// The controller's modelled computation on the target (None: its command takes effect
    /// at its sample instant).
    pub compute: Option<super::ComputeModel>,
    /// The safety verdicts' limits (`[safety]`).
    pub safety: crate::metrics::SafetyLimits,
    /// The cuff interaction-force limits of the wearer's figures (`[cuff_limits]`).
    pub cuff_limits: crate::metrics::CuffLimits,
    /// The wearer's muscle analysis (`wearer.muscles`; walking runs).
    pub muscles: Option<std::sync::Arc<crate::muscles::analysis::MuscleSetup>>,
    /// The time series carries the muscles' columns (`output.muscles`).
    pub muscle_columns: bool,
    /// The ideal device (`controller.kind = "ideal_moment"`) and the subject's mass (kg) its
    /// bound is per.
    pub ideal: Option<(crate::control::ideal::IdealParams, f64)>,
    /// The muscle wearer (`wearer.model = "muscles"`): its muscles make the body's hip, knee
    /// and ankle moments.
    pub muscle_wearer: Option<std::sync::Arc<crate::human::MuscleWearerSetup>>,
}

impl Model {
    /// The leg setup, for leg runs.
    pub fn leg(&self) -> Option<&LegSetup> {
        match &self.plant {
            PlantSetup::Leg(l) => Some(l),
            PlantSetup::Bench(_) => None,
        }
    }

    /// Whether the run walks: a leg on the ground with the body following a gait (the runs
    /// that detect gait events).
    pub fn walking(&self) -> bool {
        is_walking(&self.plant)
    }
}

/// Whether `plant` walks (see [`Model::walking`]).
pub fn is_walking(plant: &PlantSetup) -> bool {
    matches!(plant, PlantSetup::Leg(l) if l.ground.is_some()
        && l.body.as_ref().is_some_and(|b| matches!(b.targets, crate::human::BodyTargets::Walking(_))))
}
