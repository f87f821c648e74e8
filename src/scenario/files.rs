//! Files a scenario names (URDF, gait CSV): found once, read with a size cap, hashed, and
//! parsed once per process or sweep ([`Resources`]), so every run that shares a file shares
//! its parsed form and the tables built from it.

use crate::control::PluginLibrary;
use crate::error::{Error, Result};
use crate::leg::BUILTIN_URDFS;
use crate::leg::{LegOptions, LegSpec};
use crate::plant::MassTable;
use crate::reference::{FourierSeries, GaitCycle, BUILTIN_TRIALS};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Largest URDF or gait CSV read (bytes). Documented in the README.
pub const MAX_INPUT_FILE_BYTES: u64 = 8 << 20;
/// Largest scenario file read (bytes).
pub const MAX_SCENARIO_FILE_BYTES: u64 = 1 << 20;

/// SHA-256 of some bytes, as lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    format!("{:x}", Sha256::digest(bytes))
}

/// Most bytes of a plugin library hashed.
pub const MAX_PLUGIN_BYTES: u64 = 1 << 30;

/// Read a text file with a size cap (a regular file, never waited on); errors name the path.
pub fn read_capped(path: &Path, cap: u64) -> Result<String> {
    let bytes = crate::fsio::read_input(path, cap)?;
    String::from_utf8(bytes).map_err(|e| Error::Read {
        path: path.to_path_buf(),
        message: format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
    })
}

