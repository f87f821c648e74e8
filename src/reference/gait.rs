//! Gait-cycle references: knee (and hip) angle over the gait cycle from a CSV, repeated
//! seamlessly, with analytic first and second time derivatives from a periodic cubic spline.

use super::RefSample;
use crate::error::{Error, Result};

/// Built-in trials (the shared WBDS files, embedded so a run needs no data path): name, CSV
/// text, default stride time (s). The treadmill trials' strides are the subjects' measured
/// cadences (subject 01) or an estimate (subject 02: no cadence is published; from a
/// speed-cadence relation fitted to the WBDS young adults, `assets/gait/README.md`).
pub const BUILTIN_TRIALS: [(&str, &str, f64); 12] = [
    ("wbds01_overground_comfortable", include_str!("../../assets/gait/wbds01_overground_comfortable.csv"), 1.10),
    ("wbds01_overground_fast", include_str!("../../assets/gait/wbds01_overground_fast.csv"), 0.95),
    ("wbds01_overground_slow", include_str!("../../assets/gait/wbds01_overground_slow.csv"), 1.30),
    ("wbds02_overground_comfortable", include_str!("../../assets/gait/wbds02_overground_comfortable.csv"), 1.10),
    ("wbds02_overground_fast", include_str!("../../assets/gait/wbds02_overground_fast.csv"), 0.95),
    ("wbds02_overground_slow", include_str!("../../assets/gait/wbds02_overground_slow.csv"), 1.30),
    ("wbds01_treadmill_t03", include_str!("../../assets/gait/v2/wbds01_treadmill_t03.csv"), 1.3833),
    ("wbds01_treadmill_t05", include_str!("../../assets/gait/v2/wbds01_treadmill_t05.csv"), 1.0633),
    ("wbds01_treadmill_t06", include_str!("../../assets/gait/v2/wbds01_treadmill_t06.csv"), 1.0067),
    ("wbds02_treadmill_t03", include_str!("../../assets/gait/v2/wbds02_treadmill_t03.csv"), 1.21),
    ("wbds02_treadmill_t05", include_str!("../../assets/gait/v2/wbds02_treadmill_t05.csv"), 1.01),
    ("wbds02_treadmill_t06", include_str!("../../assets/gait/v2/wbds02_treadmill_t06.csv"), 0.94),
];

/// A truncated Fourier series `c0 + sum_k (a_k cos(k w x) + b_k sin(k w x))`, w = 2 pi / period,
/// fitted by least squares: smooth and periodic, with analytic derivatives of every order.
#[derive(Debug, Clone)]
pub struct FourierSeries {
    c0: f64,
    a: Vec<f64>,
    b: Vec<f64>,
    w: f64,
}

impl FourierSeries {
    /// Least-squares fit of `harmonics` harmonics to samples `(x, y)` of a function of period
    /// `period`, by Householder QR of the design matrix (nalgebra): no normal equations, so the
    /// conditioning is that of the basis, not its square. Needs more samples than
    /// `2*harmonics + 1`.
    pub fn fit(x: &[f64], y: &[f64], period: f64, harmonics: usize) -> Self {
        let w = std::f64::consts::TAU / period;
        let n = 2 * harmonics + 1;
        let a = nalgebra::DMatrix::from_fn(x.len(), n, |i, j| match j {
            0 => 1.0,
            _ => {
                let k = j.div_ceil(2) as f64;
                let (s, c) = (k * w * x[i]).sin_cos();
                if j % 2 == 1 {
                    c
                } else {
                    s
                }
            }
        });
        let qr = a.qr();
        let qty = qr.q().transpose() * nalgebra::DVector::from_column_slice(y);
        let c = qr.r().solve_upper_triangular(&qty).unwrap_or_else(|| nalgebra::DVector::zeros(n));
        Self {
            c0: c[0],
            a: (0..harmonics).map(|k| c[1 + 2 * k]).collect(),
            b: (0..harmonics).map(|k| c[2 + 2 * k]).collect(),
            w,
        }
    }

