//! Immutable leg model: links, joints, the loop-closure and actuator elements, and the planar
//! loop geometry used both to initialise the simulation and by the Rapier-independent helpers
//! in [`crate::leg::geometry`]. Built from URDF by [`crate::leg::urdf`], kept apart from it.
//!
//! Units: SI throughout (m, kg, kg m^2, rad, N, N m). Frame conventions: z up, the person faces
//! +x, the sagittal plane is x-z and every movable joint of the loop rotates about the y axis
//! (or slides in the x-z plane).

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
    pub(crate) fn name(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
        }
    }
    pub(crate) fn is_hinge(self) -> bool {
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
    /// Index of the parent link in [`LegSpec::links`].
    pub parent: usize,
    /// Index of the child link in [`LegSpec::links`].
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
    /// Index of the prismatic joint (in [`LegSpec::joints`]) it drives.
    pub joint: usize,
}

/// Planar loop geometry, everything in the root (thigh) frame.
#[derive(Clone, Debug, Default)]
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
    /// The knee-independent parts of the cylinder's triangle (see [`KneeTriangle`]).
    pub triangle: KneeTriangle,
}

/// The triangle knee - barrel pivot - rod end: two fixed sides and the angle between them,
/// which turns with the knee. Its knee-independent parts are computed once per leg.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct KneeTriangle {
    /// Knee to barrel pivot (m).
    pub a_m: f64,
    /// Knee to rod end (m).
    pub b_m: f64,
    /// Polar angle of knee -> rod end at zero knee angle (rad).
    pub rod_end_polar_rad: f64,
    /// Polar angle of knee -> barrel pivot (rad).
    pub pivot_polar_rad: f64,
}

impl KneeTriangle {
    /// The triangle of a knee frame, shank-side point and barrel frame.
    pub fn new(knee_origin: &Pose2, shank_point: P2, barrel_origin: &Pose2) -> Self {
        let pk = barrel_origin.t.minus(knee_origin.t); // knee -> pivot
        let w0 = shank_point.rot(knee_origin.a); // knee -> rod end at theta = 0
        Self { a_m: pk.norm(), b_m: shank_point.norm(), rod_end_polar_rad: w0.polar(), pivot_polar_rad: pk.polar() }
    }
}

/// How the loader treats the leg's joints.
#[derive(Clone, Debug, PartialEq)]
pub struct LegOptions {
    /// Name of the knee hinge. Default `knee`.
    pub knee_joint: String,
    /// Name of the ankle hinge (between the shank and the foot). Default `ankle`.
    pub ankle_joint: String,
    /// The ankle moves (ground contact); otherwise it is locked at 0 (treated as fixed).
    pub ankle_free: bool,
    /// Every link's mass and inertia scaled by this factor (> 0). Default 1.
    pub mass_scale: f64,
}

impl Default for LegOptions {
    fn default() -> Self {
        Self { knee_joint: "knee".into(), ankle_joint: "ankle".into(), ankle_free: false, mass_scale: 1.0 }
    }
}

/// A collision shape of a link (`<collision>`), in the link frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionSpec {
    /// Index of the link.
    pub link: usize,
    /// `<origin xyz>` (m).
    pub origin_xyz: [f64; 3],
    /// `<origin rpy>` (rad).
    pub origin_rpy: [f64; 3],
    /// The geometry.
    pub shape: CollisionShape,
}

/// Collision geometry (URDF `<geometry>`), sizes in m.
#[derive(Clone, Debug, PartialEq)]
pub enum CollisionShape {
    /// Box with full edge lengths.
    Box {
        /// Edge lengths x, y, z (m).
        size: [f64; 3],
    },
    /// Cylinder along the local z axis.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length (m).
        length: f64,
    },
    /// Sphere.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// Capsule along the local z axis (cylinder `length` with hemispherical ends).
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Length of the cylindrical part (m).
        length: f64,
    },
    /// A mesh file: not supported for contact (refused when the ground is on).
    Mesh {
        /// The file named.
        filename: String,
    },
}

/// Immutable, validated leg model: the parsed URDF plus the derived loop geometry.
///
/// Build with [`LegSpec::from_urdf_file`] or [`LegSpec::from_urdf_str`].
#[derive(Clone, Debug)]
pub struct LegSpec {
    pub(crate) robot_name: String,
    pub(crate) links: Vec<LinkSpec>,
    pub(crate) joints: Vec<JointSpec>,
    pub(crate) root: usize,
    /// Joints in parent-before-child order.
    pub(crate) topo_joints: Vec<usize>,
    /// The joint whose child each link is (None for the root).
    pub(crate) parent_joint: Vec<Option<usize>>,
    pub(crate) knee: usize,
    pub(crate) barrel: usize,
    pub(crate) rod: usize,
    pub(crate) closure: LoopClosureSpec,
    pub(crate) actuator: ActuatorSpec,
    pub(crate) geo: LoopGeometry,
    /// The ankle joint when it moves.
    pub(crate) ankle: Option<usize>,
    pub(crate) collisions: Vec<CollisionSpec>,
}

