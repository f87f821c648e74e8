//! The FMI 2.0 co-simulation entry points of exoleg's FMU: a thin C shell over
//! [`exoleg::fmu::Slave`], which holds the state machine and the simulation.
//!
//! Every entry point catches panics (a panic never unwinds into the master): the instance is
//! then poisoned, the call returns `fmi2Fatal`, and every later call on it `fmi2Error` until it
//! is freed. Errors and warnings always go to the master's logger; `logEvents` messages only
//! when logging is on (`loggingOn` or `fmi2SetDebugLogging`).
//!
//! The master's logger is a C variadic function: messages are passed as the format with every
//! `%` doubled and no further arguments, so a message never reads a missing argument.

#![allow(clippy::missing_safety_doc)]

use exoleg::fmu::{uri_to_path, FmiError, Slave, VarType};
use std::ffi::{c_char, c_int, c_uint, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// `fmi2Status`.
pub type Fmi2Status = c_int;
const OK: Fmi2Status = 0;
const WARNING: Fmi2Status = 1;
const DISCARD: Fmi2Status = 2;
const ERROR: Fmi2Status = 3;
const FATAL: Fmi2Status = 4;

/// `fmi2Type`: only `fmi2CoSimulation` (1) is offered.
const CO_SIMULATION: c_int = 1;

/// `fmi2StatusKind` values.
const LAST_SUCCESSFUL_TIME: c_int = 2;
const TERMINATED: c_int = 3;

/// `fmi2CallbackLogger`.
pub type Logger =
    Option<unsafe extern "C" fn(*mut c_void, *const c_char, Fmi2Status, *const c_char, *const c_char, ...)>;

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct CallbackFunctions {
    /// The master's logger.
    pub logger: Logger,
    /// Unused: the FMU allocates with Rust's allocator.
    pub allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    /// Unused.
    pub free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    /// Unused: `canRunAsynchronuously` is false.
    pub step_finished: Option<unsafe extern "C" fn(*mut c_void, Fmi2Status)>,
    /// Passed back to the logger.
    pub component_environment: *mut c_void,
}

/// One instance behind the `fmi2Component` pointer.
struct Instance {
    slave: Slave,
    log: Log,
    poisoned: bool,
}

/// Where messages go.
struct Log {
    name: CString,
    logger: Logger,
    env: *mut c_void,
    on: bool,
}

impl Log {
    /// Send `msg` to the master (errors and warnings always, the rest when logging is on).
    fn send(&self, status: Fmi2Status, msg: &str) {
        if status == OK && !self.on {
            return;
        }
        let Some(logger) = self.logger else { return };
        let category: &CStr = match status {
            OK => c"logEvents",
            WARNING => c"logStatusWarning",
            DISCARD => c"logStatusDiscard",
            ERROR => c"logStatusError",
            _ => c"logStatusFatal",
        };
        let text = CString::new(msg.replace('%', "%%").replace('\0', " ")).unwrap_or_default();
        // SAFETY: the master gave this logger for this environment; the format has no
        // conversions left, so no argument is read.
        unsafe { logger(self.env, self.name.as_ptr(), status, category.as_ptr(), text.as_ptr()) };
    }
}

/// A C string argument, or None when null or not UTF-8.
unsafe fn text<'a>(p: *const c_char) -> Option<&'a str> {
    if p.is_null() {
        None
    } else {
        CStr::from_ptr(p).to_str().ok()
    }
}

/// Run `f` on the instance behind `c`, logging its error and catching a panic.
unsafe fn call(
    c: *mut c_void,
    what: &str,
    f: impl FnOnce(&mut Instance) -> Result<Fmi2Status, FmiError>,
) -> Fmi2Status {
    if c.is_null() {
        return ERROR;
    }
    let p = c as *mut Instance;
    if (*p).poisoned {
        (*p).log.send(ERROR, &format!("{what}: the instance failed earlier (an internal error); free it"));
        return ERROR;
    }
    match catch_unwind(AssertUnwindSafe(|| f(&mut *p))) {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => {
            (*p).log.send(ERROR, &format!("{what}: {}", e.message));
            ERROR
        }
        Err(panic) => {
            let why = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            (*p).poisoned = true;
            (*p).log.send(FATAL, &format!("{what}: internal error ({why}); please report it"));
            FATAL
        }
    }
}

/// A slice from a C array (empty when `n` is 0); None when null with `n` > 0.
unsafe fn slice<'a, T>(p: *const T, n: usize) -> Option<&'a [T]> {
    if n == 0 {
        Some(&[])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts(p, n))
    }
}

