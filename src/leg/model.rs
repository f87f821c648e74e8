//! Immutable leg model: URDF parsing (urdf-rs + a roxmltree pass for the extension elements),
//! validation, and the planar loop geometry used both to initialise the simulation and by the
//! Rapier-independent helpers in [`crate::leg::geometry`].
//!
//! Units: SI throughout (m, kg, kg m^2, rad, N, N m). Frame conventions: z up, the person faces
//! +x, the sagittal plane is x-z and every movable joint of the loop rotates about the y axis
//! (or slides in the x-z plane).

use std::collections::HashMap;
use std::path::Path;

use super::error::LegError;
use super::planar::{Pose2, P2};

/// Gravity magnitude used everywhere in this module, m/s^2 (acts along -z).
pub const GRAVITY_M_S2: f64 = 9.81;

/// URDF joint type subset supported by the loader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// `revolute` (limited hinge).
    Revolute,
    /// `continuous` (unlimited hinge).
    Continuous,
    /// `prismatic` (slider).
    Prismatic,
    /// `fixed` (weld).
    Fixed,
}

impl JointKind {
    fn name(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
        }
    }
    fn is_hinge(self) -> bool {
        matches!(self, JointKind::Revolute | JointKind::Continuous)
    }
}

/// Mass properties of one URDF link, expressed in the link frame.
#[derive(Clone, Debug)]
pub struct LinkSpec {
    /// Link name.
    pub name: String,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass in the link frame, m.
    pub com_m: [f64; 3],
    /// Inertia tensor about the centre of mass, axes of the link frame, kg m^2.
    pub inertia_kg_m2: [[f64; 3]; 3],
}

/// One URDF joint.
#[derive(Clone, Debug)]
pub struct JointSpec {
    /// Joint name.
    pub name: String,
    /// Joint type.
    pub kind: JointKind,
    /// Index of the parent link in [`LegModel::links`].
    pub parent: usize,
    /// Index of the child link in [`LegModel::links`].
    pub child: usize,
    /// `<origin xyz>` (position of the joint frame in the parent frame), m.
    pub origin_xyz: [f64; 3],
    /// `<origin rpy>` (roll, pitch, yaw, fixed-axis XYZ as in URDF), rad.
    pub origin_rpy: [f64; 3],
    /// Unit joint axis in the joint frame.
    pub axis: [f64; 3],
    /// `(lower, upper)` limits (rad or m) when the URDF gives a non-empty range.
    pub limits: Option<(f64, f64)>,
    /// `<dynamics damping>`: N m s/rad (hinges) or N s/m (sliders). 0 if absent.
    pub damping: f64,
}

/// The `<loop_closure>` extension element.
#[derive(Clone, Debug)]
pub struct LoopClosureSpec {
    /// Element name.
    pub name: String,
    /// Index of `link1`.
    pub link1: usize,
    /// Anchor on `link1`, in `link1`'s frame, m.
    pub anchor1_m: [f64; 3],
    /// Index of `link2`.
    pub link2: usize,
    /// Anchor on `link2`, in `link2`'s frame, m.
    pub anchor2_m: [f64; 3],
}

/// The `<hydraulic_actuator>` extension element.
#[derive(Clone, Debug)]
pub struct ActuatorSpec {
    /// Element name.
    pub name: String,
    /// Index of the prismatic joint (in [`LegModel::joints`]) it drives.
    pub joint: usize,
}

/// Planar loop geometry, everything in the root (thigh) frame.
#[derive(Clone, Debug)]
pub(crate) struct LoopGeometry {
    /// Knee joint frame in the root frame (before the joint motion).
    pub knee_origin: Pose2,
    /// +1 if the knee axis is +y, -1 if -y.
    pub knee_sign: f64,
    /// Shank-side closure point in the knee-child frame.
    pub shank_point: P2,
    /// Barrel pivot joint frame in the root frame.
    pub barrel_origin: Pose2,
    /// +1 / -1 for the barrel axis.
    pub barrel_sign: f64,
    /// Rod-side closure point in the barrel frame is `u + s v` (s = prismatic coordinate).
    pub u: P2,
    /// Unit sliding direction in the barrel frame.
    pub v: P2,
    /// Prismatic limits (m).
    pub rod_limits: (f64, f64),
    /// Knee range used for the reachability check (rad).
    pub knee_range: (f64, f64),
    /// Rod-side closure point in the rod (actuator-joint child) frame.
    pub rod_point: P2,
}

