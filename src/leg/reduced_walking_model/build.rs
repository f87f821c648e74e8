//! The reduced engine's model from the URDF (its joints in order, the loop's table, the contact
//! spheres) and the small linear algebra of its equations (a Cholesky factor and its solve).

use super::*;

/// The joints in topological order with their coordinates; refuses what the engine cannot do.
pub(super) fn tree_joints(spec: &LegSpec) -> Result<Vec<TreeJoint>, LegError> {
    let mut out = Vec::new();
    for &ji in &spec.topo_joints {
        let j = &spec.joints[ji];
        let off_y = j.axis[0].abs() + j.axis[2].abs();
        let hinge = j.kind.is_hinge();
        if (hinge && off_y > 1e-9) || j.origin_rpy[0].abs() + j.origin_rpy[2].abs() > 1e-9 {
            return Err(LegError::Unsupported(format!(
                "joint '{}' is not in the sagittal plane: the reduced engine handles planar legs (hinges about y)",
                j.name
            )));
        }
        let coord = if ji == spec.knee {
            Coord::Knee
        } else if ji == spec.barrel {
            Coord::Loop(0)
        } else if ji == spec.rod {
            Coord::Loop(3)
        } else if Some(ji) == spec.ankle {
            Coord::Ankle
        } else if j.kind == JointKind::Fixed {
            Coord::Zero
        } else {
            return Err(LegError::Unsupported(format!(
                "joint '{}' moves but is not the knee, the cylinder's loop or the ankle: the reduced engine cannot move it",
                j.name
            )));
        };
        if j.kind == JointKind::Prismatic && j.axis[1].abs() > 1e-9 {
            return Err(LegError::Unsupported(format!("joint '{}' slides out of the sagittal plane", j.name)));
        }
        let origin = crate::leg::model::joint_origin(j);
        let (sign, slide) = match j.kind {
            JointKind::Prismatic => (0.0, P2::new(j.axis[0], j.axis[2]).rot(origin.a)),
            JointKind::Fixed => (0.0, P2::default()),
            _ => (j.axis[1].signum(), P2::default()),
        };
        let (sn, cn) = origin.a.sin_cos();
        out.push(TreeJoint { parent: j.parent, child: j.child, origin, origin_cs: (cn, sn), sign, slide, coord });
    }
    Ok(out)
}

/// The loop's barrel angle and rod slide with their first two knee derivatives on the grid.
pub(super) fn loop_table(spec: &LegSpec, lo: f64, step: f64) -> Result<Vec<[f64; 6]>, LegError> {
    let at = |k: f64| spec.loop_solution(k).map(|s| (s.barrel_rad, s.rod_m));
    let mut table: Vec<[f64; 6]> = Vec::with_capacity(N_TABLE);
    for i in 0..N_TABLE {
        let k = lo + i as f64 * step;
        let row = match (at(k - H), at(k), at(k + H)) {
            (Some(m), Some(c), Some(p)) => {
                // The barrel angle is wrapped to (-pi, pi]: unwrap the neighbours.
                let un = |a: f64| {
                    c.0 + (a - c.0 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
                };
                let (bm, bp) = (un(m.0), un(p.0));
                Some([
                    c.0,
                    (bp - bm) / (2.0 * H),
                    (bp - 2.0 * c.0 + bm) / (H * H),
                    c.1,
                    (p.1 - m.1) / (2.0 * H),
                    (p.1 - 2.0 * c.1 + m.1) / (H * H),
                ])
            }
            _ => None,
        };
        // Beyond where the loop closes a row repeats its neighbour (the stops keep the knee
        // away from there).
        match (row, table.last()) {
            (Some(r), _) => table.push(r),
            (None, Some(&r)) => table.push(r),
            (None, None) => table.push([f64::NAN; 6]),
        }
    }
    let first = table
        .iter()
        .position(|r| !r[0].is_nan())
        .ok_or_else(|| LegError::InvalidArgument("the loop closes nowhere in the knee range".into()))?;
    let r = table[first];
    table[..first].iter_mut().for_each(|x| *x = r);
    Ok(table)
}

/// The compliant law's contact spheres in their links' frames (planar): the geometry of the
/// Rapier engine's (`ground::contact_spheres`).
pub(super) fn contact_spheres(spec: &LegSpec) -> Result<Vec<Sphere>, LegError> {
    let mut out = Vec::new();
    for c in &spec.collisions {
        let name = &spec.links[c.link].name;
        if c.origin_rpy[0].abs() + c.origin_rpy[2].abs() > 1e-9 {
            return Err(LegError::Unsupported(format!(
                "link '{name}' <collision> has roll or yaw: the reduced engine's contact is planar"
            )));
        }
        let r = CORNER_RADIUS_M;
        let corners = |x: f64, z: f64| {
            let (x, z) = (x.max(0.0), z.max(0.0));
            vec![P2::new(x, z), P2::new(-x, z), P2::new(x, -z), P2::new(-x, -z)]
        };
        let (points, radius) = match &c.shape {
            CollisionShape::Sphere { radius } => (vec![P2::default()], *radius),
            CollisionShape::Capsule { radius, length } => (vec![P2::new(0.0, length / 2.0), P2::new(0.0, -length / 2.0)], *radius),
            CollisionShape::Box { size } => (corners(size[0] / 2.0 - r, size[2] / 2.0 - r), r),
            CollisionShape::Cylinder { radius, length } => (corners(radius - r, length / 2.0 - r), r),
            CollisionShape::Mesh { filename } => {
                return Err(LegError::Unsupported(format!(
                    "link '{name}' <collision> is a mesh ({filename}): ground contact needs boxes, cylinders, spheres or capsules"
                )))
            }
        };
        let origin = Pose2::new(c.origin_xyz[0], c.origin_xyz[2], c.origin_rpy[1]);
        out.extend(points.into_iter().map(|p| Sphere { link: c.link, center: origin.apply(p), radius_m: radius }));
    }
    Ok(out)
}

/// The generalized force of a force `f` (N, world) at a point with the Jacobian columns `jp`
/// (the pelvis's columns are `(1, 0)` and `(0, 1)`).
pub(super) fn generalized(jp: &[P2; NJ], f: P2) -> [f64; NG] {
    [f.x, f.z, jp[0].dot(f), jp[1].dot(f), jp[2].dot(f)]
}

/// `q += d`.
pub(super) fn add(q: &mut [f64; NG], d: [f64; NG]) {
    q.iter_mut().zip(d).for_each(|(q, d)| *q += d);
}

/// Lower Cholesky factor of a symmetric positive definite matrix.
pub(super) fn cholesky(m: &[[f64; NG]; NG]) -> [[f64; NG]; NG] {
    let mut l = [[0.0; NG]; NG];
    for i in 0..NG {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                l[i][i] = (m[i][i] - s).max(1e-300).sqrt();
            } else {
                l[i][j] = (m[i][j] - s) / l[j][j];
            }
        }
    }
    l
}

/// Solve `L L^T x = b`.
pub(super) fn solve(l: &[[f64; NG]; NG], mut b: [f64; NG]) -> [f64; NG] {
    for i in 0..NG {
        b[i] = (b[i] - (0..i).map(|k| l[i][k] * b[k]).sum::<f64>()) / l[i][i];
    }
    for i in (0..NG).rev() {
        b[i] = (b[i] - (i + 1..NG).map(|k| l[k][i] * b[k]).sum::<f64>()) / l[i][i];
    }
    b
}
