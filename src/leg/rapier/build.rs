//! Building the Rapier leg: the multibody tree from the URDF model, the loop closure, the
//! driven hip or the pelvis carriage, the ground, and the initial state.

use super::*;
use crate::leg::error::LegError;
use crate::leg::ground::{insert_ground, ContactReading, GroundConfig};
use crate::leg::model::{JointKind, JointSpec, LegSpec, GRAVITY_M_S2};
use crate::leg::pose::{joint_origin_pose, pose_of};
use rapier3d_f64::glamx::{DQuat, DVec3};
use rapier3d_f64::math::Pose;
use rapier3d_f64::math::Vector;
use rapier3d_f64::prelude::{
    GenericJoint, GenericJointBuilder, ImpulseJointHandle, IntegrationParameters, JointAxesMask, MassProperties,
    Multibody, MultibodyIndex, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle, SpringCoefficients,
};

/// URDF joint -> Rapier generic joint. The Rapier joint frame's X axis is aligned with the URDF
/// axis, so the Rapier coordinate equals the URDF coordinate (same sign).
fn to_generic(j: &JointSpec) -> GenericJoint {
    let origin = pose_of(j.origin_xyz, j.origin_rpy);
    let axis = DVec3::from(j.axis);
    let align = Pose::from_rotation(DQuat::from_rotation_arc(DVec3::X, axis));
    let mask = match j.kind {
        JointKind::Revolute | JointKind::Continuous => JointAxesMask::LOCKED_REVOLUTE_AXES,
        JointKind::Prismatic => JointAxesMask::LOCKED_PRISMATIC_AXES,
        JointKind::Fixed => JointAxesMask::LOCKED_FIXED_AXES,
    };
    GenericJointBuilder::new(mask).local_frame1(origin * align).local_frame2(align).contacts_enabled(false).build()
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
    if let Some(g) = ground.filter(|g| g.compliant.is_none()) {
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
        poses[j.child] = poses[j.parent] * pose_of(j.origin_xyz, j.origin_rpy) * motion;
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
) -> Result<(), LegError> {
    for &ji in &model.topo_joints {
        let j = &model.joints[ji];
        if j.kind == JointKind::Fixed {
            continue;
        }
        let mut gj = to_generic(j);
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
        // No Rapier joint limits: the end stops (knee, stroke ends, the moving ankle) are the
        // plant's, the same law on both engines (`leg::stops`; Rapier's limit constraints also
        // fail on a multibody with a kinematic hip).
        insert_joints(&mut world, model, &welds, &link_body)?;
        let (closure, anchor1, anchor2, rod_anchor_is_1) = insert_closure(&mut world, model, &welds, &link_body);
        let belt = match ground {
            Some(g) => Some(insert_ground(&mut world, model, &link_body, &welds.offset, g)?),
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
        let dt = self.world.integration_parameters.dt;
        self.world.integration_parameters.dt = 0.0;
        self.world.step();
        self.world.integration_parameters.dt = dt;
        self.pins = self.pins_now();
        if self.ground.is_some() {
            self.lab = Some(self.segment_momenta());
        }
        Ok(())
    }
}
