//! A study keeps every finished run (issue 34): each run's line is appended to a journal the
//! moment the run ends, so a study that is killed (SIGKILL, a node lost, a plugin's `exit()`)
//! or stopped (Ctrl-C, SIGTERM) keeps what it finished, and `--resume` makes only the missing
//! runs of the same plan.
//!
//! The journal is a folder beside `--out`, `.NAME.exoleg-partial/` (hidden, so `merge
//! shards/*` never takes it for a shard):
//!
//! ```text
//! journal.json    the plan it belongs to (study, plan hash, runs, shard, run outputs, controller)
//! runs.jsonl      one line per finished run, whole lines appended in the order the runs finish
//! run_NNNN/       each run's own outputs (--run-outputs)
//! .exoleg-lock    locked while a study writes the journal (a second one into the same place
//!                 is refused)
//! ```
//!
//! When every run has its line, `runs.jsonl` is written into `--out` in index order from the
//! journal's lines (the same bytes whatever the order they finished in, the number of jobs or
//! how many times the study was resumed), the run folders are moved there, `aggregate.csv`
//! is computed from those lines, `--out` is committed, and the journal removed. A journal of
//! another plan is refused with `--resume` (exit 2) and replaced without it; a last line cut
//! short by a kill is dropped (its run is made again).

use super::lines::{bounded_line, check_line, StudyKind};
use super::sweep::{Aggregate, Plan, RunLine};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The format tag of `journal.json`.
pub const JOURNAL_FORMAT: &str = "exoleg-journal-1";
const META: &str = "journal.json";
const RUNS: &str = "runs.jsonl";
const LOCK: &str = ".exoleg-lock";

/// What a journal belongs to: a study is resumed only from a journal of the same plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JournalMeta {
    /// [`JOURNAL_FORMAT`].
    pub format: String,
    /// The study.
    pub study: StudyKind,
    /// SHA-256 of the base scenario and every run's overrides (the shard module's `plan_hash`).
    pub plan_hash: String,
    /// Runs in the whole plan.
    pub runs: usize,
    /// The shard [K, N] ([0, 1]: all runs).
    pub shard: [usize; 2],
    /// Every run's outputs are kept (`--run-outputs`).
    pub run_outputs: bool,
    /// The runs are made with the caller's controller (the Python package's `controller=`),
    /// not the scenario's.
    pub caller_controller: bool,
}

/// Where the finished lines are: (offset, length with the newline) by position in the shard.
struct Lines {
    file: std::fs::File,
    len: u64,
    at: Vec<Option<(u64, u32)>>,
}

/// An open journal (locked while it lives).
pub struct Journal {
    dir: PathBuf,
    meta: JournalMeta,
    lines: Mutex<Lines>,
    kept: usize,
    _lock: std::fs::File,
}

/// The position of run `i` in the shard [K, N] of `len` runs, if the shard has it.
fn slot_of(i: usize, [k, n]: [usize; 2], len: usize) -> Option<usize> {
    let n = n.max(1);
    (i >= k && (i - k).is_multiple_of(n)).then(|| (i - k) / n).filter(|s| *s < len)
}

fn werr(p: &Path, e: impl std::fmt::Display) -> Error {
    Error::Write { path: p.to_path_buf(), message: e.to_string() }
}

/// The journal folder of a study written to `out`.
pub fn journal_dir(out: &Path) -> PathBuf {
    let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    out.with_file_name(format!(".{name}.exoleg-partial"))
}

/// The journal's `journal.json`, if it is exoleg's (None: no journal there).
fn read_meta(dir: &Path) -> Result<Option<JournalMeta>> {
    let bad = |m: String| Error::input("--out", dir.display().to_string(), m);
    match std::fs::symlink_metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(bad(crate::fsio::io_message(&e))),
        Ok(m) if !m.file_type().is_dir() => {
            return Err(bad("is not the journal of an exoleg study (not a folder): move it away".into()))
        }
        Ok(_) => {}
    }
    let bytes = crate::fsio::read_capped(&dir.join(META), 1 << 20)
        .map_err(|e| bad(format!("is not the journal of an exoleg study ({META}: {e}): move it away")))?;
    serde_json::from_slice::<JournalMeta>(&bytes)
        .ok()
        .filter(|m| m.format == JOURNAL_FORMAT)
        .map(Some)
        .ok_or_else(|| bad(format!("{META} is not an exoleg journal ({JOURNAL_FORMAT}): move the folder away")))
}

/// Lock the journal folder's lock file, or say that a study is writing it.
fn lock(dir: &Path) -> Result<std::fs::File> {
    let p = dir.join(LOCK);
    let f = std::fs::OpenOptions::new().create(true).truncate(false).write(true).open(&p).map_err(|e| werr(&p, e))?;
    rustix::fs::flock(&f, rustix::fs::FlockOperation::NonBlockingLockExclusive).map_err(|_| {
        Error::input(
            "--out",
            dir.display().to_string(),
            "another study is writing into the same place now: wait for it, or give another --out",
        )
    })?;
    Ok(f)
}

