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

use rapier3d_f64::glamx::{DQuat, DVec3, EulerRot};
pub use rapier3d_f64::math::Pose;
use rapier3d_f64::math::Vector;
use rapier3d_f64::prelude::{
    GenericJoint, GenericJointBuilder, ImpulseJointHandle, IntegrationParameters, JointAxesMask, JointAxis,
    MassProperties, Multibody, MultibodyIndex, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, SpringCoefficients,
};

use super::error::LegError;
use super::ground::{insert_ground, read_contacts, Belt, ContactReading, GroundConfig};
use super::model::{JointKind, JointSpec, LegSpec, GRAVITY_M_S2};

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
    dt: f64,
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

/// The pose of an URDF `<origin xyz rpy>`.
pub fn pose_of(xyz: [f64; 3], rpy: [f64; 3]) -> Pose {
    pose3(xyz, rpy)
}

fn pose3(xyz: [f64; 3], rpy: [f64; 3]) -> Pose {
    Pose::from_parts(DVec3::from(xyz), DQuat::from_euler(EulerRot::ZYX, rpy[2], rpy[1], rpy[0]))
}

/// The pose of a joint's `<origin>` (child joint frame in the parent link's frame).
pub fn joint_origin_pose(j: &JointSpec) -> Pose {
    pose3(j.origin_xyz, j.origin_rpy)
}

/// URDF joint -> Rapier generic joint. The Rapier joint frame's X axis is aligned with the URDF
/// axis, so the Rapier coordinate equals the URDF coordinate (same sign).
fn to_generic(j: &JointSpec, with_limits: bool) -> GenericJoint {
    let origin = pose3(j.origin_xyz, j.origin_rpy);
    let axis = DVec3::from(j.axis);
    let align = Pose::from_rotation(DQuat::from_rotation_arc(DVec3::X, axis));
    let (mask, free_axis) = match j.kind {
        JointKind::Revolute | JointKind::Continuous => (JointAxesMask::LOCKED_REVOLUTE_AXES, JointAxis::AngX),
        JointKind::Prismatic => (JointAxesMask::LOCKED_PRISMATIC_AXES, JointAxis::LinX),
        JointKind::Fixed => (JointAxesMask::LOCKED_FIXED_AXES, JointAxis::AngX),
    };
    let mut b = GenericJointBuilder::new(mask).local_frame1(origin * align).local_frame2(align).contacts_enabled(false);
    if let (true, Some((lo, hi)), false) = (with_limits, j.limits, j.kind == JointKind::Fixed) {
        b = b.limits(free_axis, [lo, hi]);
    }
    b.build()
}

/// A Rapier world with the leg's gravity and solver settings.
fn new_world(dt_s: f64, params: LegSolverParams, ground: Option<&GroundConfig>) -> PhysicsWorld {
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -GRAVITY_M_S2);
    world.integration_parameters = IntegrationParameters {
        dt: dt_s,
        num_solver_iterations: params.solver_iterations,
        num_internal_pgs_iterations: params.pgs_iterations,
        ..IntegrationParameters::default()
    };
    if let Some(g) = ground {
        let soft = SpringCoefficients::new(g.contact_frequency_hz, g.contact_damping_ratio);
        world.integration_parameters.contact_softness = soft;
        world.integration_parameters.static_contact_softness = soft;
    }
    world
}

/// World poses of every link at joint coordinates `q` (3D forward kinematics), the thigh at
/// `root` (turned by the hip flexion, raised on the carriage) when it is not welded at the origin.
fn initial_poses(model: &LegSpec, q: &[f64], root: Option<Pose>) -> Vec<Pose> {
    let mut poses = vec![Pose::IDENTITY; model.links.len()];
    if let Some(r) = root {
        poses[model.root] = r;
    }
    for &ji in &model.topo_joints {
        let j = &model.joints[ji];
        let axis = DVec3::from(j.axis);
        let motion = match j.kind {
            JointKind::Revolute | JointKind::Continuous => Pose::from_rotation(DQuat::from_axis_angle(axis, q[ji])),
            JointKind::Prismatic => Pose::from_translation(axis * q[ji]),
            JointKind::Fixed => Pose::IDENTITY,
        };
        poses[j.child] = poses[j.parent] * pose3(j.origin_xyz, j.origin_rpy) * motion;
    }
    poses
}

/// Links welded into the body of their fixed-chain ancestor (fewer multibody links = faster):
/// `anchor[l]` is the link whose Rapier body carries link `l`, `offset[l]` the pose of `l` in
/// that body's frame.
struct Welds {
    anchor: Vec<usize>,
    offset: Vec<Pose>,
}

impl Welds {
    fn new(model: &LegSpec) -> Self {
        let (anchor, offset) = (0..model.links.len())
            .map(|l| {
                let (a, chain) = model.fixed_chain(l);
                let off = chain.iter().rev().fold(Pose::IDENTITY, |p, &ji| p * joint_origin_pose(&model.joints[ji]));
                (a, off)
            })
            .unzip();
        Self { anchor, offset }
    }
}

