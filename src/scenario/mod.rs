//! Scenario files: a serde mirror of the TOML ([`ScenarioFile`]), `--set` overrides, and
//! validation into a [`Scenario`] with errors that name the file, the key and the problem.
//!
//! Every key has a default, so a scenario file lists only what it changes; unknown keys are
//! an error. The embedded default scenario is the paper's Figure 5 case.

mod overrides;
mod validate;

use crate::control::{ControllerKind, ObserverParams, RbfParams};
use crate::disturbance::Disturbances;
use crate::error::{Error, Result};
use crate::human::HumanParams;
use crate::hydraulics::{ActuatorParams, FrictionParams, HydraulicParams};
use crate::integrator::Integrator;
use crate::plant::{BenchParams, LegParams, PlantKind};
use crate::reference::{GaitCycle, GaitReference, BUILTIN_TRIALS};
use crate::sensors::SensorParams;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The embedded default scenario (paper Figure 5: F_d = 200 sin(4 pi t), gamma = 100).
pub const DEFAULT_SCENARIO_TOML: &str = include_str!("../../assets/scenarios/default.toml");
/// The name errors use for the embedded default scenario.
pub const DEFAULT_SCENARIO_NAME: &str = "<embedded default scenario>";

/// `[sim]`: time stepping.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimSection {
    /// Fixed step (s). Default 0.001. > 0.
    pub dt_s: f64,
    /// Simulated duration (s). Default 1.0. > 0.
    pub duration_s: f64,
    /// `euler`, `ode3` (default, the paper's solver) or `rk4`.
    pub integrator: Integrator,
}

impl Default for SimSection {
    fn default() -> Self {
        Self { dt_s: 0.001, duration_s: 1.0, integrator: Integrator::Ode3 }
    }
}

/// `[plant]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlantSection {
    /// `leg` (default: the URDF leg in Rapier) or `bench` (force-loading rig).
    pub kind: PlantKind,
}

impl Default for PlantSection {
    fn default() -> Self {
        Self { kind: PlantKind::Leg }
    }
}

/// Reference kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReferenceKind {
    /// Desired force `offset_n + amplitude_n*sin(2*pi*frequency_hz*t + phase_rad)`.
    Sine,
    /// A knee (and hip) gait trajectory; the desired force comes from the leg's inverse
    /// dynamics plus an outer PD on the knee angle (leg plant only).
    Gait,
}

/// `[reference]`: the desired load force (`sine`) or knee trajectory (`gait`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReferenceSection {
    /// `sine` (default) or `gait`.
    pub kind: ReferenceKind,
    /// Sine: amplitude of the desired force (N). Default 200. >= 0.
    pub amplitude_n: f64,
    /// Sine: frequency (Hz). Default 2. >= 0.
    pub frequency_hz: f64,
    /// Sine: phase (rad). Default 0.
    pub phase_rad: f64,
    /// Sine: offset (N). Default 0.
    pub offset_n: f64,
    /// Gait: built-in trial (`wbds01_overground_comfortable` (default), `..._fast`, `..._slow`,
    /// and the same for `wbds02`), used unless `gait_file` is set.
    pub gait_trial: String,
    /// Gait: a CSV with `gait_cycle_pct`, `knee_flexion_deg` (and `hip_flexion_deg`) columns,
    /// looked up next to the scenario file first, then in the working directory.
    pub gait_file: Option<String>,
    /// Gait: stride (gait-cycle) time (s). Default: the trial's (comfortable 1.10, fast 0.95,
    /// slow 1.30); required for a `gait_file` unless `cadence_steps_per_min` is given.
    pub stride_s: Option<f64>,
    /// Gait: cadence (steps/min, two steps per stride); alternative to `stride_s`.
    pub cadence_steps_per_min: Option<f64>,
    /// Gait: harmonics of the periodic Fourier fit of the angles. Default 12. 1..=40.
    pub harmonics: usize,
    /// Gait: drive the thigh along the trial's hip angle (kinematic hip joint). Default true.
    pub drive_hip: bool,
    /// Gait: outer-loop proportional gain on the knee angle error (N m/rad). Default 400. >= 0.
    pub knee_kp_nm_per_rad: f64,
    /// Gait: outer-loop derivative gain on the knee rate error (N m s/rad). Default 15. >= 0.
    pub knee_kd_nm_s_per_rad: f64,
}

