//! The reduced-coordinate engine (`leg.engine = "reduced"`, issue 11): the planar closed chain
//! in its one independent coordinate, the knee angle, with the hip driven.
//!
//! The Lagrangian of the chain with a prescribed hip angle `h(t)` (the same one
//! [`super::knee_inverse_dynamics`] inverts) gives
//!
//! ```text
//! M_kk(q) q'' = tau - M_hk(q) h'' - 1/2 M_kk'(q) q'^2 + 1/2 M_hh'(q) h'^2
//!               - [sin h X'(q) + cos h Z'(q)] - D(q) q'
//! tau = F L'(q) + f_cuff r_cuff
//! ```
//! with `M` the hip-knee mass matrix of all links through the loop, `V = sin h X(q) + cos h Z(q)`
//! the potential energy, `D(q) = sum_j c_j (dq_j/dq)^2` the URDF's joint damping reflected to the
//! knee (knee, barrel hinge and rod slide), `L(q)` the cylinder length and `r_cuff` the cuff
//! point's distance from the knee axis. Every coefficient is tabulated once per leg at load time
//! (linear interpolation on a fine grid) from the same pure-geometry functions the tests check
//! against Rapier; `L`, `L'` and `L''` are evaluated in closed form. The simulation loop
//! integrates `(q, q')` together with the hydraulics (see [`crate::plant::CoupledMechanics`]),
//! with the hip's trajectory sampled at the integrator's stages.
//!
//! It refuses what it cannot do: legs that are not planar (a joint axis off the y axis), and
//! (at scenario level) ground contact and the pelvis carriage.

use super::error::LegError;
use super::geometry::{cylinder_kinematics_at, cylinder_length_at, hip_knee_mass_matrix_at, moment_arm_at};
use super::model::{JointKind, LegSpec, GRAVITY_M_S2};
use super::planar::P2;

/// Grid points of the tables.
const N: usize = 6001;
/// Margin of the tables beyond the URDF's knee range (rad).
const MARGIN_RAD: f64 = 1.0;
/// Step of the numerical derivatives (rad).
const H: f64 = 1e-5;

/// Tabulated coefficients of the reduced dynamics, shared by every run with this leg.
#[derive(Debug, Clone)]
pub struct ReducedModel {
    lo: f64,
    step: f64,
    /// Per grid point: M_kk, M_kk', M_hk, M_hh', X', Z', D.
    table: Vec<[f64; 7]>,
    model: LegSpec,
}

/// The motion of the hip at one instant: angle (rad), rate (rad/s), acceleration (rad/s^2).
pub type HipMotion = (f64, f64, f64);

impl ReducedModel {
    /// Tabulate the model. Refuses a non-planar leg (naming the joint) and a loop that does not
    /// close somewhere in the knee range.
    pub fn new(model: &LegSpec) -> Result<Self, LegError> {
        for j in model.joints() {
            let off_y = j.axis[0].abs() + j.axis[2].abs();
            let rot = j.kind == JointKind::Revolute || j.kind == JointKind::Continuous;
            if rot && off_y > 1e-9 {
                return Err(LegError::Unsupported(format!(
                    "joint '{}' turns about {:?}: the reduced engine handles planar legs (hinges about y)",
                    j.name, j.axis
                )));
            }
            if j.origin_rpy[0].abs() + j.origin_rpy[2].abs() > 1e-9 {
                return Err(LegError::Unsupported(format!(
                    "joint '{}' has roll or yaw in its origin: the reduced engine handles planar legs",
                    j.name
                )));
            }
        }
        let (lo, hi) = model.knee_range_rad();
        let (lo, hi) = (lo - MARGIN_RAD, hi + MARGIN_RAD);
        let step = (hi - lo) / (N - 1) as f64;
        let mut table = Vec::with_capacity(N);
        for i in 0..N {
            let q = lo + i as f64 * step;
            // Beyond where the loop closes the row repeats the last one that does.
            match row(model, q) {
                Ok(r) => table.push(r),
                Err(e) => match table.last() {
                    Some(&r) => table.push(r),
                    None if q < model.knee_range_rad().0 => table.push([f64::NAN; 7]),
                    None => return Err(e),
                },
            }
        }
        // Leading rows before the loop first closed take the first row that does.
        if let Some(first) = table.iter().position(|r| !r[0].is_nan()) {
            let r = table[first];
            table[..first].iter_mut().for_each(|x| *x = r);
        } else {
            return Err(LegError::InvalidArgument("the loop closes nowhere in the knee range".into()));
        }
        Ok(Self { lo, step, table, model: model.clone() })
    }

