//! The reports a command prints: a run's summary, the wearer, the muscles, warnings, the verdict.

use super::*;

/// The report of a run; `driver`: the controller that drove it when it is not the scenario's
/// own (a HIL peer).
pub(super) fn print_summary(sc: &ResolvedScenario, m: &Summary, out: &Path, driver: Option<&str>) {
    let f = &sc.file;
    println!("scenario            {}", sc.source_name);
    println!(
        "controller          {}  (plant {:?}, hydraulics {:?})",
        driver.unwrap_or(f.controller.kind.as_str()),
        f.plant.kind,
        f.hydraulics.model
    );
    if let Some(c) = &m.controller_stop {
        println!(
            "controller stop     at t = {:.6} s ({}): {}; the device went to its fail-safe state",
            c.t_s,
            c.cause.as_str(),
            c.message
        );
    }
    if sc.model.desired_force {
        println!("max |F_L - F_d|     {:.4} N", m.max_abs_force_error_n);
        println!(
            "convergence time    {} (band {:.3} N)",
            m.force_convergence_time_s.map_or("never".into(), |t| format!("{t:.4} s")),
            m.force_convergence_band_n
        );
        println!("RMS error           {:.4} N", m.rms_force_error_n);
        if m.settle_s > 0.0 {
            println!(
                "after {:.3} s        force RMS {:.4} N, max {:.4} N",
                m.settle_s, m.rms_force_error_after_settle_n, m.max_abs_force_error_after_settle_n
            );
        }
    } else {
        println!("desired force       none (reference.force = \"none\": the controller decides the assistance)");
    }
    if let (Some(r), Some(x)) = (m.knee_rms_error_deg, m.knee_max_abs_error_deg) {
        println!("knee error          RMS {r:.4} deg, max {x:.4} deg");
    }
    if let Some(w) = &m.wearer {
        print_wearer(w);
    }
    println!("max |u|             {:.4e}", m.max_abs_valve_command);
    println!(
        "saturation          valve {:.2}%, force limit {:.2}%",
        100.0 * m.valve_saturation_fraction,
        100.0 * m.force_limit_fraction
    );
    println!("steps               {} ({:.0} steps/s)", m.steps, m.steps_per_second);
    if m.hydraulic_substeps_max > 1 {
        println!(
            "substeps            the hydraulic states were stiff for sim.dt_s: {} steps substepped, up to {} times",
            m.substepped_steps, m.hydraulic_substeps_max
        );
    }
    println!("outputs             {}", out.display());
}

/// What the wearer got (walking runs).
pub(super) fn print_wearer(w: &crate::metrics::WearerSummary) {
    let share = |s: Option<f64>| s.map_or("-".into(), |s| format!("{:.0} %", 100.0 * s));
    let phases: Vec<String> = w.phases.iter().map(|p| format!("{} {}", p.phase, share(p.device_share))).collect();
    println!("device share        {} (stance {})", phases.join(", "), share(w.stance_device_share));
    println!(
        "device work         +{:.2} J / {:.2} J per stride; hydraulic energy {:.1} J per stride ({:.0} W mean)",
        w.positive_work_per_stride_j,
        w.negative_work_per_stride_j,
        w.hydraulic_energy_per_stride_j,
        w.hydraulic_power_mean_w
    );
    println!(
        "cuffs               thigh peak {:.0} N RMS {:.0} N ({}), shank peak {:.0} N RMS {:.0} N ({}); limits comfort {:.0} N, pain {:.0} / {:.0} N",
        w.thigh_cuff.peak_n,
        w.thigh_cuff.rms_n,
        w.thigh_cuff.verdict,
        w.shank_cuff.peak_n,
        w.shank_cuff.rms_n,
        w.shank_cuff.verdict,
        w.thigh_cuff.limits_n[0],
        w.thigh_cuff.limits_n[1],
        w.shank_cuff.limits_n[1]
    );
    println!(
        "knee range          {:.1}..{:.1} deg (the wearer's data {:.1}..{:.1} deg)",
        w.knee_range_deg[0], w.knee_range_deg[1], w.data_knee_range_deg[0], w.data_knee_range_deg[1]
    );
    if let Some(m) = &w.metabolics {
        print_metabolics(m);
    }
    if let Some(p) = &w.phase_estimate {
        let ms = |x: Option<f64>| x.map_or("-".into(), |x| format!("{:.1} ms", 1e3 * x));
        println!(
            "gait phase (logged) heel strikes detected {} of {}, median latency {}, phase RMSE {}",
            p.detected,
            p.heel_strikes,
            ms(p.median_latency_s),
            p.phase_rmse_pct.map_or("-".into(), |e| format!("{e:.2} %"))
        );
    }
}

