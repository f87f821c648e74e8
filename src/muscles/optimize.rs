//! Static optimisation of one sample (OpenSim's `StaticOptimization` as a small QP): the
//! activations `a` in `[a_min, 1]` and joint reserves `R` (N m) that produce the joint
//! moments `M` with the muscles' forces at the sample's lengths and rates,
//!
//! ```text
//! minimise  sum_i w_i a_i^2 - c_i a_i  +  sum_j (R_j / rho)^2
//! subject to  sum_i A_ji a_i + R_j = b_j   (j = hip, knee, ankle)
//!             A_ji = r_ji F_max,i f_L f_V cos(alpha),  b_j = M_j - sum_i r_ji F_passive,i cos(alpha)
//! ```
//! (`w = 1, c = 0`: the sum of squared activations; `rho`: the reserves' optimal moment, 1 N m
//! as OpenSim's reserve actuators, so a reserve costs as much as a muscle at full activation
//! per N m). With the reserves eliminated it is a convex QP over a box whose Hessian is a
//! diagonal plus a rank-3 term: for a set of free activations the optimum is
//! `a_F = W^-1 (c/2 + A_F^T mu)` with `(rho^2 I + A_F W^-1 A_F^T) mu = b - A_B a_B - A_F W^-1 c / 2`
//! (a 3 x 3 solve), `R = rho^2 mu`. A primal active-set method (Nocedal and Wright 2006,
//! Algorithm 16.3) moves bounds in and out of the set from the last sample's, so a sample
//! costs a few 3 x 3 solves. The metabolic-rate objective is solved by sequential convex
//! quadratics of the muscles' rates (`metabolics`) from the squared-activation optimum: a
//! local minimum.

/// Per muscle: its column of `A` (N m per unit activation about hip, knee, ankle).
pub type Column = [f64; 3];

/// A sample's problem.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// The muscles' columns of `A`.
    pub columns: &'a [Column],
    /// The moments the activations must make (N m), passive forces taken out.
    pub b: [f64; 3],
    /// The quadratic weights `w_i` (> 0).
    pub w: &'a [f64],
    /// The linear terms `c_i` (empty: zero).
    pub c: &'a [f64],
    /// The least activation.
    pub lo: f64,
    /// The reserves' optimal moment (N m, > 0).
    pub rho: f64,
}

/// Where a variable is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Bound {
    Free,
    Lo,
    Hi,
}

/// The solver's state, kept between samples (its active set warm-starts the next).
#[derive(Debug, Clone, Default)]
pub struct Solver {
    state: Vec<Bound>,
    cand: Vec<f64>,
}

/// What a solve found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Outcome {
    /// The reserves (N m about hip, knee, ankle).
    pub reserve_nm: [f64; 3],
    /// Iterations of the active-set loop.
    pub iterations: usize,
    /// The loop reached its limit (the activations are the last feasible point).
    pub unconverged: bool,
}

/// `m x = y` for a symmetric positive definite 3 x 3 `m` (Cholesky).
fn solve3(m: [[f64; 3]; 3], y: [f64; 3]) -> [f64; 3] {
    let l00 = m[0][0].sqrt();
    let l10 = m[1][0] / l00;
    let l20 = m[2][0] / l00;
    let l11 = (m[1][1] - l10 * l10).sqrt();
    let l21 = (m[2][1] - l20 * l10) / l11;
    let l22 = (m[2][2] - l20 * l20 - l21 * l21).sqrt();
    let z0 = y[0] / l00;
    let z1 = (y[1] - l10 * z0) / l11;
    let z2 = (y[2] - l20 * z0 - l21 * z1) / l22;
    let x2 = z2 / l22;
    let x1 = (z1 - l21 * x2) / l11;
    let x0 = (z0 - l10 * x1 - l20 * x2) / l00;
    [x0, x1, x2]
}

