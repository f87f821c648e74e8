//! Rapier (f64) simulation of the leg + cylinder closed loop.
//!
//! Structure: one reduced-coordinate multibody tree (thigh = fixed root; knee, barrel pivot and
//! rod slide as multibody joints, fixed joints welded in) plus one impulse joint (a pin in the sagittal plane) that
//! closes the loop at the rod end. No colliders: mass properties come from the URDF `<inertial>`
//! only. Gravity is -9.81 m/s^2 along z.
//!
//! Driven hip ([`Leg::with_hip`]): a massless fixed "pelvis" body at the world origin becomes the
//! multibody root and the (now dynamic) thigh hangs on a *kinematic* revolute multibody joint
//! about -y (coordinate = hip flexion, rad). Rapier integrates the user-set joint velocity
//! exactly and includes its centrifugal/Coriolis effects, but drops the kinematic DoF from the
//! augmented mass, so the hip *acceleration* never reaches the free joints; [`Leg::step`] adds it
//! back as d'Alembert wrenches ([`HipCoupling::InertialCompensation`]).

use rapier3d_f64::glamx::{DQuat, DVec3};
use rapier3d_f64::math::Pose;
use rapier3d_f64::prelude::{ImpulseJointHandle, MultibodyIndex, PhysicsWorld, RigidBodyHandle};

use crate::leg::ground::{Belt, ContactReading};
use crate::leg::model::{JointKind, LegSpec};

/// Solver settings of [`Leg`].
#[derive(Clone, Copy, Debug)]
pub struct LegSolverParams {
    /// Rapier `num_solver_iterations` (default 2).
    pub solver_iterations: usize,
    /// Rapier `num_internal_pgs_iterations` (default 1).
    pub pgs_iterations: usize,
}

impl Default for LegSolverParams {
    fn default() -> Self {
        Self { solver_iterations: 2, pgs_iterations: 1 }
    }
}

/// How a driven hip (see [`Leg::with_hip`]) passes its acceleration on to the free joints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HipCoupling {
    /// Rapier's kinematic multibody joint alone. Rapier removes the kinematic DoF from the
    /// augmented mass and never sees its acceleration, so the inertial coupling `M_hk thdd_h` is
    /// lost (a velocity change of the hip does not change the relative knee velocity).
    /// Centrifugal / Coriolis terms of the hip velocity are included. For diagnostics.
    RapierOnly,
    /// Rapier's kinematic joint plus the d'Alembert wrench of the hip acceleration applied to
    /// every moving body: `f_i = -m_i (alpha x c_i)` at its CoM and `t_i = -I_i alpha` (world),
    /// `alpha = thdd_h` about the hip axis, so that `J_free^T w = -M_free,hip thdd_h` exactly.
    /// `thdd_h` is the change of the commanded hip velocity divided by dt.
    #[default]
    InertialCompensation,
}

/// State of the kinematic hip joint.
#[derive(Clone, Copy, Debug)]
struct HipState {
    /// Multibody link id of the thigh (child of the hip joint).
    link: usize,
    /// The joint is kinematic (driven); otherwise dynamic (carriage).
    kinematic: bool,
    /// Generalized velocity applied in the previous step, rad/s.
    vel: f64,
    /// Hip acceleration to compensate in the next step, rad/s^2.
    accel: f64,
    coupling: HipCoupling,
}

