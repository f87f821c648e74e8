//! Loaded walking: what the gait data imply for a single leg on a treadmill with a virtual
//! other leg (issue 12). Everything here is read off one averaged gait cycle and the leg's
//! geometry, once per run setup; the force laws that use it are in `human::body`.
//!
//! - Joint targets: hip, knee, ankle angles (Fourier fits, analytic rates).
//! - Moments and ground reaction (N m/kg, N/kg) as tabulated, times the subject's mass.
//! - The other leg is this leg half a cycle later. Its share of the body's support at a
//!   phase is `grf_other / (grf_this + grf_other)`: 1 in this leg's swing, 0 in its single
//!   support (the data's; a run on the ground times it from the leg's own contact,
//!   `human::events`).
//! - The pelvis height the data imply: the hip sits as high above the ground as the foot on
//!   the ground reaches (from the angles and the URDF's sole shapes, less the sole's static
//!   sink under the data's load), this leg's once it carries a fifth of the body weight;
//!   high enough for the swing foot to clear the ground; smoothed by a Fourier fit.
//! - The belt speed the stance implies: how fast the sole point on the ground (the heel, then
//!   the ball) moves backwards relative to the hip between heel strike and toe-off.
//! - A stance weight in [0, 1]: 1 in this leg's stance, 0 in swing, with raised-cosine
//!   transitions [`STANCE_BLEND_PCT`] wide centred on heel strike and toe-off (the data's; a
//!   run on the ground uses the detected one, `human::events`).
//! - The pelvis's fore-aft path: the hip moves over the supporting foot as the data's angles
//!   move it (this leg's in its stance, the other's in this leg's swing), so the foot that the
//!   belt carries at a constant speed needs no other angles than the data's; and, when the belt
//!   and the leg's stance sweep differ, the difference (back over the stance, forward over the
//!   swing).

use super::{CycleTable, FourierSeries, GaitReference, RefSample};
use crate::leg::{sole_contacts_at, sole_points_at, static_sink_m, LegSpec};

/// Slices of the stance in which the sole's sweep is summed.
const SWEEP_STEPS: usize = 200;
/// Samples of the data-implied pelvis height over one cycle.
const PELVIS_SAMPLES: usize = 400;
/// Harmonics of the fit of the data-implied pelvis height: up to 8 times the stride
/// frequency, about 7 Hz at 1.1 s (the body's centre of mass moves smoothly; more harmonics
/// ring at the kinks where the supporting foot changes, and the support's damper amplifies
/// the ringing of the rate into hundreds of newtons).
pub const PELVIS_HARMONICS: usize = 8;
/// Load on this leg's foot (N/kg, about a fifth of the body weight) from which its reach alone
/// sets the data-implied hip height in double support (see `pelvis_height_sample`).
pub const THIS_LEG_HOLDS_N_PER_KG: f64 = 2.0;
/// The swing foot's clearance over the ground the hip height keeps at mid-swing (m): about
/// the minimum toe clearance measured in adult walking (1-2 cm; Winter 1992, Begg et al.
/// 2007), as a half sine over the swing.
pub const SWING_CLEARANCE_M: f64 = 0.02;
/// Width of the stance weight's transitions (% of the cycle).
pub const STANCE_BLEND_PCT: f64 = 4.0;
/// Vertical ground reaction (N/kg) above which the data count a foot as on the ground.
pub const STANCE_THRESHOLD_N_PER_KG: f64 = 0.25;