impl Default for ReferenceSection {
    fn default() -> Self {
        Self {
            kind: ReferenceKind::Sine,
            amplitude_n: 200.0,
            frequency_hz: 2.0,
            phase_rad: 0.0,
            offset_n: 0.0,
            gait_trial: "wbds01_overground_comfortable".into(),
            gait_file: None,
            stride_s: None,
            cadence_steps_per_min: None,
            harmonics: 12,
            drive_hip: true,
            knee_kp_nm_per_rad: 400.0,
            knee_kd_nm_s_per_rad: 15.0,
        }
    }
}

/// Find a file a scenario names: an absolute path as is; a relative one next to the scenario
/// file first (`base_dir`), then in the working directory. The error names the key and the
/// places tried.
pub fn resolve_path(source_name: &str, key: &str, file: &str, base_dir: Option<&Path>) -> Result<std::path::PathBuf> {
    let p = Path::new(file);
    let candidates: Vec<std::path::PathBuf> = if p.is_absolute() {
        vec![p.to_path_buf()]
    } else {
        base_dir.map(|d| d.join(p)).into_iter().chain(std::iter::once(p.to_path_buf())).collect()
    };
    candidates.iter().find(|c| c.is_file()).cloned().ok_or_else(|| {
        let tried: Vec<String> = candidates.iter().map(|c| c.display().to_string()).collect();
        Error::input(source_name, key, format!("file not found (tried {})", tried.join(", ")))
    })
}

impl ReferenceSection {
    /// Load the gait trajectory this section describes. `base_dir`: the scenario's directory.
    pub fn gait(&self, source_name: &str, base_dir: Option<&Path>) -> Result<GaitReference> {
        let (cycle, default_stride) = match &self.gait_file {
            Some(file) => {
                let found = resolve_path(source_name, "reference.gait_file", file, base_dir)?;
                let found = &found;
                let text = std::fs::read_to_string(found)
                    .map_err(|e| Error::Read { path: found.clone(), message: e.to_string() })?;
                (GaitCycle::parse(&found.display().to_string(), &text, self.harmonics)?, None)
            }
            None => match GaitCycle::builtin(&self.gait_trial, self.harmonics) {
                Some(r) => {
                    let (c, s) = r?;
                    (c, Some(s))
                }
                None => {
                    let names: Vec<&str> = BUILTIN_TRIALS.iter().map(|t| t.0).collect();
                    return Err(Error::input(
                        source_name,
                        "reference.gait_trial",
                        format!("unknown trial `{}` (built-in: {})", self.gait_trial, names.join(", ")),
                    ));
                }
            },
        };
        let stride_s = match (self.stride_s, self.cadence_steps_per_min, default_stride) {
            (Some(s), _, _) => s,
            (None, Some(c), _) => 120.0 / c,
            (None, None, Some(s)) => s,
            (None, None, None) => {
                return Err(Error::input(
                    source_name,
                    "reference.stride_s",
                    "a gait_file gives no timing: set reference.stride_s or reference.cadence_steps_per_min",
                ))
            }
        };
        Ok(GaitReference { cycle, stride_s })
    }
}

/// `[controller.nominal]`: the hydraulic parameters the controller assumes. Each key that
/// is absent takes the plant's value from `[hydraulics]` (a perfect model).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NominalSection {
    /// Assumed bulk modulus (Pa).
    pub beta_pa: Option<f64>,
    /// Assumed volume V0 (m^3).
    pub v0_m3: Option<f64>,
    /// Assumed flow gain K_q (m^2/s).
    pub k_q: Option<f64>,
    /// Assumed flow-pressure coefficient K_c (m^3/(s Pa)).
    pub k_c: Option<f64>,
    /// Assumed leakage 2*C_in + C_ex (m^3/(s Pa)).
    pub leakage: Option<f64>,
    /// Assumed spool time constant (s).
    pub tau_s: Option<f64>,
    /// Assumed valve gain.
    pub k_s: Option<f64>,
    /// Assumed area A1 (m^2).
    pub a1_m2: Option<f64>,
    /// Assumed area A2 (m^2).
    pub a2_m2: Option<f64>,
}

