//! The loop's sample instants: read the sensors, hold the controller's command, the continuous
//! controller, the wearer's and the body's forces.

use super::*;

impl Simulation {
    /// Step 1 of a sampled step (MuJoCo's `mj_step1`): at a sample instant, read the sensors
    /// and update the gait cascade's outer loop; returns what the controller gets. Then
    /// [`Self::hold`] the command and [`Self::advance`].
    pub fn sample(&mut self) -> Result<SampleInput> {
        if !self.is_sample_step() {
            return Err(Error::Usage(format!("step {} (t = {} s) is not a sample instant", self.k, self.t_s())));
        }
        self.begin();
        let t = self.t_s();
        let period = self.sc.sample_period_s;
        let d = Dynamics { sc: &self.sc, controller: None, memo: &self.ref_memo };
        let mut dmech = [0.0; MAX_MECH];
        let (x, dx) = (Extra { mech: &self.mech_state, ctrl: &[] }, self.mech_scratch(&mut dmech));
        let s0 = d.evaluate(t, &self.state, x, dx, self.plant.as_ref(), &self.held);
        let truth = {
            let _timed = crate::profile::scope(crate::profile::Stage::Sensors);
            d.truth(&self.state, &self.mech_state, s0.force_rate_n_per_s, self.plant.as_ref(), t, &self.held)
        };
        let active: Vec<Option<f64>> = (0..self.sc.faults.len()).map(|i| self.fault_active(i, t)).collect();
        let at = |i: usize| active[i];
        let ControlBlock::Sampled(l) = &mut self.control else { unreachable!("is_sample_step") };
        let hook =
            (!l.sensor_faults.is_empty()).then_some((&mut l.sensor_faults, t, &at as &dyn Fn(usize) -> Option<f64>));
        let (y, counts) = {
            let _timed = crate::profile::scope(crate::profile::Stage::Sensors);
            l.sensors.sample_with(&truth, hook)
        };
        l.sampled = Some(self.k);
        l.awaiting = Some(self.k);
        // The outer loop compares each reading with the reference at the reading's time,
        // and takes the knee rate from the piston-velocity sensor when there is one
        // (v / (dL/dq): no differencing lag), else from the encoder's difference.
        let t_reading = (t - self.sc.sensors.delay_samples as f64 * period).max(0.0);
        let knee_rate = match self.sc.leg() {
            Some(leg) if self.sc.sensors.piston_velocity.enabled => {
                y.piston_velocity_m_s / crate::leg::moment_arm_at(&leg.model, y.knee_rad)
            }
            _ => y.knee_rate_rad_s,
        };
        let d = Dynamics { sc: &self.sc, controller: None, memo: &self.ref_memo };
        self.held.knee_integral_rad_s = d.pd_integral(t_reading, self.held.knee_integral_rad_s, y.knee_rad, period);
        self.held.pd_force_n = d.pd_force(t_reading, y.knee_rad, knee_rate, self.held.knee_integral_rad_s);
        // The device's truth with the outer loop's force as the step will hold it (as the
        // row records it).
        let device_truth = self.device_truth(t, s0.force_rate_n_per_s);
        let ControlBlock::Sampled(l) = &mut self.control else { unreachable!("is_sample_step") };
        let hook =
            (!l.sensor_faults.is_empty()).then_some((&mut l.sensor_faults, t, &at as &dyn Fn(usize) -> Option<f64>));
        let (device, device_counts) = match (&mut l.device, device_truth) {
            (Some(dev), Some(dt)) => {
                let _timed = crate::profile::scope(crate::profile::Stage::Sensors);
                dev.sample_with(&dt, hook)
            }
            _ => Default::default(),
        };
        if !self.sc.faults.is_empty() || self.faults.stopped.is_some() {
            self.sample_controller_faults(t);
        }
        let d = Dynamics { sc: &self.sc, controller: None, memo: &self.ref_memo };
        let r = d.reference_at(t, &self.held);
        // The next sample instant's time as that step will compute it (so its reference is
        // the one kept now).
        let every = self.sc.sample_every.unwrap_or(1);
        let r_next = d.reference_at((self.k + every) as f64 * self.sc.dt_s, &self.held);
        Ok(SampleInput {
            t_s: t,
            period_s: period,
            y,
            counts,
            device,
            device_counts,
            r,
            r_next,
            valve_limit: self.sc.valve_limit,
        })
    }

    /// What the device's sensors measure now (at `t`, the load cell's rate
    /// `force_rate_n_per_s`), when the run has them: the same truth the row's device columns
    /// record.
    pub(super) fn device_truth(&self, t: f64, force_rate_n_per_s: f64) -> Option<crate::sensors::DeviceTruth> {
        self.sc.device.as_ref()?;
        let d = self.dynamics();
        let plant = self.plant.as_ref();
        let v = plant.piston_at(t).velocity_m_s;
        let f = d.cylinder_force(&self.state, v, &d.reference_at(t, &self.held));
        let arm = plant.leg_row().map_or(0.0, |l| l.moment_arm_m);
        let w1 = self.interaction(t, force_rate_n_per_s);
        Some(d.device_truth(&self.state, plant, f, arm, w1, true, &self.held))
    }

