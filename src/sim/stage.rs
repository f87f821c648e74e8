//! One evaluation of the continuous dynamics (an integrator stage), and the record of a row.

use super::Model;
use super::{Held, State};
use crate::control::{ControlOutput, Controller};
use crate::disturbance::{CHANNEL_FORCE_ACCEL, CHANNEL_FORCE_RATE, CHANNEL_SPOOL};
use crate::human::HumanMode;
use crate::hydraulics::{ActuatorMode, ForceChannelInput, ForceRates, ForceSource, PistonKinematics};
use crate::plant::{CoupledMechanics, CoupledStage, PistonMotion, PistonPredictor, Plant, StageInputs};
use crate::record::{DeviceRow, Row};
use crate::reference::RefSample;
use crate::sensors::DeviceTruth;
use crate::sensors::Measurement;

/// The states beside the plant-side ones at a stage: the coupled mechanics' and the continuous
/// controller's.
#[derive(Clone, Copy)]
pub(super) struct Extra<'a> {
    pub mech: &'a [f64],
    pub ctrl: &'a [f64],
}

/// Where their derivatives go.
pub(super) struct ExtraMut<'a> {
    pub mech: &'a mut [f64],
    pub ctrl: &'a mut [f64],
}

impl<'a> Extra<'a> {
    /// The two from the part of a packed vector after the plant-side entries, the mechanics'
    /// `n_mech` first.
    pub fn split(x: &'a [f64], n_mech: usize) -> Self {
        let (mech, ctrl) = x.split_at(n_mech);
        Self { mech, ctrl }
    }
}

impl<'a> ExtraMut<'a> {
    /// As [`Extra::split`].
    pub fn split(x: &'a mut [f64], n_mech: usize) -> Self {
        let (mech, ctrl) = x.split_at_mut(n_mech);
        Self { mech, ctrl }
    }
}

/// Everything one evaluation produces.
pub(super) struct Stage {
    /// Time derivative of the state.
    pub derivative: State,
    /// The controller output in force at this stage.
    pub out: ControlOutput,
    /// x2 = dF_L/dt (N/s), as the load cell sees it (0 past a force bound).
    pub force_rate_n_per_s: f64,
    /// True lumped disturbance on dx2/dt relative to the nominal model (N/s^2; NaN for the
    /// two-chamber plant).
    pub lumped_n_per_s2: f64,
    /// The cylinder is at its force limit.
    pub force_limited: bool,
}

/// The desired forces a step has evaluated, by time and outer-loop force: a gait reference
/// costs two Fourier series and the friction feedforward per evaluation, and a step asks for
/// the same instants several times (its record, its stages, the sample, the interaction).
/// Cleared at every step's start (the stance weight may change there).
/// With coupled mechanics also the last mechanics stage: a sampled step evaluates its start
/// for the sensors and again for its record, with the same state.
/// Beside them, what depends on the time alone and is kept across steps (the next sample's
/// preview is the next step's present): the force reference's parts and the knee trajectory.
#[derive(Debug, Default)]
pub(super) struct RefMemo {
    entries: [(u64, u64, RefSample); 8],
    len: usize,
    next: usize,
    stage: Option<MechMemo>,
    parts: TimeMemo<crate::reference::ForceParts>,
    knee: TimeMemo<Option<RefSample>>,
}

/// A few values of a function of time alone, by the time's bits (oldest replaced first).
#[derive(Debug)]
struct TimeMemo<T> {
    entries: [Option<(u64, T)>; 4],
    next: usize,
}

impl<T> Default for TimeMemo<T> {
    fn default() -> Self {
        Self { entries: [None, None, None, None], next: 0 }
    }
}

impl<T: Copy> TimeMemo<T> {
    /// The value at `t`: kept, or `f(t)` (then kept).
    fn get(&mut self, t: f64, f: impl FnOnce(f64) -> T) -> T {
        let key = t.to_bits();
        if let Some((_, v)) = self.entries.iter().flatten().find(|(k, _)| *k == key) {
            return *v;
        }
        let v = f(t);
        self.entries[self.next] = Some((key, v));
        self.next = (self.next + 1) % self.entries.len();
        v
    }
}

