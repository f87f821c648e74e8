//! `[[faults]]` resolved: each entry's target, kind, parameters and onset checked and turned
//! into a [`Fault`]; errors name the entry and the key (`faults.2.onset_s`).

use crate::faults::{
    ActuatorFaultKind as A, ControllerFaultKind as C, Dropout, Fault, FaultKind, FaultSpec, Onset, SensorFaultKind as S,
};
use crate::sensors::{CHANNELS, DEVICE_CHANNELS};

/// What resolving the faults needs to know about the run.
pub struct FaultContext<'a> {
    /// The run's length (s).
    pub duration_s: f64,
    /// The run-in (s): an event onset's default `onset_after_s`.
    pub settle_s: f64,
    /// The controller's sample period (s; 0 = continuous: no readings, no controller timing).
    pub sample_period_s: f64,
    /// The simulation's step (s): an actuator fault acts at the start of a step.
    pub dt_s: f64,
    /// The run detects gait events (loaded walking).
    pub walking: bool,
    /// The run has a leg (the device's sensors).
    pub leg: bool,
    /// The sensors (a channel switched off has no fault).
    pub sensors: &'a crate::sensors::SensorParams,
}

type Res<T> = Result<T, (String, String)>;

/// The A/D channel of a reading's name: 0-4 the force loop's, 5-25 the device's.
pub fn sensor_channel(name: &str) -> Option<usize> {
    CHANNELS
        .iter()
        .position(|c| c.reading == name)
        .or_else(|| DEVICE_CHANNELS.iter().position(|c| c.reading == name).map(|i| i + CHANNELS.len()))
}

/// The reading's name of an A/D channel (see [`sensor_channel`]).
pub fn sensor_channel_name(i: usize) -> &'static str {
    if i < CHANNELS.len() {
        CHANNELS[i].reading
    } else {
        DEVICE_CHANNELS[i - CHANNELS.len()].reading
    }
}

/// The parameters a kind takes (every other parameter given is refused).
fn takes(kind: &FaultKind) -> &'static [&'static str] {
    match kind {
        FaultKind::Sensor(_, k) => match k {
            S::Dropout(_) => &["mode"],
            S::Stuck(_) => &["value"],
            S::Bias(_) => &["bias"],
            S::Drift(_) => &["rate"],
            S::Gain(_) => &["gain"],
            S::Noise(_) => &["sd"],
            S::Spikes { .. } => &["amplitude", "probability"],
            S::Saturation(_) => &["level"],
            S::Delay(_) => &["samples"],
        },
        FaultKind::Actuator(k) => match k {
            A::SpoolStuck(_) => &["value"],
            A::SpoolSlow(_) => &["tau_factor"],
            A::Leakage { .. } => &["area_m2", "discharge_coefficient", "density_kg_m3"],
            A::SupplyLoss { .. } => &["residual", "tau_s"],
            A::PowerLoss => &[],
        },
        FaultKind::Controller(k) => match k {
            C::Overrun(_) => &["samples"],
            C::Skip => &[],
            C::Lost(_) => &["probability"],
        },
    }
}

/// The parameters an entry gives, by name.
fn given(f: &FaultSpec) -> Vec<&'static str> {
    let opts = [
        ("mode", f.mode.is_some()),
        ("value", f.value.is_some()),
        ("bias", f.bias.is_some()),
        ("rate", f.rate.is_some()),
        ("gain", f.gain.is_some()),
        ("sd", f.sd.is_some()),
        ("amplitude", f.amplitude.is_some()),
        ("probability", f.probability.is_some()),
        ("level", f.level.is_some()),
        ("samples", f.samples.is_some()),
        ("tau_factor", f.tau_factor.is_some()),
        ("area_m2", f.area_m2.is_some()),
        ("discharge_coefficient", f.discharge_coefficient.is_some()),
        ("density_kg_m3", f.density_kg_m3.is_some()),
        ("residual", f.residual.is_some()),
        ("tau_s", f.tau_s.is_some()),
    ];
    opts.iter().filter(|(_, g)| *g).map(|(n, _)| *n).collect()
}

/// A required parameter.
fn need(key: &str, name: &str, v: Option<f64>) -> Res<f64> {
    v.ok_or_else(|| (format!("{key}.{name}"), "this kind needs it".to_string()))
}