/// One Rapier body per anchor link, carrying the merged mass properties of its welded links.
/// Returns the body of every link and the distinct bodies.
fn insert_bodies(
    world: &mut PhysicsWorld,
    model: &LegSpec,
    welds: &Welds,
    poses: &[Pose],
    hip_driven: bool,
) -> (Vec<RigidBodyHandle>, Vec<RigidBodyHandle>) {
    let n = model.links.len();
    let mut handle_of_anchor: Vec<Option<RigidBodyHandle>> = vec![None; n];
    let mut bodies = Vec::new();
    for a in (0..n).filter(|&a| welds.anchor[a] == a) {
        let mut mp = MassProperties::default();
        for (i, l) in model.links.iter().enumerate().filter(|(i, _)| welds.anchor[*i] == a) {
            let inertia = rapier3d_f64::math::Matrix::from_cols_array_2d(&l.inertia_kg_m2);
            mp += MassProperties::with_inertia_matrix(DVec3::from(l.com_m), l.mass_kg, inertia)
                .transform_by(&welds.offset[i]);
        }
        let b = if a == model.root && !hip_driven { RigidBodyBuilder::fixed() } else { RigidBodyBuilder::dynamic() };
        let h = world.bodies.insert(b.pose(poses[a]).additional_mass_properties(mp).can_sleep(false).build());
        handle_of_anchor[a] = Some(h);
        bodies.push(h);
    }
    let link_body = (0..n).filter_map(|l| handle_of_anchor[welds.anchor[l]]).collect();
    (link_body, bodies)
}

/// A massless fixed pelvis at the hip centre and a kinematic hip hinge whose joint X axis is
/// the world -y axis, so its coordinate is hip flexion.
fn insert_hip(world: &mut PhysicsWorld, thigh: RigidBodyHandle) -> Result<(), LegError> {
    let pelvis = world.bodies.insert(RigidBodyBuilder::fixed().can_sleep(false).build());
    let align = Pose::from_rotation(DQuat::from_rotation_arc(DVec3::X, -DVec3::Y));
    let gj = GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
        .local_frame1(align)
        .local_frame2(align)
        .contacts_enabled(false)
        .build();
    world
        .multibody_joints
        .insert_kinematic(pelvis, thigh, gj, true)
        .map(|_| ())
        .ok_or_else(|| LegError::Unsupported("Rapier refused the kinematic hip joint".into()))
}

/// The pelvis carriage: a fixed anchor at the origin, the pelvis on a multibody joint free in
/// x and z (x locked too when the tether is), and the thigh on a dynamic hinge about -y (or
/// welded at the initial hip angle). Returns the pelvis body.
fn insert_carriage(
    world: &mut PhysicsWorld,
    thigh: RigidBodyHandle,
    c: &CarriageConfig,
) -> Result<RigidBodyHandle, LegError> {
    let anchor = world.bodies.insert(RigidBodyBuilder::fixed().can_sleep(false).build());
    let inertia = c.pelvis_mass_kg * 0.01;
    let mp = MassProperties::new(DVec3::ZERO, c.pelvis_mass_kg, DVec3::splat(inertia));
    let pelvis = world.bodies.insert(
        RigidBodyBuilder::dynamic()
            .translation(DVec3::new(0.0, 0.0, c.pelvis_height_m))
            .additional_mass_properties(mp)
            .can_sleep(false)
            .build(),
    );
    let mut mask = JointAxesMask::LIN_Y | JointAxesMask::ANG_X | JointAxesMask::ANG_Y | JointAxesMask::ANG_Z;
    if c.tether_locked {
        mask |= JointAxesMask::LIN_X;
    }
    let slide = GenericJointBuilder::new(mask).contacts_enabled(false).build();
    world
        .multibody_joints
        .insert(anchor, pelvis, slide, true)
        .ok_or_else(|| LegError::Unsupported("Rapier refused the pelvis carriage".into()))?;
    let align = Pose::from_rotation(DQuat::from_rotation_arc(DVec3::X, -DVec3::Y));
    let hip = if c.hip_locked {
        let turn = Pose::from_rotation(DQuat::from_axis_angle(-DVec3::Y, c.hip_rad));
        GenericJointBuilder::new(JointAxesMask::LOCKED_FIXED_AXES).local_frame1(turn).contacts_enabled(false).build()
    } else {
        GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
            .local_frame1(align)
            .local_frame2(align)
            .contacts_enabled(false)
            .build()
    };
    world
        .multibody_joints
        .insert(pelvis, thigh, hip, true)
        .ok_or_else(|| LegError::Unsupported("Rapier refused the hip joint".into()))?;
    Ok(pelvis)
}

/// Checked initial joint coordinates: the loop solved at the knee angle, the ankle's on the
/// carriage.
fn initial_coords(model: &LegSpec, initial_knee_rad: f64, mount: &Mount, dt_s: f64) -> Result<Vec<f64>, LegError> {
    if !(dt_s.is_finite() && dt_s > 0.0) {
        return Err(LegError::InvalidArgument(format!("dt_s must be > 0, got {dt_s}")));
    }
    if !initial_knee_rad.is_finite() {
        return Err(LegError::InvalidArgument("initial knee angle is not finite".into()));
    }
    let mut q = model.joint_coords(&model.loop_solution_checked(initial_knee_rad)?);
    if let (Some(a), Mount::Carriage(c)) = (model.ankle, mount) {
        q[a] = c.ankle_rad;
    }
    Ok(q)
}