    /// Step 2 of a sampled step: hold the controller's output (clipped to the valve limit, and
    /// marked saturated when it was) until the next sample. A non-finite command stops the run
    /// (under `controller.on_stop = "failsafe"`: the device goes to its fail-safe state).
    pub fn hold(&mut self, out: ControlOutput) -> Result<()> {
        let t = self.t_s();
        let kind = || match &self.control {
            ControlBlock::Sampled(l) => l.ctrl.as_ref().map_or("external".to_string(), |c| c.kind().to_string()),
            ControlBlock::Continuous(_) => String::new(),
        };
        if let ControlBlock::Continuous(_) = &self.control {
            return Err(Error::Usage("hold(): the run's controller is continuous".into()));
        }
        let out = if out.valve_command.is_finite() {
            out
        } else if self.sc.on_stop == crate::control::OnStop::Failsafe {
            // A stop like any other: the device goes to its fail-safe state.
            let why = crate::control::ControlStop::command(format!("the valve command is {}", out.valve_command));
            self.go_failsafe(t, why);
            ControlOutput::default()
        } else {
            return Err(Error::ControllerStopped {
                time_s: t,
                controller: kind(),
                message: format!("the valve command is {}", out.valve_command),
            });
        };
        let out = self.sc.valve_limit.apply(out);
        let out = if self.sc.faults.is_empty() && self.faults.stopped.is_none() { out } else { self.timed_output(out) };
        if let ControlBlock::Sampled(l) = &self.control {
            if l.awaiting != Some(self.k) {
                return Err(Error::Usage(format!("hold() at step {} without sample() first", self.k)));
            }
        }
        let now = self.computed(out)?;
        let ControlBlock::Sampled(l) = &mut self.control else { return Ok(()) };
        l.awaiting = None;
        if let Some(c) = &l.ctrl {
            c.log_values(&mut l.log);
        }
        if let compute::Computed::Now(out) = now {
            l.hold.set(out);
            self.held.output = Some(out);
        }
        Ok(())
    }

    /// Record the logged values of an outside controller (the caller's loop), in the order of
    /// the names given when it was built with them.
    pub fn set_log(&mut self, values: &[f64]) {
        if let ControlBlock::Sampled(l) = &mut self.control {
            let n = MAX_LOGGED.min(values.len());
            l.log[..n].copy_from_slice(&values[..n]);
        }
    }

    /// Name the channels an outside caller logs with [`Self::set_log`] (before the first step;
    /// at most [`MAX_LOGGED`]).
    pub fn set_log_names(&mut self, names: Vec<String>) -> Result<()> {
        if names.len() > MAX_LOGGED || self.k > 0 {
            return Err(Error::Usage(format!(
                "at most {MAX_LOGGED} logged channels, named before the first step (got {})",
                names.len()
            )));
        }
        if let ControlBlock::Sampled(l) = &mut self.control {
            l.log_names = names;
        }
        Ok(())
    }

    /// The run's own controller at this step if it is a sample instant: sample, update, hold
    /// (nothing otherwise). [`Self::step`] is this and [`Self::advance`].
    pub fn control_step(&mut self) -> Result<()> {
        if !self.is_sample_step() {
            return Ok(());
        }
        let input = self.sample()?;
        let t = input.t_s;
        let skip = self.faults.skip;
        let ControlBlock::Sampled(l) = &mut self.control else { return Ok(()) };
        let Some(ctrl) = l.ctrl.as_mut() else {
            return Err(Error::Usage(format!("step {}: a sample instant needs a command (hold)", self.k)));
        };
        if skip {
            // A skipped or lost sample, or a controller in its fail-safe state: not called.
            let last = l.hold.value();
            return self.hold(last);
        }
        let updated = {
            let _timed = crate::profile::scope(crate::profile::Stage::Controller);
            ctrl.update(&input)
        };
        let out = match updated {
            Ok(out) => out,
            Err(e) if self.sc.on_stop == crate::control::OnStop::Failsafe => {
                self.go_failsafe(t, e);
                ControlOutput::default()
            }
            Err(e) => {
                return Err(Error::ControllerStopped {
                    time_s: t,
                    controller: ctrl.kind().to_string(),
                    message: e.message,
                })
            }
        };
        self.hold(out)
    }

