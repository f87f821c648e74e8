//! The muscle analysis of a run's samples: at each, the muscles' lengths and rates from the
//! joint angles and rates, their force-length-velocity at them, static optimisation of the
//! joint moments the wearer applied, and the metabolic rate of the result. OpenSim's static
//! optimisation with its metabolic probes, on the run as it goes; it changes no dynamics.
//!
//! The activations are static: the excitation is taken equal to the activation (OpenSim's
//! static optimisation has no activation dynamics either), so the probes' `A` is the
//! activation.

use super::metabolics::{MetabolicModel, MuscleConstants, MuscleState};
use super::optimize::{Column, Problem, Solver};
use super::path::Axis;
use super::{curves, MuscleSet};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// What static optimisation minimises (`wearer.muscle_cost`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MuscleCost {
    /// The sum of squared activations (OpenSim's default, Crowninshield and Brand 1981).
    #[default]
    ActivationSquared,
    /// The muscles' metabolic rate (a local minimum from the squared-activation optimum).
    Metabolic,
}

impl MuscleCost {
    /// The name in scenario files.
    pub fn as_str(&self) -> &'static str {
        match self {
            MuscleCost::ActivationSquared => "activation_squared",
            MuscleCost::Metabolic => "metabolic",
        }
    }
}

/// Values per muscle in a sample ([`Sample::values`]): activation, normalised fibre length,
/// fibre velocity over l_opt (1/s), active fibre force (N), tendon force (N), metabolic rate (W).
pub const PER_MUSCLE: [&str; 6] =
    ["activation", "fiber_length_norm", "fiber_velocity_norm", "active_force_n", "force_n", "metabolic_w"];
/// The sample's totals after the muscles' values.
pub const TOTALS: [&str; 10] = [
    "muscles_metabolic_w",
    "muscles_effort",
    "reserve_hip_nm",
    "reserve_knee_nm",
    "reserve_ankle_nm",
    "wearer_hip_moment_nm",
    "wearer_knee_moment_nm",
    "wearer_ankle_moment_nm",
    "muscle_hip_angle_deg",
    "muscles_outside_table",
];

/// The analysis's fixed part: the muscles scaled to the leg, the settings, and each muscle's
/// metabolic constants.
#[derive(Debug, Clone)]
pub struct MuscleSetup {
    /// The muscles, scaled.
    pub set: Arc<MuscleSet>,
    /// What static optimisation minimises.
    pub cost: MuscleCost,
    /// The probe.
    pub model: MetabolicModel,
    /// The reserves' optimal moment (N m).
    pub reserve_nm: f64,
    /// The subject's body mass (kg), for the basal rate and W/kg.
    pub body_mass_kg: f64,
    constants: Vec<MuscleConstants>,
    /// Each muscle's fibre height `l_opt sin(alpha_opt)` (m).
    heights_m: Vec<f64>,
    /// Per muscle, the grid of each spanned joint as an index into the set's distinct grids
    /// (their axes at a state are computed once for every muscle on them).
    grid_of: Vec<[usize; 3]>,
    /// How many distinct grids the paths have.
    grids: usize,
}

impl MuscleSetup {
    /// The analysis of `set` (scaled) with its settings, for a subject of `body_mass_kg`.
    pub fn new(
        set: Arc<MuscleSet>,
        cost: MuscleCost,
        model: MetabolicModel,
        reserve_nm: f64,
        body_mass_kg: f64,
    ) -> Self {
        let constants = set
            .muscles
            .iter()
            .map(|m| MuscleConstants {
                mass_kg: m.params.mass_kg(),
                slow_twitch: m.params.slow_twitch_fraction,
                optimal_length_m: m.params.optimal_fiber_length_m,
                max_velocity_lopt_per_s: m.params.max_contraction_velocity_lopt_per_s,
            })
            .collect();
        let heights_m = set
            .muscles
            .iter()
            .map(|m| m.params.optimal_fiber_length_m * m.params.pennation_at_optimal_rad.sin())
            .collect();
        let mut keys = Vec::new();
        let grid_of = set
            .muscles
            .iter()
            .map(|m| {
                let mut g = [0; 3];
                for (k, slot) in g.iter_mut().enumerate().take(m.path.joints.len()) {
                    let key = m.path.grid(k);
                    *slot = keys.iter().position(|x| *x == key).unwrap_or_else(|| {
                        keys.push(key);
                        keys.len() - 1
                    });
                }
                g
            })
            .collect();
        let grids = keys.len();
        Self { set, cost, model, reserve_nm, body_mass_kg, constants, heights_m, grid_of, grids }
    }

