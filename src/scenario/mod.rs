//! Scenario files: a serde mirror of the TOML ([`ScenarioFile`]), `--set` overrides, and
//! validation into a [`Scenario`] with errors that name the file, the key and the problem.
//!
//! Every key has a default, so a scenario file lists only what it changes; unknown keys are
//! an error. The embedded default scenario is the paper's Figure 5 case.

mod faults;
mod files;
mod overrides;
mod resolve;
pub(crate) mod validate;

pub use faults::*;
pub use files::*;
pub use resolve::*;

use crate::control::ControllerParams;
use crate::disturbance::Disturbances;
use crate::error::{Error, Result};
use crate::human::{HipParams, HumanParams, WearerParams};
use crate::hydraulics::{ActuatorParams, FrictionParams, HydraulicParams};
use crate::metrics::Criteria;
use crate::plant::{BenchParams, GroundParams, LegParams, PlantKind};
use crate::sensors::SensorParams;
use crate::sim::Integrator;
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
    /// Substep a stiff continuous controller too (the FDO's cubic term under a large
    /// disturbance), so it is integrated as the continuous law it is, up to the substep cap.
    /// Default false: the controller is integrated at `dt_s` like fixed-step code, and the
    /// observer diverges beyond the limit the README gives ("Observer limits").
    pub substep_controller: bool,
}

impl Default for SimSection {
    fn default() -> Self {
        Self { dt_s: 0.001, duration_s: 1.0, integrator: Integrator::Ode3, substep_controller: false }
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
    /// A constant knee and hip angle held by the outer PID alone (static tests; leg plant).
    Pose,
}

/// Where the desired force comes from (`reference.force`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum DesiredForce {
    /// exoleg computes it: the sine, or the gait cascade (inverse dynamics + the outer knee
    /// loop, the stance assistance) for a gait or a pose.
    #[default]
    Computed,
    /// None: the controller decides the assistance itself from the device's sensors; the
    /// reference readings are NaN and the run is scored by what the wearer gets, not by a
    /// force error (the wearer still walks the gait data).
    None,
}

/// `[reference]`: the desired load force (`sine`) or knee trajectory (`gait`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReferenceSection {
    /// `sine` (default) or `gait`.
    pub kind: ReferenceKind,
    /// `computed` (default) or `none`: see [`DesiredForce`].
    pub force: DesiredForce,
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
    /// Gait: SHA-256 of the gait data used (file or built-in trial); filled in by every run.
    /// When set, a run warns if the data have changed since.
    pub gait_sha256: Option<String>,
    /// Gait: stride (gait-cycle) time (s). Default: the trial's (comfortable 1.10, fast 0.95,
    /// slow 1.30); required for a `gait_file` unless `cadence_steps_per_min` is given.
    pub stride_s: Option<f64>,
    /// Gait: cadence (steps/min, two steps per stride); alternative to `stride_s`.
    pub cadence_steps_per_min: Option<f64>,
    /// Gait: harmonics of the periodic Fourier fit of the angles. Default 12. 1..=40.
    pub harmonics: usize,
    /// Deprecated: `hip.mode = "driven"` (true) or `"fixed"` (false). Read for old scenarios
    /// and summaries, with a warning.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drive_hip: Option<bool>,
    /// Pose: knee flexion to hold (deg). Default 20. Within the URDF's knee range.
    pub knee_deg: f64,
    /// Pose: hip flexion (deg). Default 10. -60..=120.
    pub hip_deg: f64,
    /// Gait and pose: outer-loop integral gain on the knee angle error (N m/(rad s)), with the
    /// integral's torque clamped to +-300 N m. Default 0. >= 0.
    pub knee_ki_nm_per_rad_s: f64,
    /// Gait on the carriage: the exoskeleton's stance assistance, a fraction of the data's knee
    /// moment over the moment arm; the cascade (inverse dynamics + PD) acts in swing, the two
    /// blended with the stance weight (see README, "Loaded walking"). Default 0. 0..=1.
    pub assist_fraction: f64,
    /// Gait: the smooth sign `tanh(v/eps)` of the seal friction the cascade compensates (m/s;
    /// the cascade's own model of the friction, with the plant's levels). Default 0.005. > 0.
    /// The plant's 1 mm/s makes F_d turn at every velocity reversal in ~0.1 ms, faster than any
    /// force loop follows (the gait runs diverge); 5 mm/s tracks best.
    pub friction_smoothing_velocity_m_s: f64,
    /// Gait: outer-loop proportional gain on the knee angle error (N m/rad). Default 400. >= 0.
    pub knee_kp_nm_per_rad: f64,
    /// Gait: outer-loop derivative gain on the knee rate error (N m s/rad). Default 15. >= 0.
    pub knee_kd_nm_s_per_rad: f64,
}

