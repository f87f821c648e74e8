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

/// Write `robustness.png` (histograms of the figures with the criteria's limits) for the runs
/// aggregated in `agg`, into `dir`. Returns the report's title line.
pub fn write_report_png(
    dir: &std::path::Path,
    base: &crate::scenario::ScenarioFile,
    source_name: &str,
    percent: f64,
    agg: &super::sweep::Aggregate,
) -> Result<String> {
    use crate::metrics::Metric;
    let c = &base.criteria;
    let mut panels = vec![
        (
            "max |F_L - F_d| after settling (N)",
            agg.values(Metric::MaxAbsForceErrorAfterSettle).to_vec(),
            c.max_force_error_n,
        ),
        (
            "RMS force error after settling (N)",
            agg.values(Metric::RmsForceErrorAfterSettle).to_vec(),
            c.rms_force_error_n,
        ),
    ];
    if base.reference.kind == crate::scenario::ReferenceKind::Gait {
        panels.push(("knee RMS error (deg)", agg.values(Metric::KneeRmsError).to_vec(), c.knee_rms_error_deg));
        panels.push(("knee max |error| (deg)", agg.values(Metric::KneeMaxAbsError).to_vec(), c.knee_max_error_deg));
    }
    let name = crate::output::text::title_name(source_name);
    let title = format!("{name}: +-{percent}% parameters, Table 2 disturbances, {} runs", agg.runs);
    crate::output::histograms_png(&dir.join("robustness.png"), &title, &panels)?;
    Ok(title)
}
