//! The checks of a leg run: the leg, the wearer and the metrics, the safety limits, walking on
//! the carriage and its combinations.

use super::*;

/// `[leg]`, `[human]`, `[metrics]`, `[criteria]`.
pub(super) fn leg_human_metrics(c: &Check, f: &ScenarioFile) -> Result<()> {
    if !(1..=64).contains(&f.leg.solver_iterations) {
        return Err(c.fail("leg.solver_iterations", format!("must be 1..=64, got {}", f.leg.solver_iterations)));
    }
    if f.human.mode == HumanMode::Cuff && f.plant.kind == PlantKind::Bench {
        return Err(
            c.fail("human.mode", "`cuff` needs a leg to strap to; use `paper` or `off` with plant.kind = \"bench\"")
        );
    }
    if let Some(b) = f.metrics.convergence_band_n {
        c.positive("metrics.convergence_band_n", b)?;
    }
    c.non_negative("metrics.settle_s", f.metrics.settle_s)?;
    if f.metrics.settle_s >= f.sim.duration_s {
        return Err(c.fail(
            "metrics.settle_s",
            format!("must be shorter than sim.duration_s = {} (nothing would be left to measure)", f.sim.duration_s),
        ));
    }
    safety_limits(c, f)?;
    let cr = &f.criteria;
    for (k, v) in cr.limits() {
        if let Some(v) = v {
            c.non_negative(&format!("criteria.{k}"), v)?;
        }
    }
    if (cr.knee_rms_error_deg.is_some() || cr.knee_max_error_deg.is_some()) && f.reference.kind != ReferenceKind::Gait {
        return Err(c.fail("criteria", "knee criteria need a knee reference (reference.kind = \"gait\")"));
    }
    let walking = f.reference.kind == ReferenceKind::Gait && f.ground.enabled && f.plant.kind == PlantKind::Leg;
    if cr.max_not_walking_flags.is_some() && !walking {
        return Err(c.fail(
            "criteria.max_not_walking_flags",
            "needs loaded walking (a gait on the carriage with ground.enabled; hip.mode = \"carriage\")",
        ));
    }
    Ok(())
}

/// Ceilings of the safety and comfort limits: far beyond anything a body or a device reaches,
/// low enough that every figure, difference and plot of them stays finite.
pub(super) const MAX_FORCE_N: f64 = 1e6;
pub(super) const MAX_MOMENT_NM: f64 = 1e6;
pub(super) const MAX_LIMIT_S: f64 = 1e6;

/// `[safety]`, `[cuff_limits]`: each limit positive (or non-negative) and under its ceiling.
pub(super) fn safety_limits(c: &Check, f: &ScenarioFile) -> Result<()> {
    let sf = &f.safety;
    c.range("safety.knee_margin_deg", sf.knee_margin_deg, 0.0, 360.0)?;
    c.positive_up_to("safety.safe_moment_nm", sf.safe_moment_nm, MAX_MOMENT_NM)?;
    c.range("safety.safe_hold_s", sf.safe_hold_s, 0.0, MAX_LIMIT_S)?;
    for (k, v, hi) in [
        ("safety.max_knee_accel_rad_s2", sf.max_knee_accel_rad_s2, 1e9),
        ("safety.max_knee_jerk_rad_s3", sf.max_knee_jerk_rad_s3, 1e12),
        ("safety.max_time_to_safe_s", sf.max_time_to_safe_s, MAX_LIMIT_S),
    ] {
        if let Some(v) = v {
            c.positive_up_to(k, v, hi)?;
        }
    }
    let cl = &f.cuff_limits;
    for (k, v) in [("comfort_n", cl.comfort_n), ("thigh_pain_n", cl.thigh_pain_n), ("shank_pain_n", cl.shank_pain_n)] {
        c.positive_up_to(&format!("cuff_limits.{k}"), v, MAX_FORCE_N)?;
    }
    Ok(())
}

