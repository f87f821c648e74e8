//! Sweeps beyond one machine (issue 9): a sweep's runs split into shards (`--shard K/N`: the
//! runs whose index % N == K, matching Slurm's `SLURM_ARRAY_TASK_ID` and Kubernetes Indexed
//! Jobs' `JOB_COMPLETION_INDEX`), each written to its own folder with the plan's hash, and
//! merged back (`exoleg merge`) into exactly what the unsharded sweep writes.
//!
//! A shard folder holds `shard.json` ([`ShardMeta`]) and `runs.jsonl` (its runs' lines, with
//! their global indices, in index order). The merge streams the shards in round-robin order
//! (index i is line i / N of shard i % N), so it never holds the runs in memory, and refuses
//! shards of different plans, a missing or duplicated shard, or a line out of place.

use super::robustness;
use super::sweep::{Aggregate, Plan, RunLine};
use crate::error::{Error, Result};
use crate::output::{self, OutputDir};
use crate::scenario::{Scenario, ScenarioFile};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

/// The format tag of `shard.json`.
pub const SHARD_FORMAT: &str = "exoleg-shard-1";

/// What kind of study a plan belongs to (what the merge writes besides the runs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StudyKind {
    /// `exoleg sweep`: `runs.jsonl` and `aggregate.csv`.
    Sweep,
    /// `exoleg robustness`: also `robustness.png`, judged by the scenario's criteria.
    Robustness {
        /// Half-width of the variation (%).
        percent: f64,
    },
}

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
pub fn write_plan(plan: &Plan, out: &mut dyn Write) -> Result<()> {
    for i in 0..plan.len() {
        let line = serde_json::json!({ "index": i, "sets": plan.sets(i) });
        writeln!(out, "{line}").map_err(|e| Error::Write { path: "<stdout>".into(), message: e.to_string() })?;
    }
    Ok(())
}

