//! Outputs: time series CSV, JSON summary, plots, written as one consistent set or not at all.
//!
//! A run writes into a fresh, uniquely named temporary folder next to `--out` (created with
//! `mkdir`, so it never follows a planted link) and, when everything is written, moves it into
//! place: a new `--out` is a rename; an existing one is swapped atomically (Linux
//! `renameat2(RENAME_EXCHANGE)`; elsewhere two renames) and the old content removed. A run that
//! fails, or is killed, leaves `--out` as it was (a signal removes the temporary folder; after
//! `kill -9` the next run into the same place removes it, once its lock shows the run gone).
//! `--out` is checked before the simulation starts: a regular file, a link, a folder holding an
//! input of the run, or a folder with anything exoleg did not write is refused.

pub mod animate;
mod csv;
pub mod indicators;
mod parquet;
mod plot;
pub mod text;
pub use self::csv::*;
pub use self::parquet::{ParquetSink, TimeSeriesSink, ROW_GROUP_ROWS};
pub use plot::*;

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Marker file that identifies a folder exoleg wrote: its first line says so, the next lines
/// list every file exoleg wrote there (paths relative to the folder).
pub const MARKER: &str = ".exoleg-output";
/// The marker's first line.
const MARKER_HEADER: &str = "exoleg output folder";
/// A lock file inside a temporary folder, locked while its run is alive.
const LOCK: &str = ".exoleg-lock";
/// Names an older exoleg wrote into a folder whose marker has no list.
const OLD_OUTPUTS: [&str; 10] = [
    "timeseries.parquet",
    "timeseries.csv",
    "summary.json",
    "force_tracking.png",
    "knee_tracking.png",
    "runs.jsonl",
    "aggregate.csv",
    "robustness.png",
    "leg_motion.gif",
    "shard.json",
];
/// Most entries checked in a folder before it is replaced.
const MAX_ENTRIES: usize = 1_000_000;

fn werr(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Write { path: path.to_path_buf(), message: e.to_string() }
}