/// The loop closure: an impulse joint at the rod end locking the two in-plane translations
/// (x, z; the leg is planar, so the out-of-plane row a spherical joint adds is redundant: it
/// only cost solver time; no shipped output changes without it). Returns it, its anchors in the
/// two links' frames, and whether the rod is its first body.
fn insert_closure(
    world: &mut PhysicsWorld,
    model: &LegSpec,
    welds: &Welds,
    link_body: &[RigidBodyHandle],
) -> (ImpulseJointHandle, DVec3, DVec3, bool) {
    let c = &model.closure;
    let (anchor1, anchor2) = (DVec3::from(c.anchor1_m), DVec3::from(c.anchor2_m));
    let sj = GenericJointBuilder::new(JointAxesMask::LIN_X | JointAxesMask::LIN_Z)
        .local_anchor1(welds.offset[c.link1] * anchor1)
        .local_anchor2(welds.offset[c.link2] * anchor2)
        .contacts_enabled(false);
    let closure = world.impulse_joints.insert(link_body[c.link1], link_body[c.link2], sj, true);
    let rod_child = model.joints[model.rod].child;
    (closure, anchor1, anchor2, welds.anchor[c.link1] == welds.anchor[rod_child])
}

/// The movable URDF joints as multibody joints between the welded bodies.
fn insert_joints(
    world: &mut PhysicsWorld,
    model: &LegSpec,
    welds: &Welds,
    link_body: &[RigidBodyHandle],
    with_limits: bool,
) -> Result<(), LegError> {
    for &ji in &model.topo_joints {
        let j = &model.joints[ji];
        if j.kind == JointKind::Fixed {
            continue;
        }
        let mut gj = to_generic(j, with_limits && Some(ji) == model.ankle);
        let f1 = welds.offset[j.parent] * gj.local_frame1;
        gj.set_local_frame1(f1);
        world
            .multibody_joints
            .insert(link_body[j.parent], link_body[j.child], gj, true)
            .ok_or_else(|| LegError::Unsupported(format!("Rapier refused multibody joint '{}'", j.name)))?;
    }
    Ok(())
}

/// Multibody link ids of the bodies the leg reads.
struct LinkIds {
    mb: MultibodyIndex,
    knee: usize,
    barrel: usize,
    rod: usize,
    hip: Option<usize>,
}

impl LinkIds {
    fn find(world: &PhysicsWorld, model: &LegSpec, link_body: &[RigidBodyHandle], hip: bool) -> Result<Self, LegError> {
        let missing = || LegError::Unsupported("a moving link is not part of the multibody".into());
        let id = |h: RigidBodyHandle| world.multibody_joints.rigid_body_link(h).map(|l| (l.multibody, l.id));
        let (mb, root) = id(link_body[model.root]).ok_or_else(missing)?;
        let child = |ji: usize| id(link_body[model.joints[ji].child]).map(|l| l.1).ok_or_else(missing);
        Ok(Self {
            mb,
            knee: child(model.knee)?,
            barrel: child(model.barrel)?,
            rod: child(model.rod)?,
            hip: hip.then_some(root),
        })
    }
}

/// The initial joint state besides the leg's own joints.
struct InitialState<'a> {
    /// Joint coordinates of the leg (loop solution).
    q: &'a [f64],
    /// Hip flexion and its velocity (rad, rad/s) on a hip joint (driven or carriage).
    hip: Option<(f64, f64)>,
    /// The carriage: its multibody link and configuration.
    carriage: Option<(Option<usize>, CarriageConfig)>,
}

/// Displace the multibody joints (which start at 0) to the loop solution, the hip angle and
/// the pelvis height; set the URDF's damping (not Rapier's default 0.1 N m s/rad) and the
/// initial velocities (the hip's, if driven).
fn set_initial_state(
    world: &mut PhysicsWorld,
    model: &LegSpec,
    ids: &LinkIds,
    link_body: &[RigidBodyHandle],
    init: &InitialState,
) {
    let joint_links: Vec<(usize, usize)> = model
        .topo_joints
        .iter()
        .filter(|&&ji| model.joints[ji].kind != JointKind::Fixed)
        .filter_map(|&ji| world.multibody_joints.rigid_body_link(link_body[model.joints[ji].child]).map(|l| (ji, l.id)))
        .collect();
    let Some(multibody) = world.multibody_joints.get_multibody_mut(ids.mb) else { return };
    // Resolves the fixed root (removes its 6 free DoFs) so that assembly ids are final.
    multibody.forward_kinematics(&world.bodies, true);
    let ndofs = multibody.ndofs();
    let (mut disp, mut damping) = (vec![0.0; ndofs], vec![0.0; ndofs]);
    let aid = |mb: &Multibody, lid: usize| mb.link(lid).map(|l| l.assembly_id());
    for &(ji, lid) in &joint_links {
        if let Some(a) = aid(multibody, lid) {
            disp[a] = init.q[ji];
            damping[a] = model.joints[ji].damping;
        }
    }
    let hip_aid = if init.hip.is_some() { ids.hip.and_then(|l| aid(multibody, l)) } else { None };
    if let (Some(a), Some((h0, _))) = (hip_aid, init.hip) {
        disp[a] = h0;
    }
    if let Some((Some(link), c)) = init.carriage {
        // The carriage's free coordinates in axis order: x (unless locked), then z.
        if let Some(a) = aid(multibody, link) {
            disp[a + usize::from(!c.tether_locked)] = c.pelvis_height_m;
        }
    }
    multibody.apply_displacements(&disp);
    multibody.damping_mut().copy_from_slice(&damping);
    multibody.generalized_velocity_mut().fill(0.0);
    if let (Some(a), Some((_, v0))) = (hip_aid, init.hip) {
        multibody.generalized_velocity_mut()[a] = v0;
    }
    multibody.forward_kinematics(&world.bodies, false);
    multibody.update_rigid_bodies(&mut world.bodies, true);
}

