//! The loop's stepping: one fixed step (record the start, integrate with substeps, check), and
//! the state's report at the end.

use super::*;

impl Simulation {
    /// Advance one step with the run's own controller; the row of the step's start goes to
    /// `sink`.
    pub fn step(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        self.control_step()?;
        self.advance(sink)
    }

    /// Integrate one fixed step from `t_k` (after [`Self::sample`] and [`Self::hold`] at a
    /// sample instant); the row of `t_k` goes to `sink`.
    pub fn advance(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        if let ControlBlock::Sampled(l) = &self.control {
            if l.hold.is_sample(self.k) && (l.sampled != Some(self.k) || l.awaiting.is_some()) {
                return Err(Error::Usage(format!(
                    "step {} (t = {} s) is a sample instant: sample() and hold() come first",
                    self.k,
                    self.t_s()
                )));
            }
        }
        let dt = self.sc.dt_s;
        let t = self.t_s();
        self.begin();
        if let ControlBlock::Continuous(_) = self.control {
            self.control_continuous(t);
        }
        let s0 = self.record_start(t, sink)?;
        let start = self.state;
        let v0 = self.plant.piston_at(t).velocity_m_s;
        let r0 = self.dynamics().reference_at(t, &self.held);
        if self.hydraulic() {
            self.integrate(t, &s0)?;
        }
        let cylinder_force_n = match &self.held.predictor {
            Some(p) => {
                p.effective_mass_kg
                    * ((self.state.piston.velocity_m_s - start.piston.velocity_m_s) / dt - p.free_accel_m_s2)
            }
            None => self.dynamics().cylinder_force(&start, v0, &r0),
        };
        let inputs = PlantInputs {
            cylinder_force_n,
            cuff_force_n: self.held.cuff_force_n,
            body: self.held.body,
            mech_end: (!self.mech_state.is_empty() && self.held.predictor.is_some()).then_some(&self.mech_state[..]),
        };
        let stroke = self.plant.advance(t, &inputs)?;
        // The plant's held forces changed with its step.
        self.ref_memo.borrow_mut().clear();
        let missed = self.hydraulic().then(|| {
            let seen = match &self.held.predictor {
                Some(_) => self.state.piston.position_m - start.piston.position_m,
                None => self.plant.piston_at(t + dt).position_m - self.plant.piston_at(t).position_m,
            };
            (self.plant.piston_at(t + dt).position_m, stroke - seen)
        });
        {
            let _timed = crate::profile::scope(crate::profile::Stage::Hydraulics);
            self.sc.cylinder.end_step_with(&mut self.state.hyd, missed, &self.held.valve);
        }
        self.k += 1;
        self.check(t + dt)
    }

    /// Evaluate the step's start, hand its row to `sink`, and set the cuff force held over the
    /// step. Returns the start's evaluation with its packed derivative in `self.first`.
    pub(super) fn record_start(&mut self, t: f64, sink: &mut dyn RecordSink) -> Result<stage::Stage> {
        let mut first = std::mem::take(&mut self.first);
        let (dp, dx) = first.split_at_mut(PLANT_LEN);
        let x = Extra { mech: &self.mech_state, ctrl: &self.controller_state };
        let dx = ExtraMut::split(dx, self.mech_state.len());
        let s0 = self.dynamics().evaluate(t, &self.state, x, dx, self.plant.as_ref(), &self.held);
        s0.derivative.pack_into(dp);
        self.first = first;
        let w1 = self.interaction(t, s0.force_rate_n_per_s);
        let mut row = self.dynamics().row(t, &self.state, &s0, w1, self.plant.as_ref(), &self.held);
        if let ControlBlock::Sampled(l) = &self.control {
            row.log = l.log;
        }
        row.fault_active = self.any_fault_active(t);
        row.muscles = self.muscle_sample(t);
        self.muscles_metabolic_w = row.muscles.as_deref().map(crate::muscles::analysis::metabolic_w);
        sink.row(&row)?;
        let cuff_force_n = if self.sc.human.mode == HumanMode::Cuff { w1 } else { 0.0 };
        // The integrator's first stage is s0 unless coupled mechanics now see another cuff force.
        self.reuse_first = self.plant.coupled().is_none() || self.held.cuff_force_n == cuff_force_n;
        self.held.cuff_force_n = cuff_force_n;
        Ok(s0)
    }

    /// The wearer's muscles at `t` (with `wearer.muscles`): the joints' angles and rates (the
    /// hip's anatomical flexion, the thigh's angle plus the data's pelvic tilt) and the moments
    /// the body applies over the step.
    pub(super) fn muscle_sample(&mut self, t: f64) -> Option<Arc<[f64]>> {
        let _timed = crate::profile::scope(crate::profile::Stage::Wearer);
        if let Some(w) = &self.wearer {
            return w.sample_at(t).cloned();
        }
        let a = self.muscles.as_mut()?;
        let b = self.plant.body_state()?;
        let tilt = match self.sc.leg().and_then(|l| l.body.as_ref()).map(|b| &b.targets) {
            Some(crate::human::BodyTargets::Walking(w)) => w.pelvic_tilt_at(t),
            _ => Default::default(),
        };
        let f = self.held.body.unwrap_or_default();
        let j = crate::muscles::analysis::Joints {
            q_rad: [b.hip.0 + tilt.value, b.knee.0, b.ankle.0],
            qd_rad_s: [b.hip.1 + tilt.rate, b.knee.1, b.ankle.1],
            moment_nm: [f.hip_torque_nm, f.knee_torque_nm, f.ankle_torque_nm],
        };
        Some(Arc::from(a.sample(&j).values))
    }

