//! Muscle activation dynamics (De Groote et al. 2016, [`curves::activation_rate`]) and their
//! inverse: the excitation that brings an activation to a target in one step (computed muscle
//! control's rule), for the muscle wearer (`crate::human::muscle_wearer`).

use super::curves;

/// De Groote's activation dynamics `da/dt = g(u, a) (u - a)` ([`curves::activation_rate`]):
/// the gain's slopes at activation `a`, `1 / (tau_a z)` and `z / tau_d` with `z = 1/2 + 3a/2`
/// (1/s).
fn gain_slopes(a: f64) -> (f64, f64) {
    let z = 0.5 + 1.5 * a;
    (1.0 / (curves::ACTIVATION_TIME_CONSTANT_S * z), z / curves::DEACTIVATION_TIME_CONSTANT_S)
}

/// De Groote's switch between activation and deactivation, `tanh(b (u - a))` at `u - a`, as
/// `1 - 2 / (exp(2 b (u - a)) + 1)`: one exponential instead of the library's tanh (about twice
/// its cost here); within 3.3e-16 of it (|u - a| <= 1, so the exponential stays finite), and the
/// gain uses it only through `1/2 +- tanh/2` and `1 - tanh^2`.
fn switch(u_minus_a: f64) -> f64 {
    1.0 - 2.0 / ((2.0 * curves::ACTIVATION_SMOOTHING * u_minus_a).exp() + 1.0)
}

/// The gain `g = (f + 1/2) slope_a + (1/2 - f) slope_d` (1/s) and its derivative in `u`
/// (1/s) from `th = tanh(b (u - a))`, `f = th / 2`.
fn gain(th: f64, (slope_a, slope_d): (f64, f64)) -> (f64, f64) {
    let f = 0.5 * th;
    let g = (f + 0.5) * slope_a + (0.5 - f) * slope_d;
    (g, 0.5 * curves::ACTIVATION_SMOOTHING * (1.0 - th * th) * (slope_a - slope_d))
}

/// The activation after `dt_s` from `a` under excitation `u`, the rate's gain frozen over the
/// step (exact for that gain; De Groote et al. 2016's dynamics).
pub fn activation_after(a: f64, u: f64, dt_s: f64) -> f64 {
    u + (a - u) * kept(a, u, dt_s)
}

/// The part of its distance to `u` activation `a` keeps over `dt_s`: `exp(-g(u, a) dt)`.
fn kept(a: f64, u: f64, dt_s: f64) -> f64 {
    let (g, _) = gain(switch(u - a), gain_slopes(a));
    (-g * dt_s).exp()
}

/// Muscles whose excitations are computed side by side: each phase of a Newton step (the
/// gains' switch, then their exponentials) runs for all of them before the next, so the
/// processor overlaps their independent work instead of waiting on one muscle's chain of
/// library calls.
const LANES: usize = 8;

/// The excitation (0..1) that brings activation `a` to `target` in `dt_s` as fast as the
/// activation dynamics allow (the inverse of [`activation_after`], computed muscle control's
/// rule): the target itself when it is reached in the step, else full excitation (rising) or
/// none (falling), so activations rise and fall at their physiological rates. `guess`: a
/// starting point (the muscle's excitation a step before: Newton's method from there takes
/// one or two steps; any value in 0..=1 gives the same answer to 1e-13).
pub fn excitation_for(a: f64, target: f64, dt_s: f64, guess: f64) -> f64 {
    let (mut u, mut after) = ([guess], [0.0]);
    excitations_for(&[a], &[target], dt_s, &mut u, &mut after);
    u[0]
}

/// [`excitation_for`] for every muscle: `u[i]` (its value the guess) the excitation that
/// brings `a[i]` to `target[i]` in `dt_s`, and `after[i]` the activation it brings it to
/// ([`activation_after`] of the excitation, from the solver's last evaluation).
pub fn excitations_for(a: &[f64], target: &[f64], dt_s: f64, u: &mut [f64], after: &mut [f64]) {
    let chunks = a.chunks(LANES).zip(target.chunks(LANES)).zip(u.chunks_mut(LANES).zip(after.chunks_mut(LANES)));
    for ((a, target), (u, after)) in chunks {
        let mut lanes = [Newton::default(); LANES];
        let lanes = &mut lanes[..a.len()];
        for (((l, &a), &target), &u) in lanes.iter_mut().zip(a).zip(target).zip(u.iter()) {
            *l = Newton::new(a, target, u.clamp(0.0, 1.0));
        }
        newton_side_by_side(lanes, dt_s, 6);
        for ((l, u), after) in lanes.iter().zip(u).zip(after) {
            (*u, *after) = l.settled().unwrap_or_else(|| {
                let u = saturated_excitation(l.a, l.target, dt_s);
                (u, activation_after(l.a, u, dt_s))
            });
        }
    }
}

