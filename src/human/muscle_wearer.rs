//! A wearer as strong and as slow as a person (issue 40, `wearer.model = "muscles"`): the
//! leg's muscles make the wearer's hip, knee and ankle moments, under a nervous system that
//! sees the body a neural delay late.
//!
//! Each step from `t` (the neural sample is the loop's step):
//!
//! ```text
//! sensed(t)  = the learned gait's angles and rates less the body's, the device's knee torque
//! seen       = sensed(t - delay)                               (the delay line)
//! asked      = M_ff(phase) + K(w) e_seen,now + D(w) e'_seen - [adapted] M_device,seen
//! target     = static optimisation of `asked` among the muscles, each at the body's state its
//!              reflex loop's delay ago (hip, knee or ankle group; the squared activations,
//!              reserves where the muscles cannot: reported, not applied)
//! u          = the excitation that brings each activation to its target in the step, or 0 / 1
//! M_muscles  = sum_i r_i (a_i F_max f_L f_V + F_passive) cos(alpha)  at the state now   (held over the step)
//! a(t + dt)  = u + (a - u) exp(-g(u, a) dt),  g: De Groote's activation rate (15 / 60 ms)
//! ```
//! `M_ff` and the gait it makes are the wearer's internal model ([`Feedforward`]): the moments
//! the body needed, per % of the cycle, to walk the data's gait without the device, learned in
//! a run of the impedance wearer before this one (a person adapted to walking knows them; the
//! data's own moments belong to a body of other segments, on two legs). `e_seen,now` is the
//! deviation seen a delay ago carried forward over the delay along its rate (a forward model of
//! the delay). `K(w)`, `D(w)`: the reflexive part of a walking person's joint impedance, blended
//! between stance and swing by the data's stance weight `w` (reflex gains are modulated over
//! the cycle, low in swing; the sources are in [`crate::human::WearerParams`]). The muscles'
//! own force-length and force-velocity add their intrinsic stiffness and damping without
//! delay. What the muscles cannot make (`asked` beyond them) is reported as the reserves and not
//! applied: a wearer who cannot hold the gait falls behind it.

use crate::muscles::analysis::{Analysis, Joints, MuscleEval, MuscleSetup};
use crate::muscles::curves;
use std::collections::VecDeque;
use std::sync::Arc;

/// The gait the wearer learned: its hip, knee and ankle moments (N m, flexion and
/// dorsiflexion positive) with the angles (rad, the hip the thigh's to the vertical) and rates
/// (rad/s) they made, and the device's knee moment it walked with (N m), per bin of the cycle
/// (bin `i` centred at `(i + 0.5) 100 / n` %), interpolated periodically.
#[derive(Debug, Clone, PartialEq)]
pub struct Feedforward {
    bins: Vec<[[f64; 3]; 3]>,
    device_nm: Vec<f64>,
}

/// Bins of a learned gait (1 % of the cycle each).
pub const FEEDFORWARD_BINS: usize = 100;

/// One sample of a learning run: % of the cycle; moments, angles, rates; the device's knee
/// moment (N m).
pub type LearnedSample = (f64, [[f64; 3]; 3], f64);

impl Feedforward {
    /// The bins' means of `samples`. None when a bin has no sample (a step longer than a bin,
    /// or too short a run).
    pub fn learn(samples: &[LearnedSample]) -> Option<Self> {
        let n = FEEDFORWARD_BINS;
        let mut sums = vec![([[0.0; 3]; 3], 0.0, 0usize); n];
        for (pct, v, device) in samples {
            let (sum, dev, count) = &mut sums[bin_of(n, *pct)];
            for (s, x) in sum.iter_mut().flatten().zip(v.iter().flatten()) {
                *s += x;
            }
            *dev += device;
            *count += 1;
        }
        let (bins, device_nm) = sums
            .into_iter()
            .map(|(sum, dev, count)| {
                (count > 0).then(|| (sum.map(|r| r.map(|x| x / count as f64)), dev / count as f64))
            })
            .collect::<Option<(Vec<_>, Vec<_>)>>()?;
        Some(Self { bins, device_nm })
    }

