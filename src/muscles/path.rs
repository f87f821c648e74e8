//! A muscle-tendon unit's path: its length as a function of the joint angles it spans, from a
//! table made offline with OpenSim (`scripts/opensim-muscles`), interpolated so that the
//! moment arm is exactly `r = -dL/dq` of the interpolated length (so the unit's power is
//! `F dL/dt`, OpenSim's `FunctionBasedPath` route).
//!
//! The interpolant is the tensor product of Catmull-Rom cubics (central-difference tangents,
//! continuous length and slope; quadratics reproduced, the end cells included), and beyond the grid the
//! length continues along its edge slope: the moment arm there is the edge's. A path whose
//! length jumps in the source model (OpenSim's conditional path points, e.g. the
//! gait10dof18musc gastrocnemius at 45 deg of knee flexion, 0.37 mm) is followed by the cubic
//! across one grid cell: its moment arm there carries the jump over the cell's width.

/// The three joints a path may span, in the order tables list them.
pub const JOINTS: [&str; 3] = ["hip", "knee", "ankle"];

/// One tabulated path: the joints it spans (indices into [`JOINTS`]), its grid (deg), and the
/// lengths (m), row-major with the last joint fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct PathTable {
    /// The spanned joints, ascending.
    pub joints: Vec<usize>,
    /// First grid angle per spanned joint (deg).
    pub start_deg: Vec<f64>,
    /// Grid step per spanned joint (deg, > 0).
    pub step_deg: Vec<f64>,
    /// Grid points per spanned joint (>= 4).
    pub count: Vec<usize>,
    /// Lengths (m).
    pub length_m: Vec<f64>,
}

/// Per spanned joint: up to four grid indices and the weights of the value and of its slope
/// (per grid step) at a point.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Axis {
    index: [usize; 4],
    w: [f64; 4],
    dw: [f64; 4],
    /// How far past the grid's edge the point is (grid steps; 0 inside).
    beyond: f64,
}

/// The Catmull-Rom weights of p[i-1..=i+2] at `t` in [0, 1] and their derivatives in t.
fn catmull_rom(t: f64) -> ([f64; 4], [f64; 4]) {
    let (t2, t3) = (t * t, t * t * t);
    let w = [-0.5 * t + t2 - 0.5 * t3, 1.0 - 2.5 * t2 + 1.5 * t3, 0.5 * t + 2.0 * t2 - 1.5 * t3, -0.5 * t2 + 0.5 * t3];
    let dw = [-0.5 + 2.0 * t - 1.5 * t2, -5.0 * t + 4.5 * t2, 0.5 + 4.0 * t - 4.5 * t2, -t + 1.5 * t2];
    (w, dw)
}

impl Axis {
    /// The axis of a grid of `n` points from `start` by `step` at `x` (same unit).
    fn at(x: f64, start: f64, step: f64, n: usize) -> Self {
        let u = (x - start) / step;
        let top = (n - 1) as f64;
        let (uc, beyond) = if u < 0.0 {
            (0.0, u)
        } else if u > top {
            (top, u - top)
        } else {
            (u, 0.0)
        };
        let i = (uc.floor() as usize).min(n - 2);
        let t = uc - i as f64;
        let (mut w, mut dw) = catmull_rom(t);
        // The grid's end cells take a quadratic through their three nearest points for the
        // missing one: p[-1] = 3 p[0] - 3 p[1] + p[2], p[n] = 3 p[n-1] - 3 p[n-2] + p[n-3].
        let mut index = [i.wrapping_sub(1), i, i + 1, i + 2];
        let fold = |w: &mut [f64; 4], lo: bool| {
            if lo {
                (w[1], w[2], w[3], w[0]) = (w[1] + 3.0 * w[0], w[2] - 3.0 * w[0], w[3] + w[0], 0.0);
            } else {
                (w[2], w[1], w[0], w[3]) = (w[2] + 3.0 * w[3], w[1] - 3.0 * w[3], w[0] + w[3], 0.0);
            }
        };
        if i == 0 {
            fold(&mut w, true);
            fold(&mut dw, true);
            index[0] = i;
        }
        if i + 2 >= n {
            fold(&mut w, false);
            fold(&mut dw, false);
            index[3] = i + 1;
        }
        Self { index, w, dw, beyond }
    }
}

impl PathTable {
    /// Grid points the table should hold.
    pub fn points(&self) -> usize {
        self.count.iter().product()
    }

    /// The length (m) at the joint angles `q_rad` (hip, knee, ankle; exoleg's signs) and its
    /// derivatives dL/dq (m/rad; 0 for a joint the path does not span).
    pub fn length_and_slope(&self, q_rad: [f64; 3]) -> (f64, [f64; 3]) {
        let (l, s, _) = self.evaluate(q_rad);
        (l, s)
    }

