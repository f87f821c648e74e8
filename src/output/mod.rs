//! Outputs: time series CSV, JSON summary, plots, written as one consistent set or not at all.
//!
//! A run writes into a fresh, uniquely named temporary folder next to `--out` (created with
//! `mkdir`, so it never follows a planted link) and, when everything is written, moves it into
//! place: a new `--out` is a rename; an existing one is swapped atomically (Linux
//! `renameat2(RENAME_EXCHANGE)`; elsewhere two renames) and the old content removed. A run that
//! fails, or is killed, leaves `--out` as it was. `--out` is checked before the simulation
//! starts: a regular file, a link, or a folder that is not an exoleg output folder is refused.

pub mod animate;
mod csv;
mod plot;
pub use self::csv::*;
pub use plot::*;

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Marker file that identifies a folder exoleg wrote (and may therefore replace).
pub const MARKER: &str = ".exoleg-output";

/// Names exoleg writes into an output folder; a folder holding only these (from an older
/// version, without the marker) may be replaced too.
const KNOWN_OUTPUTS: [&str; 9] = [
    "timeseries.csv",
    "summary.json",
    "force_tracking.png",
    "knee_tracking.png",
    "runs.jsonl",
    "aggregate.csv",
    "robustness.png",
    "leg_motion.gif",
    "shard.jsonl",
];

fn werr(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Write { path: path.to_path_buf(), message: e.to_string() }
}

/// Why `dir` may not be replaced by an output folder, if it may not.
fn foreign_content(dir: &Path) -> Result<Option<String>> {
    let rd = std::fs::read_dir(dir).map_err(|e| werr(dir, e))?;
    let mut names = Vec::new();
    for e in rd {
        let e = e.map_err(|e| werr(dir, e))?;
        names.push(e.file_name().to_string_lossy().to_string());
    }
    if names.iter().any(|n| n == MARKER) {
        return Ok(None);
    }
    let known =
        |n: &str| KNOWN_OUTPUTS.contains(&n) || (n.starts_with("run_") && n[4..].chars().all(|c| c.is_ascii_digit()));
    names.sort();
    Ok(names.into_iter().find(|n| !known(n)))
}

/// Remove temporary folders of earlier runs into `name` whose process is gone (Linux; a
/// `kill -9` leaves one behind).
fn remove_stale_temporaries(parent: &Path, name: &str) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let prefix = format!(".{name}.exoleg-tmp-");
    let Ok(rd) = std::fs::read_dir(parent) else { return };
    for e in rd.flatten() {
        let n = e.file_name().to_string_lossy().to_string();
        let Some(rest) = n.strip_prefix(&prefix) else { continue };
        let pid = rest.split('-').next().unwrap_or("");
        if !pid.is_empty() && pid.chars().all(|c| c.is_ascii_digit()) && !Path::new("/proc").join(pid).exists() {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// An output folder being written: a temporary folder that becomes `--out` on [`Self::commit`].
pub struct OutputDir {
    target: PathBuf,
    tmp: tempfile::TempDir,
}

impl OutputDir {
    /// Check `out` and create the temporary folder beside it. `flag` names the option in errors.
    pub fn prepare(out: &Path, flag: &str) -> Result<Self> {
        let bad = |m: &str| Error::input(flag, out.display().to_string(), m);
        match std::fs::symlink_metadata(out) {
            Ok(m) if m.file_type().is_symlink() => return Err(bad("is a symbolic link: give the folder itself")),
            Ok(m) if !m.is_dir() => return Err(bad("not a directory")),
            Ok(_) => {
                if let Some(n) = foreign_content(out)? {
                    return Err(bad(&format!(
                        "is not an exoleg output folder (it holds `{n}`): give a new or empty folder"
                    )));
                }
            }
            Err(_) => {}
        }
        let name = out.file_name().map(|n| n.to_string_lossy().to_string()).ok_or_else(|| bad("has no folder name"))?;
        let parent = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent).map_err(|e| werr(&parent, e))?;
        remove_stale_temporaries(&parent, &name);
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".{name}.exoleg-tmp-{}-", std::process::id()))
            .tempdir_in(&parent)
            .map_err(|e| werr(&parent, e))?;
        std::fs::write(tmp.path().join(MARKER), b"exoleg output folder\n").map_err(|e| werr(tmp.path(), e))?;
        Ok(Self { target: out.to_path_buf(), tmp })
    }

    /// Where to write the files.
    pub fn path(&self) -> &Path {
        self.tmp.path()
    }

    /// The final location.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Move the finished folder into place (atomically where the OS allows).
    pub fn commit(self) -> Result<()> {
        let tmp = self.tmp.keep();
        let target = &self.target;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(0o755));
        }
        let res = match std::fs::rename(&tmp, target) {
            Ok(()) => Ok(()),
            Err(_) if target.is_dir() => swap_into_place(&tmp, target),
            Err(e) => Err(werr(target, e)),
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
        use std::ffi::CString;
        use std::os::unix::ffi::OsStrExt;
        let a = CString::new(tmp.as_os_str().as_bytes()).map_err(|e| werr(tmp, e))?;
        let b = CString::new(target.as_os_str().as_bytes()).map_err(|e| werr(target, e))?;
        // SAFETY: both are valid NUL-terminated paths; renameat2 only reads them.
        let rc =
            unsafe { libc::renameat2(libc::AT_FDCWD, a.as_ptr(), libc::AT_FDCWD, b.as_ptr(), libc::RENAME_EXCHANGE) };
        if rc == 0 {
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