    /// The mean over a period (the constant term).
    pub fn mean(&self) -> f64 {
        self.c0
    }

    /// Value and first and second derivatives at `x`.
    pub fn eval(&self, x: f64) -> (f64, f64, f64) {
        let (mut v, mut d1, mut d2) = (self.c0, 0.0, 0.0);
        with_harmonics(self.w * x, self.a.len(), |s, c| {
            for (k, ((a, b), (s, c))) in self.a.iter().zip(&self.b).zip(s.iter().zip(c)).enumerate() {
                let kw = (k + 1) as f64 * self.w;
                v += a * c + b * s;
                d1 += kw * (b * c - a * s);
                d2 -= kw * kw * (a * c + b * s);
            }
        });
        (v, d1, d2)
    }

    /// [`Self::eval`] of this series and of `other` at `x`, in one pass when they share their
    /// frequency and number of harmonics (the same sines and cosines; each sum adds in the same
    /// order as [`Self::eval`], so the values are the same bits).
    pub fn eval_pair(&self, other: &FourierSeries, x: f64) -> ((f64, f64, f64), (f64, f64, f64)) {
        if self.w != other.w || self.a.len() != other.a.len() {
            return (self.eval(x), other.eval(x));
        }
        let (mut v, mut d1, mut d2) = (self.c0, 0.0, 0.0);
        let (mut u, mut e1, mut e2) = (other.c0, 0.0, 0.0);
        with_harmonics(self.w * x, self.a.len(), |s, c| {
            let mine = self.a.iter().zip(&self.b);
            let theirs = other.a.iter().zip(&other.b);
            for (k, (((a, b), (oa, ob)), (s, c))) in mine.zip(theirs).zip(s.iter().zip(c)).enumerate() {
                let kw = (k + 1) as f64 * self.w;
                v += a * c + b * s;
                d1 += kw * (b * c - a * s);
                d2 -= kw * kw * (a * c + b * s);
                u += oa * c + ob * s;
                e1 += kw * (ob * c - oa * s);
                e2 -= kw * kw * (oa * c + ob * s);
            }
        });
        ((v, d1, d2), (u, e1, e2))
    }

    /// Value and first, second and third derivatives at `x`.
    pub fn eval3(&self, x: f64) -> (f64, f64, f64, f64) {
        let (mut v, mut d1, mut d2, mut d3) = (self.c0, 0.0, 0.0, 0.0);
        with_harmonics(self.w * x, self.a.len(), |s, c| {
            for (k, ((a, b), (s, c))) in self.a.iter().zip(&self.b).zip(s.iter().zip(c)).enumerate() {
                let kw = (k + 1) as f64 * self.w;
                v += a * c + b * s;
                d1 += kw * (b * c - a * s);
                d2 -= kw * kw * (a * c + b * s);
                d3 -= kw * kw * kw * (b * c - a * s);
            }
        });
        (v, d1, d2, d3)
    }
}

/// Harmonics a thread's basis keeps (the longest shipped series has 48).
const BASIS_HARMONICS: usize = 64;
/// Angles whose bases a thread keeps.
const BASIS_ENTRIES: usize = 4;

/// The sines and cosines of `k theta` for k = 1.. of a few angles `theta` (this thread's).
struct Basis {
    /// Per entry: the angle's bits, how many harmonics are filled, sines, cosines.
    entries: [(u64, usize, [f64; BASIS_HARMONICS], [f64; BASIS_HARMONICS]); BASIS_ENTRIES],
    next: usize,
}

thread_local! {
    static BASIS: std::cell::RefCell<Basis> = const {
        std::cell::RefCell::new(Basis {
            entries: [(0, 0, [0.0; BASIS_HARMONICS], [0.0; BASIS_HARMONICS]); BASIS_ENTRIES],
            next: 0,
        })
    };
}

