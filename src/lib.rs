//! exoleg: a simulator for force control of hydraulic lower-limb exoskeletons.
//!
//! The blocks of the control diagram each have a module:
//! [`reference`](mod@reference) -> [`control`] (ZNN, ARBFNN-FDO-ZNN, ERL-SMC, dtznn, C plugins,
//! the knee PD; the contract every outside controller implements) -> [`hydraulics`] (valve +
//! cylinder) -> [`plant`] (bench or leg mechanics; [`leg`] is the URDF leg in Rapier or in
//! reduced coordinates) -> [`sensors`] -> back to the controller, with [`human`] interaction
//! and [`disturbance`]s injected. [`scenario`] reads, validates and resolves scenario files;
//! [`sim`] is the co-simulation loop ([`integrator`] its fixed-step schemes); [`session`] runs
//! it with the online [`metrics`] and the caller's [`record`] sink ([`output`]: streamed CSV,
//! JSON, plots); [`study`] builds single runs with any controller, comparisons, sweeps and the
//! robustness report on top; [`fsio`] is how every file is read (regular, capped) and
//! written (new or exoleg's own, never a device, a link or an input); [`profile`] times the
//! loop's stages in a `stage-timing` build; [`fmu`] packs the plant as an FMI 2.0 co-simulation FMU (the
//! `fmu/` crate exports its C entry points); [`cli`] is the command line.
//!
//! Dependencies point one way, from the ground floor up (a module imports only from the
//! lines above its own; `tests/it/architecture.rs` checks it, and that no two files import
//! each other, directly or around a circle):
//!
//! ```text
//! error, integrator, faults, profile
//! record, hydraulics, sensors, fsio
//! disturbance, leg, muscles
//! reference
//! human, control, metrics
//! plant
//! sim
//! session, output
//! scenario
//! study, fmu
//! cli
//! ```

#![deny(missing_docs)]

pub mod cli;
pub mod control;
pub mod disturbance;
pub mod error;
pub mod faults;
pub mod fmu;
pub mod fsio;
pub mod hil;
pub mod human;
pub mod hydraulics;
pub mod integrator;
pub mod leg;
pub mod metrics;
pub mod muscles;
pub mod output;
pub mod plant;
pub mod profile;
pub mod record;
pub mod reference;
pub mod scenario;
pub mod sensors;
pub mod session;
pub mod sim;
pub mod study;

pub use error::{Error, Result};
pub use scenario::{ResolvedScenario, Resources, Scenario};
pub use session::{run, run_in_memory, Session};
pub use sim::{Model, Simulation};

/// Load, validate and resolve a scenario in one call (`None` = the embedded default), with
/// `--set`-style overrides. Convenient for tests and the library API.
///
/// ```
/// // The embedded default (the paper's Figure 5 case) on the bench plant, 0.2 s.
/// let sc = exoleg::load(None, &["plant.kind=\"bench\"", "sim.duration_s=0.2"]).unwrap();
/// let (summary, record) = exoleg::run_in_memory(&sc.model).unwrap();
/// assert!(summary.max_abs_force_error_n.is_finite());
/// assert!(record.columns().iter().any(|(name, _)| name == "load_force_n"));
/// // A key that does not exist is an error that names it.
/// let e = exoleg::load(None, &["sim.dt=0.001"]).unwrap_err();
/// assert!(e.to_string().contains("sim.dt"));
/// ```
pub fn load(path: Option<&std::path::Path>, sets: &[&str]) -> Result<ResolvedScenario> {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::load(path, &sets)?.resolve(&Resources::new())
}