/// Empty a journal of exoleg's (its lines and run folders) for a new start.
fn clear(dir: &Path) -> Result<()> {
    for e in std::fs::read_dir(dir).map_err(|e| werr(dir, e))?.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        let run_dir = n.strip_prefix("run_").is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()));
        if n == RUNS || n == META {
            std::fs::remove_file(e.path()).map_err(|e2| werr(&e.path(), e2))?;
        } else if run_dir && e.file_type().is_ok_and(|t| t.is_dir()) {
            std::fs::remove_dir_all(e.path()).map_err(|e2| werr(&e.path(), e2))?;
        }
    }
    Ok(())
}

impl Journal {
    /// Open the journal of a study of `plan` into `out`: with `resume`, keep the lines of a
    /// journal of the same plan (refusing one of another plan); without, start a new one.
    pub fn open(out: &Path, meta: JournalMeta, plan: &Plan, resume: bool) -> Result<Journal> {
        let dir = journal_dir(out);
        let found = read_meta(&dir)?;
        if found.is_none() {
            std::fs::create_dir(&dir).map_err(|e| werr(&dir, e))?;
        }
        let lock = lock(&dir)?;
        if let (true, Some(old)) = (resume, &found) {
            if *old != meta {
                return Err(Error::input(
                    "--resume",
                    dir.display().to_string(),
                    format!(
                        "the interrupted study there ran another plan ({} runs, plan {}, shard {}/{}; this one: {} runs, \
                         plan {}, shard {}/{}): run that plan again with --resume, or leave --resume out to start anew",
                        old.runs,
                        &old.plan_hash.chars().take(12).collect::<String>(),
                        old.shard[0],
                        old.shard[1],
                        meta.runs,
                        &meta.plan_hash[..12.min(meta.plan_hash.len())],
                        meta.shard[0],
                        meta.shard[1]
                    ),
                ));
            }
        } else if found.is_some() {
            clear(&dir)?;
        }
        let mp = dir.join(META);
        if !mp.exists() {
            let text = serde_json::to_vec_pretty(&meta).map_err(|e| werr(&mp, e))?;
            std::fs::write(&mp, text).map_err(|e| werr(&mp, e))?;
        }
        let p = dir.join(RUNS);
        let file =
            std::fs::OpenOptions::new().create(true).append(true).read(true).open(&p).map_err(|e| werr(&p, e))?;
        let [k, n] = meta.shard;
        let mut lines = Lines { file, len: 0, at: vec![None; (k..meta.runs).step_by(n.max(1)).len()] };
        let kept = scan(&p, &mut lines, plan, meta.shard)?;
        remove_unfinished_run_folders(&dir, &lines, meta.shard)?;
        Ok(Journal { dir, meta, lines: Mutex::new(lines), kept, _lock: lock })
    }

    /// Runs kept from an earlier, interrupted study.
    pub fn kept(&self) -> usize {
        self.kept
    }

    /// Where each run's own outputs go (`run_NNNN` inside).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// True when run `i` has its line.
    pub fn done(&self, i: usize) -> bool {
        let l = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        slot_of(i, self.meta.shard, l.at.len()).is_some_and(|s| l.at[s].is_some())
    }

    /// Append a finished run's line (one write of the whole line).
    pub fn append(&self, line: &RunLine) -> Result<()> {
        let p = self.dir.join(RUNS);
        let mut text = serde_json::to_string(line).map_err(|e| werr(&p, e))?;
        text.push('\n');
        let mut l = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        let slot = slot_of(line.index, self.meta.shard, l.at.len());
        l.file.write_all(text.as_bytes()).map_err(|e| werr(&p, e))?;
        let at = l.len;
        l.len += text.len() as u64;
        if let Some(s) = slot {
            l.at[s] = Some((at, text.len() as u32));
        }
        Ok(())
    }