/// `[hip]`, `[ground]`, `[wearer]`, the leg's mass scales: ranges and the combinations that
/// make a body (the carriage needs the ground and a gait or pose to follow).
pub(super) fn walking(c: &Check, f: &ScenarioFile) -> Result<()> {
    let h = &f.hip;
    // People weigh 2-650 kg; what the pelvis carries is the subject less one leg.
    if let Some(m) = h.subject_mass_kg {
        c.range("hip.subject_mass_kg", m, 2.0, 650.0)?;
    }
    if let Some(m) = h.body_mass_kg {
        c.range("hip.body_mass_kg", m, 1.0, 650.0)?;
    }
    for (k, v) in [
        ("hip.stiffness_nm_per_rad", h.stiffness_nm_per_rad),
        ("hip.damping_nm_s_per_rad", h.damping_nm_s_per_rad),
        ("hip.tether_stiffness_n_per_m", h.tether_stiffness_n_per_m),
        ("hip.tether_damping_n_s_per_m", h.tether_damping_n_s_per_m),
        ("hip.support_stiffness_n_per_m", h.support_stiffness_n_per_m),
        ("hip.support_damping_n_s_per_m", h.support_damping_n_s_per_m),
        ("wearer.knee_stiffness_nm_per_rad", f.wearer.knee_stiffness_nm_per_rad),
        ("wearer.knee_damping_nm_s_per_rad", f.wearer.knee_damping_nm_s_per_rad),
        ("wearer.ankle_stiffness_nm_per_rad", f.wearer.ankle_stiffness_nm_per_rad),
        ("wearer.ankle_damping_nm_s_per_rad", f.wearer.ankle_damping_nm_s_per_rad),
    ] {
        c.range(k, v, 0.0, 1e7)?;
    }
    c.range("hip.moment_share", h.moment_share, 0.0, 1.0)?;
    if let Some(t) = h.pelvic_tilt_deg {
        c.range("hip.pelvic_tilt_deg", t, -30.0, 45.0)?;
    }
    c.range("wearer.knee_moment_share", f.wearer.knee_moment_share, 0.0, 1.0)?;
    c.range("wearer.ankle_moment_share", f.wearer.ankle_moment_share, 0.0, 1.0)?;
    c.range("wearer.reserve_optimal_moment_nm", f.wearer.reserve_optimal_moment_nm, 0.01, 1000.0)?;
    let carriage_gait = f.plant.kind == PlantKind::Leg
        && f.hip.mode == Some(crate::human::HipMode::Carriage)
        && f.reference.kind == ReferenceKind::Gait;
    ideal_device(c, f, carriage_gait)?;
    muscle_wearer(c, f, carriage_gait)?;
    if let Some(s) = h.other_leg_share {
        c.range("hip.other_leg_share", s, 0.0, 1.0)?;
    }
    c.range("hip.initial_clearance_m", h.initial_clearance_m, 0.0, 0.5)?;
    let g = &f.ground;
    c.range("ground.friction", g.friction, 0.0, 5.0)?;
    c.range("ground.contact_damping_ratio", g.contact_damping_ratio, 0.0, 20.0)?;
    c.range("ground.contact_frequency_hz", g.contact_frequency_hz, 1.0, 1000.0)?;
    c.range("ground.contact_modulus_pa", g.contact_modulus_pa, 1e4, 1e11)?;
    c.range("ground.contact_dissipation_s_per_m", g.contact_dissipation_s_per_m, 0.0, 50.0)?;
    c.range("ground.friction_stiffness_n_per_m", g.friction_stiffness_n_per_m, 1e3, 1e8)?;
    if let Some(v) = g.belt_speed_m_s {
        c.range("ground.belt_speed_m_s", v, -10.0, 10.0)?;
    }
    c.range("leg.mass_scale", f.leg.mass_scale, 0.2, 5.0)?;
    if let Some(m) = f.controller.nominal_leg.mass_scale {
        c.range("controller.nominal_leg.mass_scale", m, 0.2, 5.0)?;
    }
    let reduced = f.leg.engine == crate::plant::LegEngine::Reduced;
    if reduced && f.ground.enabled && f.ground.contact == crate::plant::ContactLaw::Rigid {
        return Err(c.fail(
            "ground.contact",
            "\"rigid\" is Rapier's contact constraint: the reduced engine has the compliant law (use \"compliant\" or leg.engine = \"rapier\")",
        ));
    }
    carriage_combinations(c, f)
}

pub(super) fn carriage_combinations(c: &Check, f: &ScenarioFile) -> Result<()> {
    use crate::human::HipMode;
    let mode = f.hip.mode;
    if let (Some(d), Some(m)) = (f.reference.drive_hip, mode) {
        let same = m == if d { HipMode::Driven } else { HipMode::Fixed };
        if !same {
            return Err(c.fail(
                "reference.drive_hip",
                format!(
                    "= {d} contradicts hip.mode = \"{}\": give hip.mode alone (reference.drive_hip is deprecated)",
                    m.as_str()
                ),
            ));
        }
    }
    if f.ground.enabled && f.plant.kind != PlantKind::Leg {
        return Err(c.fail("ground.enabled", "ground contact needs plant.kind = \"leg\""));
    }
    // Beyond 100 m from the hip the coordinates lose the precision the contact needs.
    if let Some(h) = f.ground.height_m {
        c.range("ground.height_m", h, -100.0, 100.0)?;
    }
    if let (Some(h), false) = (f.ground.height_m, f.hip.mode == Some(HipMode::Carriage)) {
        if h >= 0.0 {
            return Err(c.fail("ground.height_m", format!("the ground must be below the hip (z = 0), got {h} m")));
        }
    }
    if mode == Some(HipMode::Carriage) || (mode.is_none() && f.reference.kind == ReferenceKind::Pose) {
        if f.plant.kind != PlantKind::Leg {
            return Err(c.fail("hip.mode", "`carriage` carries a leg: it needs plant.kind = \"leg\""));
        }
        if !f.ground.enabled {
            return Err(c.fail(
                "ground.enabled",
                "the pelvis carriage needs the ground to stand on: set ground.enabled = true",
            ));
        }
        if f.reference.kind == ReferenceKind::Sine {
            return Err(
                c.fail("hip.mode", "`carriage` follows a gait or a pose: set reference.kind = \"gait\" or \"pose\"")
            );
        }
    } else if f.reference.kind == ReferenceKind::Pose {
        return Err(c.fail("reference.kind", "`pose` stands on the carriage: hip.mode must be \"carriage\""));
    }
    if f.reference.assist_fraction > 0.0 && mode != Some(HipMode::Carriage) {
        return Err(c.fail("reference.assist_fraction", "stance assistance needs a stance: hip.mode = \"carriage\""));
    }
    Ok(())
}

