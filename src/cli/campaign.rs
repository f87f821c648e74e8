//! `exoleg faults`: the fault campaign.

use super::*;

/// A fault campaign's verdict: its FMEA table; exit 4 if any run breaks a safety criterion.
pub(super) fn faults_verdict(r: &study::faults::CampaignReport, out: &Path) -> Result<i32> {
    print!("{}", r.fmea);
    println!(
        "{} of {} runs break a safety criterion ({} faulted runs with a fault-induced hazard); report in {}",
        r.hazard_runs,
        r.runs,
        r.fault_induced_runs,
        out.display()
    );
    if r.hazard_runs == 0 {
        Ok(EXIT_OK)
    } else {
        let base = if r.baseline_broken.is_empty() {
            String::new()
        } else {
            format!(" (the baseline itself breaks {})", r.baseline_broken.join(", "))
        };
        Err(Error::Criteria(format!("{} of {} campaign runs break a safety criterion{base}", r.hazard_runs, r.runs)))
    }
}

/// `exoleg faults`.
pub(super) fn cmd_faults(
    scenario: PathBuf,
    matrix: Option<PathBuf>,
    print_matrix: bool,
    observe_strides: f64,
    out: PathBuf,
    common: SweepArgs,
) -> Result<i32> {
    let base = Scenario::load(Some(&scenario), &common.parallel.sets)?;
    base.own_controller()?;
    warn_base(&base);
    let matrix = matrix.as_deref().map(study::faults::read_matrix).transpose()?;
    let res = crate::scenario::Resources::new();
    let c = study::faults::campaign(&base, matrix, observe_strides, None, &res)?;
    for n in &c.notes {
        eprintln!("note: {n}");
    }
    if print_matrix {
        print!("{}", c.matrix.to_toml()?);
        return Ok(EXIT_OK);
    }
    let study = shard::StudyKind::Faults { layout: c.layout };
    run_study(&c.base, &base.source_name, &c.plan, study, out, false, &common)
}
