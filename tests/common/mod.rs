#![allow(dead_code)]
//! Helpers shared by the integration tests.

use exoleg::{RunOutput, Scenario};

/// The embedded default scenario (paper Figure 5 case) moved to the bench plant, with overrides.
pub fn scenario(sets: &[&str]) -> Scenario {
    let sets: Vec<String> =
        std::iter::once("plant.kind=\"bench\"").chain(sets.iter().copied()).map(String::from).collect();
    Scenario::load(None, &sets).expect("scenario")
}

/// Run the bench version of the embedded default scenario with overrides.
pub fn run(sets: &[&str]) -> RunOutput {
    exoleg::run(&scenario(sets)).expect("run")
}

/// The embedded default scenario as it is (the leg plant), with overrides.
pub fn leg_scenario(sets: &[&str]) -> Scenario {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::load(None, &sets).expect("scenario")
}

/// Run the embedded default scenario on the leg with overrides.
pub fn leg_run(sets: &[&str]) -> RunOutput {
    exoleg::run(&leg_scenario(sets)).expect("run")
}

/// Mean of a slice.
pub fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}
pub mod leg_reference;
