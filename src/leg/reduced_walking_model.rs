//! The reduced engine's walking leg (`leg.engine = "reduced"` with `hip.mode = "carriage"`,
//! issue 24): the leg on the pelvis carriage as one planar multibody in five generalized
//! coordinates,
//!
//! ```text
//! g = (x_p, z_p, h, k, a)   pelvis fore-aft and height (m), hip flexion, knee flexion,
//!                           ankle dorsiflexion (rad)
//! M(g) g'' = Q_gravity + Q_contact + Q_joints + Q_applied - b(g, g')
//! ```
//! The closed cylinder loop is reduced to the knee: the barrel hinge and the rod slide are
//! functions of the knee angle (`beta(k)`, `s(k)` from the loop solution, tabulated with their
//! first and second derivatives), so the chain is a tree in `g`. Every link's centre of mass and
//! angle, their Jacobians `J = d(c, alpha)/dg` and the velocity-product accelerations
//! `J' g'` come from one forward pass down the tree per evaluation; then
//! `M = m_pelvis [x, z] + sum_i m_i J_c,i^T J_c,i + I_i J_alpha,i^T J_alpha,i`,
//! `b = sum_i m_i J_c,i^T (J' g')_c,i + I_i J_alpha,i (J' g')_alpha,i`, and a Cholesky solve.
//! The pelvis is a point mass on the carriage (its rotation is locked, as on the Rapier
//! carriage); the thigh hangs from it at the hip. A locked hip or tether removes its
//! coordinate.
//!
//! Forces, all explicit functions of the state evaluated at every integrator stage: gravity;
//! the URDF's joint damping (knee, barrel hinge and rod slide reflected to the knee through the
//! loop, ankle); the sole's compliant contact, the same law as the Rapier engine's
//! ([`super::ground`]: Hunt-Crossley spheres of the URDF's collision shapes, anchor-spring
//! friction), with the friction anchors held over a step (set, slipped and moved with the belt
//! at the step's start, as the Rapier engine does; within the step each anchor moves with the
//! belt and the friction force is clipped at `mu F_n`: Coulomb friction regularised by the
//! anchor spring); and what the plant applies (cylinder, body, end stops, cuff).

use super::error::LegError;
use super::ground::{
    sphere_force, sphere_stiffness, CompliantContact, ContactReading, GroundConfig, ReadingSum, CORNER_RADIUS_M,
};
use super::model::{CollisionShape, JointKind, LegSpec, GRAVITY_M_S2};
use super::planar::{Pose2, P2};

mod build;
mod contact;
mod dynamics;
use build::*;

/// Number of generalized coordinates.
pub const NG: usize = 5;
/// Number of them that turn links (hip, knee, ankle): the Jacobian columns a link carries.
const NJ: usize = 3;
/// Length of the mechanical state (coordinates, then rates).
pub const NX: usize = 2 * NG;
/// Index of the pelvis's fore-aft position in `g`.
pub const PX: usize = 0;
/// Index of the pelvis height.
pub const PZ: usize = 1;
/// Index of the hip flexion.
pub const HIP: usize = 2;
/// Index of the knee flexion.
pub const KNEE: usize = 3;
/// Index of the ankle dorsiflexion.
pub const ANKLE: usize = 4;
/// Names of the state entries (divergence reports).
pub const STATE_NAMES: [&str; NX] = [
    "pelvis_x_m",
    "pelvis_z_m",
    "hip_angle_rad",
    "knee_angle_rad",
    "ankle_angle_rad",
    "pelvis_x_rate_m_s",
    "pelvis_z_rate_m_s",
    "hip_rate_rad_s",
    "knee_rate_rad_s",
    "ankle_rate_rad_s",
];

/// Links a test's kinematics buffer holds.
#[cfg(test)]
const STACK_LINKS: usize = 16;
/// Most links the engine takes.
const MAX_LINKS: usize = 1024;
/// Grid points of the loop table.
const N_TABLE: usize = 6001;
/// Margin of the loop table beyond the knee range (rad).
const MARGIN_RAD: f64 = 1.0;
/// Step of the loop table's numerical derivatives (rad).
const H: f64 = 1e-4;

/// How a joint's coordinate follows `g`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Coord {
    /// Fixed joint.
    Zero,
    /// The knee angle itself.
    Knee,
    /// Loop table column (0: barrel hinge, 3: rod slide).
    Loop(usize),
    /// The ankle angle.
    Ankle,
}