/// Every file under `dir` (relative paths; folders are walked, nothing else followed), up to
/// [`MAX_ENTRIES`]; a link or any entry that is neither file nor folder is returned as is.
fn walk(dir: &Path) -> Result<Vec<(PathBuf, bool)>> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        for e in std::fs::read_dir(dir.join(&rel)).map_err(|e| werr(dir, e))? {
            let e = e.map_err(|e| werr(dir, e))?;
            let path = rel.join(e.file_name());
            let ty = e.file_type().map_err(|e| werr(dir, e))?;
            if ty.is_dir() && !ty.is_symlink() {
                stack.push(path);
            } else {
                out.push((path, ty.is_file()));
            }
            if out.len() + stack.len() > MAX_ENTRIES {
                return Err(werr(dir, format!("more than {MAX_ENTRIES} entries")));
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Why `dir` may not be replaced by an output folder, if it may not: exoleg replaces a folder
/// only if it is empty, or exoleg wrote it (the marker) and it holds nothing but the files the
/// marker lists (a file a user put there, or a folder named like an output, is never deleted).
fn foreign_content(dir: &Path) -> Result<Option<String>> {
    let entries = walk(dir)?;
    if entries.is_empty() {
        return Ok(None);
    }
    let marker = match std::fs::symlink_metadata(dir.join(MARKER)) {
        Ok(m) if m.is_file() && m.len() < 64 << 20 => std::fs::read_to_string(dir.join(MARKER)).unwrap_or_default(),
        _ => String::new(),
    };
    let mut lines = marker.lines();
    if lines.next() != Some(MARKER_HEADER) {
        return Ok(Some(entries[0].0.display().to_string()));
    }
    let listed: std::collections::BTreeSet<&str> = lines.collect();
    let old = |p: &Path| {
        let parts: Vec<String> = p.iter().map(|c| c.to_string_lossy().to_string()).collect();
        let name = parts.last().map(String::as_str).unwrap_or("");
        let run_dir =
            |d: &str| d.strip_prefix("run_").is_some_and(|n| !n.is_empty() && n.chars().all(|c| c.is_ascii_digit()));
        OLD_OUTPUTS.contains(&name) && (parts.len() == 1 || parts.len() == 2 && run_dir(&parts[0]))
    };
    for (p, is_file) in &entries {
        let s = p.to_string_lossy();
        let ok = *is_file && (s == MARKER || listed.contains(s.as_ref()) || listed.is_empty() && old(p));
        if !ok {
            return Ok(Some(s.into_owned()));
        }
    }
    Ok(None)
}

/// Remove temporary folders of earlier runs into `name` whose run is gone: a live run holds
/// an advisory lock on the folder's lock file (which works across PID namespaces sharing the
/// volume); a folder without one is left alone for an hour (it may be just being created).
fn remove_stale_temporaries(parent: &Path, name: &str) {
    let prefix = format!(".{name}.exoleg-tmp-");
    let Ok(rd) = std::fs::read_dir(parent) else { return };
    for e in rd.flatten() {
        let n = e.file_name().to_string_lossy().to_string();
        if !n.starts_with(&prefix) || !e.file_type().is_ok_and(|t| t.is_dir()) {
            continue;
        }
        let lock = e.path().join(LOCK);
        let stale = match std::fs::File::open(&lock) {
            Ok(f) => rustix::fs::flock(&f, rustix::fs::FlockOperation::NonBlockingLockExclusive).is_ok(),
            Err(_) => e
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_some_and(|age| age > std::time::Duration::from_secs(3600)),
        };
        if stale {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// The temporary folders being written by this process, removed by [`remove_active`] when a
/// signal ends it (Ctrl-C, `kill`, Slurm and Kubernetes stopping a job).
static ACTIVE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn active() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    ACTIVE.lock().unwrap_or_else(|p| p.into_inner())
}

/// Remove every temporary output folder this process is writing (called on SIGINT, SIGTERM,
/// SIGHUP before the process exits; the folders are then as if the run never started).
pub fn remove_active() {
    for p in active().drain(..) {
        let _ = std::fs::remove_dir_all(p);
    }
}

/// An output folder being written: a temporary folder that becomes `--out` on [`Self::commit`].
pub struct OutputDir {
    target: PathBuf,
    /// The temporary folder (None once committed).
    tmp: Option<tempfile::TempDir>,
    /// Its path.
    path: PathBuf,
    /// Held open (and locked) while the run is alive; see [`remove_stale_temporaries`].
    _lock: std::fs::File,
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        active().retain(|a| *a != self.path);
    }
}

/// True when `inner` is `outer` or inside it (both made absolute as far as they exist).
pub fn within(inner: &Path, outer: &Path) -> bool {
    let abs = |p: &Path| {
        let p = if p.is_absolute() { p.to_path_buf() } else { std::env::current_dir().unwrap_or_default().join(p) };
        // Canonicalise the longest part that exists (the rest cannot hold a link).
        let mut head = p.clone();
        let mut tail = Vec::new();
        while !head.exists() {
            match (head.file_name().map(|n| n.to_os_string()), head.parent()) {
                (Some(n), Some(par)) => {
                    tail.push(n);
                    head = par.to_path_buf();
                }
                _ => break,
            }
        }
        let mut c = std::fs::canonicalize(&head).unwrap_or(head);
        c.extend(tail.iter().rev());
        c
    };
    abs(inner).starts_with(abs(outer))
}

impl OutputDir {
    /// Check `out` and create the temporary folder beside it. `flag` names the option in errors.
    pub fn prepare(out: &Path, flag: &str) -> Result<Self> {
        Self::prepare_with_inputs(out, flag, &[])
    }

    /// [`Self::prepare`], refusing an `out` that is or holds one of `inputs` (a run never writes
    /// onto what it reads).
    pub fn prepare_with_inputs(out: &Path, flag: &str, inputs: &[PathBuf]) -> Result<Self> {
        let bad = |m: &str| Error::input(flag, out.display().to_string(), m);
        if let Some(i) = inputs.iter().find(|i| within(i, out)) {
            return Err(bad(&format!("holds an input of this run ({}): give another folder", i.display())));
        }
        match std::fs::symlink_metadata(out) {
            Ok(m) if m.file_type().is_symlink() => return Err(bad("is a symbolic link: give the folder itself")),
            Ok(m) if !m.is_dir() => return Err(bad("not a directory")),
            Ok(_) => {
                if let Some(n) = foreign_content(out)? {
                    return Err(bad(&format!(
                        "is not an exoleg output folder (it holds `{n}`, which exoleg did not write): give a new or empty folder"
                    )));
                }
            }
            Err(_) => {}
        }
        // `out/.` and `out/..` name no folder of their own (Rust's paths drop a trailing `.`).
        let raw = out.to_string_lossy();
        let raw = raw.trim_end_matches('/');
        let dots = raw == "." || raw == ".." || raw.ends_with("/.") || raw.ends_with("/..");
        let name = match out.file_name() {
            Some(n) if !dots => n.to_string_lossy().to_string(),
            _ => return Err(bad("has no folder name (`.`, `..` or a root): name the folder")),
        };
        // Absolute from here on: nothing the run does later (a plugin changing the working
        // directory) moves where its outputs go.
        let out = &std::path::absolute(out).map_err(|e| bad(&e.to_string()))?;
        let parent = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("/"),
        };
        std::fs::create_dir_all(&parent).map_err(|e| werr(&parent, e))?;
        remove_stale_temporaries(&parent, &name);
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".{name}.exoleg-tmp-"))
            .tempdir_in(&parent)
            .map_err(|e| werr(&parent, e))?;
        let lock = std::fs::File::create(tmp.path().join(LOCK)).map_err(|e| werr(tmp.path(), e))?;
        rustix::fs::flock(&lock, rustix::fs::FlockOperation::NonBlockingLockExclusive)
            .map_err(|e| werr(tmp.path(), e))?;
        active().push(tmp.path().to_path_buf());
        std::fs::write(tmp.path().join(MARKER), format!("{MARKER_HEADER}\n")).map_err(|e| werr(tmp.path(), e))?;
        Ok(Self { target: out.to_path_buf(), path: tmp.path().to_path_buf(), tmp: Some(tmp), _lock: lock })
    }

    /// Where to write the files.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The final location.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Move the finished folder into place (atomically where the OS allows). The marker lists
    /// every file written, so a later run may replace exactly these.
    pub fn commit(mut self) -> Result<()> {
        let _ = std::fs::remove_file(self.path.join(LOCK));
        let mut manifest = format!("{MARKER_HEADER}\n");
        for (p, _) in walk(&self.path)? {
            if p != Path::new(MARKER) {
                manifest.push_str(&format!("{}\n", p.display()));
            }
        }
        std::fs::write(self.path.join(MARKER), manifest).map_err(|e| werr(&self.path, e))?;
        let target = self.target.clone();
        let Some(tmp) = self.tmp.take() else { return Err(werr(&target, "already committed")) };
        let tmp = tmp.keep();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(0o755));
        }
        let res = match std::fs::rename(&tmp, &target) {
            Ok(()) => Ok(()),
            Err(_) if target.is_dir() => swap_into_place(&tmp, &target),
            Err(e) => Err(werr(&target, e)),
        };
        if res.is_err() {
            let _ = std::fs::remove_dir_all(&tmp);
        }
        res
    }
}