/// A running simulation of a [`LegSpec`]. Owns all Rapier sets and the pipeline.
pub struct Leg {
    model: LegSpec,
    world: PhysicsWorld,
    /// Rapier body carrying each URDF link (same indexing as `LegSpec::links`). Links welded
    /// by fixed joints share their parent's body.
    link_body: Vec<RigidBodyHandle>,
    /// Pose of each URDF link in the frame of its Rapier body (identity unless welded).
    link_offset: Vec<Pose>,
    /// Distinct Rapier bodies.
    bodies: Vec<RigidBodyHandle>,
    mb: MultibodyIndex,
    knee_link: usize,
    rod_link: usize,
    barrel_link: usize,
    closure: ImpulseJointHandle,
    anchor1: DVec3,
    anchor2: DVec3,
    rod_anchor_is_1: bool,
    time: f64,
    last_dl: f64,
    last_dknee: f64,
    /// `Some` when the thigh hangs on a hip joint: kinematic (see [`Leg::with_hip`]) or, on
    /// the carriage, dynamic.
    hip: Option<HipState>,
    /// The pelvis on its carriage (see [`Leg::with_config`]).
    carriage: Option<CarriageState>,
    /// Multibody link id of the foot when the ankle moves.
    ankle_link: Option<usize>,
    /// The ground collider and the belt.
    ground: Option<Belt>,
    /// What the ground did over the last step.
    contact: ContactReading,
    /// Momenta of the shank and foot at the end of the last step, for the gait-lab knee moment.
    lab: Option<SegmentMomenta>,
    /// The gait-lab knee moment over the last step (N m, extensor positive).
    lab_knee_moment_nm: f64,
    /// The cylinder's pins where the bodies are now.
    pins: Pins,
}

/// World positions (m) of the cylinder's pins, computed once whenever the bodies move.
#[derive(Clone, Copy, Debug, Default)]
struct Pins {
    /// The rod-side closure anchor.
    rod_end: DVec3,
    /// The other closure anchor (on the shank side).
    other_anchor: DVec3,
    /// The barrel's pivot on the thigh.
    barrel_pivot: DVec3,
}

/// Linear momentum (kg m/s) and angular momentum about the world origin (kg m^2/s) of the
/// shank and foot, with their mass (kg) and the moment of their weight about the origin (N m).
#[derive(Clone, Copy, Debug)]
struct SegmentMomenta {
    p: DVec3,
    h: DVec3,
    mass_kg: f64,
    weight_moment: DVec3,
}

/// How the thigh is held.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mount {
    /// Welded to the world at the hip.
    Fixed,
    /// On a kinematic hip joint at the world origin (see [`Leg::with_hip`]).
    Driven {
        /// Initial hip flexion (rad).
        hip_rad: f64,
        /// Initial hip velocity (rad/s).
        hip_vel_rad_s: f64,
    },
    /// On a dynamic hip joint of a pelvis that moves in the sagittal plane.
    Carriage(CarriageConfig),
}

impl Mount {
    /// The thigh's initial pose when it is not welded at the origin (None: welded).
    fn root_pose(&self) -> Option<Pose> {
        match *self {
            Mount::Fixed => None,
            Mount::Driven { hip_rad, .. } => Some(Pose::from_rotation(DQuat::from_axis_angle(-DVec3::Y, hip_rad))),
            Mount::Carriage(c) => Some(Pose::from_parts(
                DVec3::new(0.0, 0.0, c.pelvis_height_m),
                DQuat::from_axis_angle(-DVec3::Y, c.hip_rad),
            )),
        }
    }

    /// The hip's initial angle and rate when the hip moves.
    fn hip_init(&self) -> Option<(f64, f64)> {
        match *self {
            Mount::Fixed => None,
            Mount::Driven { hip_rad, hip_vel_rad_s } => Some((hip_rad, hip_vel_rad_s)),
            Mount::Carriage(c) => (!c.hip_locked).then_some((c.hip_rad, 0.0)),
        }
    }
}

/// The pelvis carriage: a body free in x and z (rotation locked) that carries the thigh on a
/// dynamic hip hinge about -y.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarriageConfig {
    /// Pelvis mass (kg): the body the leg carries.
    pub pelvis_mass_kg: f64,
    /// Initial hip flexion (rad).
    pub hip_rad: f64,
    /// Initial height of the hip centre (m, world z).
    pub pelvis_height_m: f64,
    /// The pelvis cannot move in x (static tests).
    pub tether_locked: bool,
    /// The hip joint is locked at `hip_rad` (static tests).
    pub hip_locked: bool,
    /// Initial ankle dorsiflexion (rad), when the ankle moves.
    pub ankle_rad: f64,
}