/// One joint of the tree, planar.
#[derive(Debug, Clone, Copy)]
struct TreeJoint {
    parent: usize,
    child: usize,
    origin: Pose2,
    /// cos and sin of the origin's pitch.
    origin_cs: (f64, f64),
    /// Hinge: +1 / -1 (the axis's y sign); slider: 0.
    sign: f64,
    /// Slider direction in the parent frame after the origin's rotation.
    slide: P2,
    coord: Coord,
}

/// One contact sphere: its link, centre in the link frame (m), radius (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Link index.
    pub link: usize,
    /// Centre in the link frame (m).
    pub center: P2,
    /// Radius (m).
    pub radius_m: f64,
}

/// Kinematics of one link frame: pose, velocity, Jacobians and velocity-product acceleration.
#[derive(Debug, Clone, Copy, Default)]
struct Kin {
    t: P2,
    /// cos and sin of the frame's angle (rad, about +y).
    cs: (f64, f64),
    v: P2,
    w: f64,
    /// Columns of the Jacobians for the hip, knee and ankle (the pelvis's columns are the
    /// same for every link: `(1, 0)`, `(0, 1)`, no rotation).
    jt: [P2; NJ],
    ja: [f64; NJ],
    bt: P2,
    ba: f64,
}

/// `d/da (R(a) u) = perp(R(a) u)` for the rotation of [`P2::rot`].
fn perp(u: P2) -> P2 {
    P2::new(u.z, -u.x)
}

impl Kin {
    /// `u` (in this frame's axes) in world axes: `u.rot(a)` with the cached cos and sin.
    fn rot(&self, u: P2) -> P2 {
        let (c, s) = self.cs;
        P2::new(u.x * c + u.z * s, -u.x * s + u.z * c)
    }

    /// A point fixed in this frame at world offset `u` from the frame's origin: its position,
    /// velocity, Jacobian and velocity-product acceleration.
    fn point(&self, u: P2) -> (P2, P2, [P2; NJ], P2) {
        let pu = perp(u);
        let jt = std::array::from_fn(|i| self.jt[i].plus(pu.scale(self.ja[i])));
        let b = self.bt.plus(pu.scale(self.ba)).minus(u.scale(self.w * self.w));
        (self.t.plus(u), self.v.plus(pu.scale(self.w)), jt, b)
    }
}

/// The walking leg's model, built once per run.
#[derive(Debug, Clone)]
pub struct WalkerModel {
    spec: LegSpec,
    joints: Vec<TreeJoint>,
    /// Per link: mass (kg), centre of mass in the link frame (m), I_yy (kg m^2).
    links: Vec<(f64, P2, f64)>,
    lo: f64,
    step: f64,
    /// Per grid point: beta, beta', beta'', s, s', s''.
    table: Vec<[f64; 6]>,
    pelvis_mass_kg: f64,
    /// The pelvis's and every link's mass (kg).
    total_mass_kg: f64,
    /// Damping of the knee, barrel hinge, rod slide and ankle (N m s/rad, N s/m).
    damping: [f64; 4],
    locked: [bool; NG],
    spheres: Vec<Sphere>,
    law: CompliantContact,
    friction: f64,
    ground_z_m: f64,
    belt_speed_m_s: f64,
    /// Links of the gait lab's shank and foot segments.
    segments: Vec<usize>,
    /// The thigh's, shank's and foot's links (the knee's parent and child, the ankle's child).
    sensor_links: [usize; 3],
}

/// What a stage applies besides gravity, damping and contact.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Applied {
    /// Generalized forces (N, N m) on `g`: tether, support, hip, knee, ankle torques.
    pub q: [f64; NG],
    /// A force (N, x and z in the link's frame) at a point (m, in the link's frame) of a link.
    pub point: Option<(usize, P2, P2)>,
    /// The hip's acceleration when it is locked and driven along a trajectory (rad/s^2; 0 for
    /// a hip held still).
    pub hip_accel_rad_s2: f64,
}

/// How the thigh is held.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WalkerMount {
    /// On the pelvis carriage: the pelvis (kg) on x and z, the hip a hinge; either locked.
    Carriage {
        /// Mass the pelvis carries (kg).
        pelvis_mass_kg: f64,
        /// The hip is held at its angle.
        hip_locked: bool,
        /// The pelvis cannot move fore-aft.
        tether_locked: bool,
    },
    /// The hip fixed at the origin, its angle prescribed (held, or driven along the gait by the
    /// plant): the hanging leg, with the ground under it.
    FixedHip,
}

/// The friction anchors over a step: per sphere, the anchor on the belt at the step's start
/// (m), and the time since the start (s).
#[derive(Debug, Clone, Copy)]
pub struct Anchors<'a> {
    /// Per sphere (None: not touching at the step's start).
    pub x_m: &'a [Option<f64>],
    /// Time since the step's start (s): the anchors have moved with the belt by this much.
    pub since_s: f64,
}

