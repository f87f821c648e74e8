//! Ground contact in Rapier, two laws:
//! - **compliant** (the default): each sole sphere is a Hunt-Crossley contact with the ground
//!   plane, `F_n = 0.4714 E sqrt(R) x^1.5 (1 + 1.5 c xdot)` (OpenSim/Simbody's
//!   SmoothSphereHalfSpaceForce without its smoothing; Serrancoli et al. 2019, Falisse et al.
//!   2019: E = 1e7 N/m^2 gives a heel-pad-sized 9 mm under one body weight, c = 2 s/m), and
//!   Coulomb friction through a sticking anchor spring on the belt (`k_t` with the damping of a
//!   1 kg point, critically; it slides at `mu F_n`, no creep while it sticks). Forces are
//!   evaluated from the state at the start of each step and applied as external forces, so a
//!   heel strike spreads over the milliseconds of the pad's compression;
//! - **rigid**: the URDF's `<collision>` shapes as Rapier colliders (a soft constraint at
//!   `contact_frequency_hz`), the belt as the contacts' tangent velocity (a physics hook): a
//!   heel strike resolves within a step (tens of kN at 0.25 ms).
//!
//! Either way a flat ground (a half-space at `height_m`) with Coulomb friction, and what the
//! contacts did over a step.

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
    /// The compliant contact law's parameters; None: Rapier's rigid contacts.
    pub compliant: Option<CompliantContact>,
}

/// Parameters of the compliant sole contact (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompliantContact {
    /// Contact modulus E (N/m^2) of the Hertz term `0.4714 E sqrt(R) x^1.5`.
    pub modulus_pa: f64,
    /// Hunt-Crossley dissipation c (s/m): the normal force is scaled by `1 + 1.5 c xdot`.
    pub dissipation_s_per_m: f64,
    /// Stiffness of the friction anchor spring per contact point (N/m).
    pub friction_stiffness_n_per_m: f64,
}

/// Factor of the Hertz term of a sphere on a half-space as OpenSim writes it
/// (`(4/3) k sqrt(R k)` with `k = E^(2/3) / 2`).
const HERTZ: f64 = 0.471_404_520_791_031_7;
/// Radius (m) given to the sagittal corners of a box or cylinder sole under compliant contact.
pub const CORNER_RADIUS_M: f64 = 0.005;
/// Mass (kg) whose critical damping the friction spring has.
const FRICTION_MASS_KG: f64 = 1.0;

