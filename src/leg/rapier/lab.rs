//! Gait-lab quantities of the Rapier leg: segment momenta, the net knee moment, energies.

use super::*;
use crate::leg::model::GRAVITY_M_S2;
use crate::leg::pose::joint_origin_pose;
use rapier3d_f64::glamx::DVec3;

impl Leg {
    /// Momenta of the links carried by the shank's and the foot's bodies (the gait lab's
    /// shank and foot segments; the cylinder's rod and barrel are other bodies).
    pub(super) fn segment_momenta(&self) -> SegmentMomenta {
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
    pub(super) fn update_lab_knee_moment(&mut self) {
        let now = self.segment_momenta();
        if let Some(before) = self.lab {
            let dt = self.dt_s();
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

    /// A link frame's planar state for the device's sensors: its origin (m, world x and z),
    /// its turn about world +y (cos, sin), the origin's velocity (m/s) and the angular
    /// velocity about +y (rad/s).
    pub fn link_planar_state(&self, link: usize) -> crate::sensors::SegmentState {
        let rb = &self.world.bodies[self.link_body[link]];
        let pose = *rb.position() * self.link_offset[link];
        let o = pose.translation;
        let x_axis = pose.rotation * DVec3::X;
        let (w, cb) = (rb.angvel(), rb.center_of_mass());
        let v = rb.linvel() + w.cross(o - cb);
        crate::sensors::SegmentState {
            origin_m: [o.x, o.z],
            cos_sin: (x_axis.x, -x_axis.z),
            velocity_m_s: [v.x, v.z],
            omega_rad_s: w.y,
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
}
