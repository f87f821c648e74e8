//! exoleg: a simulator for force control of hydraulic lower-limb exoskeletons.
//!
//! The blocks of the control diagram each have a module:
//! [`reference`] -> [`control`] (ZNN, ARBFNN-FDO-ZNN, ERL-SMC) -> [`hydraulics`] (valve +
//! cylinder force ODE) -> [`plant`] (bench or leg mechanics) -> [`sensors`] -> back to the
//! controller, with [`human`] interaction and [`disturbance`]s injected. [`sim`] wires them
//! in a small co-simulation loop; [`scenario`] loads and validates scenario files;
//! [`metrics`] defines the figures once; [`output`] writes CSV, JSON and plots.

pub mod cli;
pub mod compare;
pub mod control;
pub mod disturbance;
pub mod error;
pub mod gait_test;
pub mod human;
pub mod hydraulics;
pub mod integrator;
pub mod leg;
pub mod metrics;
pub mod output;
pub mod plant;
pub mod reference;
pub mod scenario;
pub mod sensors;
pub mod sim;
pub mod sweep;

pub use error::{Error, Result};
pub use scenario::Scenario;
pub use sim::{run, Record, RunOutput};