    /// The number of values a sample carries.
    pub fn width(&self) -> usize {
        self.set.muscles.len() * PER_MUSCLE.len() + TOTALS.len()
    }

    /// The muscles' names.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.set.muscles.iter().map(|m| m.params.name.as_str())
    }

    /// The column names of a sample's values (`muscle_<name>_<value>`, then the totals).
    pub fn column_names(&self) -> Vec<String> {
        let mut out: Vec<String> =
            self.names().flat_map(|n| PER_MUSCLE.iter().map(move |v| format!("muscle_{n}_{v}"))).collect();
        out.extend(TOTALS.iter().map(|s| s.to_string()));
        out
    }
}

/// One sample's inputs: joint angles and rates (rad, rad/s; hip flexion, knee flexion, ankle
/// dorsiflexion) and the moments the wearer applies (N m, the same signs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Joints {
    /// Angles (rad).
    pub q_rad: [f64; 3],
    /// Rates (rad/s).
    pub qd_rad_s: [f64; 3],
    /// Moments (N m).
    pub moment_nm: [f64; 3],
}

/// A sample's results, flat ([`PER_MUSCLE`] per muscle, then [`TOTALS`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// The values.
    pub values: Vec<f64>,
}

/// The leg's muscles' metabolic rate (W; `muscles_metabolic_w`: this leg alone, no basal
/// rate) from a sample's values ([`Sample::values`], or a recorded row's muscle values).
pub fn metabolic_w(values: &[f64]) -> f64 {
    values[values.len() - TOTALS.len()]
}

/// One muscle at a joint state: its moment arms (m), whether the angles were inside its
/// table, its fibre, active force-length multiplier, the moment column's scale `F_max f_L f_V
/// cos(alpha)` (N) and its passive force along the tendon (N).
#[derive(Debug, Clone, Copy, Default)]
pub struct MuscleEval {
    arms: [f64; 3],
    inside: bool,
    fibre: curves::Fibre,
    fl: f64,
    k: f64,
    pe: f64,
}

/// One muscle's path and fibre at a joint state: its moment arms (m), whether the angles were
/// inside its table, its fibre.
#[derive(Debug, Clone, Copy, Default)]
struct Geometry {
    arms: [f64; 3],
    inside: bool,
    fibre: curves::Fibre,
}

/// The analysis as it runs: the solver's warm start and the last activations.
#[derive(Debug, Clone)]
pub struct Analysis {
    setup: Arc<MuscleSetup>,
    solver: Solver,
    act: Vec<f64>,
    columns: Vec<Column>,
    /// Each muscle at the last state evaluated.
    evals: Vec<MuscleEval>,
    /// The geometry of each muscle being evaluated.
    geometry: Vec<Geometry>,
    /// The distinct grids' axes at the state being evaluated (None: not yet computed).
    axes: Vec<Option<Axis>>,
    /// How many muscles were outside their tables at the last state evaluated.
    outside: usize,
    w: Vec<f64>,
    c: Vec<f64>,
}

impl Analysis {
    /// A fresh analysis.
    pub fn new(setup: Arc<MuscleSetup>) -> Self {
        let (n, grids) = (setup.set.muscles.len(), setup.grids);
        Self {
            setup,
            solver: Solver::default(),
            act: vec![curves::MIN_ACTIVATION; n],
            columns: vec![[0.0; 3]; n],
            evals: vec![Default::default(); n],
            geometry: vec![Geometry::default(); n],
            axes: vec![None; grids],
            outside: 0,
            w: vec![1.0; n],
            c: Vec::new(),
        }
    }

