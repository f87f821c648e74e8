//! exoleg's integration tests, one binary (one link on two cores instead of twelve).

mod common;

mod animate;
mod architecture;
mod bench_motion;
mod cli;
mod device_sensors;
mod end_stops;
mod firmware;
mod fmu;
mod gait;
mod gait_check;
mod hardening;
mod hardening3;
mod hostile;
mod isolation;
mod leg_coupled;
mod leg_ground;
mod leg_hip;
mod leg_passive;
mod leg_reduced;
mod leg_statics;
mod leg_urdf_errors;
mod observer;
mod output_safety;
mod paper_tables;
mod resume;
mod sampled;
mod shard;
mod shipped_outputs;
mod subjects;
mod validation;
mod walking;
mod walking_reduced;
mod whole_controller;
mod your_controller;