    /// Integrate the hydraulic (and predictor, coupled knee, continuous controller) states over
    /// the step from `t`, in as many substeps as their stiffness needs.
    pub(super) fn integrate(&mut self, t: f64, s0: &stage::Stage) -> Result<()> {
        let n = self.substeps(t, s0.force_rate_n_per_s)?;
        let h = self.sc.dt_s / n as f64;
        let mut x = std::mem::take(&mut self.packed);
        let mut work = std::mem::take(&mut self.work);
        let mut k1 = std::mem::take(&mut self.scratch_k1);
        let reuse_first = self.reuse_first;
        let nm = self.mech_state.len();
        self.state.pack_into(&mut x);
        x[PLANT_LEN..PLANT_LEN + nm].copy_from_slice(&self.mech_state);
        x[PLANT_LEN + nm..].copy_from_slice(&self.controller_state);
        let d = self.dynamics();
        let (plant, held) = (self.plant.as_ref(), &self.held);
        let f = |tau: f64, xs: &[f64], dx: &mut [f64]| {
            let (xp, xe) = xs.split_at(PLANT_LEN);
            let (dp, de) = dx.split_at_mut(PLANT_LEN);
            let (xe, de) = (Extra::split(xe, nm), ExtraMut::split(de, nm));
            d.evaluate(tau, &State::unpack(xp), xe, de, plant, held).derivative.pack_into(dp);
        };
        for i in 0..n {
            let ti = t + i as f64 * h;
            if i == 0 && reuse_first {
                self.sc.integrator.step_in_place(ti, h, &mut x, &self.first, &mut work, f);
            } else {
                f(ti, &x, &mut k1);
                self.sc.integrator.step_in_place(ti, h, &mut x, &k1, &mut work, f);
            }
        }
        self.state = State::unpack(&x);
        self.mech_state.copy_from_slice(&x[PLANT_LEN..PLANT_LEN + nm]);
        self.controller_state.copy_from_slice(&x[PLANT_LEN + nm..]);
        (self.packed, self.work, self.scratch_k1) = (x, work, k1);
        Ok(())
    }

    /// Substeps the integrated states need over this step: the local stiffness (force-channel or
    /// chamber-pressure rate, spool, piston friction over the effective mass, oil column) must
    /// stay within half the integrator's stability limit, the reduced engine's contact
    /// ([`crate::plant::CoupledMechanics::stiffness`]) within [`CONTACT_MARGIN`] of it. More
    /// than [`MAX_SUBSTEPS`] stops the run with [`Error::Stiff`] naming the state and the step
    /// it needs.
    pub(super) fn substeps(&mut self, t: f64, force_rate_n_per_s: f64) -> Result<usize> {
        let dt = self.sc.dt_s;
        let xc = match &self.held.predictor {
            Some(_) => self.state.piston.position_m,
            None => self.plant.piston_at(t).position_m,
        };
        let (rate, k_oil) = self.sc.cylinder.local_stiffness_with(&self.state.hyd, xc, &self.held.valve);
        // Each stiffness with the fraction of the stability limit it may use: the leg's contact
        // dampers and springs, whose modes are damped, use more of it than the hydraulics.
        let mut real = (rate, "hydraulic pressure / load force", STABILITY_MARGIN);
        let mut imag = (0.0, "oil column (piston)", STABILITY_MARGIN);
        if let Some(p) = &self.held.predictor {
            let fric = self.sc.friction.slope_n_s_per_m(self.state.piston.velocity_m_s) / p.effective_mass_kg;
            if fric > real.0 {
                real = (fric, "piston velocity (seal friction)", STABILITY_MARGIN);
            }
            imag.0 = (k_oil / p.effective_mass_kg).sqrt();
        }
        let (lim_re, lim_im) = self.sc.integrator.stability_limits();
        let n_of =
            |(rate, _, margin): (f64, &str, f64), lim: f64| if lim > 0.0 { rate * dt / (margin * lim) } else { 0.0 };
        if let (Some(c), false) = (self.plant.coupled(), self.mech_state.is_empty()) {
            let (rate, w) = c.stiffness();
            let (contact_re, contact_im) = (
                (rate, "leg contact (sole dampers)", CONTACT_MARGIN),
                (w, "leg contact (sole springs)", CONTACT_MARGIN),
            );
            if n_of(contact_re, lim_re) > n_of(real, lim_re) {
                real = contact_re;
            }
            if n_of(contact_im, lim_im) > n_of(imag, lim_im) {
                imag = contact_im;
            }
        }
        if let (ControlBlock::Continuous(c), true) = (&self.control, self.sc.substep_controller) {
            let k = c.stiffness_per_s(force_rate_n_per_s, &self.controller_state);
            let observer = (k, "controller observer (FDO)", STABILITY_MARGIN);
            if n_of(observer, lim_re) > n_of(real, lim_re) {
                real = observer;
            }
        }
        let (n_real, n_imag) = (n_of(real, lim_re), n_of(imag, lim_im));
        let need = n_real.max(n_imag).ceil().max(1.0);
        if need > MAX_SUBSTEPS as f64 || !need.is_finite() {
            let ((rate, state, margin), lim) = if n_real >= n_imag { (real, lim_re) } else { (imag, lim_im) };
            return Err(Error::Stiff {
                time_s: t,
                state: state.into(),
                step_s: dt,
                rate_per_s: rate,
                needed_step_s: margin * lim / rate,
            });
        }
        let n = need as usize;
        self.max_substeps = self.max_substeps.max(n);
        self.substepped_steps += usize::from(n > 1);
        Ok(n)
    }

