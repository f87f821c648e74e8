//! A small library API for gait-trajectory tests, so controller developers can write their
//! own checks in Rust (see `examples/gait_test.rs`):
//!
//! ```no_run
//! use exoleg::study::gait_test::GaitTest;
//! let report = GaitTest::comfortable().set("controller.gamma=300").strides(4).run().unwrap();
//! assert!(report.knee_rms_error_deg() < 1.0);
//! ```

use crate::error::Result;
use crate::metrics::Summary;
use crate::record::MemoryRecord;
use crate::scenario::{Resources, Scenario};

/// The shipped comfortable-walking scenario (`assets/scenarios/gait_walk.toml`).
pub const GAIT_WALK_TOML: &str = include_str!("../../assets/scenarios/gait_walk.toml");
/// The shipped fast-walking scenario (`assets/scenarios/gait_walk_fast.toml`).
pub const GAIT_WALK_FAST_TOML: &str = include_str!("../../assets/scenarios/gait_walk_fast.toml");

/// A gait run to be configured and executed.
#[derive(Debug, Clone)]
pub struct GaitTest {
    name: String,
    toml: String,
    sets: Vec<String>,
    strides: Option<usize>,
}

impl GaitTest {
    /// Comfortable overground walking (WBDS subject 01), the shipped scenario.
    pub fn comfortable() -> Self {
        Self::from_toml("gait_walk.toml", GAIT_WALK_TOML)
    }

    /// Fast overground walking (WBDS subject 01), the shipped scenario.
    pub fn fast() -> Self {
        Self::from_toml("gait_walk_fast.toml", GAIT_WALK_FAST_TOML)
    }

    /// Any scenario text (TOML) with a name for error messages.
    pub fn from_toml(name: &str, toml: &str) -> Self {
        Self { name: name.into(), toml: toml.into(), sets: Vec::new(), strides: None }
    }

    /// Override a scenario key (`"controller.kind=\"erl_smc\""`), as `--set` does.
    pub fn set(mut self, key_value: &str) -> Self {
        self.sets.push(key_value.into());
        self
    }

    /// Run `n` strides, with the first one excluded from the headline figures.
    pub fn strides(mut self, n: usize) -> Self {
        self.strides = Some(n);
        self
    }

    /// The resolved scenario.
    pub fn scenario(&self) -> Result<Scenario> {
        let s = Scenario::from_toml_str(&self.name, &self.toml, &self.sets)?;
        match self.strides {
            None => Ok(s),
            Some(n) => {
                let stride = s.resolve(&Resources::new())?.model.reference.stride_s().unwrap_or(1.0);
                s.with_sets(&[
                    format!("sim.duration_s={:?}", n as f64 * stride),
                    format!("metrics.settle_s={stride:?}"),
                ])
            }
        }
    }

    /// Run it.
    pub fn run(&self) -> Result<GaitReport> {
        let sc = self.scenario()?.resolve(&Resources::new())?;
        let (summary, record) = crate::session::run_in_memory(&sc.model)?;
        Ok(GaitReport { summary, record })
    }
}

/// The outcome of a gait run.
#[derive(Debug, Clone)]
pub struct GaitReport {
    /// All summary figures (see `summary.json`).
    pub summary: Summary,
    /// The time series.
    pub record: MemoryRecord,
}

impl GaitReport {
    /// Knee RMS error after the settling window (deg).
    pub fn knee_rms_error_deg(&self) -> f64 {
        self.summary.knee_rms_error_deg.unwrap_or(f64::NAN)
    }
    /// Knee max |error| after the settling window (deg).
    pub fn knee_max_abs_error_deg(&self) -> f64 {
        self.summary.knee_max_abs_error_deg.unwrap_or(f64::NAN)
    }
    /// Force RMS error after the settling window (N).
    pub fn force_rms_error_n(&self) -> f64 {
        self.summary.rms_force_error_after_settle_n
    }
    /// Force max |error| after the settling window (N).
    pub fn force_max_abs_error_n(&self) -> f64 {
        self.summary.max_abs_force_error_after_settle_n
    }
}
