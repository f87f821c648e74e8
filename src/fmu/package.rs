//! `exoleg fmu`: the FMU zip of a resolved scenario.
//!
//! The scenario in `resources/scenario.toml` is the resolved one, changed in three ways only:
//! the files it reads are copied to `resources/files/` and named relative to it; a
//! continuous-controller scenario gets `controller.sample_period_s = sim.dt_s` (the master
//! samples and commands at every internal step); a plugin controller is dropped
//! (`controller.kind = "open_loop"`: the master is the controller).

use super::description::{model_description, DescriptionInfo};
use super::slave::Slave;
use super::{MODEL_IDENTIFIER, RESOURCE_SCENARIO};
use crate::error::{Error, Result};
use crate::scenario::ResolvedScenario;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The FMU library's file name as cargo builds it (`cargo build --release -p exoleg-fmu`).
#[cfg(target_os = "linux")]
pub const LIBRARY_FILE: &str = "libexoleg_fmu.so";
/// The FMU library's file name as cargo builds it (`cargo build --release -p exoleg-fmu`).
#[cfg(target_os = "macos")]
pub const LIBRARY_FILE: &str = "libexoleg_fmu.dylib";
/// The FMU library's file name as cargo builds it (`cargo build --release -p exoleg-fmu`).
#[cfg(windows)]
pub const LIBRARY_FILE: &str = "exoleg_fmu.dll";

/// FMI 2.0's platform folder and library extension for this machine.
pub fn platform_folder() -> (&'static str, &'static str) {
    if cfg!(target_os = "macos") {
        ("darwin64", "dylib")
    } else if cfg!(windows) {
        ("win64", "dll")
    } else {
        ("linux64", "so")
    }
}

/// Where `exoleg fmu` looks for the FMU library by default: next to the running executable
/// (`target/release/` after `cargo build --release -p exoleg-fmu`).
pub fn default_library() -> Option<PathBuf> {
    std::env::current_exe().ok()?.parent().map(|d| d.join(LIBRARY_FILE))
}

/// Largest FMU library `exoleg fmu` reads (bytes).
pub const MAX_LIBRARY_BYTES: u64 = 512 << 20;

/// The marker the FMU library carries (`fmu/src/lib.rs`: `exoleg-fmu-library/<version>/fmi2-cs`),
/// kept here reversed: this executable holds the check, never the marker itself (so the exoleg
/// binary is not taken for the library).
const MARKER_PREFIX_REVERSED: &[u8] = b"/yrarbil-umf-gelox";
/// The end of the marker.
const MARKER_SUFFIX: &[u8] = b"/fmi2-cs\0";

/// The zip comment of every FMU exoleg writes (how `exoleg fmu` recognises its own file).
pub const FMU_COMMENT: &str = "exoleg FMU";

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() || hay.len() < needle.len() {
        return None;
    }
    let first = needle[0];
    (0..=hay.len() - needle.len()).find(|&i| hay[i] == first && hay[i..i + needle.len()] == *needle)
}

/// Check that `bytes` are exoleg's FMU library of this version (read, never loaded): a shared
/// library of this platform carrying the `exoleg-fmu` crate's marker. The error says what the
/// file is instead.
pub fn check_library(bytes: &[u8]) -> std::result::Result<(), String> {
    const BUILD: &str = "build it with `cargo build --release -p exoleg-fmu`";
    if bytes.is_empty() {
        return Err(format!("is empty, not the FMU library ({BUILD})"));
    }
    let shared = if cfg!(target_os = "linux") {
        bytes.len() > 18 && bytes.starts_with(b"\x7fELF") && bytes[16] == 3 && bytes[17] == 0
    } else {
        bytes.len() > 4
    };
    if !shared {
        return Err(format!("is not a shared library (the FMU library is; {BUILD})"));
    }
    let mut prefix = std::hint::black_box(MARKER_PREFIX_REVERSED).to_vec();
    prefix.reverse();
    let Some(at) = find(bytes, &prefix) else {
        return Err(format!(
            "is a shared library or program, but not exoleg's FMU library (it has no exoleg-fmu marker: a plugin, or \
             another library?); {BUILD}"
        ));
    };
    let rest = &bytes[at + prefix.len()..];
    let version: String =
        rest.iter().take(40).take_while(|b| b.is_ascii_graphic() && **b != b'/').map(|b| *b as char).collect();
    let ours = rest.starts_with(env!("CARGO_PKG_VERSION").as_bytes())
        && rest[env!("CARGO_PKG_VERSION").len()..].starts_with(MARKER_SUFFIX);
    if !ours {
        return Err(format!(
            "is the FMU library of exoleg {version}, this is exoleg {}: {BUILD} from the same source",
            env!("CARGO_PKG_VERSION")
        ));
    }
    Ok(())
}

