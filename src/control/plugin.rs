//! A controller in a C shared library (`controller.kind = "plugin"`): the firmware's own code
//! in the loop, called once per sample period on a struct of readings (the Bladed DISCON
//! idea, with typed, versioned structs instead of an index-addressed array).
//!
//! The ABI is `include/exoleg_controller.h` (a test compiles it and checks every size and
//! offset against the `#[repr(C)]` structs here):
//!
//! ```text
//! uint32_t exoleg_abi_version(void)          checked first: (major << 16) | minor; the major
//!                                            must be EXOLEG_ABI_MAJOR
//! void    *exoleg_create(const ExolegInfo *) one instance per run; NULL = refused parameters
//! int32_t  exoleg_reset(void *)              before the first sample of a run
//! int32_t  exoleg_step(void *, const ExolegReadings *, ExolegCommand *)
//! void     exoleg_destroy(void *)            when the run ends (or fails)
//! ```
//! Every struct starts with its size in bytes. Status codes: 0 ok, 1 warning (counted and
//! reported in `summary.json`, the run goes on), 2 stop this run (exit 3 with the plugin's
//! message). A plugin keeps no global state: a parallel sweep creates one instance per run,
//! and instances run on several threads at once (each instance on one thread at a time).
//! The library is loaded once per process and path; a plugin that crashes takes the process
//! with it (outputs are written to a temporary folder and renamed only after a run
//! completes, so they stay whole or absent).

use super::{ControlOutput, ControlStop, DiscreteController, NominalModel, SampleInput, ValveLimit};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ffi::{c_char, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod controller;
mod instance;
pub use controller::*;
pub use instance::*;

/// A plugin's message buffer as exoleg prints it: up to the first NUL (the last byte is one
/// whatever the plugin wrote), invalid UTF-8 replaced, trimmed, control characters escaped.
pub fn message_text(buf: &[c_char; MESSAGE_LEN]) -> String {
    let mut m = *buf;
    m[MESSAGE_LEN - 1] = 0;
    // SAFETY: NUL-terminated within the buffer (forced above).
    let text = escape_controls(unsafe { CStr::from_ptr(m.as_ptr()) }.to_string_lossy().trim());
    if text.is_empty() {
        "(no message)".into()
    } else {
        text
    }
}

/// The fuzz target `plugin_abi`: what the host makes of the bytes a plugin hands back (its
/// message buffer, and channel names for `controller.plugin.log`): the message is one line
/// without control characters; accepted names make a CSV header with one column each.
pub fn fuzz_plugin_abi(bytes: &[u8]) -> Result<(), String> {
    let mut buf = [0 as c_char; MESSAGE_LEN];
    for (b, x) in buf.iter_mut().zip(bytes) {
        *b = *x as c_char;
    }
    let m = message_text(&buf);
    if m.chars().any(char::is_control) {
        return Err(format!("a control character in {m:?}"));
    }
    let names: Vec<String> = String::from_utf8_lossy(bytes).split('\u{1f}').take(32).map(String::from).collect();
    crate::record::check_log_names(&names)?;
    let header: Vec<String> = names.iter().map(|n| format!("log_{n}")).collect();
    let line = header.join(",");
    if line.split(',').count() != names.len() || line.contains(['"', '\n', '\r', ' ']) {
        return Err(format!("accepted names make a bad header: {line:?}"));
    }
    Ok(())
}

/// The ABI's major version: a library reporting another major is refused.
pub const ABI_MAJOR: u32 = 1;
/// The ABI's minor version (additions at the end of the structs; sizes tell them apart): 1.1
/// added the device's sensors to [`ExolegReadings`].
pub const ABI_MINOR: u32 = 1;
/// Most logged channels a plugin may fill (`ExolegCommand.log`).
pub const PLUGIN_LOG_LEN: usize = 8;
/// Bytes of the plugin's message buffer (`ExolegCommand.message`), the terminating NUL included.
pub const MESSAGE_LEN: usize = 160;
/// Most parameters a plugin may be given.
pub const MAX_PARAMS: usize = 256;
/// Most bytes of one datagram of the out-of-process protocol (`super::wire`, which re-exports
/// the sizes here): every route checks that a plugin's SETUP fits it.
pub const MAX_DATAGRAM: usize = 32 * 1024;
/// Longest parameter name (bytes): `controller.plugin.params` refuses a longer one on every
/// route, so no name is ever cut on the wire.
pub const MAX_NAME_LEN: usize = 255;
/// Bytes of the wire's SETUP payload before its parameters.
pub const SETUP_FIXED_LEN: usize = 80;
/// Bytes of the wire's header.
pub const WIRE_HEADER_LEN: usize = 24;
/// Status: the sample is fine.
pub const STATUS_OK: i32 = 0;
/// Status: the sample is usable but the plugin warns (counted; the last message is kept).
pub const STATUS_WARNING: i32 = 1;
/// Status: stop this run.
pub const STATUS_STOP: i32 = 2;

/// `[controller.plugin]`: the shared library and its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PluginParams {
    /// Path of the shared library (`.so`), looked up next to the scenario file first, then in
    /// the working directory.
    pub library: Option<String>,
    /// Numbers passed to the plugin at creation, by name (`{ kp = 2.0, ki = 10.0 }`).
    pub params: BTreeMap<String, toml::Value>,
    /// Names of the channels the plugin logs in `ExolegCommand.log` (columns `log_<name>`), at
    /// most 8.
    pub log: Vec<String>,
    /// SHA-256 of the library; filled in by every run (a later run warns if it changed).
    pub library_sha256: Option<String>,
    /// Run the plugin in a child process ([`super::isolate`]): a crash, an `exit()` or a hang
    /// ends only this run (exit 3 naming the signal or the timeout). Default false.
    pub isolate: bool,
    /// Isolated plugins: the longest wall-clock time one call may take (s) before the child
    /// is killed and the run ends (exit 3). Default 1. In (0, 3600].
    pub timeout_s: f64,
    /// Isolated plugins: the child's address-space limit (MiB; `RLIMIT_AS`), so a plugin that
    /// leaks costs only its own run (its allocation fails, or it is killed). None (default):
    /// no limit. 16..=1048576, on top of what the child holds when it starts (its own executable).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub memory_mb: Option<u64>,
}