/// The data of one instant of loaded walking.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WalkingSample {
    /// Thigh angle to the vertical (rad, forward positive: the carriage's hip angle) and its
    /// time derivatives.
    pub hip: RefSample,
    /// Knee flexion (rad) and its time derivatives.
    pub knee: RefSample,
    /// Ankle dorsiflexion (rad) and its time derivatives.
    pub ankle: RefSample,
    /// Net internal hip moment (N m, flexor positive).
    pub hip_moment_nm: f64,
    /// Net internal knee moment (N m, extensor positive).
    pub knee_moment_nm: f64,
    /// Net internal ankle moment (N m, plantarflexor positive).
    pub ankle_moment_nm: f64,
    /// Vertical ground reaction on this foot and on the other (N).
    pub grf_this_n: f64,
    /// Vertical ground reaction on the other foot (N).
    pub grf_other_n: f64,
    /// The other leg's share of the support (0..=1).
    pub other_share: f64,
    /// Height of the hip above the ground the data imply (m) and its rate (m/s).
    pub pelvis_height_m: f64,
    /// Rate of `pelvis_height_m` (m/s).
    pub pelvis_rate_m_s: f64,
    /// Acceleration of `pelvis_height_m` (m/s^2).
    pub pelvis_accel_m_s2: f64,
    /// Stance weight of this leg (0 swing .. 1 stance).
    pub stance_weight: f64,
    /// The pelvis's fore-aft target (m; 0 unless the belt and the leg's sweep differ, set by
    /// the loop from [`WalkingData::pelvis_x_at`]).
    pub pelvis_x_m: f64,
    /// Rate of `pelvis_x_m` (m/s).
    pub pelvis_x_rate_m_s: f64,
}

/// Pelvic tilt assumed when neither the scenario nor the gait data give one (deg).
pub const DEFAULT_PELVIC_TILT_DEG: f64 = 10.0;

/// Where the pelvic tilt of a walking run comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PelvicTilt {
    /// A constant (rad): `hip.pelvic_tilt_deg`, or [`DEFAULT_PELVIC_TILT_DEG`] when the data
    /// have no tilt column (`from_scenario` false).
    Constant {
        /// The tilt (rad).
        rad: f64,
        /// Set by `hip.pelvic_tilt_deg` (else the default).
        from_scenario: bool,
    },
    /// The data's `pelvis_tilt_deg` column over the cycle (its mean in rad, for reports).
    Data {
        /// The column's mean over the cycle (rad).
        mean_rad: f64,
    },
}

impl PelvicTilt {
    /// What a run assumed, in words (for `summary.json`).
    pub fn describe(&self) -> String {
        match self {
            PelvicTilt::Constant { rad, from_scenario: true } => {
                format!("constant {:.2} deg (hip.pelvic_tilt_deg)", rad.to_degrees())
            }
            PelvicTilt::Constant { rad, from_scenario: false } => format!(
                "constant {:.2} deg (the default: the gait data have no pelvis_tilt_deg column)",
                rad.to_degrees()
            ),
            PelvicTilt::Data { mean_rad } => {
                format!("the gait data's pelvis_tilt_deg over the cycle (mean {:.2} deg)", mean_rad.to_degrees())
            }
        }
    }
}

/// The gait data of a loaded-walking run, resolved against a leg.
#[derive(Debug, Clone)]
pub struct WalkingData {
    /// The angle trajectories (and stride time).
    pub gait: GaitReference,
    /// Subject mass the moments and the ground reaction are scaled with (kg).
    pub subject_mass_kg: f64,
    /// Anterior pelvic tilt: the data's hip flexion is the thigh's angle to the pelvis; the
    /// thigh's angle to the vertical, which the carriage's upright pelvis sets, is the hip
    /// flexion minus the tilt.
    pub pelvic_tilt: PelvicTilt,
    hip_moment: CycleTable,
    knee_moment: CycleTable,
    ankle_moment: CycleTable,
    grf: CycleTable,
    /// Hip height above the ground over the cycle (m) against % of the cycle: the lower
    /// foot's reach, smoothed by a [`PELVIS_HARMONICS`]-term Fourier fit (the switch from one
    /// foot to the other is a kink; the support's damper needs a rate).
    pelvis: FourierSeries,
    /// This leg's heel strike and toe-off (% of the cycle).
    pub stance_pct: (f64, f64),
    /// Belt speed the stance kinematics imply (m/s, the surface moving to -x).
    pub belt_speed_m_s: f64,
    /// The pelvis's fore-aft path per m/s of belt-sweep difference (m per m/s) against % of
    /// the cycle: -t over the stance, back over the swing, zero mean.
    drift: FourierSeries,
    /// The pelvis's fore-aft path over the supporting foot (m, +x forward, zero mean) against
    /// % of the cycle (see [`Self::sway_profile`]).
    sway: FourierSeries,
}

