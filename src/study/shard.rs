//! Sweeps beyond one machine (issue 9): a sweep's runs split into shards (`--shard K/N`: the
//! runs whose index % N == K, matching Slurm's `SLURM_ARRAY_TASK_ID` and Kubernetes Indexed
//! Jobs' `JOB_COMPLETION_INDEX`), each written to its own folder with the plan's hash, and
//! merged back (`exoleg merge`) into exactly what the unsharded sweep writes.
//!
//! A shard folder holds `shard.json` ([`ShardMeta`]) and `runs.jsonl` (its runs' lines, with
//! their global indices, in index order). The merge streams the shards in round-robin order
//! (index i is line i / N of shard i % N), so it never holds the runs in memory, and refuses
//! shards of different plans, a missing or duplicated shard, or a line out of place.

use super::lines::{bounded_line, check_line};
pub use super::lines::{StudyKind, MAX_LINE_BYTES};
use super::robustness;
use super::sweep::{Aggregate, Plan};
use crate::error::{Error, Result};
use crate::output::{self, OutputDir};
use crate::scenario::{Scenario, ScenarioFile};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The format tag of `shard.json` (2: the plan is recorded, so the merge checks every run's
/// overrides).
pub const SHARD_FORMAT: &str = "exoleg-shard-2";
/// `shard.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardMeta {
    /// [`SHARD_FORMAT`].
    pub format: String,
    /// The study.
    pub study: StudyKind,
    /// SHA-256 of the base scenario and every run's overrides.
    pub plan_hash: String,
    /// Runs in the whole plan.
    pub runs: usize,
    /// This shard: [K, N].
    pub shard: [usize; 2],
    /// Where the base scenario came from.
    pub source_name: String,
    /// The base scenario as run (the robustness report's criteria come from it).
    pub scenario: ScenarioFile,
    /// The plan (every run's overrides follow from it and the scenario).
    pub plan: Plan,
}

/// SHA-256 (hex) of a plan: the base scenario as run and every run's overrides, in order.
pub fn plan_hash(base: &Scenario, plan: &Plan) -> Result<String> {
    let mut h = Sha256::new();
    let text =
        serde_json::to_string(&base.file).map_err(|e| Error::input(&base.source_name, "scenario", e.to_string()))?;
    h.update(text.as_bytes());
    for i in 0..plan.len() {
        h.update(b"\n");
        h.update(plan.sets(i).join("\x1f").as_bytes());
    }
    Ok(format!("{:x}", h.finalize()))
}

/// Parse `K/N` (0 <= K < N <= 10^6).
pub fn parse_shard(s: &str) -> Result<(usize, usize)> {
    let bad = |m: &str| Error::input("--shard", s, m.to_string());
    let (k, n) = s.split_once('/').ok_or_else(|| bad("expected K/N, e.g. 0/4 (0-based, K < N)"))?;
    let k: usize = k.trim().parse().map_err(|_| bad("K is not a non-negative integer"))?;
    let n: usize = n.trim().parse().map_err(|_| bad("N is not a positive integer"))?;
    if n == 0 || n > super::sweep::MAX_RUNS {
        return Err(bad("N must be 1..=1000000"));
    }
    if k >= n {
        return Err(bad("K must be below N (0-based, like SLURM_ARRAY_TASK_ID)"));
    }
    Ok((k, n))
}

/// The expanded plan as JSON lines (`--plan`): `{"index": i, "sets": [...]}` per run.
/// A reader closing the pipe (`--plan | head`) ends the plan quietly.
pub fn write_plan(plan: &Plan, out: &mut dyn Write) -> Result<()> {
    for i in 0..plan.len() {
        let line = serde_json::json!({ "index": i, "sets": plan.sets(i) });
        match writeln!(out, "{line}") {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(()),
            Err(e) => return Err(Error::Write { path: "<stdout>".into(), message: e.to_string() }),
        }
    }
    match out.flush() {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(Error::Write { path: "<stdout>".into(), message: e.to_string() })
        }
        _ => Ok(()),
    }
}

