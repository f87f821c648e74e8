//! Write your own gait-trajectory test in Rust: compare two controllers on comfortable
//! walking and check both the knee and the force, stride by stride.
//!
//! `cargo run --release --example gait_test`

use exoleg::study::gait_test::GaitTest;

fn main() -> Result<(), exoleg::Error> {
    for kind in ["arbfnn_fdo_znn", "erl_smc"] {
        let report = GaitTest::comfortable().set(&format!("controller.kind=\"{kind}\"")).strides(4).run()?;
        println!(
            "{kind:>15}: knee RMS {:.4} deg (max {:.4}), force RMS {:.3} N (max {:.3})",
            report.knee_rms_error_deg(),
            report.knee_max_abs_error_deg(),
            report.force_rms_error_n(),
            report.force_max_abs_error_n()
        );
        for s in &report.summary.strides {
            println!(
                "{:>17} stride {} at {:.2} s: knee max {:.4} deg, force max {:.3} N, peak force {:.0} N, peak power {:.0} W",
                "", s.index, s.t_start_s, s.knee_max_abs_error_deg, s.force_max_abs_error_n, s.peak_cylinder_force_n, s.peak_power_w
            );
        }
        // A pass/fail check a controller developer would keep in CI.
        if report.knee_max_abs_error_deg() > 3.0 {
            eprintln!("{kind}: knee error above 3 deg");
        }
    }
    Ok(())
}