impl Default for PluginParams {
    fn default() -> Self {
        Self {
            library: None,
            params: BTreeMap::new(),
            log: Vec::new(),
            library_sha256: None,
            isolate: false,
            timeout_s: DEFAULT_TIMEOUT_S,
            memory_mb: None,
        }
    }
}

/// Default of `controller.plugin.timeout_s` (s).
pub const DEFAULT_TIMEOUT_S: f64 = 1.0;
/// Largest `controller.plugin.timeout_s` (s): an hour for one call.
pub const MAX_TIMEOUT_S: f64 = 3600.0;
/// `controller.plugin.memory_mb`'s range (MiB).
pub const MEMORY_MB_RANGE: (u64, u64) = (16, 1 << 20);

impl PluginParams {
    /// True when nothing is set (the section is left out of `summary.json`).
    pub fn is_unset(&self) -> bool {
        *self == Self::default()
    }

    /// Everything `[controller.plugin]` holds that any route (in-process, isolated, `exoleg
    /// hil`) gives the controller, checked once before anything starts, the same for every
    /// route: the parameters (numbers, names that the wire carries whole, a SETUP that fits
    /// one datagram), the logged channels' names, the timeout and the memory limit. Errors
    /// name the key.
    pub fn check(&self) -> Result<(), (String, String)> {
        let params = self.numbers()?;
        let setup: usize = params.iter().map(|(n, _)| 2 + n.as_bytes().len() + 8).sum();
        let bytes = WIRE_HEADER_LEN + SETUP_FIXED_LEN + setup;
        if bytes > MAX_DATAGRAM {
            return Err((
                "controller.plugin.params".into(),
                format!(
                    "{} parameters whose names and values take {bytes} bytes on the wire, more than one datagram \
                     carries ({}): shorten the names or give fewer",
                    params.len(),
                    MAX_DATAGRAM
                ),
            ));
        }
        if self.log.len() > PLUGIN_LOG_LEN {
            return Err((
                "controller.plugin.log".into(),
                format!("at most {PLUGIN_LOG_LEN} names, got {}", self.log.len()),
            ));
        }
        crate::record::check_log_names(&self.log).map_err(|m| ("controller.plugin.log".to_string(), m))?;
        let t = self.timeout_s;
        if !(t > 0.0 && t <= MAX_TIMEOUT_S) {
            return Err((
                "controller.plugin.timeout_s".into(),
                format!("must be in (0, {MAX_TIMEOUT_S}] s, got {}", crate::error::num(t)),
            ));
        }
        let (lo, hi) = MEMORY_MB_RANGE;
        if let Some(m) = self.memory_mb.filter(|m| !(lo..=hi).contains(m)) {
            return Err(("controller.plugin.memory_mb".into(), format!("must be {lo}..={hi} MiB, got {m}")));
        }
        if self.memory_mb.is_some() && !self.isolate {
            return Err((
                "controller.plugin.memory_mb".into(),
                "limits an isolated plugin's child process: set controller.plugin.isolate = true".into(),
            ));
        }
        Ok(())
    }

