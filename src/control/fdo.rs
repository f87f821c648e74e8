//! Fixed-time disturbance observer (paper Eq. 27-29).

use serde::{Deserialize, Serialize};

/// Which disturbance estimator `dtznn` uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorKind {
    /// Kalman extended-state observer (the default).
    #[default]
    Eso,
    /// A discrete fixed-time disturbance observer for D (comparison).
    Fdo,
}

/// Observer parameters (`[controller.observer]`, or just `controller.observer = "eso"|"fdo"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObserverParams {
    /// `dtznn`'s disturbance estimator: `eso` (Kalman extended-state observer, default) or
    /// `fdo` (a discrete fixed-time observer, for comparison).
    pub kind: EstimatorKind,
    /// FDO gain L (1/s): D_hat = L*psi(Xi) turns Xi (N/s) into N/s^2. Default 1 (the paper's). > 0.
    pub gain: f64,
    /// FDO exponent r in (0, 1). Default 1/3.
    pub exponent: f64,
    /// `dtznn`: process-noise spectral densities of the ESO's states [F (N^2/s), x_v (m^2/s),
    /// q ((N/s)^2/s), D ((N/s^2)^2/s)]. Default [0, 1e-12, 1e2, 1e12] (DISCRETE.md). >= 0.
    pub process_noise: [f64; 4],
}

impl Default for ObserverParams {
    fn default() -> Self {
        Self { kind: EstimatorKind::Eso, gain: 1.0, exponent: 1.0 / 3.0, process_noise: [0.0, 1e-12, 1e2, 1e12] }
    }
}

/// `controller.observer` as a table or as the estimator's name alone (errors inside the
/// table keep their key).
pub(crate) mod observer_serde {
    use super::ObserverParams;
    use serde::de::{self, MapAccess, Visitor};
    use serde::{Deserialize, Deserializer};

    struct V;

    impl<'de> Visitor<'de> for V {
        type Value = ObserverParams;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("\"eso\", \"fdo\" or a table of observer settings")
        }
        fn visit_str<E: de::Error>(self, v: &str) -> Result<ObserverParams, E> {
            let kind = super::EstimatorKind::deserialize(de::value::StrDeserializer::<E>::new(v))?;
            Ok(ObserverParams { kind, ..Default::default() })
        }
        fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<ObserverParams, A::Error> {
            ObserverParams::deserialize(de::value::MapAccessDeserializer::new(map))
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<ObserverParams, D::Error> {
        d.deserialize_any(V)
    }
}

/// The observer's estimate D_hat = L*psi(Xi), with
/// `psi(Xi) = Xi + sig(Xi)^r + sig(Xi)^(1/r) + sigmoid(Xi)`, `sig(x)^a = |x|^a*sgn(x)`,
/// `sigmoid(x) = 2/(1+exp(-x)) - 1` (odd). Its state `z` lives in the controller.
///
/// Stiffness: for r = 1/3 the cubic term dominates, `d psi/d Xi ~ 3*Xi^2`, so a large
/// disturbance makes the observer stiff (see README, "Observer limits").
#[derive(Debug, Clone)]
pub struct Fdo {
    p: ObserverParams,
}

impl Fdo {
    /// An observer with the given parameters.
    pub fn new(p: ObserverParams) -> Self {
        Self { p }
    }

    /// The paper's exponent r = 1/3 (the default), where the powers are a cube root and
    /// products: `a^r = cbrt(a)`, `a^(1/r) = a^3`, `a^(1/r-1) = a^2`, `a^(r-1) = cbrt(a)/a`.
    fn is_one_third(&self) -> bool {
        self.p.exponent == 1.0 / 3.0
    }

    /// `(|Xi|^r, |Xi|^(1/r))`.
    fn powers(&self, a: f64) -> (f64, f64) {
        if self.is_one_third() {
            (a.cbrt(), a * a * a)
        } else {
            let r = self.p.exponent;
            (a.powf(r), a.powf(1.0 / r))
        }
    }

    /// `|Xi|^(1/r-1)`.
    fn outer_slope_power(&self, a: f64) -> f64 {
        if self.is_one_third() {
            a * a
        } else {
            a.powf(1.0 / self.p.exponent - 1.0)
        }
    }