/// Write the files a finished study has besides `runs.jsonl` (`aggregate.csv`, and for a
/// robustness report `robustness.png`, for a fault campaign its tables and heat map) into
/// `dir`. Returns the report's title line, and a campaign's findings.
pub fn write_study_outputs(
    dir: &Path,
    study: &StudyKind,
    base: &ScenarioFile,
    source: &str,
    agg: &Aggregate,
) -> Result<(String, Option<super::faults::CampaignReport>)> {
    output::write_atomic(&dir.join("aggregate.csv"), agg.csv().as_bytes())?;
    match study {
        StudyKind::Sweep => Ok((format!("{} runs ({} failed)", agg.runs, agg.failed), None)),
        StudyKind::Robustness { percent } => {
            Ok((robustness::write_report_png(dir, base, source, *percent, agg)?, None))
        }
        StudyKind::Faults { layout } => {
            let r = super::faults::write_outputs(dir, layout, base, source)?;
            Ok((r.title.clone(), Some(r)))
        }
    }
}

/// Write a shard's `shard.json` into `dir`.
pub fn write_shard_meta(dir: &Path, meta: &ShardMeta) -> Result<()> {
    output::write_json(&dir.join("shard.json"), meta)
}

/// The first 12 characters of a hash (whatever a hostile file holds).
fn short(h: &str) -> String {
    h.chars().take(12).collect()
}

fn read_meta(dir: &Path) -> Result<ShardMeta> {
    let p = dir.join("shard.json");
    let text = crate::scenario::read_capped(&p, 64 << 20)?;
    parse_meta(&p.display().to_string(), &text)
}

/// Parse and check `shard.json` text (`name` for messages). The fuzz target's entry point.
pub fn parse_meta(name: &str, text: &str) -> Result<ShardMeta> {
    let p = std::path::PathBuf::from(name);
    let v: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| Error::input(p.display().to_string(), "shard.json", format!("not a shard: {e}")))?;
    match v.get("format").and_then(|f| f.as_str()) {
        Some(SHARD_FORMAT) => {}
        Some(other) => {
            let other: String = other.chars().take(40).collect();
            return Err(Error::input(
                p.display().to_string(),
                "format",
                format!("expected {SHARD_FORMAT}, got {other} (a shard of another exoleg version: run it again)"),
            ));
        }
        None => return Err(Error::input(p.display().to_string(), "format", "missing: not a shard")),
    }
    let meta: ShardMeta = serde_json::from_value(v)
        .map_err(|e| Error::input(p.display().to_string(), "shard.json", format!("not a shard: {e}")))?;
    meta.plan.check().map_err(|m| Error::input(p.display().to_string(), "plan", m))?;
    if let StudyKind::Faults { layout } = &meta.study {
        layout.check(meta.plan.len()).map_err(|m| Error::input(p.display().to_string(), "study.layout", m))?;
    }
    if meta.plan.len() != meta.runs {
        return Err(Error::input(
            p.display().to_string(),
            "runs",
            format!("{} runs, but the plan has {}", meta.runs, meta.plan.len()),
        ));
    }
    let max = super::sweep::MAX_RUNS;
    let [k, n] = meta.shard;
    if n == 0 || n > max || k >= n || meta.runs > max {
        return Err(Error::input(
            p.display().to_string(),
            "shard",
            format!("shard {k}/{n} of {} runs: needs K < N <= {max} and at most {max} runs", meta.runs),
        ));
    }
    if meta.plan_hash.len() != 64 || !meta.plan_hash.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(Error::input(p.display().to_string(), "plan_hash", "not a SHA-256 (64 hex digits)"));
    }
    Ok(meta)
}

/// A shard's `shard.json` text through the merge's reader: the fuzz target's and the
/// hostile corpus's entry point (`shard_json`).
pub fn fuzz_shard_json(text: &str) -> Result<()> {
    parse_meta("fuzz/shard.json", text).map(|_| ())
}

