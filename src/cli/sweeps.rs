//! `exoleg sweep`, `exoleg robustness` and `exoleg merge`: studies of many runs.

use super::*;

/// `exoleg sweep`.
pub(super) fn cmd_sweep(
    scenario: PathBuf,
    grids: Vec<String>,
    monte_carlo: Option<usize>,
    vary: Vec<String>,
    out: PathBuf,
    run_outputs: bool,
    common: SweepArgs,
) -> Result<i32> {
    let base = Scenario::load(Some(&scenario), &common.parallel.sets)?;
    base.own_controller()?;
    warn_base(&base);
    let plan = sweep::plan_from_args(&base, &grids, monte_carlo, &vary)?;
    run_study(&base, &base.source_name, &plan, shard::StudyKind::Sweep, out, run_outputs, &common)
}

/// Run a study's plan (or print it, or run one shard of it) into `out`.
pub(super) fn run_study(
    base: &Scenario,
    source_name: &str,
    plan: &sweep::Plan,
    study: shard::StudyKind,
    out: PathBuf,
    run_outputs: bool,
    common: &SweepArgs,
) -> Result<i32> {
    if common.plan {
        let stdout = std::io::stdout();
        shard::write_plan(plan, &mut stdout.lock())?;
        return Ok(EXIT_OK);
    }
    let sh = common.shard.as_deref().map(shard::parse_shard).transpose()?;
    let opts = sweep::RunOptions {
        jobs: common.parallel.jobs,
        progress: !common.parallel.quiet,
        shard: sh.unwrap_or((0, 1)),
        controller: None,
        cancel: None,
        resume: common.resume,
    };
    let start = std::time::Instant::now();
    let done = shard::run_study_into(base, source_name, plan, &study, &opts, sh.is_some(), run_outputs, &out)?;
    let (title, agg) = (done.title, done.aggregate);
    let wall = start.elapsed().as_secs_f64();
    println!("{title}; {wall:.2} s; {}", out.display());
    match (&study, done.faults) {
        (shard::StudyKind::Faults { .. }, Some(r)) => faults_verdict(&r, &out),
        (shard::StudyKind::Robustness { .. }, _) if common.shard.is_none() => {
            print!("{}", agg.csv());
            robustness_verdict(&base.file, &agg, &out)
        }
        _ => {
            print!("{}", agg.csv());
            Ok(EXIT_OK)
        }
    }
}

/// The robustness report's verdict: exit 4 unless every run passes.
pub(super) fn robustness_verdict(
    base: &crate::scenario::ScenarioFile,
    agg: &sweep::Aggregate,
    out: &Path,
) -> Result<i32> {
    let verdict = if base.criteria.any() {
        " the scenario's criteria"
    } else {
        " (the scenario sets no [criteria]: only divergence fails)"
    };
    println!("{}/{} runs pass{verdict} ({} failed); report in {}", agg.passed, agg.runs, agg.failed, out.display());
    if agg.passed == agg.runs {
        Ok(EXIT_OK)
    } else {
        Err(Error::Criteria(format!("{} of {} robustness runs failed", agg.runs - agg.passed, agg.runs)))
    }
}

/// `exoleg robustness`.
pub(super) fn cmd_robustness(
    scenario: PathBuf,
    percent: f64,
    samples: usize,
    out: PathBuf,
    common: SweepArgs,
) -> Result<i32> {
    let base = Scenario::load(Some(&scenario), &common.parallel.sets)?;
    base.own_controller()?;
    warn_base(&base);
    let (pinned, plan) = robustness::robustness_plan(&base, samples, percent)?;
    run_study(&pinned, &base.source_name, &plan, shard::StudyKind::Robustness { percent }, out, false, &common)
}

/// `exoleg merge`.
pub(super) fn cmd_merge(shards: Vec<PathBuf>, out: PathBuf) -> Result<i32> {
    let m = shard::merge(&shards, &out)?;
    println!("{}; {} shards merged into {}", m.title, shards.len(), out.display());
    print!("{}", m.aggregate.csv());
    match (&m.meta.study, &m.faults) {
        (shard::StudyKind::Faults { .. }, Some(r)) => faults_verdict(r, &out),
        (shard::StudyKind::Robustness { .. }, _) => robustness_verdict(&m.meta.scenario, &m.aggregate, &out),
        _ => Ok(EXIT_OK),
    }
}