/// Inertia tensor (kg m^2, link frame) times an angular velocity or acceleration.
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

impl Leg {
    /// Builds the simulation at a knee angle (rad, flexion positive) with time step `dt_s` (s),
    /// at rest. The barrel angle and the rod extension are solved from the loop geometry so that
    /// the closure gap is zero at t = 0.
    pub fn new(model: &LegSpec, initial_knee_rad: f64, dt_s: f64) -> Result<Self, LegError> {
        Self::with_params(model, initial_knee_rad, dt_s, LegSolverParams::default())
    }

    /// Like [`Leg::new`] with explicit solver settings.
    pub fn with_params(
        model: &LegSpec,
        initial_knee_rad: f64,
        dt_s: f64,
        params: LegSolverParams,
    ) -> Result<Self, LegError> {
        Self::build(model, initial_knee_rad, Mount::Fixed, dt_s, params, None)
    }

    /// Builds the simulation with a driven hip: a fixed "pelvis" body (no mass) at the world
    /// origin is the multibody root and the thigh hangs on a kinematic revolute joint about -y
    /// through the origin, whose coordinate is hip flexion (rad, positive = thigh forward).
    /// The leg starts at knee flexion `initial_knee_rad` (rad) with zero relative joint
    /// velocities, hip flexion `initial_hip_rad` (rad) and hip velocity `initial_hip_vel_rad_s`
    /// (rad/s; the whole leg then turns rigidly). Drive the hip with [`Leg::set_hip_target`] or
    /// [`Leg::set_hip_velocity`] before each [`Leg::step`]; the hip keeps its velocity otherwise.
    pub fn with_hip(
        model: &LegSpec,
        initial_knee_rad: f64,
        initial_hip_rad: f64,
        initial_hip_vel_rad_s: f64,
        dt_s: f64,
        params: LegSolverParams,
    ) -> Result<Self, LegError> {
        if !(initial_hip_rad.is_finite() && initial_hip_vel_rad_s.is_finite()) {
            return Err(LegError::InvalidArgument("initial hip state is not finite".into()));
        }
        let mount = Mount::Driven { hip_rad: initial_hip_rad, hip_vel_rad_s: initial_hip_vel_rad_s };
        Self::build(model, initial_knee_rad, mount, dt_s, params, None)
    }

    /// Builds the simulation with any mount of the thigh and, optionally, the ground (see
    /// [`Mount`], [`GroundConfig`]). The ankle moves when the model's ankle is free.
    pub fn with_config(
        model: &LegSpec,
        initial_knee_rad: f64,
        mount: Mount,
        dt_s: f64,
        params: LegSolverParams,
        ground: Option<&GroundConfig>,
    ) -> Result<Self, LegError> {
        if let Mount::Carriage(c) = &mount {
            let ok = [c.pelvis_mass_kg, c.hip_rad, c.pelvis_height_m].iter().all(|v| v.is_finite())
                && c.pelvis_mass_kg > 0.0;
            if !ok {
                return Err(LegError::InvalidArgument(format!(
                    "carriage {c:?}: finite values and a positive pelvis mass"
                )));
            }
        }
        Self::build(model, initial_knee_rad, mount, dt_s, params, ground)
    }