/// A parameter within `lo..=hi` (`open_lo`: above `lo`).
fn within(key: &str, name: &str, v: f64, lo: f64, hi: f64, open_lo: bool) -> Res<f64> {
    let ok = v.is_finite() && v <= hi && (v > lo || (!open_lo && v == lo));
    match ok {
        true => Ok(v),
        false => {
            let range = match (hi == f64::MAX, lo == -f64::MAX, open_lo) {
                (true, true, _) => "finite".to_string(),
                (true, false, true) => format!("> {lo}"),
                (true, false, false) => format!(">= {lo}"),
                (false, _, open) => format!("in {}{lo}..={hi}", if open { ">" } else { "" }),
            };
            Err((format!("{key}.{name}"), format!("must be {range}, got {v}")))
        }
    }
}

/// A delay's or an overrun's `samples`: given, 1..=100000.
fn samples(key: &str, f: &FaultSpec) -> Res<usize> {
    let n = f.samples.ok_or_else(|| (format!("{key}.samples"), "this kind needs it".to_string()))?;
    if !(1..=100_000).contains(&n) {
        return Err((format!("{key}.samples"), format!("must be 1..=100000, got {n}")));
    }
    Ok(n)
}

/// A sensor fault's kind on channel `ch`.
fn sensor_kind(key: &str, f: &FaultSpec) -> Res<S> {
    let big = f64::MAX;
    Ok(match f.kind.as_str() {
        "dropout" => S::Dropout(match f.mode.as_deref() {
            None | Some("nan") => Dropout::Nan,
            Some("zero") => Dropout::Zero,
            Some("hold") => Dropout::Hold,
            Some(m) => return Err((format!("{key}.mode"), format!("`{m}`: expected \"nan\", \"zero\" or \"hold\""))),
        }),
        "stuck" => S::Stuck(f.value.map(|v| within(key, "value", v, -big, big, false)).transpose()?),
        "bias" => S::Bias(within(key, "bias", need(key, "bias", f.bias)?, -big, big, false)?),
        "drift" => S::Drift(within(key, "rate", need(key, "rate", f.rate)?, -big, big, false)?),
        "gain" => S::Gain(within(key, "gain", need(key, "gain", f.gain)?, -1e6, 1e6, false)?),
        "noise" => S::Noise(within(key, "sd", need(key, "sd", f.sd)?, 0.0, big, false)?),
        "spikes" => S::Spikes {
            amplitude: within(key, "amplitude", need(key, "amplitude", f.amplitude)?, -big, big, false)?,
            probability: within(key, "probability", need(key, "probability", f.probability)?, 0.0, 1.0, false)?,
        },
        "saturation" => S::Saturation(within(key, "level", need(key, "level", f.level)?, 0.0, big, true)?),
        "delay" => S::Delay(samples(key, f)?),
        k => {
            return Err((
                format!("{key}.kind"),
                format!(
                    "`{k}` is not a sensor fault: dropout, stuck, bias, drift, gain, noise, spikes, saturation, delay"
                ),
            ))
        }
    })
}

/// An actuator or controller fault's kind on `target`.
fn other_kind(key: &str, target: &str, f: &FaultSpec) -> Res<FaultKind> {
    let k = f.kind.as_str();
    let bad = |list: &str| Err((format!("{key}.kind"), format!("`{k}` is not a `{target}` fault: {list}")));
    Ok(match (target, k) {
        ("valve", "stuck") => {
            FaultKind::Actuator(A::SpoolStuck(f.value.map(|v| within(key, "value", v, -1.0, 1.0, false)).transpose()?))
        }
        ("valve", "slow") => FaultKind::Actuator(A::SpoolSlow(within(
            key,
            "tau_factor",
            need(key, "tau_factor", f.tau_factor)?,
            1.0,
            1e6,
            false,
        )?)),
        ("valve", _) => return bad("stuck, slow"),
        ("leakage", "orifice") => FaultKind::Actuator(A::Leakage {
            area_m2: within(key, "area_m2", need(key, "area_m2", f.area_m2)?, 0.0, 1.0, true)?,
            cd: within(key, "discharge_coefficient", f.discharge_coefficient.unwrap_or(0.61), 0.0, 10.0, true)?,
            density_kg_m3: within(key, "density_kg_m3", f.density_kg_m3.unwrap_or(870.0), 0.0, 1e5, true)?,
        }),
        ("leakage", _) => return bad("orifice"),
        ("supply", "loss") => FaultKind::Actuator(A::SupplyLoss {
            residual: within(key, "residual", f.residual.unwrap_or(0.0), 0.0, 1.0, false)?,
            tau_s: within(key, "tau_s", f.tau_s.unwrap_or(0.0), 0.0, 1e6, false)?,
        }),
        ("supply", _) => return bad("loss"),
        ("power", "loss") => FaultKind::Actuator(A::PowerLoss),
        ("power", _) => return bad("loss"),
        ("controller", "overrun") => FaultKind::Controller(C::Overrun(samples(key, f)?)),
        ("controller", "skip") => FaultKind::Controller(C::Skip),
        ("controller", "lost") => FaultKind::Controller(C::Lost(within(
            key,
            "probability",
            need(key, "probability", f.probability)?,
            0.0,
            1.0,
            false,
        )?)),
        ("controller", _) => return bad("overrun, skip, lost"),
        _ => unreachable!("targets are checked first"),
    })
}

