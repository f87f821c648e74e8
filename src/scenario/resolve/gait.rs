//! The gait a scenario walks: its trajectory, the desired force's reference and cascade, and
//! the walking body's data.

use super::*;

impl Ctx<'_> {
    /// The gait trajectory named by `reference.gait_trial` / `reference.gait_file`.
    pub(super) fn gait(&mut self) -> Result<GaitReference> {
        let rf = &self.s.file.reference;
        let (text, default_stride) = match &rf.gait_file {
            Some(f) => (self.res.gait_text(self.src(), f, self.s.base_dir.as_deref())?, None),
            None => match Resources::builtin_gait_text(&rf.gait_trial) {
                Some((t, stride)) => (t, Some(stride)),
                None => {
                    let names: Vec<&str> = BUILTIN_TRIALS.iter().map(|t| t.0).collect();
                    return Err(Error::input(
                        self.src(),
                        "reference.gait_trial",
                        format!("unknown trial `{}` (built-in: {})", rf.gait_trial, names.join(", ")),
                    ));
                }
            },
        };
        check_hash("reference.gait", &text, &rf.gait_sha256, &mut self.warnings);
        let cycle = self.res.gait(&text, &text.origin, rf.harmonics)?;
        let stride_s = match (rf.stride_s, rf.cadence_steps_per_min, default_stride) {
            (Some(s), _, _) => s,
            (None, Some(c), _) => 120.0 / c,
            (None, None, Some(s)) => s,
            (None, None, None) => {
                return Err(Error::input(
                    self.src(),
                    "reference.stride_s",
                    "a gait_file gives no timing: set reference.stride_s or reference.cadence_steps_per_min",
                ))
            }
        };
        if rf.gait_file.is_some() {
            self.file.reference.gait_file = Some(text.origin.clone());
        }
        self.file.reference.gait_sha256 = Some(text.sha256.clone());
        self.inputs.push(InputRecord {
            key: "reference.gait",
            origin: text.origin.clone(),
            sha256: text.sha256.clone(),
        });
        Ok(GaitReference { cycle: (*cycle).clone(), stride_s, source: text.origin, sha256: text.sha256 })
    }

    /// The force reference (its cascade on the controller's leg `nominal`), and on the
    /// carriage the walking data it follows.
    pub(super) fn reference(
        &mut self,
        leg: Option<&crate::scenario::files::LoadedLeg>,
        nominal: Option<&Arc<LegSpec>>,
        mode: HipMode,
    ) -> Result<(ForceReference, Option<Arc<WalkingData>>)> {
        let f = &self.s.file;
        match f.reference.kind {
            ReferenceKind::Sine => Ok((
                ForceReference::Sine(Sine {
                    amplitude: f.reference.amplitude_n,
                    frequency_hz: f.reference.frequency_hz,
                    phase_rad: f.reference.phase_rad,
                    offset: f.reference.offset_n,
                }),
                None,
            )),
            ReferenceKind::Pose => Ok((ForceReference::Pose { knee_rad: f.reference.knee_deg.to_radians() }, None)),
            ReferenceKind::Gait => {
                let (leg, nominal) = leg
                    .zip(nominal)
                    .ok_or_else(|| Error::input(self.src(), "reference.kind", "`gait` needs plant.kind = \"leg\""))?;
                let gait = self.gait()?;
                check_gait_in_leg_range(self.src(), &gait, &leg.model)?;
                let walking = match mode {
                    HipMode::Carriage => Some(self.walking(&gait, &leg.model)?),
                    _ => None,
                };
                let k = self.cascade(gait, nominal, mode, walking.clone())?;
                Ok((ForceReference::Gait(k), walking))
            }
        }
    }

    /// The gait cascade on the controller's leg: the inverse-dynamics fit (cached), blended
    /// with the stance assistance on the carriage, and the friction model.
    pub(super) fn cascade(
        &mut self,
        gait: GaitReference,
        nominal: &Arc<LegSpec>,
        mode: HipMode,
        walking: Option<Arc<WalkingData>>,
    ) -> Result<Arc<KneeForceReference>> {
        let f = &self.s.file;
        let with_hip = mode != HipMode::Fixed;
        let key = format!(
            "{}|{:?}|{}|{}|{}|{with_hip}|{}",
            self.file.leg.urdf_sha256.clone().unwrap_or_default(),
            (&f.leg.knee_joint, f.controller.nominal_leg.mass_scale.unwrap_or(f.leg.mass_scale)),
            gait.sha256,
            f.reference.harmonics,
            gait.stride_s.to_bits(),
            self.file.controller.nominal_leg.urdf_sha256.clone().unwrap_or_default(),
        );
        let model = nominal.clone();
        let fit = self.res.cascade(key, || KneeForceReference::inverse_dynamics_fit(&gait, &model, with_hip))?;
        let fraction = f.reference.assist_fraction;
        let stance = match walking {
            Some(w) if fraction != 0.0 => {
                let a = KneeForceReference::assist_fit(&gait, &model, &w, fraction)?;
                Some((w, Some(Arc::new(a))))
            }
            Some(w) => Some((w, None)),
            None => None,
        };
        // The cascade's model of the seal friction: the plant's levels with its own smooth sign.
        let fr = FrictionParams {
            smoothing_velocity_m_s: f.reference.friction_smoothing_velocity_m_s,
            ..f.friction.clone()
        };
        Ok(Arc::new(KneeForceReference::new(gait, model, fr, mode == HipMode::Driven, fit, stance)))
    }

    /// The walking data of a gait on the carriage (cached per gait, leg and subject).
    pub(super) fn walking(&mut self, gait: &GaitReference, model: &Arc<LegSpec>) -> Result<Arc<WalkingData>> {
        let (subject, tilt) = (self.s.file.hip.subject_mass(), self.s.file.hip.pelvic_tilt_deg.map(f64::to_radians));
        let g = &self.s.file.ground;
        let sole = (g.enabled && g.contact == crate::plant::ContactLaw::Compliant).then_some(g.contact_modulus_pa);
        let key = format!(
            "{}|{}|{}|{:?}|{:?}|{:p}",
            gait.sha256,
            gait.stride_s.to_bits(),
            subject.to_bits(),
            tilt.map(f64::to_bits),
            sole.map(f64::to_bits),
            Arc::as_ptr(model)
        );
        let src = self.src().to_string();
        let w = self.res.walking(key, || {
            WalkingData::new(gait.clone(), model, subject, tilt, sole)
                .map_err(|m| Error::input(&src, format!("reference.gait ({})", gait.source), m))
        })?;
        if let Some(v) = self.s.file.ground.belt_speed_m_s.filter(|_| self.s.file.ground.enabled) {
            let sweep = w.belt_speed_m_s;
            let off = v / sweep - 1.0;
            let msg = format!(
                "ground.belt_speed_m_s = {v} m/s and the speed the leg's stance sweeps at this stride time ({sweep:.3} \
                 m/s) differ by {:+.0} %: the belt will {} the stance foot (set the subject's height and the \
                 stride time, or leave the belt speed unset)",
                100.0 * off,
                if off > 0.0 { "drag back" } else { "push forward" }
            );
            if off.abs() > BELT_MISMATCH_WARNING && !self.warnings.contains(&msg) {
                self.warnings.push(msg);
            }
        }
        Ok(w)
    }
}