impl WalkingData {
    /// Read the walking data off `gait` for `model` (whose ankle moves) and a subject of
    /// `subject_mass_kg`, with a constant pelvic tilt (rad) or, without one, the data's own
    /// tilt column (else [`DEFAULT_PELVIC_TILT_DEG`]). Errors name the missing column or the
    /// geometric problem.
    pub fn new(
        gait: GaitReference,
        model: &LegSpec,
        subject_mass_kg: f64,
        pelvic_tilt_rad: Option<f64>,
        sole_modulus_pa: Option<f64>,
    ) -> Result<Self, String> {
        let c = &gait.cycle;
        let need = |n: &str| c.kinetic(n).cloned().ok_or_else(|| format!("the gait data have no `{n}` column"));
        if c.hip.is_none() || c.ankle.is_none() {
            return Err("the gait data need `hip_flexion_deg` and `ankle_dorsiflexion_deg` columns".into());
        }
        let grf = need("grf_vertical_n_per_kg")?;
        let stance_pct = stance_window(&grf)?;
        let pelvic_tilt = match (pelvic_tilt_rad, &c.pelvis_tilt) {
            (Some(rad), _) => PelvicTilt::Constant { rad, from_scenario: true },
            (None, Some(series)) => PelvicTilt::Data { mean_rad: series.mean() },
            (None, None) => PelvicTilt::Constant { rad: DEFAULT_PELVIC_TILT_DEG.to_radians(), from_scenario: false },
        };
        let mut w = WalkingData {
            hip_moment: need("hip_moment_nm_per_kg")?,
            knee_moment: need("knee_moment_nm_per_kg")?,
            ankle_moment: need("ankle_moment_nm_per_kg")?,
            grf,
            gait,
            subject_mass_kg,
            pelvic_tilt,
            pelvis: FourierSeries::fit(&[0.0, 50.0, 25.0], &[0.0; 3], 100.0, 1),
            stance_pct,
            belt_speed_m_s: 0.0,
            drift: FourierSeries::fit(&[0.0, 50.0, 25.0], &[0.0; 3], 100.0, 1),
            sway: FourierSeries::fit(&[0.0, 50.0, 25.0], &[0.0; 3], 100.0, 1),
        };

        let pcts: Vec<f64> = (0..PELVIS_SAMPLES).map(|i| i as f64 * 100.0 / PELVIS_SAMPLES as f64).collect();
        let pelvis =
            pcts.iter().map(|&p| w.pelvis_height_sample(model, sole_modulus_pa, p)).collect::<Result<Vec<_>, _>>()?;
        let pelvis = FourierSeries::fit(&pcts, &pelvis, 100.0, PELVIS_HARMONICS);
        let (hs, to) = stance_pct;
        let stance_s = ((to - hs).rem_euclid(100.0)) / 100.0 * w.gait.stride_s;
        let belt = w.stance_sweep_m(model)? / stance_s;
        (w.pelvis, w.belt_speed_m_s) = (pelvis, belt);
        w.drift = w.drift_profile();
        w.sway = w.sway_profile(model)?;
        Ok(w)
    }

