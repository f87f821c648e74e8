//! What a URDF leg must be: planar joints, one tree with the cylinder's loop, moving bodies
//! with mass, and the mass properties of bodies merged over fixed joints.

use super::*;

/// Every joint lies in the sagittal plane: origins turn about y only, hinges about +-y,
/// sliders in x-z.
pub(super) fn check_planar(joints: &[JointSpec]) -> Result<(), LegError> {
    for j in joints {
        let [r, _, y] = j.origin_rpy;
        if r.abs() > 1e-12 || y.abs() > 1e-12 {
            return Err(LegError::Unsupported(format!(
                "joint '{}' origin rpy has roll/yaw; only pitch (about y) is supported in the sagittal model",
                j.name
            )));
        }
        let bad = match j.kind {
            JointKind::Revolute | JointKind::Continuous => j.axis[0].abs() > 1e-9 || j.axis[2].abs() > 1e-9,
            JointKind::Prismatic => j.axis[1].abs() > 1e-9,
            JointKind::Fixed => false,
        };
        if bad {
            let want = if j.kind == JointKind::Prismatic { "lie in the x-z plane" } else { "be +-y" };
            return Err(LegError::Unsupported(format!("joint '{}' axis must {want}", j.name)));
        }
    }
    Ok(())
}

/// The movable joints are exactly the knee, the barrel pivot (the hinge the actuator's
/// barrel hangs from) and the actuator. Returns the barrel pivot.
pub(super) fn check_topology(
    links: &[LinkSpec],
    joints: &[JointSpec],
    parent_joint: &[Option<usize>],
    [knee, rod, ankle]: [usize; 3],
    actuator: &str,
) -> Result<usize, LegError> {
    let barrel_link = joints[rod].parent;
    let barrel = parent_joint[barrel_link].ok_or_else(|| {
        LegError::Unsupported(format!(
            "actuator joint '{}' parent link '{}' must hang from a barrel pivot hinge",
            joints[rod].name, links[barrel_link].name
        ))
    })?;
    expect_kind(
        &joints[barrel],
        &format!("barrel pivot of actuator '{actuator}'"),
        JointKind::is_hinge,
        "revolute or continuous",
    )?;
    if let Some(j) =
        joints.iter().enumerate().find(|(ji, j)| j.kind != JointKind::Fixed && ![knee, barrel, rod, ankle].contains(ji))
    {
        return Err(LegError::Unsupported(format!(
            "movable joint '{}' is neither the knee, the ankle, the barrel pivot nor the actuator",
            j.1.name
        )));
    }
    Ok(barrel)
}

/// Every moving body (a link on a movable joint with the links welded to it) needs mass and a
/// positive definite inertia; massless frames and point masses on fixed joints are merged in.
pub(super) fn check_moving_bodies(m: &LegSpec) -> Result<(), LegError> {
    for ji in [m.knee, m.barrel, m.rod].into_iter().chain(m.ankle) {
        let body = m.joints[ji].child;
        let members: Vec<usize> = (0..m.links.len()).filter(|&l| m.fixed_chain(l).0 == body).collect();
        let (mass, inertia) = merged_mass_properties(m, &members);
        let names = || members.iter().map(|&l| m.links[l].name.clone()).collect::<Vec<_>>();
        if mass <= 0.0 {
            return Err(LegError::MovingBodyWithoutMass { link: m.links[body].name.clone(), links: names() });
        }
        let ev = eigenvalues(&inertia);
        let scale = ev.iter().fold(0.0f64, |a, e| a.max(e.abs()));
        if ev.iter().any(|e| *e <= 1e-12 * scale) || scale == 0.0 {
            return Err(LegError::MovingBodyWithoutInertia {
                link: m.links[body].name.clone(),
                links: names(),
                eigenvalues: ev,
            });
        }
    }
    Ok(())
}

/// Mass (kg) and inertia about the merged centre of mass (kg m^2, body frame) of links welded
/// into one body (`members[..]` all have the same fixed-chain ancestor).
pub(super) fn merged_mass_properties(m: &LegSpec, members: &[usize]) -> (f64, [[f64; 3]; 3]) {
    let parts: Vec<(f64, DVec3, DMat3)> = members
        .iter()
        .map(|&l| {
            let (_, chain) = m.fixed_chain(l);
            let pose = chain.iter().rev().fold(crate::leg::pose::Pose::IDENTITY, |p, &ji| {
                p * crate::leg::pose::joint_origin_pose(&m.joints[ji])
            });
            let link = &m.links[l];
            let r = DMat3::from_quat(pose.rotation);
            let c = pose * DVec3::from(link.com_m);
            (link.mass_kg, c, r * DMat3::from_cols_array_2d(&link.inertia_kg_m2) * r.transpose())
        })
        .collect();
    let mass: f64 = parts.iter().map(|p| p.0).sum();
    if mass <= 0.0 {
        return (mass, [[0.0; 3]; 3]);
    }
    let com = parts.iter().fold(DVec3::ZERO, |a, p| a + p.1 * p.0) / mass;
    let inertia = parts.iter().fold(DMat3::ZERO, |a, (mi, ci, ii)| {
        let d = *ci - com;
        a + *ii + (DMat3::IDENTITY * d.length_squared() - DMat3::from_cols(d * d.x, d * d.y, d * d.z)) * *mi
    });
    (mass, inertia.to_cols_array_2d())
}