/// True when `f` is an FMU exoleg wrote: a zip whose comment is [`FMU_COMMENT`] (at most
/// 64 KiB from its end; the end-of-central-directory record).
pub fn is_exoleg_fmu(f: &mut std::fs::File, len: u64) -> bool {
    use std::io::{Read, Seek, SeekFrom};
    let tail_len = len.min(22 + 65_535);
    if tail_len < 22 || f.seek(SeekFrom::Start(len - tail_len)).is_err() {
        return false;
    }
    let mut tail = Vec::new();
    f.take(tail_len).read_to_end(&mut tail).is_ok() && has_fmu_comment(&tail)
}

/// True when the end of a zip (`tail`: its last bytes) has exoleg's FMU comment.
pub fn has_fmu_comment(tail: &[u8]) -> bool {
    if tail.len() < 22 {
        return false;
    }
    let Some(at) = (0..=tail.len() - 22).rev().find(|&i| tail[i..i + 4] == *b"PK\x05\x06") else { return false };
    let n = u16::from_le_bytes([tail[at + 20], tail[at + 21]]) as usize;
    tail.get(at + 22..at + 22 + n).is_some_and(|c| c == FMU_COMMENT.as_bytes())
}

/// The fuzz target `fmu_library`: the checks `exoleg fmu` makes of a library and of an
/// existing `--out` file, on arbitrary bytes (never loaded, never a panic).
pub fn fuzz_fmu_library(bytes: &[u8]) -> bool {
    let lib = check_library(bytes).is_ok();
    has_fmu_comment(bytes) || lib
}

/// What `exoleg fmu` wrote.
#[derive(Debug, Clone)]
pub struct FmuReport {
    /// The FMU's GUID.
    pub guid: String,
    /// Outputs, parameters and inputs in the description.
    pub outputs: usize,
    /// Parameters the master may set.
    pub parameters: usize,
    /// Files copied into `resources/files/`.
    pub files: usize,
    /// The communication step that samples every reading (s).
    pub sample_period_s: f64,
    /// Bytes of the zip.
    pub bytes: u64,
}

/// Set a dotted key in a TOML table (creating tables on the way).
fn set_key(table: &mut toml::Table, key: &str, value: toml::Value) {
    let mut parts: Vec<&str> = key.split('.').collect();
    let last = parts.pop().unwrap_or(key);
    let mut t = table;
    for p in parts {
        let entry = t.entry(p.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if !entry.is_table() {
            *entry = toml::Value::Table(toml::Table::new());
        }
        let toml::Value::Table(next) = entry else { return };
        t = next;
    }
    t.insert(last.to_string(), value);
}

/// The scenario key that names an input file, as recorded in `summary.json`'s inputs.
fn file_key(input_key: &str) -> Option<&'static str> {
    match input_key {
        "leg.urdf" => Some("leg.urdf"),
        "controller.nominal_leg.urdf" => Some("controller.nominal_leg.urdf"),
        "reference.gait" => Some("reference.gait_file"),
        _ => None,
    }
}

/// The resources' scenario text and the files to copy: (name under `files/`, source path).
fn resource_scenario(r: &ResolvedScenario) -> Result<(String, Vec<(String, PathBuf)>)> {
    let mut table = match toml::Value::try_from(&r.file) {
        Ok(toml::Value::Table(t)) => t,
        _ => return Err(Error::input(&r.source_name, "scenario", "cannot re-serialise the scenario")),
    };
    let m = &r.model;
    if m.sample_every.is_none() {
        set_key(&mut table, "controller.sample_period_s", toml::Value::Float(m.dt_s));
    }
    if r.file.controller.kind == crate::control::ControllerKind::Plugin {
        set_key(&mut table, "controller.kind", toml::Value::String("open_loop".into()));
        if let Some(toml::Value::Table(c)) = table.get_mut("controller") {
            c.remove("plugin");
        }
    }
    let mut files: Vec<(String, PathBuf)> = Vec::new();
    for input in &r.inputs {
        let path = PathBuf::from(&input.origin);
        let Some(key) = file_key(input.key) else { continue };
        if !path.is_absolute() || (key == "reference.gait_file" && r.file.reference.gait_file.is_none()) {
            continue;
        }
        let stem = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_else(|| "input".into());
        let name = match files.iter().find(|(_, p)| *p == path) {
            Some((n, _)) => n.clone(),
            None => {
                let n = if files.iter().any(|(n, _)| *n == stem) { format!("{}_{stem}", files.len()) } else { stem };
                files.push((n.clone(), path.clone()));
                n
            }
        };
        set_key(&mut table, key, toml::Value::String(format!("files/{name}")));
    }
    let body = toml::to_string(&table)
        .map_err(|e| Error::input(&r.source_name, "scenario", format!("cannot write the FMU's scenario: {e}")))?;
    let text = format!(
        "# The scenario of an exoleg FMU, resolved from {}.\n# Files it reads are in files/, next to it.\n\n{body}",
        r.source_name.replace('\n', " ")
    );
    Ok((text, files))
}