/// What [`WalkerModel::step_start`] finds.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepStart {
    /// What the ground does (N, m).
    pub contact: ContactReading,
    /// `(M^-1)_kk`, the knee's compliance with every other coordinate free (1/(kg m^2)).
    pub knee_compliance: f64,
    /// `M_kk`, the knee's inertia with every other coordinate held (kg m^2): the closed
    /// chain's below the knee, as the Rapier engine's stops use.
    pub knee_inertia_kg_m2: f64,
    /// `(M^-1)_aa`, the ankle's compliance with every other coordinate free (1/(kg m^2); 0
    /// for a locked ankle).
    pub ankle_compliance: f64,
    /// How stiff the contacts make the motion: decay rate (1/s) and oscillation (rad/s).
    pub stiffness: (f64, f64),
    /// Momentum of the gait lab's shank and foot segments (kg m/s, x and z).
    pub momentum: [f64; 2],
    /// Their angular momentum about the world origin (kg m^2/s, about +y).
    pub angular_momentum: f64,
    /// Their weight's moment about the origin (N m, about +y).
    pub weight_moment: f64,
    /// Their mass (kg).
    pub segment_mass_kg: f64,
    /// The knee centre (m, world x and z).
    pub knee_centre: P2,
    /// The thigh's, shank's and foot's link frames (the device's sensors).
    pub links: [crate::sensors::SegmentState; 3],
}

/// What [`WalkerModel::step_start`] computed at a step's state that the step's first
/// evaluation, at the same state, needs again: the links' kinematics, the mass matrix and its
/// locked Cholesky factor, and the contact's generalized forces (their friction anchors as the
/// start set them). [`WalkerModel::evaluate_from`] uses them when its state is this one (bit
/// for bit), and gives the same bits as [`WalkerModel::evaluate`].
#[derive(Debug, Clone, Default)]
pub struct StartCache {
    x: Option<[f64; NX]>,
    kin: Vec<Kin>,
    m: [[f64; NG]; NG],
    l: [[f64; NG]; NG],
    /// The touching spheres' generalized forces, in the order the contact adds them.
    contact_q: Vec<[f64; NG]>,
    contact: ContactReading,
}

/// The result of one evaluation.
#[derive(Debug, Clone, Copy, Default)]
pub struct Evaluation {
    /// `g''`.
    pub accel: [f64; NG],
    /// What the ground did.
    pub contact: ContactReading,
}

impl WalkerModel {
    /// The model of `spec` held by `mount` over the ground `ground` (compliant law only).
    /// Refuses non-planar legs, joints the engine does not know, mesh or rolled collision
    /// shapes, and rigid contact, naming what.
    pub fn new(spec: &LegSpec, mount: WalkerMount, ground: Option<&GroundConfig>) -> Result<Self, LegError> {
        let (pelvis_mass_kg, hip_locked, tether_locked, pelvis_fixed) = match mount {
            WalkerMount::Carriage { pelvis_mass_kg, hip_locked, tether_locked } => {
                (pelvis_mass_kg, hip_locked, tether_locked, false)
            }
            // The pelvis's mass does not enter: its coordinates are locked.
            WalkerMount::FixedHip => (1.0, true, true, true),
        };
        if spec.links.len() > MAX_LINKS {
            return Err(LegError::Unsupported(format!(
                "{} links: the reduced engine's walking leg takes at most {MAX_LINKS}",
                spec.links.len()
            )));
        }
        let joints = tree_joints(spec)?;
        let (lo, hi) = spec.knee_range_rad();
        let (lo, hi) = (lo - MARGIN_RAD, hi + MARGIN_RAD);
        let step = (hi - lo) / (N_TABLE - 1) as f64;
        let table = loop_table(spec, lo, step)?;
        let links =
            spec.links.iter().map(|l| (l.mass_kg, P2::new(l.com_m[0], l.com_m[2]), l.inertia_kg_m2[1][1])).collect();
        let damping = [
            spec.knee_joint().damping,
            spec.barrel_joint().damping,
            spec.rod_joint().damping,
            spec.ankle_joint().map_or(0.0, |a| a.damping),
        ];
        let mut locked = [false; NG];
        locked[HIP] = hip_locked;
        locked[PX] = tether_locked;
        locked[PZ] = pelvis_fixed;
        locked[ANKLE] = spec.ankle.is_none();
        let (law, friction, ground_z_m, belt_speed_m_s, spheres) = match ground {
            None => (
                CompliantContact { modulus_pa: 0.0, dissipation_s_per_m: 0.0, friction_stiffness_n_per_m: 1.0 },
                0.0,
                0.0,
                0.0,
                Vec::new(),
            ),
            Some(g) => {
                let law = g.compliant.ok_or_else(|| {
                    LegError::Unsupported(
                        "the reduced engine's contact is the compliant law: ground.contact = \"rigid\" needs leg.engine = \"rapier\"".into(),
                    )
                })?;
                (law, g.friction, g.height_m, g.belt_speed_m_s, contact_spheres(spec)?)
            }
        };
        let knee = spec.knee_joint();
        let foot = spec.ankle_joint().map_or(knee.child, |a| a.child);
        let segments = (0..spec.links.len())
            .filter(|&l| {
                let a = spec.fixed_chain(l).0;
                a == spec.fixed_chain(knee.child).0 || a == spec.fixed_chain(foot).0
            })
            .collect();
        Ok(Self {
            spec: spec.clone(),
            joints,
            links,
            lo,
            step,
            table,
            pelvis_mass_kg,
            total_mass_kg: pelvis_mass_kg + spec.links.iter().map(|l| l.mass_kg).sum::<f64>(),
            damping,
            locked,
            spheres,
            law,
            friction,
            ground_z_m,
            belt_speed_m_s,
            segments,
            sensor_links: [knee.parent, knee.child, foot],
        })
    }

