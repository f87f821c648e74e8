//! Ground contact in Rapier: the URDF's `<collision>` shapes as colliders on the leg's bodies,
//! a flat ground (a half-space at `height_m`) with Coulomb friction, a treadmill belt as the
//! contacts' tangent velocity (a physics hook), and what the contacts did over a step.

use rapier3d_f64::glamx::{DQuat, DVec3};
use rapier3d_f64::math::Pose;
use rapier3d_f64::prelude::{
    ActiveHooks, ColliderBuilder, ColliderHandle, ContactModificationContext, Group, InteractionGroups,
    ModifiableContacts, PhysicsHooks, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle,
};

use super::error::LegError;
use super::model::{CollisionShape, LegSpec};

/// The ground under the foot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundConfig {
    /// Height of the ground surface (m, world z; the hip starts at the origin or above it).
    pub height_m: f64,
    /// Coulomb friction coefficient between the sole and the ground (>= 0).
    pub friction: f64,
    /// Belt speed (m/s, positive moves the surface toward -x, under a person walking to +x).
    pub belt_speed_m_s: f64,
    /// Natural frequency of the contact constraint's regularisation (Hz): Rapier's contacts
    /// are soft springs; stiffer ones penetrate less under the body's weight.
    pub contact_frequency_hz: f64,
    /// Damping ratio of the contact constraint's regularisation (-).
    pub contact_damping_ratio: f64,
}

/// The treadmill: every contact with the ground gets the belt's velocity as its tangent
/// velocity.
pub(super) struct Belt {
    pub ground: ColliderHandle,
    pub speed_m_s: f64,
}

impl PhysicsHooks for Belt {
    fn modify_solver_contacts(&self, context: &mut ContactModificationContext) {
        // The tangent velocity is that of the second collider relative to the first; the
        // ground surface moves at -speed along x.
        let sign = if context.collider1 == self.ground { -1.0 } else { 1.0 };
        if let ModifiableContacts::Rigid(m) = &mut context.contacts {
            for c in m.solver_contacts.iter_mut() {
                c.tangent_velocity = DVec3::new(sign * self.speed_m_s, 0.0, 0.0);
            }
        }
    }
}

/// What the ground did to the leg over the last step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactReading {
    /// Vertical ground reaction on the foot (N, up positive): the normal impulses over the step
    /// divided by the step.
    pub vertical_n: f64,
    /// Horizontal ground reaction on the foot (N, +x): the friction impulses over the step.
    pub horizontal_n: f64,
    /// Deepest penetration of a sole shape into the ground (m, >= 0).
    pub penetration_m: f64,
    /// Centre of pressure (world x, z in m): the contact points weighted by their normal
    /// impulses (None without contact).
    pub cop_m: Option<[f64; 2]>,
    /// Moment of the ground reaction about the world origin (N m, about +y).
    pub moment_origin_y_nm: f64,
}

/// Collision groups: the sole collides with the ground only.
fn groups(own: Group, other: Group) -> InteractionGroups {
    InteractionGroups::new(own, other, Default::default())
}