    /// The hip's height above the ground the data imply at `pct` (m), before smoothing: each
    /// foot on the ground (the data's ground reaction above [`STANCE_THRESHOLD_N_PER_KG`])
    /// reaches down from the hip as far as the leg's geometry at the data's angles allows,
    /// less the static sink of its sole under the data's load on that foot (the compliant
    /// law's, `sole_modulus_pa`; none on rigid contacts). With both feet down this leg's reach
    /// holds the hip once its foot carries [`THIS_LEG_HOLDS_N_PER_KG`] (blended linearly from
    /// the other's below that, so the height is continuous through heel strike and toe-off):
    /// this leg is a body and the other is not, and the data's angles on a leg of other
    /// proportions than the subject's do not make the two reaches agree (holding the hip at
    /// the lower one pressed subject 02's landing leg 4 cm into the belt; at the load-weighted
    /// mean, subject 01's overground cycle on the 1.75 m leg landed 10 % of the stride late).
    /// A foot in swing keeps [`SWING_CLEARANCE_M`] (a half sine over the swing, 0 at toe-off
    /// and heel strike) between itself and the ground: where the leg's geometry at the data's
    /// angles would put the swing foot lower, the hip is raised.
    fn pelvis_height_sample(&self, model: &LegSpec, sole_modulus_pa: Option<f64>, pct: f64) -> Result<f64, String> {
        let (hs, to) = self.stance_pct;
        let swing_len = (hs - to).rem_euclid(100.0);
        let foot = |p: f64| -> Result<(Option<(f64, f64)>, f64), String> {
            let t = p / 100.0 * self.gait.stride_s;
            let (h, k, a) = (self.thigh_at(t).value, self.gait.knee_at(t).value, self.gait.ankle_at(t).value);
            let (_, contacts) = sole_contacts_at(model, h, k, a)
                .filter(|c| !c.1.is_empty())
                .ok_or_else(|| format!("the leg cannot take the data's pose at {p:.1} % (loop or soles)"))?;
            let reach = -contacts.iter().map(|c| c.0.z).fold(f64::INFINITY, f64::min);
            let load = self.grf.at(p);
            if load > STANCE_THRESHOLD_N_PER_KG {
                let sink = sole_modulus_pa.map_or(0.0, |e| static_sink_m(e, &contacts, load * self.subject_mass_kg));
                return Ok((Some((reach - sink, load)), reach));
            }
            let x = (p - to).rem_euclid(100.0);
            let clearance =
                if x < swing_len { SWING_CLEARANCE_M * (std::f64::consts::PI * x / swing_len).sin() } else { 0.0 };
            Ok((None, reach + clearance))
        };
        let (this, other) = (foot(pct)?, foot(pct + 50.0)?);
        let held = match (this.0, other.0) {
            (Some((a, la)), Some((b, _))) => {
                let w = (la / THIS_LEG_HOLDS_N_PER_KG).min(1.0);
                w * a + (1.0 - w) * b
            }
            (Some((a, _)), None) | (None, Some((a, _))) => a,
            (None, None) => this.1.max(other.1),
        };
        let swing_needs = |f: (Option<(f64, f64)>, f64)| if f.0.is_none() { f.1 } else { f64::MIN };
        Ok(held.max(swing_needs(this)).max(swing_needs(other)))
    }

    /// The fore-aft path of the pelvis per m/s of belt-sweep difference (see
    /// [`Self::pelvis_x_at`]): piecewise linear in time, back over the stance, forward over the
    /// swing, zero mean, fitted with [`PELVIS_HARMONICS`] (its rate then has no steps).
    fn drift_profile(&self) -> FourierSeries {
        let (hs, to) = self.stance_pct;
        let stance = (to - hs).rem_euclid(100.0) / 100.0;
        let t = self.gait.stride_s;
        let path = |pct: f64| {
            let x = (pct - hs).rem_euclid(100.0) / 100.0;
            let back = if x < stance { -x * t } else { -stance * t + stance / (1.0 - stance) * (x - stance) * t };
            back + stance * t / 2.0
        };
        let pcts: Vec<f64> = (0..PELVIS_SAMPLES).map(|i| i as f64 * 100.0 / PELVIS_SAMPLES as f64).collect();
        let xs: Vec<f64> = pcts.iter().map(|&p| path(p)).collect();
        FourierSeries::fit(&pcts, &xs, 100.0, PELVIS_HARMONICS)
    }

    /// The sole points (in the hip's frame, m) at the data's pose at `pct`.
    fn sole_points(&self, model: &LegSpec, pct: f64) -> Result<Vec<crate::leg::planar::P2>, String> {
        let t = pct / 100.0 * self.gait.stride_s;
        let (h, k, a) = (self.thigh_at(t).value, self.gait.knee_at(t).value, self.gait.ankle_at(t).value);
        sole_points_at(model, h, k, a)
            .map(|p| p.1)
            .filter(|p| !p.is_empty())
            .ok_or_else(|| format!("the leg cannot take the data's pose at {pct:.1} % (loop or soles)"))
    }