    /// The setup.
    pub fn setup(&self) -> &Arc<MuscleSetup> {
        &self.setup
    }

    /// Muscle `i`'s path and fibre at the state of `j`, its path's axes from (and into)
    /// `self.axes`: the first half of its evaluation ([`Self::curves`] the second).
    fn geometry(&mut self, i: usize, j: &Joints) -> Geometry {
        let set = &self.setup.set;
        let path = &set.muscles[i].path;
        let mut axes = [Axis::default(); 3];
        for (k, a) in axes.iter_mut().enumerate().take(path.joints.len()) {
            *a = *self.axes[self.setup.grid_of[i][k]].get_or_insert_with(|| path.axis(k, j.q_rad));
        }
        let (l, arms, inside) = set.length_arms_inside_axes(i, &axes);
        let v_mt = -(arms[0] * j.qd_rad_s[0] + arms[1] * j.qd_rad_s[1] + arms[2] * j.qd_rad_s[2]);
        let p = &set.muscles[i].params;
        let w = self.setup.heights_m[i];
        let fibre = curves::fibre_with_height(l, v_mt, p.tendon_slack_length_m, p.optimal_fiber_length_m, w);
        Geometry { arms, inside, fibre }
    }

    /// Muscle `i` with its geometry `g`: its force-length, force-velocity and passive curves.
    fn curves(&self, i: usize, g: Geometry) -> MuscleEval {
        let Geometry { arms, inside, fibre } = g;
        let p = &self.setup.set.muscles[i].params;
        let ln = fibre.length_norm.clamp(curves::MIN_NORM_FIBER_LENGTH, curves::MAX_NORM_FIBER_LENGTH);
        let vn = (fibre.velocity_per_s / p.max_contraction_velocity_lopt_per_s).clamp(-1.0, 1.0);
        let fl = curves::active_force_length(ln);
        let k = p.max_isometric_force_n * fl * curves::force_velocity(vn) * fibre.cos_pennation;
        let pe = p.max_isometric_force_n * curves::passive_force_length(ln) * fibre.cos_pennation;
        MuscleEval { arms, inside, fibre, fl, k, pe }
    }

    /// The muscles at `j`: fibres, the moment columns and the passive moments. The paths and
    /// fibres of every muscle first, then their curves: the curves' library calls side by side
    /// (independent work the processor overlaps), the same bits as muscle by muscle.
    fn muscles_at(&mut self, j: &Joints) -> ([f64; 3], usize) {
        self.axes.iter_mut().for_each(|a| *a = None);
        for i in 0..self.evals.len() {
            self.geometry[i] = self.geometry(i, j);
        }
        for i in 0..self.evals.len() {
            self.evals[i] = self.curves(i, self.geometry[i]);
        }
        self.load()
    }

    /// The moment columns from `self.evals`; the passive moments (N m) and how many muscles
    /// are outside their tables.
    fn load(&mut self) -> ([f64; 3], usize) {
        let mut passive_moment = [0.0; 3];
        let mut outside = 0;
        for (e, col) in self.evals.iter().zip(&mut self.columns) {
            outside += usize::from(!e.inside);
            *col = e.arms.map(|r| r * e.k);
            for (pm, r) in passive_moment.iter_mut().zip(e.arms) {
                *pm += r * e.pe;
            }
        }
        self.outside = outside;
        (passive_moment, outside)
    }

    /// Every muscle at the state of `j`.
    pub fn evaluate(&mut self, j: &Joints) -> &[MuscleEval] {
        self.muscles_at(j);
        &self.evals
    }

    /// The metabolic rate (W) of muscle `i` at activation `a`.
    fn rate_w(&self, i: usize, a: f64) -> f64 {
        self.rate_of(i, a, a)
    }

