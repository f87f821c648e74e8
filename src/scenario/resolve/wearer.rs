//! The muscle wearer's setup: its muscles, gains and delays, and the gait it learns in a run of
//! the impedance wearer.

use super::*;

impl Scenario {
    /// The muscle wearer of `wearer.model = "muscles"` on the analysis's muscles, its gains
    /// scaled by the subject's mass, its gait learned in [`Self::learning_scenario`].
    pub(super) fn muscle_wearer_setup(
        &self,
        res: &Resources,
        muscles: Option<&Arc<crate::muscles::analysis::MuscleSetup>>,
        stride_s: Option<f64>,
    ) -> Result<Arc<crate::human::MuscleWearerSetup>> {
        let w = &self.file.wearer;
        let (Some(muscles), Some(stride_s)) = (muscles, stride_s) else {
            return Err(Error::input(
                &self.source_name,
                "wearer.model",
                "\"muscles\" needs the leg's muscles and a gait",
            ));
        };
        let learning = self.learning_scenario(stride_s).resolve(res)?;
        let feedforward = crate::sim::learn::learn_gait(learning.model).map_err(|e| {
            Error::input(&self.source_name, "wearer.model", format!("the muscle wearer could not learn the gait: {e}"))
        })?;
        let m = self.file.hip.subject_mass();
        let per_kg = |g: [f64; 3]| g.map(|k| k * m);
        Ok(Arc::new(crate::human::MuscleWearerSetup {
            muscles: muscles.clone(),
            delay_s: w.neural_delay_s.per_joint(),
            muscle_group: crate::human::muscle_wearer::muscle_groups(
                muscles.set.muscles.iter().map(|m| &m.path.joints),
            ),
            adapted: w.adapted,
            stiffness_nm_per_rad: [per_kg(w.stance_stiffness_nm_per_rad_kg), per_kg(w.swing_stiffness_nm_per_rad_kg)],
            damping_nm_s_per_rad: [per_kg(w.stance_damping_nm_s_per_rad_kg), per_kg(w.swing_damping_nm_s_per_rad_kg)],
            feedforward: Arc::new(feedforward),
        }))
    }

    /// The run the muscle wearer learns its gait in (its internal model): this walk with the
    /// impedance wearer, the cylinder disconnected and no faults, for
    /// [`crate::sim::learn::LEARNING_STRIDES`] strides, recording nothing.
    pub(super) fn learning_scenario(&self, stride_s: f64) -> Scenario {
        let mut l = self.clone();
        let f = &mut l.file;
        // The cylinder free: no command reaches the knee, so the controller is a zero valve
        // command (open loop), which needs no desired force (`reference.force = "none"`
        // scenarios learn too).
        f.actuator.mode = crate::hydraulics::ActuatorMode::Free;
        f.controller = crate::control::ControllerParams {
            kind: crate::control::ControllerKind::OpenLoop,
            open_loop_command: 0.0,
            ..Default::default()
        };
        f.faults.clear();
        f.wearer = crate::human::WearerParams {
            knee_stiffness_nm_per_rad: f.wearer.knee_stiffness_nm_per_rad,
            knee_damping_nm_s_per_rad: f.wearer.knee_damping_nm_s_per_rad,
            knee_moment_share: f.wearer.knee_moment_share,
            ankle_stiffness_nm_per_rad: f.wearer.ankle_stiffness_nm_per_rad,
            ankle_damping_nm_s_per_rad: f.wearer.ankle_damping_nm_s_per_rad,
            ankle_moment_share: f.wearer.ankle_moment_share,
            ..Default::default()
        };
        f.output.muscles = false;
        f.sim.duration_s = stride_s * crate::sim::learn::LEARNING_STRIDES as f64;
        l
    }
}