/// `f(sin k theta, cos k theta)` for k = 1..=n, by the angle-addition recurrence from one
/// `sin_cos(theta)`. The series of a gait cycle share their angle at an instant (the hip, the
/// pelvis, the knee and the ankle at the loop's time; the knee again for the friction's
/// feedforward one step before): the sines and cosines of the last few angles are kept per
/// thread, and every series gets the same bits as from its own recurrence.
fn with_harmonics<R>(theta: f64, n: usize, f: impl FnOnce(&[f64], &[f64]) -> R) -> R {
    let fill = |s: &mut [f64], c: &mut [f64]| {
        let (s1, c1) = theta.sin_cos();
        let (mut sk, mut ck) = (s1, c1);
        for (s, c) in s.iter_mut().zip(c.iter_mut()) {
            (*s, *c) = (sk, ck);
            (sk, ck) = (sk * c1 + ck * s1, ck * c1 - sk * s1);
        }
    };
    if n > BASIS_HARMONICS {
        let (mut s, mut c) = (vec![0.0; n], vec![0.0; n]);
        fill(&mut s, &mut c);
        return f(&s, &c);
    }
    BASIS.with_borrow_mut(|b| {
        let key = theta.to_bits();
        let i = match b.entries.iter().position(|e| e.0 == key && e.1 >= n) {
            Some(i) => i,
            None => {
                let i = b.next;
                b.next = (i + 1) % BASIS_ENTRIES;
                let e = &mut b.entries[i];
                fill(&mut e.2[..n], &mut e.3[..n]);
                (e.0, e.1) = (key, n);
                i
            }
        };
        let e = &b.entries[i];
        f(&e.2[..n], &e.3[..n])
    })
}

/// `x.rem_euclid(100.0)`, the same bits, without the library's `fmod` (a hundred-odd
/// instructions, several times per step on the gait path): `x - 100 trunc(x / 100)` is exact
/// when the quotient is right, and the remainder's sign and size say when it is not.
pub fn rem_euclid_100(x: f64) -> f64 {
    if !x.is_finite() || x.abs() >= 1e15 {
        return x.rem_euclid(100.0);
    }
    let q = (x / 100.0).trunc();
    let r = x - 100.0 * q;
    if r.abs() >= 100.0 || (r != 0.0 && (r < 0.0) != (x < 0.0)) {
        return x.rem_euclid(100.0);
    }
    // fmod's zero carries the dividend's sign; rem_euclid adds the divisor to a negative one.
    let r = if r == 0.0 { 0.0f64.copysign(x) } else { r };
    if r < 0.0 {
        r + 100.0
    } else {
        r
    }
}

/// Most rows a gait CSV may have.
pub const MAX_GAIT_ROWS: usize = 100_000;
/// Largest gap (in % of the cycle) allowed between consecutive rows, the wrap-around from the
/// last row to the first row of the next cycle included.
pub const MAX_GAIT_GAP_PCT: f64 = 10.0;

/// The cycle percentages must cover one whole cycle: at most 100 % from first to last, and no
/// gap (wrap-around included) wider than [`MAX_GAIT_GAP_PCT`].
fn check_coverage(pct: &[f64]) -> std::result::Result<(), String> {
    let (first, last) = (pct[0], pct[pct.len() - 1]);
    let span = last - first;
    if span > 100.0 + 1e-9 {
        return Err(format!("spans {span} %; one cycle is at most 100 %"));
    }
    if span <= 1.0 + 1e-9 && first >= 0.0 {
        return Err(format!(
            "runs from {first} to {last}: that looks like fractions of the cycle (0..1); give percent (0..100)"
        ));
    }
    let wrap = first + 100.0 - last;
    let (gap, at) = pct
        .windows(2)
        .map(|w| (w[1] - w[0], w[0]))
        .chain(std::iter::once((wrap, last)))
        .fold((0.0f64, first), |a, b| if b.0 > a.0 { b } else { a });
    if gap > MAX_GAIT_GAP_PCT + 1e-9 {
        return Err(format!(
            "covers only part of the cycle: {gap:.1} % without data after {at} % (at most {MAX_GAIT_GAP_PCT} %)"
        ));
    }
    Ok(())
}

