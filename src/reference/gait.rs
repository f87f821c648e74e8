//! Gait-cycle references: knee (and hip) angle over the gait cycle from a CSV, repeated
//! seamlessly, with analytic first and second time derivatives from a periodic cubic spline.

use super::RefSample;
use crate::error::{Error, Result};

/// Built-in trials (the shared WBDS files, embedded so a run needs no data path).
pub const BUILTIN_TRIALS: [(&str, &str, f64); 6] = [
    (
        "wbds01_overground_comfortable",
        include_str!("../../assets/gait/wbds01_overground_comfortable.csv"),
        1.10,
    ),
    (
        "wbds01_overground_fast",
        include_str!("../../assets/gait/wbds01_overground_fast.csv"),
        0.95,
    ),
    (
        "wbds01_overground_slow",
        include_str!("../../assets/gait/wbds01_overground_slow.csv"),
        1.30,
    ),
    (
        "wbds02_overground_comfortable",
        include_str!("../../assets/gait/wbds02_overground_comfortable.csv"),
        1.10,
    ),
    (
        "wbds02_overground_fast",
        include_str!("../../assets/gait/wbds02_overground_fast.csv"),
        0.95,
    ),
    (
        "wbds02_overground_slow",
        include_str!("../../assets/gait/wbds02_overground_slow.csv"),
        1.30,
    ),
];

/// Interpolating cubic spline with periodic end conditions (C2 across the period boundary).
#[derive(Debug, Clone)]
pub struct PeriodicSpline {
    x: Vec<f64>,
    y: Vec<f64>,
    m: Vec<f64>,
    period: f64,
}

/// Solve a dense linear system in place (Gaussian elimination with partial pivoting).
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap_or(c);
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            if f != 0.0 {
                let (top, bottom) = a.split_at_mut(r);
                for (x, y) in bottom[0][c..].iter_mut().zip(&top[c][c..]) {
                    *x -= f * y;
                }
                b[r] -= f * b[c];
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x
}

impl PeriodicSpline {
    /// Knots `x` strictly increasing with `x[n-1] < x[0] + period`, values `y`. At least 3 knots.
    pub fn new(x: Vec<f64>, y: Vec<f64>, period: f64) -> Self {
        let n = x.len();
        let h = |i: usize| {
            if i + 1 < n {
                x[i + 1] - x[i]
            } else {
                x[0] + period - x[n - 1]
            }
        };
        let mut a = vec![vec![0.0; n]; n];
        let mut b = vec![0.0; n];
        for i in 0..n {
            let (ip, im) = ((i + 1) % n, (i + n - 1) % n);
            let (hi, hm) = (h(i), h(im));
            a[i][im] += hm;
            a[i][i] += 2.0 * (hm + hi);
            a[i][ip] += hi;
            b[i] = 6.0 * ((y[ip] - y[i]) / hi - (y[i] - y[im]) / hm);
        }
        let m = solve_dense(a, b);
        Self { x, y, m, period }
    }

    /// Value, first and second derivative at `xq` (any real; wrapped into the period).
    pub fn eval(&self, xq: f64) -> (f64, f64, f64) {
        let n = self.x.len();
        let x0 = self.x[0];
        let u = x0 + (xq - x0).rem_euclid(self.period);
        let i = self.x.partition_point(|&k| k <= u).saturating_sub(1);
        let ip = (i + 1) % n;
        let xi1 = if i + 1 < n { self.x[i + 1] } else { x0 + self.period };
        let h = xi1 - self.x[i];
        let (a, b) = ((xi1 - u) / h, (u - self.x[i]) / h);
        let (yi, yj, mi, mj) = (self.y[i], self.y[ip], self.m[i], self.m[ip]);
        let v = a * yi + b * yj + ((a * a * a - a) * mi + (b * b * b - b) * mj) * h * h / 6.0;
        let d1 = (yj - yi) / h - (3.0 * a * a - 1.0) / 6.0 * h * mi + (3.0 * b * b - 1.0) / 6.0 * h * mj;
        let d2 = a * mi + b * mj;
        (v, d1, d2)
    }
}

