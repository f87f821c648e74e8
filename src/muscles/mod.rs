//! The wearer's muscles (issue 39): the sagittal muscle-tendon units of one leg that span the
//! hip, knee and ankle, their paths, their mechanics, how static optimisation shares the
//! joint moments among them, and what that costs in metabolic energy. Three rooms, one
//! direction, as OpenSim keeps them: geometry ([`path`]), mechanics ([`curves`]) and the
//! metabolic probes ([`metabolics`]) that read a muscle's state; [`optimize`] shares a sample's
//! moments; [`analysis`] runs all of it on a run's samples.
//!
//! The default model is OpenSim Moco's `2D_gait` (Falisse et al. 2019: the nine muscles of the
//! standard 2D gait models, gait10dof18musc's geometry (Delp et al. 1990, planarised by A.
//! Seth) with a fixed knee axis and De Groote's muscles; opensim-core, Apache 2.0), embedded
//! from `assets/muscles/2d_gait.toml`, which `scripts/opensim-muscles` made from the model with
//! OpenSim 4.6 (`assets/muscles/README.md`; `gait10dof18musc.toml` and `rajagopal2016.toml`
//! beside it). `wearer.muscles_file` takes a table the same script makes from any OpenSim
//! model.
//!
//! Scaling to the subject follows OpenSim's scale tool with one factor for every segment,
//! `s = (thigh + shank of the leg) / (thigh + shank of the model)` (exoleg's built-in legs
//! scale thigh and shank alike): path lengths and moment arms times `s`, optimal fibre and
//! tendon slack lengths times `s` (the tool keeps their ratio to the path length at the
//! default pose), maximum isometric forces unchanged (the tool leaves them), muscle masses
//! from the forces and the scaled fibre lengths.

pub mod activation;
pub mod analysis;
pub mod curves;
mod file;
pub mod metabolics;
pub mod optimize;
pub mod path;

use crate::error::{Error, Result};
use path::PathTable;
use std::sync::Arc;

/// The embedded default table.
pub const BUILTIN_NAME: &str = "builtin:2d_gait";
const BUILTIN_TOML: &str = include_str!("../../assets/muscles/2d_gait.toml");
/// The format tag a table carries.
pub const FORMAT: &str = "exoleg-muscles-1";
/// Most muscles a table may hold.
pub const MAX_MUSCLES: usize = 200;
/// Most grid points a table may hold in all.
pub const MAX_POINTS: usize = 4_000_000;
/// Largest table file read (bytes).
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// One muscle's parameters, as the source model has them (SI units).
#[derive(Debug, Clone, PartialEq)]
pub struct MuscleParams {
    /// exoleg's name for it (the source model's without the side suffix).
    pub name: String,
    /// The source model's muscle names it stands for.
    pub source_names: Vec<String>,
    /// Maximum isometric force (N).
    pub max_isometric_force_n: f64,
    /// Optimal fibre length (m).
    pub optimal_fiber_length_m: f64,
    /// Tendon slack length (m).
    pub tendon_slack_length_m: f64,
    /// Pennation at the optimal fibre length (rad).
    pub pennation_at_optimal_rad: f64,
    /// Maximum contraction velocity (optimal fibre lengths per second).
    pub max_contraction_velocity_lopt_per_s: f64,
    /// Fraction of slow-twitch fibres (0..1).
    pub slow_twitch_fraction: f64,
    /// The source model's muscle class (e.g. `Millard2012EquilibriumMuscle`).
    pub source_class: Option<String>,
    /// The source model's tendon is rigid.
    pub source_rigid_tendon: Option<bool>,
    /// Specific tension (Pa), for the muscle's mass.
    pub specific_tension_pa: f64,
    /// Muscle density (kg/m^3).
    pub density_kg_per_m3: f64,
}

impl MuscleParams {
    /// The muscle's mass (kg): `F_max / sigma * rho * l_opt` (Umberger et al. 2003).
    pub fn mass_kg(&self) -> f64 {
        self.max_isometric_force_n / self.specific_tension_pa * self.density_kg_per_m3 * self.optimal_fiber_length_m
    }
}

/// One muscle: parameters and path.
#[derive(Debug, Clone, PartialEq)]
pub struct Muscle {
    /// Its parameters (scaled).
    pub params: MuscleParams,
    /// Its path (the source model's size; [`MuscleSet::scale`] multiplies).
    pub path: PathTable,
}