    /// Moments (N m), angles (rad) and rates (rad/s) at `pct` % of the cycle.
    pub fn at(&self, pct: f64) -> [[f64; 3]; 3] {
        let (i, k, f) = between_bins(self.bins.len(), pct);
        let (a, b) = (&self.bins[i], &self.bins[k]);
        std::array::from_fn(|r| std::array::from_fn(|j| a[r][j] + f * (b[r][j] - a[r][j])))
    }

    /// The device's knee moment of the learning run per bin (N m, flexion positive).
    pub fn device_bins(&self) -> &[f64] {
        &self.device_nm
    }
}

/// The bins either side of `pct` % of the cycle among `n` bins centred at `(i + 0.5) 100 / n`
/// %, and the fraction of the way from the first to the second.
fn between_bins(n: usize, pct: f64) -> (usize, usize, f64) {
    let x = crate::reference::rem_euclid_100(pct) / 100.0 * n as f64 - 0.5;
    let lo = x.floor();
    let i = (lo as isize).rem_euclid(n as isize) as usize;
    (i, (i + 1) % n, x - lo)
}

/// Bins of the cycle interpolated at `pct` % (periodic).
fn interpolate_bins(bins: &[f64], pct: f64) -> f64 {
    let (i, k, f) = between_bins(bins.len(), pct);
    bins[i] + f * (bins[k] - bins[i])
}

/// The bin of `pct` % of the cycle among `n`.
fn bin_of(n: usize, pct: f64) -> usize {
    ((crate::reference::rem_euclid_100(pct) / 100.0 * n as f64) as usize).min(n - 1)
}

/// How fast the adapted wearer's expectation of the device's moment follows what it feels
/// (strides: the time constant of its exponential average at each % of the cycle).
pub const DEVICE_ADAPTATION_STRIDES: f64 = 1.0;

/// Each muscle's reflex group (0 hip, 1 knee, 2 ankle) from the joints its path spans
/// (indices into [`crate::muscles::path::JOINTS`]): a muscle spanning the hip is a hip muscle,
/// else one spanning the ankle an ankle muscle, else a knee muscle. So the two-joint muscles
/// about the knee go with their other joint, as Geyer and Herr 2010 group them (SCONE's
/// `ControllerGH2010M18.scone`: hamstrings and rectus femoris 5 ms with the hip's muscles,
/// gastrocnemius 20 ms with the ankle's, vasti and biceps femoris short head 10 ms).
pub fn muscle_groups(spans: impl Iterator<Item = impl AsRef<[usize]>>) -> Vec<usize> {
    spans
        .map(|j| {
            let j = j.as_ref();
            if j.contains(&0) {
                0
            } else if j.contains(&2) {
                2
            } else {
                1
            }
        })
        .collect()
}

/// The muscle wearer, resolved: its muscles and analysis settings, its delay, its feedback
/// gains (scaled by the subject's mass), its learned gait.
#[derive(Debug, Clone)]
pub struct MuscleWearerSetup {
    /// The muscles (scaled to the leg) and the static optimisation's settings.
    pub muscles: Arc<MuscleSetup>,
    /// The neural delays of the hip's, the knee's and the ankle's feedback (s).
    pub delay_s: [f64; 3],
    /// Each muscle's reflex group: the joint (0 hip, 1 knee, 2 ankle) whose delay it is seen
    /// with ([`muscle_groups`]).
    pub muscle_group: Vec<usize>,
    /// Discounts the device's moment it expects.
    pub adapted: bool,
    /// Feedback stiffness about hip, knee, ankle in stance and in swing (N m/rad).
    pub stiffness_nm_per_rad: [[f64; 3]; 2],
    /// Feedback damping in stance and in swing (N m s/rad).
    pub damping_nm_s_per_rad: [[f64; 3]; 2],
    /// The gait it learned.
    pub feedforward: Arc<Feedforward>,
}

