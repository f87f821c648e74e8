//! Sagittal-plane leg + knee-exoskeleton hydraulic cylinder model.
//!
//! * [`LegSpec`]: immutable model loaded from a URDF with two extension elements
//!   (`<loop_closure>` and `<hydraulic_actuator>`), validated, with the planar loop geometry.
//! * [`urdf`]: the URDF reader that builds a [`LegSpec`] ([`LegSpec::from_urdf_str`]), kept
//!   apart from the model; [`pose`]: frames of URDF origins.
//! * [`Leg`]: Rapier 0.36 (f64) simulation of that model (multibody tree + impulse-joint loop
//!   closure), in [`rapier`]: built ([`rapier`]`::build`), stepped (`::step`), and its gait-lab
//!   quantities (`::lab`).
//! * [`ReducedModel`]: the same closed chain in its knee coordinate (the reduced engine).
//! * [`geometry`]: Rapier-independent helpers (cylinder length, moment arm, gravity torque,
//!   holding force, reduced generalized inertia) for tests and inverse dynamics.
//!
//! Units are SI (m, kg, s, rad, N, N m, J). Conventions: z up, person faces +x, sagittal plane
//! x-z, knee angle positive in flexion (the foot moves to -x), actuator force positive when it
//! lengthens the cylinder, gravity 9.81 m/s^2 along -z.

pub mod error;
pub mod geometry;
pub mod ground;
pub mod model;
pub mod planar;
pub mod pose;
pub mod rapier;
pub mod reduced_knee_model;
pub mod reduced_walking_model;
pub mod stops;
pub mod subject;
pub mod urdf;

pub use error::LegError;
pub use geometry::{
    cylinder_length_at, foot_points_at, generalized_inertia_at, gravity_torque_at, hip_inverse_dynamics,
    hip_knee_mass_matrix_at, hip_rotated, holding_force_at, knee_forward_acceleration, knee_inverse_dynamics,
    link_poses_at, link_poses_full_at, link_poses_with_hip_at, loop_pose_at, moment_arm_at, moment_arm_curvature_at,
    moment_arm_slope_at, potential_energy_at, potential_energy_with_hip_at, reduced_acceleration, sole_contacts_at,
    sole_points_at, FootPoints,
};
pub use ground::{static_sink_m, CompliantContact, ContactReading, GroundConfig, CORNER_RADIUS_M};
pub use model::{
    ActuatorSpec, CollisionShape, CollisionSpec, JointKind, JointSpec, LegOptions, LegSpec, LinkSpec, LoopClosureSpec,
    LoopPose,
};
pub use pose::{joint_origin_pose, pose_of, Pose};
pub use rapier::{CarriageConfig, HipCoupling, Leg, LegForces, LegSolverParams, Mount};

/// Built-in URDFs, embedded so a run needs no data path: `builtin:exo_leg` (75 kg, 1.75 m
/// male) and `builtin:exo_leg_small` (60 kg, 1.60 m female, heavier cylinder).
pub const BUILTIN_URDFS: [(&str, &str); 2] = [
    ("builtin:exo_leg", include_str!("../../urdf/exo_leg.urdf")),
    ("builtin:exo_leg_small", include_str!("../../urdf/exo_leg_small.urdf")),
];
pub use reduced_knee_model::{HipMotion, ReducedModel};
pub use reduced_walking_model::WalkerModel;
pub use stops::{EndStops, StopReport, StopSource};