    /// [`Self::length_and_slope`] and whether the angles are inside the grid.
    pub fn evaluate(&self, q_rad: [f64; 3]) -> (f64, [f64; 3], bool) {
        let mut axes = [Axis::default(); 3];
        for (k, a) in axes.iter_mut().enumerate().take(self.joints.len()) {
            *a = self.axis(k, q_rad);
        }
        self.evaluate_axes(&axes)
    }

    /// The grid of spanned joint `k` (its joint, first angle, step and points): paths with the
    /// same grid share its [`Self::axis`] at a state.
    pub(crate) fn grid(&self, k: usize) -> (usize, u64, u64, usize) {
        (self.joints[k], self.start_deg[k].to_bits(), self.step_deg[k].to_bits(), self.count[k])
    }

    /// Spanned joint `k`'s grid indices and weights at the angles `q_rad`.
    pub(crate) fn axis(&self, k: usize, q_rad: [f64; 3]) -> Axis {
        Axis::at(q_rad[self.joints[k]].to_degrees(), self.start_deg[k], self.step_deg[k], self.count[k])
    }

    /// [`Self::evaluate`] from the spanned joints' axes (`axes[k]` of [`Self::axis`]).
    pub(crate) fn evaluate_axes(&self, axes: &[Axis; 3]) -> (f64, [f64; 3], bool) {
        let d = self.joints.len();
        let (mut l, dl) = match d {
            1 => self.sum1(&axes[0]),
            2 => self.sum2(&axes[0], &axes[1]),
            _ => self.sum_any(&axes[..d]),
        };
        let mut slope = [0.0; 3];
        let mut inside = true;
        for (k, &j) in self.joints.iter().enumerate() {
            // Per grid step to per radian; past the edge the length goes on along the slope.
            let per_rad = dl[k] / self.step_deg[k].to_radians();
            slope[j] = per_rad;
            l += per_rad * (axes[k].beyond * self.step_deg[k]).to_radians();
            inside &= axes[k].beyond == 0.0;
        }
        (l, slope, inside)
    }

    /// One joint: the value and its slope per grid step.
    fn sum1(&self, a: &Axis) -> (f64, [f64; 3]) {
        let (mut l, mut d) = (0.0, 0.0);
        for m in 0..4 {
            let p = self.length_m[a.index[m]];
            l += a.w[m] * p;
            d += a.dw[m] * p;
        }
        (l, [d, 0.0, 0.0])
    }

    /// Two joints (the second fastest in the table).
    fn sum2(&self, a: &Axis, b: &Axis) -> (f64, [f64; 3]) {
        let stride = self.count[1];
        let (mut l, mut d0, mut d1) = (0.0, 0.0, 0.0);
        for m in 0..4 {
            let row = &self.length_m[a.index[m] * stride..];
            let (mut v, mut dv) = (0.0, 0.0);
            for n in 0..4 {
                let p = row[b.index[n]];
                v += b.w[n] * p;
                dv += b.dw[n] * p;
            }
            l += a.w[m] * v;
            d0 += a.dw[m] * v;
            d1 += a.w[m] * dv;
        }
        (l, [d0, d1, 0.0])
    }

    /// Any number of joints: the tensor product's 4^d terms.
    fn sum_any(&self, axes: &[Axis]) -> (f64, [f64; 3]) {
        let d = axes.len();
        let strides = self.strides();
        let (mut l, mut dl) = (0.0, [0.0; 3]);
        for c in 0..4usize.pow(d as u32) {
            let (mut offset, mut w) = (0, 1.0);
            let mut dw = [1.0; 3];
            for (k, a) in axes.iter().enumerate() {
                let m = (c >> (2 * k)) & 3;
                offset += a.index[m] * strides[k];
                for (kk, dwk) in dw.iter_mut().enumerate().take(d) {
                    *dwk *= if kk == k { a.dw[m] } else { a.w[m] };
                }
                w *= a.w[m];
            }
            let p = self.length_m[offset];
            l += w * p;
            for k in 0..d {
                dl[k] += dw[k] * p;
            }
        }
        (l, dl)
    }

    /// Whether the angles are inside the grid on every spanned joint.
    pub fn covers(&self, q_rad: [f64; 3]) -> bool {
        self.joints.iter().enumerate().all(|(k, &j)| {
            let x = q_rad[j].to_degrees();
            let end = self.start_deg[k] + (self.count[k] - 1) as f64 * self.step_deg[k];
            x >= self.start_deg[k] && x <= end
        })
    }