/// What the wearer senses at an instant.
#[derive(Debug, Clone, Copy, Default)]
struct Sensed {
    t_s: f64,
    pct: f64,
    error_rad: [f64; 3],
    error_rate_rad_s: [f64; 3],
    device_torque_nm: f64,
}

/// One step's inputs: the body now and where it is in the cycle.
#[derive(Debug, Clone, Copy, Default)]
pub struct WearerInputs {
    /// Hip (anatomical flexion: the thigh's angle plus the pelvic tilt), knee and ankle angles
    /// (rad) and rates (rad/s) now: the muscles' state.
    pub joints: Joints,
    /// The body's hip (the thigh's to the vertical), knee and ankle angles (rad): the learned
    /// gait's frame.
    pub body_rad: [f64; 3],
    /// Their rates (rad/s).
    pub body_rate_rad_s: [f64; 3],
    /// Where the gait is (% of the cycle).
    pub pct: f64,
    /// The data's stance weight now (0 swing .. 1 stance).
    pub stance_weight: f64,
    /// The device's torque at the knee now (N m, flexion positive).
    pub device_torque_nm: f64,
}

/// What the adapted wearer felt of the device in this stride: the bin it is in, and per bin
/// the sum and count of the moments felt there since it last entered it.
#[derive(Debug, Clone)]
struct DeviceFelt {
    bin: Option<usize>,
    felt: Vec<Option<(f64, usize)>>,
}

/// The muscle wearer as it runs: activations, the delay line, the last sample.
#[derive(Debug, Clone)]
pub struct MuscleWearer {
    setup: Arc<MuscleWearerSetup>,
    analysis: Analysis,
    act: Vec<f64>,
    /// Excitations sent over the current step (and the next step's starting guess).
    exc: Vec<f64>,
    /// The activations static optimisation asks for.
    target: Vec<f64>,
    /// The activations at the step's end (what the excitations reach).
    next_act: Vec<f64>,
    line: VecDeque<Sensed>,
    /// The muscles at the body's state of each entry of `line`: what the nervous system knows
    /// of each muscle its delay later.
    body: VecDeque<Vec<MuscleEval>>,
    /// The delay line's memory of the muscles, kept for the next entry.
    spare: Vec<MuscleEval>,
    /// The device's moment the adapted wearer expects per bin of the cycle (N m).
    expected_device_nm: Vec<f64>,
    device: DeviceFelt,
    started: bool,
    /// The muscles' moments over the current step (N m).
    made_nm: [f64; 3],
    /// What the nervous system asked of them (N m).
    asked_nm: [f64; 3],
    reserve_nm: [f64; 3],
    last: Option<(f64, Arc<[f64]>)>,
}

impl MuscleWearer {
    /// A wearer at rest (its first step starts its activations where it asks them).
    pub fn new(setup: Arc<MuscleWearerSetup>) -> Self {
        let n = setup.muscles.set.muscles.len();
        Self {
            analysis: Analysis::new(setup.muscles.clone()),
            act: vec![curves::MIN_ACTIVATION; n],
            exc: vec![curves::MIN_ACTIVATION; n],
            target: vec![curves::MIN_ACTIVATION; n],
            next_act: vec![curves::MIN_ACTIVATION; n],
            line: VecDeque::new(),
            body: VecDeque::new(),
            spare: Vec::new(),
            // At first it expects the device it learned the gait with.
            expected_device_nm: setup.feedforward.device_bins().to_vec(),
            device: DeviceFelt { bin: None, felt: vec![None; FEEDFORWARD_BINS] },
            started: false,
            made_nm: [0.0; 3],
            asked_nm: [0.0; 3],
            reserve_nm: [0.0; 3],
            last: None,
            setup,
        }
    }

    /// Record what the wearer senses now; drop what no delay needs.
    fn sense(&mut self, now: Sensed) {
        self.line.push_back(now);
        let due = now.t_s - self.setup.delay_s.iter().fold(0.0, |m: f64, &d| m.max(d));
        while self.line.len() > 1 && self.line[1].t_s <= due + 1e-12 {
            self.line.pop_front();
            if let Some(v) = self.body.pop_front() {
                self.spare = v;
            }
        }
    }