/// How deep (m) the lowest of a sole's contact points sinks into the ground when the sole,
/// held at its pose, carries `load_n` statically under the compliant law of `modulus_pa`:
/// the depth at which the Hertz forces of the points (`(bottom point, radius)` in any frame
/// with z up, as [`super::sole_contacts_at`] gives them) add up to the load. 0 without load.
pub fn static_sink_m(modulus_pa: f64, contacts: &[(super::planar::P2, f64)], load_n: f64) -> f64 {
    let lowest = contacts.iter().map(|c| c.0.z).fold(f64::INFINITY, f64::min);
    let positive = |v: f64| v > 0.0 && v.is_finite();
    if !positive(load_n) || !lowest.is_finite() || !positive(modulus_pa) {
        return 0.0;
    }
    let force = |depth: f64| -> f64 {
        contacts.iter().map(|(p, r)| HERTZ * modulus_pa * r.sqrt() * (depth - (p.z - lowest)).max(0.0).powf(1.5)).sum()
    };
    // The force grows without bound with the depth: double until it carries the load, then
    // bisect (60 halvings: far below a micrometre).
    let mut hi = 1e-3;
    while force(hi) < load_n && hi < 10.0 {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if force(mid) > load_n {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// One contact point of the compliant law: a sphere on a link, and where its friction anchor
/// sits on the belt while it touches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ContactSphere {
    link: usize,
    /// Centre in the link's body frame (m).
    center_body: DVec3,
    radius_m: f64,
    anchor_x_m: Option<f64>,
}

/// The compliant contact's state.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Compliant {
    params: CompliantContact,
    spheres: Vec<ContactSphere>,
    ground_z_m: f64,
    friction: f64,
}

/// The treadmill: every contact with the ground gets the belt's velocity as its tangent
/// velocity (rigid contacts), or the compliant law's state.
pub(super) struct Belt {
    pub ground: ColliderHandle,
    pub speed_m_s: f64,
    pub compliant: Option<Compliant>,
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

fn mesh_error(model: &LegSpec, link: usize, filename: &str) -> LegError {
    LegError::Unsupported(format!(
        "link '{}' <collision> is a mesh ({filename}): ground contact needs boxes, cylinders, spheres or capsules",
        model.links()[link].name
    ))
}

/// The compliant law's contact spheres: each sphere, both ends of a capsule, the sagittal
/// corners of a box or cylinder (radius [`CORNER_RADIUS_M`]), in their link's body frame.
fn contact_spheres(model: &LegSpec, link_offset: &[Pose]) -> Result<Vec<ContactSphere>, LegError> {
    let mut out = Vec::new();
    for c in model.collisions() {
        let (points, radius): (Vec<DVec3>, f64) = match &c.shape {
            CollisionShape::Sphere { radius } => (vec![DVec3::ZERO], *radius),
            CollisionShape::Capsule { radius, length } => {
                (vec![DVec3::new(0.0, 0.0, length / 2.0), DVec3::new(0.0, 0.0, -length / 2.0)], *radius)
            }
            CollisionShape::Box { size } => {
                let (x, z) = (size[0] / 2.0 - CORNER_RADIUS_M, size[2] / 2.0 - CORNER_RADIUS_M);
                (corners(x.max(0.0), z.max(0.0)), CORNER_RADIUS_M)
            }
            CollisionShape::Cylinder { radius, length } => {
                let (x, z) = (radius - CORNER_RADIUS_M, length / 2.0 - CORNER_RADIUS_M);
                (corners(x.max(0.0), z.max(0.0)), CORNER_RADIUS_M)
            }
            CollisionShape::Mesh { filename } => return Err(mesh_error(model, c.link, filename)),
        };
        let local = link_offset[c.link] * super::pose::pose_of(c.origin_xyz, c.origin_rpy);
        for p in points {
            out.push(ContactSphere { link: c.link, center_body: local * p, radius_m: radius, anchor_x_m: None });
        }
    }
    Ok(out)
}

fn corners(x: f64, z: f64) -> Vec<DVec3> {
    vec![DVec3::new(x, 0.0, z), DVec3::new(-x, 0.0, z), DVec3::new(x, 0.0, -z), DVec3::new(-x, 0.0, -z)]
}

/// Add the ground, and either the URDF's collision shapes as colliders (rigid contacts; no
/// density: the URDF's `<inertial>` stays the mass) on the bodies that carry their links, or
/// the compliant law's contact spheres. A mesh is refused, naming its link.
pub(super) fn insert_ground(
    world: &mut PhysicsWorld,
    model: &LegSpec,
    link_body: &[RigidBodyHandle],
    link_offset: &[Pose],
    g: &GroundConfig,
) -> Result<Belt, LegError> {
    let compliant = match g.compliant {
        Some(params) => Some(Compliant {
            params,
            spheres: contact_spheres(model, link_offset)?,
            ground_z_m: g.height_m,
            friction: g.friction,
        }),
        None => None,
    };
    for c in model.collisions().iter().filter(|_| compliant.is_none()) {
        let shape = match &c.shape {
            CollisionShape::Box { size } => ColliderBuilder::cuboid(size[0] / 2.0, size[1] / 2.0, size[2] / 2.0),
            CollisionShape::Cylinder { radius, length } => ColliderBuilder::cylinder(length / 2.0, *radius),
            CollisionShape::Sphere { radius } => ColliderBuilder::ball(*radius),
            CollisionShape::Capsule { radius, length } => ColliderBuilder::capsule_z(length / 2.0, *radius),
            CollisionShape::Mesh { filename } => return Err(mesh_error(model, c.link, filename)),
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
    let ground = world.colliders.insert_with_parent(ground, body, &mut world.bodies);
    Ok(Belt { ground, speed_m_s: g.belt_speed_m_s, compliant })
}

/// The compliant law over the coming step of `dt_s`: each touching sphere's normal and
/// friction forces, applied to its body at the contact point on the ground surface; returns
/// what they add up to.
pub(super) fn apply_compliant(
    world: &mut PhysicsWorld,
    link_body: &[RigidBodyHandle],
    c: &mut Compliant,
    belt_speed_m_s: f64,
    dt_s: f64,
) -> ContactReading {
    let mut r = ContactReading::default();
    let mut sum = ReadingSum::default();
    for s in c.spheres.iter_mut() {
        let h = link_body[s.link];
        let rb = &world.bodies[h];
        let center = *rb.position() * s.center_body;
        let x = c.ground_z_m + s.radius_m - center.z;
        if x <= 0.0 {
            s.anchor_x_m = None;
            continue;
        }
        let point = DVec3::new(center.x, center.y, c.ground_z_m);
        let v = rb.velocity_at_point(point);
        let (fx, fz) =
            sphere_force(&c.params, c.friction, s.radius_m, x, point.x, [v.x, v.z], belt_speed_m_s, &mut s.anchor_x_m);
        // The anchor is a point of the belt: it moves with the surface.
        if let Some(anchor) = s.anchor_x_m.as_mut() {
            *anchor -= belt_speed_m_s * dt_s;
        }
        let f = DVec3::new(fx, 0.0, fz);
        world.bodies[h].add_force_at_point(f, point, true);
        sum.add(&mut r, [point.x, point.z], [fx, fz], x);
    }
    sum.finish(&mut r);
    r
}

/// The compliant law at one contact sphere of radius `radius_m` (m) pressed `depth_m` (> 0, m)
/// into the ground, its contact point on the ground surface at `point_x_m` (m) moving at `v`
/// (m/s, x and z) over a belt running at `belt_speed_m_s` (m/s): the Hunt-Crossley normal
/// force and the anchor-spring friction (module doc). `anchor_x_m` is the friction spring's
/// anchor on the belt (m): set at the contact point when None, moved to where the spring
/// carries `friction * F_n` when the point slips. Returns the force on the foot (N, x and z).
/// Both engines use it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn sphere_force(
    law: &CompliantContact,
    friction: f64,
    radius_m: f64,
    depth_m: f64,
    point_x_m: f64,
    v: [f64; 2],
    belt_speed_m_s: f64,
    anchor_x_m: &mut Option<f64>,
) -> (f64, f64) {
    let kt = law.friction_stiffness_n_per_m;
    let ct = 2.0 * (kt * FRICTION_MASS_KG).sqrt();
    let x = depth_m;
    let hertz = HERTZ * law.modulus_pa * radius_m.sqrt() * x * x.sqrt();
    let fz = (hertz * (1.0 + 1.5 * law.dissipation_s_per_m * -v[1])).max(0.0);
    let anchor = anchor_x_m.get_or_insert(point_x_m);
    let mut fx = -kt * (point_x_m - *anchor) - ct * (v[0] + belt_speed_m_s);
    let limit = friction * fz;
    if fx.abs() > limit {
        fx = fx.signum() * limit;
        *anchor = point_x_m + fx / kt;
    }
    (fx, fz)
}

/// The compliant law's local stiffness at one sphere pressed `depth_m` (m) into the ground with
/// the penetration rate `depth_rate_m_s` (m/s): the normal spring's slope (N/m) and damping
/// (N s/m), the friction spring's stiffness (N/m) and damping (N s/m). For the integrators'
/// step limits.
pub(crate) fn sphere_stiffness(law: &CompliantContact, radius_m: f64, depth_m: f64, depth_rate_m_s: f64) -> [f64; 4] {
    let k = HERTZ * law.modulus_pa * radius_m.sqrt();
    let x = depth_m.max(0.0);
    let c = law.dissipation_s_per_m;
    let kt = law.friction_stiffness_n_per_m;
    [
        1.5 * k * x.sqrt() * (1.0 + 1.5 * c * depth_rate_m_s).max(0.0),
        1.5 * c * k * x * x.sqrt(),
        kt,
        2.0 * (kt * FRICTION_MASS_KG).sqrt(),
    ]
}

/// Running sums of a [`ContactReading`] over contact points.
#[derive(Default)]
pub(crate) struct ReadingSum {
    cop: [f64; 2],
    fz_sum: f64,
}

impl ReadingSum {
    /// Add the force `f` (N, x and z) at the ground point `point` (m, x and z) with the depth
    /// `depth_m` (m) to `r`.
    pub(crate) fn add(&mut self, r: &mut ContactReading, point: [f64; 2], f: [f64; 2], depth_m: f64) {
        r.vertical_n += f[1];
        r.horizontal_n += f[0];
        r.penetration_m = r.penetration_m.max(depth_m);
        // (p x f).y for p = (px, 0, pz), f = (fx, 0, fz).
        r.moment_origin_y_nm += point[1] * f[0] - point[0] * f[1];
        self.cop[0] += point[0] * f[1];
        self.cop[1] += point[1] * f[1];
        self.fz_sum += f[1];
    }

    /// The centre of pressure of what was added.
    pub(crate) fn finish(&self, r: &mut ContactReading) {
        if self.fz_sum > 0.0 {
            r.cop_m = Some([self.cop[0] / self.fz_sum, self.cop[1] / self.fz_sum]);
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::leg::planar::P2;

    /// The static sink is the Hertz law inverted: one 2 cm sphere at E = 1e7 carrying 730 N
    /// sinks (730 / (0.4714 E sqrt R))^(2/3) = 10.6 mm; two level spheres share the load; a
    /// sphere 20 mm higher takes none of a load that sinks the lower one 10.6 mm; no load, no
    /// sink.
    #[test]
    fn static_sink_inverts_the_hertz_law() {
        let (e, r) = (1e7, 0.02);
        let analytic = |load: f64| (load / (HERTZ * e * f64::sqrt(r))).powf(2.0 / 3.0);
        let one = static_sink_m(e, &[(P2::new(0.0, -0.5), r)], 730.0);
        assert!((one - analytic(730.0)).abs() < 1e-9 && (one - 0.0106).abs() < 2e-4, "{one}");
        let two = static_sink_m(e, &[(P2::new(0.0, -0.5), r), (P2::new(0.17, -0.5), r)], 730.0);
        assert!((two - analytic(365.0)).abs() < 1e-9, "{two}");
        let high = static_sink_m(e, &[(P2::new(0.0, -0.5), r), (P2::new(0.17, -0.48), r)], 730.0);
        assert!((high - one).abs() < 1e-9, "{high}");
        assert_eq!(static_sink_m(e, &[(P2::new(0.0, -0.5), r)], 0.0), 0.0);
        assert_eq!(static_sink_m(e, &[], 730.0), 0.0);
    }
}