    /// The parameters as (name, number) pairs; errors name the key.
    pub fn numbers(&self) -> Result<Vec<(CString, f64)>, (String, String)> {
        if self.params.len() > MAX_PARAMS {
            return Err(("controller.plugin.params".into(), format!("at most {MAX_PARAMS} parameters")));
        }
        self.params
            .iter()
            .map(|(k, v)| {
                let key = format!("controller.plugin.params.{k}");
                let x = match v {
                    toml::Value::Float(x) => *x,
                    toml::Value::Integer(i) => *i as f64,
                    other => return Err((key, format!("must be a number, got {}", other.type_str()))),
                };
                if !x.is_finite() {
                    return Err((key, format!("must be a finite number, got {x}")));
                }
                if k.is_empty() || k.len() > MAX_NAME_LEN {
                    let n = k.len();
                    return Err((key, format!("a name of 1..={MAX_NAME_LEN} bytes, got {n}")));
                }
                let name = CString::new(k.as_str()).map_err(|_| (key, "the name contains a NUL byte".to_string()))?;
                Ok((name, x))
            })
            .collect()
    }
}

/// One parameter as the plugin sees it.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct ExolegParam {
    /// NUL-terminated name (valid during `exoleg_create` only).
    pub name: *const c_char,
    /// Its value.
    pub value: f64,
}

/// What a plugin is told at creation.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct ExolegInfo {
    /// `sizeof(ExolegInfo)`.
    pub size: u32,
    /// The host's ABI version, `(major << 16) | minor`.
    pub abi_version: u32,
    /// Sample period (s).
    pub sample_period_s: f64,
    /// Valve command limit (0 = none); the actuator clips any command to it.
    pub valve_command_limit: f64,
    /// The nominal force-ODE coefficients (`controller.nominal` over `[hydraulics]`): n1
    /// (N/m), n2 (N/m), n3 (1/s), the spool time constant tau (s) and valve gain k_s (m).
    pub nominal_n1: f64,
    /// n2 (N/m).
    pub nominal_n2: f64,
    /// n3 (1/s).
    pub nominal_n3: f64,
    /// tau (s).
    pub nominal_tau_s: f64,
    /// k_s (m per unit command).
    pub nominal_k_s: f64,
    /// The run's seed.
    pub seed: u64,
    /// Number of parameters.
    pub n_params: u32,
    /// Reserved (0).
    pub reserved: u32,
    /// The parameters (valid during `exoleg_create` only).
    pub params: *const ExolegParam,
}