/// What the wearer's muscles cost (`wearer.muscles`).
pub(super) fn print_metabolics(m: &crate::metrics::muscles::MetabolicsSummary) {
    let change = match (m.baseline_gross_w_per_kg, m.change_pct) {
        (Some(b), Some(c)) => format!("; without the device's help {b:.2} W/kg: {c:+.1} %"),
        _ => String::new(),
    };
    println!(
        "metabolic rate      gross {:.2} W/kg, net {:.2} W/kg ({}, {} muscles, {}){change}",
        m.gross_w_per_kg, m.net_w_per_kg, m.metabolic_model, m.muscle_model, m.muscle_cost
    );
    let mut top: Vec<(&String, &f64)> = m.per_muscle_w.iter().collect();
    top.sort_by(|a, b| b.1.total_cmp(a.1));
    let top: Vec<String> = top.iter().take(4).map(|(n, w)| format!("{n} {w:.0} W")).collect();
    let effort_change = m.effort_change_pct.map_or(String::new(), |c| format!(" ({c:+.1} %)"));
    println!(
        "muscles             effort {:.3}{effort_change}; {}; peak reserves hip {:.1} %, knee {:.1} %, ankle {:.1} % of the moments",
        m.effort,
        top.join(", "),
        m.peak_reserve_pct[0],
        m.peak_reserve_pct[1],
        m.peak_reserve_pct[2]
    );
    let off: Vec<&str> = m.emg.iter().filter(|e| !e.agrees).map(|e| e.muscle.as_str()).collect();
    println!(
        "activations vs EMG  {} of {} muscles on in Perry's (1992) phases{}",
        m.emg.len() - off.len(),
        m.emg.len(),
        if off.is_empty() { String::new() } else { format!(" (not: {})", off.join(", ")) }
    );
}

/// The warnings of a study's base scenario, once (a file changed since a recorded run, ...);
/// its errors surface when the study's runs are resolved.
pub(super) fn warn_base(base: &Scenario) {
    if let Ok(r) = base.resolve(&Resources::new()) {
        warn(&r.warnings);
    }
}

pub(super) fn warn(warnings: &[String]) {
    for w in warnings {
        eprintln!("warning: {}", output::text::terminal(w));
    }
}

/// A controller's stop under `controller.on_stop = "failsafe"` said on stderr (whatever
/// `--quiet` says: the run went on without its controller).
pub(super) fn warn_controller_stop(m: &Summary) {
    if let Some(c) = m.controller_stop.as_ref().filter(|c| c.cause != crate::control::StopCause::Crash) {
        eprintln!(
            "warning: the controller stopped at t = {:.6} s ({}): {}; the device went to its fail-safe state \
             (controller.on_stop = \"failsafe\"; summary.json: controller_stop)",
            c.t_s,
            c.cause.as_str(),
            c.message
        );
    }
}

/// A run's exit: 0 if it passes, else exit 4 naming the failed criteria and a crashed
/// controller.
pub(super) fn verdict(sc: &ResolvedScenario, report: &study::RunReport) -> Result<i32> {
    if report.passed() {
        return Ok(EXIT_OK);
    }
    let mut failed: Vec<String> = report.criteria.iter().filter(|c| !c.pass).map(|c| c.name.clone()).collect();
    if let Some(crash) = report.summary.controller_crash() {
        failed.push(format!(
            "{crash} (controller.on_stop = \"failsafe\": the device went to its fail-safe state and the run went on)"
        ));
    }
    Err(Error::Criteria(format!("{} failed: {}", sc.source_name, failed.join(", "))))
}