/// One muscle at a pose ([`MuscleSet::at_pose`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MusclePose {
    /// exoleg's name.
    pub name: String,
    /// The source model's muscles it stands for.
    pub source_names: Vec<String>,
    /// Maximum isometric force (N).
    pub max_isometric_force_n: f64,
    /// Optimal fibre length (m).
    pub optimal_fiber_length_m: f64,
    /// Tendon slack length (m).
    pub tendon_slack_length_m: f64,
    /// Pennation at the optimal fibre length (rad).
    pub pennation_at_optimal_rad: f64,
    /// Maximum contraction velocity (l_opt/s).
    pub max_contraction_velocity_lopt_per_s: f64,
    /// Slow-twitch fraction.
    pub slow_twitch_fraction: f64,
    /// Mass (kg), for the metabolic rate.
    pub mass_kg: f64,
    /// The joints it spans.
    pub joints: Vec<String>,
    /// Muscle-tendon length (m).
    pub length_m: f64,
    /// Moment arms about hip, knee, ankle (m; `r = -dL/dq`: a flexor's and a dorsiflexor's
    /// positive).
    pub moment_arm_m: [f64; 3],
    /// The pose is inside the table's grid (else the length is extrapolated).
    pub inside_table: bool,
}

/// A leg's muscles, scaled to a subject.
#[derive(Debug, Clone, PartialEq)]
pub struct MuscleSet {
    /// The source model's name.
    pub model: String,
    /// Where the table came from (a path or [`BUILTIN_NAME`]).
    pub source: String,
    /// The source model's citation and credits.
    pub citation: String,
    /// The source model's credits and licence.
    pub credits: String,
    /// The muscles.
    pub muscles: Vec<Muscle>,
    /// The length scale applied to the paths (1 = the source model's size).
    pub scale: f64,
    /// The source model's thigh and shank lengths (m).
    pub model_segments_m: (f64, f64),
    /// The source model's mass (kg).
    pub model_mass_kg: f64,
    /// Where the table came from: the model file, the tools, the coordinates.
    pub info: SourceInfo,
}

/// A table's provenance, as its file states it.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct SourceInfo {
    /// The `.osim` file.
    pub osim_file: Option<String>,
    /// The OpenSim version that made it.
    pub opensim_version: Option<String>,
    /// The command that made it.
    pub generated_by: Option<String>,
    /// The model whose metabolics probe gave the slow-twitch fractions, and the probe.
    pub metabolics: Option<(String, String)>,
    /// The source model's hip, knee and ankle coordinates and their signs against exoleg's.
    pub coordinates: Vec<(String, f64)>,
}

impl MuscleSet {
    /// The embedded default (gait10dof18musc) at its own size.
    pub fn builtin() -> Result<Arc<MuscleSet>> {
        static SET: std::sync::OnceLock<std::result::Result<Arc<MuscleSet>, String>> = std::sync::OnceLock::new();
        SET.get_or_init(|| Self::parse(BUILTIN_TOML, BUILTIN_NAME).map(Arc::new).map_err(|e| e.to_string()))
            .clone()
            .map_err(|m| Error::input(BUILTIN_NAME, "", m))
    }

    /// A table's text `text` from `source` (for messages), validated.
    pub fn parse(text: &str, source: &str) -> Result<MuscleSet> {
        let raw: file::MusclesFile = {
            let de = toml::Deserializer::parse(text).map_err(|e| Error::input(source, "", e.to_string()))?;
            serde_path_to_error::deserialize(de).map_err(|e| {
                let key = e.path().to_string();
                Error::input(source, key, e.into_inner().message().to_string())
            })?
        };
        raw.validate(source)
    }

    /// The set scaled by `s` (lengths and moment arms; forces unchanged).
    pub fn scaled(&self, s: f64) -> MuscleSet {
        let mut out = self.clone();
        out.scale = self.scale * s;
        for m in &mut out.muscles {
            m.params.optimal_fiber_length_m *= s;
            m.params.tendon_slack_length_m *= s;
        }
        out
    }

    /// The scale factor for a leg with `thigh_m` and `shank_m` segments (a leg without an
    /// ankle, `shank_m` 0: by the thigh alone).
    pub fn scale_for(&self, thigh_m: f64, shank_m: f64) -> f64 {
        if shank_m > 0.0 {
            (thigh_m + shank_m) / (self.model_segments_m.0 + self.model_segments_m.1)
        } else {
            thigh_m / self.model_segments_m.0
        }
    }