/// One gait cycle read from a CSV: knee (and optionally hip) angle against % of the cycle.
#[derive(Debug, Clone)]
pub struct GaitCycle {
    /// Knee flexion (rad, flexion positive) against cycle percentage.
    pub knee: PeriodicSpline,
    /// Hip flexion (rad, flexion positive) against cycle percentage, if the file has it.
    pub hip: Option<PeriodicSpline>,
    /// Number of data rows read.
    pub rows: usize,
}

impl GaitCycle {
    /// Parse a gait CSV. Needs columns `gait_cycle_pct` and `knee_flexion_deg`
    /// (`hip_flexion_deg` optional); at least 8 rows; the cycle percentage strictly increasing
    /// and spanning at most 100 %. When the last row closes the cycle (its percentage is the
    /// first plus 100, as in the shared WBDS files), it is the same instant as the first row:
    /// the two values are averaged so the cycle repeats without a jump.
    pub fn parse(name: &str, text: &str) -> Result<Self> {
        let bad = |key: &str, msg: String| Error::input(name, key, msg);
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let headers = rdr
            .headers()
            .map_err(|e| bad("header", format!("malformed CSV: {e}")))?
            .clone();
        let col = |n: &str| headers.iter().position(|h| h == n);
        let ipct = col("gait_cycle_pct").ok_or_else(|| bad("gait_cycle_pct", "missing column".into()))?;
        let iknee = col("knee_flexion_deg").ok_or_else(|| bad("knee_flexion_deg", "missing column".into()))?;
        let ihip = col("hip_flexion_deg");
        let (mut pct, mut knee, mut hip) = (Vec::new(), Vec::new(), Vec::new());
        for (r, rec) in rdr.records().enumerate() {
            let row = r + 2; // 1-based, after the header
            let rec = rec.map_err(|e| bad(&format!("row {row}"), format!("malformed CSV: {e}")))?;
            let get = |i: usize, cname: &str| -> Result<f64> {
                let s = rec
                    .get(i)
                    .ok_or_else(|| bad(&format!("row {row}, {cname}"), "missing value".into()))?;
                let v: f64 = s
                    .parse()
                    .map_err(|_| bad(&format!("row {row}, {cname}"), format!("not a number: {s:?}")))?;
                if !v.is_finite() {
                    return Err(bad(&format!("row {row}, {cname}"), format!("not finite: {s}")));
                }
                Ok(v)
            };
            pct.push(get(ipct, "gait_cycle_pct")?);
            knee.push(get(iknee, "knee_flexion_deg")?.to_radians());
            if let Some(i) = ihip {
                hip.push(get(i, "hip_flexion_deg")?.to_radians());
            }
        }
        if pct.len() < 8 {
            return Err(bad(
                "rows",
                format!("need at least 8 rows over the cycle, got {}", pct.len()),
            ));
        }
        if let Some(i) = pct.windows(2).position(|w| w[1] <= w[0]) {
            return Err(bad(
                &format!("row {}, gait_cycle_pct", i + 3),
                format!(
                    "cycle percentage must increase strictly: {} after {}",
                    pct[i + 1],
                    pct[i]
                ),
            ));
        }
        let span = pct[pct.len() - 1] - pct[0];
        if span > 100.0 + 1e-9 {
            return Err(bad(
                "gait_cycle_pct",
                format!("spans {span} %; one cycle is at most 100 %"),
            ));
        }
        let rows = pct.len();
        let closes = (span - 100.0).abs() <= 1e-9;
        let finish = |mut v: Vec<f64>| -> PeriodicSpline {
            let mut p = pct.clone();
            if closes {
                let last = v.pop().unwrap();
                p.pop();
                v[0] = 0.5 * (v[0] + last);
            }
            PeriodicSpline::new(p, v, 100.0)
        };
        let hip = if ihip.is_some() { Some(finish(hip)) } else { None };
        Ok(GaitCycle {
            knee: finish(knee),
            hip,
            rows,
        })
    }

