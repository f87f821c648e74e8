//! End stops: the knee's URDF limits, the cylinder's stroke ends, and the moving ankle's URDF
//! limits, as physical stops, identical in meaning on both engines.
//!
//! A stop is a one-sided spring-damper on the joint coordinate q beyond its limit:
//!
//! ```text
//! pen = lo - q  (below lo)   or   q - hi  (above hi)          (rad, > 0 inside the stop)
//! tau = k pen + c d(pen)/dt, pushing out of the stop only      (N m)
//! k = STOP_STIFFNESS_NM_PER_RAD,  c = 2 STOP_DAMPING_RATIO sqrt(k I)
//! ```
//! with I the joint's inertia there (for the knee: the closed chain's M(q), cylinder included).
//! Both engines hold the stop torque over a step and evaluate it linearly implicitly at the end
//! of the step (where the joint will be), so it is stable for any stiffness and step, and a
//! joint about to run into its stop is caught in that step: a stiff stop becomes the torque that
//! brings the joint to its limit within the step. The
//! cylinder's stroke ends act on the knee through the loop: the knee angles at which the rod
//! reaches its prismatic limits are knee stops too. Under the largest loads of the tests
//! (+-2000 N on the cylinder, about 100 N m at the knee) a stop gives way by a few hundredths of a
//! degree, also when the leg runs into it at 34 rad/s (`tests/it/end_stops.rs`).

use super::model::LegSpec;
use serde::{Deserialize, Serialize};

/// Stiffness of every end stop (N m/rad).
pub const STOP_STIFFNESS_NM_PER_RAD: f64 = 2.0e6;
/// Damping ratio of every end stop (-), with the joint's inertia at the stop.
pub const STOP_DAMPING_RATIO: f64 = 1.0;

/// Where a side of a stop comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopSource {
    /// The joint's URDF `<limit>`.
    JointLimit,
    /// The cylinder's stroke end (the rod's prismatic `<limit>`), through the loop.
    StrokeEnd,
}

/// The range a joint may move in, and what bounds each side (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopRange {
    /// Lower limit (rad).
    pub lo_rad: f64,
    /// Upper limit (rad).
    pub hi_rad: f64,
    /// What sets the lower limit.
    pub lo_source: StopSource,
    /// What sets the upper limit.
    pub hi_source: StopSource,
}

impl StopRange {
    /// A range from one joint's limits.
    pub fn joint(lo_rad: f64, hi_rad: f64) -> Self {
        Self { lo_rad, hi_rad, lo_source: StopSource::JointLimit, hi_source: StopSource::JointLimit }
    }

    /// How far `q` is inside a stop (rad, > 0) and which side (-1 below `lo`, +1 above `hi`);
    /// None within the range.
    pub fn penetration(&self, q: f64) -> Option<(f64, f64)> {
        if q < self.lo_rad {
            Some((self.lo_rad - q, -1.0))
        } else if q > self.hi_rad {
            Some((q - self.hi_rad, 1.0))
        } else {
            None
        }
    }

    /// The stop's spring-damper at `q` (rad), `qd` (rad/s) with the damper `c_nm_s_per_rad`
    /// (N m s/rad), evaluated where the joint is (N m, positive increasing q; pushing out of the
    /// stop only): for engines that evaluate it at every integrator stage and resolve its
    /// stiffness with their steps (the reduced engine's walking leg).
    pub fn spring_damper(&self, q: f64, qd: f64, c_nm_s_per_rad: f64) -> f64 {
        let k = STOP_STIFFNESS_NM_PER_RAD;
        if q < self.lo_rad {
            (k * (self.lo_rad - q) - c_nm_s_per_rad * qd).max(0.0)
        } else if q > self.hi_rad {
            -(k * (q - self.hi_rad) + c_nm_s_per_rad * qd).max(0.0)
        } else {
            0.0
        }
    }

    /// Whether the joint at `q` (rad) is in the stop or within `band_rad` (rad) of it.
    pub fn near(&self, q: f64, band_rad: f64) -> bool {
        q < self.lo_rad + band_rad || q > self.hi_rad - band_rad
    }