/// Default knee range used for the stroke check when the knee joint has no limits, rad
/// (0..100 deg of flexion).
pub const DEFAULT_KNEE_RANGE_RAD: (f64, f64) = (0.0, 100.0 * std::f64::consts::PI / 180.0);

impl LegSpec {
    /// The ankle joint, when it moves (`leg.ankle = "free"`).
    pub fn ankle_joint(&self) -> Option<&JointSpec> {
        self.ankle.map(|j| &self.joints[j])
    }

    /// The foot's link: the ankle's child, or the shank when the leg has no ankle.
    pub fn foot_link(&self) -> usize {
        self.ankle_joint().map_or(self.knee_joint().child, |a| a.child)
    }

    /// Where the device's sensors sit by default on this leg: the IMUs 6 cm in front of the
    /// thigh's and the shank's axis, 40 % and 35 % of the way down the segment (the knee's
    /// origin in the thigh frame, the ankle's in the shank frame; 0.4 m for a shank without
    /// an ankle), and the heel and forefoot sensors at the rearmost and foremost contact
    /// points of the foot link's collision shapes (x in the foot frame; -0.03 and 0.15 m
    /// without any).
    pub fn device_defaults(&self) -> crate::sensors::DeviceDefaults {
        let len = |o: [f64; 3]| o[0].hypot(o[2]);
        let thigh = len(self.knee_joint().origin_xyz);
        let shank = self.ankle_joint().map_or(0.4, |a| len(a.origin_xyz));
        let foot = self.foot_link();
        let xs: Vec<f64> = self
            .collisions
            .iter()
            .filter(|c| c.link == foot)
            .flat_map(|c| {
                let half = match &c.shape {
                    CollisionShape::Box { size } => size[0] / 2.0,
                    CollisionShape::Cylinder { radius, .. } => *radius,
                    _ => 0.0,
                };
                [c.origin_xyz[0] - half, c.origin_xyz[0] + half]
            })
            .collect();
        let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let foot_x_m = if hi > lo { (lo, hi) } else { (-0.03, 0.15) };
        crate::sensors::DeviceDefaults { imu_xyz_m: [[0.06, 0.0, -0.4 * thigh], [0.06, 0.0, -0.35 * shank]], foot_x_m }
    }

    /// The collision shapes of every link (used with ground contact).
    pub fn collisions(&self) -> &[CollisionSpec] {
        &self.collisions
    }

    /// Total mass of the links that are not the cylinder (thigh, shank, foot and what is
    /// welded to them), kg: the leg the wearer brings.
    pub fn leg_mass_kg(&self) -> f64 {
        let cylinder = [self.joints[self.barrel].child, self.joints[self.rod].child];
        self.links
            .iter()
            .enumerate()
            .filter(|(i, _)| !cylinder.contains(&self.fixed_chain(*i).0))
            .map(|(_, l)| l.mass_kg)
            .sum()
    }

    /// The fixed-joint walk: from `link` up through fixed joints to the first link that moves
    /// on its own (or the root). Returns that ancestor and the fixed joints crossed, nearest
    /// first. Every consumer composes the joints' origins in its own representation (planar
    /// loop geometry, Rapier poses, cuff points, mass merging).
    pub fn fixed_chain(&self, mut link: usize) -> (usize, Vec<usize>) {
        let mut chain = Vec::new();
        while let Some(ji) = self.parent_joint[link] {
            if self.joints[ji].kind != JointKind::Fixed {
                break;
            }
            chain.push(ji);
            link = self.joints[ji].parent;
        }
        (link, chain)
    }

    /// Index of the joint whose child is `link` (None for the root).
    pub fn parent_joint(&self, link: usize) -> Option<usize> {
        self.parent_joint[link]
    }

    /// The thigh's and the shank's sagittal lengths (m): the knee joint's origin in the thigh's
    /// frame and the ankle joint's in the shank's (0 without an ankle).
    pub fn thigh_shank_lengths_m(&self) -> (f64, f64) {
        let sagittal = |j: &JointSpec| j.origin_xyz[0].hypot(j.origin_xyz[2]);
        let knee = self.knee_joint();
        (sagittal(knee), self.ankle_joint().map_or(0.0, sagittal))
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