impl Default for ReferenceSection {
    fn default() -> Self {
        Self {
            kind: ReferenceKind::Sine,
            force: DesiredForce::Computed,
            amplitude_n: 200.0,
            frequency_hz: 2.0,
            phase_rad: 0.0,
            offset_n: 0.0,
            gait_trial: "wbds01_overground_comfortable".into(),
            gait_file: None,
            gait_sha256: None,
            stride_s: None,
            cadence_steps_per_min: None,
            harmonics: 12,
            drive_hip: None,
            knee_deg: 20.0,
            hip_deg: 10.0,
            knee_ki_nm_per_rad_s: 0.0,
            assist_fraction: 0.0,
            friction_smoothing_velocity_m_s: 0.005,
            knee_kp_nm_per_rad: 400.0,
            knee_kd_nm_s_per_rad: 15.0,
        }
    }
}

/// `[output]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSection {
    /// Record one `timeseries.csv` row (and one Python column entry) every this many steps:
    /// the rows at steps 0, n, 2n, ... The summary, the metrics and the plots still see every
    /// step. Default 1. 1..=10^9.
    pub every_steps: usize,
    /// `"csv"` (default): `timeseries.csv`; `"parquet"`: `timeseries.parquet` (the same
    /// columns as doubles, SNAPPY-compressed; for long runs).
    pub format: OutputFormat,
    /// Per muscle columns (`muscle_<name>_activation`, `_fiber_length_norm`,
    /// `_fiber_velocity_norm`, `_active_force_n`, `_force_n`, `_metabolic_w`) and the muscle
    /// analysis's totals, last (needs `wearer.muscles = true`). Default false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub muscles: bool,
}

/// `output.format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OutputFormat {
    /// `timeseries.csv`.
    #[default]
    Csv,
    /// `timeseries.parquet`.
    Parquet,
}

impl Default for OutputSection {
    fn default() -> Self {
        Self { every_steps: 1, format: OutputFormat::Csv, muscles: false }
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

/// The scenario file as written (every key defaulted). Also what `summary.json` records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScenarioFile {
    /// Seed of every random element (random disturbances, sensor noise, Monte-Carlo draws).
    /// Default 1. 0..=2^64-1; above 2^63-1 (beyond TOML's integers) give it as a string.
    #[serde(with = "seed_serde")]
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
    pub controller: ControllerParams,
    /// Sensors (sampled mode).
    pub sensors: SensorParams,
    /// Injected disturbances.
    pub disturbance: Disturbances,
    /// Human-robot interaction.
    pub human: HumanParams,
    /// The thigh's mount and the body on the carriage.
    pub hip: HipParams,
    /// Ground contact.
    pub ground: GroundParams,
    /// The wearer's knee and ankle (carriage).
    pub wearer: WearerParams,
    /// Metric settings.
    pub metrics: MetricsSection,
    /// Pass/fail criteria.
    pub criteria: Criteria,
    /// `[cuff_limits]`: the comfort and pain limits of the cuff interaction forces (the
    /// wearer's figures of walking runs).
    pub cuff_limits: crate::metrics::CuffLimits,
    /// `[safety]`: the limits of the safety verdicts.
    pub safety: crate::metrics::SafetyLimits,
    /// `[[faults]]`: what breaks, when (see `crate::faults`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<crate::faults::FaultSpec>,
    /// What the run records.
    pub output: OutputSection,
    /// The wearer's body: scales the built-in leg and sets the subject's mass.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub subject: Option<SubjectParams>,
}

/// `[subject]`: the wearer. With a built-in `leg.urdf` the leg is the built-in one scaled to
/// the subject (`exoleg urdf --subject` writes it; README, "Loaded walking for any subject"):
/// de Leva's segments for the stature (and leg length), the exoskeleton of the subject's sex
/// scaled with the thigh. A user's URDF is used as given (a warning says so). The mass is
/// `hip.subject_mass_kg` unless that is set too.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubjectParams {
    /// Body mass (kg). 20..=300.
    pub mass_kg: f64,
    /// Stature (m). 1.0..=2.3.
    pub height_m: f64,
    /// Hip joint centre to floor (m), if measured (e.g. WBDS's leg length); else de Leva's
    /// segments for the stature. 0.35..=0.65 of the stature.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leg_length_m: Option<f64>,
    /// `"male"` (default) or `"female"`: de Leva's table and the exoskeleton template.
    #[serde(default)]
    pub sex: crate::leg::subject::Sex,
}