    fn build(
        model: &LegSpec,
        initial_knee_rad: f64,
        mount: Mount,
        dt_s: f64,
        params: LegSolverParams,
        ground: Option<&GroundConfig>,
    ) -> Result<Self, LegError> {
        let q = initial_coords(model, initial_knee_rad, &mount, dt_s)?;
        let mut world = new_world(dt_s, params, ground);
        let welds = Welds::new(model);
        let root = mount.root_pose();
        let poses = initial_poses(model, &q, root);
        let (link_body, bodies) = insert_bodies(&mut world, model, &welds, &poses, root.is_some());
        let pelvis = match mount {
            Mount::Fixed => None,
            Mount::Driven { .. } => {
                insert_hip(&mut world, link_body[model.root])?;
                None
            }
            Mount::Carriage(c) => Some(insert_carriage(&mut world, link_body[model.root], &c)?),
        };
        // The free ankle has no actuator: on the ground its URDF limits hold the foot. The
        // knee and the rod keep no Rapier limits (the cylinder's stroke ends are the
        // hydraulics' hard stops).
        insert_joints(&mut world, model, &welds, &link_body, ground.is_some())?;
        let (closure, anchor1, anchor2, rod_anchor_is_1) = insert_closure(&mut world, model, &welds, &link_body);
        let belt = match ground {
            Some(g) => Some(Belt {
                ground: insert_ground(&mut world, model, &link_body, &welds.offset, g)?,
                speed_m_s: g.belt_speed_m_s,
            }),
            None => None,
        };
        let ids = LinkIds::find(&world, model, &link_body, root.is_some())?;
        let hip_init = mount.hip_init();
        let carriage = pelvis.zip(match mount {
            Mount::Carriage(c) => Some(c),
            _ => None,
        });
        let carriage_link = carriage.and_then(|(p, _)| world.multibody_joints.rigid_body_link(p).map(|l| l.id));
        let init = InitialState { q: &q, hip: hip_init, carriage: carriage.map(|(_, c)| (carriage_link, c)) };
        set_initial_state(&mut world, model, &ids, &link_body, &init);
        // Rapier applies the user-provided mass properties lazily, in the first pipeline step
        // (before it, `mass() == 0` and `world_com` is the body origin, which would give
        // `add_force_at_point` a wrong lever arm). A zero-dt step applies these user changes
        // without moving anything.
        world.integration_parameters.dt = 0.0;
        world.step();
        world.integration_parameters.dt = dt_s;
        let kinematic = matches!(mount, Mount::Driven { .. });
        let hip = ids.hip.zip(hip_init).map(|(link, (_, v0))| HipState {
            link,
            kinematic,
            vel: v0,
            accel: 0.0,
            coupling: HipCoupling::default(),
        });
        let ankle_link =
            model.ankle_joint().and_then(|j| world.multibody_joints.rigid_body_link(link_body[j.child]).map(|l| l.id));
        let carriage =
            carriage.map(|(pelvis, c)| CarriageState { pelvis, hip_locked_rad: c.hip_locked.then_some(c.hip_rad) });
        let mut leg = Leg {
            model: model.clone(),
            world,
            link_body,
            link_offset: welds.offset,
            bodies,
            mb: ids.mb,
            knee_link: ids.knee,
            rod_link: ids.rod,
            barrel_link: ids.barrel,
            closure,
            anchor1,
            anchor2,
            rod_anchor_is_1,
            dt: dt_s,
            time: 0.0,
            last_dl: 0.0,
            last_dknee: 0.0,
            hip,
            carriage,
            ankle_link,
            ground: belt,
            contact: ContactReading::default(),
            lab: None,
            lab_knee_moment_nm: 0.0,
            pins: Pins::default(),
        };
        leg.pins = leg.pins_now();
        if leg.ground.is_some() {
            leg.lab = Some(leg.segment_momenta());
        }
        Ok(leg)
    }

    /// Set the knee rate (rad/s) and the barrel and rod rates the loop implies (from the
    /// loop geometry), e.g. to start a gait run on its trajectory instead of at rest.
    pub fn set_knee_velocity(&mut self, knee_rate_rad_s: f64) -> Result<(), LegError> {
        let q = self.knee_angle_rad();
        let h = 1e-6;
        let qp = self.model.joint_coords(&self.model.loop_solution_checked(q + h)?);
        let qm = self.model.joint_coords(&self.model.loop_solution_checked(q - h)?);
        let joints: Vec<(usize, usize)> = [self.model.knee, self.model.barrel, self.model.rod]
            .into_iter()
            .zip([self.knee_link, self.barrel_link, self.rod_link])
            .collect();
        let mb = self.world.multibody_joints.get_multibody_mut(self.mb).unwrap();
        let aids: Vec<(usize, usize)> =
            joints.iter().map(|&(ji, lid)| (ji, mb.link(lid).unwrap().assembly_id())).collect();
        let mut v = mb.generalized_velocity_mut();
        for (ji, aid) in aids {
            v[aid] = (qp[ji] - qm[ji]) / (2.0 * h) * knee_rate_rad_s;
        }
        mb.forward_kinematics(&self.world.bodies, false);
        mb.update_rigid_bodies(&mut self.world.bodies, true);
        Ok(())
    }

