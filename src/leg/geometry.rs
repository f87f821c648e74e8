//! Rapier-independent geometry and reduced (1-DoF) mechanics of the knee + cylinder loop.
//!
//! All functions assume the thigh (root link) frame coincides with the world frame (hip at the
//! origin, thigh hanging along -z), gravity `-9.81 m/s^2` along z.
//!
//! Sign conventions: knee angle `theta` positive in flexion; cylinder length `L` is the pin-to-pin
//! distance barrel pivot -> rod end; actuator force `F` positive when it lengthens the cylinder.
//! The generalized knee torque of the actuator is `F * dL/dtheta`.

use super::error::LegError;
use super::model::{LegSpec, LoopPose, GRAVITY_M_S2};
use super::planar::Pose2;

/// Central-difference step for the numerical derivatives below, rad.
const H: f64 = 1e-5;

/// Pin-to-pin cylinder length at a knee angle (law of cosines), m.
///
/// `L^2 = a^2 + b^2 - 2 a b cos(gamma)`, with `a` = |barrel pivot - knee centre|,
/// `b` = |rod end - knee centre| and `gamma` the angle between the two at the knee, which varies
/// one-to-one with the knee angle.
pub fn cylinder_length_at(model: &LegSpec, knee_rad: f64) -> f64 {
    let (a, b, gamma) = triangle(model, knee_rad);
    (a * a + b * b - 2.0 * a * b * gamma.cos()).max(0.0).sqrt()
}

/// Moment arm `dL/dtheta` of the cylinder about the knee, m/rad (analytic derivative of the law
/// of cosines: `sigma * a b sin(gamma) / L`). Negative when flexion shortens the cylinder.
pub fn moment_arm_at(model: &LegSpec, knee_rad: f64) -> f64 {
    cylinder_kinematics_at(model, knee_rad).1
}

/// Slope of the moment arm, `d^2L/dtheta^2` (m/rad^2), analytic:
/// `a b cos(gamma) / L - (a b sin(gamma))^2 / L^3` (the sign of the knee axis squares away).
pub fn moment_arm_slope_at(model: &LegSpec, knee_rad: f64) -> f64 {
    cylinder_kinematics_at(model, knee_rad).2
}

/// Cylinder length (m), moment arm `dL/dtheta` (m/rad) and its slope `d^2L/dtheta^2`
/// (m/rad^2) at one knee angle, with one sine and cosine (the length is
/// [`cylinder_length_at`]'s).
pub fn cylinder_kinematics_at(model: &LegSpec, knee_rad: f64) -> (f64, f64, f64) {
    let (a, b, gamma) = triangle(model, knee_rad);
    let (sin, cos) = gamma.sin_cos();
    let l = (a * a + b * b - 2.0 * a * b * cos).max(0.0).sqrt();
    let s = a * b * sin;
    (l, model.geo.knee_sign * s / l, a * b * cos / l - s * s / (l * l * l))
}

/// Third derivative of the cylinder length, `d^3L/dtheta^3` (m/rad^3), analytic.
pub fn moment_arm_curvature_at(model: &LegSpec, knee_rad: f64) -> f64 {
    let (a, b, gamma) = triangle(model, knee_rad);
    let l = (a * a + b * b - 2.0 * a * b * gamma.cos()).max(0.0).sqrt();
    let sg = model.geo.knee_sign;
    let (ab, (s, c)) = (a * b, gamma.sin_cos());
    let l1 = sg * ab * s / l;
    -sg * ab * s / l - ab * c * l1 / (l * l) - 2.0 * ab * ab * s * c * sg / (l * l * l)
        + 3.0 * ab * ab * s * s * l1 / (l * l * l * l)
}

fn triangle(model: &LegSpec, knee_rad: f64) -> (f64, f64, f64) {
    let g = &model.geo;
    let t = &g.triangle;
    let gamma = t.rod_end_polar_rad + g.knee_sign * knee_rad - t.pivot_polar_rad;
    (t.a_m, t.b_m, gamma)
}

/// Solves the loop: barrel angle, rod extension and cylinder length for a knee angle.
/// Errors if the rod cannot reach, or the extension is outside the prismatic limits.
pub fn loop_pose_at(model: &LegSpec, knee_rad: f64) -> Result<LoopPose, LegError> {
    model.loop_solution_checked(knee_rad)
}