/// Replace the existing folder `target` by `tmp`, then remove the old content.
fn swap_into_place(tmp: &Path, target: &Path) -> Result<()> {
    if let Some(n) = foreign_content(target)? {
        return Err(werr(target, format!("is no longer an exoleg output folder (it holds `{n}`)")));
    }
    #[cfg(target_os = "linux")]
    {
        use rustix::fs::{renameat_with, RenameFlags, CWD};
        if renameat_with(CWD, tmp, CWD, target, RenameFlags::EXCHANGE).is_ok() {
            let _ = std::fs::remove_dir_all(tmp);
            return Ok(());
        }
    }
    let old = PathBuf::from(format!("{}-old", tmp.display()));
    std::fs::rename(target, &old).map_err(|e| werr(target, e))?;
    std::fs::rename(tmp, target).map_err(|e| werr(target, e))?;
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

/// Write `bytes` to `path` atomically: a uniquely named temporary file in the same folder
/// (created exclusively, never following a link), synced, then renamed over `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if path.is_dir() {
        return Err(Error::input("output", path.display().to_string(), "is a directory, not a file"));
    }
    let mut f = tempfile::Builder::new().prefix(".exoleg-tmp-").tempfile_in(dir).map_err(|e| werr(path, e))?;
    f.write_all(bytes).map_err(|e| werr(path, e))?;
    f.as_file().sync_all().map_err(|e| werr(path, e))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = f.as_file().set_permissions(std::fs::Permissions::from_mode(0o644));
    }
    f.persist(path).map_err(|e| werr(path, e.error))?;
    Ok(())
}

/// Serialise `value` as pretty JSON into `path` (atomic).
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let bytes = serde_json::to_vec_pretty(value).map_err(|e| werr(path, e))?;
    write_atomic(path, &bytes)
}
