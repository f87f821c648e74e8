//! A run with its figures: a [`Simulation`] whose rows feed the online metrics and the
//! caller's sink as it goes. Drive it with [`Session::step`] (the run's own controller) or,
//! when the caller owns the loop, [`Session::sample`] / [`Session::hold`] /
//! [`Session::advance`]; [`Session::finish`] records the final state and returns the summary.

use crate::control::{ControlOutput, SampleInput};
use crate::error::Result;
use crate::metrics::{SafetyMetrics, SafetySetup, Summary, SummaryBuilder, WalkingMetrics, WearerMetrics};
use crate::record::{Layout, MemoryRecord, RecordSink, Row};
use crate::sim::{Model, Simulation};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A session's sinks as a [`Fan`] (a macro: the fields borrowed apart from the simulation).
macro_rules! fan {
    ($s:expr) => {
        Fan {
            metrics: &mut $s.metrics,
            sink: &mut $s.sink,
            walking: $s.walking.as_mut(),
            wearer: $s.wearer.as_mut(),
            safety: $s.safety.as_mut(),
            muscles: $s.muscles.as_mut(),
        }
    };
}

/// The sinks of a session, fed in order without allocating per row.
struct Fan<'a, S: RecordSink + ?Sized> {
    metrics: &'a mut SummaryBuilder,
    sink: &'a mut S,
    walking: Option<&'a mut WalkingMetrics>,
    wearer: Option<&'a mut WearerMetrics>,
    safety: Option<&'a mut SafetyMetrics>,
    muscles: Option<&'a mut crate::metrics::muscles::MuscleMetrics>,
}

impl<S: RecordSink + ?Sized> RecordSink for Fan<'_, S> {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        self.metrics.start(layout)?;
        self.sink.start(layout)?;
        self.walking.as_mut().map_or(Ok(()), |w| w.start(layout))?;
        self.wearer.as_mut().map_or(Ok(()), |w| w.start(layout))?;
        self.safety.as_mut().map_or(Ok(()), |w| w.start(layout))?;
        self.muscles.as_mut().map_or(Ok(()), |w| w.start(layout))
    }
    fn row(&mut self, row: &Row) -> Result<()> {
        use crate::profile::{scope, Stage};
        {
            let _timed = scope(Stage::Metrics);
            self.metrics.row(row)?;
        }
        {
            let _timed = scope(Stage::Recording);
            self.sink.row(row)?;
        }
        let _timed = scope(Stage::Metrics);
        self.walking.as_mut().map_or(Ok(()), |w| w.row(row))?;
        self.wearer.as_mut().map_or(Ok(()), |w| w.row(row))?;
        self.safety.as_mut().map_or(Ok(()), |w| w.row(row))?;
        self.muscles.as_mut().map_or(Ok(()), |w| w.row(row))
    }
}

/// What a finished session gives back.
pub struct Finished<S> {
    /// The figures.
    pub summary: Summary,
    /// Design figures of the controller (gains computed at start), if it has any.
    pub design: Option<serde_json::Value>,
    /// The caller's sink.
    pub sink: S,
}

/// A simulation with its online metrics and the caller's sink.
pub struct Session<S: RecordSink> {
    sim: Simulation,
    metrics: SummaryBuilder,
    walking: Option<WalkingMetrics>,
    wearer: Option<WearerMetrics>,
    safety: Option<SafetyMetrics>,
    muscles: Option<crate::metrics::muscles::MuscleMetrics>,
    sink: S,
    /// Time spent simulating (s), for `steps_per_second`.
    wall: Duration,
    /// The sinks have their layout (at the first step, once the controller's logged channels
    /// are known).
    started: bool,
    /// Set by the caller to stop [`Session::run_to_end`] (checked every [`CANCEL_CHECK_STEPS`]).
    cancel: Option<Arc<AtomicBool>>,
}

/// Steps between two checks of a session's cancel flag.
pub const CANCEL_CHECK_STEPS: usize = 256;