/// Check that the shard folders are the N shards of one plan, each once, and that the plan is
/// the one its hash says; returns (folder, meta) ordered by K.
fn check_shards(dirs: &[PathBuf]) -> Result<Vec<(PathBuf, ShardMeta)>> {
    let first_dir = dirs.first().ok_or_else(|| Error::input("merge", "SHARDS", "give the shard folders"))?;
    let first = read_meta(first_dir)?;
    let n = first.shard[1];
    let base = Scenario {
        source_name: first.source_name.clone(),
        base_dir: None,
        path: None,
        file: first.scenario.clone(),
        external_controller: None,
    };
    if plan_hash(&base, &first.plan)? != first.plan_hash {
        return Err(Error::input(first_dir.display().to_string(), "plan_hash", "does not match its plan and scenario"));
    }
    check_study(first_dir, &first, &base)?;
    let mut seen: Vec<Option<usize>> = vec![None; n];
    let mut out = Vec::with_capacity(n);
    for (i, d) in dirs.iter().enumerate() {
        let m = if i == 0 { first.clone() } else { read_meta(d)? };
        if m.plan_hash != first.plan_hash
            || m.shard[1] != n
            || m.runs != first.runs
            || m.study != first.study
            || m.plan != first.plan
            || m.scenario != first.scenario
        {
            return Err(Error::input(
                d.display().to_string(),
                "shard.json",
                format!(
                    "from another sweep (plan {} of {} shards, expected {} of {n})",
                    short(&m.plan_hash),
                    m.shard[1],
                    short(&first.plan_hash)
                ),
            ));
        }
        let k = m.shard[0];
        if let Some(j) = seen[k] {
            return Err(Error::input(
                d.display().to_string(),
                "shard",
                format!("shard {k}/{n} given twice (also {})", dirs[j].display()),
            ));
        }
        seen[k] = Some(i);
        out.push((d.clone(), m));
    }
    if let Some(k) = seen.iter().position(|s| s.is_none()) {
        return Err(Error::input("merge", "SHARDS", format!("shard {k}/{n} is missing")));
    }
    out.sort_by_key(|(_, m)| m.shard[0]);
    Ok(out)
}

/// The study a shard says it belongs to must be the one its plan is: a robustness report's
/// plan is the report's for its percent, runs and scenario (the title and the plot say so).
fn check_study(dir: &Path, meta: &ShardMeta, base: &Scenario) -> Result<()> {
    let bad = |m: String| Error::input(dir.display().to_string(), "study", m);
    if meta.source_name.chars().count() > 4096 || meta.source_name.chars().any(char::is_control) {
        return Err(Error::input(dir.display().to_string(), "source_name", "not a scenario's name"));
    }
    match meta.study {
        // A campaign's plan lists every run's overrides; its layout was checked against it
        // when the shard was read.
        StudyKind::Sweep | StudyKind::Faults { .. } => Ok(()),
        StudyKind::Robustness { percent } => {
            let (_, plan) = robustness::robustness_plan(base, meta.runs, percent)
                .map_err(|e| bad(format!("not a robustness report's ({e})")))?;
            if plan == meta.plan {
                Ok(())
            } else {
                Err(bad(format!("says robustness at {percent} %, but its plan is not that report's")))
            }
        }
    }
}

/// What a merge produced.
#[derive(Debug, Clone)]
pub struct Merged {
    /// The report's title line.
    pub title: String,
    /// The shards' metadata (shard 0's).
    pub meta: ShardMeta,
    /// The aggregated runs.
    pub aggregate: Aggregate,
    /// A fault campaign's findings.
    pub faults: Option<super::faults::CampaignReport>,
}