    /// Set the ankle angle (rad, dorsiflexion positive) and rate (rad/s) when the ankle moves;
    /// does nothing with a locked ankle. A jump of the foot into the ground leaves Rapier's
    /// recycled contacts stale for a step: start with the foot placed through
    /// [`CarriageConfig::ankle_rad`] instead.
    pub fn set_ankle_state(&mut self, angle_rad: f64, rate_rad_s: f64) -> Result<(), LegError> {
        let Some(link) = self.ankle_link else { return Ok(()) };
        if !(angle_rad.is_finite() && rate_rad_s.is_finite()) {
            return Err(LegError::InvalidArgument("ankle state is not finite".into()));
        }
        let now = self.ankle_angle_rad();
        let mb = self.world.multibody_joints.get_multibody_mut(self.mb).unwrap();
        let aid = mb.link(link).unwrap().assembly_id();
        let mut disp = vec![0.0; mb.ndofs()];
        disp[aid] = angle_rad - now;
        mb.apply_displacements(&disp);
        mb.generalized_velocity_mut()[aid] = rate_rad_s;
        mb.forward_kinematics(&self.world.bodies, false);
        mb.update_rigid_bodies(&mut self.world.bodies, true);
        // Move the colliders and redo the collision detection now (the multibody writes the
        // body poses without flagging them for the colliders; a zero-dt step moves nothing),
        // so the next step does not see the foot where it was before.
        for &h in &self.bodies {
            let rb = &mut self.world.bodies[h];
            let pose = *rb.position();
            rb.set_position(pose, true);
        }
        self.world.integration_parameters.dt = 0.0;
        self.world.step();
        self.world.integration_parameters.dt = self.dt;
        self.pins = self.pins_now();
        if self.ground.is_some() {
            self.lab = Some(self.segment_momenta());
        }
        Ok(())
    }

