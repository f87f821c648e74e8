//! The reduced engine's ground contact: the spheres that touch, their forces, the step's start
//! (the contact anchors) and the contact's stiffness for the step's stability.

use super::*;

impl WalkerModel {
    /// Sphere `s` at `kin` if it touches: its depth (m), ground point (m) and the point's
    /// velocity (m/s) and Jacobian.
    pub(super) fn sphere_at(&self, kin: &[Kin], s: &Sphere) -> Option<(f64, P2, P2, [P2; NJ])> {
        let k = &kin[s.link];
        let u = k.rot(s.center);
        let depth = self.ground_z_m + s.radius_m - (k.t.z + u.z);
        if depth <= 0.0 {
            return None;
        }
        let point = P2::new(k.t.x + u.x, self.ground_z_m);
        let (_, v, jp, _) = k.point(point.minus(k.t));
        Some((depth, point, v, jp))
    }

    /// The contact forces at the link kinematics `kin`, added to `q` (and, with `record`, each
    /// touching sphere's generalized force pushed there); what they add up to.
    pub(super) fn contact(
        &self,
        kin: &[Kin],
        anchors: &Anchors,
        q: &mut [f64; NG],
        mut record: Option<&mut Vec<[f64; NG]>>,
    ) -> ContactReading {
        let _timed = crate::profile::scope(crate::profile::Stage::Contact);
        let mut r = ContactReading::default();
        let mut sum = ReadingSum::default();
        let belt = self.belt_speed_m_s;
        for (i, sphere) in self.spheres.iter().enumerate() {
            let Some((depth, point, v, jp)) = self.sphere_at(kin, sphere) else { continue };
            let radius = sphere.radius_m;
            let mut anchor = anchors.x_m.get(i).copied().flatten().map(|a| a - belt * anchors.since_s);
            let (fx, fz) =
                sphere_force(&self.law, self.friction, radius, depth, point.x, [v.x, v.z], belt, &mut anchor);
            let g = generalized(&jp, P2::new(fx, fz));
            add(q, g);
            if let Some(rec) = record.as_deref_mut() {
                rec.push(g);
            }
            sum.add(&mut r, [point.x, point.z], [fx, fz], depth);
        }
        sum.finish(&mut r);
        r
    }

    /// The start of a step at state `x`, in one pass: the friction `anchors` updated by the
    /// Rapier engine's rule (a sphere off the ground has none, one that touches keeps its
    /// anchor or gets one where it touches, one that slips has its anchor moved to where the
    /// spring carries `mu F_n`), what the ground does then, the knee's compliance, and the gait
    /// lab's shank and foot segments.
    pub fn step_start(&self, x: &[f64; NX], anchors: &mut [Option<f64>]) -> StepStart {
        self.step_start_into(x, anchors, &mut StartCache::default())
    }

    /// [`Self::step_start`], keeping in `cache` what the step's first evaluation needs again.
    pub fn step_start_into(&self, x: &[f64; NX], anchors: &mut [Option<f64>], cache: &mut StartCache) -> StepStart {
        self.with_kin(|kin| {
            self.kinematics(x, kin);
            self.step_start_kin(kin, x, anchors, cache)
        })
    }