impl SubjectParams {
    /// As the leg generator takes it.
    pub fn body(&self) -> crate::leg::subject::SubjectBody {
        crate::leg::subject::SubjectBody {
            mass_kg: self.mass_kg,
            height_m: self.height_m,
            leg_length_m: self.leg_length_m,
            sex: self.sex,
        }
    }
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
            controller: ControllerParams::default(),
            sensors: SensorParams::default(),
            disturbance: Disturbances::default(),
            human: HumanParams::default(),
            hip: HipParams::default(),
            ground: GroundParams::default(),
            wearer: WearerParams::default(),
            metrics: MetricsSection::default(),
            criteria: Criteria::default(),
            cuff_limits: crate::metrics::CuffLimits::default(),
            safety: crate::metrics::SafetyLimits::default(),
            faults: Vec::new(),
            output: OutputSection::default(),
            subject: None,
        }
    }
}

/// A seed is a u64; TOML integers are i64: values above i64::MAX are read from and written as
/// decimal strings.
mod seed_serde {
    use serde::{de, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &u64, s: S) -> Result<S::Ok, S::Error> {
        match i64::try_from(*v) {
            Ok(i) => s.serialize_i64(i),
            Err(_) => s.serialize_str(&v.to_string()),
        }
    }

    struct SeedVisitor;

    const EXPECTED: &str = "an integer in 0..=18446744073709551615";

    impl de::Visitor<'_> for SeedVisitor {
        type Value = u64;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str(EXPECTED)
        }
        fn visit_i64<E: de::Error>(self, i: i64) -> Result<u64, E> {
            u64::try_from(i).map_err(|_| E::custom(format!("must be >= 0, got {i}")))
        }
        fn visit_u64<E: de::Error>(self, u: u64) -> Result<u64, E> {
            Ok(u)
        }
        fn visit_f64<E: de::Error>(self, x: f64) -> Result<u64, E> {
            Err(E::custom(format!("must be {EXPECTED}, got {}", crate::scenario::validate::num(x))))
        }
        fn visit_str<E: de::Error>(self, t: &str) -> Result<u64, E> {
            let shown: String = t.chars().take(40).collect();
            t.trim().parse::<u64>().map_err(|_| E::custom(format!("must be {EXPECTED}, got {shown:?}")))
        }
        fn visit_bool<E: de::Error>(self, b: bool) -> Result<u64, E> {
            Err(E::custom(format!("must be {EXPECTED}, got {b}")))
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
        d.deserialize_any(SeedVisitor)
    }
}

/// A validated scenario: the file as written (every key defaulted and checked) with where it
/// came from. [`Scenario::resolve`] turns it into what a run needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Where it came from (file path or the embedded default's name), with " (with --set)"
    /// when overrides were applied.
    pub source_name: String,
    /// Directory of the scenario file, for relative paths inside it (None for the embedded one).
    pub base_dir: Option<std::path::PathBuf>,
    /// The scenario file itself (None for the embedded one and scenarios given as data).
    pub path: Option<std::path::PathBuf>,
    /// The validated values.
    pub file: ScenarioFile,
    /// Read from a `summary.json` of a run whose controller came from outside the scenario
    /// (a Python callable, a Rust controller, a loop the caller owns): that controller, which
    /// the file does not hold. [`Scenario::own_controller`] refuses to replay it without it.
    pub external_controller: Option<String>,
}

