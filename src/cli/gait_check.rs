//! `exoleg gait-check`: every trial of folders of gait data.

use super::*;

/// `exoleg gait-check`: the table printed, the bad trials listed on stderr; exit 2 if any
/// input was bad, else 4 if a trial misses the targets.
pub(super) fn cmd_gait_check(dirs: Vec<PathBuf>, out: PathBuf, a: GaitCheckArgs) -> Result<i32> {
    use crate::study::gait_check::{CheckOptions, Targets};
    let targets = Targets {
        stance: (a.min_stance, a.max_stance),
        min_grf_r: a.min_grf_r,
        min_knee_moment_r: a.min_knee_moment_r,
        extensor_within_pct: a.extensor_within_pct,
        flexor_within: a.flexor_within,
        require_peaks: a.require_peaks,
    };
    let opts = CheckOptions {
        engine: a.engine,
        dt_s: a.dt_s,
        strides: a.strides,
        jobs: a.parallel.jobs,
        progress: !a.parallel.quiet,
        targets,
        scenario: a.scenario,
        sets: a.parallel.sets,
    };
    let report = crate::study::gait_check::gait_check(&dirs, &out, &opts)?;
    print!("{}", report.table());
    println!("outputs             {}", out.display());
    let bad = report.bad_input();
    for t in &bad {
        if let crate::study::gait_check::Outcome::BadInput(m) = &t.outcome {
            eprintln!("bad input: {}", output::text::terminal(m));
        }
    }
    let (meet, n) = report.count_meeting(report.trials.iter());
    if !bad.is_empty() {
        let msg =
            format!("{} of {n} trials are bad input (listed above); the others ran: {}", bad.len(), out.display());
        return Err(Error::input("gait-check", "", msg));
    }
    if meet < n {
        return Err(Error::Criteria(format!("{} of {n} trials miss the targets (table above)", n - meet)));
    }
    Ok(EXIT_OK)
}