    /// [`Self::step_start_into`] at the link kinematics `kin` of state `x`.
    pub(super) fn step_start_kin(
        &self,
        kin: &[Kin],
        x: &[f64; NX],
        anchors: &mut [Option<f64>],
        cache: &mut StartCache,
    ) -> StepStart {
        for (sphere, anchor) in self.spheres.iter().zip(anchors.iter_mut()) {
            match self.sphere_at(kin, sphere) {
                None => *anchor = None,
                Some((depth, point, v, _)) => {
                    let (r, belt) = (sphere.radius_m, self.belt_speed_m_s);
                    sphere_force(&self.law, self.friction, r, depth, point.x, [v.x, v.z], belt, anchor);
                }
            }
        }
        cache.contact_q.clear();
        let anchored = Anchors { x_m: anchors, since_s: 0.0 };
        let contact = self.contact(kin, &anchored, &mut [0.0; NG], Some(&mut cache.contact_q));
        let m = self.mass_matrix(kin, None);
        let mut locked = m;
        self.lock(&mut locked, &mut [0.0; NG], &[0.0; NG]);
        let l = cholesky(&locked);
        cache.x = Some(*x);
        cache.kin.clear();
        cache.kin.extend_from_slice(kin);
        (cache.m, cache.l, cache.contact) = (m, l, contact);
        let (mut p, mut h, mut weight_moment, mut mass) = (P2::default(), 0.0, 0.0, 0.0);
        for &li in &self.segments {
            let (m, com, iyy) = self.links[li];
            let k = &kin[li];
            let (c, v, _, _) = k.point(k.rot(com));
            p = p.plus(v.scale(m));
            // (c x m v).y = m (c.z v.x - c.x v.z); the link's spin w is about +y.
            h += m * (c.z * v.x - c.x * v.z) + iyy * k.w;
            weight_moment += m * GRAVITY_M_S2 * c.x;
            mass += m;
        }
        let knee = self.spec.knee_joint();
        let knee_centre = kin[knee.parent].t.plus(kin[knee.parent].rot(crate::leg::model::joint_origin(knee).t));
        StepStart {
            contact,
            stiffness: self.contact_stiffness(kin, &l),
            knee_compliance: Self::knee_compliance(&l),
            knee_inertia_kg_m2: m[KNEE][KNEE],
            ankle_compliance: if self.locked[ANKLE] { 0.0 } else { Self::compliance(&l, ANKLE) },
            momentum: [p.x, p.z],
            angular_momentum: h,
            weight_moment,
            segment_mass_kg: mass,
            knee_centre,
            links: self.sensor_links.map(|l| {
                let k = &kin[l];
                crate::sensors::SegmentState {
                    origin_m: [k.t.x, k.t.z],
                    cos_sin: k.cs,
                    velocity_m_s: [k.v.x, k.v.z],
                    omega_rad_s: k.w,
                }
            }),
        }
    }

    /// How stiff the contacts make the motion at `kin` with the mass matrix's Cholesky factor
    /// `l`: the touching spheres' normal and friction dampers (1/s) and springs (rad/s) on the
    /// mass they move (`J M^-1 J^T` at the contact point, each direction), summed over the
    /// spheres: a bound on the largest eigenvalue of `M^-1 C` (and `M^-1 K`) that is 7 % over it
    /// in stance on `gait_treadmill.toml` (power iteration: 5150/s against 5500/s) at a
    /// fraction of the cost. What an explicit integrator's step must resolve.
    pub(super) fn contact_stiffness(&self, kin: &[Kin], l: &[[f64; NG]; NG]) -> (f64, f64) {
        let (mut rate, mut omega2) = (0.0, 0.0);
        for s in &self.spheres {
            let Some((depth, _, v, jp)) = self.sphere_at(kin, s) else { continue };
            let [kn, cn, kt, ct] = sphere_stiffness(&self.law, s.radius_m, depth, -v.z);
            let free = |j: f64, i: usize| if self.locked[i] { 0.0 } else { j };
            let (jz, jx) = (generalized(&jp, P2::new(0.0, 1.0)), generalized(&jp, P2::new(1.0, 0.0)));
            let jz: [f64; NG] = std::array::from_fn(|i| free(jz[i], i));
            let jx: [f64; NG] = std::array::from_fn(|i| free(jx[i], i));
            let inv_mass = |j: [f64; NG]| solve(l, j).iter().zip(&j).map(|(a, b)| a * b).sum::<f64>();
            let (wz, wx) = (inv_mass(jz), inv_mass(jx));
            rate += cn * wz + ct * wx;
            omega2 += kn * wz + kt * wx;
        }
        (rate, omega2.sqrt())
    }
}