/// Suffix of a source name whose scenario had `--set` overrides.
const WITH_SET: &str = " (with --set)";

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
                let text = files::read_capped(p, files::MAX_SCENARIO_FILE_BYTES)?;
                if p.extension().is_some_and(|e| e == "json") {
                    let (table, external) = overrides::parse_json(&name, &text)?;
                    let base = p.parent().map(|d| d.to_path_buf());
                    let s = Self::from_table(name, table, sets)?;
                    let path = Some(p.to_path_buf());
                    return Ok(Scenario { base_dir: base, path, external_controller: external, ..s });
                }
                (name.clone(), overrides::parse_toml(&name, &text)?)
            }
        };
        let base = path.and_then(|p| p.parent()).map(|d| d.to_path_buf());
        Self::from_table(name, table, sets).map(|s| Scenario { base_dir: base, path: path.map(Path::to_path_buf), ..s })
    }

    /// Refuse to run this scenario with its own controller when it comes from a `summary.json`
    /// of a run whose controller came from outside (which the file does not hold): exit 2
    /// naming the controller, instead of silently replaying another one.
    pub fn own_controller(&self) -> Result<()> {
        match &self.external_controller {
            None => Ok(()),
            Some(c) => Err(Error::input(
                &self.source_name,
                "external_controller",
                format!(
                    "the run was made with the controller `{c}` given to it from outside the scenario (Python, \
                     Rust or a loop of your own), which summary.json does not hold: replaying it would run the \
                     scenario's controller ({}) instead; give that controller again (Python: exoleg.run(path, \
                     controller=...))",
                    self.file.controller.kind.as_str()
                ),
            )),
        }
    }

    /// Parse scenario text (TOML) with a name for error messages, apply overrides, validate.
    pub fn from_toml_str(name: &str, text: &str, sets: &[String]) -> Result<Scenario> {
        Self::from_table(name.to_string(), overrides::parse_toml(name, text)?, sets)
    }

    fn from_table(name: String, mut table: toml::Table, sets: &[String]) -> Result<Scenario> {
        for s in sets {
            overrides::apply_set(&mut table, s)?;
        }
        let source = if sets.is_empty() || name.ends_with(WITH_SET) { name } else { format!("{name}{WITH_SET}") };
        let file: ScenarioFile = serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(|e| {
            let key = e.path().to_string();
            let msg = overrides::clean_serde_message(&e.into_inner().to_string());
            Error::input(&source, if key == "." { "scenario".to_string() } else { key }, msg)
        })?;
        validate::validate(&source, &file)?;
        Ok(Scenario { source_name: source, base_dir: None, path: None, file, external_controller: None })
    }

    /// A scenario given as JSON data (an object of sections, the Python package's dicts), with
    /// overrides given as data: (dotted key, JSON value) pairs.
    pub fn from_json(
        name: &str,
        scenario: Option<serde_json::Value>,
        overrides: Vec<(String, serde_json::Value)>,
    ) -> Result<Scenario> {
        let table = match scenario {
            None => overrides::parse_toml(DEFAULT_SCENARIO_NAME, DEFAULT_SCENARIO_TOML)?,
            Some(v) => match overrides::json_to_toml(name, "", v)? {
                toml::Value::Table(t) => t,
                _ => return Err(Error::input(name, "", "a scenario must be an object of sections")),
            },
        };
        Self::from_table(name.to_string(), table, &[])?.with_values(overrides)
    }

    /// Same scenario with overrides given as data on top: (dotted key, JSON value) pairs, never
    /// parsed from text (a key holding `=` is a key that does not exist).
    pub fn with_values(&self, overrides: Vec<(String, serde_json::Value)>) -> Result<Scenario> {
        if overrides.is_empty() {
            return Ok(self.clone());
        }
        let mut table = match toml::Value::try_from(&self.file) {
            Ok(toml::Value::Table(t)) => t,
            _ => return Err(Error::input(&self.source_name, "scenario", "cannot re-serialise scenario")),
        };
        for (k, v) in overrides {
            let value = overrides::json_to_toml("overrides", &k, v)?;
            overrides::apply_value(&mut table, &k, value).map_err(|e| match e {
                Error::Input { key, message, .. } => Error::input("overrides", key, message),
                other => other,
            })?;
        }
        let name = if self.source_name.ends_with(WITH_SET) {
            self.source_name.clone()
        } else {
            format!("{}{WITH_SET}", self.source_name)
        };
        let s = Self::from_table(name, table, &[])?;
        Ok(Scenario {
            base_dir: self.base_dir.clone(),
            path: self.path.clone(),
            external_controller: self.external_controller.clone(),
            ..s
        })
    }

    /// Same scenario with overrides applied on top (used by `compare` and sweeps).
    pub fn with_sets(&self, sets: &[String]) -> Result<Scenario> {
        if sets.is_empty() {
            return Ok(self.clone());
        }
        let table = match toml::Value::try_from(&self.file) {
            Ok(toml::Value::Table(t)) => t,
            _ => return Err(Error::input(&self.source_name, "scenario", "cannot re-serialise scenario")),
        };
        let s = Self::from_table(self.source_name.clone(), table, sets)?;
        Ok(Scenario {
            base_dir: self.base_dir.clone(),
            path: self.path.clone(),
            external_controller: self.external_controller.clone(),
            ..s
        })
    }
}

pub mod fuzz;

pub use fuzz::{
    gait_csv as fuzz_gait_csv, muscles as fuzz_muscles, scenario as fuzz_scenario, set_flags as fuzz_set_flags,
    subjects_csv as fuzz_subjects_csv, urdf as fuzz_urdf,
};
