//! Adaptive RBF network (paper Eq. 24-26, 36), 4-7-1.

use serde::{Deserialize, Serialize};

/// Number of hidden nodes.
pub const RBF_NODES: usize = 7;

/// RBF network parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RbfParams {
    /// Node centres c_i; each node's centre has this value in all 4 inputs
    /// `[x1 (N), x2 (N/s), e1 (N), e1_dot (N/s)]`. Default 1e3*[-2.5,-1.7,-0.9,0,0.9,1.7,2.5].
    pub centres: [f64; RBF_NODES],
    /// Gaussian width b (same units as the inputs). Default 1e3. > 0.
    pub width: f64,
    /// Adaptation parameter eta; the weight rate is Xi*h/eta. Default 0.005. > 0.
    pub eta: f64,
}

impl Default for RbfParams {
    fn default() -> Self {
        Self { centres: [-2500.0, -1700.0, -900.0, 0.0, 900.0, 1700.0, 2500.0], width: 1e3, eta: 0.005 }
    }
}

/// The network: g_hat = W^T h(e_bar), h_i = exp(-||e_bar - c_i||^2 / (2 b^2)).
#[derive(Debug, Clone)]
pub struct RbfNetwork {
    p: RbfParams,
}

impl RbfNetwork {
    /// A network with the given parameters.
    pub fn new(p: RbfParams) -> Self {
        Self { p }
    }

    /// Hidden-layer activations for input `e_bar`.
    pub fn activations(&self, e_bar: &[f64; 4]) -> [f64; RBF_NODES] {
        let inv = 1.0 / (2.0 * self.p.width * self.p.width);
        let mut h = [0.0; RBF_NODES];
        for (hi, c) in h.iter_mut().zip(self.p.centres) {
            let d2: f64 = e_bar.iter().map(|x| (x - c) * (x - c)).sum();
            *hi = (-d2 * inv).exp();
        }
        h
    }

    /// Output g_hat = W^T h (N/s^2).
    pub fn output(&self, h: &[f64; RBF_NODES], w: &[f64]) -> f64 {
        h.iter().zip(w).map(|(a, b)| a * b).sum()
    }

    /// Adaptive law dW/dt = +Xi*h/eta (MODEL.md: the sign that makes the paper's V3 decrease).
    pub fn weight_rates(&self, h: &[f64; RBF_NODES], xi: f64, dw: &mut [f64]) {
        for (d, hi) in dw.iter_mut().zip(h) {
            *d = xi * hi / self.p.eta;
        }
    }
}
