//! Exact sampled-data models and steady-state Kalman gains, for controllers designed in
//! discrete time (nalgebra: matrix exponential, LU solves).

use nalgebra::{DMatrix, DVector};

/// A continuous LTI model `x' = A x + B u + E w` sampled at period `h`: `u` held (zero-order
/// hold), `w` ramped (first-order hold: `w(s) = w0 + w1 s` over the sample).
#[derive(Debug, Clone, PartialEq)]
pub struct SampledLti {
    /// `expm(A h)`.
    pub phi: DMatrix<f64>,
    /// `int_0^h expm(A s) ds B` (the held input).
    pub gamma: DVector<f64>,
    /// `int_0^h expm(A (h - s)) E ds` (the ramped input's value at the sample start).
    pub g0: DVector<f64>,
    /// `int_0^h expm(A (h - s)) E s ds` (its slope, per second).
    pub g1: DVector<f64>,
}

impl SampledLti {
    /// Discretize exactly with one block-matrix exponential of
    /// `[[A, B, E, 0], [0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0]] h`.
    pub fn new(a: &DMatrix<f64>, b: &DVector<f64>, e: &DVector<f64>, h: f64) -> Self {
        let n = a.nrows();
        let mut m = DMatrix::<f64>::zeros(n + 3, n + 3);
        m.view_mut((0, 0), (n, n)).copy_from(a);
        m.view_mut((0, n), (n, 1)).copy_from(b);
        m.view_mut((0, n + 1), (n, 1)).copy_from(e);
        m[(n + 1, n + 2)] = 1.0;
        let x = (m * h).exp();
        Self {
            phi: x.view((0, 0), (n, n)).into_owned(),
            gamma: x.view((0, n), (n, 1)).column(0).into_owned(),
            g0: x.view((0, n + 1), (n, 1)).column(0).into_owned(),
            g1: x.view((0, n + 2), (n, 1)).column(0).into_owned(),
        }
    }

    /// One step: `Phi x + Gamma u + G0 w0 + G1 w1`.
    pub fn step(&self, x: &DVector<f64>, u: f64, w0: f64, w1: f64) -> DVector<f64> {
        let mut out = DVector::zeros(x.len());
        self.step_into(x, u, w0, w1, &mut out);
        out
    }

    /// [`Self::step`] into `out` (not `x`), summed left to right.
    pub fn step_into(&self, x: &DVector<f64>, u: f64, w0: f64, w1: f64, out: &mut DVector<f64>) {
        self.phi.mul_to(x, out);
        for i in 0..out.len() {
            out[i] = ((out[i] + self.gamma[i] * u) + self.g0[i] * w0) + self.g1[i] * w1;
        }
    }
}

/// The steady-state Kalman gain of `x+ = Phi x + w (cov Q)`, `y = C x + v (cov R)`, for the
/// measurement update `x = x_prior + L (y - C x_prior)`: the a-priori covariance P solves the
/// discrete algebraic Riccati equation `P = Phi P Phi^T - Phi P C^T (C P C^T + R)^-1 C P Phi^T + Q`,
/// found by the structure-preserving doubling algorithm (quadratic convergence, robust for
/// the marginally stable modes of a disturbance model; Chu et al. 2004) applied to the dual
/// control equation (A = Phi^T, B = C^T); then `L = P C^T (C P C^T + R)^-1`. Returns
/// (L, P, doubling steps); None if it does not converge (an undetectable model) within
/// `max_iter` doublings.
pub fn kalman_gain(
    phi: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    max_iter: usize,
) -> Option<(DMatrix<f64>, DMatrix<f64>, usize)> {
    let n = phi.nrows();
    let eye = DMatrix::<f64>::identity(n, n);
    let mut a = phi.transpose();
    let mut g = c.transpose() * r.clone().try_inverse()? * c;
    let mut h = q.clone();
    for it in 0..max_iter {
        let w = (&eye + &g * &h).try_inverse()?;
        let a_next = &a * &w * &a;
        let g_next = &g + &a * &w * &g * a.transpose();
        let h_next = &h + a.transpose() * &h * &w * &a;
        let h_next = (&h_next + h_next.transpose()) * 0.5;
        if !h_next.iter().all(|v| v.is_finite()) {
            return None;
        }
        // Converged when every entry moved by less than 1e-13 of its correlation scale.
        let settled = (0..n).all(|i| {
            (0..n).all(|j| {
                let scale = (h_next[(i, i)].abs() * h_next[(j, j)].abs()).sqrt().max(1e-300);
                (h_next[(i, j)] - h[(i, j)]).abs() <= 1e-13 * scale
            })
        });
        (a, g, h) = (a_next, g_next, h_next);
        if settled {
            let s_inv = (c * &h * c.transpose() + r).try_inverse()?;
            return Some((&h * c.transpose() * s_inv, h, it + 1));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A first-order lag x' = -a x + b u + e w: the sampled terms in closed form.
    #[test]
    fn first_order_lag_matches_the_closed_form() {
        let (a, b, e, h) = (3.0, 2.0, -0.5, 0.1);
        let s = SampledLti::new(
            &DMatrix::from_element(1, 1, -a),
            &DVector::from_element(1, b),
            &DVector::from_element(1, e),
            h,
        );
        let ea = (-a * h).exp();
        assert!((s.phi[(0, 0)] - ea).abs() < 1e-14);
        assert!((s.gamma[0] - b * (1.0 - ea) / a).abs() < 1e-14);
        assert!((s.g0[0] - e * (1.0 - ea) / a).abs() < 1e-14);
        // int_0^h exp(-a (h - s)) s ds = h/a - (1 - exp(-a h))/a^2
        assert!((s.g1[0] - e * (h / a - (1.0 - ea) / (a * a))).abs() < 1e-14);
    }

    /// A scalar random walk observed in noise: the Riccati fixed point in closed form,
    /// P = q/2 + sqrt(q^2/4 + q r), L = P/(P + r).
    #[test]
    fn kalman_gain_of_a_random_walk() {
        let (q, r) = (0.3, 2.0);
        let one = DMatrix::from_element(1, 1, 1.0);
        let (l, p, _) =
            kalman_gain(&one, &one, &DMatrix::from_element(1, 1, q), &DMatrix::from_element(1, 1, r), 100).unwrap();
        let p_exact = q / 2.0 + (q * q / 4.0 + q * r).sqrt();
        assert!((p[(0, 0)] - p_exact).abs() < 1e-10, "{} vs {p_exact}", p[(0, 0)]);
        assert!((l[(0, 0)] - p_exact / (p_exact + r)).abs() < 1e-12);
    }
}