    /// Muscle `i`'s length (m) and moment arms about hip, knee, ankle (m; `r = -dL/dq`,
    /// flexion and dorsiflexion positive) at `q_rad`.
    pub fn length_and_arms(&self, i: usize, q_rad: [f64; 3]) -> (f64, [f64; 3]) {
        let (l, r, _) = self.length_arms_inside(i, q_rad);
        (l, r)
    }

    /// [`Self::length_and_arms`] and whether the angles are inside the muscle's table.
    pub fn length_arms_inside(&self, i: usize, q_rad: [f64; 3]) -> (f64, [f64; 3], bool) {
        self.to_scale(self.muscles[i].path.evaluate(q_rad))
    }

    /// [`Self::length_arms_inside`] from the path's axes at the state
    /// ([`path::PathTable::axis`]).
    pub(crate) fn length_arms_inside_axes(&self, i: usize, axes: &[path::Axis; 3]) -> (f64, [f64; 3], bool) {
        self.to_scale(self.muscles[i].path.evaluate_axes(axes))
    }

    /// A path's length, slopes and coverage to the scaled length and moment arms.
    fn to_scale(&self, (l, d, inside): (f64, [f64; 3], bool)) -> (f64, [f64; 3], bool) {
        // (+ 0.0: a joint the path does not span has a zero arm, not -0.)
        (self.scale * l, d.map(|x| -self.scale * x + 0.0), inside)
    }

    /// Every muscle at the joint angles `q_rad` (hip flexion, knee flexion, ankle
    /// dorsiflexion): its parameters, length and moment arms (`exoleg muscles`).
    pub fn at_pose(&self, q_rad: [f64; 3]) -> Vec<MusclePose> {
        self.muscles
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let (l, r) = self.length_and_arms(i, q_rad);
                let p = &m.params;
                MusclePose {
                    name: p.name.clone(),
                    source_names: p.source_names.clone(),
                    max_isometric_force_n: p.max_isometric_force_n,
                    optimal_fiber_length_m: p.optimal_fiber_length_m,
                    tendon_slack_length_m: p.tendon_slack_length_m,
                    pennation_at_optimal_rad: p.pennation_at_optimal_rad,
                    max_contraction_velocity_lopt_per_s: p.max_contraction_velocity_lopt_per_s,
                    slow_twitch_fraction: p.slow_twitch_fraction,
                    mass_kg: p.mass_kg(),
                    joints: m.path.joints.iter().map(|&j| path::JOINTS[j].to_string()).collect(),
                    length_m: l,
                    moment_arm_m: r,
                    inside_table: m.path.covers(q_rad),
                }
            })
            .collect()
    }

    /// The index of the muscle named `name`.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.muscles.iter().position(|m| m.params.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The embedded table: nine muscles with the source model's parameters (gait10dof18musc,
    /// MUSCLES.md section 3b), their joints, and the slow-twitch fractions of its metabolics
    /// model.
    #[test]
    fn builtin_table() {
        let s = MuscleSet::builtin().unwrap();
        let names: Vec<&str> = s.muscles.iter().map(|m| m.params.name.as_str()).collect();
        assert_eq!(
            names,
            ["hamstrings", "bifemsh", "glut_max", "iliopsoas", "rect_fem", "vasti", "gastroc", "soleus", "tib_ant"]
        );
        let p = |n: &str| &s.muscles[s.index(n).unwrap()];
        assert_eq!(p("vasti").params.max_isometric_force_n, 5000.0);
        assert_eq!(p("soleus").params.slow_twitch_fraction, 0.8);
        assert_eq!(p("gastroc").path.joints, vec![1, 2]);
        assert_eq!(p("hamstrings").path.joints, vec![0, 1]);
        assert!((p("soleus").params.pennation_at_optimal_rad - 0.436).abs() < 1e-3);
        // Signs: the vasti extend the knee (negative arm), the hamstrings flex it and extend
        // the hip, the soleus plantarflexes, the tibialis dorsiflexes.
        let q = [0.0, 20f64.to_radians(), 0.0];
        let arm = |n: &str| s.length_and_arms(s.index(n).unwrap(), q).1;
        assert!(arm("vasti")[1] < -0.03 && arm("hamstrings")[1] > 0.02 && arm("hamstrings")[0] < -0.03);
        assert!(arm("soleus")[2] < -0.03 && arm("tib_ant")[2] > 0.02 && arm("iliopsoas")[0] > 0.0);
    }
}