    /// How far (m) the sole point that is lowest at `from` % moves backwards under the hip
    /// until `to` % (the point the belt holds, as the foot rolls from the heel to the ball).
    fn sweep_between(&self, model: &LegSpec, from: f64, to: f64) -> Result<f64, String> {
        let (now, next) = (self.sole_points(model, from)?, self.sole_points(model, to)?);
        let i = (0..now.len()).fold(0, |b, i| if now[i].z < now[b].z { i } else { b });
        Ok(now[i].x - next[i].x)
    }

    /// How far the sole travels backwards under the hip over the stance (m): in
    /// [`SWEEP_STEPS`] slices from heel strike to toe-off, the motion of the sole point that is
    /// lowest at the start of each slice (the heel, then the ball: the point the belt holds).
    fn stance_sweep_m(&self, model: &LegSpec) -> Result<f64, String> {
        let (hs, to) = self.stance_pct;
        let len = (to - hs).rem_euclid(100.0);
        let at = |j: usize| hs + len * j as f64 / SWEEP_STEPS as f64;
        (1..=SWEEP_STEPS).map(|j| self.sweep_between(model, at(j - 1), at(j))).sum()
    }

    /// The pelvis's fore-aft path over the supporting foot (m, zero mean) against % of the
    /// cycle, fitted with [`PELVIS_HARMONICS`]: the hip moves forward over the foot on the
    /// belt at the rate the data's angles sweep the foot back under it (this leg in its data
    /// stance, the other, this leg half a cycle later, in this leg's swing), less that
    /// phase's mean rate, which the belt (and, when it differs, [`Self::drift_profile`])
    /// carries. A person's pelvis decelerates over the first half of each stance and speeds
    /// up over the second (the braking and then propulsive ground reaction); a pelvis held
    /// at a constant speed makes the stance leg sweep at the belt's speed all along, off the
    /// data's angles, and the stance knee moment loses its loading-response extensor and
    /// terminal-stance flexor (README, "Walking for anyone").
    fn sway_profile(&self, model: &LegSpec) -> Result<FourierSeries, String> {
        let (hs, to) = self.stance_pct;
        let len = (to - hs).rem_euclid(100.0);
        let n = PELVIS_SAMPLES;
        let dp = 100.0 / n as f64;
        let stance: Vec<bool> = (0..n).map(|i| (i as f64 * dp - hs).rem_euclid(100.0) < len).collect();
        let rates = (0..n)
            .map(|i| {
                let p = i as f64 * dp + if stance[i] { 0.0 } else { 50.0 };
                self.sweep_between(model, p, p + dp)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mean = |phase: bool| {
            let (sum, count) =
                rates.iter().zip(&stance).filter(|(_, &s)| s == phase).fold((0.0, 0), |a, (r, _)| (a.0 + r, a.1 + 1));
            sum / count.max(1) as f64
        };
        let (in_stance, in_swing) = (mean(true), mean(false));
        let mut x = 0.0;
        let mut path = Vec::with_capacity(n);
        for (r, s) in rates.iter().zip(&stance) {
            path.push(x);
            x += r - if *s { in_stance } else { in_swing };
        }
        let mid = path.iter().sum::<f64>() / n as f64;
        let pcts: Vec<f64> = (0..n).map(|i| i as f64 * dp).collect();
        let path: Vec<f64> = path.iter().map(|v| v - mid).collect();
        Ok(FourierSeries::fit(&pcts, &path, 100.0, PELVIS_HARMONICS))
    }

    /// The thigh's angle to the vertical (rad, forward positive): hip flexion minus the
    /// pelvic tilt (and its rates, when it is the data's).
    /// The pelvis's anterior tilt the thigh's angle leaves out at `t_s` (rad, with its rates):
    /// the data's hip flexion is the thigh's angle plus this.
    pub fn pelvic_tilt_at(&self, t_s: f64) -> RefSample {
        match self.pelvic_tilt {
            PelvicTilt::Constant { rad, .. } => RefSample { value: rad, ..Default::default() },
            PelvicTilt::Data { .. } => self.gait.pelvis_tilt_at(t_s).unwrap_or_default(),
        }
    }

    fn thigh_at(&self, t_s: f64) -> RefSample {
        let mut h = self.gait.hip_at(t_s);
        match self.pelvic_tilt {
            PelvicTilt::Constant { rad, .. } => h.value -= rad,
            PelvicTilt::Data { .. } => {
                let p = self.gait.pelvis_tilt_at(t_s).unwrap_or_default();
                h.value -= p.value;
                h.rate -= p.rate;
                h.accel -= p.accel;
            }
        }
        h
    }

    /// Cycle percentage at `t_s` (0..100).
    pub fn pct_at(&self, t_s: f64) -> f64 {
        super::rem_euclid_100(t_s / self.gait.stride_s * 100.0)
    }

    /// Stance weight of this leg at cycle percentage `pct` (0 swing .. 1 stance): raised-cosine
    /// edges [`STANCE_BLEND_PCT`] wide, 0.5 at heel strike and at toe-off.
    pub fn stance_weight_at_pct(&self, pct: f64) -> f64 {
        let (hs, to) = self.stance_pct;
        let len = super::rem_euclid_100(to - hs);
        let x = super::rem_euclid_100(pct - hs);
        let half = STANCE_BLEND_PCT / 2.0;
        let edge = |d: f64| 0.5 * (std::f64::consts::PI * d.min(half) / STANCE_BLEND_PCT).sin();
        if x <= len {
            0.5 + edge(x.min(len - x))
        } else {
            0.5 - edge((x - len).min(100.0 - x))
        }
    }

    /// The data at time `t_s` (the cycle repeats every stride).
    pub fn at(&self, t_s: f64) -> WalkingSample {
        let pct = self.pct_at(t_s);
        let m = self.subject_mass_kg;
        WalkingSample {
            hip: self.thigh_at(t_s),
            knee: self.gait.knee_at(t_s),
            ankle: self.gait.ankle_at(t_s),
            hip_moment_nm: self.hip_moment.at(pct) * m,
            knee_moment_nm: self.knee_moment.at(pct) * m,
            ankle_moment_nm: self.ankle_moment.at(pct) * m,
            ..self.support_at(t_s)
        }
    }

    /// [`Self::at`] without the joints: the ground reactions, the pelvis and the stance weight
    /// (the angles and moments zero), for a body whose joints something else drives (the
    /// muscle wearer).
    pub fn support_at(&self, t_s: f64) -> WalkingSample {
        let pct = self.pct_at(t_s);
        let (g_this, g_other) = self.grf_pair_n(pct);
        let (pelvis, rate_per_pct, accel_per_pct2) = self.pelvis.eval(pct);
        WalkingSample {
            hip: RefSample::default(),
            knee: RefSample::default(),
            ankle: RefSample::default(),
            hip_moment_nm: 0.0,
            knee_moment_nm: 0.0,
            ankle_moment_nm: 0.0,
            grf_this_n: g_this,
            grf_other_n: g_other,
            other_share: Self::share_of(g_this, g_other),
            pelvis_height_m: pelvis,
            pelvis_rate_m_s: rate_per_pct * 100.0 / self.gait.stride_s,
            pelvis_accel_m_s2: accel_per_pct2 * (100.0 / self.gait.stride_s).powi(2),
            stance_weight: self.stance_weight_at_pct(pct),
            pelvis_x_m: 0.0,
            pelvis_x_rate_m_s: 0.0,
        }
    }

    /// The data's vertical ground reaction on this foot and on the other at `pct` (N).
    fn grf_pair_n(&self, pct: f64) -> (f64, f64) {
        let m = self.subject_mass_kg;
        (self.grf.at(pct).max(0.0) * m, self.grf.at(pct + 50.0).max(0.0) * m)
    }

    fn share_of(g_this: f64, g_other: f64) -> f64 {
        let total = g_this + g_other;
        if total > 0.0 {
            g_other / total
        } else {
            0.5
        }
    }

    /// The other leg's share of the support in the data at `t_s` ([`WalkingSample::other_share`]
    /// without the rest of the sample).
    pub fn other_share_at(&self, t_s: f64) -> f64 {
        let (g_this, g_other) = self.grf_pair_n(self.pct_at(t_s));
        Self::share_of(g_this, g_other)
    }

    /// The pelvis's fore-aft target (m, +x forward, zero mean over the cycle) and its rate
    /// (m/s) at `t_s` for a belt that runs `drift_m_s` faster than the leg's stance sweep
    /// ([`Self::belt_speed_m_s`]): over the supporting foot as the data's angles move it
    /// (its sway profile), and back at `drift_m_s` over the data's stance and forward
    /// again over the swing (see `human::body`), smoothed by [`PELVIS_HARMONICS`].
    pub fn pelvis_x_at(&self, t_s: f64, drift_m_s: f64) -> (f64, f64) {
        let ((x, rate_per_pct, _), (y, sway_per_pct, _)) = self.drift.eval_pair(&self.sway, self.pct_at(t_s));
        (drift_m_s * x + y, (drift_m_s * rate_per_pct + sway_per_pct) * 100.0 / self.gait.stride_s)
    }

    /// The lowest hip height over the cycle the data imply (m).
    pub fn lowest_pelvis_height_m(&self) -> f64 {
        (0..200).map(|i| self.pelvis.eval(i as f64 * 0.5).0).fold(f64::INFINITY, f64::min)
    }

    /// The dataset's vertical ground reaction of this leg at `pct` (N).
    pub fn grf_at_pct(&self, pct: f64) -> f64 {
        self.grf.at(pct) * self.subject_mass_kg
    }

    /// The dataset's knee moment at `pct` (N m, extensor positive).
    pub fn knee_moment_at_pct(&self, pct: f64) -> f64 {
        self.knee_moment.at(pct) * self.subject_mass_kg
    }
}

/// Heel strike and toe-off (% of the cycle): the ends of the longest run of rows whose
/// ground reaction exceeds [`STANCE_THRESHOLD_N_PER_KG`], read cyclically at 0.1 % steps.
fn stance_window(grf: &CycleTable) -> Result<(f64, f64), String> {
    let n = 1000;
    let on: Vec<bool> = (0..n).map(|i| grf.at(i as f64 / 10.0) > STANCE_THRESHOLD_N_PER_KG).collect();
    if on.iter().all(|&b| b) || on.iter().all(|&b| !b) {
        return Err("the ground reaction has no stance and swing (`grf_vertical_n_per_kg`)".into());
    }
    let start = (0..n).find(|&i| on[i] && !on[(i + n - 1) % n]).unwrap_or(0);
    let (mut best, mut at, mut len) = ((0, 0), start, 0);
    for k in 0..n {
        let i = (start + k) % n;
        if on[i] {
            if len == 0 {
                at = i;
            }
            len += 1;
            if len > best.1 {
                best = (at, len);
            }
        } else {
            len = 0;
        }
    }
    Ok((best.0 as f64 / 10.0, ((best.0 + best.1) % n) as f64 / 10.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::leg::LegOptions;
    use crate::reference::GaitCycle;

    fn data(trial: &str) -> WalkingData {
        let (cycle, stride) = GaitCycle::builtin(trial, 12).unwrap().unwrap();
        let gait = GaitReference { cycle, stride_s: stride, source: trial.into(), sha256: String::new() };
        let text = crate::leg::BUILTIN_URDFS[0].1;
        let model = LegSpec::from_urdf_with(text, &LegOptions { ankle_free: true, ..Default::default() }).unwrap();
        WalkingData::new(gait, &model, 75.0, Some(10f64.to_radians()), Some(1e7)).unwrap()
    }

    #[test]
    fn stance_pelvis_and_belt_from_the_comfortable_trial() {
        let w = data("wbds01_overground_comfortable");
        let (hs, to) = w.stance_pct;
        let p: Vec<f64> = (0..100).map(|i| w.at(i as f64 / 100.0 * 1.1).pelvis_height_m).collect();
        let (lo, hi) = p.iter().fold((f64::MAX, f64::MIN), |a, &v| (a.0.min(v), a.1.max(v)));
        println!("stance {hs}..{to} belt {} pelvis {lo}..{hi}", w.belt_speed_m_s);
        for pct in (0..100).step_by(4).map(f64::from) {
            let s = w.at(pct / 100.0 * 1.1);
            println!(
                "{pct}: w {:.3} share {:.3} grf {:.0} {:.0}",
                s.stance_weight, s.other_share, s.grf_this_n, s.grf_other_n
            );
        }
    }
}