    /// The index stride of each spanned joint in `length_m`.
    fn strides(&self) -> [usize; 3] {
        let mut s = [1usize; 3];
        for k in (0..self.joints.len().saturating_sub(1)).rev() {
            s[k] = s[k + 1] * self.count[k + 1];
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(joints: Vec<usize>, f: impl Fn(&[f64]) -> f64) -> PathTable {
        let (start, step, count) = ([-40.0, -10.0, -30.0], [1.0, 2.0, 1.5], [131usize, 66, 41]);
        let start_deg: Vec<f64> = joints.iter().map(|&j| start[j]).collect();
        let step_deg: Vec<f64> = joints.iter().map(|&j| step[j]).collect();
        let count: Vec<usize> = joints.iter().map(|&j| count[j]).collect();
        let n: usize = count.iter().product();
        let mut length_m = Vec::with_capacity(n);
        for i in 0..n {
            let mut rem = i;
            let mut x = vec![0.0; joints.len()];
            for k in (0..joints.len()).rev() {
                x[k] = (start_deg[k] + (rem % count[k]) as f64 * step_deg[k]).to_radians();
                rem /= count[k];
            }
            length_m.push(f(&x));
        }
        PathTable { joints, start_deg, step_deg, count, length_m }
    }

    /// A smooth path of two joints: the interpolant's length and slopes to the function's,
    /// the slope exactly the derivative of the interpolated length (central differences of
    /// it), continuous across cells, and linear past the grid.
    #[test]
    fn interpolation_is_the_length_and_its_derivative() {
        let f = |x: &[f64]| 0.4 + 0.03 * (x[0] + 0.3).sin() - 0.02 * x[1] + 0.01 * (x[0] * x[1]).cos();
        let t = table(vec![0, 1], f);
        for (h, k) in [(10.3f64, 35.7f64), (-39.0, -9.0), (0.0, 0.0), (88.5, 119.0), (25.0, 60.0)] {
            let q = [h.to_radians(), k.to_radians(), 0.0];
            let (l, s) = t.length_and_slope(q);
            assert!((l - f(&[q[0], q[1]])).abs() < 2e-7, "L at ({h}, {k})");
            let e = 1e-7;
            let num = |j: usize| {
                let (mut a, mut b) = (q, q);
                a[j] += e;
                b[j] -= e;
                (t.length_and_slope(a).0 - t.length_and_slope(b).0) / (2.0 * e)
            };
            assert!((s[0] - num(0)).abs() < 1e-7 && (s[1] - num(1)).abs() < 1e-7, "slope at ({h}, {k}): {s:?}");
            assert_eq!(s[2], 0.0);
        }
        // Past the grid: linear in the angle with the edge's slope.
        let edge = [90f64.to_radians(), 0.3, 0.0];
        let (l0, s0) = t.length_and_slope(edge);
        let far = [100f64.to_radians(), 0.3, 0.0];
        let (l1, s1) = t.length_and_slope(far);
        assert!((s1[0] - s0[0]).abs() < 1e-12 && (l1 - (l0 + s0[0] * 10f64.to_radians())).abs() < 1e-12);
        assert!(!t.covers(far) && t.covers(edge));
    }

    /// One and three joints: cubic polynomials in each angle are reproduced exactly inside
    /// the grid (Catmull-Rom reproduces quadratics; cubics to the grid's truncation).
    #[test]
    fn one_and_three_joints() {
        let q = |x: f64| 0.3 + 0.02 * x + 0.01 * x * x;
        let t1 = table(vec![2], |x| q(x[0]));
        for a in [-29.0f64, -3.3, 0.0, 12.7, 29.9] {
            let (l, s) = t1.length_and_slope([0.0, 0.0, a.to_radians()]);
            let x = a.to_radians();
            assert!((l - q(x)).abs() < 1e-12 && (s[2] - (0.02 + 0.02 * x)).abs() < 1e-10, "{a}");
        }
        let t3 = table(vec![0, 1, 2], |x| q(x[0]) + 2.0 * q(x[1]) - q(x[2]) + 0.05 * x[0] * x[2]);
        let x = [0.2, 0.7, -0.1];
        let (l, s) = t3.length_and_slope(x);
        let want = q(x[0]) + 2.0 * q(x[1]) - q(x[2]) + 0.05 * x[0] * x[2];
        assert!((l - want).abs() < 1e-12, "{l} vs {want}");
        assert!((s[0] - (0.02 + 0.02 * x[0] + 0.05 * x[2])).abs() < 1e-10);
        assert!((s[1] - 2.0 * (0.02 + 0.02 * x[1])).abs() < 1e-10);
        assert!((s[2] - (-(0.02 + 0.02 * x[2]) + 0.05 * x[0])).abs() < 1e-10);
    }
}
