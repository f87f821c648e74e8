//! What a Python controller sees and returns: [`Obs`], the readings of one sample by name
//! (reused for every sample of a run), and [`read_command`], its return value read as a command
//! and logged channels. Both routes use it: the callback (`controller.rs`) and your loop
//! (`stepwise.rs`).

use exoleg::control::{ControlOutput, SampleInput, N_READINGS, READINGS};
use exoleg::sensors::{DEVICE_CHANNELS, DEVICE_READINGS};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt};

/// The readings of one sample, by name (SI units; see the README's "Your controller"). One
/// object is reused for every sample of a run: keep the numbers, not the object.
#[pyclass(module = "exoleg._native")]
#[derive(Clone)]
pub struct Obs {
    /// Sample instant (s).
    #[pyo3(get)]
    pub t_s: f64,
    /// Sample period (s).
    #[pyo3(get)]
    pub period_s: f64,
    /// Load cell (N).
    #[pyo3(get)]
    pub force_n: f64,
    /// Its firmware difference (N/s).
    #[pyo3(get)]
    pub force_rate_n_per_s: f64,
    /// Spool LVDT (m; NaN without the sensor).
    #[pyo3(get)]
    pub spool_m: f64,
    /// Piston position (m).
    #[pyo3(get)]
    pub piston_m: f64,
    /// Piston velocity (m/s).
    #[pyo3(get)]
    pub piston_velocity_m_s: f64,
    /// Piston acceleration (m/s^2).
    #[pyo3(get)]
    pub piston_accel_m_s2: f64,
    /// Knee flexion (rad).
    #[pyo3(get)]
    pub knee_rad: f64,
    /// Knee rate (rad/s).
    #[pyo3(get)]
    pub knee_rate_rad_s: f64,
    /// Desired force now (N).
    #[pyo3(get)]
    pub ref_force_n: f64,
    /// Its rate (N/s).
    #[pyo3(get)]
    pub ref_force_rate_n_per_s: f64,
    /// Its second derivative (N/s^2).
    #[pyo3(get)]
    pub ref_force_accel_n_per_s2: f64,
    /// Desired force one sample ahead (N).
    #[pyo3(get)]
    pub next_ref_force_n: f64,
    /// Its rate (N/s).
    #[pyo3(get)]
    pub next_ref_force_rate_n_per_s: f64,
    /// Its second derivative (N/s^2).
    #[pyo3(get)]
    pub next_ref_force_accel_n_per_s2: f64,
    /// The valve command limit (0 = none).
    #[pyo3(get)]
    pub valve_command_limit: f64,
    /// Raw A/D counts (force, spool, piston, knee, piston velocity; None = not quantised).
    #[pyo3(get)]
    pub counts: Counts,
    /// The device's readings (ABI 1.1: `hip_rad` ... `load_pressure_pa`), read by name through
    /// `__getattr__`.
    pub device: [f64; DEVICE_READINGS],
    /// The device's raw A/D counts (`exoleg.Obs.device_channels` order; None = not quantised).
    #[pyo3(get)]
    pub device_counts: Vec<Option<i64>>,
}

/// Raw A/D counts of the five channels (None = not quantised).
pub type Counts = (Option<i64>, Option<i64>, Option<i64>, Option<i64>, Option<i64>);

impl Obs {
    /// Fill from one sample (the fields in the order of `exoleg::control::READINGS`).
    pub fn set(&mut self, s: &SampleInput) {
        let c = s.counts.0;
        let v = s.reading_values();
        let [t_s, period_s, force_n, force_rate_n_per_s, spool_m, piston_m, piston_velocity_m_s, piston_accel_m_s2, knee_rad, knee_rate_rad_s, ref_force_n, ref_force_rate_n_per_s, ref_force_accel_n_per_s2, next_ref_force_n, next_ref_force_rate_n_per_s, next_ref_force_accel_n_per_s2, valve_command_limit] =
            std::array::from_fn(|i| v[i]);
        self.device.copy_from_slice(&v[17..]);
        self.device_counts.clear();
        self.device_counts.extend_from_slice(&s.device_counts.0);
        let (device, device_counts) = (self.device, std::mem::take(&mut self.device_counts));
        *self = Obs {
            t_s,
            period_s,
            force_n,
            force_rate_n_per_s,
            spool_m,
            piston_m,
            piston_velocity_m_s,
            piston_accel_m_s2,
            knee_rad,
            knee_rate_rad_s,
            ref_force_n,
            ref_force_rate_n_per_s,
            ref_force_accel_n_per_s2,
            next_ref_force_n,
            next_ref_force_rate_n_per_s,
            next_ref_force_accel_n_per_s2,
            valve_command_limit,
            counts: (c[0], c[1], c[2], c[3], c[4]),
            device,
            device_counts,
        };
    }

