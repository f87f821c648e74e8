//! Sensor faults (`crate::faults`) applied to the readings: after the A/D and the delay line,
//! before the firmware's differences (a knee encoder that drops out takes its rate with it).
//! The truth is untouched. A faulted reading has no raw counts.

use crate::faults::{Dropout, Fault, FaultKind, SensorFaultKind};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::collections::VecDeque;

/// One sensor fault's state.
#[derive(Debug, Clone)]
struct Entry {
    /// Index of the fault in the run's list.
    fault: usize,
    /// A/D channel (0-4 the force loop's, 5-25 the device's).
    ch: usize,
    kind: SensorFaultKind,
    rng: ChaCha8Rng,
    /// The last reading before the fault (dropout `hold`, stuck without a value).
    last: f64,
    /// The value held while active (stuck, hold).
    held: Option<f64>,
    /// The last `n` readings (extra delay).
    line: VecDeque<f64>,
}

/// The sensor faults of a run and their state.
#[derive(Debug, Clone, Default)]
pub struct SensorFaults {
    entries: Vec<Entry>,
}

impl SensorFaults {
    /// The sensor faults of `faults`, their noise seeded from `seed`.
    pub fn new(faults: &[Fault], seed: u64) -> Self {
        let entries = faults
            .iter()
            .enumerate()
            .filter_map(|(i, f)| match f.kind {
                FaultKind::Sensor(ch, kind) => Some(Entry {
                    fault: i,
                    ch,
                    kind,
                    rng: ChaCha8Rng::seed_from_u64(
                        seed ^ 0xFA17_0000_0000_0000 ^ (i as u64 + 1).wrapping_mul(0x9E37_79B9),
                    ),
                    last: f64::NAN,
                    held: None,
                    line: VecDeque::new(),
                }),
                _ => None,
            })
            .collect();
        Self { entries }
    }

    /// Whether the run has any.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Apply the faults on channels `offset..offset + r.len()` to the readings `r` of the
    /// sample at `t_s` (s): `active(i)` and `onset(i)` say whether fault `i` is active and
    /// since when. A changed reading loses its counts (`counts[k] = None`).
    pub fn apply(
        &mut self,
        t_s: f64,
        offset: usize,
        r: &mut [f64],
        counts: &mut [Option<i64>],
        active: &dyn Fn(usize) -> Option<f64>,
    ) {
        let n = r.len();
        for e in self.entries.iter_mut().filter(|e| e.ch >= offset && e.ch < offset + n) {
            let k = e.ch - offset;
            let x = r[k];
            if let SensorFaultKind::Delay(n) = e.kind {
                e.line.push_back(x);
                if e.line.len() > n + 1 {
                    e.line.pop_front();
                }
            }
            let Some(t0) = active(e.fault) else {
                e.last = x;
                e.held = None;
                continue;
            };
            let y = match e.kind {
                SensorFaultKind::Dropout(Dropout::Nan) => f64::NAN,
                SensorFaultKind::Dropout(Dropout::Zero) => 0.0,
                SensorFaultKind::Dropout(Dropout::Hold) => *e.held.get_or_insert(e.last),
                SensorFaultKind::Stuck(Some(v)) => v,
                SensorFaultKind::Stuck(None) => *e.held.get_or_insert(x),
                SensorFaultKind::Bias(b) => x + b,
                SensorFaultKind::Drift(rate) => x + rate * (t_s - t0),
                SensorFaultKind::Gain(g) => x * g,
                SensorFaultKind::Noise(sd) => {
                    let z: f64 = StandardNormal.sample(&mut e.rng);
                    x + sd * z
                }
                SensorFaultKind::Spikes { amplitude, probability } => {
                    let u: f64 = rand::Rng::random(&mut e.rng);
                    let sign: f64 = if rand::Rng::random::<bool>(&mut e.rng) { 1.0 } else { -1.0 };
                    if u < probability {
                        x + sign * amplitude
                    } else {
                        x
                    }
                }
                SensorFaultKind::Saturation(level) => x.clamp(-level, level),
                SensorFaultKind::Delay(_) => e.line.front().copied().unwrap_or(x),
            };
            r[k] = y;
            counts[k] = None;
        }
    }
}