/// Add the URDF's collision shapes as colliders (no density: the URDF's `<inertial>` stays the
/// mass) on the bodies that carry their links, and the ground. Returns the ground's body and
/// collider. A mesh is refused, naming its link.
pub(super) fn insert_ground(
    world: &mut PhysicsWorld,
    model: &LegSpec,
    link_body: &[RigidBodyHandle],
    link_offset: &[Pose],
    g: &GroundConfig,
) -> Result<ColliderHandle, LegError> {
    for c in model.collisions() {
        let shape = match &c.shape {
            CollisionShape::Box { size } => ColliderBuilder::cuboid(size[0] / 2.0, size[1] / 2.0, size[2] / 2.0),
            CollisionShape::Cylinder { radius, length } => ColliderBuilder::cylinder(length / 2.0, *radius),
            CollisionShape::Sphere { radius } => ColliderBuilder::ball(*radius),
            CollisionShape::Capsule { radius, length } => ColliderBuilder::capsule_z(length / 2.0, *radius),
            CollisionShape::Mesh { filename } => {
                return Err(LegError::Unsupported(format!(
                    "link '{}' <collision> is a mesh ({filename}): ground contact needs boxes, cylinders, spheres or capsules",
                    model.links()[c.link].name
                )))
            }
        };
        let local = link_offset[c.link] * super::pose::pose_of(c.origin_xyz, c.origin_rpy);
        let shape = match &c.shape {
            // Parry's cylinder runs along y, URDF's along z.
            CollisionShape::Cylinder { .. } => {
                shape.position(local * Pose::from_rotation(DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2)))
            }
            _ => shape.position(local),
        };
        let collider =
            shape.density(0.0).friction(g.friction).collision_groups(groups(Group::GROUP_1, Group::GROUP_2)).build();
        world.colliders.insert_with_parent(collider, link_body[c.link], &mut world.bodies);
    }
    let body = world.bodies.insert(RigidBodyBuilder::fixed().build());
    let hooks = if g.belt_speed_m_s != 0.0 { ActiveHooks::MODIFY_SOLVER_CONTACTS } else { ActiveHooks::empty() };
    let ground = ColliderBuilder::cuboid(100.0, 100.0, 1.0)
        .translation(DVec3::new(0.0, 0.0, g.height_m - 1.0))
        .friction(g.friction)
        .collision_groups(groups(Group::GROUP_2, Group::GROUP_1))
        .active_hooks(hooks)
        .build();
    Ok(world.colliders.insert_with_parent(ground, body, &mut world.bodies))
}

/// Read the contacts of the ground after a step of `dt_s`.
pub(super) fn read_contacts(world: &PhysicsWorld, ground: ColliderHandle, dt_s: f64) -> ContactReading {
    let mut r = ContactReading::default();
    let (mut cop, mut lambda_sum) = ([0.0f64; 2], 0.0);
    for pair in world.narrow_phase.contact_pairs_with(ground) {
        // The manifold normal points from the first collider to the second and the impulses
        // push the second one along it: with the ground first they act on the foot as they are.
        let sign = if pair.collider1 == ground { 1.0 } else { -1.0 };
        for m in pair.manifolds() {
            let n = m.data.normal * sign;
            let (c1, c2) = (world.colliders.get(pair.collider1), world.colliders.get(pair.collider2));
            for p in &m.points {
                r.penetration_m = r.penetration_m.max(-p.dist);
                let lambda = p.data.impulse;
                // `tangent_impulse` is the step's total friction impulse in the constraint's
                // tangent basis, which is not kept; `warmstart_tangent_world` is the last
                // substep's in world axes, in the same basis. In the sagittal plane both lie
                // along the one tangent direction, so the total is the world vector scaled by
                // their ratio. Friction acts on the foot opposite to the normal's convention.
                let (total, last) = (p.data.tangent_impulse, p.data.warmstart_tangent_impulse);
                let last2 = last.norm_squared();
                let ratio = if last2 > 0.0 { total.dot(&last) / last2 } else { 0.0 };
                let tangent = -p.data.warmstart_tangent_world * ratio * sign;
                let f = (n * lambda + tangent) / dt_s;
                r.vertical_n += f.z;
                r.horizontal_n += f.x;
                let world_point = match (pair.collider1 == ground, c1, c2) {
                    (true, _, Some(c)) => *c.position() * p.local_p2,
                    (false, Some(c), _) => *c.position() * p.local_p1,
                    _ => continue,
                };
                r.moment_origin_y_nm += world_point.cross(f).y;
                cop[0] += world_point.x * lambda;
                cop[1] += world_point.z * lambda;
                lambda_sum += lambda;
            }
        }
    }
    if lambda_sum > 0.0 {
        r.cop_m = Some([cop[0] / lambda_sum, cop[1] / lambda_sum]);
    }
    r
}