/// SHA-256 of a regular file's bytes (streamed, at most [`MAX_PLUGIN_BYTES`]), as lowercase hex.
fn file_sha256(path: &Path) -> std::result::Result<String, String> {
    let (f, len) = crate::fsio::open_regular(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if len > MAX_PLUGIN_BYTES {
        return Err(format!("{}: {len} bytes, more than the {MAX_PLUGIN_BYTES} byte limit", path.display()));
    }
    let mut h = Sha256::new();
    use std::io::Read;
    std::io::copy(&mut f.take(MAX_PLUGIN_BYTES), &mut h).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(format!("{:x}", h.finalize()))
}

/// Find a file a scenario names: an absolute path as is; a relative one next to the scenario
/// file first (`base_dir`), then in the working directory. The error names the key and the
/// places tried. The result is absolute, so a run records where its input really was.
pub fn resolve_path(source_name: &str, key: &str, file: &str, base_dir: Option<&Path>) -> Result<PathBuf> {
    if file.trim().is_empty() {
        return Err(Error::input(source_name, key, "is empty: give a file's path"));
    }
    let p = Path::new(file);
    let candidates: Vec<PathBuf> = if p.is_absolute() {
        vec![p.to_path_buf()]
    } else {
        base_dir.map(|d| d.join(p)).into_iter().chain(std::iter::once(p.to_path_buf())).collect()
    };
    for c in &candidates {
        match std::fs::metadata(c) {
            Ok(m) if m.is_file() => return Ok(std::fs::canonicalize(c).unwrap_or_else(|_| c.clone())),
            Ok(m) => {
                let what = if m.is_dir() { "a directory" } else { "not a regular file (a device, FIFO or socket)" };
                return Err(Error::input(source_name, key, format!("{} is {what}: give a file", c.display())));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            // A link loop, a denied folder: say so, not "not found".
            Err(e) => {
                let m = crate::fsio::io_message(&e);
                return Err(Error::input(source_name, key, format!("{}: {m}", c.display())));
            }
        }
    }
    let tried: Vec<String> = candidates.iter().map(|c| c.display().to_string()).collect();
    Err(Error::input(source_name, key, format!("file not found (tried {})", tried.join(", "))))
}

/// An input file's text with where it came from and its hash.
#[derive(Debug, Clone)]
pub struct InputText {
    /// `builtin:...` or the absolute path.
    pub origin: String,
    /// The text.
    pub text: Arc<str>,
    /// SHA-256 of the text (hex).
    pub sha256: String,
}

/// A loaded leg: the validated model and its effective-mass table.
#[derive(Debug)]
pub struct LoadedLeg {
    /// The model.
    pub model: Arc<LegSpec>,
    /// Its effective-mass table.
    pub mass: Arc<MassTable>,
}

/// Key of a cached inverse-dynamics fit: everything it depends on (leg text and options, gait
/// text, harmonics, stride, hip motion, assistance), written out.
pub type CascadeKey = String;

/// Parsed inputs shared by all runs of a process or sweep. Every entry is built the first
/// time it is asked for and reused after; errors are not cached.
#[derive(Default)]
pub struct Resources {
    texts: Mutex<HashMap<String, InputText>>,
    legs: Mutex<HashMap<(String, String), Arc<LoadedLeg>>>,
    walking: Mutex<HashMap<String, Arc<crate::reference::WalkingData>>>,
    reduced: Mutex<HashMap<usize, Arc<crate::leg::ReducedModel>>>,
    gaits: Mutex<HashMap<(String, usize), Arc<GaitCycle>>>,
    cascades: Mutex<HashMap<CascadeKey, Arc<FourierSeries>>>,
    plugins: Mutex<HashMap<PathBuf, (Arc<PluginLibrary>, String)>>,
    muscles: Mutex<HashMap<String, Arc<crate::muscles::MuscleSet>>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl Resources {
    /// A fresh, empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// The URDF text `key` names (`builtin:...` or a path, looked up next to the scenario).
    pub fn urdf_text(&self, source_name: &str, key: &str, urdf: &str, base_dir: Option<&Path>) -> Result<InputText> {
        if let Some((name, text)) = BUILTIN_URDFS.iter().find(|(n, _)| *n == urdf) {
            return Ok(InputText {
                origin: name.to_string(),
                text: Arc::from(*text),
                sha256: sha256_hex(text.as_bytes()),
            });
        }
        let path = resolve_path(source_name, key, urdf, base_dir)?;
        self.file_text(&path)
    }

    /// The gait CSV text for `reference.gait_file`, or a built-in trial's.
    pub fn gait_text(&self, source_name: &str, file: &str, base_dir: Option<&Path>) -> Result<InputText> {
        let path = resolve_path(source_name, "reference.gait_file", file, base_dir)?;
        self.file_text(&path)
    }

    /// A built-in trial's text (None if there is no such trial).
    pub fn builtin_gait_text(name: &str) -> Option<(InputText, f64)> {
        BUILTIN_TRIALS.iter().find(|t| t.0 == name).map(|(n, text, stride)| {
            (InputText { origin: n.to_string(), text: Arc::from(*text), sha256: sha256_hex(text.as_bytes()) }, *stride)
        })
    }

    fn file_text(&self, path: &Path) -> Result<InputText> {
        let key = path.display().to_string();
        if let Some(t) = lock(&self.texts).get(&key) {
            return Ok(t.clone());
        }
        let text = read_capped(path, MAX_INPUT_FILE_BYTES)?;
        let t = InputText { origin: key.clone(), sha256: sha256_hex(text.as_bytes()), text: Arc::from(text) };
        lock(&self.texts).insert(key, t.clone());
        Ok(t)
    }

    /// The leg model of a URDF text (parsed and tabulated once per text and options).
    pub fn leg(
        &self,
        urdf: &InputText,
        options: &LegOptions,
    ) -> std::result::Result<Arc<LoadedLeg>, crate::leg::LegError> {
        let key = (urdf.sha256.clone(), format!("{options:?}"));
        let mut legs = lock(&self.legs);
        if let Some(l) = legs.get(&key) {
            return Ok(l.clone());
        }
        let model = LegSpec::from_urdf_with(&urdf.text, options)?;
        let mass = MassTable::new(&model)?;
        let l = Arc::new(LoadedLeg { model: Arc::new(model), mass: Arc::new(mass) });
        legs.insert(key, l.clone());
        Ok(l)
    }

    /// The reduced-coordinate model of a loaded leg (tabulated once per leg).
    pub fn reduced(
        &self,
        leg: &Arc<LegSpec>,
    ) -> std::result::Result<Arc<crate::leg::ReducedModel>, crate::leg::LegError> {
        let key = Arc::as_ptr(leg) as usize;
        let mut c = lock(&self.reduced);
        if let Some(r) = c.get(&key) {
            return Ok(r.clone());
        }
        let r = Arc::new(crate::leg::ReducedModel::new(leg)?);
        c.insert(key, r.clone());
        Ok(r)
    }

    /// Walking data for a key (gait, leg, subject), built once with `build`.
    pub fn walking(
        &self,
        key: String,
        build: impl FnOnce() -> Result<crate::reference::WalkingData>,
    ) -> Result<Arc<crate::reference::WalkingData>> {
        let mut c = lock(&self.walking);
        if let Some(w) = c.get(&key) {
            return Ok(w.clone());
        }
        let w = Arc::new(build()?);
        c.insert(key, w.clone());
        Ok(w)
    }

    /// The parsed gait cycle of a CSV text (once per text and harmonics).
    pub fn gait(&self, csv: &InputText, name: &str, harmonics: usize) -> Result<Arc<GaitCycle>> {
        let key = (csv.sha256.clone(), harmonics);
        let mut gaits = lock(&self.gaits);
        if let Some(g) = gaits.get(&key) {
            return Ok(g.clone());
        }
        let g = Arc::new(GaitCycle::parse(name, &csv.text, harmonics)?);
        gaits.insert(key, g.clone());
        Ok(g)
    }

    /// The controller plugin `controller.plugin.library` names, loaded once per path, with the
    /// library's SHA-256.
    pub fn plugin(
        &self,
        source_name: &str,
        library: &str,
        base_dir: Option<&Path>,
    ) -> Result<(Arc<PluginLibrary>, String)> {
        const KEY: &str = "controller.plugin.library";
        let path = resolve_path(source_name, KEY, library, base_dir)?;
        let mut c = lock(&self.plugins);
        if let Some(p) = c.get(&path) {
            return Ok(p.clone());
        }
        let sha = file_sha256(&path).map_err(|e| Error::input(source_name, KEY, e))?;
        let lib = PluginLibrary::load(&path).map_err(|e| Error::input(source_name, KEY, e))?;
        let entry = (Arc::new(lib), sha);
        c.insert(path, entry.clone());
        Ok(entry)
    }

    /// The muscle table `wearer.muscles_file` names (parsed once per content), with its text's
    /// origin and hash.
    pub fn muscle_set(
        &self,
        source_name: &str,
        file: &str,
        base_dir: Option<&Path>,
    ) -> Result<(Arc<crate::muscles::MuscleSet>, InputText)> {
        const KEY: &str = "wearer.muscles_file";
        let path = resolve_path(source_name, KEY, file, base_dir)?;
        let text = read_capped(&path, crate::muscles::MAX_FILE_BYTES)?;
        let t =
            InputText { origin: path.display().to_string(), sha256: sha256_hex(text.as_bytes()), text: Arc::from("") };
        let mut c = lock(&self.muscles);
        if let Some(m) = c.get(&t.sha256) {
            return Ok((m.clone(), t));
        }
        let m = Arc::new(crate::muscles::MuscleSet::parse(&text, &t.origin)?);
        c.insert(t.sha256.clone(), m.clone());
        Ok((m, t))
    }

    /// A gait inverse-dynamics fit, built once per key with `build`.
    pub fn cascade(
        &self,
        key: CascadeKey,
        build: impl FnOnce() -> Result<FourierSeries>,
    ) -> Result<Arc<FourierSeries>> {
        let mut c = lock(&self.cascades);
        if let Some(k) = c.get(&key) {
            return Ok(k.clone());
        }
        let k = Arc::new(build()?);
        c.insert(key, k.clone());
        Ok(k)
    }
}