impl Problem<'_> {
    fn c(&self, i: usize) -> f64 {
        self.c.get(i).copied().unwrap_or(0.0)
    }

    /// The multipliers `mu` of the free set's optimum with the bound variables at `x`.
    fn multipliers(&self, state: &[Bound], x: &[f64]) -> [f64; 3] {
        let r2 = self.rho * self.rho;
        let mut g = [[0.0; 3]; 3];
        (g[0][0], g[1][1], g[2][2]) = (r2, r2, r2);
        let mut rhs = self.b;
        for (i, col) in self.columns.iter().enumerate() {
            match state[i] {
                Bound::Free => {
                    let inv = 1.0 / self.w[i];
                    for r in 0..3 {
                        rhs[r] -= col[r] * inv * 0.5 * self.c(i);
                        for k in 0..=r {
                            g[r][k] += col[r] * col[k] * inv;
                        }
                    }
                }
                _ => (0..3).for_each(|r| rhs[r] -= col[r] * x[i]),
            }
        }
        (g[0][1], g[0][2], g[1][2]) = (g[1][0], g[2][0], g[2][1]);
        solve3(g, rhs)
    }

    /// The objective's half gradient in `a_i` at `x` with the multipliers `mu`.
    fn half_gradient(&self, i: usize, x: f64, mu: &[f64; 3]) -> f64 {
        let col = &self.columns[i];
        self.w[i] * x - 0.5 * self.c(i) - (col[0] * mu[0] + col[1] * mu[1] + col[2] * mu[2])
    }

    /// The reserves at activations `x`.
    pub fn reserves(&self, x: &[f64]) -> [f64; 3] {
        let mut r = self.b;
        for (col, a) in self.columns.iter().zip(x) {
            (0..3).for_each(|j| r[j] -= col[j] * a);
        }
        r
    }

    /// The objective at `x`.
    pub fn objective(&self, x: &[f64]) -> f64 {
        let r = self.reserves(x);
        let act: f64 = x.iter().enumerate().map(|(i, a)| self.w[i] * a * a - self.c(i) * a).sum();
        act + r.iter().map(|v| (v / self.rho).powi(2)).sum::<f64>()
    }
}