    /// What bounds the side `side` (-1 lower, +1 upper).
    pub fn source(&self, side: f64) -> StopSource {
        if side < 0.0 {
            self.lo_source
        } else {
            self.hi_source
        }
    }

    /// The stop torque (N m, positive increasing q) held over a step of `dt_s` (s) at `q`
    /// (rad), `qd` (rad/s) for a joint of inertia `inertia_kg_m2` (kg m^2): the spring-damper
    /// of the module doc evaluated at the end of the step (linearly implicit), so a joint about
    /// to cross its limit within the step is stopped in that step rather than one step later.
    /// `position_gain` is how the engine moves the joint under a torque held over the step:
    /// `q' = q + qd dt + position_gain (tau / I) dt^2` (0.5 for an exact or RK integration,
    /// (n + 1) / (2 n) for n velocity-then-position substeps, 1 for symplectic Euler). 0 when
    /// neither the joint nor its end-of-step position is in a stop.
    pub fn torque(&self, q: f64, qd: f64, inertia_kg_m2: f64, dt_s: f64, position_gain: f64) -> f64 {
        let k = STOP_STIFFNESS_NM_PER_RAD;
        let i = inertia_kg_m2.max(1e-9);
        let c = 2.0 * STOP_DAMPING_RATIO * (k * i).sqrt();
        let gain = 1.0 + (k * position_gain * dt_s + c) * dt_s / i;
        let ahead = q + qd * dt_s;
        if q < self.lo_rad || ahead < self.lo_rad {
            ((k * (self.lo_rad - ahead) - c * qd) / gain).max(0.0)
        } else if q > self.hi_rad || ahead > self.hi_rad {
            -((k * (ahead - self.hi_rad) + c * qd) / gain).max(0.0)
        } else {
            0.0
        }
    }
}

/// The stops of a leg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndStops {
    /// The knee: its URDF limits (or the loader's default range) and the stroke ends.
    pub knee: StopRange,
    /// The ankle, when it moves and has URDF limits.
    pub ankle: Option<StopRange>,
    /// The foot's inertia about the ankle axis (kg m^2), for the ankle stop.
    pub ankle_inertia_kg_m2: f64,
}

impl EndStops {
    /// The stops of `model`: the knee's range narrowed to where the rod stays within its
    /// stroke, and the moving ankle's limits.
    pub fn of(model: &LegSpec) -> Self {
        let (lo, hi) = model.knee_range_rad();
        let mut knee = StopRange::joint(lo, hi);
        if let Some((s_lo, s_hi)) = stroke_knee_range(model, lo, hi) {
            if s_lo > knee.lo_rad {
                (knee.lo_rad, knee.lo_source) = (s_lo, StopSource::StrokeEnd);
            }
            if s_hi < knee.hi_rad {
                (knee.hi_rad, knee.hi_source) = (s_hi, StopSource::StrokeEnd);
            }
        }
        let ankle = model.ankle_joint().and_then(|j| j.limits).map(|(a, b)| StopRange::joint(a, b));
        let ankle_inertia_kg_m2 = model.ankle_joint().map_or(0.0, |j| {
            let l = &model.links()[j.child];
            let [x, _, z] = l.com_m;
            l.inertia_kg_m2[1][1] + l.mass_kg * (x * x + z * z)
        });
        Self { knee, ankle, ankle_inertia_kg_m2 }
    }
}

/// The knee angles (rad) around [`lo`, `hi`] where the rod reaches its stroke ends: the widest
/// interval containing the knee range on which the rod stays within its prismatic limits
/// (searched 1 rad beyond the range each way; an end the rod never reaches there is no stop).
fn stroke_knee_range(model: &LegSpec, lo: f64, hi: f64) -> Option<(f64, f64)> {
    let (r_lo, r_hi) = model.rod_limits_m();
    let inside = |q: f64| model.loop_solution(q).is_some_and(|s| s.rod_m >= r_lo && s.rod_m <= r_hi);
    let mid = 0.5 * (lo + hi);
    if !inside(mid) {
        return None;
    }
    // Walk out from the middle in small steps, then bisect the crossing.
    let edge = |dir: f64, limit: f64| {
        let n = 400;
        let step = (limit + 1.0 * dir - mid).abs() / n as f64 * dir;
        let mut a = mid;
        for _ in 0..n {
            let b = a + step;
            if !inside(b) {
                let (mut x, mut y) = (a, b);
                for _ in 0..60 {
                    let m = 0.5 * (x + y);
                    if inside(m) {
                        x = m;
                    } else {
                        y = m;
                    }
                }
                return x;
            }
            a = b;
        }
        if dir < 0.0 {
            f64::NEG_INFINITY
        } else {
            f64::INFINITY
        }
    };
    Some((edge(-1.0, lo), edge(1.0, hi)))
}

