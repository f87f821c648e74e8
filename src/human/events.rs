//! Gait events from the simulation (issue 23): stance and swing of the leg detected from its
//! foot's contact, the way an exoskeleton's foot switch or insole sees them, with hysteresis.
//! They drive the cascade's switch and the assistance law (through the stance weight) and the
//! virtual other leg's share of the support; the data's phase stays the clock of the targets
//! (angles, moments, the other leg's own events) only.
//!
//! ```text
//!            vertical GRF > on_n  (and >= min_swing_s in swing)
//!   SWING  ------------------------------------------------->  STANCE
//!          <-------------------------------------------------
//!            vertical GRF < off_n (and >= min_stance_s in stance)
//! ```
//! The vertical ground reaction is the one of the last completed step (a sensor reads what
//! has happened). The run starts in swing (the sole starts above the ground).
//!
//! - Stance weight `w` (0 swing .. 1 stance): from the value it had at the last switch to
//!   the new state's value along a raised cosine of `blend_s`, with analytic rates (the force
//!   controllers differentiate the desired force).
//! - The other leg's share of the support: 1 in swing; in stance the larger of the data's
//!   loading curve timed from the detected heel strike (the data's share from their heel strike
//!   until the other foot's toe-off, so weight moves onto the leg only once it is on the
//!   ground, however early or late that is) and the data's unloading curve on the data's clock
//!   (from the other foot's heel strike, which is the data's event: the other leg is virtual,
//!   until mid-swing in the data: a foot still down after the data's toe-off leaves the body
//!   to the other leg); blended with the swing's 1 by `w`.

use crate::reference::{RefSample, WalkingData};

/// Above this vertical ground reaction (N per kg of the subject's mass) a foot in swing counts
/// as down.
pub const CONTACT_ON_N_PER_KG: f64 = 0.5;
/// Below this (N/kg) a foot in stance counts as lifted.
pub const CONTACT_OFF_N_PER_KG: f64 = 0.1;
/// Shortest stance the detector accepts before a toe-off (% of the stride): a heel that
/// bounces off the belt in the loading response does not end the stance (people's stance is
/// 55-65 % of the stride; 20 % is far below any walking).
pub const MIN_STANCE_PCT: f64 = 20.0;
/// Shortest swing the detector accepts before a heel strike (% of the stride): contact chatter
/// at toe-off does not start a new stance.
pub const MIN_SWING_PCT: f64 = 10.0;
/// Width of the stance weight's transitions (% of the stride): 4 % (about 40 ms at 1 s).
pub const BLEND_PCT: f64 = 4.0;

/// The detector's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EventParams {
    /// Stance begins above this vertical ground reaction (N).
    pub on_n: f64,
    /// Stance ends below this vertical ground reaction (N).
    pub off_n: f64,
    /// Shortest accepted stance (s).
    pub min_stance_s: f64,
    /// Shortest accepted swing (s).
    pub min_swing_s: f64,
    /// Width of the stance weight's transitions (s).
    pub blend_s: f64,
}

impl EventParams {
    /// The defaults for a subject of `subject_mass_kg` and a stride of `stride_s`.
    pub fn for_subject(subject_mass_kg: f64, stride_s: f64) -> Self {
        Self {
            on_n: CONTACT_ON_N_PER_KG * subject_mass_kg,
            off_n: CONTACT_OFF_N_PER_KG * subject_mass_kg,
            min_stance_s: MIN_STANCE_PCT / 100.0 * stride_s,
            min_swing_s: MIN_SWING_PCT / 100.0 * stride_s,
            blend_s: BLEND_PCT / 100.0 * stride_s,
        }
    }
}

/// The detector's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaitEvents {
    params: EventParams,
    stance: bool,
    /// Time of the last switch (s).
    switched_s: f64,
    /// Stance weight at the last switch.
    weight_at_switch: f64,
    /// Number of detected heel strikes.
    heel_strikes: usize,
}

