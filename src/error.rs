//! Error types and the process exit codes they map to.

use std::path::PathBuf;

/// Exit code for a successful run.
pub const EXIT_OK: i32 = 0;
/// Exit code for an I/O or other runtime failure that is not the user's input.
pub const EXIT_FAILURE: i32 = 1;
/// Exit code for bad input: scenario file, URDF, gait CSV, or command-line arguments.
pub const EXIT_BAD_INPUT: i32 = 2;
/// Exit code for a simulation that went non-finite (diverged).
pub const EXIT_SIM_FAILED: i32 = 3;
/// Exit code for a run that completed but failed the scenario's pass/fail criteria.
pub const EXIT_CRITERIA_FAILED: i32 = 4;

/// Everything that can go wrong in exoleg.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Bad user input; `source_name` is the file (or `--set`) it came from, `key` the dotted key.
    #[error("{}", join_nonempty(&[.source_name, .key, .message]))]
    Input {
        /// File path or `--set` or `<embedded default>`.
        source_name: String,
        /// Dotted key or element name the problem is in (may be empty).
        key: String,
        /// What is wrong.
        message: String,
    },
    /// A file could not be read.
    #[error("{}: cannot read: {}", clip(&path.display().to_string()), clip(message))]
    Read {
        /// The path that failed.
        path: PathBuf,
        /// OS message.
        message: String,
    },
    /// The simulation produced a non-finite value.
    #[error("simulation diverged at t = {time_s:.6} s: state `{state}` became {value:.6e}")]
    Diverged {
        /// Simulated time at which it was detected (s).
        time_s: f64,
        /// Name of the state that went non-finite.
        state: String,
        /// The offending value.
        value: f64,
    },
    /// A state is too stiff for the step even with the automatic substeps: the run would be
    /// wrong, so it stops.
    #[error(
        "simulation stopped at t = {time_s:.6} s: `{state}` is too stiff for sim.dt_s = {step_s:e} s \
         (local rate {rate_per_s:.3e} 1/s): it needs steps of at most {needed_step_s:.3e} s"
    )]
    Stiff {
        /// Simulated time (s).
        time_s: f64,
        /// The stiff state.
        state: String,
        /// The fixed step (s).
        step_s: f64,
        /// The local rate (eigenvalue magnitude or frequency) found (1/s).
        rate_per_s: f64,
        /// The step the integrator would need (s).
        needed_step_s: f64,
    },
    /// The controller stopped the run (a plugin's stop status, a non-finite command, a
    /// callback that failed).
    #[error("controller `{controller}` stopped the run at t = {time_s:.6} s: {}", clip(message))]
    ControllerStopped {
        /// Simulated time (s).
        time_s: f64,
        /// The controller's kind.
        controller: String,
        /// What happened.
        message: String,
    },
    /// The caller asked the run to stop (Ctrl-C in the Python package).
    #[error("interrupted")]
    Interrupted,
    /// The library was used out of order (e.g. a step without the command for its sample).
    #[error("{}", clip(.0))]
    Usage(String),
    /// Output could not be written.
    #[error("{}: cannot write: {}", clip(&path.display().to_string()), clip(message))]
    Write {
        /// The path that failed.
        path: PathBuf,
        /// OS or encoder message.
        message: String,
    },
    /// The run completed but failed its criteria.
    #[error("criteria failed: {0}")]
    Criteria(String),
}

impl Error {
    /// Shorthand for [`Error::Input`].
    pub fn input(source_name: impl Into<String>, key: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Input { source_name: source_name.into(), key: key.into(), message: message.into() }
    }

    /// The same error, marked as belonging to run `i` of a sweep (bad input names the run).
    pub fn in_run(self, i: usize) -> Self {
        match self {
            Error::Input { source_name, key, message } => {
                Error::Input { source_name: format!("{source_name} [run {i}]"), key, message }
            }
            other => other,
        }
    }

    /// The process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. } | Error::Read { .. } => EXIT_BAD_INPUT,
            Error::Diverged { .. } | Error::Stiff { .. } | Error::ControllerStopped { .. } => EXIT_SIM_FAILED,
            Error::Write { .. } | Error::Usage(_) | Error::Interrupted => EXIT_FAILURE,
            Error::Criteria(_) => EXIT_CRITERIA_FAILED,
        }
    }
}

/// Result alias used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// `a: b: c`, leaving out empty parts, each [`clip`]ped.
fn join_nonempty(parts: &[&String]) -> String {
    parts.iter().filter(|p| !p.trim().is_empty()).map(|p| clip(p)).collect::<Vec<_>>().join(": ")
}

/// Longest part of a message echoed whole (characters); a value a user gave may be any size.
pub const MAX_ECHO_CHARS: usize = 2000;

/// A message part as printed: control characters escaped (one line, nothing that moves a
/// terminal's cursor), and cut after [`MAX_ECHO_CHARS`] characters with the size said.
pub fn clip(s: &str) -> String {
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i >= MAX_ECHO_CHARS {
            out.push_str(&format!("... ({} bytes in all)", s.len()));
            break;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// A number as a message shows it: plain in the everyday range, else in exponent form (no
/// 309-digit 1e308).
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e15).contains(&a) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}