/// Write the files a finished study has besides `runs.jsonl` (`aggregate.csv`, and for a
/// robustness report `robustness.png`) into `dir`. Returns the report's title line.
pub fn write_study_outputs(
    dir: &Path,
    study: &StudyKind,
    base: &ScenarioFile,
    source: &str,
    agg: &Aggregate,
) -> Result<String> {
    output::write_atomic(&dir.join("aggregate.csv"), agg.csv().as_bytes())?;
    match study {
        StudyKind::Sweep => Ok(format!("{} runs ({} failed)", agg.runs, agg.failed)),
        StudyKind::Robustness { percent } => robustness::write_report_png(dir, base, source, *percent, agg),
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
    let meta: ShardMeta = serde_json::from_str(text)
        .map_err(|e| Error::input(p.display().to_string(), "shard.json", format!("not a shard: {e}")))?;
    if meta.format != SHARD_FORMAT {
        return Err(Error::input(
            p.display().to_string(),
            "format",
            format!("expected {SHARD_FORMAT}, got {}", meta.format),
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

/// Check that the shard folders are the N shards of one plan, each once; returns their metas
/// ordered by K.
fn check_shards(dirs: &[PathBuf]) -> Result<Vec<ShardMeta>> {
    let metas: Vec<ShardMeta> = dirs.iter().map(|d| read_meta(d)).collect::<Result<_>>()?;
    let first = metas.first().ok_or_else(|| Error::input("merge", "SHARDS", "give the shard folders"))?;
    let n = first.shard[1];
    for (m, d) in metas.iter().zip(dirs) {
        if m.plan_hash != first.plan_hash || m.shard[1] != n || m.runs != first.runs || m.study != first.study {
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
    }
    let mut seen = vec![None; n];
    for (i, m) in metas.iter().enumerate() {
        let k = m.shard[0];
        if k >= n {
            return Err(Error::input(dirs[i].display().to_string(), "shard", format!("shard {k} of {n}")));
        }
        if let Some(j) = seen[k] {
            return Err(Error::input(
                dirs[i].display().to_string(),
                "shard",
                format!("shard {k}/{n} given twice (also {})", dirs[j as usize].display()),
            ));
        }
        seen[k] = Some(i as u32);
    }
    if let Some(k) = seen.iter().position(|s| s.is_none()) {
        return Err(Error::input("merge", "SHARDS", format!("shard {k}/{n} is missing")));
    }
    let mut ordered: Vec<(usize, ShardMeta)> = metas.into_iter().enumerate().collect();
    ordered.sort_by_key(|(_, m)| m.shard[0]);
    Ok(ordered.into_iter().map(|(_, m)| m).collect())
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
}

/// Merge shard folders into `out`: `runs.jsonl` in index order, `aggregate.csv` and the
/// study's plots, byte for byte what the unsharded study writes.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<Merged> {
    let metas = check_shards(dirs)?;
    let mut by_k: Vec<&PathBuf> = dirs.iter().collect();
    by_k.sort_by_key(|d| read_meta(d).map(|m| m.shard[0]).unwrap_or(usize::MAX));
    let n = metas[0].shard[1];
    let mut readers = Vec::with_capacity(n);
    for d in &by_k {
        let p = d.join("runs.jsonl");
        let f =
            std::fs::File::open(&p).map_err(|e| Error::input(p.display().to_string(), "runs.jsonl", e.to_string()))?;
        readers.push((p, std::io::BufReader::new(f).lines()));
    }
    let dir = OutputDir::prepare_with_inputs(out, "--out", dirs)?;
    let path = dir.path().join("runs.jsonl");
    let werr = |e: std::io::Error| Error::Write { path: path.clone(), message: e.to_string() };
    let mut w = std::io::BufWriter::new(std::fs::File::create(&path).map_err(werr)?);
    let mut agg = Aggregate::default();
    for i in 0..metas[0].runs {
        let (p, lines) = &mut readers[i % n];
        let bad = |m: String| Error::input(p.display().to_string(), format!("run {i}"), m);
        let text =
            lines.next().ok_or_else(|| bad("missing: the shard ends early".into()))?.map_err(|e| bad(e.to_string()))?;
        let line: RunLine = serde_json::from_str(&text).map_err(|e| bad(format!("not a run line: {e}")))?;
        if line.index != i {
            return Err(bad(format!("found run {} in its place", line.index)));
        }
        agg.add(&line);
        w.write_all(text.as_bytes()).and_then(|_| w.write_all(b"\n")).map_err(werr)?;
    }
    for (p, lines) in &mut readers {
        if lines.next().is_some() {
            return Err(Error::input(p.display().to_string(), "runs.jsonl", "more runs than the plan has"));
        }
    }
    w.flush().map_err(werr)?;
    drop(w);
    let meta = metas.into_iter().next().expect("checked: at least one shard");
    let title = write_study_outputs(dir.path(), &meta.study, &meta.scenario, &meta.source_name, &agg)?;
    dir.commit()?;
    Ok(Merged { title, meta, aggregate: agg })
}

/// What a study run produced.
#[derive(Debug, Clone)]
pub struct StudyDone {
    /// The report's title line.
    pub title: String,
    /// The aggregated runs (this shard's, when sharded).
    pub aggregate: Aggregate,
}

/// Run a study's plan (all of it, or the shard in `opts.shard` when `sharded`) into the folder
/// `out`, atomically: `runs.jsonl`, and `shard.json` for a shard or the study's other outputs
/// (`aggregate.csv`, plots) for the whole plan. The CLI and the Python package both use it.
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
    let path = dir.path().join("runs.jsonl");
    let werr = |e: std::io::Error| Error::Write { path: path.clone(), message: e.to_string() };
    let mut w = std::io::BufWriter::new(std::fs::File::create(&path).map_err(werr)?);
    let agg = super::sweep::run_plan(base, plan, &res, opts, run_outputs.then_some(dir.path()), &mut w)?;
    w.flush().map_err(werr)?;
    drop(w);
    let title = if sharded {
        let (k, n) = opts.shard;
        let meta = ShardMeta {
            format: SHARD_FORMAT.into(),
            study: study.clone(),
            plan_hash: plan_hash(base, plan)?,
            runs: plan.len(),
            shard: [k, n],
            source_name: source_name.to_string(),
            scenario: base.file.clone(),
        };
        write_shard_meta(dir.path(), &meta)?;
        format!("shard {k}/{n}: {} runs ({} failed)", agg.runs, agg.failed)
    } else {
        write_study_outputs(dir.path(), study, &base.file, source_name, &agg)?
    };
    dir.commit()?;
    Ok(StudyDone { title, aggregate: agg })
}
