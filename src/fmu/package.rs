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
        std::fs::copy(src, &dst).map_err(|e| Error::Read { path: src.clone(), message: e.to_string() })?;
    }
    let (slave, _, guid) = Slave::open(dir).map_err(|e| {
        Error::Usage(format!("the FMU's own scenario does not run ({}); please report this", e.message))
    })?;
    Ok((slave, guid))
}

/// Write the FMU of `resolved` to `out` (through a temporary file, renamed when complete),
/// with `library` (the `exoleg-fmu` crate's shared library) as its binary.
pub fn package(resolved: &ResolvedScenario, library: &Path, out: &Path) -> Result<FmuReport> {
    let lib = std::fs::read(library).map_err(|e| Error::Read {
        path: library.to_path_buf(),
        message: format!(
            "{e} (the FMU's library: build it with `cargo build --release -p exoleg-fmu`, or pass --library PATH)"
        ),
    })?;
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
    let bytes = write_zip(out, &entries)?;
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

/// Write a zip of `entries` (name, bytes, unix mode) to `out` atomically; returns its size.
fn write_zip(out: &Path, entries: &[(String, Vec<u8>, u32)]) -> Result<u64> {
    let io = |e: &dyn std::fmt::Display| Error::Write { path: out.to_path_buf(), message: e.to_string() };
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if out.is_dir() {
        return Err(Error::Usage(format!("--out {} is a folder: give the FMU's file name", out.display())));
    }
    let tmp = tempfile::NamedTempFile::new_in(&dir).map_err(|e| io(&e))?;
    let mut zip = zip::ZipWriter::new(tmp.reopen().map_err(|e| io(&e))?);
    for (name, bytes, mode) in entries {
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .last_modified_time(zip::DateTime::default())
            .unix_permissions(*mode);
        zip.start_file(name.as_str(), opts).map_err(|e| io(&e))?;
        zip.write_all(bytes).map_err(|e| io(&e))?;
    }
    let f = zip.finish().map_err(|e| io(&e))?;
    f.sync_all().map_err(|e| io(&e))?;
    let len = f.metadata().map_err(|e| io(&e))?.len();
    tmp.persist(out).map_err(|e| io(&e.error))?;
    Ok(len)
}
