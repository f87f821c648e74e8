//! The typed state of the co-simulation loop and its packing for the integrators
//! (MuJoCo keeps `qpos`/`act` as named slices of one array; so do we, in one place): the
//! plant-side entries first, then the coupled mechanics' (reduced engine), then the continuous controller's, sized when the controller is
//! built.

use crate::hydraulics::HydraulicState;

/// Piston states of the leg's local piston model inside a step (unused for a prescribed piston).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PistonState {
    /// Predicted piston position (m).
    pub position_m: f64,
    /// Predicted piston velocity (m/s).
    pub velocity_m_s: f64,
}

/// The plant-side states the loop integrates over a step (the continuous controller's state is
/// a slice beside it).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    /// Force channel.
    pub hyd: HydraulicState,
    /// Piston predictor.
    pub piston: PistonState,
}

/// Number of plant-side entries in the packed vector; the coupled mechanics' and the controller's follow.
pub const PLANT_LEN: usize = 6;

const FORCE: usize = 0;
const SPOOL: usize = 1;
const ACCEL_DIST: usize = 2;
const PISTON_POSITION: usize = 3;
const PISTON_VELOCITY: usize = 4;
const MEAN_PRESSURE: usize = 5;

/// Names of the plant-side entries, in packed order (used in divergence reports).
const NAMES: [&str; PLANT_LEN] = [
    "load_force_n",
    "spool_m",
    "accel_disturbance_integral_n_per_s",
    "predicted_piston_m",
    "predicted_piston_velocity_m_s",
    "mean_chamber_pressure_pa",
];

impl State {
    /// Write the plant-side entries into the first [`PLANT_LEN`] of `x` (which has at least
    /// as many).
    pub fn pack_into(&self, x: &mut [f64]) {
        let Some(x) = x.first_chunk_mut::<PLANT_LEN>() else { return };
        x[FORCE] = self.hyd.force_n;
        x[SPOOL] = self.hyd.spool_m;
        x[ACCEL_DIST] = self.hyd.accel_dist_n_per_s;
        x[PISTON_POSITION] = self.piston.position_m;
        x[PISTON_VELOCITY] = self.piston.velocity_m_s;
        x[MEAN_PRESSURE] = self.hyd.mean_pressure_pa;
    }

    /// The plant-side state from the first [`PLANT_LEN`] entries of a packed vector (which
    /// has at least as many).
    pub fn unpack(x: &[f64]) -> Self {
        let Some(x) = x.first_chunk::<PLANT_LEN>() else { return State::default() };
        State {
            hyd: HydraulicState {
                force_n: x[FORCE],
                spool_m: x[SPOOL],
                accel_dist_n_per_s: x[ACCEL_DIST],
                mean_pressure_pa: x[MEAN_PRESSURE],
            },
            piston: PistonState { position_m: x[PISTON_POSITION], velocity_m_s: x[PISTON_VELOCITY] },
        }
    }

    /// The first non-finite entry of this state and then of the controller state `controller`
    /// (its entries named by `controller_names`), with its name.
    pub fn first_non_finite(&self, controller: &[f64], controller_names: &[String]) -> Option<(String, f64)> {
        let mut x = [0.0; PLANT_LEN];
        self.pack_into(&mut x);
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Some((NAMES[i].to_string(), x[i]));
        }
        let i = controller.iter().position(|v| !v.is_finite())?;
        let name = controller_names.get(i).cloned().unwrap_or_else(|| format!("controller_state_{i}"));
        Some((name, controller[i]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack_round_trips_and_names_the_bad_entry() {
        let mut s = State::default();
        s.hyd.force_n = 1.0;
        s.hyd.mean_pressure_pa = 2.0;
        s.piston.velocity_m_s = 3.0;
        let mut x = [0.0; PLANT_LEN];
        s.pack_into(&mut x);
        assert_eq!(State::unpack(&x), s);
        let ctrl = [0.0, f64::NAN];
        let (name, _) = s.first_non_finite(&ctrl, &["z".into(), "w1".into()]).unwrap();
        assert_eq!(name, "w1");
        s.piston.position_m = f64::INFINITY;
        assert_eq!(s.first_non_finite(&ctrl, &[]).unwrap().0, "predicted_piston_m");
    }
}
