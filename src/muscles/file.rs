//! A muscle table's serde mirror (`format = "exoleg-muscles-1"`) and its validation into a
//! [`MuscleSet`]: every error names the file, the muscle (its index and name) and the field.

use super::path::{PathTable, JOINTS};
use super::{Muscle, MuscleParams, MuscleSet, SourceInfo, FORMAT, MAX_MUSCLES, MAX_POINTS};
use crate::error::{Error, Result};
use serde::Deserialize;

/// A coordinate of the source model and its sign against exoleg's.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coordinate {
    pub name: String,
    pub sign: f64,
}

/// `[coordinates]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coordinates {
    pub hip: Coordinate,
    pub knee: Coordinate,
    pub ankle: Coordinate,
}

/// One `[[muscle]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MuscleRow {
    pub name: String,
    pub source_names: Vec<String>,
    #[serde(default)]
    pub muscle_class: Option<String>,
    pub max_isometric_force_n: f64,
    pub optimal_fiber_length_m: f64,
    pub tendon_slack_length_m: f64,
    pub pennation_at_optimal_rad: f64,
    pub max_contraction_velocity_lopt_per_s: f64,
    #[serde(default)]
    pub rigid_tendon: Option<bool>,
    pub slow_twitch_fraction: f64,
    #[serde(default)]
    pub specific_tension_pa: Option<f64>,
    #[serde(default)]
    pub muscle_density_kg_per_m3: Option<f64>,
    pub joints: Vec<String>,
    pub start_deg: Vec<f64>,
    pub step_deg: Vec<f64>,
    pub count: Vec<usize>,
    pub length_m: Vec<f64>,
}

/// The whole table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MusclesFile {
    pub format: String,
    pub model: String,
    #[serde(default)]
    pub osim_file: Option<String>,
    #[serde(default)]
    pub source: String,
    #[serde(default)]
    pub credits: String,
    #[serde(default)]
    pub opensim_version: Option<String>,
    #[serde(default)]
    pub generated_by: Option<String>,
    pub model_mass_kg: f64,
    pub thigh_length_m: f64,
    pub shank_length_m: f64,
    #[serde(default)]
    pub metabolics_file: Option<String>,
    #[serde(default)]
    pub metabolics_probe: Option<String>,
    pub coordinates: Coordinates,
    pub muscle: Vec<MuscleRow>,
}

/// `v` within `lo..=hi` and finite, else the message.
fn within(v: f64, lo: f64, hi: f64) -> std::result::Result<f64, String> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(v)
    } else {
        Err(format!("{v} is outside {lo}..={hi}"))
    }
}

