//! Wall-clock figures of a controller (measured, reported, never in the physics): the
//! percentiles of its compute times and of a link's round trips.

use serde::Serialize;

/// The distribution of a measured time (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimingStats {
    /// Number of measurements.
    pub samples: usize,
    /// Median (s).
    pub p50_s: f64,
    /// 99th percentile (s).
    pub p99_s: f64,
    /// Largest (s).
    pub max_s: f64,
    /// Mean (s).
    pub mean_s: f64,
}

impl TimingStats {
    /// The figures of `times_s` (nearest-rank percentiles); None when there are none.
    pub fn of(times_s: &[f64]) -> Option<Self> {
        let mut v: Vec<f64> = times_s.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let at = |p: f64| v[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
        Some(Self {
            samples: n,
            p50_s: at(0.50),
            p99_s: at(0.99),
            max_s: v[n - 1],
            mean_s: v.iter().sum::<f64>() / n as f64,
        })
    }

    /// As JSON (None when there are no measurements).
    pub fn json(times_s: &[f64]) -> Option<serde_json::Value> {
        Self::of(times_s).and_then(|t| serde_json::to_value(t).ok())
    }
}