    /// The model this simulation was built from.
    pub fn model(&self) -> &LegSpec {
        &self.model
    }
    /// Simulated time since construction, s.
    pub fn time_s(&self) -> f64 {
        self.time
    }
    /// Time step, s.
    pub fn dt_s(&self) -> f64 {
        self.dt
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

    /// Selects how the hip acceleration is passed on (default
    /// [`HipCoupling::InertialCompensation`]). No effect for a fixed thigh.
    pub fn set_hip_coupling(&mut self, coupling: HipCoupling) {
        if let Some(h) = &mut self.hip {
            h.coupling = coupling;
        }
    }

    /// Sets the hip velocity (rad/s, flexion positive) used during the next step(s). The hip
    /// angle integrates it exactly (`theta_h += v dt`). The acceleration `(v - v_prev) / dt` is
    /// compensated in the next step (see [`HipCoupling`]). Error for a fixed thigh.
    pub fn set_hip_velocity(&mut self, velocity_rad_s: f64) -> Result<(), LegError> {
        let dt = self.dt;
        let mb_id = self.mb;
        let h = self
            .hip
            .as_mut()
            .filter(|h| h.kinematic)
            .ok_or_else(|| LegError::InvalidArgument("the leg has no driven hip (use Leg::with_hip)".into()))?;
        if !velocity_rad_s.is_finite() {
            return Err(LegError::InvalidArgument("hip velocity is not finite".into()));
        }
        h.accel += (velocity_rad_s - h.vel) / dt;
        h.vel = velocity_rad_s;
        let mb = self.world.multibody_joints.get_multibody_mut(mb_id).unwrap();
        let aid = mb.link(h.link).unwrap().assembly_id();
        mb.generalized_velocity_mut()[aid] = velocity_rad_s;
        Ok(())
    }

    /// Prescribes the hip flexion angle (rad) reached at the end of the next step: sets the
    /// kinematic joint velocity to `(angle - current) / dt`, which Rapier integrates exactly.
    /// For a smooth `theta_h(t)`, call it with `theta_h(t + dt)` before every step; the hip
    /// acceleration seen by the compensation is then the second difference of the samples.
    pub fn set_hip_target(&mut self, angle_rad_at_end_of_step: f64) -> Result<(), LegError> {
        let v = (angle_rad_at_end_of_step - self.hip_angle_rad()) / self.dt;
        self.set_hip_velocity(v)
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
        self.last_dknee / self.dt
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
        self.last_dl / self.dt
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

    /// Advances by one step of `dt_s`: clears the user forces/torques of every body, applies
    /// `actuator_force_n` (N, positive lengthens the cylinder) as an equal and opposite pair along
    /// the pin-to-pin line (on the rod at its closure anchor, on the barrel at its pivot), plus an
    /// optional external force `(point in shank frame [m], force in world [N])` on the knee child
    /// (shank), then steps Rapier. With a driven hip ([`Leg::with_hip`]) it also applies the
    /// d'Alembert wrenches of the hip acceleration set since the last step (see [`HipCoupling`]).
    pub fn step(&mut self, actuator_force_n: f64, shank_force: Option<([f64; 3], [f64; 3])>) {
        self.step_with(&LegForces { actuator_force_n, shank_force, ..Default::default() })
    }

    /// Advances by one step with every force of [`LegForces`]: the cylinder pair and the shank
    /// force as [`Leg::step`], torques across the hip (carriage), knee and ankle as equal and
    /// opposite pairs on the bodies they join, and the force on the pelvis. With the ground,
    /// the contacts of the step are read afterwards ([`Leg::contact`]).
    pub fn step_with(&mut self, forces: &LegForces) {
        let (actuator_force_n, shank_force) = (forces.actuator_force_n, forces.shank_force);
        let l0 = self.cylinder_length_m();
        let k0 = self.knee_angle_rad();
        for h in self.bodies.iter().copied().chain(self.carriage.map(|c| c.pelvis)) {
            let rb = &mut self.world.bodies[h];
            rb.reset_forces(false);
            rb.reset_torques(false);
        }
        if actuator_force_n != 0.0 {
            let (pr, pb) = (self.pins.rod_end, self.pins.barrel_pivot);
            let u = (pr - pb).normalize_or_zero();
            let f = u * actuator_force_n;
            let rod_body = if self.rod_anchor_is_1 { self.model.closure.link1 } else { self.model.closure.link2 };
            self.world.bodies[self.link_body[rod_body]].add_force_at_point(f, pr, true);
            let barrel_body = self.model.joints[self.model.barrel].child;
            self.world.bodies[self.link_body[barrel_body]].add_force_at_point(-f, pb, true);
        }
        if let Some(h) = self.hip {
            if h.coupling == HipCoupling::InertialCompensation && h.accel != 0.0 {
                self.apply_hip_inertial_wrenches(h.accel);
            }
        }
        if let Some((p, f)) = shank_force {
            let shank = self.model.joints[self.model.knee].child;
            let pw = self.world_point(shank, DVec3::from(p));
            self.world.bodies[self.link_body[shank]].add_force_at_point(DVec3::from(f), pw, true);
        }
        self.apply_walking_forces(forces);
        match &self.ground {
            Some(belt) => self.world.step_with_events(belt, &()),
            None => self.world.step(),
        }
        self.pins = self.pins_now();
        if let Some(belt) = &self.ground {
            self.contact = read_contacts(&self.world, belt.ground, self.dt);
            self.update_lab_knee_moment();
        }
        if let Some(h) = &mut self.hip {
            h.accel = 0.0;
        }
        self.time += self.dt;
        self.last_dl = self.cylinder_length_m() - l0;
        self.last_dknee = self.knee_angle_rad() - k0;
    }

    /// Torque pairs across the hip, knee and ankle, and the pelvis force (zero ones skipped).
    fn apply_walking_forces(&mut self, f: &LegForces) {
        let knee = &self.model.joints[self.model.knee];
        let (shank, thigh) = (knee.child, knee.parent);
        if f.knee_torque_nm != 0.0 {
            let axis = self.link_pose(shank).rotation * DVec3::from(knee.axis);
            self.torque_pair(shank, thigh, axis * f.knee_torque_nm);
        }
        if let (Some(a), true) = (self.model.ankle_joint().cloned(), f.ankle_torque_nm != 0.0) {
            let axis = self.link_pose(a.child).rotation * DVec3::from(a.axis);
            self.torque_pair(a.child, a.parent, axis * f.ankle_torque_nm);
        }
        if let Some(c) = self.carriage {
            if f.hip_torque_nm != 0.0 {
                let t = -DVec3::Y * f.hip_torque_nm;
                self.world.bodies[self.link_body[self.model.root]].add_torque(t, true);
                self.world.bodies[c.pelvis].add_torque(-t, true);
            }
            if f.pelvis_force_n != [0.0, 0.0] {
                let force = DVec3::new(f.pelvis_force_n[0], 0.0, f.pelvis_force_n[1]);
                self.world.bodies[c.pelvis].add_force(force, true);
            }
        }
    }

    /// `torque` on the body of `on`, its opposite on the body of `from` (world frame).
    fn torque_pair(&mut self, on: usize, from: usize, torque: DVec3) {
        self.world.bodies[self.link_body[on]].add_torque(torque, true);
        self.world.bodies[self.link_body[from]].add_torque(-torque, true);
    }

    /// Momenta of the links carried by the shank's and the foot's bodies (the gait lab's
    /// shank and foot segments; the cylinder's rod and barrel are other bodies).
    fn segment_momenta(&self) -> SegmentMomenta {
        let knee = &self.model.joints[self.model.knee];
        let foot = self.model.ankle_joint().map_or(knee.child, |a| a.child);
        let segs = [self.link_body[knee.child], self.link_body[foot]];
        let gravity = DVec3::new(0.0, 0.0, -GRAVITY_M_S2);
        let mut m = SegmentMomenta { p: DVec3::ZERO, h: DVec3::ZERO, mass_kg: 0.0, weight_moment: DVec3::ZERO };
        for (li, l) in self.model.links.iter().enumerate() {
            let hb = self.link_body[li];
            if !segs.contains(&hb) {
                continue;
            }
            let rb = &self.world.bodies[hb];
            let pose = *rb.position() * self.link_offset[li];
            let c = pose * DVec3::from(l.com_m);
            let (w, cb) = (rb.angvel(), rb.center_of_mass());
            let v = rb.linvel() + w.cross(c - cb);
            let iw = pose.rotation * inertia_times(&l.inertia_kg_m2, pose.rotation.inverse() * w);
            m.p += v * l.mass_kg;
            m.h += c.cross(v * l.mass_kg) + iw;
            m.mass_kg += l.mass_kg;
            m.weight_moment += c.cross(gravity * l.mass_kg);
        }
        m
    }

    /// The net knee moment a gait lab would compute over the last step: the Newton-Euler
    /// balance of the shank and foot from the ground reaction (force and moment) and the
    /// change of their momenta, about the knee centre at the end of the step.
    fn update_lab_knee_moment(&mut self) {
        let now = self.segment_momenta();
        if let Some(before) = self.lab {
            let dt = self.dt;
            let c = self.contact;
            let grf = DVec3::new(c.horizontal_n, 0.0, c.vertical_n);
            let gravity = DVec3::new(0.0, 0.0, -GRAVITY_M_S2);
            // Force the thigh side applies at the knee: R = dP/dt - m g - GRF.
            let r = (now.p - before.p) / dt - gravity * now.mass_kg - grf;
            let knee = &self.model.joints[self.model.knee];
            let kc = self.world_point(knee.parent, joint_origin_pose(knee).translation);
            // Moment about the origin: M_k + K x R + weight + ground = dH/dt.
            let mk =
                (now.h - before.h) / dt - kc.cross(r) - now.weight_moment - DVec3::new(0.0, c.moment_origin_y_nm, 0.0);
            // Flexion is a rotation about +y: an extensor moment is -y.
            self.lab_knee_moment_nm = -mk.y;
        }
        self.lab = Some(now);
    }

    /// The net internal knee moment over the last step as a gait lab computes it from the
    /// ground reaction and the shank and foot motion (N m, extensor positive as in the WBDS
    /// data); 0 without ground or before the second step.
    pub fn lab_knee_moment_nm(&self) -> f64 {
        self.lab_knee_moment_nm
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

    /// Total linear momentum of every body (kg m/s, world x and z).
    pub fn momentum(&self) -> [f64; 2] {
        let mut p = DVec3::ZERO;
        for h in self.bodies.iter().copied().chain(self.carriage.map(|c| c.pelvis)) {
            let rb = &self.world.bodies[h];
            if rb.is_dynamic() {
                p += rb.linvel() * rb.mass();
            }
        }
        [p.x, p.z]
    }

    /// d'Alembert wrench of a hip angular acceleration `accel` (rad/s^2, flexion positive) on
    /// every link not carried by the thigh body: `-m (alpha x c)` at the CoM, `-I_world alpha`.
    fn apply_hip_inertial_wrenches(&mut self, accel: f64) {
        let alpha = -DVec3::Y * accel; // hip flexion = rotation about -y through the origin
        let thigh_body = self.link_body[self.model.root];
        for (li, l) in self.model.links.iter().enumerate() {
            let h = self.link_body[li];
            if h == thigh_body {
                continue;
            }
            let pose = *self.world.bodies[h].position() * self.link_offset[li];
            let c = pose * DVec3::from(l.com_m);
            let f = -l.mass_kg * alpha.cross(c);
            let w = pose.rotation.inverse() * alpha;
            let iw = inertia_times(&l.inertia_kg_m2, w);
            let rb = &mut self.world.bodies[h];
            rb.add_force_at_point(f, c, true);
            rb.add_torque(-(pose.rotation * iw), true);
        }
    }

    /// Kinetic energy of all links, J (from the multibody generalized velocities and body
    /// Jacobians, so it is consistent with the solved velocities).
    pub fn kinetic_energy_j(&self) -> f64 {
        let mb = self.multibody();
        let qd = mb.generalized_velocity();
        let mut ke = 0.0;
        for link in mb.links() {
            let h = link.rigid_body_handle();
            let rb = &self.world.bodies[h];
            if !rb.is_dynamic() {
                continue;
            }
            // Body Jacobian rows: linear velocity of the body's centre of mass, angular velocity.
            let v = mb.body_jacobian(link.link_id()) * qd;
            let lin = DVec3::new(v[0], v[1], v[2]);
            let ang = DVec3::new(v[3], v[4], v[5]);
            let cb = rb.center_of_mass();
            for (li, l) in self.model.links.iter().enumerate() {
                if self.link_body[li] != h {
                    continue;
                }
                let pose = *rb.position() * self.link_offset[li];
                let vl = lin + ang.cross(pose * DVec3::from(l.com_m) - cb);
                let w = pose.rotation.inverse() * ang;
                let iw = inertia_times(&l.inertia_kg_m2, w);
                ke += 0.5 * l.mass_kg * vl.length_squared() + 0.5 * w.dot(iw);
            }
        }
        ke
    }

    /// Gravitational potential energy of all links, J (z measured from the hip / world origin).
    pub fn potential_energy_j(&self) -> f64 {
        self.model
            .links
            .iter()
            .enumerate()
            .map(|(i, l)| l.mass_kg * GRAVITY_M_S2 * self.world_point(i, DVec3::from(l.com_m)).z)
            .sum()
    }

    /// Kinetic + gravitational potential energy of all links and the pelvis (carriage), J.
    pub fn total_energy_j(&self) -> f64 {
        self.kinetic_energy_j() + self.potential_energy_j() + self.pelvis_energy_j()
    }

    /// Kinetic + gravitational potential energy of the pelvis on its carriage (J; 0 without).
    pub fn pelvis_energy_j(&self) -> f64 {
        self.carriage.map_or(0.0, |c| {
            let rb = &self.world.bodies[c.pelvis];
            0.5 * rb.mass() * rb.linvel().length_squared() + rb.mass() * GRAVITY_M_S2 * rb.translation().z
        })
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