/// `[controller.ideal]`: its ranges, and the ideal device only on a walking run.
fn ideal_device(c: &Check, f: &ScenarioFile, carriage_gait: bool) -> Result<()> {
    c.range("controller.ideal.max_nm_per_kg", f.controller.ideal.max_nm_per_kg, 0.0, 5.0)?;
    c.range("controller.ideal.step_nm", f.controller.ideal.step_nm, -500.0, 500.0)?;
    c.range("controller.ideal.step_at_s", f.controller.ideal.step_at_s, 0.0, 1e6)?;
    if f.controller.kind == ControllerKind::IdealMoment && !carriage_gait {
        return Err(c.fail(
            "controller.kind",
            "\"ideal_moment\" applies the data's knee moment: it needs a walking run (plant.kind = \"leg\", hip.mode = \"carriage\", reference.kind = \"gait\")",
        ));
    }
    if f.controller.kind != ControllerKind::IdealMoment && !f.controller.ideal.is_default() {
        return Err(c.fail("controller.ideal", "has no effect without controller.kind = \"ideal_moment\""));
    }
    Ok(())
}

/// The muscle wearer's and the muscle analysis's keys: ranges, a walking run, and no key that
/// means nothing without them.
fn muscle_wearer(c: &Check, f: &ScenarioFile, carriage_gait: bool) -> Result<()> {
    for (joint, d) in ["hip", "knee", "ankle"].iter().zip(f.wearer.neural_delay_s.per_joint()) {
        c.range(&format!("wearer.neural_delay_s ({joint})"), d, 0.0, 0.3)?;
    }
    let w = &f.wearer;
    for (key, gains, hi) in [
        ("stance_stiffness_nm_per_rad_kg", w.stance_stiffness_nm_per_rad_kg, 50.0),
        ("swing_stiffness_nm_per_rad_kg", w.swing_stiffness_nm_per_rad_kg, 50.0),
        ("stance_damping_nm_s_per_rad_kg", w.stance_damping_nm_s_per_rad_kg, 5.0),
        ("swing_damping_nm_s_per_rad_kg", w.swing_damping_nm_s_per_rad_kg, 5.0),
    ] {
        for (joint, g) in ["hip", "knee", "ankle"].iter().zip(gains) {
            c.range(&format!("wearer.{key} ({joint})"), g, 0.0, hi)?;
        }
    }
    let muscle_wearer = w.model == crate::human::WearerModel::Muscles;
    if !muscle_wearer {
        let d = crate::human::WearerParams::default();
        for (key, set) in [
            ("wearer.adapted", w.adapted != d.adapted),
            ("wearer.neural_delay_s", w.neural_delay_s != d.neural_delay_s),
            (
                "wearer.stance_stiffness_nm_per_rad_kg",
                w.stance_stiffness_nm_per_rad_kg != d.stance_stiffness_nm_per_rad_kg,
            ),
            (
                "wearer.swing_stiffness_nm_per_rad_kg",
                w.swing_stiffness_nm_per_rad_kg != d.swing_stiffness_nm_per_rad_kg,
            ),
            (
                "wearer.stance_damping_nm_s_per_rad_kg",
                w.stance_damping_nm_s_per_rad_kg != d.stance_damping_nm_s_per_rad_kg,
            ),
            (
                "wearer.swing_damping_nm_s_per_rad_kg",
                w.swing_damping_nm_s_per_rad_kg != d.swing_damping_nm_s_per_rad_kg,
            ),
        ] {
            if set {
                return Err(c.fail(key, "has no effect without wearer.model = \"muscles\""));
            }
        }
    }
    if muscle_wearer && !carriage_gait {
        return Err(c.fail(
            "wearer.model",
            "\"muscles\" drives the body with the leg's muscles: it needs a walking run (plant.kind = \"leg\", hip.mode = \"carriage\", reference.kind = \"gait\")",
        ));
    }
    if f.wearer.muscles && !carriage_gait {
        return Err(c.fail(
            "wearer.muscles",
            "the muscle analysis needs a walking run: plant.kind = \"leg\", hip.mode = \"carriage\" and reference.kind = \"gait\"",
        ));
    }
    if !f.wearer.muscles && !muscle_wearer {
        for (k, set) in [
            ("wearer.muscles_file", f.wearer.muscles_file.is_some()),
            ("output.muscles", f.output.muscles),
            ("wearer.muscle_cost", f.wearer.muscle_cost != Default::default()),
            ("wearer.metabolic_model", f.wearer.metabolic_model != Default::default()),
        ] {
            if set {
                return Err(c.fail(k, "has no effect without wearer.muscles = true"));
            }
        }
    }
    Ok(())
}