    /// The metabolic rate (W) of muscle `i` at activation `a` under excitation `u`.
    fn rate_of(&self, i: usize, a: f64, u: f64) -> f64 {
        let MuscleEval { fibre: f, fl, k, pe, .. } = self.evals[i];
        let p = &self.setup.set.muscles[i].params;
        let s = MuscleState {
            excitation: u,
            activation: a,
            length_norm: f.length_norm,
            velocity_m_s: f.velocity_per_s * p.optimal_fiber_length_m,
            active_force_n: a * k / f.cos_pennation,
            passive_force_n: pe / f.cos_pennation,
            force_length: fl,
        };
        self.setup.model.rate_w(&self.setup.constants[i], &s)
    }

    /// The sample at `j`: static optimisation of `j.moment_nm`, its activations as the
    /// excitations.
    pub fn sample(&mut self, j: &Joints) -> Sample {
        let (reserve, outside) = self.optimise(j);
        let act = std::mem::take(&mut self.act);
        let s = self.values(j, &act, &act, reserve, outside);
        self.act = act;
        s
    }

    /// Static optimisation at `j`: `self.act` the activations that make `j.moment_nm`; the
    /// reserves (what the muscles cannot, N m) and how many muscles left their tables.
    fn optimise(&mut self, j: &Joints) -> ([f64; 3], usize) {
        let (passive_moment, outside) = self.muscles_at(j);
        (self.optimise_loaded(j.moment_nm, passive_moment), outside)
    }

    /// Static optimisation of `moment_nm` (N m) among the muscles as loaded, whose passive
    /// moments are `passive_moment` (N m): `self.act`; the reserves (N m).
    fn optimise_loaded(&mut self, moment_nm: [f64; 3], passive_moment: [f64; 3]) -> [f64; 3] {
        let b = [0, 1, 2].map(|k| moment_nm[k] - passive_moment[k]);
        self.w.iter_mut().for_each(|w| *w = 1.0);
        self.c.clear();
        let rho = self.setup.reserve_nm;
        let p = Problem { columns: &self.columns, b, w: &self.w, c: &self.c, lo: curves::MIN_ACTIVATION, rho };
        let out = self.solver.solve(&p, &mut self.act);
        if self.setup.cost == MuscleCost::Metabolic {
            return self.metabolic_descent(b);
        }
        out.reserve_nm
    }

    /// The excitations a nervous system sends for the moments `moment_nm` (N m) with each
    /// muscle as it knows it, `seen` (an evaluation of each, [`Self::evaluate`]'s at some state):
    /// static optimisation, into `out`; the reserves: what the muscles cannot (N m).
    pub fn excitations_seen(
        &mut self,
        moment_nm: [f64; 3],
        seen: impl Iterator<Item = MuscleEval>,
        out: &mut [f64],
    ) -> [f64; 3] {
        for (e, s) in self.evals.iter_mut().zip(seen) {
            *e = s;
        }
        let (passive_moment, _) = self.load();
        let reserve = self.optimise_loaded(moment_nm, passive_moment);
        out.copy_from_slice(&self.act);
        reserve
    }

    /// The muscles' moments about hip, knee and ankle (N m; flexion and dorsiflexion positive)
    /// of the muscles `evals` ([`Self::evaluate`]'s at some state)
    /// with activations `a`, passive forces included.
    pub fn moments_of(&mut self, evals: &[MuscleEval], a: &[f64]) -> [f64; 3] {
        self.evals.copy_from_slice(evals);
        let (mut m, _) = self.load();
        for (col, a) in self.columns.iter().zip(a) {
            (0..3).for_each(|k| m[k] += col[k] * a);
        }
        m
    }

    /// The sample of muscles at activations `a` under excitations `u` (a muscle wearer's), at
    /// the state of the last [`Self::moments_of`] call, which `j` repeats with the moments the
    /// muscles make (its angles are read for the record only), with the reserves `reserve`:
    /// into `out` ([`MuscleSetup::width`] values).
    pub fn sample_after_moments(&self, j: &Joints, a: &[f64], u: &[f64], reserve: [f64; 3], out: &mut [f64]) {
        self.values_into(j, a, u, reserve, self.outside, out);
    }