/// One column of a gait cycle as read, against the cycle percentage, interpolated linearly and
/// periodically (period 100 %): kinetics are used as forces, which need no derivatives, and a
/// Fourier fit would ring at heel strike and toe-off.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleTable {
    pct: Vec<f64>,
    values: Vec<f64>,
}

impl CycleTable {
    /// Value at `pct` (% of the cycle, any real: wrapped into the cycle).
    pub fn at(&self, pct: f64) -> f64 {
        let (first, n) = (self.pct[0], self.pct.len());
        let p = first + rem_euclid_100(pct - first);
        let i = self.pct.partition_point(|&x| x <= p);
        let (lo, hi) = if i == 0 || i == n {
            // Between the last row and the first row of the next cycle.
            ((self.pct[n - 1], self.values[n - 1]), (first + 100.0, self.values[0]))
        } else {
            ((self.pct[i - 1], self.values[i - 1]), (self.pct[i], self.values[i]))
        };
        let p = if p < lo.0 { p + 100.0 } else { p };
        let span = hi.0 - lo.0;
        if span <= 0.0 {
            return lo.1;
        }
        lo.1 + (hi.1 - lo.1) * (p - lo.0) / span
    }
}

/// Optional columns of a gait CSV, with the check each value must pass: angles in degrees
/// (|v| <= 360, fitted), moments in N m/kg (|v| <= 20) and ground reaction in N/kg
/// (-5..=50), tabulated; the pelvis's anterior tilt to the vertical in degrees (-90..=90,
/// fitted).
pub const OPTIONAL_GAIT_COLUMNS: [(&str, f64, f64); 7] = [
    ("hip_flexion_deg", -360.0, 360.0),
    ("ankle_dorsiflexion_deg", -360.0, 360.0),
    ("hip_moment_nm_per_kg", -20.0, 20.0),
    ("knee_moment_nm_per_kg", -20.0, 20.0),
    ("ankle_moment_nm_per_kg", -20.0, 20.0),
    ("grf_vertical_n_per_kg", -5.0, 50.0),
    ("pelvis_tilt_deg", -90.0, 90.0),
];