    /// The moments the nervous system asks for at `t_s` (N m), with `seen` the delay line's
    /// entries each joint's delay ago ([`seen_index`]) and `ff` the learned gait's moments now
    /// (N m).
    fn asked(&mut self, t_s: f64, x: &WearerInputs, seen: [usize; 3], ff: [f64; 3]) -> [f64; 3] {
        let s = &self.setup;
        let w = x.stance_weight.clamp(0.0, 1.0);
        let blend = |g: &[[f64; 3]; 2], j: usize| w * g[0][j] + (1.0 - w) * g[1][j];
        let fb = [0, 1, 2].map(|j| {
            let seen = &self.line[seen[j]];
            // The deviation seen a delay ago, carried forward over the delay along its rate.
            let delay = (t_s - seen.t_s).max(0.0);
            let e = seen.error_rad[j] + seen.error_rate_rad_s[j] * delay;
            blend(&s.stiffness_nm_per_rad, j) * e + blend(&s.damping_nm_s_per_rad, j) * seen.error_rate_rad_s[j]
        });
        let mut asked = [0, 1, 2].map(|j| ff[j] + fb[j]);
        if s.adapted {
            // The knee moment the gait took, the device's part of it as it was in the
            // learning run less what the wearer now expects of the device.
            let learned = interpolate_bins(s.feedforward.device_bins(), x.pct);
            asked[1] += learned - self.expect_device(self.line[seen[1]], x.pct);
        }
        asked
    }

    /// The device's moment the adapted wearer expects at `pct` (N m): at each % of the cycle
    /// an exponential average over [`DEVICE_ADAPTATION_STRIDES`] of the strides before this
    /// one of what it felt there (a knee's delay late). A wearer used to the device knows its
    /// pattern; a change, a fault, is felt as a push until it has walked with it a while.
    /// `felt`: what it sensed a knee's delay ago.
    fn expect_device(&mut self, felt: Sensed, pct: f64) -> f64 {
        let n = self.expected_device_nm.len();
        let b = bin_of(n, felt.pct);
        let d = &mut self.device;
        if d.bin != Some(b) {
            // Entering a bin: what was felt there a stride ago joins the expectation.
            if let Some((sum, count)) = d.felt[b].filter(|(_, c)| *c > 0) {
                let keep = (-1.0 / DEVICE_ADAPTATION_STRIDES).exp();
                let e = &mut self.expected_device_nm[b];
                *e = keep * *e + (1.0 - keep) * sum / count as f64;
            }
            d.felt[b] = Some((0.0, 0));
            d.bin = Some(b);
        }
        if let Some((sum, count)) = d.felt[b].as_mut() {
            *sum += felt.device_torque_nm;
            *count += 1;
        }
        interpolate_bins(&self.expected_device_nm, pct)
    }

