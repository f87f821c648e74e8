#![allow(dead_code)]
//! Helpers shared by the integration tests.

use exoleg::{RunOutput, Scenario};

/// Load the embedded default scenario with overrides.
pub fn scenario(sets: &[&str]) -> Scenario {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::load(None, &sets).expect("scenario")
}

/// Run the embedded default scenario with overrides.
pub fn run(sets: &[&str]) -> RunOutput {
    exoleg::run(&scenario(sets)).expect("run")
}

/// Mean of a slice.
pub fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}