/// Open a shard's `runs.jsonl`: a regular file (a device, FIFO or folder is refused before it
/// is read).
fn open_runs(dir: &Path) -> Result<(PathBuf, std::fs::File)> {
    let p = dir.join("runs.jsonl");
    let bad = |m: String| Error::input(p.display().to_string(), "runs.jsonl", m);
    let (f, _) = crate::fsio::open_regular(&p).map_err(bad)?;
    Ok((p, f))
}

/// Pass 1 over one shard (run K, K + N, ...): every line checked, the figures aggregated;
/// returns each line's length (newline included) and the SHA-256 of the shard's lines.
fn scan_shard(dir: &Path, k: usize, n: usize, plan: &Plan, agg: &mut Aggregate) -> Result<(Vec<u64>, [u8; 32])> {
    let (p, f) = open_runs(dir)?;
    let mut r = std::io::BufReader::new(f);
    let mut buf = Vec::new();
    let mut lens = Vec::new();
    let mut h = Sha256::new();
    let runs = plan.len();
    for i in (k..runs).step_by(n) {
        let bad = |m: String| Error::input(p.display().to_string(), format!("run {i}"), m);
        bounded_line(&mut r, &mut buf)
            .map_err(|e| bad(e.to_string()))?
            .ok_or_else(|| bad("missing: the shard ends early".into()))?;
        agg.add(&check_line(&buf, i, plan).map_err(bad)?);
        h.update(&buf);
        lens.push(buf.len() as u64 + 1);
    }
    if bounded_line(&mut r, &mut buf)
        .map_err(|e| Error::input(p.display().to_string(), "runs.jsonl", e.to_string()))?
        .is_some()
    {
        return Err(Error::input(p.display().to_string(), "runs.jsonl", "more runs than the plan has"));
    }
    Ok((lens, h.finalize().into()))
}

/// Pass 2 over one shard: copy its lines to their places in `out` (offsets of run K, K + N, ...),
/// checking they are the bytes pass 1 checked.
fn copy_shard(dir: &Path, offsets: &[u64], digest: &[u8; 32], out: &std::fs::File, out_path: &Path) -> Result<()> {
    use std::os::unix::fs::FileExt;
    let (p, f) = open_runs(dir)?;
    let mut r = std::io::BufReader::new(f);
    let mut buf = Vec::new();
    let mut h = Sha256::new();
    let changed = || Error::input(p.display().to_string(), "runs.jsonl", "changed while it was being merged");
    for &at in offsets {
        bounded_line(&mut r, &mut buf).map_err(|_| changed())?.ok_or_else(changed)?;
        h.update(&buf);
        buf.push(b'\n');
        out.write_all_at(&buf, at)
            .map_err(|e| Error::Write { path: out_path.to_path_buf(), message: e.to_string() })?;
    }
    if <[u8; 32]>::from(h.finalize()) != *digest {
        return Err(changed());
    }
    Ok(())
}

/// Merge shard folders into `out`: `runs.jsonl` in index order, `aggregate.csv` and the
/// study's plots, byte for byte what the unsharded study writes. One shard is open at a time
/// (any number of shards, whatever the open-file limit); every line is read with a size cap and
/// checked against the plan (run index, overrides, fields as exoleg writes them, plausible
/// figures) before anything is written; `out` is never one of the shards.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<Merged> {
    let shards = check_shards(dirs)?;
    let n = shards.len();
    let plan = shards[0].1.plan.clone();
    let mut agg = Aggregate::default();
    let mut scanned = Vec::with_capacity(n);
    for (k, (d, _)) in shards.iter().enumerate() {
        scanned.push(scan_shard(d, k, n, &plan, &mut agg)?);
    }
    // Where each run's line goes: runs in index order, run i from shard i % n.
    let mut offsets: Vec<Vec<u64>> = scanned.iter().map(|(l, _)| Vec::with_capacity(l.len())).collect();
    let mut at = 0u64;
    for i in 0..plan.len() {
        offsets[i % n].push(at);
        at += scanned[i % n].0[i / n];
    }
    let dir = OutputDir::prepare_with_inputs(out, "--out", dirs)?;
    let path = dir.path().join("runs.jsonl");
    let werr = |e: std::io::Error| Error::Write { path: path.clone(), message: e.to_string() };
    let f = std::fs::File::create(&path).map_err(werr)?;
    f.set_len(at).map_err(werr)?;
    for (k, (d, _)) in shards.iter().enumerate() {
        copy_shard(d, &offsets[k], &scanned[k].1, &f, &path)?;
    }
    f.sync_all().map_err(werr)?;
    drop(f);
    let meta = shards.into_iter().next().map(|(_, m)| m).ok_or_else(|| Error::input("merge", "SHARDS", "no shard"))?;
    let (title, faults) = write_study_outputs(dir.path(), &meta.study, &meta.scenario, &meta.source_name, &agg)?;
    dir.commit()?;
    Ok(Merged { title, meta, aggregate: agg, faults })
}

