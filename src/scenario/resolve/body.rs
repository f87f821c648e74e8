//! The leg's and the body's setup from a scenario: the gait within the leg's range, the start
//! pose, the leg, the walking body's targets and its sole's height.

use super::*;

/// Refuse a gait whose knee leaves what the leg can do: the cylinder loop must close at every
/// angle of the trajectory, and the angles must lie within 20 deg of the URDF's knee range.
pub(super) fn check_gait_in_leg_range(src: &str, gait: &GaitReference, model: &LegSpec) -> Result<()> {
    let (lo, hi) = model.knee_range_rad();
    let margin = 20f64.to_radians();
    for i in 0..1000 {
        let pct = i as f64 / 10.0;
        let q = gait.knee_at(pct / 100.0 * gait.stride_s).value;
        let outside = q < lo - margin || q > hi + margin;
        let unreachable = model.loop_solution_checked(q).err();
        if outside || unreachable.is_some() {
            let why = match unreachable {
                Some(e) if !outside => format!("the cylinder cannot reach it ({e})"),
                _ => format!(
                    "more than 20 deg outside the leg's knee range [{:.1}, {:.1}] deg",
                    lo.to_degrees(),
                    hi.to_degrees()
                ),
            };
            return Err(Error::input(
                src,
                format!("reference.gait ({}): knee_flexion_deg", gait.source),
                format!("the fitted knee angle reaches {:.2} deg at {pct:.1} % of the cycle: {why}", q.to_degrees()),
            ));
        }
    }
    Ok(())
}

/// Initial knee state: at rest at `leg.initial_knee_deg`; else on the gait trajectory;
/// else at rest at 30 deg. Returns the start and whether it is on the trajectory.
pub(super) fn leg_start(s: &Scenario, model: &LegSpec, reference: &ForceReference) -> Result<(LegStart, bool)> {
    let f = &s.file;
    let on_trajectory = f.leg.initial_knee_deg.is_none() && reference.knee_at(0.0).is_some();
    let (q0, qd0) = match (f.leg.initial_knee_deg, reference.knee_at(0.0)) {
        (Some(d), _) => (d.to_radians(), 0.0),
        (None, Some(k)) => (k.value, k.rate),
        (None, None) => (30f64.to_radians(), 0.0),
    };
    let (lo, hi) = model.knee_range_rad();
    if f.leg.initial_knee_deg.is_some() {
        let outside = (lo - q0).max(q0 - hi).max(0.0);
        if outside > 20f64.to_radians() {
            return Err(Error::input(
                &s.source_name,
                "leg.initial_knee_deg",
                format!(
                    "{:.2} deg is outside the URDF knee range [{:.1}, {:.1}] deg by more than 20 deg",
                    q0.to_degrees(),
                    lo.to_degrees(),
                    hi.to_degrees()
                ),
            ));
        }
        model
            .loop_solution_checked(q0)
            .map_err(|e| Error::input(&s.source_name, "leg.initial_knee_deg", e.to_string()))?;
    }
    if on_trajectory {
        let key = match reference {
            ForceReference::Pose { .. } => "reference.knee_deg",
            _ => "reference.gait (the knee angle at t = 0)",
        };
        model.loop_solution_checked(q0).map_err(|e| Error::input(&s.source_name, key, e.to_string()))?;
    }
    let hip: Option<RefSample> = reference.hip_at(0.0);
    Ok((LegStart { knee_rad: q0, knee_rate_rad_s: qd0, hip }, on_trajectory))
}

/// A belt speed further than this (relative) from the leg's stance sweep gets a warning.
pub const BELT_MISMATCH_WARNING: f64 = 0.10;

/// The leg plant's setup: start, cuff, and with contact the ground and the body.
pub(super) fn leg_setup(
    s: &Scenario,
    l: &crate::scenario::files::LoadedLeg,
    reference: &ForceReference,
    mode: HipMode,
    walking: Option<Arc<WalkingData>>,
) -> Result<LegSetup> {
    let f = &s.file;
    let (start, start_on_trajectory) = leg_start(s, &l.model, reference)?;
    if f.ground.enabled {
        if let Some(c) =
            l.model.collisions().iter().find(|c| matches!(c.shape, crate::leg::CollisionShape::Mesh { .. }))
        {
            let link = &l.model.links()[c.link].name;
            return Err(Error::input(
                &s.source_name,
                format!("leg.urdf (link '{link}' <collision>)"),
                "a mesh: ground contact needs boxes, cylinders, spheres or capsules",
            ));
        }
    }
    let cuff_point_m = crate::plant::cuff_point_from_model(&l.model, &f.human.cuff_link, f.human.cuff_xyz)
        .map_err(|m| Error::input(&s.source_name, "human.cuff_link", m))?;
    let (ground, body) = body_setup(s, &l.model, mode, walking, &start, reference)?;
    let knee = l.model.knee_joint().origin_xyz;
    let thigh_cuff = f.human.thigh_cuff_xyz.unwrap_or([knee[0], 0.0, 0.6 * knee[2]]);
    let cuff_lever_m =
        ((thigh_cuff[0] - knee[0]).hypot(thigh_cuff[2] - knee[2]), cuff_point_m[0].hypot(cuff_point_m[2]));
    if cuff_lever_m.0 < 1e-3 {
        return Err(Error::input(
            &s.source_name,
            "human.thigh_cuff_xyz",
            "lies on the knee axis: it carries no moment",
        ));
    }
    Ok(LegSetup {
        model: l.model.clone(),
        mass: l.mass.clone(),
        start,
        solver_iterations: f.leg.solver_iterations,
        cuff_point_m,
        cuff_lever_m,
        start_on_trajectory,
        ground,
        body,
        reduced: None,
        walker: None,
        stops: crate::leg::EndStops::of(&l.model),
    })
}