/// Planar poses (x, z, pitch) of every link in the world frame for a knee angle, indexed like
/// [`LegSpec::links`]. Ignores prismatic limits (pure geometry).
pub fn link_poses_at(model: &LegSpec, knee_rad: f64) -> Result<Vec<Pose2>, LegError> {
    let sol = model.loop_solution(knee_rad).ok_or_else(|| LegError::Unreachable {
        actuator: model.actuator.name.clone(),
        knee_rad,
        reason: "the rod cannot reach the shank mounting point".into(),
    })?;
    Ok(model.link_poses(&model.joint_coords(&sol)))
}

/// Gravitational potential energy `V(theta) = sum m g z_com` of all links (thigh included), J,
/// with z measured from the hip.
pub fn potential_energy_at(model: &LegSpec, knee_rad: f64) -> Result<f64, LegError> {
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
pub fn generalized_inertia_at(model: &LegSpec, knee_rad: f64) -> Result<f64, LegError> {
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
pub fn gravity_torque_at(model: &LegSpec, knee_rad: f64) -> Result<f64, LegError> {
    let vp = potential_energy_at(model, knee_rad + H)?;
    let vm = potential_energy_at(model, knee_rad - H)?;
    Ok(-(vp - vm) / (2.0 * H))
}

/// Actuator force that holds the knee in static equilibrium at `knee_rad`, N
/// (positive = pushing, lengthening): `F = (dV/dtheta) / (dL/dtheta)` (virtual work).
pub fn holding_force_at(model: &LegSpec, knee_rad: f64) -> Result<f64, LegError> {
    Ok(-gravity_torque_at(model, knee_rad)? / moment_arm_at(model, knee_rad))
}

/// Knee angular acceleration of the passive reduced model (Lagrange equation), rad/s^2:
/// `M qdd + 1/2 M' qd^2 + V' = Q`, with `Q = F dL/dtheta + tau_ext`.
pub fn reduced_acceleration(
    model: &LegSpec,
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

// ---------------------------------------------------------------------------------------------
// Moving hip: generalized coordinates q = (theta_h, theta_k).
//
// The whole planar leg (thigh = URDF root, shank + foot, barrel, rod) turns rigidly about the
// world y axis through the hip (world origin). Hip flexion `theta_h` is positive when the thigh
// swings forward (the knee moves to +x for a person facing +x). With the right-handed rotation
// about +y used by [`Pose2`] (`x' = x cos a + z sin a`, `z' = -x sin a + z cos a`) a positive
// angle moves a point below the hip to -x, so hip flexion is the rotation by `a = -theta_h`
// about +y (equivalently `+theta_h` about -y; the Rapier hip joint axis is -y):
//
//     world pose of link i = Rot_y(-theta_h) * P_i(theta_k)        (P_i from `link_poses_at`)
//
// Kinetic energy, with c_i(theta_k) the CoM and alpha_i(theta_k) the pitch of link i in the
// thigh frame, c' = dc/dtheta_k, alpha' = dalpha/dtheta_k (numerical, loop kinematics):
//
//     T = 1/2 (M_hh thd_h^2 + 2 M_hk thd_h thd_k + M_kk thd_k^2)
//     M_hh = sum m |c|^2 + Iyy
//     M_hk = -sum m (c_z c'_x - c_x c'_z) + Iyy alpha'
//     M_kk = sum m |c'|^2 + Iyy alpha'^2            (= `generalized_inertia_at`)
//
// (all three depend on theta_k only). Lagrange, knee row (the M_hk' thd_h thd_k terms cancel):
//
//     tau_k = M_kk thdd_k + M_hk thdd_h + 1/2 M_kk' thd_k^2 - 1/2 M_hh' thd_h^2 + dV/dtheta_k
//
// hip row:
//
//     tau_h = M_hh thdd_h + M_hk thdd_k + M_hh' thd_h thd_k + M_hk' thd_k^2 + dV/dtheta_h
//
// with V(theta_h, theta_k) = sum m g z_i, z_i = c_x sin(theta_h) + c_z cos(theta_h).
// ---------------------------------------------------------------------------------------------

/// Step for derivatives of the mass-matrix entries with respect to the knee angle, rad.
const H_DM: f64 = 1e-4;

/// Planar world pose of a thigh-frame pose after hip flexion `hip_rad` (rad, flexion positive =
/// thigh forward): `Rot_y(-hip_rad) * p`.
pub fn hip_rotated(hip_rad: f64, p: &Pose2) -> Pose2 {
    Pose2::rot(-hip_rad).mul(p)
}

/// Link poses (x, z in m, pitch about +y in rad) in the world frame for hip flexion `hip_rad` and
/// knee flexion `knee_rad` (rad), indexed like [`LegSpec::links`].
pub fn link_poses_with_hip_at(model: &LegSpec, hip_rad: f64, knee_rad: f64) -> Result<Vec<Pose2>, LegError> {
    Ok(link_poses_at(model, knee_rad)?.iter().map(|p| hip_rotated(hip_rad, p)).collect())
}

/// Hip-knee generalized mass matrix `(M_hh, M_hk, M_kk)`, kg m^2, for q = (theta_h, theta_k)
/// (independent of the hip angle). `M_kk` equals [`generalized_inertia_at`]; `M_hh` is the
/// inertia of the whole leg about the hip axis; `M_hk < 0` near full extension (a forward hip
/// acceleration flexes a passive knee).
pub fn hip_knee_mass_matrix_at(model: &LegSpec, knee_rad: f64) -> Result<(f64, f64, f64), LegError> {
    let p0 = link_poses_at(model, knee_rad)?;
    let pp = link_poses_at(model, knee_rad + H)?;
    let pm = link_poses_at(model, knee_rad - H)?;
    let (mut mhh, mut mhk, mut mkk) = (0.0, 0.0, 0.0);
    for (i, l) in model.links.iter().enumerate() {
        let com = super::planar::P2::new(l.com_m[0], l.com_m[2]);
        let c = p0[i].apply(com);
        let dc = pp[i].apply(com).minus(pm[i].apply(com)).scale(1.0 / (2.0 * H));
        let da = (pp[i].a - pm[i].a) / (2.0 * H);
        let iyy = l.inertia_kg_m2[1][1];
        mhh += l.mass_kg * c.dot(c) + iyy;
        mhk -= l.mass_kg * (c.z * dc.x - c.x * dc.z) + iyy * da;
        mkk += l.mass_kg * dc.dot(dc) + iyy * da * da;
    }
    Ok((mhh, mhk, mkk))
}

/// Gravitational potential energy `sum m g z_com` of all links with a moving hip, J (z from the
/// hip). `hip_rad`, `knee_rad` in rad (flexion positive).
pub fn potential_energy_with_hip_at(model: &LegSpec, hip_rad: f64, knee_rad: f64) -> Result<f64, LegError> {
    let poses = link_poses_at(model, knee_rad)?;
    let (s, c) = hip_rad.sin_cos();
    Ok(model
        .links
        .iter()
        .zip(&poses)
        .map(|(l, p)| {
            let q = p.apply(super::planar::P2::new(l.com_m[0], l.com_m[2]));
            l.mass_kg * GRAVITY_M_S2 * (q.x * s + q.z * c)
        })
        .sum())
}

/// Mass-matrix entries and their knee derivatives: `(M_hh, M_hk, M_kk, M_hh', M_hk', M_kk')`.
fn mass_terms(model: &LegSpec, knee_rad: f64) -> Result<[f64; 6], LegError> {
    let (mhh, mhk, mkk) = hip_knee_mass_matrix_at(model, knee_rad)?;
    let (hp, kp, pp) = hip_knee_mass_matrix_at(model, knee_rad + H_DM)?;
    let (hm, km, pm) = hip_knee_mass_matrix_at(model, knee_rad - H_DM)?;
    let d = 2.0 * H_DM;
    Ok([mhh, mhk, mkk, (hp - hm) / d, (kp - km) / d, (pp - pm) / d])
}

/// Knee forces of the two-DoF model except the `M_kk thdd_k` term, N m.
fn knee_bias(
    model: &LegSpec,
    m: &[f64; 6],
    hip: (f64, f64, f64),
    knee_rad: f64,
    knee_vel: f64,
) -> Result<f64, LegError> {
    let (th, thd, thdd) = hip;
    let dv = (potential_energy_with_hip_at(model, th, knee_rad + H)?
        - potential_energy_with_hip_at(model, th, knee_rad - H)?)
        / (2.0 * H);
    Ok(m[1] * thdd + 0.5 * m[5] * knee_vel * knee_vel - 0.5 * m[3] * thd * thd + dv)
}

/// Inverse dynamics of the knee coordinate with a prescribed hip motion.
///
/// `hip` and `knee` are `(angle rad, rate rad/s, acceleration rad/s^2)`, flexion positive.
/// Returns the generalized knee force (N m) needed,
/// `tau_k = M_kk thdd_k + M_hk thdd_h + 1/2 M_kk' thd_k^2 - 1/2 M_hh' thd_h^2 + dV/dtheta_k`,
/// where `tau_k = F dL/dtheta_k + tau_ext` (F = actuator force in N, positive lengthening;
/// `tau_ext` = external cuff torque on the knee coordinate, N m). With the hip fixed
/// (`hip = (0, 0, 0)`) this is the inverse of [`reduced_acceleration`].
pub fn knee_inverse_dynamics(model: &LegSpec, hip: (f64, f64, f64), knee: (f64, f64, f64)) -> Result<f64, LegError> {
    let m = mass_terms(model, knee.0)?;
    Ok(m[2] * knee.2 + knee_bias(model, &m, hip, knee.0, knee.1)?)
}

/// Forward dynamics of the knee coordinate with a prescribed hip motion: knee acceleration,
/// rad/s^2, for a generalized knee force `tau_k` (N m, see [`knee_inverse_dynamics`]).
/// `hip = (angle rad, rate rad/s, acceleration rad/s^2)`; `knee_rad` rad; `knee_vel` rad/s.
pub fn knee_forward_acceleration(
    model: &LegSpec,
    hip: (f64, f64, f64),
    knee_rad: f64,
    knee_vel: f64,
    tau_k: f64,
) -> Result<f64, LegError> {
    let m = mass_terms(model, knee_rad)?;
    Ok((tau_k - knee_bias(model, &m, hip, knee_rad, knee_vel)?) / m[2])
}

/// Generalized hip torque (N m, positive in flexion) needed to produce the given motion of both
/// coordinates: `tau_h = M_hh thdd_h + M_hk thdd_k + M_hh' thd_h thd_k + M_hk' thd_k^2 + dV/dtheta_h`.
/// `hip`, `knee` = `(angle rad, rate rad/s, acceleration rad/s^2)`. The actuator's internal force
/// pair does no work on the hip coordinate (both its ends turn with the thigh), so this is the
/// torque the hip drive has to provide.
pub fn hip_inverse_dynamics(model: &LegSpec, hip: (f64, f64, f64), knee: (f64, f64, f64)) -> Result<f64, LegError> {
    let m = mass_terms(model, knee.0)?;
    let dv = (potential_energy_with_hip_at(model, hip.0 + H, knee.0)?
        - potential_energy_with_hip_at(model, hip.0 - H, knee.0)?)
        / (2.0 * H);
    Ok(m[0] * hip.2 + m[1] * knee.2 + m[3] * hip.1 * knee.1 + m[4] * knee.1 * knee.1 + dv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moment_arm_slope_matches_a_central_difference() {
        for (name, text) in crate::leg::BUILTIN_URDFS {
            let m = LegSpec::from_urdf_str(text, "knee").unwrap();
            for deg in [0.0f64, 17.0, 45.0, 80.0, 100.0] {
                let q = deg.to_radians();
                let h = 1e-5;
                let fd = (moment_arm_at(&m, q + h) - moment_arm_at(&m, q - h)) / (2.0 * h);
                let exact = moment_arm_slope_at(&m, q);
                assert!((fd - exact).abs() < 1e-8, "{name} at {deg} deg: {exact} vs {fd}");
                let fd3 = (moment_arm_slope_at(&m, q + h) - moment_arm_slope_at(&m, q - h)) / (2.0 * h);
                let exact3 = moment_arm_curvature_at(&m, q);
                assert!((fd3 - exact3).abs() < 1e-7, "{name} at {deg} deg: {exact3} vs {fd3}");
            }
        }
    }
}

/// Where the foot is for a hip, knee and ankle angle (rad; hip and knee flexion, ankle
/// dorsiflexion positive), in the hip frame (hip at the origin, z up, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootPoints {
    /// The ankle joint centre (the origin of the ankle's child link).
    pub ankle: super::planar::P2,
    /// The lowest point of any collision shape (the sole's contact point on flat ground).
    pub lowest: super::planar::P2,
}

/// The ankle centre and the lowest collision point for hip flexion `hip_rad`, knee flexion
/// `knee_rad` and ankle dorsiflexion `ankle_rad` (used only when the model's ankle moves).
/// Spheres and capsules count with their radius, boxes and cylinders by the corners of their
/// sagittal outline; meshes are skipped. None when the model has no collision shapes or the
/// loop cannot close at `knee_rad`.
pub fn foot_points_at(model: &LegSpec, hip_rad: f64, knee_rad: f64, ankle_rad: f64) -> Option<FootPoints> {
    let (ankle, points) = sole_points_at(model, hip_rad, knee_rad, ankle_rad)?;
    let lowest = points.into_iter().reduce(|a, b| if b.z < a.z { b } else { a })?;
    Some(FootPoints { ankle, lowest })
}

/// The ankle centre and the bottom point of every collision shape (spheres and capsules by
/// their radius, boxes and cylinders by the corners of their sagittal outline; meshes
/// skipped), in the order of the model's collisions, for the angles of [`foot_points_at`].
pub fn sole_points_at(
    model: &LegSpec,
    hip_rad: f64,
    knee_rad: f64,
    ankle_rad: f64,
) -> Option<(super::planar::P2, Vec<super::planar::P2>)> {
    let (ankle, contacts) = sole_contacts_at(model, hip_rad, knee_rad, ankle_rad)?;
    Some((ankle, contacts.into_iter().map(|c| c.0).collect()))
}

/// [`sole_points_at`] with the radius (m) each point has under the compliant contact law
/// (`leg::ground`): a sphere's or capsule's own, [`super::CORNER_RADIUS_M`] at the corners of
/// a box or cylinder.
pub fn sole_contacts_at(
    model: &LegSpec,
    hip_rad: f64,
    knee_rad: f64,
    ankle_rad: f64,
) -> Option<(super::planar::P2, Vec<(super::planar::P2, f64)>)> {
    use super::model::CollisionShape as S;
    use super::planar::P2;
    let poses = link_poses_full_at(model, hip_rad, knee_rad, ankle_rad)?;
    let foot = model.ankle.map_or_else(|| model.joints[model.knee].child, |a| model.joints[a].child);
    let mut out = Vec::new();
    for c in &model.collisions {
        let pose = poses[c.link].mul(&Pose2::new(c.origin_xyz[0], c.origin_xyz[2], c.origin_rpy[1]));
        let (corners, radius): (Vec<P2>, f64) = match &c.shape {
            S::Sphere { radius } => (vec![P2::default()], *radius),
            S::Capsule { radius, length } => (vec![P2::new(0.0, length / 2.0), P2::new(0.0, -length / 2.0)], *radius),
            S::Box { size } => {
                let (x, z) = (size[0] / 2.0, size[2] / 2.0);
                (vec![P2::new(x, z), P2::new(-x, z), P2::new(x, -z), P2::new(-x, -z)], 0.0)
            }
            S::Cylinder { radius, length } => {
                let (x, z) = (*radius, length / 2.0);
                (vec![P2::new(x, z), P2::new(-x, z), P2::new(x, -z), P2::new(-x, -z)], 0.0)
            }
            S::Mesh { .. } => continue,
        };
        let contact_radius = if radius > 0.0 { radius } else { super::CORNER_RADIUS_M };
        out.extend(corners.into_iter().map(|k| (pose.apply(k).minus(P2::new(0.0, radius)), contact_radius)));
    }
    Some((poses[foot].t, out))
}

/// Planar poses of every link (hip frame: hip at the origin, z up) for hip flexion, knee
/// flexion and ankle dorsiflexion (rad; the ankle's only when it moves), indexed like
/// [`LegSpec::links`]. None when the loop cannot close at `knee_rad`.
pub fn link_poses_full_at(model: &LegSpec, hip_rad: f64, knee_rad: f64, ankle_rad: f64) -> Option<Vec<Pose2>> {
    let mut q = model.joint_coords(&model.loop_solution(knee_rad)?);
    if let Some(a) = model.ankle {
        q[a] = ankle_rad;
    }
    Some(model.link_poses(&q).iter().map(|p| hip_rotated(hip_rad, p)).collect())
}