impl<S: RecordSink> Session<S> {
    /// A session over `sim`; the sinks get the run's column layout at the first step.
    pub fn new(sim: Simulation, sink: S) -> Result<Self> {
        let sc = sim.model().clone();
        let layout = sim.layout();
        let metrics = SummaryBuilder::new(sc.metrics);
        let data = sc.leg().and_then(|l| l.body.as_ref()).and_then(|b| match &b.targets {
            crate::human::BodyTargets::Walking(w) => Some(w.clone()),
            crate::human::BodyTargets::Pose(_) => None,
        });
        let walking =
            layout.contact.then(|| WalkingMetrics::new(sc.metrics.settle_s, sc.metrics.stride_s, data.clone()));
        let safety = sc.leg().map(|l| SafetyMetrics::new(safety_setup(&sc, l, data.as_deref())));
        let muscles = match (&sc.muscles, &data) {
            (Some(m), Some(d)) => {
                Some(crate::metrics::muscles::MuscleMetrics::new(sc.metrics.settle_s, m.clone(), d.clone()))
            }
            _ => None,
        };
        let wearer =
            data.filter(|_| layout.contact).map(|d| WearerMetrics::new(sc.metrics.settle_s, d, sc.cuff_limits));
        Ok(Self {
            sim,
            metrics,
            walking,
            wearer,
            safety,
            muscles,
            sink,
            wall: Duration::ZERO,
            started: false,
            cancel: None,
        })
    }

    /// Stop [`Self::run_to_end`] with [`crate::Error::Interrupted`] when `flag` is set.
    pub fn set_cancel(&mut self, flag: Option<Arc<AtomicBool>>) {
        self.cancel = flag;
    }

    /// The simulation.
    pub fn sim(&self) -> &Simulation {
        &self.sim
    }

    /// The simulation, to change what it allows between steps (e.g. logged channels).
    pub fn sim_mut(&mut self) -> &mut Simulation {
        &mut self.sim
    }

    /// Give the sinks the run's layout, once (at the first step, when an outside controller's
    /// logged channels are known).
    fn ensure_started(&mut self) -> Result<()> {
        if self.started {
            return Ok(());
        }
        let layout = self.sim.layout();
        crate::record::check_log_names(&layout.log)
            .map_err(|m| crate::error::Error::input("controller", "logged channels", m))?;
        fan!(self).start(&layout)?;
        self.started = true;
        Ok(())
    }

    /// One fixed step into the sinks (untimed).
    fn advance_inner(&mut self) -> Result<()> {
        self.ensure_started()?;
        let mut fan = fan!(self);
        self.sim.advance(&mut fan)
    }

    fn timed<T>(&mut self, f: impl FnOnce(&mut Self) -> Result<T>) -> Result<T> {
        let t0 = Instant::now();
        let r = f(self);
        self.wall += t0.elapsed();
        r
    }

    /// One step with the run's own controller.
    pub fn step(&mut self) -> Result<()> {
        self.timed(|s| {
            s.sim.control_step()?;
            s.advance_inner()
        })
    }

    /// Every remaining step with the run's own controller.
    pub fn run_to_end(&mut self) -> Result<()> {
        self.timed(|s| {
            while !s.sim.done() {
                s.sim.control_step()?;
                s.advance_inner()?;
                if s.sim.steps_taken() % CANCEL_CHECK_STEPS == 0
                    && s.cancel.as_ref().is_some_and(|c| c.load(Ordering::Relaxed))
                {
                    return Err(crate::error::Error::Interrupted);
                }
            }
            Ok(())
        })
    }

    /// Read the sensors at a sample instant (see [`Simulation::sample`]).
    pub fn sample(&mut self) -> Result<SampleInput> {
        self.sim.sample()
    }

    /// Hold a command (see [`Simulation::hold`]).
    pub fn hold(&mut self, out: ControlOutput) -> Result<()> {
        self.sim.hold(out)
    }

    /// One fixed step (see [`Simulation::advance`]).
    pub fn advance(&mut self) -> Result<()> {
        self.timed(|s| s.advance_inner())
    }