/// A mutable slice from a C array.
unsafe fn slice_mut<'a, T>(p: *mut T, n: usize) -> Option<&'a mut [T]> {
    if n == 0 {
        Some(&mut [])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts_mut(p, n))
    }
}

fn null_arg() -> FmiError {
    FmiError { message: "a null array with a nonzero count".into() }
}

/// Warnings as a status (each logged).
fn warned(log: &Log, warnings: &[String]) -> Fmi2Status {
    for w in warnings {
        log.send(WARNING, w);
    }
    if warnings.is_empty() {
        OK
    } else {
        WARNING
    }
}

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

/// What `exoleg fmu` looks for in a library before it packs it (by reading the file, never
/// loading it): this crate's marker with exoleg's version. Exported so the linker keeps it.
static LIBRARY_MARKER: &str = concat!("exoleg-fmu-library/", env!("CARGO_PKG_VERSION"), "/fmi2-cs\0");

/// The library's identity (`exoleg-fmu-library/<version>/fmi2-cs`), NUL-terminated.
#[no_mangle]
pub extern "C" fn exoleg_fmu_library_id() -> *const c_char {
    LIBRARY_MARKER.as_ptr().cast()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: c_int,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    logging_on: c_int,
) -> *mut c_void {
    let caught = catch_unwind(AssertUnwindSafe(|| {
        let (logger, env) = match functions.as_ref() {
            Some(f) => (f.logger, f.component_environment),
            None => (None, std::ptr::null_mut()),
        };
        let name = text(instance_name).unwrap_or("");
        let log = Log { name: CString::new(name).unwrap_or_default(), logger, env, on: logging_on != 0 };
        if instance_name.is_null() || name.is_empty() {
            log.send(ERROR, "fmi2Instantiate: instanceName must be a non-empty string");
            return std::ptr::null_mut();
        }
        match instantiate(fmu_type, guid, resource_location) {
            Ok((slave, warnings)) => {
                warned(&log, &warnings);
                Box::into_raw(Box::new(Instance { slave, log, poisoned: false })) as *mut c_void
            }
            Err(e) => {
                log.send(ERROR, &format!("fmi2Instantiate: {}", e.message));
                std::ptr::null_mut()
            }
        }
    }));
    caught.unwrap_or(std::ptr::null_mut())
}