    /// The continuous controller's turn at `t`: the outer loop from the plant's knee state and,
    /// at step 0, the controller state from the first ideal reading.
    pub(super) fn control_continuous(&mut self, t: f64) {
        let d = self.dynamics();
        let q = self.plant.knee_rad();
        let integral = d.pd_integral(t, self.held.knee_integral_rad_s, q, self.sc.dt_s);
        let pd = d.pd_force(t, q, self.plant.knee_rate_rad_s(), integral);
        self.held.knee_integral_rad_s = integral;
        self.held.pd_force_n = pd;
        if self.k == 0 {
            let init = Held { output: Some(ControlOutput::default()), ..self.held };
            let d = self.dynamics();
            let mut dmech = [0.0; MAX_MECH];
            let (x, dx) = (Extra { mech: &self.mech_state, ctrl: &[] }, self.mech_scratch(&mut dmech));
            let s0 = d.evaluate(0.0, &self.state, x, dx, self.plant.as_ref(), &init);
            let mech = &self.mech_state;
            let y0: Measurement = d.truth(&self.state, mech, s0.force_rate_n_per_s, self.plant.as_ref(), 0.0, &init);
            let r0 = d.reference_at(0.0, &self.held);
            if let ControlBlock::Continuous(c) = &self.control {
                c.init(&y0, &r0, &mut self.controller_state);
            }
        }
    }

    /// The interaction force w1 at a stage's force error and rate (0 with the human off).
    pub(super) fn interaction(&self, t: f64, force_rate_n_per_s: f64) -> f64 {
        let h = &self.sc.human;
        match h.mode {
            HumanMode::Cuff | HumanMode::Paper => {
                let r = self.dynamics().reference_at(t, &self.held);
                h.interaction(self.state.hyd.force_n - r.value, force_rate_n_per_s - r.rate)
            }
            HumanMode::Off => 0.0,
        }
    }

    /// The body's forces on the carriage for the step from `t` (the human's other half, next
    /// to w1): its force laws at the body's state and the data's sample.
    pub(super) fn body_forces(&mut self, t: f64) -> Option<crate::human::BodyForces> {
        let _timed = crate::profile::scope(crate::profile::Stage::Wearer);
        let b = self.sc.leg()?.body.as_ref()?;
        let state = self.plant.body_state()?;
        // The muscle wearer drives the joints: the data's angles and moments are not needed
        // (an ideal device reads the data's knee moment).
        let mut sample = match &b.targets {
            crate::human::BodyTargets::Walking(w) if self.wearer.is_some() && self.sc.ideal.is_none() => {
                w.support_at(t)
            }
            targets => targets.at(t),
        };
        if let crate::human::BodyTargets::Walking(w) = &b.targets {
            if let Some(e) = &self.held.events {
                sample.other_share = e.other_share(t, w);
            }
            (sample.pelvis_x_m, sample.pelvis_x_rate_m_s) = w.pelvis_x_at(t, b.pelvis_drift_m_s);
        }
        let mut f = crate::human::body_forces(&b.hip, &b.wearer, &sample, &state);
        if let Some((ideal, mass_kg)) = &self.sc.ideal {
            // The data's moment is extensor positive, the knee's torque flexion positive.
            f.device_knee_torque_nm = -ideal.moment_nm(sample.knee_moment_nm, *mass_kg) - ideal.step_at(t);
        }
        if let (true, crate::human::BodyTargets::Walking(w)) = (self.wearer.is_some(), &b.targets) {
            let tilt = w.pelvic_tilt_at(t);
            let pct = w.pct_at(t);
            let x = crate::human::WearerInputs {
                joints: crate::muscles::analysis::Joints {
                    q_rad: [state.hip.0 + tilt.value, state.knee.0, state.ankle.0],
                    qd_rad_s: [state.hip.1 + tilt.rate, state.knee.1, state.ankle.1],
                    moment_nm: [0.0; 3],
                },
                body_rad: [state.hip.0, state.knee.0, state.ankle.0],
                body_rate_rad_s: [state.hip.1, state.knee.1, state.ankle.1],
                pct,
                stance_weight: w.stance_weight_at_pct(pct),
                device_torque_nm: self.device_knee_torque_nm(t) + f.device_knee_torque_nm,
            };
            let dt = self.sc.dt_s;
            let m = self.wearer.as_mut().map(|w| w.step(t, dt, &x)).unwrap_or_default();
            (f.hip_torque_nm, f.knee_torque_nm, f.ankle_torque_nm) = (m[0], m[1], m[2]);
        }
        Some(f)
    }

    /// The cylinder's torque at the knee now (N m, flexion positive: what the plant applies).
    pub(super) fn device_knee_torque_nm(&self, t: f64) -> f64 {
        let d = self.dynamics();
        let v = self.plant.piston_at(t).velocity_m_s;
        let arm = self.plant.leg_row().map_or(0.0, |l| l.moment_arm_m);
        d.cylinder_force(&self.state, v, &d.reference_at(t, &self.held)) * arm
    }
}