/// The readings of one sample (see the README's table).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct ExolegReadings {
    /// `sizeof(ExolegReadings)`.
    pub size: u32,
    /// Bit i set: `counts[i]` holds channel i's raw A/D counts (0 force, 1 spool, 2 piston,
    /// 3 knee, 4 piston velocity).
    pub counts_valid: u32,
    /// Sample instant (s).
    pub t_s: f64,
    /// Sample period (s).
    pub period_s: f64,
    /// Load cell (N).
    pub force_n: f64,
    /// Its firmware difference (N/s).
    pub force_rate_n_per_s: f64,
    /// Spool (m; NaN without the sensor).
    pub spool_m: f64,
    /// Piston position (m).
    pub piston_m: f64,
    /// Piston velocity (m/s).
    pub piston_velocity_m_s: f64,
    /// Piston acceleration (m/s^2).
    pub piston_accel_m_s2: f64,
    /// Knee flexion (rad).
    pub knee_rad: f64,
    /// Knee rate (rad/s).
    pub knee_rate_rad_s: f64,
    /// Desired force now (N).
    pub ref_force_n: f64,
    /// Its rate (N/s).
    pub ref_force_rate_n_per_s: f64,
    /// Its second derivative (N/s^2).
    pub ref_force_accel_n_per_s2: f64,
    /// Desired force one sample ahead (N).
    pub next_ref_force_n: f64,
    /// Its rate (N/s).
    pub next_ref_force_rate_n_per_s: f64,
    /// Its second derivative (N/s^2).
    pub next_ref_force_accel_n_per_s2: f64,
    /// Valve command limit (0 = none).
    pub valve_command_limit: f64,
    /// Raw A/D counts, by channel (valid where `counts_valid` says).
    pub counts: [i64; 5],
    /// ABI 1.1: hip encoder (rad).
    pub hip_rad: f64,
    /// Its filtered difference (rad/s).
    pub hip_rate_rad_s: f64,
    /// Thigh accelerometer x, y, z (m/s^2, sensor frame).
    pub thigh_accel_m_s2: [f64; 3],
    /// Thigh gyroscope (rad/s).
    pub thigh_gyro_rad_s: [f64; 3],
    /// Shank accelerometer (m/s^2).
    pub shank_accel_m_s2: [f64; 3],
    /// Shank gyroscope (rad/s).
    pub shank_gyro_rad_s: [f64; 3],
    /// Heel force (N).
    pub heel_force_n: f64,
    /// Forefoot force (N).
    pub forefoot_force_n: f64,
    /// Foot switch (0 or 1).
    pub foot_contact: f64,
    /// Thigh cuff force (N).
    pub thigh_cuff_force_n: f64,
    /// Shank cuff force (N).
    pub shank_cuff_force_n: f64,
    /// Chamber A pressure (Pa).
    pub pressure_a_pa: f64,
    /// Chamber B pressure (Pa).
    pub pressure_b_pa: f64,
    /// Supply pressure (Pa).
    pub supply_pressure_pa: f64,
    /// Load pressure (Pa).
    pub load_pressure_pa: f64,
    /// Bit i: `device_counts[i]` holds the device channel i's raw A/D counts.
    pub device_counts_valid: u32,
    /// Reserved (0).
    pub reserved1: u32,
    /// The device's raw A/D counts (`crate::sensors::DEVICE_CHANNELS` order).
    pub device_counts: [i64; 21],
}

/// What a plugin returns for one sample.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct ExolegCommand {
    /// `sizeof(ExolegCommand)`.
    pub size: u32,
    /// Reserved (0).
    pub reserved: u32,
    /// The valve command u (dimensionless; k_s*u is the commanded spool position in m).
    pub valve_command: f64,
    /// The plugin's disturbance estimate (N/s^2), logged; 0 if it has none.
    pub disturbance_estimate_n_per_s2: f64,
    /// Logged channels (`controller.plugin.log` names them).
    pub log: [f64; PLUGIN_LOG_LEN],
    /// A NUL-terminated message for a warning or stop status.
    pub message: [c_char; MESSAGE_LEN],
}

impl Default for ExolegCommand {
    fn default() -> Self {
        Self {
            size: std::mem::size_of::<Self>() as u32,
            reserved: 0,
            valve_command: 0.0,
            disturbance_estimate_n_per_s2: 0.0,
            log: [0.0; PLUGIN_LOG_LEN],
            message: [0; MESSAGE_LEN],
        }
    }
}

type AbiFn = unsafe extern "C" fn() -> u32;
type CreateFn = unsafe extern "C" fn(*const ExolegInfo) -> *mut c_void;
type ResetFn = unsafe extern "C" fn(*mut c_void) -> i32;
type StepFn = unsafe extern "C" fn(*mut c_void, *const ExolegReadings, *mut ExolegCommand) -> i32;
type DestroyFn = unsafe extern "C" fn(*mut c_void);

