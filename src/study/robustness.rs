//! The robustness report: the plant's parameters varied within +-percent while the
//! controller keeps the nominal model, the paper's Table 2 disturbances on, every run checked
//! against the scenario's `[criteria]`.

use super::sweep::{value_at, Dist, Plan, Varied, MAX_RUNS};
use crate::error::{Error, Result};
use crate::scenario::Scenario;

/// The parameters the report varies, with the keys of the controller's nominal model they
/// must be pinned to (so the plant varies and the controller does not), and keys that move
/// with them to keep the model's relations (static friction >= Coulomb friction).
pub const ROBUSTNESS_KEYS: [(&str, Option<&str>, Option<&str>); 8] = [
    ("hydraulics.beta_pa", Some("controller.nominal.beta_pa"), None),
    ("hydraulics.v0_m3", Some("controller.nominal.v0_m3"), None),
    ("hydraulics.k_q", Some("controller.nominal.k_q"), None),
    ("friction.viscous_n_s_per_m", None, None),
    ("friction.coulomb_n", None, Some("friction.static_n")),
    ("human.k_p", None, None),
    ("human.k_d", None, None),
    ("leg.mass_scale", Some("controller.nominal_leg.mass_scale"), None),
];

/// The paper's Table 2 disturbance forms (constant, random, sine, exponential decay, each of
/// unit amplitude) on dx2/dt, plus its state-dependent g = 0.05 x1 + 1e-3 x2.
pub const TABLE2_DISTURBANCES: [&str; 3] = [
    "disturbance.force_accel=[{kind=\"constant\",value=1.0},{kind=\"random\",amplitude=1.0},{kind=\"sine\"},{kind=\"exp_decay\"}]",
    "disturbance.state_gain_force=0.05",
    "disturbance.state_gain_force_rate=1e-3",
];

/// The robustness runs: every parameter of [`ROBUSTNESS_KEYS`] uniform within +-`percent` %
/// (static friction scaled with Coulomb friction), the controller's nominal model pinned to
/// the base values, the Table 2 disturbances on. Returns the pinned base and the plan.
pub fn robustness_plan(base: &Scenario, n: usize, percent: f64) -> Result<(Scenario, Plan)> {
    if !(percent.is_finite() && (0.0..100.0).contains(&percent)) {
        return Err(Error::input("--percent", percent.to_string(), "must be in [0, 100)"));
    }
    if n == 0 || n > MAX_RUNS {
        return Err(Error::input("--samples", n.to_string(), format!("must be 1..={MAX_RUNS} runs")));
    }
    let mut pinned: Vec<String> = TABLE2_DISTURBANCES.iter().map(|s| s.to_string()).collect();
    for (k, nominal, _) in ROBUSTNESS_KEYS {
        if let Some(nk) = nominal {
            pinned.push(format!("{nk}={:?}", value_at(base, k)?.0));
        }
    }
    let base = base.with_sets(&pinned)?;
    let mut vary = Vec::new();
    for (k, _, follower) in ROBUSTNESS_KEYS {
        let (b, integer) = value_at(&base, k)?;
        let followers = match follower {
            Some(f) => vec![(f.to_string(), value_at(&base, f)?.0)],
            None => Vec::new(),
        };
        vary.push(Varied { key: k.to_string(), dist: Dist::Pct(percent), base: b, integer, followers });
    }
    let seed = base.file.seed;
    Ok((base, Plan::MonteCarlo { n, vary, seed }))
}