    /// One step of `dt_s` from `t_s`: returns the muscles' moments about hip, knee and ankle
    /// over it (N m, flexion and dorsiflexion positive).
    pub fn step(&mut self, t_s: f64, dt_s: f64, x: &WearerInputs) -> [f64; 3] {
        let [ff, q, qd] = self.setup.feedforward.at(x.pct);
        self.sense(Sensed {
            t_s,
            pct: x.pct,
            error_rad: [0, 1, 2].map(|j| q[j] - x.body_rad[j]),
            error_rate_rad_s: [0, 1, 2].map(|j| qd[j] - x.body_rate_rad_s[j]),
            device_torque_nm: x.device_torque_nm,
        });
        let seen = self.setup.delay_s.map(|d| seen_index(&self.line, t_s, d));
        let asked = self.asked(t_s, x, seen, ff);
        // The muscles now, kept beside the delay line's newest entry: what the nervous system
        // knows of each a delay later.
        let mut now = std::mem::take(&mut self.spare);
        now.clear();
        now.extend_from_slice(self.analysis.evaluate(&x.joints));
        self.body.push_back(now);
        // The activations that would make the asked moments (static optimisation) with each
        // muscle as the nervous system knows it: its state its reflex loop's delay ago.
        let (body, group) = (&self.body, &self.setup.muscle_group);
        let known = group.iter().enumerate().map(|(i, &g)| body[seen[g]][i]);
        self.reserve_nm = self.analysis.excitations_seen(asked, known, &mut self.target);
        if !self.started {
            // A person standing in the gait, not a limp leg: activations start where asked.
            self.act.copy_from_slice(&self.target);
            self.exc.copy_from_slice(&self.target);
            self.started = true;
        }
        let now = self.body.back().map(Vec::as_slice).unwrap_or_default();
        self.made_nm = self.analysis.moments_of(now, &self.act);
        self.asked_nm = asked;
        excitations_for(&self.act, &self.target, dt_s, &mut self.exc, &mut self.next_act);
        let state = Joints { moment_nm: self.made_nm, ..x.joints };
        // The last step's sample's memory when no record holds it any more.
        let mut values = match self.last.take() {
            Some((_, v)) if Arc::strong_count(&v) == 1 && Arc::weak_count(&v) == 0 => v,
            _ => vec![0.0; self.analysis.setup().width()].into(),
        };
        if let Some(out) = Arc::get_mut(&mut values) {
            self.analysis.sample_after_moments(&state, &self.act, &self.exc, self.reserve_nm, out);
        }
        self.last = Some((t_s, values));
        std::mem::swap(&mut self.act, &mut self.next_act);
        self.made_nm
    }

    /// The muscles' sample of the step from `t_s` ([`crate::muscles::analysis::Sample`]'s
    /// values; None before it).
    pub fn sample_at(&self, t_s: f64) -> Option<&Arc<[f64]>> {
        self.last.as_ref().filter(|(t, _)| *t == t_s).map(|(_, s)| s)
    }

    /// What the nervous system asked over the step (N m) and what the muscles could not (N m).
    pub fn asked_and_reserves(&self) -> ([f64; 3], [f64; 3]) {
        (self.asked_nm, self.reserve_nm)
    }
}

/// The index in the delay line `line` of what was sensed `delay_s` before `t_s` (the oldest
/// entry at the start).
fn seen_index(line: &VecDeque<Sensed>, t_s: f64, delay_s: f64) -> usize {
    let due = t_s - delay_s + 1e-12;
    line.partition_point(|s| s.t_s <= due).saturating_sub(1)
}

/// De Groote's activation dynamics `da/dt = g(u, a) (u - a)` ([`curves::activation_rate`]):
/// the gain's slopes at activation `a`, `1 / (tau_a z)` and `z / tau_d` with `z = 1/2 + 3a/2`
/// (1/s).
fn gain_slopes(a: f64) -> (f64, f64) {
    let z = 0.5 + 1.5 * a;
    (1.0 / (curves::ACTIVATION_TIME_CONSTANT_S * z), z / curves::DEACTIVATION_TIME_CONSTANT_S)
}

/// De Groote's switch between activation and deactivation, `tanh(b (u - a))` at `u - a`, as
/// `1 - 2 / (exp(2 b (u - a)) + 1)`: one exponential instead of the library's tanh (about twice
/// its cost here); within 3.3e-16 of it (|u - a| <= 1, so the exponential stays finite), and the
/// gain uses it only through `1/2 +- tanh/2` and `1 - tanh^2`.
fn switch(u_minus_a: f64) -> f64 {
    1.0 - 2.0 / ((2.0 * curves::ACTIVATION_SMOOTHING * u_minus_a).exp() + 1.0)
}

/// The gain `g = (f + 1/2) slope_a + (1/2 - f) slope_d` (1/s) and its derivative in `u`
/// (1/s) from `th = tanh(b (u - a))`, `f = th / 2`.
fn gain(th: f64, (slope_a, slope_d): (f64, f64)) -> (f64, f64) {
    let f = 0.5 * th;
    let g = (f + 0.5) * slope_a + (0.5 - f) * slope_d;
    (g, 0.5 * curves::ACTIVATION_SMOOTHING * (1.0 - th * th) * (slope_a - slope_d))
}