/// The targets of a pose on the carriage: the angles held, the foot flat (ankle = knee -
/// hip), the hip as high as the sole reaches, the other leg's share of the subject's weight.
pub(super) fn pose_targets(s: &Scenario, model: &LegSpec) -> Result<WalkingSample> {
    let f = &s.file;
    let (h, k) = (f.reference.hip_deg.to_radians(), f.reference.knee_deg.to_radians());
    let fp = foot_points_at(model, h, k, k - h).ok_or_else(|| {
        Error::input(&s.source_name, "reference.knee_deg", "the leg cannot take this pose (loop or soles)")
    })?;
    let share = f.hip.other_leg_share.unwrap_or(0.5);
    let weight = f.hip.subject_mass() * crate::leg::model::GRAVITY_M_S2;
    let at = |v: f64| RefSample { value: v, ..Default::default() };
    Ok(WalkingSample {
        hip: at(h),
        knee: at(k),
        ankle: at(k - h),
        grf_this_n: (1.0 - share) * weight,
        grf_other_n: share * weight,
        other_share: share,
        pelvis_height_m: -fp.lowest.z,
        stance_weight: 1.0,
        ..Default::default()
    })
}

/// With ground contact: the ground (height, belt) and, on the carriage, the body.
pub(super) fn body_setup(
    s: &Scenario,
    model: &LegSpec,
    mode: HipMode,
    walking: Option<Arc<WalkingData>>,
    start: &LegStart,
    reference: &ForceReference,
) -> Result<(Option<GroundConfig>, Option<Arc<BodySetup>>)> {
    let f = &s.file;
    let g = &f.ground;
    if !g.enabled {
        return Ok((None, None));
    }
    let targets = match (mode, walking) {
        (HipMode::Carriage, Some(w)) => Some(BodyTargets::Walking(w)),
        (HipMode::Carriage, None) => Some(BodyTargets::Pose(pose_targets(s, model)?)),
        _ => None,
    };
    let height_m = match (g.height_m, &targets) {
        (Some(h), _) => h,
        (None, Some(_)) => 0.0,
        (None, None) => lowest_sole_z(s, model, start, reference)?,
    };
    let belt_speed_m_s = g.belt_speed_m_s.unwrap_or(match &targets {
        Some(BodyTargets::Walking(w)) => w.belt_speed_m_s,
        _ => 0.0,
    });
    let ground = GroundConfig {
        height_m,
        friction: g.friction,
        belt_speed_m_s,
        contact_frequency_hz: g.contact_frequency_hz,
        contact_damping_ratio: g.contact_damping_ratio,
        compliant: (g.contact == crate::plant::ContactLaw::Compliant).then_some(crate::leg::CompliantContact {
            modulus_pa: g.contact_modulus_pa,
            dissipation_s_per_m: g.contact_dissipation_s_per_m,
            friction_stiffness_n_per_m: g.friction_stiffness_n_per_m,
        }),
    };
    let Some(targets) = targets else { return Ok((Some(ground), None)) };
    let pelvis_mass_kg = f.hip.body_mass_kg.unwrap_or(f.hip.subject_mass() - model.leg_mass_kg());
    if pelvis_mass_kg <= 0.0 {
        return Err(Error::input(
            &s.source_name,
            "hip.body_mass_kg",
            format!(
                "the subject ({} kg) minus this leg ({:.2} kg) leaves {pelvis_mass_kg:.2} kg for the body: must be > 0",
                f.hip.subject_mass(),
                model.leg_mass_kg()
            ),
        ));
    }
    let ankle_rad = targets.at(0.0).ankle.value;
    let pelvis_drift_m_s = match &targets {
        BodyTargets::Walking(w) => belt_speed_m_s - w.belt_speed_m_s,
        BodyTargets::Pose(_) => 0.0,
    };
    let mut hip = f.hip.clone();
    hip.support_force.get_or_insert(match &targets {
        BodyTargets::Walking(_) => crate::human::SupportForce::Data,
        BodyTargets::Pose(_) => crate::human::SupportForce::Weight,
    });
    let body = BodySetup { hip, wearer: f.wearer.clone(), targets, pelvis_mass_kg, ankle_rad, pelvis_drift_m_s };
    Ok((Some(ground), Some(Arc::new(body))))
}

/// Default ground height without the carriage: the lowest sole point (ankle at 0) at the
/// start, or over the gait cycle when the hip is driven along it.
pub(super) fn lowest_sole_z(
    s: &Scenario,
    model: &LegSpec,
    start: &LegStart,
    reference: &ForceReference,
) -> Result<f64> {
    let none = || Error::input(&s.source_name, "ground.enabled", "the URDF has no collision shapes to stand on");
    let z = |h: f64, k: f64| foot_points_at(model, h, k, 0.0).map(|p| p.lowest.z);
    let z0 = z(start.hip.map_or(0.0, |h| h.value), start.knee_rad).ok_or_else(none)?;
    let Some(stride) = reference.stride_s().filter(|_| start.hip.is_some()) else { return Ok(z0) };
    // Driven along a gait: the lowest the sole reaches over the cycle (200 samples).
    let mut lowest = z0;
    for i in 0..200 {
        let t = stride * i as f64 / 200.0;
        if let (Some(h), Some(k)) = (reference.hip_at(t), reference.knee_at(t)) {
            lowest = lowest.min(z(h.value, k.value).unwrap_or(lowest));
        }
    }
    Ok(lowest)
}