    /// The leg it was built from.
    pub fn model(&self) -> &LegSpec {
        &self.model
    }

    fn at(&self, q: f64) -> [f64; 7] {
        table_at(&self.table, self.lo, self.step, q)
    }

    /// Effective mass at the cylinder, `M_kk / L'^2` (kg).
    pub fn effective_mass_kg(&self, q: f64) -> f64 {
        let arm = moment_arm_at(&self.model, q);
        self.at(q)[0] / (arm * arm)
    }

    /// Knee acceleration (rad/s^2) at knee angle `q` (rad), rate `qd` (rad/s), hip motion `hip`
    /// and generalized knee force `tau` (N m).
    pub fn acceleration(&self, q: f64, qd: f64, hip: HipMotion, tau: f64) -> f64 {
        let [mkk, dmkk, mhk, dmhh, dx, dz, d] = self.at(q);
        let (h, hd, hdd) = hip;
        let (s, c) = h.sin_cos();
        let dv = s * dx + c * dz;
        (tau - mhk * hdd - 0.5 * dmkk * qd * qd + 0.5 * dmhh * hd * hd - dv - d * qd) / mkk
    }

    /// Cylinder length (m) and its knee derivative (m/rad) at `q`.
    pub fn cylinder(&self, q: f64) -> (f64, f64) {
        (cylinder_length_at(&self.model, q), moment_arm_at(&self.model, q))
    }

    /// Cylinder length (m), its first (m/rad) and second (m/rad^2) knee derivatives at `q`.
    pub fn cylinder_kinematics(&self, q: f64) -> (f64, f64, f64) {
        cylinder_kinematics_at(&self.model, q)
    }
}

/// Row `x` of a table sampled on the uniform grid `lo + i * step` (at least two rows), linearly
/// interpolated, clamped to the grid's ends.
pub(crate) fn table_at<const C: usize>(table: &[[f64; C]], lo: f64, step: f64, x: f64) -> [f64; C] {
    let n = table.len();
    let u = ((x - lo) / step).clamp(0.0, (n - 1) as f64);
    let i = (u as usize).min(n - 2);
    let f = u - i as f64;
    let (a, b) = (&table[i], &table[i + 1]);
    std::array::from_fn(|k| a[k] + (b[k] - a[k]) * f)
}

/// One row of the table at knee angle `q`.
fn row(model: &LegSpec, q: f64) -> Result<[f64; 7], LegError> {
    let (_, mhk, mkk) = hip_knee_mass_matrix_at(model, q)?;
    let (hp, _, kp) = hip_knee_mass_matrix_at(model, q + 1e-4)?;
    let (hm, _, km) = hip_knee_mass_matrix_at(model, q - 1e-4)?;
    let (xp, zp) = potential_parts(model, q + H)?;
    let (xm, zm) = potential_parts(model, q - H)?;
    Ok([mkk, (kp - km) / 2e-4, mhk, (hp - hm) / 2e-4, (xp - xm) / (2.0 * H), (zp - zm) / (2.0 * H), damping(model, q)?])
}

/// `X(q), Z(q)` of `V = sin h X + cos h Z`: the links' weights times their x and z (J).
fn potential_parts(model: &LegSpec, q: f64) -> Result<(f64, f64), LegError> {
    let poses = super::geometry::link_poses_at(model, q)?;
    Ok(model.links().iter().zip(&poses).fold((0.0, 0.0), |(x, z), (l, p)| {
        let c = p.apply(P2::new(l.com_m[0], l.com_m[2]));
        (x + l.mass_kg * GRAVITY_M_S2 * c.x, z + l.mass_kg * GRAVITY_M_S2 * c.z)
    }))
}

/// `D(q) = sum_j c_j (dq_j/dq)^2` over the moving joints of the loop (N m s/rad).
fn damping(model: &LegSpec, q: f64) -> Result<f64, LegError> {
    let (p, m) = (model.loop_solution_checked(q + H)?, model.loop_solution_checked(q - H)?);
    let rates = [1.0, (p.barrel_rad - m.barrel_rad) / (2.0 * H), (p.rod_m - m.rod_m) / (2.0 * H)];
    let joints = [model.knee_joint(), model.barrel_joint(), model.rod_joint()];
    Ok(joints.iter().zip(rates).map(|(j, r)| j.damping * r * r).sum())
}