/// The activation after `dt_s` from `a` under excitation `u`, the rate's gain frozen over the
/// step (exact for that gain; De Groote et al. 2016's dynamics).
pub fn activation_after(a: f64, u: f64, dt_s: f64) -> f64 {
    u + (a - u) * kept(a, u, dt_s)
}

/// The part of its distance to `u` activation `a` keeps over `dt_s`: `exp(-g(u, a) dt)`.
fn kept(a: f64, u: f64, dt_s: f64) -> f64 {
    let (g, _) = gain(switch(u - a), gain_slopes(a));
    (-g * dt_s).exp()
}

/// Muscles whose excitations are computed side by side: each phase of a Newton step (the
/// gains' switch, then their exponentials) runs for all of them before the next, so the
/// processor overlaps their independent work instead of waiting on one muscle's chain of
/// library calls.
const LANES: usize = 8;

/// The excitation (0..1) that brings activation `a` to `target` in `dt_s` as fast as the
/// activation dynamics allow (the inverse of [`activation_after`], computed muscle control's
/// rule): the target itself when it is reached in the step, else full excitation (rising) or
/// none (falling), so activations rise and fall at their physiological rates. `guess`: a
/// starting point (the muscle's excitation a step before: Newton's method from there takes
/// one or two steps; any value in 0..=1 gives the same answer to 1e-13).
pub fn excitation_for(a: f64, target: f64, dt_s: f64, guess: f64) -> f64 {
    let (mut u, mut after) = ([guess], [0.0]);
    excitations_for(&[a], &[target], dt_s, &mut u, &mut after);
    u[0]
}

/// [`excitation_for`] for every muscle: `u[i]` (its value the guess) the excitation that
/// brings `a[i]` to `target[i]` in `dt_s`, and `after[i]` the activation it brings it to
/// ([`activation_after`] of the excitation, from the solver's last evaluation).
pub fn excitations_for(a: &[f64], target: &[f64], dt_s: f64, u: &mut [f64], after: &mut [f64]) {
    let chunks = a.chunks(LANES).zip(target.chunks(LANES)).zip(u.chunks_mut(LANES).zip(after.chunks_mut(LANES)));
    for ((a, target), (u, after)) in chunks {
        let mut lanes = [Newton::default(); LANES];
        let lanes = &mut lanes[..a.len()];
        for (((l, &a), &target), &u) in lanes.iter_mut().zip(a).zip(target).zip(u.iter()) {
            *l = Newton::new(a, target, u.clamp(0.0, 1.0));
        }
        newton_side_by_side(lanes, dt_s, 6);
        for ((l, u), after) in lanes.iter().zip(u).zip(after) {
            (*u, *after) = l.settled().unwrap_or_else(|| {
                let u = saturated_excitation(l.a, l.target, dt_s);
                (u, activation_after(l.a, u, dt_s))
            });
        }
    }
}

/// The excitation of a muscle Newton's method did not settle from its guess: the gain of a
/// saturated command in that direction, then the command that reaches the target with it
/// (exact when it saturates: the gain is the saturated one), refined by Newton's method.
fn saturated_excitation(a: f64, target: f64, dt_s: f64) -> f64 {
    let e = kept(a, if target >= a { 1.0 } else { 0.0 }, dt_s);
    let u = ((target - a * e) / (1.0 - e)).clamp(0.0, 1.0);
    if u == 0.0 || u == 1.0 {
        return u;
    }
    let mut lane = [Newton::new(a, target, u)];
    newton_side_by_side(&mut lane, dt_s, 30);
    lane[0].settled().map_or(u, |(u, _)| u)
}

/// A Newton step at most this long (in excitation) settles an excitation inside 0..1: the
/// next would be about `h''/(2h') step^2`, under 1e-13 for the curvatures of these dynamics.
const QUADRATIC_STEP: f64 = 1e-8;

/// Where one muscle's Newton iteration is.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
enum Progress {
    #[default]
    Running,
    Settled,
    Failed,
}

