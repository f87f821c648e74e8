//! A plugin's instances: what the host tells them, the setup shared by a run's instances (in
//! process or isolated), creating one, and its status codes as the run takes them.

use super::*;

/// What the host tells every instance.
#[derive(Debug, Clone, Copy)]
pub struct HostInfo {
    /// Sample period (s).
    pub period_s: f64,
    /// Valve limit.
    pub limit: ValveLimit,
    /// The controller's nominal model.
    pub nominal: NominalModel,
    /// The run's seed.
    pub seed: u64,
}

/// A plugin ready to be instantiated for each run: the library, its parameters, its logs, and
/// whether each instance runs in a child process.
#[derive(Debug)]
pub struct PluginSetup {
    pub(super) lib: Arc<PluginLibrary>,
    pub(super) params: Vec<(CString, f64)>,
    pub(super) log: Vec<String>,
    pub(super) info: HostInfo,
    /// `controller.plugin.isolate`: how an isolated instance runs; None in-process.
    pub(super) isolate: Option<Isolation>,
}

/// An isolated plugin's limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Isolation {
    /// The longest call (s): `controller.plugin.timeout_s`.
    pub timeout_s: f64,
    /// The child's address-space limit (MiB): `controller.plugin.memory_mb`.
    pub memory_mb: Option<u64>,
}

impl PluginSetup {
    /// Check the parameters and log names of `p` for `lib`; errors name the key.
    pub fn new(lib: Arc<PluginLibrary>, p: &PluginParams, info: HostInfo) -> Result<Self, (String, String)> {
        p.check()?;
        let params = p.numbers()?;
        let isolate = p.isolate.then_some(Isolation { timeout_s: p.timeout_s, memory_mb: p.memory_mb });
        Ok(Self { lib, params, log: p.log.clone(), info, isolate })
    }

    /// The library.
    pub fn library(&self) -> &Arc<PluginLibrary> {
        &self.lib
    }

    /// The names of the channels the plugin logs.
    pub fn log_names(&self) -> &[String] {
        &self.log
    }

    /// What a peer outside the process needs to create the same instance (the wire's SETUP).
    pub fn wire_setup(&self) -> InstanceSetup {
        let c = &self.info.nominal.c;
        InstanceSetup {
            sample_period_s: self.info.period_s,
            valve_command_limit: self.info.limit.0,
            nominal: [c.n1, c.n2, c.n3, c.tau_s, c.k_s],
            seed: self.info.seed,
            params: self.params.iter().map(|(n, v)| (n.to_string_lossy().into_owned(), *v)).collect(),
        }
    }

    /// `controller.plugin.isolate`: an isolated instance's limits, None when the plugin runs
    /// in-process.
    pub fn isolation(&self) -> Option<Isolation> {
        self.isolate
    }

    /// A new in-process instance (`exoleg_create`); an error if the plugin refuses its
    /// parameters.
    pub fn instance(self: &Arc<Self>) -> Result<PluginController, String> {
        let handle = create_instance(&self.lib, &self.wire_setup())?;
        Ok(PluginController {
            setup: self.clone(),
            handle,
            readings: ExolegReadings::default(),
            command: ExolegCommand::default(),
            reset: false,
            status: StatusCount::new(self.lib.name()),
            compute_s: Vec::new(),
        })
    }
}

/// What creating an instance takes besides the library: the host's figures and the
/// parameters (an outside peer gets it in the wire's SETUP).
#[derive(Debug, Clone, PartialEq)]
pub struct InstanceSetup {
    /// Sample period (s).
    pub sample_period_s: f64,
    /// Valve command limit (0 = none).
    pub valve_command_limit: f64,
    /// The nominal model: n1 (N/m), n2 (N/m), n3 (1/s), tau (s), k_s (m).
    pub nominal: [f64; 5],
    /// The run's seed.
    pub seed: u64,
    /// The parameters, by name.
    pub params: Vec<(String, f64)>,
}

/// `exoleg_create` with the figures and parameters of `setup` (in-process, and in an isolated
/// plugin's host process: the same call either way). An error if it returns NULL.
pub(crate) fn create_instance(lib: &PluginLibrary, setup: &InstanceSetup) -> Result<*mut c_void, String> {
    let names: Vec<CString> =
        setup.params.iter().map(|(n, _)| CString::new(n.replace('\0', "")).unwrap_or_default()).collect();
    let params: Vec<ExolegParam> =
        names.iter().zip(&setup.params).map(|(n, (_, v))| ExolegParam { name: n.as_ptr(), value: *v }).collect();
    let [n1, n2, n3, tau_s, k_s] = setup.nominal;
    let info = ExolegInfo {
        size: std::mem::size_of::<ExolegInfo>() as u32,
        abi_version: (ABI_MAJOR << 16) | ABI_MINOR,
        sample_period_s: setup.sample_period_s,
        valve_command_limit: setup.valve_command_limit,
        nominal_n1: n1,
        nominal_n2: n2,
        nominal_n3: n3,
        nominal_tau_s: tau_s,
        nominal_k_s: k_s,
        seed: setup.seed,
        n_params: params.len() as u32,
        reserved: 0,
        params: params.as_ptr(),
    };
    let handle = lib.create_raw(&info);
    if handle.is_null() {
        return Err(format!("{}: exoleg_create returned NULL (it refused its parameters)", lib.name()));
    }
    Ok(handle)
}

/// A plugin's status codes as the run takes them: warnings counted (the last message kept),
/// a stop or an unknown code an error naming the call.
#[derive(Debug, Clone)]
pub(crate) struct StatusCount {
    /// The plugin's name for messages.
    pub name: String,
    pub warnings: usize,
    pub last_warning: Option<String>,
}

impl StatusCount {
    pub fn new(name: String) -> Self {
        Self { name, warnings: 0, last_warning: None }
    }

    /// Take `status` from `call`, with the plugin's `message` (read only when needed).
    pub fn take(&mut self, call: &str, status: i32, message: impl FnOnce() -> String) -> Result<(), ControlStop> {
        match status {
            STATUS_OK => Ok(()),
            STATUS_WARNING => {
                self.warnings += 1;
                self.last_warning = Some(message());
                Ok(())
            }
            STATUS_STOP => Err(ControlStop::stop(format!(
                "plugin {} stopped the run in {call} (status 2): {}",
                self.name,
                message()
            ))),
            other => {
                Err(ControlStop::crash(format!("plugin {} returned the unknown status {other} from {call}", self.name)))
            }
        }
    }
}