/// One gait cycle read from a CSV: knee (and optionally hip and ankle) angle against % of the
/// cycle, and the kinetics columns when the file has them.
#[derive(Debug, Clone)]
pub struct GaitCycle {
    /// Knee flexion (rad, flexion positive) against cycle percentage.
    pub knee: FourierSeries,
    /// Hip flexion (rad, flexion positive) against cycle percentage, if the file has it.
    pub hip: Option<FourierSeries>,
    /// Ankle dorsiflexion (rad, dorsiflexion positive), if the file has it.
    pub ankle: Option<FourierSeries>,
    /// Pelvis tilt to the vertical (rad, anterior positive), if the file has it.
    pub pelvis_tilt: Option<FourierSeries>,
    /// Tabulated kinetics by column name (`hip_moment_nm_per_kg`, `knee_moment_nm_per_kg`,
    /// `ankle_moment_nm_per_kg`: net internal moments, hip flexor, knee extensor, ankle
    /// plantarflexor positive; `grf_vertical_n_per_kg`: up positive), those the file has.
    pub kinetics: Vec<(&'static str, CycleTable)>,
    /// Number of data rows read.
    pub rows: usize,
}

/// The rows of a gait CSV: percentages, knee angles (rad) and the optional columns present
/// (angles in rad, the rest as given).
struct GaitRows {
    pct: Vec<f64>,
    knee: Vec<f64>,
    optional: Vec<(&'static str, Vec<f64>)>,
}

fn read_gait_rows(name: &str, text: &str) -> Result<GaitRows> {
    let bad = |key: &str, msg: String| Error::input(name, key, msg);
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(text.as_bytes());
    let headers = rdr.headers().map_err(|e| bad("header", format!("malformed CSV: {e}")))?.clone();
    let col = |n: &str| headers.iter().position(|h| h == n);
    let ipct = col("gait_cycle_pct").ok_or_else(|| bad("gait_cycle_pct", "missing column".into()))?;
    let iknee = col("knee_flexion_deg").ok_or_else(|| bad("knee_flexion_deg", "missing column".into()))?;
    let present: Vec<(usize, (&'static str, f64, f64))> =
        OPTIONAL_GAIT_COLUMNS.iter().filter_map(|c| col(c.0).map(|i| (i, *c))).collect();
    let mut rows = GaitRows {
        pct: Vec::new(),
        knee: Vec::new(),
        optional: present.iter().map(|(_, c)| (c.0, Vec::new())).collect(),
    };
    for (r, rec) in rdr.records().enumerate() {
        let row = r + 2; // 1-based line number, after the header
        if row > MAX_GAIT_ROWS + 1 {
            return Err(bad("rows", format!("more than {MAX_GAIT_ROWS} rows (the cap)")));
        }
        let rec = rec.map_err(|e| bad(&format!("row {row}"), format!("malformed CSV: {e}")))?;
        let get = |i: usize, cname: &str, lo: f64, hi: f64| -> Result<f64> {
            let s = rec.get(i).ok_or_else(|| bad(&format!("row {row}, {cname}"), "missing value".into()))?;
            let v: f64 = s.parse().map_err(|_| bad(&format!("row {row}, {cname}"), format!("not a number: {s:?}")))?;
            if !v.is_finite() {
                return Err(bad(&format!("row {row}, {cname}"), format!("not finite: {s}")));
            }
            if !(lo..=hi).contains(&v) {
                let what = if cname.ends_with("_deg") { "a joint angle in degrees" } else { "plausible" };
                return Err(bad(&format!("row {row}, {cname}"), format!("{v} is not {what} (allowed {lo}..={hi})")));
            }
            Ok(if cname.ends_with("_deg") { v.to_radians() } else { v })
        };
        rows.pct.push(get(ipct, "gait_cycle_pct", f64::MIN, f64::MAX)?);
        rows.knee.push(get(iknee, "knee_flexion_deg", -360.0, 360.0)?);
        for ((i, c), (_, v)) in present.iter().zip(rows.optional.iter_mut()) {
            v.push(get(*i, c.0, c.1, c.2)?);
        }
    }
    Ok(rows)
}

impl GaitCycle {
    /// Parse a gait CSV and fit each angle with a `harmonics`-term periodic Fourier series
    /// (least squares). Needs columns `gait_cycle_pct` and `knee_flexion_deg`
    /// ([`OPTIONAL_GAIT_COLUMNS`] optional); at least `2*harmonics + 2` and 8 rows; the cycle
    /// percentage strictly increasing and spanning at most 100 %. A last row that closes the
    /// cycle (first percentage + 100, as in the shared WBDS files) is the same instant as the
    /// first row: the least-squares fit weighs both, so the cycle repeats without a jump.
    pub fn parse(name: &str, text: &str, harmonics: usize) -> Result<Self> {
        let bad = |key: &str, msg: String| Error::input(name, key, msg);
        let GaitRows { pct, knee, optional } = read_gait_rows(name, text)?;
        let need = (2 * harmonics + 2).max(8);
        if pct.len() < need {
            return Err(bad(
                "rows",
                format!("need at least {need} rows over the cycle for {harmonics} harmonics, got {}", pct.len()),
            ));
        }
        if let Some(i) = pct.windows(2).position(|w| w[1] <= w[0]) {
            return Err(bad(
                &format!("row {}, gait_cycle_pct", i + 3),
                format!("cycle percentage must increase strictly: {} after {}", pct[i + 1], pct[i]),
            ));
        }
        check_coverage(&pct).map_err(|m| bad("gait_cycle_pct", m))?;
        let rows = pct.len();
        let fit = |v: &[f64]| FourierSeries::fit(&pct, v, 100.0, harmonics);
        let angle = |n: &str| optional.iter().find(|c| c.0 == n).map(|c| fit(&c.1));
        let (hip, ankle) = (angle("hip_flexion_deg"), angle("ankle_dorsiflexion_deg"));
        let pelvis_tilt = angle("pelvis_tilt_deg");
        let kinetics = optional
            .iter()
            .filter(|c| !c.0.ends_with("_deg"))
            .map(|c| (c.0, CycleTable { pct: pct.clone(), values: c.1.clone() }))
            .collect();
        Ok(GaitCycle { knee: fit(&knee), hip, ankle, pelvis_tilt, kinetics, rows })
    }

    /// A kinetics column by name, if the file has it.
    pub fn kinetic(&self, name: &str) -> Option<&CycleTable> {
        self.kinetics.iter().find(|c| c.0 == name).map(|c| &c.1)
    }

    /// Load a built-in trial by name; also returns its default stride time (s).
    pub fn builtin(name: &str, harmonics: usize) -> Option<Result<(Self, f64)>> {
        BUILTIN_TRIALS.iter().find(|t| t.0 == name).map(|t| Ok((Self::parse(t.0, t.1, harmonics)?, t.2)))
    }
}

/// A gait reference in time: a cycle repeated with a stride time.
#[derive(Debug, Clone)]
pub struct GaitReference {
    /// The cycle.
    pub cycle: GaitCycle,
    /// Stride (gait-cycle) time (s).
    pub stride_s: f64,
    /// Where the cycle came from (trial name or file path), for messages.
    pub source: String,
    /// SHA-256 of the data (hex).
    pub sha256: String,
}

impl GaitReference {
    fn sample(&self, s: &FourierSeries, t_s: f64) -> RefSample {
        let k = 100.0 / self.stride_s; // % per second
        let (v, d1, d2) = s.eval(t_s * k);
        RefSample { value: v, rate: d1 * k, accel: d2 * k * k }
    }

    /// Desired knee flexion (rad) and its time derivatives at `t_s`.
    pub fn knee_at(&self, t_s: f64) -> RefSample {
        self.sample(&self.cycle.knee, t_s)
    }

    /// Desired knee flexion (rad) and its first three time derivatives at `t_s`.
    pub fn knee_jerk_at(&self, t_s: f64) -> (f64, f64, f64, f64) {
        let k = 100.0 / self.stride_s;
        let (v, d1, d2, d3) = self.cycle.knee.eval3(t_s * k);
        (v, d1 * k, d2 * k * k, d3 * k * k * k)
    }

    /// Ankle dorsiflexion (rad) and its time derivatives at `t_s` (zero if the file has no
    /// ankle column).
    pub fn ankle_at(&self, t_s: f64) -> RefSample {
        self.cycle.ankle.as_ref().map_or(RefSample::default(), |a| self.sample(a, t_s))
    }

    /// Pelvis tilt (rad, anterior positive) and its time derivatives at `t_s`, if the file has
    /// a `pelvis_tilt_deg` column.
    pub fn pelvis_tilt_at(&self, t_s: f64) -> Option<RefSample> {
        self.cycle.pelvis_tilt.as_ref().map(|p| self.sample(p, t_s))
    }

    /// Hip flexion (rad) and its time derivatives at `t_s` (zero if the file has no hip column).
    pub fn hip_at(&self, t_s: f64) -> RefSample {
        self.cycle.hip.as_ref().map_or(RefSample::default(), |h| self.sample(h, t_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paired evaluation gives the same bits as two single ones (it is on every gait run's
    /// hot path; the shipped outputs' hashes rest on it), and falls back for unlike series.
    #[test]
    fn eval_pair_is_bit_identical_to_eval() {
        let x: Vec<f64> = (0..200).map(|i| i as f64 * 0.0055).collect();
        let y1: Vec<f64> = x.iter().map(|t| (7.0 * t).sin() + 0.3 * (19.0 * t).cos()).collect();
        let y2: Vec<f64> = x.iter().map(|t| (t * 3.0).cos() * t).collect();
        let (a, b) = (FourierSeries::fit(&x, &y1, 1.1, 20), FourierSeries::fit(&x, &y2, 1.1, 20));
        let other = FourierSeries::fit(&x, &y2, 1.1, 12);
        for t in [0.0, 0.123, 0.77, 1.05, 3.3] {
            assert_eq!(a.eval_pair(&b, t), (a.eval(t), b.eval(t)));
            assert_eq!(a.eval_pair(&other, t), (a.eval(t), other.eval(t)));
        }
    }

    /// The fast remainder gives `rem_euclid`'s bits, at the edges and on a million values.
    #[test]
    fn rem_euclid_100_is_rem_euclid() {
        let mut x = 0x853c_49e6_748f_ea9bu64;
        let edges = [0.0, -0.0, 100.0, -100.0, 99.99999999999999, -1e-300, 299.99999999999994, 1e15, -1e15, 5e16];
        let randoms = (0..1_000_000).map(|i| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let u = x as f64 / u64::MAX as f64;
            match i % 3 {
                0 => (u - 0.5) * 1000.0,
                1 => (u - 0.3) * 1e7,
                _ => ((x % 2000) as f64 - 1000.0) * 100.0 * (1.0 + (u - 0.5) * 1e-15),
            }
        });
        for v in edges.into_iter().chain(randoms) {
            assert_eq!(rem_euclid_100(v).to_bits(), v.rem_euclid(100.0).to_bits(), "{v:e}");
        }
        assert!(rem_euclid_100(f64::NAN).is_nan());
    }

    /// A series evaluated after another of the same angle (the kept basis) gives the bits of
    /// its own recurrence: interleaved angles and lengths, against a fresh thread.
    #[test]
    fn kept_harmonics_give_the_same_bits() {
        let x: Vec<f64> = (0..300).map(|i| i as f64 * 0.0037).collect();
        let y: Vec<f64> = x.iter().map(|t| (5.0 * t).sin() + (t * 2.0).cos() * t).collect();
        let series: Vec<FourierSeries> = [3, 12, 48, 70].iter().map(|&h| FourierSeries::fit(&x, &y, 1.1, h)).collect();
        let ts = [0.0, 0.3, 0.3, 1.7, 0.3, 2.2, 1.7];
        let here: Vec<_> =
            ts.iter().flat_map(|&t| series.iter().map(move |s| (s.eval(t), s.eval3(t), s.eval_pair(s, t)))).collect();
        let fresh = std::thread::scope(|sc| {
            sc.spawn(|| {
                ts.iter()
                    .flat_map(|&t| {
                        series.iter().map(move |s| {
                            // A new thread per evaluation: nothing kept.
                            std::thread::scope(|s2| {
                                s2.spawn(|| (s.eval(t), s.eval3(t), s.eval_pair(s, t))).join().unwrap()
                            })
                        })
                    })
                    .collect::<Vec<_>>()
            })
            .join()
            .unwrap()
        });
        assert_eq!(here, fresh);
    }

    #[test]
    fn fourier_fit_reproduces_a_trigonometric_polynomial_and_its_derivatives() {
        let x: Vec<f64> = (0..60).map(|i| i as f64 * 100.0 / 60.0 + 0.3 * (i % 3) as f64).collect();
        let w = std::f64::consts::TAU / 100.0;
        let f = |x: f64| 1.5 + (w * x).sin() - 0.2 * (3.0 * w * x).cos();
        let y: Vec<f64> = x.iter().map(|&x| f(x)).collect();
        let s = FourierSeries::fit(&x, &y, 100.0, 5);
        for &q in &[0.0, 13.7, 99.9, 250.3, -7.0] {
            let (v, d1, d2) = s.eval(q);
            let e1 = w * (w * q).cos() + 0.6 * w * (3.0 * w * q).sin();
            let e2 = -w * w * (w * q).sin() + 1.8 * w * w * (3.0 * w * q).cos();
            assert!((v - f(q)).abs() < 1e-10 && (d1 - e1).abs() < 1e-10 && (d2 - e2).abs() < 1e-10, "at {q}");
        }
    }

    #[test]
    fn builtin_cycle_repeats_without_a_jump_and_fits_the_data() {
        let (c, stride) = GaitCycle::builtin("wbds01_overground_comfortable", 12).unwrap().unwrap();
        let g = GaitReference { cycle: c.clone(), stride_s: stride, source: String::new(), sha256: String::new() };
        let (a, b) = (g.knee_at(stride - 1e-9), g.knee_at(stride + 1e-9));
        assert!((a.value - b.value).abs() < 1e-8 && (a.rate - b.rate).abs() < 1e-5);
        // Peak knee flexion 67.6 deg at 74 % (README of the data).
        let (mut best, mut at) = (0.0, 0.0);
        for i in 0..1000 {
            let t = i as f64 * stride / 1000.0;
            let v = g.knee_at(t).value.to_degrees();
            if v > best {
                (best, at) = (v, t / stride * 100.0);
            }
        }
        assert!((best - 67.6).abs() < 0.5 && (at - 74.0).abs() < 1.5, "peak {best} at {at} %");
        // A 12-harmonic fit stays within 0.5 deg of every data row.
        let mut rdr = csv::Reader::from_reader(BUILTIN_TRIALS[0].1.as_bytes());
        for r in rdr.records() {
            let r = r.unwrap();
            let (p, k): (f64, f64) = (r[0].parse().unwrap(), r[2].parse().unwrap());
            let v = c.knee.eval(p).0.to_degrees();
            assert!((v - k).abs() < 0.5, "{p} %: fit {v} vs data {k}");
        }
    }

    #[test]
    fn malformed_files_are_rejected_with_the_problem_named() {
        let hdr = "gait_cycle_pct,knee_flexion_deg\n";
        let rows = |v: &[(f64, &str)]| v.iter().map(|(p, k)| format!("{p},{k}\n")).collect::<String>();
        let ok: Vec<(f64, &str)> = (0..10).map(|i| (i as f64 * 10.0, "5")).collect();
        assert!(GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&ok)), 3).is_ok());
        let e = GaitCycle::parse("f.csv", "gait_cycle_pct,hip\n0,1\n", 3).unwrap_err().to_string();
        assert!(e.contains("f.csv") && e.contains("knee_flexion_deg") && e.contains("missing column"), "{e}");
        let mut nm = ok.clone();
        nm[4].0 = 20.0;
        let e = GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&nm)), 3).unwrap_err().to_string();
        assert!(e.contains("row 6") && e.contains("increase"), "{e}");
        let mut nan = ok.clone();
        nan[3].1 = "NaN";
        let e = GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&nan)), 3).unwrap_err().to_string();
        assert!(e.contains("row 5") && e.contains("not finite"), "{e}");
        let e = GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&ok[..5])), 3).unwrap_err().to_string();
        assert!(e.contains("at least 8 rows"), "{e}");
        let e = GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&ok)), 12).unwrap_err().to_string();
        assert!(e.contains("at least 26 rows"), "{e}");
    }
}
