//! Stepping the Rapier leg: the forces of one step, the driven hip, the carriage.

use super::*;
use crate::leg::error::LegError;
use crate::leg::ground::{apply_compliant, read_contacts, Belt};
use rapier3d_f64::glamx::DVec3;

impl Leg {
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
        let dt = self.dt_s();
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
        let v = (angle_rad_at_end_of_step - self.hip_angle_rad()) / self.dt_s();
        self.set_hip_velocity(v)
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
        let dt = self.dt_s();
        let compliant = match &mut self.ground {
            Some(Belt { compliant: Some(c), speed_m_s, .. }) => {
                Some(apply_compliant(&mut self.world, &self.link_body, c, *speed_m_s, dt))
            }
            _ => None,
        };
        match &self.ground {
            Some(belt) if belt.compliant.is_none() => self.world.step_with_events(belt, &()),
            _ => self.world.step(),
        }
        self.pins = self.pins_now();
        if let Some(belt) = &self.ground {
            self.contact = compliant.unwrap_or_else(|| read_contacts(&self.world, belt.ground, dt));
            self.update_lab_knee_moment();
        }
        if let Some(h) = &mut self.hip {
            h.accel = 0.0;
        }
        self.time += self.dt_s();
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
}