/// Everything that acts on the leg over one step besides gravity and the ground.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LegForces {
    /// Cylinder force (N, positive lengthens).
    pub actuator_force_n: f64,
    /// An external force on the shank: (point in the shank frame (m), force in world (N)).
    pub shank_force: Option<([f64; 3], [f64; 3])>,
    /// Torque across the hip (N m, flexion positive), carriage only.
    pub hip_torque_nm: f64,
    /// Torque across the knee (N m, flexion positive), e.g. the wearer's muscles.
    pub knee_torque_nm: f64,
    /// Torque across the ankle (N m, in its coordinate's direction: dorsiflexion positive).
    pub ankle_torque_nm: f64,
    /// Force on the pelvis (N, world x and z), carriage only.
    pub pelvis_force_n: [f64; 2],
}

#[derive(Clone, Copy, Debug)]
struct CarriageState {
    pelvis: RigidBodyHandle,
    hip_locked_rad: Option<f64>,
}

fn inertia_times(i: &[[f64; 3]; 3], w: DVec3) -> DVec3 {
    DVec3::new(
        i[0][0] * w.x + i[0][1] * w.y + i[0][2] * w.z,
        i[1][0] * w.x + i[1][1] * w.y + i[1][2] * w.z,
        i[2][0] * w.x + i[2][1] * w.y + i[2][2] * w.z,
    )
}

/// Index of the single free coordinate in `MultibodyJoint::coords()` (LinX = 0, AngX = 3).
fn coord_index(kind: JointKind) -> usize {
    match kind {
        JointKind::Prismatic => 0,
        _ => 3,
    }
}

mod build;
mod lab;
mod step;

impl Leg {
    /// The model this simulation was built from.
    pub fn model(&self) -> &LegSpec {
        &self.model
    }
    /// Simulated time since construction, s.
    pub fn time_s(&self) -> f64 {
        self.time
    }
    /// Time step, s: Rapier's integration parameter, the one place it is held.
    pub fn dt_s(&self) -> f64 {
        self.world.integration_parameters.dt
    }

    fn multibody(&self) -> &rapier3d_f64::prelude::Multibody {
        self.world.multibody_joints.get_multibody(self.mb).unwrap()
    }

    fn coord(&self, link: usize, kind: JointKind) -> f64 {
        self.multibody().link(link).unwrap().joint().coords()[coord_index(kind)]
    }

    fn gen_vel(&self, link: usize) -> f64 {
        let mb = self.multibody();
        mb.joint_velocity(mb.link(link).unwrap())[0]
    }

    /// Whether the hip is driven (built with [`Leg::with_hip`]).
    pub fn has_hip(&self) -> bool {
        self.hip.is_some() || self.carriage.is_some()
    }

    /// Hip flexion angle (kinematic joint coordinate), rad; 0 for a fixed thigh.
    pub fn hip_angle_rad(&self) -> f64 {
        if let Some(h) = self.carriage.and_then(|c| c.hip_locked_rad) {
            return h;
        }
        self.hip.map_or(0.0, |h| self.coord(h.link, JointKind::Revolute))
    }

    /// Hip flexion velocity (the kinematic joint velocity used in the last / next step), rad/s;
    /// 0 for a fixed thigh.
    pub fn hip_velocity_rad_s(&self) -> f64 {
        self.hip.map_or(0.0, |h| self.gen_vel(h.link))
    }