impl GaitEvents {
    /// A detector in settled swing at the start of a run.
    pub fn new(params: EventParams) -> Self {
        Self { params, stance: false, switched_s: f64::NEG_INFINITY, weight_at_switch: 0.0, heel_strikes: 0 }
    }

    /// Whether the leg is in stance.
    pub fn in_stance(&self) -> bool {
        self.stance
    }

    /// Detected heel strikes so far.
    pub fn heel_strikes(&self) -> usize {
        self.heel_strikes
    }

    /// Feed the vertical ground reaction (N) the foot had over the step that ended at `t_s`.
    pub fn update(&mut self, t_s: f64, vertical_n: f64) {
        let dwell = if self.stance { self.params.min_stance_s } else { self.params.min_swing_s };
        if t_s - self.switched_s < dwell {
            return;
        }
        let switch = if self.stance { vertical_n < self.params.off_n } else { vertical_n > self.params.on_n };
        if switch {
            self.weight_at_switch = self.stance_weight(t_s).value;
            self.stance = !self.stance;
            self.switched_s = t_s;
            self.heel_strikes += usize::from(self.stance);
        }
    }

    /// The stance weight at `t_s` (>= the last switch) with its first two time derivatives.
    pub fn stance_weight(&self, t_s: f64) -> RefSample {
        let target = if self.stance { 1.0 } else { 0.0 };
        let tau = self.params.blend_s;
        let x = (t_s - self.switched_s) / tau;
        if x.is_nan() || x >= 1.0 || tau <= 0.0 {
            return RefSample { value: target, rate: 0.0, accel: 0.0 };
        }
        let x = x.max(0.0);
        let span = target - self.weight_at_switch;
        let pi = std::f64::consts::PI;
        RefSample {
            value: self.weight_at_switch + span * 0.5 * (1.0 - (pi * x).cos()),
            rate: span * 0.5 * pi / tau * (pi * x).sin(),
            accel: span * 0.5 * (pi / tau).powi(2) * (pi * x).cos(),
        }
    }