impl NominalSection {
    /// The controller's parameter set: the plant's, with the given assumptions replacing it.
    pub fn apply(&self, plant: &HydraulicParams) -> HydraulicParams {
        let mut p = plant.clone();
        let pick = |o: Option<f64>, v: &mut f64| {
            if let Some(x) = o {
                *v = x
            }
        };
        pick(self.beta_pa, &mut p.beta_pa);
        pick(self.v0_m3, &mut p.v0_m3);
        pick(self.k_q, &mut p.k_q);
        pick(self.k_c, &mut p.k_c);
        pick(self.leakage, &mut p.leakage);
        pick(self.tau_s, &mut p.tau_s);
        pick(self.k_s, &mut p.k_s);
        pick(self.a1_m2, &mut p.a1_m2);
        pick(self.a2_m2, &mut p.a2_m2);
        p
    }
}

/// `[controller]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerSection {
    /// `znn`, `arbfnn_fdo_znn` (default) or `erl_smc`.
    pub kind: ControllerKind,
    /// ZNN design parameter gamma (1/s). Default 100. > 0.
    pub gamma: f64,
    /// ERL-SMC reaching gain k (1/s). Default 100. > 0.
    pub k: f64,
    /// ERL-SMC surface slope delta (1/s). Default 15. > 0.
    pub delta: f64,
    /// ERL-SMC switching gain zeta (N/s^2). Default 10. >= 0.
    pub zeta: f64,
    /// Controller sample period (s); 0 = continuous (evaluated at every solver stage).
    /// Otherwise a whole multiple of `sim.dt_s`. Default 0.
    pub sample_period_s: f64,
    /// RBF network.
    pub rbf: RbfParams,
    /// Fixed-time disturbance observer.
    pub observer: ObserverParams,
    /// The model the controller assumes.
    pub nominal: NominalSection,
}

impl Default for ControllerSection {
    fn default() -> Self {
        Self {
            kind: ControllerKind::ArbfnnFdoZnn,
            gamma: 100.0,
            k: 100.0,
            delta: 15.0,
            zeta: 10.0,
            sample_period_s: 0.0,
            rbf: RbfParams::default(),
            observer: ObserverParams::default(),
            nominal: NominalSection::default(),
        }
    }
}

/// `[metrics]`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsSection {
    /// Band for the convergence time (N). Default: 1% of the reference amplitude (sine) or of
    /// the largest desired force of the run (gait).
    pub convergence_band_n: Option<f64>,
    /// Settling window excluded from the "after settling" figures (s). Default 0. >= 0.
    pub settle_s: f64,
}

/// `[criteria]`: pass/fail limits checked after a run (absent = not checked). A run whose
/// criteria fail still writes its outputs and exits with code 4.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CriteriaSection {
    /// Limit on max |F_L - F_d| after the settling window (N).
    pub max_force_error_n: Option<f64>,
    /// Limit on the RMS force error after the settling window (N).
    pub rms_force_error_n: Option<f64>,
    /// Limit on the knee RMS error after the settling window (deg).
    pub knee_rms_error_deg: Option<f64>,
    /// Limit on max |knee error| after the settling window (deg).
    pub knee_max_error_deg: Option<f64>,
    /// Limit on the fraction of samples with the valve command saturated.
    pub max_valve_saturation_fraction: Option<f64>,
    /// Limit on the fraction of samples at the supply-pressure force limit.
    pub max_force_limit_fraction: Option<f64>,
}

/// The scenario file as written (every key defaulted). Also what `summary.json` records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScenarioFile {
    /// Seed of every random element (random disturbances). Default 1.
    pub seed: u64,
    /// Time stepping.
    pub sim: SimSection,
    /// Plant choice.
    pub plant: PlantSection,
    /// Bench plant settings.
    pub bench: BenchParams,
    /// Leg plant settings.
    pub leg: LegParams,
    /// Valve and cylinder.
    pub hydraulics: HydraulicParams,
    /// Piston friction.
    pub friction: FrictionParams,
    /// Actuator mode and limits.
    pub actuator: ActuatorParams,
    /// Desired force.
    pub reference: ReferenceSection,
    /// Force controller.
    pub controller: ControllerSection,
    /// Sensors (sampled mode).
    pub sensors: SensorParams,
    /// Injected disturbances.
    pub disturbance: Disturbances,
    /// Human-robot interaction.
    pub human: HumanParams,
    /// Metric settings.
    pub metrics: MetricsSection,
    /// Pass/fail criteria.
    pub criteria: CriteriaSection,
}