unsafe fn instantiate(
    fmu_type: c_int,
    guid: *const c_char,
    resource_location: *const c_char,
) -> Result<(Slave, Vec<String>), FmiError> {
    if fmu_type != CO_SIMULATION {
        return Err(FmiError {
            message: "this FMU is for co-simulation only (fmuType must be fmi2CoSimulation)".into(),
        });
    }
    let guid = text(guid).ok_or_else(|| FmiError { message: "fmuGUID is missing".into() })?;
    let uri = text(resource_location).ok_or_else(|| FmiError {
        message: "fmuResourceLocation is missing (the FMU's resources/ hold its scenario)".into(),
    })?;
    let resources = uri_to_path(uri)?;
    Slave::instantiate(&resources, guid)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
    if !c.is_null() {
        let _ = catch_unwind(|| drop(Box::from_raw(c as *mut Instance)));
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: *mut c_void,
    logging_on: c_int,
    _n_categories: usize,
    _categories: *const *const c_char,
) -> Fmi2Status {
    call(c, "fmi2SetDebugLogging", |i| {
        i.log.on = logging_on != 0;
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: *mut c_void,
    _tolerance_defined: c_int,
    _tolerance: f64,
    start_time: f64,
    stop_time_defined: c_int,
    stop_time: f64,
) -> Fmi2Status {
    call(c, "fmi2SetupExperiment", |i| {
        i.slave.setup_experiment(start_time, (stop_time_defined != 0).then_some(stop_time))?;
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> Fmi2Status {
    call(c, "fmi2EnterInitializationMode", |i| {
        i.slave.enter_initialization_mode()?;
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> Fmi2Status {
    call(c, "fmi2ExitInitializationMode", |i| {
        let warnings = i.slave.exit_initialization_mode()?;
        Ok(warned(&i.log, &warnings))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> Fmi2Status {
    call(c, "fmi2Terminate", |i| {
        i.slave.terminate()?;
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> Fmi2Status {
    call(c, "fmi2Reset", |i| {
        i.slave.reset();
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(c: *mut c_void, vr: *const c_uint, nvr: usize, value: *mut f64) -> Fmi2Status {
    call(c, "fmi2GetReal", |i| {
        let (Some(vrs), Some(out)) = (slice(vr, nvr), slice_mut(value, nvr)) else { return Err(null_arg()) };
        i.slave.get(VarType::Real, vrs, out)?;
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: *mut c_void,
    vr: *const c_uint,
    nvr: usize,
    value: *mut c_int,
) -> Fmi2Status {
    call(c, "fmi2GetInteger", |i| {
        let (Some(vrs), Some(out)) = (slice(vr, nvr), slice_mut(value, nvr)) else { return Err(null_arg()) };
        let mut tmp = vec![0.0; nvr];
        i.slave.get(VarType::Integer, vrs, &mut tmp)?;
        for (o, x) in out.iter_mut().zip(tmp) {
            *o = x as c_int;
        }
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(c: *mut c_void, vr: *const c_uint, nvr: usize, value: *const f64) -> Fmi2Status {
    call(c, "fmi2SetReal", |i| {
        let (Some(vrs), Some(values)) = (slice(vr, nvr), slice(value, nvr)) else { return Err(null_arg()) };
        i.slave.set(VarType::Real, vrs, values)?;
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: *mut c_void,
    vr: *const c_uint,
    nvr: usize,
    value: *const c_int,
) -> Fmi2Status {
    call(c, "fmi2SetInteger", |i| {
        let (Some(vrs), Some(values)) = (slice(vr, nvr), slice(value, nvr)) else { return Err(null_arg()) };
        let values: Vec<f64> = values.iter().map(|&x| x as f64).collect();
        i.slave.set(VarType::Integer, vrs, &values)?;
        Ok(OK)
    })
}

/// Get/Set of a type this FMU has no variables of: fine for none, an error for any.
unsafe fn no_variables(c: *mut c_void, what: &str, vr: *const c_uint, nvr: usize) -> Fmi2Status {
    call(c, what, |_| match slice(vr, nvr) {
        Some([]) => Ok(OK),
        Some(v) => {
            Err(FmiError { message: format!("unknown value reference {} (this FMU has no such variables)", v[0]) })
        }
        None => Err(null_arg()),
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: *mut c_void,
    vr: *const c_uint,
    nvr: usize,
    _value: *mut c_int,
) -> Fmi2Status {
    no_variables(c, "fmi2GetBoolean", vr, nvr)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: *mut c_void,
    vr: *const c_uint,
    nvr: usize,
    _value: *const c_int,
) -> Fmi2Status {
    no_variables(c, "fmi2SetBoolean", vr, nvr)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: *mut c_void,
    vr: *const c_uint,
    nvr: usize,
    _value: *mut *const c_char,
) -> Fmi2Status {
    no_variables(c, "fmi2GetString", vr, nvr)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: *mut c_void,
    vr: *const c_uint,
    nvr: usize,
    _value: *const *const c_char,
) -> Fmi2Status {
    no_variables(c, "fmi2SetString", vr, nvr)
}

/// An entry point of a capability the FMU does not declare.
unsafe fn unsupported(c: *mut c_void, what: &str, why: &str) -> Fmi2Status {
    call(c, what, |_| Err(FmiError { message: format!("not supported: {why}") }))
}

const NO_STATE: &str = "canGetAndSetFMUstate is false (Rapier's world has no snapshot)";

#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, _state: *mut *mut c_void) -> Fmi2Status {
    unsupported(c, "fmi2GetFMUstate", NO_STATE)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, _state: *mut c_void) -> Fmi2Status {
    unsupported(c, "fmi2SetFMUstate", NO_STATE)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, state: *mut *mut c_void) -> Fmi2Status {
    if !state.is_null() && (*state).is_null() {
        return OK;
    }
    unsupported(c, "fmi2FreeFMUstate", NO_STATE)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: *mut c_void,
    _state: *mut c_void,
    _size: *mut usize,
) -> Fmi2Status {
    unsupported(c, "fmi2SerializedFMUstateSize", NO_STATE)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: *mut c_void,
    _state: *mut c_void,
    _bytes: *mut c_char,
    _size: usize,
) -> Fmi2Status {
    unsupported(c, "fmi2SerializeFMUstate", NO_STATE)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: *mut c_void,
    _bytes: *const c_char,
    _size: usize,
    _state: *mut *mut c_void,
) -> Fmi2Status {
    unsupported(c, "fmi2DeSerializeFMUstate", NO_STATE)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: *mut c_void,
    _unknown: *const c_uint,
    _n_unknown: usize,
    _known: *const c_uint,
    _n_known: usize,
    _dv_known: *const f64,
    _dv_unknown: *mut f64,
) -> Fmi2Status {
    unsupported(c, "fmi2GetDirectionalDerivative", "providesDirectionalDerivative is false")
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: *mut c_void,
    _vr: *const c_uint,
    _nvr: usize,
    _order: *const c_int,
    _value: *const f64,
) -> Fmi2Status {
    unsupported(c, "fmi2SetRealInputDerivatives", "canInterpolateInputs is false (the command is held)")
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: *mut c_void,
    _vr: *const c_uint,
    _nvr: usize,
    _order: *const c_int,
    _value: *mut f64,
) -> Fmi2Status {
    unsupported(c, "fmi2GetRealOutputDerivatives", "maxOutputDerivativeOrder is 0")
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(c: *mut c_void, t: f64, h: f64, _no_set_prior: c_int) -> Fmi2Status {
    call(c, "fmi2DoStep", |i| {
        i.slave.do_step(t, h)?;
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> Fmi2Status {
    unsupported(c, "fmi2CancelStep", "steps are synchronous (canRunAsynchronuously is false)")
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: *mut c_void, _kind: c_int, _value: *mut Fmi2Status) -> Fmi2Status {
    call(c, "fmi2GetStatus", |_| Ok(DISCARD))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: *mut c_void, kind: c_int, value: *mut f64) -> Fmi2Status {
    call(c, "fmi2GetRealStatus", |i| {
        if kind != LAST_SUCCESSFUL_TIME || value.is_null() {
            return Ok(DISCARD);
        }
        *value = i.slave.time_s();
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(c: *mut c_void, _kind: c_int, _value: *mut c_int) -> Fmi2Status {
    call(c, "fmi2GetIntegerStatus", |_| Ok(DISCARD))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(c: *mut c_void, kind: c_int, value: *mut c_int) -> Fmi2Status {
    call(c, "fmi2GetBooleanStatus", |i| {
        if kind != TERMINATED || value.is_null() {
            return Ok(DISCARD);
        }
        *value = c_int::from(i.slave.phase() == exoleg::fmu::Phase::Terminated);
        Ok(OK)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(c: *mut c_void, _kind: c_int, _value: *mut *const c_char) -> Fmi2Status {
    call(c, "fmi2GetStringStatus", |_| Ok(DISCARD))
}