/// One coupled-mechanics stage: its time, load force and cuff force (bits), state, derivative
/// and result.
#[derive(Debug, Clone, Copy)]
struct MechMemo {
    /// Still valid (a step's start forgets it without freeing the slot).
    live: bool,
    key: (u64, u64, u64),
    x: [f64; MAX_MECH],
    dx: [f64; MAX_MECH],
    out: CoupledStage,
}

/// Longest mechanical state the memo keeps.
pub(super) const MAX_MECH: usize = 16;

impl RefMemo {
    /// Forget every entry.
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
        if let Some(m) = &mut self.stage {
            m.live = false;
        }
    }
}

/// The immutable model of a run plus the continuous controller (if any): what a stage needs.
pub(super) struct Dynamics<'a> {
    pub sc: &'a Model,
    pub controller: Option<&'a dyn Controller>,
    pub memo: &'a std::cell::RefCell<RefMemo>,
}

impl Dynamics<'_> {
    /// Desired force at `t` with the held outer-loop force.
    pub fn reference_at(&self, t: f64, held: &Held) -> RefSample {
        let _timed = crate::profile::scope(crate::profile::Stage::Reference);
        if !self.sc.desired_force {
            return RefSample { value: f64::NAN, rate: f64::NAN, accel: f64::NAN };
        }
        let key = (t.to_bits(), held.pd_force_n.to_bits());
        let mut memo = self.memo.borrow_mut();
        if let Some(e) = memo.entries[..memo.len].iter().find(|e| (e.0, e.1) == key) {
            return e.2;
        }
        let reference = &self.sc.reference;
        let parts = memo.parts.get(t, |t| reference.force_parts(t));
        let r = reference.force_from(&parts, t, held.pd_force_n, held.events.map(|e| e.stance_weight(t)));
        let i = memo.next;
        memo.entries[i] = (key.0, key.1, r);
        memo.next = (i + 1) % memo.entries.len();
        memo.len = (memo.len + 1).min(memo.entries.len());
        r
    }

    /// The knee trajectory at `t` (gait and pose references), kept for the instants asked
    /// again.
    pub fn knee_at(&self, t: f64) -> Option<RefSample> {
        let _timed = crate::profile::scope(crate::profile::Stage::Reference);
        self.memo.borrow_mut().knee.get(t, |t| self.sc.reference.knee_at(t))
    }

    /// The gait cascade's outer-loop force for a knee reading at `t` (0 without a cascade).
    pub fn pd_force(&self, t: f64, knee_rad: f64, knee_rate_rad_s: f64, integral_rad_s: f64) -> f64 {
        match (&self.sc.knee_pd, self.knee_at(t)) {
            (Some(pd), Some(desired)) => pd.force_n(&desired, knee_rad, knee_rate_rad_s, integral_rad_s),
            _ => 0.0,
        }
    }

    /// The outer loop's knee-error integral (rad s) after `dt_s` more at reading `knee_rad`.
    pub fn pd_integral(&self, t: f64, integral_rad_s: f64, knee_rad: f64, dt_s: f64) -> f64 {
        match (&self.sc.knee_pd, self.knee_at(t)) {
            (Some(pd), Some(desired)) => pd.integrate(integral_rad_s, desired.value - knee_rad, dt_s),
            _ => 0.0,
        }
    }

    /// Piston motion at a stage: prescribed by the plant, from the coupled mechanics' state
    /// `mech`, or from the predictor states.
    pub fn piston(&self, t: f64, s: &State, mech: &[f64], plant: &dyn Plant, held: &Held) -> PistonMotion {
        match (held.predictor.as_ref(), plant.coupled()) {
            (None, _) => plant.piston_at(t),
            (Some(_), Some(c)) => {
                let mut scratch = [0.0; MAX_MECH];
                self.coupled(t, s, mech, &mut scratch[..mech.len()], c, held).piston
            }
            (Some(p), None) => Self::predicted(s, p, self.sc.friction.force_n(s.piston.velocity_m_s)),
        }
    }

    /// With coupled mechanics: the piston and the knee at the mechanical state `mech`, whose
    /// derivative goes to `dmech`.
    fn coupled(
        &self,
        t: f64,
        s: &State,
        mech: &[f64],
        dmech: &mut [f64],
        c: &dyn CoupledMechanics,
        held: &Held,
    ) -> CoupledStage {
        let key = (t.to_bits(), s.hyd.force_n.to_bits(), held.cuff_force_n.to_bits());
        let n = mech.len();
        if let Some(m) = self.memo.borrow().stage.as_ref().filter(|m| m.live && m.key == key && m.x[..n] == *mech) {
            dmech.copy_from_slice(&m.dx[..n]);
            return m.out;
        }
        let net_force = |v: f64| s.hyd.force_n - self.sc.friction.force_n(v);
        let inputs = StageInputs { net_force_n: &net_force, cuff_force_n: held.cuff_force_n, body: held.body };
        let out = c.stage(t, mech, &inputs, dmech);
        if n <= MAX_MECH {
            let mut memo = self.memo.borrow_mut();
            let m =
                memo.stage.get_or_insert(MechMemo { live: true, key, x: [0.0; MAX_MECH], dx: [0.0; MAX_MECH], out });
            (m.live, m.key, m.out) = (true, key, out);
            m.x[..n].copy_from_slice(mech);
            m.dx[..n].copy_from_slice(dmech);
        }
        out
    }

    /// The predictor's piston motion at state `s` with the friction `friction_n` (N) at its
    /// velocity.
    fn predicted(s: &State, p: &PistonPredictor, friction_n: f64) -> PistonMotion {
        // The force ODE sees the plant integrator's effective velocity v + a*lead (see
        // PistonPredictor).
        let v = s.piston.velocity_m_s;
        let a = p.free_accel_m_s2 + (s.hyd.force_n - friction_n) / p.effective_mass_kg;
        let v_eff = v + (a - p.lead_exempt_accel_m_s2) * p.velocity_lead_s;
        PistonMotion { position_m: s.piston.position_m, velocity_m_s: v_eff, accel_m_s2: a }
    }

    /// The force-channel inputs other than `u`, the cylinder's force rates and d(d_F)/dt at
    /// time `t`.
    fn environment(
        &self,
        t: f64,
        s: &State,
        piston: &PistonMotion,
        r: &RefSample,
        held: &Held,
    ) -> (ForceChannelInput, ForceRates, f64) {
        let f = self.sc;
        let (dist, seed) = (&f.disturbance, f.seed);
        let (d_f, d_f_rate) = dist.force_rate.value_and_rate(t, seed, CHANNEL_FORCE_RATE);
        let mut inp = ForceChannelInput {
            valve_command: 0.0,
            piston_velocity_m_s: piston.velocity_m_s,
            force_rate_dist_n_per_s: d_f,
            force_accel_dist_n_per_s2: 0.0,
            spool_dist_m_per_s: dist.spool.value(t, seed, CHANNEL_SPOOL),
        };
        let kin = PistonKinematics { position_m: piston.position_m, velocity_m_s: piston.velocity_m_s };
        let rates = {
            let _timed = crate::profile::scope(crate::profile::Stage::Hydraulics);
            self.sc.cylinder.rates_with(&s.hyd, &kin, &inp, &held.valve)
        };
        let x2 = rates.raw_n_per_s;
        let mut d_acc = dist.force_accel.value(t, seed, CHANNEL_FORCE_ACCEL)
            + dist.state_gain_force * s.hyd.force_n
            + dist.state_gain_force_rate * x2;
        if f.human.mode == HumanMode::Paper {
            d_acc += f.human.interaction(s.hyd.force_n - r.value, x2 - r.rate);
        }
        inp.force_accel_dist_n_per_s2 = d_acc;
        (inp, rates, d_f_rate)
    }

    /// What ideal sensors read: the plant's state at `t`, the load cell's rate `x2`, and the
    /// piston velocity the oil column experiences (with a predictor: the effective velocity of
    /// the plant's integrator, including its substep lead; what a velocity sensor on the real
    /// cylinder would measure).
    pub fn truth(&self, s: &State, mech: &[f64], x2: f64, plant: &dyn Plant, t: f64, held: &Held) -> Measurement {
        let p = plant.piston_at(t);
        let v = match held.predictor.as_ref() {
            Some(_) => self.piston(t, s, mech, plant, held).velocity_m_s,
            None => p.velocity_m_s,
        };
        Measurement {
            force_n: s.hyd.force_n,
            force_rate_n_per_s: x2,
            spool_m: s.hyd.spool_m,
            piston_m: p.position_m,
            piston_velocity_m_s: v,
            piston_accel_m_s2: p.accel_m_s2,
            knee_rad: plant.knee_rad(),
            knee_rate_rad_s: plant.knee_rate_rad_s(),
        }
    }

    /// Evaluate the continuous dynamics at (t, s), the coupled mechanics' state `x.mech` and
    /// the continuous controller's state `x.ctrl` with what is held over the step; their
    /// derivatives go to `dx`.
    pub fn evaluate(&self, t: f64, s: &State, x: Extra, dx: ExtraMut, plant: &dyn Plant, held: &Held) -> Stage {
        let sc = self.sc;
        let pred = held.predictor.as_ref();
        let coupled = pred.and(plant.coupled()).map(|c| self.coupled(t, s, x.mech, dx.mech, c, held));
        let (ctrl, dctrl) = (x.ctrl, dx.ctrl);
        // Friction and its slope at the predictor's piston velocity (unused without one).
        let (friction_n, friction_slope) = match (pred, coupled) {
            (Some(_), None) => sc.friction.force_and_slope(s.piston.velocity_m_s),
            _ => (0.0, 0.0),
        };
        let mut piston = match (pred, coupled) {
            (_, Some(c)) => c.piston,
            (Some(p), None) => Self::predicted(s, p, friction_n),
            (None, None) => plant.piston_at(t),
        };
        // The desired force enters a stage through a continuous controller and the paper's
        // human only: a sampled controller's stages do without it (a gait reference costs two
        // Fourier series and the friction feedforward).
        let continuous = held.output.is_none() && self.controller.is_some();
        let r = match continuous || sc.human.mode == HumanMode::Paper {
            true => self.reference_at(t, held),
            false => RefSample::default(),
        };
        let (mut inp, rates, d_f_rate) = self.environment(t, s, &piston, &r, held);
        let x2 = rates.load_cell_n_per_s;
        // With a predictor, the derivative of the effective velocity is a + lead*da/dt, with
        // da/dt = (dF_L/dt - F_f'(v)*a)/m_eff: the piston acceleration the force ODE
        // experiences, so it is what an ideal sensor reports.
        if let (Some(p), None) = (pred, coupled) {
            let a = piston.accel_m_s2;
            let a_dot = (x2 - friction_slope * a) / p.effective_mass_kg;
            piston.accel_m_s2 = a + p.velocity_lead_s * a_dot;
        }
        let y = Measurement {
            force_n: s.hyd.force_n,
            force_rate_n_per_s: x2,
            spool_m: s.hyd.spool_m,
            piston_m: piston.position_m,
            piston_velocity_m_s: piston.velocity_m_s,
            piston_accel_m_s2: piston.accel_m_s2,
            // Coupled mechanics: the knee at this stage; otherwise the plant's at the step start.
            knee_rad: coupled.map_or_else(|| plant.knee_rad(), |c| c.knee.0),
            knee_rate_rad_s: coupled.map_or_else(|| plant.knee_rate_rad_s(), |c| c.knee.1),
        };
        let mut derivative = State::default();
        let out = match (held.output, self.controller) {
            (Some(o), _) => o,
            (None, Some(c)) => {
                let _timed = crate::profile::scope(crate::profile::Stage::Controller);
                c.output_and_derivatives(t, &r, &y, ctrl, sc.valve_limit, dctrl)
            }
            (None, None) => ControlOutput::default(),
        };
        inp.valve_command = out.valve_command;
        // Without power the valve's command is 0 (its spool spring-centred).
        let out = if held.valve.power_off {
            inp.valve_command = 0.0;
            ControlOutput { valve_command: 0.0, ..out }
        } else {
            out
        };
        derivative.hyd = sc.cylinder.derivatives_with(&s.hyd, &inp, &rates, &held.valve);
        match (pred, coupled) {
            (_, Some(c)) => {
                derivative.piston.position_m = c.piston.velocity_m_s;
                derivative.piston.velocity_m_s = c.piston.accel_m_s2;
            }
            (Some(p), None) => {
                derivative.piston.position_m = piston.velocity_m_s;
                derivative.piston.velocity_m_s = p.free_accel_m_s2 + (s.hyd.force_n - friction_n) / p.effective_mass_kg;
            }
            (None, None) => {}
        }
        // True dx2/dt (linear model, analytic) and the part of it the controller's nominal model
        // does not explain; NaN for the two-chamber model.
        let spool_rate = sc.cylinder.coeffs.spool_rate(&s.hyd.channel(), &inp);
        let lumped_n_per_s2 =
            match sc.cylinder.force_accel(spool_rate, piston.accel_m_s2, x2, d_f_rate, inp.force_accel_dist_n_per_s2) {
                Some(dx2) => dx2 - sc.nominal.force_accel(out.valve_command, &y),
                None => f64::NAN,
            };
        Stage { derivative, out, force_rate_n_per_s: x2, lumped_n_per_s2, force_limited: sc.cylinder.at_limit(&s.hyd) }
    }

    /// The net force the actuator applies to the mechanics (N).
    pub fn cylinder_force(&self, s: &State, piston_velocity_m_s: f64, r: &RefSample) -> f64 {
        let act = &self.sc.actuator;
        match act.mode {
            ActuatorMode::Hydraulic => s.hyd.force_n - self.sc.friction.force_n(piston_velocity_m_s),
            ActuatorMode::Force => match act.force_source {
                ForceSource::Constant => act.force_n,
                ForceSource::Reference => r.value,
            },
            ActuatorMode::Free => 0.0,
        }
    }

    /// What the device's sensors measure at state `s` with the net cylinder force
    /// `cylinder_force_n` (N) on the moment arm `arm_m` (m/rad), the interaction force `w1` and
    /// what is held over the step (an ideal device's moment); the segments' kinematics only
    /// with `kinematics`.
    ///
    /// The cuffs carry the device's knee moment `M = -F_cyl dL/dq` (extensor positive) over
    /// their lever arms about the knee (the exoskeleton's frames strapped to the limb at one
    /// cuff each, their own inertia neglected: an extensor moment presses both cuffs
    /// forward, the knee back), and the shank cuff the human's interaction force w1 of
    /// `human.mode = "cuff"` (applied there, forward when it extends the knee).
    #[allow(clippy::too_many_arguments)]
    pub fn device_truth(
        &self,
        s: &State,
        plant: &dyn Plant,
        cylinder_force_n: f64,
        arm_m: f64,
        w1: f64,
        kinematics: bool,
        held: &Held,
    ) -> DeviceTruth {
        let cyl = &self.sc.cylinder;
        let (pressure_a_pa, pressure_b_pa) = cyl.pressures_pa(&s.hyd);
        let leg = self.sc.leg();
        let (thigh, shank) = leg.map_or((f64::NAN, f64::NAN), |l| {
            // An ideal device's moment goes through the cuffs as the cylinder's does.
            let m = -cylinder_force_n * arm_m - held.body.map_or(0.0, |b| b.device_knee_torque_nm);
            let w = if self.sc.human.mode == HumanMode::Cuff { arm_m.signum() * w1 } else { 0.0 };
            (m / l.cuff_lever_m.0, m / l.cuff_lever_m.1 + w)
        });
        DeviceTruth {
            leg: if kinematics { plant.leg_kinematics() } else { None },
            foot: leg.map(|_| plant.foot_load().unwrap_or_default()),
            thigh_cuff_force_n: thigh,
            shank_cuff_force_n: shank,
            pressure_a_pa,
            pressure_b_pa,
            supply_pressure_pa: cyl.supply_return_pa.0,
            load_pressure_pa: cyl.load_pressure_pa(&s.hyd),
        }
    }

    /// The device's row from its truth `d` at state `s`, with the device moment of
    /// `cylinder_force_n` on `arm_m`.
    fn device_row(&self, d: &DeviceTruth, s: &State, cylinder_force_n: f64, arm_m: f64) -> DeviceRow {
        // What is not computed (the kinematics and the foot's split without the device's
        // columns) is 0 (not NaN: rows compare equal run to run).
        let (heel, fore) = match (&d.foot, &self.sc.device) {
            (Some(f), Some(dev)) => f.split(dev.foot_x_m.0, dev.foot_x_m.1),
            _ => (0.0, 0.0),
        };
        let seg = |f: fn(&crate::sensors::LegKinematics) -> crate::sensors::SegmentState| {
            d.leg.as_ref().map_or((0.0, 0.0), |l| {
                let g = f(l);
                (g.angle_rad().to_degrees(), -g.omega_rad_s.to_degrees())
            })
        };
        let ((ta, tr), (sa, sr)) = (seg(|l| l.thigh), seg(|l| l.shank));
        let cyl = &self.sc.cylinder;
        DeviceRow {
            thigh_angle_deg: ta,
            shank_angle_deg: sa,
            thigh_rate_deg_s: tr,
            shank_rate_deg_s: sr,
            heel_force_n: heel,
            forefoot_force_n: fore,
            thigh_cuff_force_n: d.thigh_cuff_force_n,
            shank_cuff_force_n: d.shank_cuff_force_n,
            pressure_a_pa: d.pressure_a_pa,
            pressure_b_pa: d.pressure_b_pa,
            load_pressure_pa: d.load_pressure_pa,
            hydraulic_power_w: d.supply_pressure_pa * cyl.supply_flow_m3_s(&s.hyd),
            device_knee_moment_nm: -cylinder_force_n * arm_m,
        }
    }

    /// The row of state `s` at `t`, with the stage `st` evaluated there and the interaction
    /// force `w1`.
    pub fn row(&self, t: f64, s: &State, st: &Stage, w1: f64, plant: &dyn Plant, held: &Held) -> Row {
        let r = self.reference_at(t, held);
        let p = plant.piston_at(t);
        let leg = plant.leg_row();
        let cylinder_force_n = self.cylinder_force(s, p.velocity_m_s, &r);
        let device = leg.map(|l| {
            let truth = self.device_truth(s, plant, cylinder_force_n, l.moment_arm_m, w1, self.sc.device_columns, held);
            let mut row = self.device_row(&truth, s, cylinder_force_n, l.moment_arm_m);
            // An ideal device's moment is the device's too (extensor positive).
            row.device_knee_moment_nm -= held.body.map_or(0.0, |b| b.device_knee_torque_nm);
            row
        });
        Row {
            t_s: t,
            ref_force_n: r.value,
            ref_force_rate_n_per_s: r.rate,
            load_force_n: s.hyd.force_n,
            force_error_n: s.hyd.force_n - r.value,
            force_rate_n_per_s: st.force_rate_n_per_s,
            valve_command: st.out.valve_command,
            valve_saturated: st.out.saturated,
            spool_m: s.hyd.spool_m,
            force_limited: st.force_limited,
            piston_m: p.position_m,
            piston_velocity_m_s: p.velocity_m_s,
            friction_force_n: self.sc.friction.force_n(p.velocity_m_s),
            cylinder_force_n,
            interaction_force: w1,
            disturbance_estimate_n_per_s2: st.out.disturbance_estimate_n_per_s2,
            rbf_output_n_per_s2: st.out.rbf_output_n_per_s2,
            lumped_disturbance_n_per_s2: st.lumped_n_per_s2,
            ref_knee_deg: self.knee_at(t).map(|k| k.value.to_degrees()),
            leg,
            contact: plant.contact_row(),
            device,
            fault_active: false,
            log: Default::default(),
            muscles: None,
        }
    }
}