    fn values(&self) -> [f64; N_READINGS] {
        let mut v = [0.0; N_READINGS];
        v[17..].copy_from_slice(&self.device);
        v[..17].copy_from_slice(&[
            self.t_s,
            self.period_s,
            self.force_n,
            self.force_rate_n_per_s,
            self.spool_m,
            self.piston_m,
            self.piston_velocity_m_s,
            self.piston_accel_m_s2,
            self.knee_rad,
            self.knee_rate_rad_s,
            self.ref_force_n,
            self.ref_force_rate_n_per_s,
            self.ref_force_accel_n_per_s2,
            self.next_ref_force_n,
            self.next_ref_force_rate_n_per_s,
            self.next_ref_force_accel_n_per_s2,
            self.valve_command_limit,
        ]);
        v
    }
}

impl Default for Obs {
    fn default() -> Self {
        Self {
            t_s: 0.0,
            period_s: 0.0,
            force_n: 0.0,
            force_rate_n_per_s: 0.0,
            spool_m: 0.0,
            piston_m: 0.0,
            piston_velocity_m_s: 0.0,
            piston_accel_m_s2: 0.0,
            knee_rad: 0.0,
            knee_rate_rad_s: 0.0,
            ref_force_n: 0.0,
            ref_force_rate_n_per_s: 0.0,
            ref_force_accel_n_per_s2: 0.0,
            next_ref_force_n: 0.0,
            next_ref_force_rate_n_per_s: 0.0,
            next_ref_force_accel_n_per_s2: 0.0,
            valve_command_limit: 0.0,
            counts: Default::default(),
            device: [f64::NAN; DEVICE_READINGS],
            device_counts: Vec::with_capacity(DEVICE_CHANNELS.len()),
        }
    }
}

#[pymethods]
impl Obs {
    /// The reading names, in the order of [`Obs::array`].
    #[classattr]
    fn fields() -> Vec<&'static str> {
        READINGS.iter().map(|r| r.name).collect()
    }

    /// The readings as a numpy float64 vector, in the order of `Obs.fields`.
    fn array<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        numpy::PyArray1::from_slice_bound(py, &self.values())
    }

    /// The device's A/D channels, in the order of `Obs.device_counts`.
    #[classattr]
    fn device_channels() -> Vec<&'static str> {
        DEVICE_CHANNELS.iter().map(|c| c.reading).collect()
    }

    /// The device's readings by name (`obs.thigh_gyro_y_rad_s`, ...).
    fn __getattr__(&self, name: &str) -> PyResult<f64> {
        match READINGS[17..].iter().position(|r| r.name == name) {
            Some(i) => Ok(self.device[i]),
            None => Err(pyo3::exceptions::PyAttributeError::new_err(format!(
                "'Obs' has no reading `{name}` (Obs.fields lists them)"
            ))),
        }
    }

    /// A copy that later samples do not change.
    fn copy(&self) -> Obs {
        self.clone()
    }

    fn __repr__(&self) -> String {
        let parts: Vec<String> =
            READINGS.iter().map(|r| r.name).zip(self.values()).map(|(n, v)| format!("{n}={v}")).collect();
        format!("Obs({})", parts.join(", "))
    }
}

/// What a Python controller returned, as a command and its logged values.
pub struct Command {
    pub output: ControlOutput,
    pub log: Option<Vec<(String, f64)>>,
}

/// Read a controller's return value: a number, or a dict with `valve_command` and logged
/// numbers. Errors say what was wrong.
pub fn read_command(v: &Bound<'_, PyAny>) -> Result<Command, String> {
    if let Ok(f) = v.downcast::<PyFloat>() {
        return Ok(Command { output: ControlOutput::command(f.value()), log: None });
    }
    if v.is_instance_of::<PyInt>() {
        return number(v, "the valve command").map(|x| Command { output: ControlOutput::command(x), log: None });
    }
    if v.hasattr("__float__").unwrap_or(false) && !v.is_instance_of::<PyDict>() {
        if let Ok(x) = v.extract::<f64>() {
            return Ok(Command { output: ControlOutput::command(x), log: None });
        }
    }
    let Ok(d) = v.downcast::<PyDict>() else {
        return Err(format!(
            "it returned {} ({}); expected the valve command (a number) or a dict with `valve_command`",
            v.repr().map_or("?".into(), |r| r.to_string()),
            v.get_type().name().map_or("?".into(), |n| n.to_string())
        ));
    };
    let mut u = None;
    let mut log = Vec::new();
    for (k, x) in d.iter() {
        let key: String = k.extract().map_err(|_| "a key of the returned dict is not a string".to_string())?;
        let shown: String = key.chars().take(80).flat_map(char::escape_default).collect();
        let val = number(&x, &format!("`{shown}` in the returned dict"))?;
        if key == "valve_command" {
            u = Some(val);
        } else {
            log.push((key, val));
        }
    }
    let u = u.ok_or("the returned dict has no `valve_command`")?;
    Ok(Command { output: ControlOutput::command(u), log: Some(log) })
}

/// A returned number as a float; `what` names it. An integer too large for a float (10**400)
/// is said to be one, not "not a number".
fn number(x: &Bound<'_, PyAny>, what: &str) -> Result<f64, String> {
    x.extract::<f64>().map_err(|_| {
        if x.is_instance_of::<PyInt>() {
            let digits = x.str().map_or(0, |s| s.len().unwrap_or(0));
            format!("{what} is an integer of {digits} digits, too large for a float (at most about 1.8e308)")
        } else {
            format!("{what} is not a number")
        }
    })
}