    /// Write `runs.jsonl` into `out_dir` in index order from the journal's lines, checking each
    /// one, and move the runs' own folders there; returns the aggregate of the lines.
    pub fn assemble(&self, plan: &Plan, out_dir: &Path) -> Result<Aggregate> {
        use std::os::unix::fs::FileExt;
        let l = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        l.file.sync_all().map_err(|e| werr(&self.dir, e))?;
        let p = out_dir.join(RUNS);
        let mut w = std::io::BufWriter::new(std::fs::File::create(&p).map_err(|e| werr(&p, e))?);
        let mut agg = Aggregate::default();
        let [k, n] = self.meta.shard;
        let mut buf = Vec::new();
        for (slot, i) in (k..self.meta.runs).step_by(n.max(1)).enumerate() {
            let (at, len) = l.at[slot].ok_or_else(|| werr(&self.dir, format!("run {i} has no line")))?;
            buf.resize(len as usize, 0);
            l.file.read_exact_at(&mut buf, at).map_err(|e| werr(&self.dir, e))?;
            let line = check_line(&buf[..buf.len() - 1], i, plan).map_err(|m| werr(&self.dir.join(RUNS), m))?;
            agg.add(&line);
            w.write_all(&buf).map_err(|e| werr(&p, e))?;
            let run = self.dir.join(format!("run_{i:04}"));
            if self.meta.run_outputs && run.exists() {
                std::fs::rename(&run, out_dir.join(format!("run_{i:04}"))).map_err(|e| werr(&run, e))?;
            }
        }
        w.into_inner().map_err(|e| werr(&p, e.error()))?.sync_all().map_err(|e| werr(&p, e))?;
        Ok(agg)
    }

    /// Remove the journal (its study's outputs are in place).
    pub fn remove(self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Remove the `run_NNNN` folders of runs without a line (a run a kill cut short is made
/// again from nothing).
fn remove_unfinished_run_folders(dir: &Path, lines: &Lines, [k, n]: [usize; 2]) -> Result<()> {
    for e in std::fs::read_dir(dir).map_err(|e| werr(dir, e))?.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(i) = name.strip_prefix("run_").and_then(|d| d.parse::<usize>().ok()) else { continue };
        let done = slot_of(i, [k, n], lines.at.len()).is_some_and(|s| lines.at[s].is_some());
        if !done && e.file_type().is_ok_and(|t| t.is_dir()) {
            std::fs::remove_dir_all(e.path()).map_err(|e2| werr(&e.path(), e2))?;
        }
    }
    Ok(())
}

/// Read a journal's lines into `lines` (the kept runs): every complete line checked against the
/// plan (its index in this shard, once, its overrides, its fields); a last line cut short by a
/// kill is dropped and the file truncated before it. Returns how many lines were kept.
fn scan(p: &Path, lines: &mut Lines, plan: &Plan, [k, n]: [usize; 2]) -> Result<usize> {
    let bad = |m: String| Error::input(p.display().to_string(), "runs.jsonl", m);
    let f = lines.file.try_clone().map_err(|e| werr(p, e))?;
    let mut r = std::io::BufReader::new(f);
    let (mut buf, mut at, mut kept) = (Vec::new(), 0u64, 0);
    while bounded_line(&mut r, &mut buf).map_err(|e| bad(e.to_string()))?.is_some() {
        // bounded_line drops the newline: a line a kill cut short has none after it.
        let ends = {
            use std::os::unix::fs::FileExt;
            let mut nl = [0u8];
            lines.file.read_exact_at(&mut nl, at + buf.len() as u64).is_ok() && nl[0] == b'\n'
        };
        if !ends {
            break;
        }
        let index = serde_json::from_slice::<RunLine>(&buf).map(|l| l.index).unwrap_or(usize::MAX);
        let what = |m: String| bad(format!("line {}: {m} (remove {} to start anew)", kept + 1, p.display()));
        let slot = slot_of(index, [k, n], lines.at.len()).ok_or_else(|| what("not a run of this shard".into()))?;
        if lines.at[slot].is_some() {
            return Err(what(format!("run {index} twice")));
        }
        check_line(&buf, index, plan).map_err(what)?;
        lines.at[slot] = Some((at, buf.len() as u32 + 1));
        at += buf.len() as u64 + 1;
        kept += 1;
    }
    lines.file.set_len(at).map_err(|e| werr(p, e))?;
    lines.len = at;
    Ok(kept)
}

/// The fuzz target `journal`: a journal's `runs.jsonl` as `--resume` reads it (arbitrary
/// bytes, a plan of 8 grid runs), through the real reader on a temporary file. Returns the
/// runs kept; an error is a refusal, never a panic.
pub fn fuzz_journal(bytes: &[u8]) -> Result<usize> {
    let plan = Plan::Grid(vec![("seed".into(), (1..=8).map(|i| i.to_string()).collect())]);
    let dir = tempfile::tempdir().map_err(|e| werr(Path::new("."), e))?;
    let p = dir.path().join(RUNS);
    std::fs::write(&p, bytes).map_err(|e| werr(&p, e))?;
    let file = std::fs::OpenOptions::new().append(true).read(true).open(&p).map_err(|e| werr(&p, e))?;
    let mut lines = Lines { file, len: 0, at: vec![None; 4] };
    // Shard 1 of 2: runs 1, 3, 5, 7.
    let kept = scan(&p, &mut lines, &plan, [1, 2])?;
    if lines.len > bytes.len() as u64 || lines.at.iter().flatten().count() != kept {
        return Err(werr(&p, "the reader kept more than it read"));
    }
    Ok(kept)
}