/// What the stops did over a run: time at each, and the deepest penetration.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct StopReport {
    /// Time at the knee's lower URDF limit (s).
    pub knee_lower_s: f64,
    /// Time at the knee's upper URDF limit (s).
    pub knee_upper_s: f64,
    /// Time at a stroke end of the cylinder (s).
    pub stroke_end_s: f64,
    /// Time at an ankle limit (s).
    pub ankle_s: f64,
    /// Deepest penetration into any stop (deg).
    pub max_penetration_deg: f64,
}

impl StopReport {
    /// Count one step of `dt_s` at knee angle `q` and ankle angle `ankle` (rad).
    pub fn add(&mut self, stops: &EndStops, q: f64, ankle: Option<f64>, dt_s: f64) {
        if let Some((pen, side)) = stops.knee.penetration(q) {
            match (stops.knee.source(side), side < 0.0) {
                (StopSource::StrokeEnd, _) => self.stroke_end_s += dt_s,
                (StopSource::JointLimit, true) => self.knee_lower_s += dt_s,
                (StopSource::JointLimit, false) => self.knee_upper_s += dt_s,
            }
            self.max_penetration_deg = self.max_penetration_deg.max(pen.to_degrees());
        }
        if let (Some(range), Some(a)) = (&stops.ankle, ankle) {
            if let Some((pen, _)) = range.penetration(a) {
                self.ankle_s += dt_s;
                self.max_penetration_deg = self.max_penetration_deg.max(pen.to_degrees());
            }
        }
    }

    /// True when no stop was touched.
    pub fn is_clear(&self) -> bool {
        self.knee_lower_s + self.knee_upper_s + self.stroke_end_s + self.ankle_s == 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stop pushes out only, is zero in the range, and its implicit form brings a stiff
    /// joint back within one step instead of overshooting.
    #[test]
    fn stop_torque_pushes_out_and_is_stable() {
        let r = StopRange::joint(0.0, 1.0);
        assert_eq!(r.torque(0.5, 10.0, 0.3, 1e-3, 1.0), 0.0);
        // Below the lower limit, at rest: pushes up.
        let t = r.torque(-0.01, 0.0, 0.3, 1e-3, 1.0);
        assert!(t > 0.0, "{t}");
        // Leaving the stop fast: no pull back into it.
        assert_eq!(r.torque(-0.001, 50.0, 0.3, 1e-3, 1.0), 0.0);
        // Above the upper limit moving out: pushes down.
        assert!(r.torque(1.01, 1.0, 0.3, 1e-3, 1.0) < 0.0);
        // A joint (0.3 kg m^2) running into the stop at 30 rad/s with 1 ms steps (semi-implicit
        // Euler, the stop torque held over each step, 100 N m pushing into the stop): caught in
        // the step it would cross (no elastic rebound), then held against the push.
        // Static give under the push: push (1 + (k dt + c) dt / I) / k. Measured: deepest
        // 0.0368 deg (that value), at rest afterwards.
        let (i, dt, push) = (0.3, 1e-3, -100.0);
        let (mut q, mut qd, mut deepest) = (0.05, -30.0, 0.0f64);
        for _ in 0..500 {
            qd += (r.torque(q, qd, i, dt, 1.0) + push) / i * dt;
            q += qd * dt;
            deepest = deepest.max(-q);
        }
        println!("deepest {} deg, leaving at {qd} rad/s", deepest.to_degrees());
        assert!(deepest > 0.012f64.to_radians() && deepest < 0.1f64.to_radians(), "{}", deepest.to_degrees());
        assert!(qd.abs() < 1e-3, "{qd} rad/s against a steady push");
    }
}
