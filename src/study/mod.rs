//! Studies built on the simulation core: one run written to a folder, the paper's cases,
//! parameter sweeps, the robustness report, and the gait-test API.

pub mod compare;
pub mod firmware;
pub mod gait_test;
pub mod journal;
pub mod robustness;
pub mod shard;
mod single;
pub mod sweep;

pub use single::*;
