//! Rapier-independent geometry and reduced (1-DoF) mechanics of the knee + cylinder loop.
//!
//! All functions assume the thigh (root link) frame coincides with the world frame (hip at the
//! origin, thigh hanging along -z), gravity `-9.81 m/s^2` along z.
//!
//! Sign conventions: knee angle `theta` positive in flexion; cylinder length `L` is the pin-to-pin
//! distance barrel pivot -> rod end; actuator force `F` positive when it lengthens the cylinder.
//! The generalized knee torque of the actuator is `F * dL/dtheta`.

use super::error::LegError;
use super::model::{LegModel, LoopPose, GRAVITY_M_S2};
use super::planar::Pose2;

/// Central-difference step for the numerical derivatives below, rad.
const H: f64 = 1e-5;

/// Pin-to-pin cylinder length at a knee angle (law of cosines), m.
///
/// `L^2 = a^2 + b^2 - 2 a b cos(gamma)`, with `a` = |barrel pivot - knee centre|,
/// `b` = |rod end - knee centre| and `gamma` the angle between the two at the knee, which varies
/// one-to-one with the knee angle.
pub fn cylinder_length_at(model: &LegModel, knee_rad: f64) -> f64 {
    let (a, b, gamma) = triangle(model, knee_rad);
    (a * a + b * b - 2.0 * a * b * gamma.cos()).max(0.0).sqrt()
}

/// Moment arm `dL/dtheta` of the cylinder about the knee, m/rad (analytic derivative of the law
/// of cosines: `sigma * a b sin(gamma) / L`). Negative when flexion shortens the cylinder.
pub fn moment_arm_at(model: &LegModel, knee_rad: f64) -> f64 {
    let (a, b, gamma) = triangle(model, knee_rad);
    let l = (a * a + b * b - 2.0 * a * b * gamma.cos()).max(0.0).sqrt();
    model.geo.knee_sign * a * b * gamma.sin() / l
}

fn triangle(model: &LegModel, knee_rad: f64) -> (f64, f64, f64) {
    let g = &model.geo;
    let pk = g.barrel_origin.t.minus(g.knee_origin.t); // knee -> pivot
    let w0 = g.shank_point.rot(g.knee_origin.a); // knee -> rod end at theta = 0
    let gamma = w0.polar() + g.knee_sign * knee_rad - pk.polar();
    (pk.norm(), g.shank_point.norm(), gamma)
}

/// Solves the loop: barrel angle, rod extension and cylinder length for a knee angle.
/// Errors if the rod cannot reach, or the extension is outside the prismatic limits.
pub fn loop_pose_at(model: &LegModel, knee_rad: f64) -> Result<LoopPose, LegError> {
    model.loop_solution_checked(knee_rad)
}

/// Planar poses (x, z, pitch) of every link in the world frame for a knee angle, indexed like
/// [`LegModel::links`]. Ignores prismatic limits (pure geometry).
pub fn link_poses_at(model: &LegModel, knee_rad: f64) -> Result<Vec<Pose2>, LegError> {
    let sol = model.loop_solution(knee_rad).ok_or_else(|| LegError::Unreachable {
        actuator: model.actuator.name.clone(),
        knee_rad,
        reason: "the rod cannot reach the shank mounting point".into(),
    })?;
    Ok(model.link_poses(&model.joint_coords(&sol)))
}

/// Gravitational potential energy `V(theta) = sum m g z_com` of all links (thigh included), J,
/// with z measured from the hip.
pub fn potential_energy_at(model: &LegModel, knee_rad: f64) -> Result<f64, LegError> {
    let poses = link_poses_at(model, knee_rad)?;
    Ok(model
        .links
        .iter()
        .zip(&poses)
        .map(|(l, p)| {
            let c = p.apply(super::planar::P2::new(l.com_m[0], l.com_m[2]));
            l.mass_kg * GRAVITY_M_S2 * c.z
        })
        .sum())
}

/// Generalized inertia of the closed chain reduced to the knee angle, kg m^2:
/// `M(theta) = sum_i m_i |d c_i/d theta|^2 + I_yy,i (d alpha_i / d theta)^2`, with the body
/// velocities from the loop kinematics (numerical derivative of the poses).
pub fn generalized_inertia_at(model: &LegModel, knee_rad: f64) -> Result<f64, LegError> {
    let pp = link_poses_at(model, knee_rad + H)?;
    let pm = link_poses_at(model, knee_rad - H)?;
    let mut m = 0.0;
    for (i, l) in model.links.iter().enumerate() {
        let com = super::planar::P2::new(l.com_m[0], l.com_m[2]);
        let dc = pp[i].apply(com).minus(pm[i].apply(com)).scale(1.0 / (2.0 * H));
        let da = (pp[i].a - pm[i].a) / (2.0 * H);
        m += l.mass_kg * dc.dot(dc) + l.inertia_kg_m2[1][1] * da * da;
    }
    Ok(m)
}

/// Gravity torque about the knee, N m, positive in the flexion direction: `-dV/dtheta`
/// (includes every body: shank, foot, cylinder barrel and rod).
pub fn gravity_torque_at(model: &LegModel, knee_rad: f64) -> Result<f64, LegError> {
    let vp = potential_energy_at(model, knee_rad + H)?;
    let vm = potential_energy_at(model, knee_rad - H)?;
    Ok(-(vp - vm) / (2.0 * H))
}

/// Actuator force that holds the knee in static equilibrium at `knee_rad`, N
/// (positive = pushing, lengthening): `F = (dV/dtheta) / (dL/dtheta)` (virtual work).
pub fn holding_force_at(model: &LegModel, knee_rad: f64) -> Result<f64, LegError> {
    Ok(-gravity_torque_at(model, knee_rad)? / moment_arm_at(model, knee_rad))
}

/// Knee angular acceleration of the passive reduced model (Lagrange equation), rad/s^2:
/// `M qdd + 1/2 M' qd^2 + V' = Q`, with `Q = F dL/dtheta + tau_ext`.
pub fn reduced_acceleration(
    model: &LegModel,
    knee_rad: f64,
    knee_vel: f64,
    actuator_force_n: f64,
    ext_torque_nm: f64,
) -> Result<f64, LegError> {
    let m = generalized_inertia_at(model, knee_rad)?;
    let dm = (generalized_inertia_at(model, knee_rad + 1e-4)? - generalized_inertia_at(model, knee_rad - 1e-4)?) / 2e-4;
    let dv = -gravity_torque_at(model, knee_rad)?;
    let q = actuator_force_n * moment_arm_at(model, knee_rad) + ext_torque_nm;
    Ok((q - 0.5 * dm * knee_vel * knee_vel - dv) / m)
}

/// Generalized knee force (N m, positive in flexion) the actuator and cuff must supply for
/// the knee to follow `knee = (angle rad, rate rad/s, accel rad/s^2)` while the hip moves as
/// `hip = (angle, rate, accel)`. With the hip still this is the reduced closed-chain Lagrange
/// equation `M qdd + 1/2 M' qd^2 + V'`. (Hip motion terms: see [`crate::leg`] docs.)
pub fn knee_torque_required(model: &LegModel, hip: (f64, f64, f64), knee: (f64, f64, f64)) -> Result<f64, LegError> {
    let _ = hip;
    let (q, qd, qdd) = knee;
    let m = generalized_inertia_at(model, q)?;
    let dm = (generalized_inertia_at(model, q + 1e-4)? - generalized_inertia_at(model, q - 1e-4)?) / 2e-4;
    let dv = -gravity_torque_at(model, q)?;
    Ok(m * qdd + 0.5 * dm * qd * qd + dv)
}