/// The excitation of a muscle Newton's method did not settle from its guess: the gain of a
/// saturated command in that direction, then the command that reaches the target with it
/// (exact when it saturates: the gain is the saturated one), refined by Newton's method.
fn saturated_excitation(a: f64, target: f64, dt_s: f64) -> f64 {
    let e = kept(a, if target >= a { 1.0 } else { 0.0 }, dt_s);
    let u = ((target - a * e) / (1.0 - e)).clamp(0.0, 1.0);
    if u == 0.0 || u == 1.0 {
        return u;
    }
    let mut lane = [Newton::new(a, target, u)];
    newton_side_by_side(&mut lane, dt_s, 30);
    lane[0].settled().map_or(u, |(u, _)| u)
}

/// A Newton step at most this long (in excitation) settles an excitation inside 0..1: the
/// next would be about `h''/(2h') step^2`, under 1e-13 for the curvatures of these dynamics.
const QUADRATIC_STEP: f64 = 1e-8;

/// Where one muscle's Newton iteration is.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
enum Progress {
    #[default]
    Running,
    Settled,
    Failed,
}

/// Newton's method on h(u) = u + (a - u) exp(-g(u) dt) - target for one muscle, `u` within
/// 0..=1: settled at the `u` it last evaluated once the step from it is under 1e-13 (a bound
/// when the target is out of reach in the step), or inside the bounds at the next once the step
/// is under [`QUADRATIC_STEP`] (the target reached); failed where h' <= 0.
#[derive(Debug, Clone, Copy, Default)]
struct Newton {
    a: f64,
    target: f64,
    u: f64,
    /// The activation `u` reaches ([`activation_after`]), once evaluated.
    reached: f64,
    /// [`gain_slopes`] at `a`.
    slopes: (f64, f64),
    progress: Progress,
}

impl Newton {
    fn new(a: f64, target: f64, u: f64) -> Self {
        if a == target {
            // The root itself: an activation kept where it is (a muscle resting at its least
            // activation most often) needs the excitation equal to it.
            return Self { a, target, u: a, reached: a, slopes: (0.0, 0.0), progress: Progress::Settled };
        }
        Self { a, target, u, reached: f64::NAN, slopes: gain_slopes(a), progress: Progress::Running }
    }

    /// The excitation and the activation it reaches, once settled.
    fn settled(&self) -> Option<(f64, f64)> {
        (self.progress == Progress::Settled).then_some((self.u, self.reached))
    }

    /// One step from `u` with `th = tanh(b (u - a))`.
    fn advance(&mut self, th: f64, dt_s: f64) {
        let (a, u) = (self.a, self.u);
        let (g, dg) = gain(th, self.slopes);
        let e = (-g * dt_s).exp();
        self.reached = u + (a - u) * e;
        let h = self.reached - self.target;
        let dh = 1.0 - e - (a - u) * e * dt_s * dg;
        if dh <= 0.0 {
            self.progress = Progress::Failed;
            return;
        }
        let next = (u - h / dh).clamp(0.0, 1.0);
        let step = (next - u).abs();
        if step <= 1e-13 {
            self.progress = Progress::Settled;
            return;
        }
        self.u = next;
        if step <= QUADRATIC_STEP && next > 0.0 && next < 1.0 {
            // Inside the bounds after a step this small, Newton's next step (about
            // h''/(2h') step^2) is below rounding: `next` reaches the target.
            self.reached = self.target;
            self.progress = Progress::Settled;
        }
    }
}