/// Write the resources folder under `dir` and open it as an FMU instance would.
fn stage_resources(dir: &Path, text: &str, files: &[(String, PathBuf)]) -> Result<(Slave, String)> {
    let io = |p: &Path, e: std::io::Error| Error::Write { path: p.to_path_buf(), message: e.to_string() };
    std::fs::create_dir_all(dir.join("files")).map_err(|e| io(dir, e))?;
    let scenario = dir.join(RESOURCE_SCENARIO);
    std::fs::write(&scenario, text).map_err(|e| io(&scenario, e))?;
    for (name, src) in files {
        let dst = dir.join("files").join(name);
        let bytes = crate::fsio::read_input(src, crate::scenario::MAX_INPUT_FILE_BYTES)?;
        std::fs::write(&dst, bytes).map_err(|e| io(&dst, e))?;
    }
    let (slave, _, guid) = Slave::open(dir).map_err(|e| {
        Error::Usage(format!("the FMU's own scenario does not run ({}); please report this", e.message))
    })?;
    Ok((slave, guid))
}

/// The rule for `exoleg fmu --out`: a new file, or an FMU exoleg wrote that is none of
/// `inputs`.
pub fn out_rule(inputs: &[PathBuf]) -> crate::fsio::OutFile<'_> {
    crate::fsio::OutFile { flag: "--out", what: "an FMU exoleg wrote", inputs, ours: is_exoleg_fmu }
}

/// Read and check the FMU library (a regular file, capped, exoleg's of this version).
pub fn read_library(library: &Path) -> Result<Vec<u8>> {
    let bad = |m: String| Error::input("--library", library.display().to_string(), m);
    let lib = crate::fsio::read_capped(library, MAX_LIBRARY_BYTES).map_err(|e| {
        bad(format!(
            "{e} (the FMU's library: build it with `cargo build --release -p exoleg-fmu`, or pass --library PATH)"
        ))
    })?;
    check_library(&lib).map_err(bad)?;
    Ok(lib)
}

/// Write the FMU of `resolved` to `out` (through a temporary file, renamed when complete),
/// with `library` (the `exoleg-fmu` crate's shared library) as its binary. `out` is checked
/// first ([`out_rule`]: never one of `inputs`, the library, or anything exoleg did not write).
pub fn package(resolved: &ResolvedScenario, library: &Path, out: &Path, inputs: &[PathBuf]) -> Result<FmuReport> {
    let mut inputs = inputs.to_vec();
    inputs.extend(resolved.input_paths());
    inputs.push(library.to_path_buf());
    crate::fsio::check_out(out, &out_rule(&inputs))?;
    let lib = read_library(library)?;
    let (text, files) = resource_scenario(resolved)?;
    let stage = tempfile::tempdir()
        .map_err(|e| Error::Write { path: std::env::temp_dir(), message: format!("temporary folder: {e}") })?;
    let res_dir = stage.path().join("resources");
    let (slave, guid) = stage_resources(&res_dir, &text, &files)?;
    let m = &resolved.model;
    let period = if m.sample_every.is_some() { m.sample_period_s } else { m.dt_s };
    let name = format!("exoleg {}", resolved.source_name);
    let info =
        DescriptionInfo { model_name: &name, guid: &guid, stop_time_s: m.steps as f64 * m.dt_s, step_size_s: period };
    let xml = model_description(&info, slave.variables());
    let (platform, ext) = platform_folder();
    let mut entries: Vec<(String, Vec<u8>, u32)> = vec![
        ("modelDescription.xml".into(), xml.into_bytes(), 0o644),
        (format!("binaries/{platform}/{MODEL_IDENTIFIER}.{ext}"), lib, 0o755),
        (format!("resources/{RESOURCE_SCENARIO}"), text.into_bytes(), 0o644),
    ];
    for (n, _) in &files {
        let p = res_dir.join("files").join(n);
        let bytes = std::fs::read(&p).map_err(|e| Error::Read { path: p.clone(), message: e.to_string() })?;
        entries.push((format!("resources/files/{n}"), bytes, 0o644));
    }
    let bytes = write_zip(out, &entries, &out_rule(&inputs))?;
    let vars = slave.variables();
    Ok(FmuReport {
        guid,
        outputs: vars.iter().filter(|v| v.causality == super::Causality::Output).count(),
        parameters: vars.iter().filter(|v| v.causality == super::Causality::Parameter).count(),
        files: files.len(),
        sample_period_s: period,
        bytes,
    })
}

/// Write a zip of `entries` (name, bytes, unix mode) to `out` under `rule`; returns its size.
fn write_zip(out: &Path, entries: &[(String, Vec<u8>, u32)], rule: &crate::fsio::OutFile) -> Result<u64> {
    crate::fsio::write_out(out, rule, |f| {
        let mut zip = zip::ZipWriter::new(&mut *f);
        for (name, bytes, mode) in entries {
            let opts = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Deflated)
                .last_modified_time(zip::DateTime::default())
                .unix_permissions(*mode);
            zip.start_file(name.as_str(), opts).map_err(std::io::Error::other)?;
            zip.write_all(bytes)?;
        }
        zip.set_comment(FMU_COMMENT).map_err(std::io::Error::other)?;
        zip.finish().map_err(std::io::Error::other)?;
        Ok(())
    })
}