/// A name of letters, digits and `_`, 1..=64 characters.
fn name_ok(n: &str) -> bool {
    !n.is_empty() && n.len() <= 64 && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl MusclesFile {
    pub fn validate(self, source: &str) -> Result<MuscleSet> {
        let bad = |key: &str, m: String| Error::input(source, key, m);
        if self.format != FORMAT {
            return Err(bad("format", format!("'{}' is not {FORMAT}", crate::error::clip(&self.format))));
        }
        within(self.model_mass_kg, 1.0, 1000.0).map_err(|m| bad("model_mass_kg", m))?;
        within(self.thigh_length_m, 0.05, 2.0).map_err(|m| bad("thigh_length_m", m))?;
        within(self.shank_length_m, 0.05, 2.0).map_err(|m| bad("shank_length_m", m))?;
        for (k, c) in
            [("hip", &self.coordinates.hip), ("knee", &self.coordinates.knee), ("ankle", &self.coordinates.ankle)]
        {
            if c.sign != 1.0 && c.sign != -1.0 {
                return Err(bad(&format!("coordinates.{k}.sign"), format!("{} is not 1 or -1", c.sign)));
            }
        }
        if self.muscle.is_empty() || self.muscle.len() > MAX_MUSCLES {
            return Err(bad("muscle", format!("{} muscles: 1..={MAX_MUSCLES} are needed", self.muscle.len())));
        }
        let mut points = 0usize;
        let mut muscles = Vec::with_capacity(self.muscle.len());
        for (i, row) in self.muscle.into_iter().enumerate() {
            let label = crate::error::clip(&row.name);
            let key = |f: &str| format!("muscle[{i}] '{label}'.{f}");
            if !name_ok(&row.name) {
                return Err(bad(&format!("muscle[{i}].name"), "1..=64 letters, digits or '_'".into()));
            }
            if muscles.iter().any(|m: &Muscle| m.params.name == row.name) {
                return Err(bad(&key("name"), "a second muscle of this name".into()));
            }
            points = points.saturating_add(row.length_m.len());
            if points > MAX_POINTS {
                return Err(bad(&key("length_m"), format!("more than {MAX_POINTS} grid points in the file")));
            }
            muscles.push(row.validate(&key, source)?);
        }
        Ok(MuscleSet {
            model: self.model,
            source: source.to_string(),
            citation: self.source,
            credits: self.credits,
            muscles,
            scale: 1.0,
            model_segments_m: (self.thigh_length_m, self.shank_length_m),
            model_mass_kg: self.model_mass_kg,
            info: SourceInfo {
                osim_file: self.osim_file,
                opensim_version: self.opensim_version,
                generated_by: self.generated_by,
                metabolics: self.metabolics_file.zip(self.metabolics_probe),
                coordinates: [self.coordinates.hip, self.coordinates.knee, self.coordinates.ankle]
                    .into_iter()
                    .map(|c| (c.name, c.sign))
                    .collect(),
            },
        })
    }
}

impl MuscleRow {
    fn validate(self, key: &dyn Fn(&str) -> String, source: &str) -> Result<Muscle> {
        let bad = |f: &str, m: String| Error::input(source, key(f), m);
        let num = |f: &str, v: f64, lo: f64, hi: f64| within(v, lo, hi).map_err(|m| bad(f, m));
        let params = MuscleParams {
            max_isometric_force_n: num("max_isometric_force_n", self.max_isometric_force_n, 1e-3, 1e5)?,
            optimal_fiber_length_m: num("optimal_fiber_length_m", self.optimal_fiber_length_m, 1e-4, 2.0)?,
            tendon_slack_length_m: num("tendon_slack_length_m", self.tendon_slack_length_m, 0.0, 3.0)?,
            pennation_at_optimal_rad: num("pennation_at_optimal_rad", self.pennation_at_optimal_rad, 0.0, 1.2)?,
            max_contraction_velocity_lopt_per_s: num(
                "max_contraction_velocity_lopt_per_s",
                self.max_contraction_velocity_lopt_per_s,
                0.1,
                100.0,
            )?,
            slow_twitch_fraction: num("slow_twitch_fraction", self.slow_twitch_fraction, 0.0, 1.0)?,
            specific_tension_pa: num("specific_tension_pa", self.specific_tension_pa.unwrap_or(0.25e6), 1e3, 1e8)?,
            density_kg_per_m3: num(
                "muscle_density_kg_per_m3",
                self.muscle_density_kg_per_m3.unwrap_or(1059.7),
                1.0,
                1e5,
            )?,
            name: self.name,
            source_names: self.source_names,
            source_class: self.muscle_class,
            source_rigid_tendon: self.rigid_tendon,
        };
        if params.source_names.len() > 64 || params.source_names.iter().any(|n| n.is_empty() || n.len() > 128) {
            return Err(bad("source_names", "1..=64 names of 1..=128 characters".into()));
        }
        let d = self.joints.len();
        if d == 0 || d > 3 {
            return Err(bad("joints", format!("{d} joints: 1..=3 of hip, knee, ankle")));
        }
        let mut joints = Vec::with_capacity(d);
        for j in &self.joints {
            match JOINTS.iter().position(|n| n == j) {
                Some(k) if joints.last().is_none_or(|&p| k > p) => joints.push(k),
                Some(_) => return Err(bad("joints", "hip, knee, ankle in that order, each once".into())),
                None => return Err(bad("joints", format!("'{}' is not hip, knee or ankle", crate::error::clip(j)))),
            }
        }
        for (f, len) in
            [("start_deg", self.start_deg.len()), ("step_deg", self.step_deg.len()), ("count", self.count.len())]
        {
            if len != d {
                return Err(bad(f, format!("{len} values for {d} joints")));
            }
        }
        for k in 0..d {
            num("start_deg", self.start_deg[k], -360.0, 360.0)?;
            num("step_deg", self.step_deg[k], 1e-3, 90.0)?;
            if !(4..=100_000).contains(&self.count[k]) {
                return Err(bad("count", format!("{} grid points: 4..=100000 per joint", self.count[k])));
            }
            num("start_deg", self.start_deg[k] + (self.count[k] - 1) as f64 * self.step_deg[k], -360.0, 360.0)
                .map_err(|_| bad("count", "the grid runs past +-360 deg".into()))?;
        }
        let want = self.count.iter().try_fold(1usize, |a, &c| a.checked_mul(c)).filter(|&n| n <= MAX_POINTS);
        if want != Some(self.length_m.len()) {
            return Err(bad(
                "length_m",
                format!(
                    "{} values, the grid needs {}",
                    self.length_m.len(),
                    want.map_or("too many".into(), |n| n.to_string())
                ),
            ));
        }
        if let Some((p, v)) =
            self.length_m.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v > 0.0 && **v <= 5.0))
        {
            return Err(bad("length_m", format!("value {p} is {v}: lengths are in 0..=5 m")));
        }
        let path = PathTable {
            joints,
            start_deg: self.start_deg,
            step_deg: self.step_deg,
            count: self.count,
            length_m: self.length_m,
        };
        Ok(Muscle { params, path })
    }
}