    /// The leg.
    pub fn spec(&self) -> &LegSpec {
        &self.spec
    }

    /// The contact spheres.
    pub fn spheres(&self) -> &[Sphere] {
        &self.spheres
    }

    /// Belt speed (m/s).
    pub fn belt_speed_m_s(&self) -> f64 {
        self.belt_speed_m_s
    }

    /// Whether coordinate `i` is locked.
    pub fn locked(&self, i: usize) -> bool {
        self.locked[i]
    }

    fn loop_at(&self, k: f64) -> [f64; 6] {
        super::reduced_knee_model::table_at(&self.table, self.lo, self.step, k)
    }

    /// `f` with a buffer for every link's kinematics (this thread's, kept between calls: a
    /// stage writes every entry it reads, from the root down, before reading it).
    fn with_kin<R>(&self, f: impl FnOnce(&mut [Kin]) -> R) -> R {
        thread_local! {
            static KIN: std::cell::RefCell<Vec<Kin>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        let n = self.links.len();
        KIN.with_borrow_mut(|buf| {
            if buf.len() < n {
                buf.resize(n, Kin::default());
            }
            f(&mut buf[..n])
        })
    }

    /// Kinematics of every link frame at state `x` into `out` (indexed like the links).
    fn kinematics(&self, x: &[f64; NX], out: &mut [Kin]) {
        let (g, gd) = (&x[..NG], &x[NG..]);
        let root = &mut out[self.spec.root];
        let cs = (-g[HIP]).sin_cos();
        *root = Kin {
            t: P2::new(g[PX], g[PZ]),
            cs: (cs.1, cs.0),
            v: P2::new(gd[PX], gd[PZ]),
            w: -gd[HIP],
            ..Kin::default()
        };
        // Column 0 is the hip's: the thigh turns by -h.
        root.ja[0] = -1.0;
        let lp = self.loop_at(g[KNEE]);
        let kd = gd[KNEE];
        for j in &self.joints {
            // The joint's coordinate, its rate, its gradient in g and its velocity-product
            // acceleration.
            let (q, qd, grad, qb) = match j.coord {
                Coord::Zero => (0.0, 0.0, (KNEE - HIP, 0.0), 0.0),
                Coord::Knee => (g[KNEE], kd, (KNEE - HIP, 1.0), 0.0),
                Coord::Loop(c) => (lp[c], lp[c + 1] * kd, (KNEE - HIP, lp[c + 1]), lp[c + 2] * kd * kd),
                Coord::Ankle => (g[ANKLE], gd[ANKLE], (ANKLE - HIP, 1.0), 0.0),
            };
            // Built from the parent in place (a copy of the whole frame per joint showed in the
            // profile).
            let p = &out[j.parent];
            let o = p.rot(j.origin.t);
            let mut c = if j.sign != 0.0 || j.coord == Coord::Zero {
                let (_, v, jt, bt) = p.point(o);
                let mut ja = p.ja;
                ja[grad.0] += j.sign * grad.1;
                Kin { t: p.t.plus(o), cs: p.cs, v, w: p.w + j.sign * qd, jt, ja, bt, ba: p.ba + j.sign * qb }
            } else {
                let e = p.rot(j.slide);
                let u = o.plus(e.scale(q));
                let (t, v, mut jt, bt) = p.point(u);
                jt[grad.0] = jt[grad.0].plus(e.scale(grad.1));
                let bt = bt.plus(perp(e).scale(2.0 * p.w * qd)).plus(e.scale(qb));
                Kin { t, cs: p.cs, v: v.plus(e.scale(qd)), w: p.w, jt, ja: p.ja, bt, ba: p.ba }
            };
            // cos and sin of the child's angle by angle addition: the parent's, the origin's
            // pitch, and the hinge's turn.
            let (c2, s2) = if j.sign != 0.0 {
                let (sn, cn) = (j.origin.a + j.sign * q).sin_cos();
                (cn, sn)
            } else {
                j.origin_cs
            };
            let (c1, s1) = p.cs;
            c.cs = (c1 * c2 - s1 * s2, s1 * c2 + c1 * s2);
            out[j.child] = c;
        }
    }

    /// Total energy (J): kinetic of every link and the pelvis, potential in gravity (from
    /// z = 0), at state `x`.
    pub fn energy_j(&self, x: &[f64; NX]) -> f64 {
        self.with_kin(|kin| {
            self.kinematics(x, kin);
            self.energy_kin(kin, x)
        })
    }

    /// [`Self::energy_j`] at the link kinematics `kin` of state `x`.
    fn energy_kin(&self, kin: &[Kin], x: &[f64; NX]) -> f64 {
        let vp = (x[NG + PX], x[NG + PZ]);
        let mut e =
            0.5 * self.pelvis_mass_kg * (vp.0 * vp.0 + vp.1 * vp.1) + self.pelvis_mass_kg * GRAVITY_M_S2 * x[PZ];
        for (l, &(m, com, iyy)) in self.links.iter().enumerate() {
            let k = &kin[l];
            let (c, v, _, _) = k.point(k.rot(com));
            e += 0.5 * m * v.dot(v) + 0.5 * iyy * k.w * k.w + m * GRAVITY_M_S2 * c.z;
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::leg::geometry::{hip_knee_mass_matrix_at, potential_energy_with_hip_at};

    /// The forward pass's mass matrix and gravity forces against the knee-only engine's
    /// independent formulas (link poses differentiated numerically): the hip-knee block is
    /// `hip_knee_mass_matrix_at`'s, the gravity forces are `-dV/dq`, the pelvis rows carry the
    /// whole mass. Measured: the block to 8.8e-10 relative, gravity to 1.4e-8 (the
    /// numerical derivatives' error).
    #[test]
    fn mass_matrix_and_gravity_match_the_independent_formulas() {
        let m = LegSpec::from_urdf_str(crate::leg::BUILTIN_URDFS[0].1, "knee").unwrap();
        let w = WalkerModel::new(
            &m,
            WalkerMount::Carriage { pelvis_mass_kg: 60.0, hip_locked: false, tether_locked: false },
            None,
        )
        .unwrap();
        for (h_deg, k_deg) in [(0.0f64, 5.0f64), (20.0, 40.0), (-10.0, 80.0)] {
            let (h, k) = (h_deg.to_radians(), k_deg.to_radians());
            let mut x = [0.0; NX];
            (x[PZ], x[HIP], x[KNEE]) = (0.9, h, k);
            let mut kin = [Kin::default(); STACK_LINKS];
            w.kinematics(&x, &mut kin);
            let mut q = [0.0; NG];
            let mm = w.mass_matrix(&kin, Some(&mut q));
            let (mhh, mhk, mkk) = hip_knee_mass_matrix_at(&m, k).unwrap();
            let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-3);
            let block = [rel(mm[HIP][HIP], mhh), rel(mm[HIP][KNEE], mhk), rel(mm[KNEE][KNEE], mkk)];
            assert!(block.iter().all(|e| *e < 3e-9), "({h_deg}, {k_deg}): {block:?}");
            let e = 1e-6;
            let dv = |dh: f64, dk: f64| {
                (potential_energy_with_hip_at(&m, h + dh, k + dk).unwrap()
                    - potential_energy_with_hip_at(&m, h - dh, k - dk).unwrap())
                    / (2.0 * e)
            };
            let total = 60.0 + m.links().iter().map(|l| l.mass_kg).sum::<f64>();
            assert!(rel(q[PZ], -total * GRAVITY_M_S2) < 1e-12 && q[PX] == 0.0, "{q:?}");
            let gravity = [rel(q[HIP], -dv(e, 0.0)), rel(q[KNEE], -dv(0.0, e))];
            assert!(gravity.iter().all(|e| *e < 4e-8), "({h_deg}, {k_deg}): {gravity:?}");
        }
    }
}