/// Immutable, validated leg model: the parsed URDF plus the derived loop geometry.
///
/// Build with [`LegModel::from_urdf_file`] or [`LegModel::from_urdf_str`].
#[derive(Clone, Debug)]
pub struct LegModel {
    pub(crate) robot_name: String,
    pub(crate) links: Vec<LinkSpec>,
    pub(crate) joints: Vec<JointSpec>,
    pub(crate) root: usize,
    /// Joints in parent-before-child order.
    pub(crate) topo_joints: Vec<usize>,
    pub(crate) knee: usize,
    pub(crate) barrel: usize,
    pub(crate) rod: usize,
    pub(crate) closure: LoopClosureSpec,
    pub(crate) actuator: ActuatorSpec,
    pub(crate) geo: LoopGeometry,
}

/// Default knee range used for the stroke check when the knee joint has no limits, rad
/// (0..100 deg of flexion).
pub const DEFAULT_KNEE_RANGE_RAD: (f64, f64) = (0.0, 100.0 * std::f64::consts::PI / 180.0);

fn parse_vec3(text: &str, what: &str) -> Result<[f64; 3], LegError> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| LegError::Urdf(format!("{what}: cannot parse '{text}': {e}")))?;
    if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
        return Err(LegError::Urdf(format!("{what}: expected 3 finite numbers, got '{text}'")));
    }
    Ok([v[0], v[1], v[2]])
}

/// Rotation matrix of URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll).
pub(crate) fn rpy_matrix(rpy: [f64; 3]) -> [[f64; 3]; 3] {
    let (sr, cr) = rpy[0].sin_cos();
    let (sp, cp) = rpy[1].sin_cos();
    let (sy, cy) = rpy[2].sin_cos();
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

fn transpose(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = a[j][i];
        }
    }
    r
}