/// What a study run produced.
#[derive(Debug, Clone)]
pub struct StudyDone {
    /// The report's title line.
    pub title: String,
    /// The aggregated runs (this shard's, when sharded).
    pub aggregate: Aggregate,
    /// A fault campaign's findings (the whole plan's).
    pub faults: Option<super::faults::CampaignReport>,
}

/// Run a study's plan (all of it, or the shard in `opts.shard` when `sharded`) into the folder
/// `out`, atomically: `runs.jsonl`, and `shard.json` for a shard or the study's other outputs
/// (`aggregate.csv`, plots) for the whole plan. Every run's line is kept in the study's
/// journal as the run finishes ([`super::journal`]); with `opts.resume`, the runs an
/// interrupted study of the same plan finished are kept and only the others made. The CLI
/// and the Python package both use it.
#[allow(clippy::too_many_arguments)]
pub fn run_study_into(
    base: &Scenario,
    source_name: &str,
    plan: &Plan,
    study: &StudyKind,
    opts: &super::sweep::RunOptions,
    sharded: bool,
    run_outputs: bool,
    out: &Path,
) -> Result<StudyDone> {
    let res = crate::scenario::Resources::new();
    super::sweep::validate_plan(base, plan, &res, opts)?;
    let inputs = base.resolve(&res).map(|r| r.input_paths()).unwrap_or_else(|_| base.path.iter().cloned().collect());
    let dir = OutputDir::prepare_with_inputs(out, "--out", &inputs)?;
    let (k, n) = opts.shard;
    let meta = super::journal::JournalMeta {
        format: super::journal::JOURNAL_FORMAT.into(),
        study: study.clone(),
        plan_hash: plan_hash(base, plan)?,
        runs: plan.len(),
        shard: [k, n],
        run_outputs,
        caller_controller: opts.controller.is_some(),
    };
    let journal = super::journal::Journal::open(dir.target(), meta, plan, opts.resume)?;
    if journal.kept() > 0 {
        eprintln!("resuming: {} finished runs kept from {}", journal.kept(), journal.dir().display());
    }
    let run_dir = run_outputs.then_some(journal.dir());
    super::sweep::run_plan(base, plan, &res, opts, run_dir, &|i| journal.done(i), &|l| journal.append(l))?;
    let agg = journal.assemble(plan, dir.path())?;
    let mut faults = None;
    let title = if sharded {
        let meta = ShardMeta {
            format: SHARD_FORMAT.into(),
            study: study.clone(),
            plan_hash: plan_hash(base, plan)?,
            runs: plan.len(),
            shard: [k, n],
            source_name: source_name.to_string(),
            scenario: base.file.clone(),
            plan: plan.clone(),
        };
        write_shard_meta(dir.path(), &meta)?;
        format!("shard {k}/{n}: {} runs ({} failed)", agg.runs, agg.failed)
    } else {
        let (title, report) = write_study_outputs(dir.path(), study, &base.file, source_name, &agg)?;
        faults = report;
        title
    };
    dir.commit()?;
    journal.remove();
    Ok(StudyDone { title, aggregate: agg, faults })
}