    /// The virtual other leg's share of the support at `t_s` (see the module doc).
    pub fn other_share(&self, t_s: f64, data: &WalkingData) -> f64 {
        let w = self.stance_weight(t_s).value;
        if w <= 0.0 {
            return 1.0;
        }
        let (hs, to) = data.stance_pct;
        let share_at = |pct: f64| data.other_share_at(pct / 100.0 * data.gait.stride_s);
        // The other foot leaves the ground (the data's loading ends) at its toe-off, half a
        // cycle after this leg's; it lands at its heel strike, half a cycle after this leg's.
        let loading_len = crate::reference::rem_euclid_100(to - 50.0 - hs);
        let stance_len = crate::reference::rem_euclid_100(to - hs);
        let since_hs =
            if self.stance { (t_s - self.switched_s).max(0.0) / data.gait.stride_s * 100.0 } else { f64::MAX };
        let loading = if since_hs < loading_len { share_at(hs + since_hs) } else { 0.0 };
        let into_stance = crate::reference::rem_euclid_100(data.pct_at(t_s) - hs);
        // After the data's toe-off the data's share is 1: a foot still on the ground then is
        // late (the other leg has the body); from mid-swing on it is early (only the loading
        // curve from its own heel strike applies).
        let late = stance_len + 0.5 * (100.0 - stance_len);
        let unloading = if (50.0..late).contains(&into_stance) { share_at(data.pct_at(t_s)) } else { 0.0 };
        1.0 - w * (1.0 - loading.max(unloading))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> EventParams {
        EventParams { on_n: 37.0, off_n: 15.0, min_stance_s: 0.03, min_swing_s: 0.03, blend_s: 0.04 }
    }

    #[test]
    fn hysteresis_and_dwell() {
        let mut e = GaitEvents::new(params());
        e.update(0.10, 30.0);
        assert!(!e.in_stance(), "below on_n");
        e.update(0.11, 40.0);
        assert!(e.in_stance());
        e.update(0.12, 5.0);
        assert!(e.in_stance(), "within the dwell");
        e.update(0.15, 20.0);
        assert!(e.in_stance(), "above off_n");
        e.update(0.16, 10.0);
        assert!(!e.in_stance());
        assert_eq!(e.heel_strikes(), 1);
    }

    fn walking() -> WalkingData {
        use crate::leg::{LegOptions, LegSpec};
        use crate::reference::{GaitCycle, GaitReference};
        let trial = "wbds01_treadmill_t05";
        let (cycle, stride) = GaitCycle::builtin(trial, 12).unwrap().unwrap();
        let gait = GaitReference { cycle, stride_s: stride, source: trial.into(), sha256: String::new() };
        let model = LegSpec::from_urdf_with(
            crate::leg::BUILTIN_URDFS[0].1,
            &LegOptions { ankle_free: true, ..Default::default() },
        )
        .unwrap();
        WalkingData::new(gait, &model, 74.3, None, Some(1e7)).unwrap()
    }

    /// The other leg's share follows the detected contact: all of the body in swing whatever
    /// the data's phase, the data's loading curve from the detected heel strike, the data's
    /// unloading on the data's clock, and all of it again for a foot still down after the
    /// data's toe-off.
    #[test]
    fn the_other_legs_share_follows_the_contact() {
        let w = walking();
        let stride = w.gait.stride_s;
        let (hs, to) = w.stance_pct;
        let t = |pct: f64| pct / 100.0 * stride;
        let p = EventParams::for_subject(74.3, stride);
        let mut e = GaitEvents::new(p);
        // In the data's mid-stance but detected in swing: the other leg carries the body.
        assert_eq!(e.other_share(t(hs + 30.0), &w), 1.0);
        // An early heel strike at 90 % of the cycle (the data's swing: share 1 there).
        let strike = t(90.0);
        e.update(strike, 1000.0);
        assert!(e.in_stance());
        let after = |dt: f64| e.other_share(strike + dt, &w);
        // Right after it the weight ramps from 1; once the ramp is done the loading curve
        // (the data's share 5 % of a stride after their heel strike) holds.
        assert!(after(0.0) > 0.999, "{}", after(0.0));
        let loading = w.at(t(hs + 5.0)).other_share;
        assert!((after(t(5.0)) - loading).abs() < 1e-9, "{} vs {loading}", after(t(5.0)));
        assert!(loading > 0.2 && loading < 0.9, "{loading}");
        // Past the loading curve (20 % into the detected stance, the data's 10 %): single
        // support, although the data's clock says double support.
        assert_eq!(after(t(20.0)), 0.0);
        // The data's unloading (after the other foot's heel strike at hs + 50 %).
        let mut late = GaitEvents::new(p);
        late.update(t(hs), 1000.0);
        let unloading = late.other_share(t(hs + 55.0), &w);
        assert!((unloading - w.at(t(hs + 55.0)).other_share).abs() < 1e-12 && unloading > 0.0);
        // Still down after the data's toe-off: the other leg has the body.
        assert_eq!(late.other_share(t(to + 2.0), &w), 1.0);
    }

    #[test]
    fn stance_weight_is_smooth_and_its_rates_match() {
        let mut e = GaitEvents::new(params());
        e.update(0.2, 100.0);
        e.update(0.235, 0.0); // leaves mid-ramp: the weight continues from where it was
        let (t, h) = (0.25, 1e-6);
        let (a, p, m) = (e.stance_weight(t), e.stance_weight(t + h), e.stance_weight(t - h));
        assert!(((p.value - m.value) / (2.0 * h) - a.rate).abs() < 1e-5 * a.rate.abs().max(1.0));
        assert!(((p.rate - m.rate) / (2.0 * h) - a.accel).abs() < 1e-4 * a.accel.abs().max(1.0));
        assert!((e.stance_weight(0.235).value - 0.5 * (1.0 - (std::f64::consts::PI * 0.875).cos())).abs() < 1e-12);
        assert_eq!(e.stance_weight(0.3).value, 0.0);
    }
}
