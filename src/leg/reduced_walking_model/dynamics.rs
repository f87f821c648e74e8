//! The reduced engine's equations of motion: the mass matrix and the bias forces by the forward
//! pass, the locked coordinates, the compliances, and the accelerations at a state.

use super::*;

impl WalkerModel {
    /// The mass matrix at the link kinematics `kin`; with `q`, subtracts the gravity and
    /// velocity-product forces from it. Every link's Jacobian has the unit pelvis columns
    /// (`J_c[x_p] = (1, 0)`, `J_c[z_p] = (0, 1)`, no rotation), so those rows are sums of the
    /// links' masses and first moments.
    #[allow(clippy::needless_range_loop)] // matrix indices read as the formulas
    pub(super) fn bias_forces(&self, kin: &[Kin], q: &mut [f64; NG]) {
        // The same terms in the same order as `mass_matrix` subtracts them (the same bits).
        q[PZ] -= self.total_mass_kg * GRAVITY_M_S2;
        for (l, &(mass, com, iyy)) in self.links.iter().enumerate() {
            let k = &kin[l];
            let (_, _, jc, bc) = k.point(k.rot(com));
            q[PX] -= mass * bc.x;
            q[PZ] -= mass * bc.z;
            for r in 0..NJ {
                q[HIP + r] -= mass * (jc[r].dot(bc) + GRAVITY_M_S2 * jc[r].z) + iyy * k.ja[r] * k.ba;
            }
        }
    }

    /// The mass matrix at the link kinematics `kin`; with `q`, subtracts the gravity and
    /// velocity-product forces from it ([`Self::bias_forces`]).
    #[allow(clippy::needless_range_loop)] // matrix indices read as the formulas
    pub(super) fn mass_matrix(&self, kin: &[Kin], mut q: Option<&mut [f64; NG]>) -> [[f64; NG]; NG] {
        let mut m = [[0.0; NG]; NG];
        m[PX][PX] = self.total_mass_kg;
        m[PZ][PZ] = self.total_mass_kg;
        if let Some(q) = q.as_deref_mut() {
            q[PZ] -= self.total_mass_kg * GRAVITY_M_S2;
        }
        for (l, &(mass, com, iyy)) in self.links.iter().enumerate() {
            let k = &kin[l];
            let (_, _, jc, bc) = k.point(k.rot(com));
            for c in 0..NJ {
                m[PX][HIP + c] += mass * jc[c].x;
                m[PZ][HIP + c] += mass * jc[c].z;
                for r in 0..=c {
                    m[HIP + r][HIP + c] += mass * jc[r].dot(jc[c]) + iyy * k.ja[r] * k.ja[c];
                }
            }
            if let Some(q) = q.as_deref_mut() {
                q[PX] -= mass * bc.x;
                q[PZ] -= mass * bc.z;
                for r in 0..NJ {
                    q[HIP + r] -= mass * (jc[r].dot(bc) + GRAVITY_M_S2 * jc[r].z) + iyy * k.ja[r] * k.ba;
                }
            }
        }
        for r in 0..NG {
            for c in 0..r {
                m[r][c] = m[c][r];
            }
        }
        m
    }

    /// The locked coordinates out of `m g'' = q`: each moves with its prescribed acceleration
    /// (`prescribed`, rad/s^2 or m/s^2: a driven hip's, else 0), whose inertial coupling moves
    /// to the right-hand side; its row becomes `g_i'' = prescribed_i`.
    #[allow(clippy::needless_range_loop)] // matrix indices read as the formulas
    pub(super) fn lock(&self, m: &mut [[f64; NG]; NG], q: &mut [f64; NG], prescribed: &[f64; NG]) {
        for i in (0..NG).filter(|&i| self.locked[i]) {
            for r in (0..NG).filter(|&r| r != i) {
                q[r] -= m[r][i] * prescribed[i];
            }
        }
        for i in (0..NG).filter(|&i| self.locked[i]) {
            for c in 0..NG {
                (m[i][c], m[c][i]) = (0.0, 0.0);
            }
            (m[i][i], q[i]) = (1.0, prescribed[i]);
        }
    }

    /// `(M^-1)_kk` from the Cholesky factor `l`.
    pub(super) fn knee_compliance(l: &[[f64; NG]; NG]) -> f64 {
        Self::compliance(l, KNEE)
    }

    /// `(M^-1)_ii` from the Cholesky factor `l`.
    pub(super) fn compliance(l: &[[f64; NG]; NG], i: usize) -> f64 {
        let mut e = [0.0; NG];
        e[i] = 1.0;
        solve(l, e)[i]
    }

    /// Evaluate the dynamics at state `x` with `applied` forces and the friction `anchors`.
    pub fn evaluate(&self, x: &[f64; NX], applied: &Applied, anchors: &Anchors) -> Evaluation {
        self.evaluate_from(x, applied, anchors, None)
    }

    /// [`Self::evaluate`], taking from `start` what its step's start computed when `x` is that
    /// state (the same bits, faster).
    pub fn evaluate_from(
        &self,
        x: &[f64; NX],
        applied: &Applied,
        anchors: &Anchors,
        start: Option<&StartCache>,
    ) -> Evaluation {
        let start = start.filter(|c| c.x.is_some_and(|cx| cx.iter().zip(x).all(|(a, b)| a.to_bits() == b.to_bits())));
        match start {
            Some(c) => self.evaluate_kin(&c.kin, x, applied, anchors, Some(c)),
            None => self.with_kin(|kin| {
                self.kinematics(x, kin);
                self.evaluate_kin(kin, x, applied, anchors, None)
            }),
        }
    }

    /// [`Self::evaluate_from`] at the link kinematics `kin` of state `x`.
    pub(super) fn evaluate_kin(
        &self,
        kin: &[Kin],
        x: &[f64; NX],
        applied: &Applied,
        anchors: &Anchors,
        start: Option<&StartCache>,
    ) -> Evaluation {
        let mut q = applied.q;
        let mut m = match start {
            Some(c) => {
                self.bias_forces(kin, &mut q);
                c.m
            }
            None => self.mass_matrix(kin, Some(&mut q)),
        };
        // The start's contact had its anchors where they are now only at the step's start.
        let contact = match start.filter(|_| anchors.since_s == 0.0) {
            Some(c) => {
                c.contact_q.iter().for_each(|g| add(&mut q, *g));
                c.contact
            }
            None => self.contact(kin, anchors, &mut q, None),
        };
        if let Some((link, p, f)) = applied.point {
            let k = &kin[link];
            let (_, _, jp, _) = k.point(k.rot(p));
            add(&mut q, generalized(&jp, k.rot(f)));
        }
        let lp = self.loop_at(x[KNEE]);
        let [ck, cb, cr, ca] = self.damping;
        q[KNEE] -= (ck + cb * lp[1] * lp[1] + cr * lp[4] * lp[4]) * x[NG + KNEE];
        q[ANKLE] -= ca * x[NG + ANKLE];
        let mut prescribed = [0.0; NG];
        prescribed[HIP] = applied.hip_accel_rad_s2;
        self.lock(&mut m, &mut q, &prescribed);
        // Locking changes the matrix the same way whatever the prescribed accelerations: the
        // start's factor is this one's.
        let l = match start {
            Some(c) => c.l,
            None => cholesky(&m),
        };
        Evaluation { accel: solve(&l, q), contact }
    }
}