/// Whether a run with `sensors` (a leg run when `leg`) has the reading channel `name` (a
/// sensor switched off, or the device's on the bench, has none).
pub fn reading_available(sensors: &crate::sensors::SensorParams, leg: bool, name: &str) -> bool {
    let cx =
        FaultContext { duration_s: 0.0, settle_s: 0.0, sample_period_s: 0.0, dt_s: 0.0, walking: false, leg, sensors };
    sensor_channel(name).is_some_and(|ch| has_channel(&cx, ch))
}

/// Whether the run has A/D channel `ch` (a sensor switched off, or the device's on the bench,
/// has none).
fn has_channel(cx: &FaultContext, ch: usize) -> bool {
    let s = cx.sensors;
    if ch < CHANNELS.len() {
        return s.channel(CHANNELS[ch].id).enabled;
    }
    let c = &DEVICE_CHANNELS[ch - CHANNELS.len()];
    // On the bench only the pressure transducers exist.
    if !cx.leg && c.unit != "Pa" {
        return false;
    }
    match c.key {
        "thigh_imu.accel" | "thigh_imu.gyro" => s.thigh_imu.enabled,
        "shank_imu.accel" | "shank_imu.gyro" => s.shank_imu.enabled,
        "foot" => s.foot.enabled,
        "hip" => s.hip.enabled,
        "thigh_cuff" => s.thigh_cuff.enabled,
        "shank_cuff" => s.shank_cuff.enabled,
        "pressure_a" => s.pressure_a.enabled,
        "pressure_b" => s.pressure_b.enabled,
        "supply_pressure" => s.supply_pressure.enabled,
        _ => s.load_pressure.enabled,
    }
}

/// One entry: its kind (with the parameters it takes, no other) and its onset.
fn resolve_one(cx: &FaultContext, key: &str, f: &FaultSpec) -> Res<Fault> {
    let kind = match f.target.as_str() {
        t @ ("valve" | "leakage" | "supply" | "power" | "controller") => other_kind(key, t, f)?,
        t => {
            let ch = sensor_channel(t).ok_or_else(|| {
                (
                    format!("{key}.target"),
                    format!("`{t}` is not a reading channel (`Obs.fields`' A/D channels) nor valve, leakage, supply, power, controller"),
                )
            })?;
            if !has_channel(cx, ch) {
                return Err((
                    format!("{key}.target"),
                    format!("the run has no `{t}` sensor (switched off, or no leg)"),
                ));
            }
            FaultKind::Sensor(ch, sensor_kind(key, f)?)
        }
    };
    if let Some(p) = given(f).into_iter().find(|p| !takes(&kind).contains(p)) {
        return Err((format!("{key}.{p}"), format!("not a parameter of a `{}` `{}` fault", f.target, f.kind)));
    }
    let sampled = matches!(kind, FaultKind::Sensor(..) | FaultKind::Controller(_));
    if sampled && cx.sample_period_s == 0.0 {
        return Err((
            format!("{key}.target"),
            "sensor and controller faults act on a sampled controller: set controller.sample_period_s > 0".into(),
        ));
    }
    let onset = onset(cx, key, f)?;
    let duration_s = match f.duration_s {
        Some(d) => acting_duration(cx, key, d, sampled)?,
        None => f64::INFINITY,
    };
    if let (FaultKind::Sensor(_, S::Dropout(Dropout::Hold)), Onset::At(t)) = (kind, onset) {
        if t < 1e-9 {
            return Err((
                format!("{key}.mode"),
                "\"hold\" holds the last reading before the onset, and at onset_s = 0 there is none: give an onset after the first sample, or mode = \"nan\" or \"zero\"".into(),
            ));
        }
    }
    Ok(Fault { kind, onset, duration_s })
}

