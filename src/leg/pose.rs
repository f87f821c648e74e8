//! Poses and frames of URDF origins (Rapier's `Pose`: a rotation and a translation).

use super::model::JointSpec;
use rapier3d_f64::glamx::{DQuat, DVec3, EulerRot};
pub use rapier3d_f64::math::Pose;

/// The pose of an URDF `<origin xyz rpy>`.
pub fn pose_of(xyz: [f64; 3], rpy: [f64; 3]) -> Pose {
    Pose::from_parts(DVec3::from(xyz), DQuat::from_euler(EulerRot::ZYX, rpy[2], rpy[1], rpy[0]))
}

/// The pose of a joint's `<origin>` (child joint frame in the parent link's frame).
pub fn joint_origin_pose(j: &JointSpec) -> Pose {
    pose_of(j.origin_xyz, j.origin_rpy)
}
