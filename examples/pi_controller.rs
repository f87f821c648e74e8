//! Your own controller in the loop, from outside the crate: a PI force controller with a
//! feedforward, run as 1 kHz firmware on the paper's default case (the URDF leg, a 2 Hz sine
//! of 200 N), with the same outputs as `exoleg run` (`out/pi_controller/`).
//!
//! ```sh
//! cargo run --release --example pi_controller [-- SCENARIO [OUT]]
//! ```
//!
//! The law, at each sample (readings `y`, desired force `r` now and one sample ahead):
//! ```text
//! e  = F_d - F                              (N)
//! u  = u_ff + kp e + ki integral(e)         (valve command)
//! u_ff = (dF_d/dt + n3 F_d + n2 v) / (n1 k_s)   (the nominal model's command for F_d,
//!                                            with the piston velocity v)
//! ```
//! with kp and ki placing the force loop near 40 Hz: the valve integrates the command into
//! force at n1 k_s (N/s per unit command), so kp = 2 pi 40 / (n1 k_s), ki = kp 2 pi 5.

use exoleg::control::{ControlOutput, ControlStop, DiscreteController, NominalModel, SampleInput};
use std::path::PathBuf;

/// A PI force controller with the nominal model's feedforward.
struct Pi {
    kp: f64,
    ki: f64,
    integral_n_s: f64,
    nominal: NominalModel,
}

impl Pi {
    fn new(nominal: NominalModel) -> Self {
        let gain = nominal.c.n1 * nominal.c.k_s; // N/s of force rate per unit command
        let kp = std::f64::consts::TAU * 40.0 / gain;
        Self { kp, ki: kp * std::f64::consts::TAU * 5.0, integral_n_s: 0.0, nominal }
    }
}

impl DiscreteController for Pi {
    fn kind(&self) -> &str {
        "pi"
    }

    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        let c = &self.nominal.c;
        let e = s.r.value - s.y.force_n;
        let u_ff = (s.r.rate + c.n3 * s.r.value + c.n2 * s.y.piston_velocity_m_s) / (c.n1 * c.k_s);
        let u = u_ff + self.kp * e + self.ki * self.integral_n_s;
        // Anti-windup: integrate only while the valve is not at its limit.
        let limit = s.valve_limit.0;
        if limit == 0.0 || u.abs() < limit {
            self.integral_n_s += e * s.period_s;
        }
        Ok(ControlOutput::command(u))
    }

    fn log_names(&self) -> Vec<String> {
        vec!["integral_n_s".into()]
    }

    fn log_values(&self, out: &mut [f64]) {
        out[0] = self.integral_n_s;
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenario = args.first().map(PathBuf::from);
    let out = PathBuf::from(args.get(1).map_or("out/pi_controller", String::as_str));
    // The scenario, sampled at 1 kHz (a controller from outside always runs sampled).
    let sc = exoleg::load(scenario.as_deref(), &["controller.sample_period_s=0.001"])?;
    let pi = Pi::new(sc.model.nominal);
    let report = exoleg::study::RunBuilder::new(&sc).controller(Box::new(pi)).write_to(&out)?;
    let m = &report.summary;
    println!("scenario            {}", sc.source_name);
    println!("controller          pi (kp, ki from the nominal model), 1 kHz");
    println!("max |F_L - F_d|     {:.4} N", m.max_abs_force_error_n);
    println!("RMS error           {:.4} N", m.rms_force_error_n);
    println!("outputs             {}", out.display());
    Ok(())
}