impl Solver {
    /// Solve `p` in place: `x` holds a start on entry (clipped into the box) and the optimum on
    /// return.
    #[allow(clippy::needless_range_loop)] // per variable, its state, its candidate and its column
    pub fn solve(&mut self, p: &Problem, x: &mut [f64]) -> Outcome {
        let n = x.len();
        if self.state.len() != n {
            self.state = vec![Bound::Free; n];
        }
        self.cand.resize(n, 0.0);
        for (i, v) in x.iter_mut().enumerate() {
            *v = v.clamp(p.lo, 1.0);
            self.state[i] = match self.state[i] {
                Bound::Lo => {
                    *v = p.lo;
                    Bound::Lo
                }
                Bound::Hi => {
                    *v = 1.0;
                    Bound::Hi
                }
                Bound::Free => Bound::Free,
            };
        }
        let limit = 10 * n + 10;
        for it in 1..=limit {
            let mu = p.multipliers(&self.state, x);
            // The free set's optimum, and the first bound on the way to it.
            let mut step = 1.0;
            let mut blocking = None;
            for i in 0..n {
                if self.state[i] != Bound::Free {
                    continue;
                }
                let col = &p.columns[i];
                let target = (0.5 * p.c(i) + col[0] * mu[0] + col[1] * mu[1] + col[2] * mu[2]) / p.w[i];
                self.cand[i] = target;
                let d = target - x[i];
                let room = if d < 0.0 { p.lo - x[i] } else { 1.0 - x[i] };
                if (d < 0.0 && target < p.lo) || (d > 0.0 && target > 1.0) {
                    let s = (room / d).clamp(0.0, 1.0);
                    if s < step {
                        (step, blocking) = (s, Some((i, if d < 0.0 { Bound::Lo } else { Bound::Hi })));
                    }
                }
            }
            for i in (0..n).filter(|&i| self.state[i] == Bound::Free) {
                x[i] += step * (self.cand[i] - x[i]);
            }
            if let Some((i, b)) = blocking {
                x[i] = if b == Bound::Lo { p.lo } else { 1.0 };
                self.state[i] = b;
                continue;
            }
            // At the free set's optimum: release the bound whose multiplier has the wrong sign.
            let mut worst = (0.0, None);
            for i in 0..n {
                let g = p.half_gradient(i, x[i], &mu);
                let wrong = match self.state[i] {
                    Bound::Lo => -g,
                    Bound::Hi => g,
                    Bound::Free => 0.0,
                };
                if wrong > worst.0 * (1.0 + 1e-12) + 1e-14 {
                    worst = (wrong, Some(i));
                }
            }
            match worst.1 {
                Some(i) => self.state[i] = Bound::Free,
                None => return Outcome { reserve_nm: p.reserves(x), iterations: it, unconverged: false },
            }
        }
        Outcome { reserve_nm: p.reserves(x), iterations: limit, unconverged: true }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Against a brute-force check of the KKT conditions and of the objective: no feasible
    /// perturbation of the solution lowers it, on 300 random problems (9 and 40 muscles,
    /// moments within and beyond the muscles' reach, warm starts carried over).
    #[test]
    fn solves_random_problems_to_optimality() {
        let mut seed = 7u64;
        let mut solver = Solver::default();
        for case in 0..300 {
            let n = if case % 3 == 0 { 40 } else { 9 };
            let cols: Vec<Column> = (0..n)
                .map(|_| [0.0; 3].map(|_| (lcg(&mut seed) - 0.5) * 200.0 * (lcg(&mut seed) > 0.3) as u8 as f64))
                .collect();
            let reach = if case % 5 == 0 { 400.0 } else { 60.0 };
            let b = [0.0; 3].map(|_| (lcg(&mut seed) - 0.5) * reach);
            let w = vec![1.0; n];
            let c: Vec<f64> = if case % 4 == 0 { (0..n).map(|_| lcg(&mut seed) * 0.2).collect() } else { Vec::new() };
            let p = Problem { columns: &cols, b, w: &w, c: &c, lo: 0.01, rho: 1.0 };
            let mut x = vec![0.3; n];
            let out = solver.solve(&p, &mut x);
            assert!(!out.unconverged, "case {case}");
            assert!(x.iter().all(|v| (0.01..=1.0).contains(v)));
            let f0 = p.objective(&x);
            for k in 0..200 {
                let i = k % n;
                let d = (lcg(&mut seed) - 0.5) * 1e-3;
                let mut y = x.clone();
                y[i] = (y[i] + d).clamp(0.01, 1.0);
                if k % 7 == 0 {
                    let j = (i + 1 + k) % n;
                    y[j] = (y[j] - d).clamp(0.01, 1.0);
                }
                assert!(p.objective(&y) >= f0 - 1e-9 * f0.abs().max(1.0), "case {case}: a better point");
            }
        }
    }

    /// Muscles that can make the moment leave no reserve; one that cannot leaves the rest.
    #[test]
    fn reserves_take_what_the_muscles_cannot() {
        let cols: Vec<Column> = vec![[50.0, 0.0, 0.0], [0.0, -80.0, 0.0], [0.0, 40.0, 30.0]];
        let w = vec![1.0; 3];
        let p = Problem { columns: &cols, b: [20.0, -30.0, 10.0], w: &w, c: &[], lo: 0.01, rho: 1.0 };
        let mut x = vec![0.0; 3];
        let out = Solver::default().solve(&p, &mut x);
        assert!(out.reserve_nm.iter().all(|r| r.abs() < 0.05), "{out:?} {x:?}");
        let p = Problem { b: [200.0, 0.0, 0.0], ..p };
        let out = Solver::default().solve(&p, &mut x);
        assert!((x[0] - 1.0).abs() < 1e-12 && (out.reserve_nm[0] - 150.0).abs() < 0.1, "{out:?}");
    }
}