    /// Load a built-in trial by name.
    pub fn builtin(name: &str) -> Option<(Self, f64)> {
        BUILTIN_TRIALS
            .iter()
            .find(|t| t.0 == name)
            .map(|t| (Self::parse(t.0, t.1).expect("built-in gait data is valid"), t.2))
    }
}

/// A gait reference in time: a cycle repeated with a stride time.
#[derive(Debug, Clone)]
pub struct GaitReference {
    /// The cycle.
    pub cycle: GaitCycle,
    /// Stride (gait-cycle) time (s).
    pub stride_s: f64,
}

impl GaitReference {
    fn sample(&self, s: &PeriodicSpline, t_s: f64) -> RefSample {
        let k = 100.0 / self.stride_s; // % per second
        let (v, d1, d2) = s.eval(t_s * k);
        RefSample {
            value: v,
            rate: d1 * k,
            accel: d2 * k * k,
        }
    }

    /// Desired knee flexion (rad) and its time derivatives at `t_s`.
    pub fn knee_at(&self, t_s: f64) -> RefSample {
        self.sample(&self.cycle.knee, t_s)
    }

    /// Hip flexion (rad) and its time derivatives at `t_s` (zero if the file has no hip column).
    pub fn hip_at(&self, t_s: f64) -> RefSample {
        self.cycle
            .hip
            .as_ref()
            .map_or(RefSample::default(), |h| self.sample(h, t_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periodic_spline_reproduces_a_sine_and_its_derivatives() {
        let n = 50;
        let x: Vec<f64> = (0..n).map(|i| i as f64 * 2.0).collect();
        let w = std::f64::consts::TAU / 100.0;
        let y: Vec<f64> = x.iter().map(|&x| (w * x).sin()).collect();
        let s = PeriodicSpline::new(x, y, 100.0);
        for &q in &[0.0, 13.7, 99.9, 100.0, 250.3, -7.0] {
            let (v, d1, d2) = s.eval(q);
            assert!((v - (w * q).sin()).abs() < 1e-5, "value at {q}");
            assert!((d1 - w * (w * q).cos()).abs() < 1e-4 * w, "d1 at {q}");
            assert!((d2 + w * w * (w * q).sin()).abs() < 2e-2 * w * w, "d2 at {q}");
        }
    }

    #[test]
    fn builtin_cycle_repeats_without_a_jump() {
        let (c, stride) = GaitCycle::builtin("wbds01_overground_comfortable").unwrap();
        let g = GaitReference {
            cycle: c,
            stride_s: stride,
        };
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
        assert!(
            (best - 67.6).abs() < 0.3 && (at - 74.0).abs() < 1.5,
            "peak {best} at {at} %"
        );
    }

    #[test]
    fn malformed_files_are_rejected_with_the_problem_named() {
        let hdr = "gait_cycle_pct,knee_flexion_deg\n";
        let rows = |v: &[(f64, &str)]| v.iter().map(|(p, k)| format!("{p},{k}\n")).collect::<String>();
        let ok: Vec<(f64, &str)> = (0..10).map(|i| (i as f64 * 10.0, "5")).collect();
        assert!(GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&ok))).is_ok());
        let e = GaitCycle::parse("f.csv", "gait_cycle_pct,hip\n0,1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("f.csv") && e.contains("knee_flexion_deg") && e.contains("missing column"),
            "{e}"
        );
        let mut nm = ok.clone();
        nm[4].0 = 20.0;
        let e = GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&nm)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("row 6") && e.contains("increase"), "{e}");
        let mut nan = ok.clone();
        nan[3].1 = "NaN";
        let e = GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&nan)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("row 5") && e.contains("not finite"), "{e}");
        let e = GaitCycle::parse("f.csv", &(hdr.to_string() + &rows(&ok[..5])))
            .unwrap_err()
            .to_string();
        assert!(e.contains("at least 8 rows"), "{e}");
    }
}