/// At most `steps` Newton steps of each of `lanes` (at most [`LANES`]), side by side.
fn newton_side_by_side(lanes: &mut [Newton], dt_s: f64, steps: usize) {
    let mut th = [0.0; LANES];
    for _ in 0..steps {
        let mut running = false;
        for (l, th) in lanes.iter().zip(&mut th) {
            if l.progress == Progress::Running {
                *th = switch(l.u - l.a);
                running = true;
            }
        }
        if !running {
            return;
        }
        for (l, &th) in lanes.iter_mut().zip(&th) {
            if l.progress == Progress::Running {
                l.advance(th, dt_s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The time for activation to go half way from `a0` toward `u` (s) stepping `step` with
    /// `dt_s`.
    fn half_time(a0: f64, u: f64, dt_s: f64, step: impl Fn(f64, f64, f64) -> f64) -> f64 {
        let (mut a, mut t) = (a0, 0.0);
        while (a - a0).abs() < 0.5 * (u - a0).abs() {
            let next = step(a, u, dt_s);
            // Linear within the step for the crossing.
            let target = a0 + 0.5 * (u - a0);
            if (next - a0).abs() >= 0.5 * (u - a0).abs() {
                return t + dt_s * (target - a) / (next - a);
            }
            (a, t) = (next, t + dt_s);
        }
        t
    }

    /// The wearer's activation update at 1 ms follows De Groote's dynamics integrated finely
    /// (10 us Euler): a full excitation step is half way in 9.6 ms, a release in 26.8 ms;
    /// the frozen-rate update at 1 ms within 1.2 ms of it (measured: 0.48 ms early on the rise).
    #[test]
    fn activation_update_follows_the_dynamics() {
        let (ta, td, b) =
            (curves::ACTIVATION_TIME_CONSTANT_S, curves::DEACTIVATION_TIME_CONSTANT_S, curves::ACTIVATION_SMOOTHING);
        let fine = |a: f64, u: f64, dt: f64| a + curves::activation_rate(u, a, ta, td, b) * dt;
        for (a0, u) in [(0.01, 1.0), (1.0, 0.01)] {
            let exact = half_time(a0, u, 1e-5, fine);
            let ours = half_time(a0, u, 1e-3, activation_after);
            assert!((ours - exact).abs() < 1.2e-3, "{a0} -> {u}: {ours} s against {exact} s");
        }
        assert!((half_time(0.01, 1.0, 1e-5, fine) - 0.0095).abs() < 1e-3);
        assert!((half_time(1.0, 0.01, 1e-5, fine) - 0.0268).abs() < 2e-3);
    }

    /// The switch is De Groote's tanh to rounding over every `u - a` (measured: 3.3e-16 at most
    /// on 20001 points of -1..1).
    #[test]
    fn switch_is_the_tanh() {
        let worst = (0..=20000)
            .map(|i| -1.0 + i as f64 / 10000.0)
            .map(|x| (switch(x) - (curves::ACTIVATION_SMOOTHING * x).tanh()).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-15, "{worst}");
    }

    /// The excitation that reaches a target in one step is found, and a target beyond reach
    /// saturates the excitation.
    #[test]
    fn excitation_inverts_the_update() {
        for (a, target) in [(0.2, 0.25), (0.5, 0.495), (0.3, 0.3)] {
            let u = excitation_for(a, target, 1e-3, 0.5);
            assert!((activation_after(a, u, 1e-3) - target).abs() < 1e-12, "{a} -> {target}: u {u}");
        }
        // Every reachable target on a grid, at 1 ms and 0.25 ms: exact to 1e-12.
        for dt in [1e-3, 2.5e-4] {
            for i in 0..=50 {
                let a = 0.01 + 0.98 * i as f64 / 50.0;
                for k in -20..=20 {
                    let target = (a + 0.004 * k as f64 * dt / 1e-3).clamp(0.01, 1.0);
                    let u = excitation_for(a, target, dt, (a + 0.37 * k as f64).rem_euclid(1.0));
                    let other = excitation_for(a, target, dt, a);
                    assert!((u - other).abs() < 1e-11, "the guess changed the answer: {u} {other}");
                    let reached = activation_after(a, u, dt);
                    let reachable = u > 0.0 && u < 1.0;
                    if reachable {
                        assert!((reached - target).abs() < 1e-12, "{a} -> {target} in {dt}: {reached}");
                    } else {
                        // Saturated: the target is beyond what a full step reaches.
                        assert!((target - a).signum() * (target - reached) >= -1e-15, "{a} -> {target}");
                    }
                }
            }
        }
        assert_eq!(excitation_for(0.1, 0.9, 1e-3, 0.1), 1.0);
        assert_eq!(excitation_for(0.9, 0.1, 1e-3, 0.5), 0.0);
    }
}
