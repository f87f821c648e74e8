//! The leg as an FMI 2.0 co-simulation FMU: everything in a scenario but the controller
//! (reference, hydraulics, leg, contact and carriage, sensors, human, disturbances), for
//! Simulink, OpenModelica, FMPy and any FMI 2.0 master.
//!
//! - [`package`]: `exoleg fmu` writes the zip (`modelDescription.xml`,
//!   `binaries/<platform>/exoleg.<ext>`, `resources/` with the resolved scenario and every
//!   file it reads).
//! - [`Slave`]: one instance as safe Rust (FMI's state machine over a
//!   [`crate::sim::Simulation`] with the controller outside); the `fmu/` crate exports the
//!   `fmi2*` C functions over it.
//! - [`variables()`]: the one table of variables both use (readings, truth channels, the valve
//!   command, parameters, the nominal model).

mod description;
mod package;
mod slave;
mod variables;

pub use description::{model_description, DescriptionInfo};
pub use package::{
    check_library, default_library, fuzz_fmu_library, has_fmu_comment, is_exoleg_fmu, out_rule, package,
    platform_folder, read_library, FmuReport, FMU_COMMENT, LIBRARY_FILE, MAX_LIBRARY_BYTES,
};
pub use slave::{uri_to_path, FmiError, FmiResult, Phase, Slave};
pub use variables::{nominal_values, variables, Causality, Role, VarType, Variable, NOMINAL, PARAMETERS, UNITS};

use sha2::{Digest, Sha256};

/// The FMU's `modelIdentifier`: its library is `binaries/<platform>/exoleg.<ext>`.
pub const MODEL_IDENTIFIER: &str = "exoleg";

/// The scenario inside `resources/`.
pub const RESOURCE_SCENARIO: &str = "scenario.toml";

/// The FMU's GUID: a hash of the scenario it runs and of its variables (so a description, a
/// resources folder or a library from different builds never pair up silently).
pub fn guid_of(scenario_text: &str, vars: &[Variable]) -> String {
    let mut h = Sha256::new();
    h.update(b"exoleg-fmu-1\0");
    h.update(scenario_text.as_bytes());
    for v in vars {
        h.update(format!("\0{}|{}|{:?}|{:?}", v.name, v.vr, v.ty, v.causality).as_bytes());
    }
    let d = h.finalize();
    let x: String = d.iter().take(16).map(|b| format!("{b:02x}")).collect();
    format!("{{{}-{}-{}-{}-{}}}", &x[0..8], &x[8..12], &x[12..16], &x[16..20], &x[20..32])
}