/// Newton's method on h(u) = u + (a - u) exp(-g(u) dt) - target for one muscle, `u` within
/// 0..=1: settled at the `u` it last evaluated once the step from it is under 1e-13 (a bound
/// when the target is out of reach in the step), or inside the bounds at the next once the step
/// is under [`QUADRATIC_STEP`] (the target reached); failed where h' <= 0.
#[derive(Debug, Clone, Copy, Default)]
struct Newton {
    a: f64,
    target: f64,
    u: f64,
    /// The activation `u` reaches ([`activation_after`]), once evaluated.
    reached: f64,
    /// [`gain_slopes`] at `a`.
    slopes: (f64, f64),
    progress: Progress,
}

impl Newton {
    fn new(a: f64, target: f64, u: f64) -> Self {
        if a == target {
            // The root itself: an activation kept where it is (a muscle resting at its least
            // activation most often) needs the excitation equal to it.
            return Self { a, target, u: a, reached: a, slopes: (0.0, 0.0), progress: Progress::Settled };
        }
        Self { a, target, u, reached: f64::NAN, slopes: gain_slopes(a), progress: Progress::Running }
    }

    /// The excitation and the activation it reaches, once settled.
    fn settled(&self) -> Option<(f64, f64)> {
        (self.progress == Progress::Settled).then_some((self.u, self.reached))
    }

    /// One step from `u` with `th = tanh(b (u - a))`.
    fn advance(&mut self, th: f64, dt_s: f64) {
        let (a, u) = (self.a, self.u);
        let (g, dg) = gain(th, self.slopes);
        let e = (-g * dt_s).exp();
        self.reached = u + (a - u) * e;
        let h = self.reached - self.target;
        let dh = 1.0 - e - (a - u) * e * dt_s * dg;
        if dh <= 0.0 {
            self.progress = Progress::Failed;
            return;
        }
        let next = (u - h / dh).clamp(0.0, 1.0);
        let step = (next - u).abs();
        if step <= 1e-13 {
            self.progress = Progress::Settled;
            return;
        }
        self.u = next;
        if step <= QUADRATIC_STEP && next > 0.0 && next < 1.0 {
            // Inside the bounds after a step this small, Newton's next step (about
            // h''/(2h') step^2) is below rounding: `next` reaches the target.
            self.reached = self.target;
            self.progress = Progress::Settled;
        }
    }
}