/// A loaded plugin library (once per process and path; shared by the runs that use it).
pub struct PluginLibrary {
    /// Where it was loaded from.
    pub path: PathBuf,
    /// Its ABI version as it reported it.
    pub abi_version: u32,
    create: CreateFn,
    reset: ResetFn,
    step: StepFn,
    destroy: DestroyFn,
    // Last: the functions above point into it.
    _lib: libloading::Library,
}

impl std::fmt::Debug for PluginLibrary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PluginLibrary").field("path", &self.path).field("abi_version", &self.abi_version).finish()
    }
}

impl PluginLibrary {
    /// Load a library: a regular file, `exoleg_abi_version` checked before anything else, then
    /// the four entry points. Errors say what is wrong (the caller names the key).
    pub fn load(path: &Path) -> Result<Self, String> {
        let meta = std::fs::metadata(path).map_err(|e| format!("{}: {e}", path.display()))?;
        if !meta.is_file() {
            return Err(format!("{}: not a regular file", path.display()));
        }
        let lib = open_now(path)?;
        let abi_version = {
            // SAFETY: the symbol's type is the ABI's `uint32_t exoleg_abi_version(void)`.
            let f = unsafe { lib.get::<AbiFn>(b"exoleg_abi_version\0") }
                .map_err(|_| format!("{}: no symbol `exoleg_abi_version` (not an exoleg plugin)", path.display()))?;
            let _guard = exit_guard::arm();
            // SAFETY: a C function without arguments.
            unsafe { f() }
        };
        if abi_version >> 16 != ABI_MAJOR {
            return Err(format!(
                "{}: ABI version {}.{}, this exoleg speaks {ABI_MAJOR}.{ABI_MINOR} (the major versions must match; rebuild it against include/exoleg_controller.h)",
                path.display(),
                abi_version >> 16,
                abi_version & 0xffff
            ));
        }
        // SAFETY (each `get`): the symbol names and types are the ABI's (the header).
        let create = *unsafe { lib.get::<CreateFn>(b"exoleg_create\0") }.map_err(|_| missing(path, "exoleg_create"))?;
        let reset = *unsafe { lib.get::<ResetFn>(b"exoleg_reset\0") }.map_err(|_| missing(path, "exoleg_reset"))?;
        let step = *unsafe { lib.get::<StepFn>(b"exoleg_step\0") }.map_err(|_| missing(path, "exoleg_step"))?;
        let destroy =
            *unsafe { lib.get::<DestroyFn>(b"exoleg_destroy\0") }.map_err(|_| missing(path, "exoleg_destroy"))?;
        Ok(Self { path: path.to_path_buf(), abi_version, create, reset, step, destroy, _lib: lib })
    }

    /// `exoleg_create` (an isolated plugin's host process calls the library directly).
    pub(crate) fn create_raw(&self, info: &ExolegInfo) -> *mut c_void {
        let _guard = exit_guard::arm();
        // SAFETY: `info` and what it points to live through the call.
        unsafe { (self.create)(info) }
    }

    /// `exoleg_reset` of an instance this library created.
    pub(crate) fn reset_raw(&self, handle: *mut c_void) -> i32 {
        let _guard = exit_guard::arm();
        // SAFETY: a live instance of this library (the caller's contract).
        unsafe { (self.reset)(handle) }
    }

    /// `exoleg_step` of an instance this library created.
    pub(crate) fn step_raw(&self, handle: *mut c_void, r: &ExolegReadings, c: &mut ExolegCommand) -> i32 {
        let _guard = exit_guard::arm();
        // SAFETY: a live instance; both structs are sized and valid through the call.
        unsafe { (self.step)(handle, r, c) }
    }

    /// `exoleg_destroy` of an instance this library created (once).
    pub(crate) fn destroy_raw(&self, handle: *mut c_void) {
        let _guard = exit_guard::arm();
        // SAFETY: a live instance, destroyed once (the caller's contract).
        unsafe { (self.destroy)(handle) }
    }

