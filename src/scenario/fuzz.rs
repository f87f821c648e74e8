//! Entry points of the fuzz targets (`fuzz/`) and of the hostile-corpus replay
//! (`tests/corpus/`): each reads arbitrary text the way a run reads that input and returns
//! the error a user would see. They must never panic.

use super::{Resources, Scenario};
use crate::error::{Error, Result};

/// Steps a fuzzed scenario runs after it resolves (the blocks built, the first samples
/// taken: sensors, dtznn, plugins, contact, the carriage).
pub const FUZZ_STEPS: usize = 20;

/// A scenario file: parse, validate, resolve (leg, gait and cascade included), then build
/// the run and take its first [`FUZZ_STEPS`] steps. A simulation that diverges or stops is
/// a result, not a failure; only a panic is.
pub fn scenario(text: &str) -> Result<()> {
    let sc = Scenario::from_toml_str("fuzz.toml", text, &[])?.resolve(&Resources::new())?;
    let mut sim = match crate::sim::Simulation::new(sc.model.clone()) {
        Ok(s) => s,
        Err(e @ Error::Input { .. }) => return Err(e),
        Err(_) => return Ok(()),
    };
    for _ in 0..FUZZ_STEPS.min(sc.model.steps) {
        if sim.step(&mut crate::record::NullSink).is_err() {
            break;
        }
    }
    Ok(())
}

/// URDF text through the leg loader with knee joint `knee`.
pub fn urdf(text: &str) -> Result<()> {
    crate::leg::LegSpec::from_urdf_str(text, "knee")
        .map(|_| ())
        .map_err(|e| Error::input("fuzz.urdf", "leg.urdf", e.to_string()))
}

/// A gait CSV: parse and fit (12 harmonics).
pub fn gait_csv(text: &str) -> Result<()> {
    crate::reference::GaitCycle::parse("fuzz.csv", text, 12).map(|_| ())
}

/// A `subjects.csv` of a gait folder (`exoleg gait-check`): the table and every row.
pub fn subjects_csv(text: &str) -> Result<()> {
    crate::reference::read_subjects("subjects.csv", text)?.into_iter().try_for_each(|r| r.row.map(|_| ()))
}

/// A muscle table (`wearer.muscles_file`): parsed and validated, every muscle's length and
/// moment arms evaluated at poses inside, at the edges of and far outside its grid.
pub fn muscles(text: &str) -> Result<()> {
    let set = crate::muscles::MuscleSet::parse(text, "muscles.toml")?;
    for q in [[0.0, 0.0, 0.0], [1.2, 2.0, -0.6], [-40.0, 300.0, 9.0], [0.3, -0.17, 0.5]] {
        for i in 0..set.muscles.len() {
            let (l, r) = set.length_and_arms(i, q);
            if !(l.is_finite() && r.iter().all(|x| x.is_finite())) {
                return Err(crate::error::Error::input("muscles.toml", "length_m", "a non-finite length"));
            }
        }
    }
    Ok(())
}

/// `--set` flags, one per line, on the embedded default scenario, resolved.
pub fn set_flags(text: &str) -> Result<()> {
    let sets: Vec<String> = text.lines().map(str::to_string).collect();
    Scenario::load(None, &sets)?.resolve(&Resources::new()).map(|_| ())
}
