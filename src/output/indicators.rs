//! The run's figures as EUROBENCH performance-indicator files: one small YAML per indicator in
//! `indicators/` (`type: 'scalar'` and `value: ...`), the format the exoskeleton-benchmarking
//! tools of the EUROBENCH project read (one file per performance indicator, named after it).
//! Written for every walking run; a figure the run does not have is left out.

use crate::error::Result;
use crate::metrics::Summary;
use std::path::Path;

/// The indicators of a summary: (file name without `.yaml`, value), finite values only.
pub fn indicators(s: &Summary) -> Vec<(String, f64)> {
    let mut out: Vec<(String, f64)> = Vec::new();
    let mut put = |name: &str, v: Option<f64>| {
        if let Some(v) = v.filter(|v| v.is_finite()) {
            out.push((name.to_string(), v));
        }
    };
    put("force_rms_error_after_settle_n", Some(s.rms_force_error_after_settle_n));
    put("knee_rms_error_deg", s.knee_rms_error_deg);
    if let Some(c) = &s.contact {
        put("stance_fraction", Some(c.stance_fraction));
        if let Some(d) = &c.dataset {
            put("grf_correlation", Some(d.grf_correlation));
            put("knee_moment_stance_correlation", Some(d.knee_moment_stance_correlation));
        }
        put("not_walking_flags", c.not_walking.as_ref().map(|v| v.len() as f64));
    }
    let Some(w) = &s.wearer else { return out };
    for p in &w.phases {
        put(&format!("device_share_{}", p.phase), p.device_share);
        put(&format!("device_moment_mean_{}_nm", p.phase), Some(p.device_moment_mean_nm));
        put(&format!("remaining_torque_rms_{}_nm", p.phase), Some(p.remaining_rms_nm));
    }
    put("device_share_stance", w.stance_device_share);
    put("remaining_torque_peak_nm", Some(w.remaining_peak_nm));
    put("positive_work_per_stride_j", Some(w.positive_work_per_stride_j));
    put("negative_work_per_stride_j", Some(w.negative_work_per_stride_j));
    put("hydraulic_energy_per_stride_j", Some(w.hydraulic_energy_per_stride_j));
    put("hydraulic_power_mean_w", Some(w.hydraulic_power_mean_w));
    for (name, c) in [("thigh", &w.thigh_cuff), ("shank", &w.shank_cuff)] {
        put(&format!("{name}_cuff_force_peak_n"), Some(c.peak_n));
        put(&format!("{name}_cuff_force_rms_n"), Some(c.rms_n));
        put(&format!("{name}_cuff_over_comfort_fraction"), Some(c.over_comfort_fraction));
    }
    put("knee_range_min_deg", Some(w.knee_range_deg[0]));
    put("knee_range_max_deg", Some(w.knee_range_deg[1]));
    if let Some(p) = &w.phase_estimate {
        put("heel_strike_latency_median_s", p.median_latency_s);
        put("gait_phase_rmse_pct", p.phase_rmse_pct);
    }
    if let Some(m) = &w.metabolics {
        put("metabolic_rate_gross_w_per_kg", Some(m.gross_w_per_kg));
        put("metabolic_rate_net_w_per_kg", Some(m.net_w_per_kg));
        put("metabolic_energy_per_stride_j", m.gross_j_per_stride);
        put("muscle_effort", Some(m.effort));
        put("metabolic_rate_change_pct", m.change_pct);
        put("muscle_effort_change_pct", m.effort_change_pct);
        for (joint, r) in ["hip", "knee", "ankle"].iter().zip(m.peak_reserve_pct) {
            put(&format!("peak_reserve_{joint}_pct"), Some(r));
        }
        for (muscle, w) in &m.per_muscle_w {
            put(&format!("muscle_{muscle}_metabolic_w"), Some(*w));
        }
    }
    out
}

/// Write `dir/indicators/<name>.yaml` for every indicator of a walking run (nothing for other
/// runs); each file written atomically.
pub fn write_indicators(dir: &Path, s: &Summary) -> Result<()> {
    if s.wearer.is_none() {
        return Ok(());
    }
    let folder = dir.join("indicators");
    std::fs::create_dir_all(&folder)
        .map_err(|e| crate::error::Error::Write { path: folder.clone(), message: e.to_string() })?;
    for (name, v) in indicators(s) {
        let text = format!("type: 'scalar'\nvalue: {}\n", ryu::Buffer::new().format(v));
        super::write_atomic(&folder.join(format!("{name}.yaml")), text.as_bytes())?;
    }
    Ok(())
}