    /// The library's file name, for messages.
    pub fn name(&self) -> String {
        self.path.file_name().map_or_else(|| self.path.display().to_string(), |n| n.to_string_lossy().into_owned())
    }
}

/// Open a library with every symbol it needs resolved now (`RTLD_NOW`): a symbol nothing
/// provides is an error here, naming it, not a crash at its first call in the middle of a run.
fn open_now(path: &Path) -> Result<libloading::Library, String> {
    use libloading::os::unix::{Library, RTLD_LOCAL, RTLD_NOW};
    let _guard = exit_guard::arm();
    // SAFETY: loading a library runs its initialisers; the user names the library to run
    // as their controller, which is the point of a plugin (documented).
    let lib = unsafe { Library::open(Some(path), RTLD_NOW | RTLD_LOCAL) }.map_err(|e| {
        let text = escape_controls(&e.to_string());
        match text.split_once("undefined symbol: ") {
            Some((_, sym)) => format!(
                "{}: the library needs the symbol `{}`, which neither it nor what it links provides (every \
                 symbol is resolved when the plugin loads: link the library that defines it)",
                path.display(),
                sym.split([' ', ',', ')']).next().unwrap_or(sym)
            ),
            None => format!("{}: cannot load the library: {text}", path.display()),
        }
    })?;
    Ok(lib.into())
}

/// `s` with every control character escaped (a plugin's or a loader's message on one line,
/// with nothing that moves a terminal's cursor).
pub fn escape_controls(s: &str) -> String {
    s.chars().flat_map(|c| if c.is_control() { c.escape_default().collect::<Vec<_>>() } else { vec![c] }).collect()
}

/// The process's exit status while a plugin runs: a plugin that calls `exit()` (whatever the
/// code) cannot make an unfinished run look finished. While armed (the CLI's whole command;
/// every call into a plugin), an `atexit` handler turns any exit that exoleg did not make
/// into exit 3 with a message; exoleg's own exits go through [`exit_guard::exit`].
pub mod exit_guard {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    static ARMED: AtomicUsize = AtomicUsize::new(0);
    static EXITING: AtomicBool = AtomicBool::new(false);
    static INSTALL: std::sync::Once = std::sync::Once::new();

    extern "C" {
        fn atexit(f: extern "C" fn()) -> std::ffi::c_int;
        fn _exit(code: std::ffi::c_int) -> !;
        fn write(fd: std::ffi::c_int, buf: *const std::ffi::c_void, n: usize) -> isize;
    }

    extern "C" fn on_exit() {
        if ARMED.load(Ordering::SeqCst) > 0 && !EXITING.load(Ordering::SeqCst) {
            let msg: &[u8] = b"error: something in the run (a controller plugin?) called exit() before exoleg \
                finished: the run did not complete and its outputs are not written (exit 3)\n";
            // SAFETY: write(2) and _exit(2) are async-signal-safe and take valid arguments.
            unsafe {
                write(2, msg.as_ptr().cast(), msg.len());
                _exit(crate::error::EXIT_SIM_FAILED)
            }
        }
    }

    /// Armed until dropped.
    #[must_use]
    pub struct Armed(());

    impl Drop for Armed {
        fn drop(&mut self) {
            ARMED.fetch_sub(1, Ordering::SeqCst);
        }
    }

    /// Arm the guard (installing its handler the first time).
    pub fn arm() -> Armed {
        INSTALL.call_once(|| {
            // SAFETY: registers a plain function; atexit fails only without memory (then the
            // guard is simply not there).
            unsafe { atexit(on_exit) };
        });
        ARMED.fetch_add(1, Ordering::SeqCst);
        Armed(())
    }

    /// Stand aside for good: a plugin's `exit()` is this process's exit status (an isolated
    /// plugin's host process, whose status the run reads).
    pub fn stand_aside() {
        EXITING.store(true, Ordering::SeqCst);
    }

    /// Exit the process with `code` as exoleg means it (the guard stands aside).
    pub fn exit(code: i32) -> ! {
        EXITING.store(true, Ordering::SeqCst);
        std::process::exit(code)
    }
}

fn missing(path: &Path, symbol: &str) -> String {
    format!("{}: no symbol `{symbol}`", path.display())
}