    /// Knee flexion angle (multibody coordinate), rad.
    pub fn knee_angle_rad(&self) -> f64 {
        self.coord(self.knee_link, self.model.joints[self.model.knee].kind)
    }
    /// Knee angular velocity (multibody generalized velocity after the last step), rad/s.
    pub fn knee_velocity_rad_s(&self) -> f64 {
        self.gen_vel(self.knee_link)
    }
    /// Change of the knee angle over the last step divided by dt, rad/s (geometric velocity).
    pub fn knee_velocity_geometric_rad_s(&self) -> f64 {
        self.last_dknee / self.dt_s()
    }
    /// Barrel pivot joint angle, rad.
    pub fn barrel_angle_rad(&self) -> f64 {
        self.coord(self.barrel_link, self.model.joints[self.model.barrel].kind)
    }
    /// Prismatic (rod slide) coordinate, m.
    pub fn rod_extension_m(&self) -> f64 {
        self.coord(self.rod_link, JointKind::Prismatic)
    }

    fn world_point(&self, link: usize, local: DVec3) -> DVec3 {
        self.world.bodies[self.link_body[link]].position() * (self.link_offset[link] * local)
    }

    /// The pins' world positions from the bodies' poses.
    fn pins_now(&self) -> Pins {
        let c = &self.model.closure;
        let (p1, p2) = (self.world_point(c.link1, self.anchor1), self.world_point(c.link2, self.anchor2));
        let (rod_end, other_anchor) = if self.rod_anchor_is_1 { (p1, p2) } else { (p2, p1) };
        let barrel_pivot = self.world_point(self.model.joints[self.model.barrel].child, DVec3::ZERO);
        Pins { rod_end, other_anchor, barrel_pivot }
    }

    /// Measured pin-to-pin cylinder length (barrel pivot to the rod-side closure anchor), m.
    pub fn cylinder_length_m(&self) -> f64 {
        (self.pins.rod_end - self.pins.barrel_pivot).length()
    }
    /// Cylinder length change over the last step divided by dt, m/s (geometric, so it is
    /// consistent with the positions after the constraint solver's corrections).
    pub fn cylinder_velocity_m_s(&self) -> f64 {
        self.last_dl / self.dt_s()
    }
    /// Cylinder length change over the last step, m.
    pub fn cylinder_length_change_m(&self) -> f64 {
        self.last_dl
    }
    /// Distance between the two loop-closure anchor points in world, m.
    pub fn loop_gap_m(&self) -> f64 {
        let p = &self.pins;
        let (p1, p2) = if self.rod_anchor_is_1 { (p.rod_end, p.other_anchor) } else { (p.other_anchor, p.rod_end) };
        (p1 - p2).length()
    }

    /// World pose of a link (by index into `LegSpec::links`).
    pub fn link_pose(&self, link: usize) -> Pose {
        *self.world.bodies[self.link_body[link]].position() * self.link_offset[link]
    }

    /// What the ground did over the last step (zero without ground).
    pub fn contact(&self) -> ContactReading {
        self.contact
    }

    /// Ankle angle (rad, in its coordinate's direction) when the ankle moves, else 0.
    pub fn ankle_angle_rad(&self) -> f64 {
        self.ankle_link.map_or(0.0, |l| self.coord(l, JointKind::Revolute))
    }

    /// Ankle rate (rad/s) when the ankle moves, else 0.
    pub fn ankle_velocity_rad_s(&self) -> f64 {
        self.ankle_link.map_or(0.0, |l| self.gen_vel(l))
    }

    /// The pelvis (hip centre) position (world x, z in m) and velocity (m/s); the origin at
    /// rest without a carriage.
    pub fn pelvis_state(&self) -> ([f64; 2], [f64; 2]) {
        match self.carriage {
            None => ([0.0; 2], [0.0; 2]),
            Some(c) => {
                let rb = &self.world.bodies[c.pelvis];
                let (p, v) = (rb.translation(), rb.linvel());
                ([p.x, p.z], [v.x, v.z])
            }
        }
    }

    /// Handle of the loop-closure impulse joint (the in-plane pin at the rod end).
    pub fn closure_joint(&self) -> ImpulseJointHandle {
        self.closure
    }

    /// Access to the underlying Rapier world (read-only), for diagnostics.
    pub fn rapier_world(&self) -> &PhysicsWorld {
        &self.world
    }
}