    /// What the leg's end stops did so far (leg runs).
    pub fn stop_report(&self) -> Option<crate::leg::StopReport> {
        self.plant.stop_report()
    }

    /// Sensor readings that clipped at full scale, by channel (sampled mode).
    pub fn sensor_clips(&self) -> Vec<(&'static str, usize)> {
        match &self.control {
            ControlBlock::Sampled(l) => l.sensors.clipped(),
            ControlBlock::Continuous(_) => Vec::new(),
        }
    }

    /// Most substeps of the hydraulic states in one step so far, and how many steps needed
    /// more than one.
    pub fn substep_stats(&self) -> (usize, usize) {
        (self.max_substeps, self.substepped_steps)
    }

    /// Stop on a non-finite state (a stopped controller's aside) or an implausible spool.
    pub(super) fn check(&self, t: f64) -> Result<()> {
        let mech = self.mech_state.iter().zip(self.mech_names).find(|(v, _)| !v.is_finite());
        let bad = mech.map(|(v, n)| (n.to_string(), *v));
        let bad =
            bad.or_else(|| self.state.first_non_finite(&self.controller_state, &self.controller_names)).or_else(|| {
                match &self.control {
                    // A stopped controller (the device in its fail-safe state) is not called
                    // again: its state no longer matters.
                    ControlBlock::Sampled(_) if self.faults.stopped.is_some() => None,
                    ControlBlock::Sampled(l) => l.ctrl.as_ref().and_then(|c| c.first_non_finite()),
                    ControlBlock::Continuous(_) => None,
                }
            });
        if let Some((state, value)) = bad {
            return Err(Error::Diverged { time_s: t, state: self.with_hint(state), value });
        }
        // No valve spool travels a metre: a run whose spool does has gone unstable even if the
        // numbers are still finite (e.g. held against a pressure limit).
        let xv = self.state.hyd.spool_m;
        if xv.abs() > MAX_PLAUSIBLE_SPOOL_M {
            return Err(Error::Diverged { time_s: t, state: self.with_hint("spool_m (beyond 1 m)".into()), value: xv });
        }
        Ok(())
    }

    /// A diverged state's name, with the likely cause when a continuous controller has a stiff
    /// observer the loop does not substep (the paper's FDO: its cubic term outruns a 1 ms step
    /// at a heel strike).
    pub(super) fn with_hint(&self, state: String) -> String {
        let observer = match &self.control {
            ControlBlock::Continuous(c) => c.stiffness_per_s(0.0, &vec![0.0; self.controller_state.len()]) > 0.0,
            ControlBlock::Sampled(_) => false,
        };
        match observer && !self.sc.substep_controller {
            true => format!(
                "{state}; the controller's observer may be stiffer than sim.dt_s: try sim.substep_controller = true or a smaller step"
            ),
            false => state,
        }
    }

    /// The row of the state now, evaluated the way the next step would see it (with the
    /// command held so far): what [`Self::finish`] records, and an FMU's outputs between
    /// steps. It changes nothing the run computes.
    pub fn row_now(&mut self) -> Row {
        let t = self.t_s();
        self.begin();
        let d = self.dynamics();
        let mut dc = vec![0.0; self.controller_state.len()];
        let mut dm = vec![0.0; self.mech_state.len()];
        let x = Extra { mech: &self.mech_state, ctrl: &self.controller_state };
        let s =
            d.evaluate(t, &self.state, x, ExtraMut { mech: &mut dm, ctrl: &mut dc }, self.plant.as_ref(), &self.held);
        let w1 = self.interaction(t, s.force_rate_n_per_s);
        let mut row = d.row(t, &self.state, &s, w1, self.plant.as_ref(), &self.held);
        if let ControlBlock::Sampled(l) = &self.control {
            row.log = l.log;
        }
        row.fault_active = self.any_fault_active(t);
        row.muscles = self.muscle_sample(t);
        row
    }

    /// Record the final state, evaluated the way the next step would see it.
    pub fn finish(&mut self, sink: &mut dyn RecordSink) -> Result<()> {
        let row = self.row_now();
        sink.row(&row)
    }
}
