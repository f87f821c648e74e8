//! Fixed-step explicit Runge-Kutta integrators (the ground floor: nothing else in the crate is
//! needed here). The co-simulation loop integrates its state in place over a slice with
//! scratch it allocates once; small fixed-size states (the reduced leg's knee) use arrays.

use serde::{Deserialize, Serialize};

/// Which fixed-step scheme integrates the continuous states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// Forward Euler, first order (what simple firmware does).
    Euler,
    /// Bogacki-Shampine third order, MATLAB/Simulink `ode3` (the paper's solver).
    Ode3,
    /// Classic fourth-order Runge-Kutta.
    Rk4,
}

impl Integrator {
    /// The name used in scenario files.
    pub fn name(&self) -> &'static str {
        match self {
            Integrator::Euler => "euler",
            Integrator::Ode3 => "ode3",
            Integrator::Rk4 => "rk4",
        }
    }

    /// Stability limits of the scheme for a linear mode `x' = lambda x` with `lambda h` on the
    /// negative real axis and on the imaginary axis: (real, imaginary). Forward Euler is
    /// unstable for every undamped oscillation (0).
    pub fn stability_limits(&self) -> (f64, f64) {
        match self {
            Integrator::Euler => (2.0, 0.0),
            Integrator::Ode3 => (2.51, 1.73),
            Integrator::Rk4 => (2.78, 2.82),
        }
    }

    /// One step of size `dt_s` from `(t_s, x)` over a fixed-size state; `f(t, x)` returns
    /// dx/dt.
    pub fn step<const N: usize>(
        &self,
        t_s: f64,
        dt_s: f64,
        x: &[f64; N],
        mut f: impl FnMut(f64, &[f64; N]) -> [f64; N],
    ) -> [f64; N] {
        let k1 = f(t_s, x);
        self.step_from(t_s, dt_s, x, &k1, f)
    }

    /// [`Self::step`] with the first stage's slope `k1 = f(t_s, x)` already known (every scheme
    /// here starts with it): the same result with one evaluation fewer.
    pub fn step_from<const N: usize>(
        &self,
        t_s: f64,
        dt_s: f64,
        x: &[f64; N],
        k1: &[f64; N],
        mut f: impl FnMut(f64, &[f64; N]) -> [f64; N],
    ) -> [f64; N] {
        let mut out = *x;
        let mut work = [[0.0; N]; SCRATCH_VECTORS];
        self.step_in_place(t_s, dt_s, &mut out, k1, work.as_flattened_mut(), |t, xs, dx| {
            let mut xa = [0.0; N];
            xa.copy_from_slice(xs);
            dx.copy_from_slice(&f(t, &xa));
        });
        out
    }

    /// One step of size `dt_s` from `t_s` over a state of any length, in place: `x` holds the
    /// state at `t_s` on entry and at `t_s + dt_s` on return; `k1` is the slope at `(t_s, x)`;
    /// `f(t, x, dx)` writes dx/dt into `dx`. `work` is scratch of at least
    /// [`SCRATCH_VECTORS`]` * x.len()` entries (allocated once by the caller, so a step
    /// allocates nothing).
    pub fn step_in_place(
        &self,
        t_s: f64,
        dt_s: f64,
        x: &mut [f64],
        k1: &[f64],
        work: &mut [f64],
        mut f: impl FnMut(f64, &[f64], &mut [f64]),
    ) {
        let n = x.len();
        let h = dt_s;
        let k1 = &k1[..n];
        let (k2, rest) = work.split_at_mut(n);
        let (k3, rest) = rest.split_at_mut(n);
        let (k4, rest) = rest.split_at_mut(n);
        let stage = &mut rest[..n];
        let axpy = |out: &mut [f64], x: &[f64], a: f64, k: &[f64]| {
            for ((o, x), k) in out.iter_mut().zip(x).zip(k) {
                *o = x + a * k;
            }
        };
        match self {
            Integrator::Euler => {
                for (x, k1) in x.iter_mut().zip(k1) {
                    *x += h * k1;
                }
            }
            Integrator::Ode3 => {
                // Bogacki-Shampine: c = [0, 1/2, 3/4], b = [2/9, 1/3, 4/9].
                axpy(stage, x, 0.5 * h, k1);
                f(t_s + 0.5 * h, stage, k2);
                axpy(stage, x, 0.75 * h, k2);
                f(t_s + 0.75 * h, stage, k3);
                for (((x, k1), k2), k3) in x.iter_mut().zip(k1).zip(&*k2).zip(&*k3) {
                    *x += h * (2.0 / 9.0 * k1 + 1.0 / 3.0 * k2 + 4.0 / 9.0 * k3);
                }
            }
            Integrator::Rk4 => {
                axpy(stage, x, 0.5 * h, k1);
                f(t_s + 0.5 * h, stage, k2);
                axpy(stage, x, 0.5 * h, k2);
                f(t_s + 0.5 * h, stage, k3);
                axpy(stage, x, h, k3);
                f(t_s + h, stage, k4);
                for ((((x, k1), k2), k3), k4) in x.iter_mut().zip(k1).zip(&*k2).zip(&*k3).zip(&*k4) {
                    *x += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
                }
            }
        }
    }
}

