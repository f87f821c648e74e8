//! `exoleg run`.

use super::*;

/// `exoleg run`'s switches.
pub(super) struct RunFlags {
    pub(super) quiet: bool,
    pub(super) animate: bool,
    pub(super) baseline: bool,
}

/// `exoleg run`.
pub(super) fn cmd_run(scenario: Option<PathBuf>, out: PathBuf, sets: Vec<String>, flags: RunFlags) -> Result<i32> {
    let RunFlags { quiet, animate, baseline } = flags;
    let loaded = Scenario::load(scenario.as_deref(), &sets)?;
    loaded.own_controller()?;
    let res = Resources::new();
    let sc = loaded.resolve(&res)?;
    warn(&sc.warnings);
    if animate && sc.model.leg().is_none() {
        return Err(Error::input(&sc.source_name, "--animate", "the animation draws the leg: plant.kind = \"leg\""));
    }
    let base = if baseline { Some(study::baseline_metabolics(&loaded, &res)?) } else { None };
    let report = study::RunBuilder::new(&sc).animate(animate).baseline(base).write_to(&out)?;
    if !out.join("summary.json").is_file() {
        return Err(Error::Write { path: out.clone(), message: "the run's summary.json is not there".into() });
    }
    if !quiet {
        print_summary(&sc, &report.summary, &out, None);
    }
    warn_controller_stop(&report.summary);
    if let Some(s) = report.summary.end_stops.filter(|s| !s.is_clear()) {
        eprintln!(
            "warning: the leg ran into its end stops: knee at its lower limit {:.3} s, upper limit {:.3} s, \
             cylinder stroke ends {:.3} s, ankle limits {:.3} s; deepest {:.3} deg (summary.json: end_stops)",
            s.knee_lower_s, s.knee_upper_s, s.stroke_end_s, s.ankle_s, s.max_penetration_deg
        );
    }
    if let Some(why) = report.summary.contact.as_ref().and_then(|c| c.not_walking.as_ref()).filter(|v| !v.is_empty()) {
        eprintln!(
            "warning: this run is not walking: {} (summary.json: not_walking; criteria.max_not_walking_flags = 0 \
             fails such a run)",
            why.join("; ")
        );
    }
    for (channel, n) in &report.summary.sensor_clipped_readings {
        eprintln!("warning: sensors.{channel}: {n} readings clipped at the full scale; raise sensors.{channel}.range");
    }
    for c in &report.criteria {
        let verdict = if c.pass { "pass" } else { "FAIL" };
        println!("criterion {:<30} {verdict}: {:.4} (limit {:.4})", c.name, c.value, c.limit);
    }
    verdict(&sc, &report)
}