    /// Record the final state and gather the figures.
    pub fn finish(mut self) -> Result<Finished<S>> {
        self.timed(|s| {
            s.ensure_started()?;
            let mut fan = fan!(s);
            s.sim.finish(&mut fan)
        })?;
        let sim = &self.sim;
        let sc = sim.model();
        let mut summary = self.metrics.finish(self.wall.as_secs_f64());
        crate::profile::count_loop(sim.steps_taken() as u64, self.wall.as_nanos() as u64);
        summary.contact = self.walking.map(|w| w.finish());
        summary.wearer = self.wearer.and_then(|w| w.finish());
        if let Some(w) = summary.wearer.as_mut() {
            w.metabolics = self.muscles.as_ref().and_then(|m| m.finish());
        }
        summary.safety = self.safety.map(|s| s.finish(sim.controller_stop().map(|(t, why)| (t, why.cause))));
        summary.controller_stop = sim.controller_stop().map(|(t_s, why)| crate::metrics::ControllerStopReport {
            t_s,
            cause: why.cause,
            message: why.message.clone(),
        });
        summary.engine =
            sc.leg().map(|l| if l.reduced.is_some() || l.walker.is_some() { "reduced" } else { "rapier" }.to_string());
        (summary.hydraulic_substeps_max, summary.substepped_steps) = sim.substep_stats();
        summary.sensor_clipped_readings = sim.sensor_clips().into_iter().map(|(k, n)| (k.to_string(), n)).collect();
        summary.end_stops = sim.stop_report();
        let (n, last) = sim.controller_warnings();
        if n > 0 {
            summary.controller_warnings =
                Some(crate::metrics::ControllerWarnings { samples: n, last: last.unwrap_or_default() });
        }
        (summary.controller_compute, summary.controller_link) = sim.controller_timing();
        summary.compute_model = sim.compute_summary().and_then(|c| serde_json::to_value(c).ok());
        Ok(Finished { summary, design: sim.controller_design(), sink: self.sink })
    }
}

/// The safety figures' setup of a leg run: the limits, the URDF's knee range, the wearer's
/// knee range and largest knee acceleration in the data (walking runs), the cuffs' pain
/// limits.
fn safety_setup(sc: &Model, leg: &crate::plant::LegSetup, data: Option<&crate::reference::WalkingData>) -> SafetySetup {
    let data = data.map(|w| {
        let g = &w.gait;
        let (mut lo, mut hi, mut acc) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        for i in 0..400 {
            let k = g.knee_at(i as f64 * g.stride_s / 400.0);
            (lo, hi, acc) = (lo.min(k.value), hi.max(k.value), acc.max(k.accel.abs()));
        }
        ((lo, hi), acc)
    });
    SafetySetup {
        limits: sc.safety,
        settle_s: sc.metrics.settle_s,
        urdf_knee_rad: leg.model.knee_range_rad(),
        data,
        cuff_pain_n: [sc.cuff_limits.thigh_pain_n, sc.cuff_limits.shank_pain_n],
    }
}

/// Run a resolved model to the end with its own controller, streaming rows to `sink`; returns
/// the summary.
pub fn run(sc: &Arc<Model>, sink: &mut dyn RecordSink) -> Result<Summary> {
    run_with_design(sc, sink).map(|(s, _)| s)
}

/// Like [`run`], also returning the controller's design figures (sampled controllers that
/// compute gains at start), for `summary.json`.
pub fn run_with_design(sc: &Arc<Model>, sink: &mut dyn RecordSink) -> Result<(Summary, Option<serde_json::Value>)> {
    run_simulation(Simulation::new(sc.clone())?, sink)
}

/// Run a built simulation (any controller) to the end, streaming rows to `sink`.
pub fn run_simulation(sim: Simulation, sink: &mut dyn RecordSink) -> Result<(Summary, Option<serde_json::Value>)> {
    run_cancellable(sim, sink, None)
}

/// [`run_simulation`], stopped with [`crate::Error::Interrupted`] when `cancel` is set.
pub fn run_cancellable(
    sim: Simulation,
    sink: &mut dyn RecordSink,
    cancel: Option<Arc<AtomicBool>>,
) -> Result<(Summary, Option<serde_json::Value>)> {
    let mut s = Session::new(sim, sink)?;
    s.set_cancel(cancel);
    s.run_to_end()?;
    let f = s.finish()?;
    Ok((f.summary, f.design))
}

/// Run and keep the whole record in memory (tests, the library API).
pub fn run_in_memory(sc: &Arc<Model>) -> Result<(Summary, MemoryRecord)> {
    let mut rec = MemoryRecord::default();
    let summary = run(sc, &mut rec)?;
    Ok((summary, rec))
}