impl LegModel {
    /// Load and validate a URDF file. `knee_joint` names the knee hinge (usually `"knee"`).
    pub fn from_urdf_file(path: impl AsRef<Path>, knee_joint: &str) -> Result<Self, LegError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| LegError::Io { path: path.to_path_buf(), source })?;
        Self::from_urdf_str(&text, knee_joint)
    }

    /// Parse and validate URDF text. `knee_joint` names the knee hinge (usually `"knee"`).
    pub fn from_urdf_str(text: &str, knee_joint: &str) -> Result<Self, LegError> {
        // Pass 1: well-formedness + extension elements (urdf-rs drops unknown elements).
        let doc = roxmltree::Document::parse(text).map_err(|e| LegError::Xml(e.to_string()))?;
        let robot_el = doc.root_element();
        if robot_el.tag_name().name() != "robot" {
            return Err(LegError::Missing { what: "<robot> root element".into() });
        }
        // Pass 2: the standard URDF part.
        let robot = urdf_rs::read_from_string(text).map_err(|e| LegError::Urdf(e.to_string()))?;

        // ---- links ----
        let mut links = Vec::with_capacity(robot.links.len());
        let mut link_idx: HashMap<String, usize> = HashMap::new();
        for l in &robot.links {
            if link_idx.insert(l.name.clone(), links.len()).is_some() {
                return Err(LegError::NotATree(format!("link '{}' defined twice", l.name)));
            }
            let m = l.inertial.mass.value;
            if !(m.is_finite() && m > 0.0) {
                return Err(LegError::NonPositiveMass { link: l.name.clone(), mass: m });
            }
            let i = &l.inertial.inertia;
            let it = [[i.ixx, i.ixy, i.ixz], [i.ixy, i.iyy, i.iyz], [i.ixz, i.iyz, i.izz]];
            let minors = [
                it[0][0],
                it[0][0] * it[1][1] - it[0][1] * it[1][0],
                it[0][0] * (it[1][1] * it[2][2] - it[1][2] * it[2][1])
                    - it[0][1] * (it[1][0] * it[2][2] - it[1][2] * it[2][0])
                    + it[0][2] * (it[1][0] * it[2][1] - it[1][1] * it[2][0]),
            ];
            if !minors.iter().all(|x| x.is_finite() && *x > 0.0) {
                return Err(LegError::InertiaNotPositiveDefinite { link: l.name.clone(), minors });
            }
            let r = rpy_matrix(l.inertial.origin.rpy.0);
            let inertia = mat_mul(&mat_mul(&r, &it), &transpose(&r));
            links.push(LinkSpec {
                name: l.name.clone(),
                mass_kg: m,
                com_m: l.inertial.origin.xyz.0,
                inertia_kg_m2: inertia,
            });
        }

        // ---- joints ----
        let mut joints = Vec::with_capacity(robot.joints.len());
        let mut joint_idx: HashMap<String, usize> = HashMap::new();
        let mut parent_joint: Vec<Option<usize>> = vec![None; links.len()];
        for j in &robot.joints {
            let kind = match j.joint_type {
                urdf_rs::JointType::Revolute => JointKind::Revolute,
                urdf_rs::JointType::Continuous => JointKind::Continuous,
                urdf_rs::JointType::Prismatic => JointKind::Prismatic,
                urdf_rs::JointType::Fixed => JointKind::Fixed,
                ref other => {
                    return Err(LegError::Unsupported(format!("joint '{}' has unsupported type {other:?}", j.name)))
                }
            };
            let lookup = |n: &str, role: &str| {
                link_idx.get(n).copied().ok_or_else(|| LegError::UnknownLink {
                    element: format!("joint '{}' {role}", j.name),
                    link: n.to_string(),
                })
            };
            let parent = lookup(&j.parent.link, "parent")?;
            let child = lookup(&j.child.link, "child")?;
            if parent == child {
                return Err(LegError::NotATree(format!(
                    "joint '{}' connects link '{}' to itself",
                    j.name, j.parent.link
                )));
            }
            let id = joints.len();
            if joint_idx.insert(j.name.clone(), id).is_some() {
                return Err(LegError::NotATree(format!("joint '{}' defined twice", j.name)));
            }
            if let Some(prev) = parent_joint[child] {
                return Err(LegError::NotATree(format!(
                    "link '{}' is the child of two joints ('{}' and '{}'), which closes a kinematic loop; use <loop_closure>",
                    j.child.link, joints_name(&joints, prev), j.name
                )));
            }
            parent_joint[child] = Some(id);
            let a = j.axis.xyz.0;
            let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            if kind != JointKind::Fixed && !(n.is_finite() && n > 1e-12) {
                return Err(LegError::Urdf(format!("joint '{}' has a zero axis", j.name)));
            }
            let axis = if n > 1e-12 { [a[0] / n, a[1] / n, a[2] / n] } else { [1.0, 0.0, 0.0] };
            let limits = if matches!(kind, JointKind::Revolute | JointKind::Prismatic) && j.limit.upper > j.limit.lower
            {
                Some((j.limit.lower, j.limit.upper))
            } else {
                None
            };
            joints.push(JointSpec {
                name: j.name.clone(),
                kind,
                parent,
                child,
                origin_xyz: j.origin.xyz.0,
                origin_rpy: j.origin.rpy.0,
                axis,
                limits,
                damping: j.dynamics.as_ref().map(|d| d.damping).unwrap_or(0.0),
            });
        }

        // ---- tree check: exactly one root, everything reachable ----
        let roots: Vec<usize> = (0..links.len()).filter(|&l| parent_joint[l].is_none()).collect();
        if roots.is_empty() {
            return Err(LegError::NotATree("no root link (every link has a parent: cycle)".into()));
        }
        if roots.len() > 1 {
            let names: Vec<&str> = roots.iter().map(|&r| links[r].name.as_str()).collect();
            return Err(LegError::NotATree(format!("several root links: {}", names.join(", "))));
        }
        let root = roots[0];
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); links.len()];
        for (ji, j) in joints.iter().enumerate() {
            children[j.parent].push(ji);
        }
        let mut topo_joints = Vec::with_capacity(joints.len());
        let mut stack = vec![root];
        let mut seen = vec![false; links.len()];
        seen[root] = true;
        while let Some(l) = stack.pop() {
            for &ji in &children[l] {
                topo_joints.push(ji);
                let c = joints[ji].child;
                seen[c] = true;
                stack.push(c);
            }
        }
        if let Some(l) = (0..links.len()).find(|&l| !seen[l]) {
            return Err(LegError::NotATree(format!(
                "link '{}' is not reachable from root '{}' (kinematic cycle)",
                links[l].name, links[root].name
            )));
        }

        // ---- extension elements ----
        let find_one = |tag: &str| -> Result<roxmltree::Node, LegError> {
            let mut it = robot_el.children().filter(|n| n.is_element() && n.tag_name().name() == tag);
            let first = it.next().ok_or_else(|| LegError::Missing { what: format!("<{tag}> element") })?;
            if it.next().is_some() {
                return Err(LegError::Unsupported(format!("more than one <{tag}> element")));
            }
            Ok(first)
        };
        let attr = |n: &roxmltree::Node, a: &str, what: &str| -> Result<String, LegError> {
            n.attribute(a)
                .map(str::to_string)
                .ok_or_else(|| LegError::Missing { what: format!("attribute '{a}' of {what}") })
        };
        let lc = find_one("loop_closure")?;
        let lc_name = attr(&lc, "name", "<loop_closure>")?;
        let mut ends = Vec::new();
        for tag in ["link1", "link2"] {
            let what = format!("loop_closure '{lc_name}' {tag}");
            let el = lc
                .children()
                .find(|n| n.is_element() && n.tag_name().name() == tag)
                .ok_or_else(|| LegError::Missing { what: format!("<{tag}> of loop_closure '{lc_name}'") })?;
            let lname = attr(&el, "name", &what)?;
            let li = *link_idx
                .get(&lname)
                .ok_or_else(|| LegError::UnknownLink { element: what.clone(), link: lname.clone() })?;
            let xyz = match el.attribute("xyz") {
                Some(t) => parse_vec3(t, &format!("{what} xyz"))?,
                None => [0.0; 3],
            };
            ends.push((li, xyz));
        }
        let closure = LoopClosureSpec {
            name: lc_name.clone(),
            link1: ends[0].0,
            anchor1_m: ends[0].1,
            link2: ends[1].0,
            anchor2_m: ends[1].1,
        };
        let ha = find_one("hydraulic_actuator")?;
        let ha_name = attr(&ha, "name", "<hydraulic_actuator>")?;
        let ha_joint = attr(&ha, "joint", &format!("hydraulic_actuator '{ha_name}'"))?;
        let rod = *joint_idx.get(&ha_joint).ok_or_else(|| LegError::UnknownJoint {
            element: format!("hydraulic_actuator '{ha_name}'"),
            joint: ha_joint.clone(),
        })?;
        if joints[rod].kind != JointKind::Prismatic {
            return Err(LegError::WrongJointType {
                joint: ha_joint,
                role: format!("joint of hydraulic_actuator '{ha_name}'"),
                expected: "prismatic".into(),
                found: joints[rod].kind.name().into(),
            });
        }
        let actuator = ActuatorSpec { name: ha_name.clone(), joint: rod };

        let knee = *joint_idx.get(knee_joint).ok_or_else(|| LegError::UnknownJoint {
            element: "knee joint parameter".into(),
            joint: knee_joint.to_string(),
        })?;
        if !joints[knee].kind.is_hinge() {
            return Err(LegError::WrongJointType {
                joint: knee_joint.into(),
                role: "knee".into(),
                expected: "revolute or continuous".into(),
                found: joints[knee].kind.name().into(),
            });
        }

        // ---- planarity ----
        for j in &joints {
            let [r, _, y] = j.origin_rpy;
            if r.abs() > 1e-12 || y.abs() > 1e-12 {
                return Err(LegError::Unsupported(format!(
                    "joint '{}' origin rpy has roll/yaw; only pitch (about y) is supported in the sagittal model",
                    j.name
                )));
            }
            match j.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    if j.axis[0].abs() > 1e-9 || j.axis[2].abs() > 1e-9 {
                        return Err(LegError::Unsupported(format!("joint '{}' axis must be +-y", j.name)));
                    }
                }
                JointKind::Prismatic => {
                    if j.axis[1].abs() > 1e-9 {
                        return Err(LegError::Unsupported(format!(
                            "joint '{}' axis must lie in the x-z plane",
                            j.name
                        )));
                    }
                }
                JointKind::Fixed => {}
            }
        }

        // ---- loop topology ----
        let barrel_link = joints[rod].parent;
        let barrel = parent_joint[barrel_link].ok_or_else(|| {
            LegError::Unsupported(format!(
                "actuator joint '{}' parent link '{}' must hang from a barrel pivot hinge",
                joints[rod].name, links[barrel_link].name
            ))
        })?;
        if !joints[barrel].kind.is_hinge() {
            return Err(LegError::WrongJointType {
                joint: joints[barrel].name.clone(),
                role: format!("barrel pivot of actuator '{ha_name}'"),
                expected: "revolute or continuous".into(),
                found: joints[barrel].kind.name().into(),
            });
        }
        for (ji, j) in joints.iter().enumerate() {
            if j.kind != JointKind::Fixed && ji != knee && ji != barrel && ji != rod {
                return Err(LegError::Unsupported(format!(
                    "movable joint '{}' is neither the knee, the barrel pivot nor the actuator",
                    j.name
                )));
            }
        }
        // Walk up fixed joints: (ancestor, planar pose of `l` in ancestor, y offset).
        let rigid_anchor = |mut l: usize| -> (usize, Pose2, f64) {
            let mut pose = Pose2::IDENTITY;
            let mut y = 0.0;
            while let Some(ji) = parent_joint[l] {
                let j = &joints[ji];
                if j.kind != JointKind::Fixed {
                    break;
                }
                pose = joint_origin(j).mul(&pose);
                y += j.origin_xyz[1];
                l = j.parent;
            }
            (l, pose, y)
        };
        let (kb, fk, yk) = rigid_anchor(joints[knee].parent);
        let (bb, fb, yb) = rigid_anchor(joints[barrel].parent);
        if kb != root || bb != root {
            return Err(LegError::Unsupported(format!(
                "knee '{}' and barrel pivot '{}' must both be attached (directly or via fixed joints) to the root link '{}'",
                joints[knee].name, joints[barrel].name, links[root].name
            )));
        }
        let shank = joints[knee].child;
        let rod_link = joints[rod].child;
        let a1 = rigid_anchor(closure.link1);
        let a2 = rigid_anchor(closure.link2);
        let p1 = P2::new(closure.anchor1_m[0], closure.anchor1_m[2]);
        let p2 = P2::new(closure.anchor2_m[0], closure.anchor2_m[2]);
        let (rod_side, rod_p, rod_y, shank_side, shank_p, shank_y) = if a1.0 == rod_link && a2.0 == shank {
            (a1, p1, closure.anchor1_m[1], a2, p2, closure.anchor2_m[1])
        } else if a2.0 == rod_link && a1.0 == shank {
            (a2, p2, closure.anchor2_m[1], a1, p1, closure.anchor1_m[1])
        } else {
            return Err(LegError::Unsupported(format!(
                "loop_closure '{}' must join the actuator rod '{}' and the knee child '{}' (or links welded to them)",
                closure.name, links[rod_link].name, links[shank].name
            )));
        };
        let rod_point = rod_side.1.apply(rod_p);
        let shank_point = shank_side.1.apply(shank_p);
        let ko = joint_origin(&joints[knee]);
        let bo = joint_origin(&joints[barrel]);
        let ro = joint_origin(&joints[rod]);
        let ra = joints[rod].axis;
        let y_rod = yb + joints[barrel].origin_xyz[1] + joints[rod].origin_xyz[1] + rod_side.2 + rod_y;
        let y_shank = yk + joints[knee].origin_xyz[1] + shank_side.2 + shank_y;
        if (y_rod - y_shank).abs() > 1e-9 {
            return Err(LegError::Unsupported(format!(
                "loop_closure '{}' anchors lie at different y ({y_rod} vs {y_shank} m)",
                closure.name
            )));
        }
        let rod_limits = joints[rod].limits.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        let knee_range = joints[knee].limits.unwrap_or(DEFAULT_KNEE_RANGE_RAD);
        let geo = LoopGeometry {
            knee_origin: fk.mul(&ko),
            knee_sign: joints[knee].axis[1].signum(),
            shank_point,
            barrel_origin: fb.mul(&bo),
            barrel_sign: joints[barrel].axis[1].signum(),
            u: ro.apply(rod_point),
            v: P2::new(ra[0], ra[2]).rot(ro.a),
            rod_limits,
            knee_range,
            rod_point,
        };
        let model = LegModel {
            robot_name: robot.name.clone(),
            links,
            joints,
            root,
            topo_joints,
            knee,
            barrel,
            rod,
            closure,
            actuator,
            geo,
        };
        // ---- reachability over the knee range ----
        let n = 200;
        for k in 0..=n {
            let th = knee_range.0 + (knee_range.1 - knee_range.0) * k as f64 / n as f64;
            model.loop_solution_checked(th)?;
        }
        Ok(model)
    }

    /// Robot name from the URDF.
    pub fn robot_name(&self) -> &str {
        &self.robot_name
    }
    /// All links (index = link id used by the other accessors).
    pub fn links(&self) -> &[LinkSpec] {
        &self.links
    }
    /// All joints.
    pub fn joints(&self) -> &[JointSpec] {
        &self.joints
    }
    /// Root link index (the thigh).
    pub fn root_link(&self) -> usize {
        self.root
    }
    /// Knee joint.
    pub fn knee_joint(&self) -> &JointSpec {
        &self.joints[self.knee]
    }
    /// Barrel pivot joint (hinge of the cylinder barrel on the thigh).
    pub fn barrel_joint(&self) -> &JointSpec {
        &self.joints[self.barrel]
    }
    /// Actuator (prismatic) joint.
    pub fn rod_joint(&self) -> &JointSpec {
        &self.joints[self.rod]
    }
    /// The loop closure element.
    pub fn loop_closure(&self) -> &LoopClosureSpec {
        &self.closure
    }
    /// The hydraulic actuator element.
    pub fn actuator(&self) -> &ActuatorSpec {
        &self.actuator
    }
    /// Index of a link by name.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.links.iter().position(|l| l.name == name)
    }
    /// Knee centre in the thigh (root) frame, (x, z) in m.
    pub fn knee_center_m(&self) -> (f64, f64) {
        (self.geo.knee_origin.t.x, self.geo.knee_origin.t.z)
    }
    /// Barrel pivot in the thigh (root) frame, (x, z) in m.
    pub fn barrel_pivot_m(&self) -> (f64, f64) {
        (self.geo.barrel_origin.t.x, self.geo.barrel_origin.t.z)
    }
    /// Rod-end (shank-side closure) point in the knee-child (shank) frame, (x, z) in m.
    pub fn rod_end_in_shank_m(&self) -> (f64, f64) {
        (self.geo.shank_point.x, self.geo.shank_point.z)
    }
    /// Rod-side closure point in the rod (actuator-joint child) frame, (x, z) in m.
    pub fn rod_end_in_rod_m(&self) -> (f64, f64) {
        (self.geo.rod_point.x, self.geo.rod_point.z)
    }
    /// Knee range used for validation, rad (URDF limits, or 0..100 deg if none).
    pub fn knee_range_rad(&self) -> (f64, f64) {
        self.geo.knee_range
    }
    /// Prismatic (rod extension) limits, m.
    pub fn rod_limits_m(&self) -> (f64, f64) {
        self.geo.rod_limits
    }

    /// Solves the loop at a knee angle without checking the prismatic limits.
    pub(crate) fn loop_solution(&self, knee_rad: f64) -> Option<LoopPose> {
        let g = &self.geo;
        let d = g.knee_origin.mul(&Pose2::rot(g.knee_sign * knee_rad)).apply(g.shank_point);
        let e = d.minus(g.barrel_origin.t);
        let rho = e.norm();
        let uv = g.u.dot(g.v);
        let disc = uv * uv - g.u.dot(g.u) + rho * rho;
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let s = -uv + disc.sqrt();
        let c = g.u.plus(g.v.scale(s));
        if c.norm() < 1e-12 || rho < 1e-12 {
            return None;
        }
        let total = e.polar() - c.polar();
        let phi = wrap_pi(g.barrel_sign * (total - g.barrel_origin.a));
        Some(LoopPose { knee_rad, barrel_rad: phi, rod_m: s, cylinder_length_m: rho })
    }

    /// Loop solution with the prismatic-limit check, as an error naming the actuator.
    pub(crate) fn loop_solution_checked(&self, knee_rad: f64) -> Result<LoopPose, LegError> {
        let sol = self.loop_solution(knee_rad).ok_or_else(|| LegError::Unreachable {
            actuator: self.actuator.name.clone(),
            knee_rad,
            reason: "the rod cannot reach the shank mounting point".into(),
        })?;
        let (lo, hi) = self.geo.rod_limits;
        if sol.rod_m < lo - 1e-9 || sol.rod_m > hi + 1e-9 {
            return Err(LegError::Unreachable {
                actuator: self.actuator.name.clone(),
                knee_rad,
                reason: format!(
                    "required rod extension {:.4} m is outside joint '{}' limits [{lo}, {hi}] m",
                    sol.rod_m, self.joints[self.rod].name
                ),
            });
        }
        Ok(sol)
    }

    /// Joint coordinates of all joints (knee, barrel, rod from the loop; fixed = 0).
    pub(crate) fn joint_coords(&self, sol: &LoopPose) -> Vec<f64> {
        let mut q = vec![0.0; self.joints.len()];
        q[self.knee] = sol.knee_rad;
        q[self.barrel] = sol.barrel_rad;
        q[self.rod] = sol.rod_m;
        q
    }

    /// Planar poses of all links in the root frame for the given joint coordinates.
    pub(crate) fn link_poses(&self, q: &[f64]) -> Vec<Pose2> {
        let mut poses = vec![Pose2::IDENTITY; self.links.len()];
        for &ji in &self.topo_joints {
            let j = &self.joints[ji];
            let motion = match j.kind {
                JointKind::Revolute | JointKind::Continuous => Pose2::rot(j.axis[1].signum() * q[ji]),
                JointKind::Prismatic => Pose2::trans(P2::new(j.axis[0] * q[ji], j.axis[2] * q[ji])),
                JointKind::Fixed => Pose2::IDENTITY,
            };
            poses[j.child] = poses[j.parent].mul(&joint_origin(j)).mul(&motion);
        }
        poses
    }
}

fn joints_name(joints: &[JointSpec], i: usize) -> &str {
    &joints[i].name
}

/// Planar pose of a joint's `<origin>` (pitch only).
pub(crate) fn joint_origin(j: &JointSpec) -> Pose2 {
    Pose2::new(j.origin_xyz[0], j.origin_xyz[2], j.origin_rpy[1])
}

fn wrap_pi(a: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let mut r = a % two_pi;
    if r > std::f64::consts::PI {
        r -= two_pi;
    } else if r <= -std::f64::consts::PI {
        r += two_pi;
    }
    r
}

/// Configuration of the closed loop for one knee angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopPose {
    /// Knee flexion, rad (positive = flexion, shank swings backward).
    pub knee_rad: f64,
    /// Barrel pivot joint coordinate, rad.
    pub barrel_rad: f64,
    /// Prismatic (rod slide) coordinate, m.
    pub rod_m: f64,
    /// Pin-to-pin cylinder length (barrel pivot to rod end), m.
    pub cylinder_length_m: f64,
}