/// At most `steps` Newton steps of each of `lanes` (at most [`LANES`]), side by side.
fn newton_side_by_side(lanes: &mut [Newton], dt_s: f64, steps: usize) {
    let mut th = [0.0; LANES];
    for _ in 0..steps {
        let mut running = false;
        for (l, th) in lanes.iter().zip(&mut th) {
            if l.progress == Progress::Running {
                *th = switch(l.u - l.a);
                running = true;
            }
        }
        if !running {
            return;
        }
        for (l, &th) in lanes.iter_mut().zip(&th) {
            if l.progress == Progress::Running {
                l.advance(th, dt_s);
            }
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// The time for activation to go half way from `a0` toward `u` (s) stepping `step` with
    /// `dt_s`.
    fn half_time(a0: f64, u: f64, dt_s: f64, step: impl Fn(f64, f64, f64) -> f64) -> f64 {
        let (mut a, mut t) = (a0, 0.0);
        while (a - a0).abs() < 0.5 * (u - a0).abs() {
            let next = step(a, u, dt_s);
            // Linear within the step for the crossing.
            let target = a0 + 0.5 * (u - a0);
            if (next - a0).abs() >= 0.5 * (u - a0).abs() {
                return t + dt_s * (target - a) / (next - a);
            }
            (a, t) = (next, t + dt_s);
        }
        t
    }

    /// The wearer's activation update at 1 ms follows De Groote's dynamics integrated finely
    /// (10 us Euler): a full excitation step is half way in 9.6 ms, a release in 26.8 ms;
    /// the frozen-rate update at 1 ms within 1.2 ms of it (measured: 0.48 ms early on the rise).
    #[test]
    fn activation_update_follows_the_dynamics() {
        let (ta, td, b) =
            (curves::ACTIVATION_TIME_CONSTANT_S, curves::DEACTIVATION_TIME_CONSTANT_S, curves::ACTIVATION_SMOOTHING);
        let fine = |a: f64, u: f64, dt: f64| a + curves::activation_rate(u, a, ta, td, b) * dt;
        for (a0, u) in [(0.01, 1.0), (1.0, 0.01)] {
            let exact = half_time(a0, u, 1e-5, fine);
            let ours = half_time(a0, u, 1e-3, activation_after);
            assert!((ours - exact).abs() < 1.2e-3, "{a0} -> {u}: {ours} s against {exact} s");
        }
        assert!((half_time(0.01, 1.0, 1e-5, fine) - 0.0095).abs() < 1e-3);
        assert!((half_time(1.0, 0.01, 1e-5, fine) - 0.0268).abs() < 2e-3);
    }

    /// The switch is De Groote's tanh to rounding over every `u - a` (measured: 3.3e-16 at most
    /// on 20001 points of -1..1).
    #[test]
    fn switch_is_the_tanh() {
        let worst = (0..=20000)
            .map(|i| -1.0 + i as f64 / 10000.0)
            .map(|x| (switch(x) - (curves::ACTIVATION_SMOOTHING * x).tanh()).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-15, "{worst}");
    }

    /// The excitation that reaches a target in one step is found, and a target beyond reach
    /// saturates the excitation.
    #[test]
    fn excitation_inverts_the_update() {
        for (a, target) in [(0.2, 0.25), (0.5, 0.495), (0.3, 0.3)] {
            let u = excitation_for(a, target, 1e-3, 0.5);
            assert!((activation_after(a, u, 1e-3) - target).abs() < 1e-12, "{a} -> {target}: u {u}");
        }
        // Every reachable target on a grid, at 1 ms and 0.25 ms: exact to 1e-12.
        for dt in [1e-3, 2.5e-4] {
            for i in 0..=50 {
                let a = 0.01 + 0.98 * i as f64 / 50.0;
                for k in -20..=20 {
                    let target = (a + 0.004 * k as f64 * dt / 1e-3).clamp(0.01, 1.0);
                    let u = excitation_for(a, target, dt, (a + 0.37 * k as f64).rem_euclid(1.0));
                    let other = excitation_for(a, target, dt, a);
                    assert!((u - other).abs() < 1e-11, "the guess changed the answer: {u} {other}");
                    let reached = activation_after(a, u, dt);
                    let reachable = u > 0.0 && u < 1.0;
                    if reachable {
                        assert!((reached - target).abs() < 1e-12, "{a} -> {target} in {dt}: {reached}");
                    } else {
                        // Saturated: the target is beyond what a full step reaches.
                        assert!((target - a).signum() * (target - reached) >= -1e-15, "{a} -> {target}");
                    }
                }
            }
        }
        assert_eq!(excitation_for(0.1, 0.9, 1e-3, 0.1), 1.0);
        assert_eq!(excitation_for(0.9, 0.1, 1e-3, 0.5), 0.0);
    }

    /// The learned gait interpolates between bin centres and wraps around the cycle.
    #[test]
    fn feedforward_bins_interpolate_periodically() {
        let samples: Vec<_> = (0..1000)
            .map(|i| {
                let pct = i as f64 / 10.0;
                (pct, [[pct.to_radians().sin(), 0.0, 0.0], [0.0; 3], [0.0; 3]], pct.to_radians().cos())
            })
            .collect();
        let ff = Feedforward::learn(&samples).unwrap();
        // Bin 0 holds 0..1 % (mean 0.45 %), bin 99 holds 99..100 % (mean 99.45 %).
        let at = |p: f64| ff.at(p)[0][0];
        assert!((at(0.5) - 0.45f64.to_radians().sin()).abs() < 1e-3);
        assert!((at(100.0) - 0.5 * (at(99.5) + at(100.5))).abs() < 1e-9);
        assert!((ff.device_bins()[0] - 0.45f64.to_radians().cos()).abs() < 1e-3);
        assert!(Feedforward::learn(&samples[..500]).is_none());
    }
}
