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

use crate::muscles::activation::excitations_for;
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

#[cfg(test)]
mod tests {
    use super::*;

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
