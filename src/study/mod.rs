//! Studies built on the simulation core: one run written to a folder, the paper's cases,
//! parameter sweeps, the robustness report, the fault campaign, the gait-test API, and the check of a folder of gait
//! trials (`gait-check`).

pub mod compare;
pub mod faults;
pub mod firmware;
pub mod gait_check;
pub mod gait_test;
pub mod journal;
pub mod lines;
pub mod robustness;
pub mod shard;
mod single;
pub mod sweep;

pub use single::*;