/// Scratch vectors [`Integrator::step_in_place`] needs, per state entry.
pub const SCRATCH_VECTORS: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    /// One step on x' = lambda x multiplies x by R(lambda h): |R| <= 1 just inside the stated
    /// limits and > 1 just outside.
    #[test]
    fn stability_limits_are_where_the_amplification_crosses_one() {
        for m in [Integrator::Euler, Integrator::Ode3, Integrator::Rk4] {
            let (re, im) = m.stability_limits();
            let amp = |z_re: f64, z_im: f64| {
                // Complex lambda h as a 2-vector: x' = [[a, -b], [b, a]] x.
                let x = m.step(0.0, 1.0, &[1.0, 0.0], |_, x| [z_re * x[0] - z_im * x[1], z_im * x[0] + z_re * x[1]]);
                x[0].hypot(x[1])
            };
            assert!(amp(-0.995 * re, 0.0) <= 1.0 && amp(-1.01 * re, 0.0) > 1.0, "{m:?} real");
            if im > 0.0 {
                assert!(amp(0.0, 0.995 * im) <= 1.0 && amp(0.0, 1.01 * im) > 1.0, "{m:?} imaginary");
            } else {
                assert!(amp(0.0, 0.01) > 1.0, "{m:?}: forward Euler amplifies every oscillation");
            }
        }
    }

    /// Starting from a known first slope gives the bits of the full step.
    #[test]
    fn step_from_a_known_slope_is_the_step() {
        let f = |t: f64, x: &[f64; 2]| [x[1], -4.0 * x[0] + t.sin()];
        for m in [Integrator::Euler, Integrator::Ode3, Integrator::Rk4] {
            let x = [0.3, -1.1];
            assert_eq!(m.step(0.2, 0.01, &x, f), m.step_from(0.2, 0.01, &x, &f(0.2, &x), f), "{m:?}");
        }
    }

    /// Global error on x' = -x over [0, 1] must fall with the scheme's order.
    #[test]
    fn convergence_orders() {
        for (m, order) in [(Integrator::Euler, 1.0), (Integrator::Ode3, 3.0), (Integrator::Rk4, 4.0)] {
            let err = |n: usize| {
                let h = 1.0 / n as f64;
                let mut x = [1.0];
                for k in 0..n {
                    x = m.step(k as f64 * h, h, &x, |_, x| [-x[0]]);
                }
                (x[0] - (-1.0f64).exp()).abs()
            };
            let p = (err(20) / err(40)).log2();
            assert!((p - order).abs() < 0.15, "{m:?}: observed order {p}");
        }
    }
}