/// A fault's `duration_s`: at least the tick it acts at (a sensor or controller fault at
/// sample instants, an actuator fault at the start of a step), so that it acts at least once.
fn acting_duration(cx: &FaultContext, key: &str, d: f64, sampled: bool) -> Res<f64> {
    let d = within(key, "duration_s", d, 0.0, f64::MAX, true)?;
    let (tick, what) = if sampled { (cx.sample_period_s, "sample") } else { (cx.dt_s, "step (sim.dt_s)") };
    if d < tick * (1.0 - 1e-9) {
        return Err((
            format!("{key}.duration_s"),
            format!("{d} s is shorter than one {what} of {tick} s: the fault would never act"),
        ));
    }
    Ok(d)
}

/// An entry's onset: a time within the run, or a gait event of a walking run.
fn onset(cx: &FaultContext, key: &str, f: &FaultSpec) -> Res<Onset> {
    let end = cx.duration_s;
    match (f.onset_s, f.onset_event.as_deref()) {
        (Some(_), Some(_)) => Err((format!("{key}.onset_event"), "give onset_s or onset_event, not both".into())),
        (None, None) => Err((format!("{key}.onset_s"), "a fault needs an onset: onset_s, or onset_event".into())),
        (Some(t), None) => {
            if f.onset_phase_pct.is_some() || f.onset_after_s.is_some() {
                return Err((format!("{key}.onset_phase_pct"), "goes with onset_event, not onset_s".into()));
            }
            if !(0.0..end).contains(&t) {
                return Err((format!("{key}.onset_s"), format!("must be within the run, 0..{end} s, got {t}")));
            }
            Ok(Onset::At(t))
        }
        (None, Some("heel_strike")) => {
            if !cx.walking {
                return Err((
                    format!("{key}.onset_event"),
                    "gait events need a walking run (a gait on the carriage with ground.enabled)".into(),
                ));
            }
            let phase_pct = within(key, "onset_phase_pct", f.onset_phase_pct.unwrap_or(0.0), 0.0, 100.0, false)?;
            let after_s = f.onset_after_s.unwrap_or(cx.settle_s);
            if !(0.0..end).contains(&after_s) {
                return Err((
                    format!("{key}.onset_after_s"),
                    format!("must be within the run, 0..{end} s, got {after_s}"),
                ));
            }
            Ok(Onset::HeelStrike { after_s, phase_pct })
        }
        (None, Some(e)) => Err((format!("{key}.onset_event"), format!("`{e}`: the gait event is \"heel_strike\""))),
    }
}

/// The target two faults contradict on: the same sensor channel, or the same actuator part.
fn target_of(k: &FaultKind) -> (u8, usize) {
    match k {
        FaultKind::Sensor(ch, _) => (0, *ch),
        FaultKind::Actuator(A::SpoolStuck(_) | A::SpoolSlow(_)) => (1, 0),
        FaultKind::Actuator(A::Leakage { .. }) => (1, 1),
        FaultKind::Actuator(A::SupplyLoss { .. }) => (1, 2),
        FaultKind::Actuator(A::PowerLoss) => (1, 3),
        FaultKind::Controller(_) => (2, 0),
    }
}

/// Whether two faults may be active at once (event onsets are not known in advance: they may).
fn may_overlap(a: &Fault, b: &Fault) -> bool {
    match (a.onset, b.onset) {
        (Onset::At(s), Onset::At(t)) => s < t + b.duration_s && t < s + a.duration_s,
        _ => true,
    }
}

/// Resolve every `[[faults]]` entry of a scenario; two faults on one target at once are refused.
pub fn resolve_faults(specs: &[FaultSpec], cx: &FaultContext) -> Res<Vec<Fault>> {
    if specs.len() > 1000 {
        return Err(("faults".into(), format!("at most 1000 faults, got {}", specs.len())));
    }
    let mut out: Vec<Fault> = Vec::with_capacity(specs.len());
    for (i, f) in specs.iter().enumerate() {
        let key = format!("faults.{i}");
        let fault = resolve_one(cx, &key, f)?;
        if let Some(j) = out.iter().position(|g| target_of(&g.kind) == target_of(&fault.kind) && may_overlap(g, &fault))
        {
            return Err((
                format!("{key}.target"),
                format!("contradicts faults.{j} on `{}` at the same time (one fault per target at a time)", f.target),
            ));
        }
        out.push(fault);
    }
    Ok(out)
}