impl Default for ScenarioFile {
    fn default() -> Self {
        Self {
            seed: 1,
            sim: SimSection::default(),
            plant: PlantSection::default(),
            bench: BenchParams::default(),
            leg: LegParams::default(),
            hydraulics: HydraulicParams::default(),
            friction: FrictionParams::default(),
            actuator: ActuatorParams::default(),
            reference: ReferenceSection::default(),
            controller: ControllerSection::default(),
            sensors: SensorParams::default(),
            disturbance: Disturbances::default(),
            human: HumanParams::default(),
            metrics: MetricsSection::default(),
            criteria: CriteriaSection::default(),
        }
    }
}

/// A validated scenario, ready to build a simulation from.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Where it came from (file path or the embedded default's name).
    pub source_name: String,
    /// Directory of the scenario file, for relative paths inside it (None for the embedded one).
    pub base_dir: Option<std::path::PathBuf>,
    /// The resolved values.
    pub file: ScenarioFile,
}

impl Scenario {
    /// Load a scenario from a TOML file (or, for `.json`, a scenario or a `summary.json`
    /// whose `scenario` field is used), apply `--set key=value` overrides, validate.
    /// `None` loads the embedded default.
    pub fn load(path: Option<&Path>, sets: &[String]) -> Result<Scenario> {
        let (name, table) = match path {
            None => (
                DEFAULT_SCENARIO_NAME.to_string(),
                overrides::parse_toml(DEFAULT_SCENARIO_NAME, DEFAULT_SCENARIO_TOML)?,
            ),
            Some(p) => {
                let name = p.display().to_string();
                let text = std::fs::read_to_string(p)
                    .map_err(|e| Error::Read { path: p.to_path_buf(), message: e.to_string() })?;
                let table = if p.extension().is_some_and(|e| e == "json") {
                    overrides::parse_json(&name, &text)?
                } else {
                    overrides::parse_toml(&name, &text)?
                };
                (name, table)
            }
        };
        let base = path.and_then(|p| p.parent()).map(|d| d.to_path_buf());
        Self::from_table(name, table, sets).map(|s| Scenario { base_dir: base, ..s })
    }

    /// Parse scenario text (TOML) with a name for error messages, apply overrides, validate.
    pub fn from_toml_str(name: &str, text: &str, sets: &[String]) -> Result<Scenario> {
        Self::from_table(name.to_string(), overrides::parse_toml(name, text)?, sets)
    }

    fn from_table(name: String, mut table: toml::Table, sets: &[String]) -> Result<Scenario> {
        for s in sets {
            overrides::apply_set(&mut table, s)?;
        }
        let source = if sets.is_empty() { name.clone() } else { format!("{name} (with --set)") };
        let file: ScenarioFile = serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(|e| {
            let key = e.path().to_string();
            let msg = e.into_inner().to_string();
            // The TOML deserialiser appends "in `key`" on a second line; the key is already named.
            let msg = msg.lines().next().unwrap_or_default().to_string();
            Error::input(&source, if key == "." { String::new() } else { key }, msg)
        })?;
        validate::validate(&source, &file)?;
        Ok(Scenario { source_name: source, base_dir: None, file })
    }

    /// Same scenario with overrides applied on top (used by `compare` and sweeps).
    pub fn with_sets(&self, sets: &[String]) -> Result<Scenario> {
        let table = match toml::Value::try_from(&self.file) {
            Ok(toml::Value::Table(t)) => t,
            _ => return Err(Error::input(&self.source_name, "", "cannot re-serialise scenario")),
        };
        let s = Self::from_table(self.source_name.clone(), table, sets)?;
        Ok(Scenario { base_dir: self.base_dir.clone(), ..s })
    }

    /// Convergence band (N): the scenario's, or 1% of the reference amplitude.
    pub fn convergence_band_n(&self) -> f64 {
        self.file.metrics.convergence_band_n.unwrap_or(0.01 * self.file.reference.amplitude_n)
    }

    /// Number of fixed steps in the run.
    pub fn steps(&self) -> usize {
        (self.file.sim.duration_s / self.file.sim.dt_s).round() as usize
    }
}
