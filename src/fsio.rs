//! Files in and out, one rule each way.
//!
//! **In**: every file exoleg reads (scenario, URDF, gait CSV, plugin, FMU library, shard) is a
//! regular file, opened without blocking (a FIFO is refused, never waited on) and checked on
//! the open file itself, then read with a size cap ([`read_capped`]).
//!
//! **Out**: a command that writes one file (`fmu --out`, `compare --json`, `urdf --out`)
//! writes only to a new path or over a regular file exoleg wrote (each command recognises its
//! own format: [`OutFile::ours`]); never over a symbolic link, a device, a FIFO, a socket, a
//! folder or one of the command's own inputs ([`check_out`]). The bytes go to a temporary file
//! beside the target, are synced, and take the target's place in one rename that cannot
//! replace anything else: Linux `renameat2` with `RENAME_NOREPLACE` for a new path, and with
//! `RENAME_EXCHANGE` for exoleg's own file, whose identity (device, inode) is checked once
//! exchanged and swapped back if it changed since the check ([`write_out`]).

use crate::error::{Error, Result};
use std::fs::File;
use std::io::{Read, Write};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// A file's identity: (device, inode).
pub type Identity = (u64, u64);

/// What kind of thing `m` describes, for messages.
fn kind(m: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = m.file_type();
    if t.is_symlink() {
        "a symbolic link"
    } else if t.is_dir() {
        "a folder"
    } else if t.is_char_device() || t.is_block_device() {
        "a device"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_socket() {
        "a socket"
    } else {
        "a regular file"
    }
}

/// An OS error as exoleg says it (a link loop is not "file not found").
pub fn io_message(e: &std::io::Error) -> String {
    match e.raw_os_error() {
        Some(40) => "a symbolic link loop (too many levels of symbolic links)".into(),
        _ => e.to_string(),
    }
}

/// Open `path` for reading without blocking (a FIFO with no writer opens at once and is then
/// refused) and without taking a terminal; `follow`: follow a final symbolic link. Errors
/// say what is there when it is not a regular file.
fn open_checked(path: &Path, follow: bool) -> std::result::Result<(File, std::fs::Metadata), String> {
    use rustix::fs::{Mode, OFlags};
    // Look first: a device is never opened (opening some has effects).
    let before = if follow { std::fs::metadata(path) } else { std::fs::symlink_metadata(path) };
    let before = before.map_err(|e| io_message(&e))?;
    if !before.is_file() {
        return Err(format!("{}, not a regular file", kind(&before)));
    }
    let mut flags = OFlags::RDONLY | OFlags::NONBLOCK | OFlags::CLOEXEC | OFlags::NOCTTY;
    if !follow {
        flags |= OFlags::NOFOLLOW;
    }
    let fd = rustix::fs::open(path, flags, Mode::empty()).map_err(|e| io_message(&e.into()))?;
    let f = File::from(fd);
    let m = f.metadata().map_err(|e| io_message(&e))?;
    if !m.is_file() || (m.dev(), m.ino()) != (before.dev(), before.ino()) {
        return Err(format!("{}, not a regular file", kind(&m)));
    }
    Ok((f, m))
}

/// Open a regular file for reading (following links); the error names what is there instead.
pub fn open_regular(path: &Path) -> std::result::Result<(File, u64), String> {
    open_checked(path, true).map(|(f, m)| (f, m.len()))
}

/// The bytes of the regular file `path`, at most `cap` of them (more is an error, found
/// without reading past the cap). Errors say what is wrong, without the path.
pub fn read_capped(path: &Path, cap: u64) -> std::result::Result<Vec<u8>, String> {
    let (f, len) = open_regular(path)?;
    if len > cap {
        return Err(format!("{len} bytes, more than the {cap} byte limit"));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    f.take(cap + 1).read_to_end(&mut bytes).map_err(|e| io_message(&e))?;
    if bytes.len() as u64 > cap {
        return Err(format!("more than the {cap} byte limit"));
    }
    Ok(bytes)
}

/// [`read_capped`] as an [`Error::Read`] naming the path.
pub fn read_input(path: &Path, cap: u64) -> Result<Vec<u8>> {
    read_capped(path, cap).map_err(|message| Error::Read { path: path.to_path_buf(), message })
}

/// The identity of what `path` names (following links), if it exists.
pub fn identity(path: &Path) -> Option<Identity> {
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

/// The rule for one file a command writes.
pub struct OutFile<'a> {
    /// The flag that names it (`--out`, `--json`), for messages.
    pub flag: &'a str,
    /// What exoleg writes there, for messages ("an FMU", "a URDF").
    pub what: &'a str,
    /// The command's inputs (scenario, URDF, gait file, plugin, library, ...): never written.
    pub inputs: &'a [PathBuf],
    /// Recognises a file exoleg wrote in this format (the open file and its length).
    pub ours: fn(&mut File, u64) -> bool,
}

/// The inputs every command has: its own executable.
pub fn own_executable() -> Vec<PathBuf> {
    std::env::current_exe().into_iter().collect()
}

/// Check that `path` may be written under `rule`: nothing there (None), or a regular file
/// exoleg wrote in this format that is no input of the command (its identity). Anything else
/// is refused (exit 2) before the command does its work.
pub fn check_out(path: &Path, rule: &OutFile) -> Result<Option<Identity>> {
    let bad = |m: String| Error::input(rule.flag, path.display().to_string(), m);
    let raw = path.to_string_lossy();
    if raw.is_empty() || raw.ends_with('/') || path.file_name().is_none() {
        return Err(bad(format!("names a folder: give the file name of {}", rule.what)));
    }
    let m = match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(bad(io_message(&e))),
        Ok(m) => m,
    };
    if !m.file_type().is_file() {
        return Err(bad(format!(
            "is {}: exoleg writes only a new file or one it wrote ({}); give another name",
            kind(&m),
            rule.what
        )));
    }
    let id = (m.dev(), m.ino());
    if let Some(i) = rule.inputs.iter().find(|i| identity(i) == Some(id)) {
        return Err(bad(format!("is an input of this command ({}): give another name", i.display())));
    }
    let (mut f, m2) = open_checked(path, false).map_err(bad)?;
    if (m2.dev(), m2.ino()) != id || !(rule.ours)(&mut f, m2.len()) {
        return Err(bad(format!(
            "holds a file exoleg did not write (not {}): give a new name, or remove it first",
            rule.what
        )));
    }
    Ok(Some(id))
}

fn werr(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Write { path: path.to_path_buf(), message: e.to_string() }
}

/// Write a file under `rule`: [`check_out`], `fill` writes the content into a temporary file
/// beside `path` (mode 0644), synced, then moved into place by a rename that replaces nothing
/// but the file checked. Returns the file's size.
pub fn write_out(path: &Path, rule: &OutFile, fill: impl FnOnce(&mut File) -> std::io::Result<()>) -> Result<u64> {
    let expected = check_out(path, rule)?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp =
        tempfile::Builder::new().prefix(&format!(".{name}.exoleg-tmp-")).tempfile_in(dir).map_err(|e| werr(path, e))?;
    let (mut f, tmp_path) = tmp.into_parts();
    fill(&mut f).and_then(|_| f.flush()).map_err(|e| werr(path, e))?;
    {
        use std::os::unix::fs::PermissionsExt;
        f.set_permissions(std::fs::Permissions::from_mode(0o644)).map_err(|e| werr(path, e))?;
    }
    f.sync_all().map_err(|e| werr(path, e))?;
    let len = f.metadata().map_err(|e| werr(path, e))?.len();
    drop(f);
    place(&tmp_path, path, expected, rule)?;
    // `tmp_path` now names the replaced file (or nothing): dropping it removes it.
    drop(tmp_path);
    Ok(len)
}

/// [`write_out`] of bytes.
pub fn write_bytes(path: &Path, rule: &OutFile, bytes: &[u8]) -> Result<u64> {
    write_out(path, rule, |f| f.write_all(bytes))
}

/// Move `tmp` to `path`, replacing nothing (`expected` None) or exactly the file `expected`.
fn place(tmp: &Path, path: &Path, expected: Option<Identity>, rule: &OutFile) -> Result<()> {
    use rustix::fs::{renameat_with, RenameFlags, CWD};
    let changed =
        || Error::input(rule.flag, path.display().to_string(), "changed while exoleg was writing it: left as it is");
    match expected {
        None => match renameat_with(CWD, tmp, CWD, path, RenameFlags::NOREPLACE) {
            Ok(()) => Ok(()),
            Err(rustix::io::Errno::EXIST) => Err(changed()),
            // A file system without renameat2: a hard link never replaces anything.
            Err(_) => {
                std::fs::hard_link(tmp, path).map_err(|e| match e.kind() {
                    std::io::ErrorKind::AlreadyExists => changed(),
                    _ => werr(path, e),
                })?;
                std::fs::remove_file(tmp).map_err(|e| werr(tmp, e))
            }
        },
        Some(id) => match renameat_with(CWD, tmp, CWD, path, RenameFlags::EXCHANGE) {
            Ok(()) => {
                let old = std::fs::symlink_metadata(tmp).map_err(|e| werr(tmp, e))?;
                if old.file_type().is_file() && (old.dev(), old.ino()) == id {
                    return Ok(());
                }
                // Something else took the path since the check: put it back.
                renameat_with(CWD, tmp, CWD, path, RenameFlags::EXCHANGE).map_err(|e| werr(path, e))?;
                Err(changed())
            }
            Err(_) => {
                let now = std::fs::symlink_metadata(path).map_err(|_| changed())?;
                if !now.file_type().is_file() || (now.dev(), now.ino()) != id {
                    return Err(changed());
                }
                std::fs::rename(tmp, path).map_err(|e| werr(path, e))
            }
        },
    }
}

/// Read at most `n` bytes from the start of `f`.
pub fn head(f: &mut File, n: usize) -> Vec<u8> {
    let mut buf = Vec::with_capacity(n.min(1 << 20));
    let _ = f.take(n as u64).read_to_end(&mut buf);
    buf
}

#[cfg(test)]
mod tests {
    use super::*;

    fn any(_: &mut File, _: u64) -> bool {
        true
    }

    fn never(_: &mut File, _: u64) -> bool {
        false
    }

    #[test]
    fn writes_new_and_own_files_only() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("a.txt");
        let input = d.path().join("in.txt");
        std::fs::write(&input, "input").unwrap();
        let inputs = [input.clone()];
        let rule = OutFile { flag: "--out", what: "a test file", inputs: &inputs, ours: any };
        write_bytes(&p, &rule, b"one").unwrap();
        write_bytes(&p, &rule, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        use std::os::unix::fs::PermissionsExt;
        assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o644);
        // An input, a link to it, a hard link to it: refused, untouched.
        let link = d.path().join("link");
        std::os::unix::fs::symlink(&input, &link).unwrap();
        let hard = d.path().join("hard");
        std::fs::hard_link(&input, &hard).unwrap();
        for t in [&input, &link, &hard] {
            let e = write_bytes(t, &rule, b"x").unwrap_err();
            assert_eq!(e.exit_code(), 2, "{e}");
        }
        assert_eq!(std::fs::read(&input).unwrap(), b"input");
        // A file exoleg did not write, a FIFO, a folder.
        let foreign = OutFile { ours: never, ..rule };
        assert!(write_bytes(&p, &foreign, b"x").unwrap_err().to_string().contains("did not write"));
        let fifo = d.path().join("fifo");
        rustix::fs::mknodat(
            rustix::fs::CWD,
            &fifo,
            rustix::fs::FileType::Fifo,
            rustix::fs::Mode::from_raw_mode(0o644),
            0,
        )
        .unwrap();
        assert!(write_bytes(&fifo, &foreign, b"x").unwrap_err().to_string().contains("a FIFO"));
        assert!(write_bytes(d.path(), &foreign, b"x").unwrap_err().to_string().contains("a folder"));
        // Nothing left behind.
        let left: Vec<_> = std::fs::read_dir(d.path())
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().contains("exoleg-tmp"))
            .collect();
        assert!(left.is_empty());
    }

    #[test]
    fn reads_regular_files_only_and_capped() {
        let d = tempfile::tempdir().unwrap();
        let fifo = d.path().join("fifo");
        rustix::fs::mknodat(
            rustix::fs::CWD,
            &fifo,
            rustix::fs::FileType::Fifo,
            rustix::fs::Mode::from_raw_mode(0o644),
            0,
        )
        .unwrap();
        assert!(read_capped(&fifo, 10).unwrap_err().contains("a FIFO"));
        assert!(read_capped(Path::new("/dev/zero"), 10).unwrap_err().contains("a device"));
        assert!(read_capped(d.path(), 10).unwrap_err().contains("a folder"));
        let f = d.path().join("f");
        std::fs::write(&f, "0123456789ab").unwrap();
        assert!(read_capped(&f, 10).unwrap_err().contains("limit"));
        assert_eq!(read_capped(&f, 12).unwrap(), b"0123456789ab");
        let (a, b) = (d.path().join("a"), d.path().join("b"));
        std::os::unix::fs::symlink(&a, &b).unwrap();
        std::os::unix::fs::symlink(&b, &a).unwrap();
        assert!(read_capped(&a, 10).unwrap_err().contains("loop"));
    }
}