    /// psi(Xi).
    pub fn psi(&self, xi: f64) -> f64 {
        let (inner, outer) = self.powers(xi.abs());
        xi + inner.copysign(xi) + outer.copysign(xi) + (2.0 / (1.0 + (-xi).exp()) - 1.0)
    }

    /// d(L*psi)/dXi, for implicit updates.
    pub fn estimate_slope(&self, xi: f64) -> f64 {
        let r = self.p.exponent;
        let a = xi.abs().max(1e-300);
        let e = (-xi).exp();
        let sig = if e.is_finite() { 2.0 * e / ((1.0 + e) * (1.0 + e)) } else { 0.0 };
        let inner = if self.is_one_third() { a.cbrt() / a } else { a.powf(r - 1.0) };
        self.p.gain * (1.0 + r * inner + self.outer_slope_power(a) / r + sig)
    }

    /// d(L*psi)/dXi without the `sig(Xi)^r` term (whose slope is unbounded at 0): the rate
    /// that limits an explicit integrator's step.
    pub fn lipschitz_slope(&self, xi: f64) -> f64 {
        let r = self.p.exponent;
        let e = (-xi).exp();
        let sig = if e.is_finite() { 2.0 * e / ((1.0 + e) * (1.0 + e)) } else { 0.0 };
        self.p.gain * (1.0 + self.outer_slope_power(xi.abs()) / r + sig)
    }

    /// D_hat = L*psi(Xi) (N/s^2).
    pub fn estimate(&self, xi: f64) -> f64 {
        self.p.gain * self.psi(xi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The analytic slope the backward-Euler update uses matches a central difference, on both
    /// sides of 0 and where the cubic term dominates.
    #[test]
    fn estimate_slope_matches_a_central_difference() {
        let f = Fdo::new(ObserverParams { gain: 2.5, ..Default::default() });
        for xi in [-40.0, -3.0, -0.2, 0.05, 0.7, 12.0, 150.0] {
            let h = 1e-6 * (1.0 + f64::abs(xi));
            let fd = (f.estimate(xi + h) - f.estimate(xi - h)) / (2.0 * h);
            let exact = f.estimate_slope(xi);
            assert!((fd - exact).abs() < 1e-6 * exact.abs(), "xi {xi}: {exact} vs {fd}");
        }
        // At 150 the cubic term gives 3 L xi^2 = 168,750.
        assert!((f.estimate_slope(150.0) / 168_750.0 - 1.0).abs() < 1e-3);
    }

    /// The cube-root path of r = 1/3 gives the general powers' values (to rounding), and
    /// another exponent takes the general path.
    #[test]
    fn one_third_matches_the_general_powers() {
        let f = Fdo::new(ObserverParams::default());
        let r = 1.0 / 3.0;
        for xi in [-40.0, -3.0, -0.2, 1e-9, 0.05, 0.7, 12.0, 150.0] {
            let a: f64 = f64::abs(xi);
            let general =
                xi + a.powf(r).copysign(xi) + a.powf(1.0 / r).copysign(xi) + (2.0 / (1.0 + (-xi).exp()) - 1.0);
            assert!((f.psi(xi) - general).abs() <= 1e-14 * general.abs().max(1.0), "xi {xi}");
            let slope = 1.0 + r * a.powf(r - 1.0) + a.powf(1.0 / r - 1.0) / r;
            let sig = 2.0 * (-xi).exp() / ((1.0 + (-xi).exp()) * (1.0 + (-xi).exp()));
            assert!((f.estimate_slope(xi) - slope - sig).abs() <= 1e-13 * slope, "xi {xi}");
        }
        // r = 1/2: psi(4) = 4 + 2 + 16 + sigmoid(4).
        let half = Fdo::new(ObserverParams { exponent: 0.5, ..Default::default() });
        let sigmoid = 2.0 / (1.0 + (-4.0f64).exp()) - 1.0;
        assert!((half.psi(4.0) - (22.0 + sigmoid)).abs() < 1e-12);
    }
}