    /// The sample's values at the fibres now.
    fn values(&self, j: &Joints, act: &[f64], exc: &[f64], reserve: [f64; 3], outside: usize) -> Sample {
        let mut values = vec![0.0; self.setup.width()];
        self.values_into(j, act, exc, reserve, outside, &mut values);
        Sample { values }
    }

    /// [`Self::values`] into `out` ([`MuscleSetup::width`] values).
    fn values_into(&self, j: &Joints, act: &[f64], exc: &[f64], reserve: [f64; 3], outside: usize, out: &mut [f64]) {
        let (per_muscle, totals) = out.split_at_mut(act.len() * PER_MUSCLE.len());
        let (mut total_w, mut effort) = (0.0, 0.0);
        for (i, ((&a, &u), slot)) in act.iter().zip(exc).zip(per_muscle.chunks_exact_mut(PER_MUSCLE.len())).enumerate()
        {
            let MuscleEval { fibre: f, k, pe, .. } = self.evals[i];
            let rate = self.rate_of(i, a, u);
            total_w += rate;
            effort += a * a;
            let active = a * k / f.cos_pennation;
            slot.copy_from_slice(&[a, f.length_norm, f.velocity_per_s, active, a * k + pe, rate]);
        }
        let [rh, rk, ra] = reserve;
        let [mh, mk, ma] = j.moment_nm;
        let t = [total_w, effort, rh, rk, ra, mh, mk, ma, j.q_rad[0].to_degrees(), outside as f64];
        totals.copy_from_slice(&t);
    }

    /// Sequential convex quadratics of the muscles' metabolic rates from the activations now
    /// (the squared-activation optimum): each step's quadratic has the rate's slope and its
    /// curvature (floored to stay convex), a step is kept when the true objective (the rates
    /// and the reserves at 100 W per (rho N m)^2) falls. Returns the reserves.
    #[allow(clippy::needless_range_loop)] // per muscle, several vectors
    fn metabolic_descent(&mut self, b: [f64; 3]) -> [f64; 3] {
        let n = self.act.len();
        let rho = self.setup.reserve_nm / 10.0;
        let objective = |this: &Self, x: &[f64]| -> f64 {
            let mut r = b;
            for (col, a) in this.columns.iter().zip(x) {
                (0..3).for_each(|k| r[k] -= col[k] * a);
            }
            (0..n).map(|i| this.rate_w(i, x[i])).sum::<f64>() + r.iter().map(|v| (v / rho).powi(2)).sum::<f64>()
        };
        let mut best = objective(self, &self.act);
        let h = 1e-4;
        for _ in 0..12 {
            let x0 = self.act.clone();
            self.c.clear();
            for i in 0..n {
                let a = x0[i].clamp(curves::MIN_ACTIVATION + h, 1.0 - h);
                let (e0, ep, em) = (self.rate_w(i, a), self.rate_w(i, a + h), self.rate_w(i, a - h));
                let slope = (ep - em) / (2.0 * h);
                let curv = ((ep - 2.0 * e0 + em) / (h * h)).max(1e-3 * self.setup.constants[i].mass_kg * 100.0);
                self.w[i] = 0.5 * curv;
                self.c.push(curv * x0[i] - slope);
            }
            let p = Problem { columns: &self.columns, b, w: &self.w, c: &self.c, lo: curves::MIN_ACTIVATION, rho };
            let mut x = x0.clone();
            self.solver.solve(&p, &mut x);
            let mut step = 1.0;
            let mut improved = false;
            while step > 1e-3 {
                let trial: Vec<f64> = x0.iter().zip(&x).map(|(a, b)| a + step * (b - a)).collect();
                let f = objective(self, &trial);
                if f < best - 1e-9 * best.abs() {
                    (best, improved) = (f, true);
                    self.act = trial;
                    break;
                }
                step *= 0.5;
            }
            if !improved {
                break;
            }
        }
        let mut r = b;
        for (col, a) in self.columns.iter().zip(&self.act) {
            (0..3).for_each(|k| r[k] -= col[k] * a);
        }
        r
    }
}
