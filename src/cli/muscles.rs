//! `exoleg muscles`: the wearer's muscles at a pose.

use super::*;

/// `exoleg muscles`: the scenario's muscles (scaled to its leg, or the source model's own
/// size) at a pose, as a table or JSON.
pub(super) fn cmd_muscles(
    scenario: Option<PathBuf>,
    pose: &str,
    generic: bool,
    json: bool,
    sets: Vec<String>,
) -> Result<i32> {
    let parts: Vec<&str> = pose.split(',').map(str::trim).collect();
    let angles: Vec<f64> = parts.iter().filter_map(|p| p.parse::<f64>().ok()).filter(|v| v.is_finite()).collect();
    if parts.len() != 3 || angles.len() != 3 || angles.iter().any(|a| a.abs() > 360.0) {
        return Err(Error::input("--pose", "", "give three angles in degrees, HIP,KNEE,ANKLE (each -360..=360)"));
    }
    let loaded = Scenario::load(scenario.as_deref(), &sets)?;
    let res = Resources::new();
    let set = match &loaded.file.wearer.muscles_file {
        None => crate::muscles::MuscleSet::builtin()?,
        Some(f) => res.muscle_set(&loaded.source_name, f, loaded.base_dir.as_deref())?.0,
    };
    let set = if generic {
        (*set).clone()
    } else {
        let sc = loaded.resolve(&res)?;
        let leg = sc.model.leg().ok_or_else(|| {
            Error::input(
                &sc.source_name,
                "plant.kind",
                "the muscles scale to the leg: plant.kind = \"leg\" (or --generic)",
            )
        })?;
        let (thigh, shank) = leg.model.thigh_shank_lengths_m();
        set.scaled(set.scale_for(thigh, shank))
    };
    let q = [angles[0].to_radians(), angles[1].to_radians(), angles[2].to_radians()];
    let muscles = set.at_pose(q);
    if json {
        let v = serde_json::json!({
            "model": set.model, "table": set.source, "citation": set.citation, "credits": set.credits,
            "scale": set.scale, "source": set.info, "pose_deg": {"hip": angles[0], "knee": angles[1], "ankle": angles[2]},
            "muscles": muscles,
        });
        println!("{}", serde_json::to_string_pretty(&v).map_err(|e| Error::Usage(e.to_string()))?);
        return Ok(EXIT_OK);
    }
    print_muscles(&set, &angles, &muscles);
    Ok(EXIT_OK)
}

pub(super) fn print_muscles(set: &crate::muscles::MuscleSet, angles: &[f64], muscles: &[crate::muscles::MusclePose]) {
    let size =
        if set.scale == 1.0 { "its own size".to_string() } else { format!("scaled x{:.4} to the leg", set.scale) };
    println!("model      {} ({}), {size}", set.model, set.source);
    println!(
        "pose       hip {} deg, knee {} deg, ankle {} deg (hip flexion +, knee flexion +, ankle dorsiflexion +; r = -dL/dq)",
        angles[0], angles[1], angles[2]
    );
    println!(
        "{:<11} {:>8} {:>8} {:>8} {:>6} {:>5} {:>8} {:>8} {:>8} {:>8}  source muscles",
        "muscle", "F_max N", "l_opt m", "l_slk m", "pen deg", "slow", "L m", "r_hip mm", "r_knee", "r_ankle"
    );
    for m in muscles {
        let r = m.moment_arm_m.map(|x| 1e3 * x);
        println!(
            "{:<11} {:>8.1} {:>8.4} {:>8.4} {:>6.1} {:>5.2} {:>8.4} {:>8.2} {:>8.2} {:>8.2}  {}{}",
            m.name,
            m.max_isometric_force_n,
            m.optimal_fiber_length_m,
            m.tendon_slack_length_m,
            m.pennation_at_optimal_rad.to_degrees(),
            m.slow_twitch_fraction,
            m.length_m,
            r[0],
            r[1],
            r[2],
            m.source_names.join(" "),
            if m.inside_table { "" } else { " (outside its table: extrapolated)" }
        );
    }
}
