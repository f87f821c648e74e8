//! One run written to an output folder: streamed `timeseries.csv`, `summary.json` and plots.

use crate::control::DiscreteController;
use crate::error::{Error, Result};
use crate::metrics::{check_criteria, CriterionResult, Summary};
use crate::output::{force_tracking_png, knee_tracking_png, write_json, PlotBuffer};
use crate::record::{RecordSink, Tee};
use crate::scenario::{InputRecord, ResolvedScenario, ScenarioFile};
use crate::sim::{ControllerSource, Simulation};
use serde::Serialize;
use std::path::Path;

/// What `summary.json` holds: the figures, the criteria verdict, the files read, and the
/// resolved scenario (feed the file back to `exoleg run` to reproduce the run).
#[derive(Debug, Clone, Serialize)]
pub struct SummaryFile<'a> {
    /// The figures.
    #[serde(flatten)]
    pub summary: &'a Summary,
    /// Each criterion of the scenario, checked.
    pub criteria_results: &'a [CriterionResult],
    /// All criteria passed (true when there are none).
    pub criteria_passed: bool,
    /// The files the run read, with their content hashes.
    pub inputs: &'a [InputRecord],
    /// Design figures of the controller computed at start (sampled `dtznn`), if any.
    pub controller_design: Option<serde_json::Value>,
    /// The controller given to the run from outside the scenario (a Python callable, a Rust
    /// controller, a loop the caller owns), which this file cannot hold: replaying the file
    /// is refused unless that controller is given again. Absent for the scenario's own.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub external_controller: Option<String>,
    /// The scenario as run.
    pub scenario: &'a ScenarioFile,
}

/// What `summary.json` says of a controller given to the run from outside the scenario
/// (None: the scenario's own, which `scenario` holds).
pub fn external_controller(source: &ControllerSource) -> Option<String> {
    match source {
        ControllerSource::Model => None,
        ControllerSource::Discrete(c) => Some(c.kind().to_string()),
        ControllerSource::External => Some("external loop".to_string()),
    }
}

impl<'a> SummaryFile<'a> {
    /// The summary of a run of `sc`: its figures, its criteria checked, what it read.
    pub fn new(
        sc: &'a ResolvedScenario,
        summary: &'a Summary,
        criteria: &'a [CriterionResult],
        controller_design: Option<serde_json::Value>,
    ) -> Self {
        Self {
            summary,
            criteria_results: criteria,
            criteria_passed: criteria.iter().all(|c| c.pass),
            inputs: &sc.inputs,
            controller_design,
            external_controller: None,
            scenario: &sc.file,
        }
    }

    /// The same, naming the controller from outside that made the run.
    pub fn external(mut self, controller: Option<String>) -> Self {
        self.external_controller = controller;
        self
    }
}

/// The outcome of a run written to a folder.
#[derive(Debug, Clone)]
pub struct RunReport {
    /// The figures.
    pub summary: Summary,
    /// The criteria checks.
    pub criteria: Vec<CriterionResult>,
}

impl RunReport {
    /// All criteria passed (true when there are none) and the controller did not crash.
    pub fn passed(&self) -> bool {
        self.summary.passes(&self.criteria)
    }
}

/// Plot title: the scenario's file name, controller, plant and reference.
pub fn run_title(sc: &ResolvedScenario) -> String {
    let f = &sc.file;
    let reference = match &sc.model.reference {
        crate::reference::ForceReference::Sine(s) => format!("F_d = {} N sine at {} Hz", s.amplitude, s.frequency_hz),
        crate::reference::ForceReference::Gait(k) => {
            format!("gait {}", crate::output::text::title_name(&k.gait.source))
        }
        crate::reference::ForceReference::Pose { knee_rad } => format!("pose, knee {:.1} deg", knee_rad.to_degrees()),
    };
    let name = crate::output::text::title_name(&sc.source_name);
    format!("{name} | {} | {:?} | {}", f.controller.kind.as_str(), f.plant.kind, reference)
}

/// A run kept in memory (the Python package's `exoleg.run`): what `summary.json` holds, and
/// the time series as columns named like `timeseries.csv`'s.
#[derive(Debug, Clone)]
pub struct MemoryRun {
    /// `summary.json`'s content.
    pub summary_json: serde_json::Value,
    /// Column names, as in `timeseries.csv`'s header.
    pub columns: Vec<String>,
    /// The values, row after row (`rows x columns.len()`).
    pub values: Vec<f64>,
}

/// Run `sc` in memory: the same figures and columns as [`run_into`] writes, no files.
pub fn run_to_memory(sc: &ResolvedScenario) -> Result<MemoryRun> {
    run_to_memory_with(sc, ControllerSource::Model)
}

/// [`run_to_memory`] with the controller from `source`.
pub fn run_to_memory_with(sc: &ResolvedScenario, source: ControllerSource) -> Result<MemoryRun> {
    let mut thinned = crate::record::EveryNth::new(crate::record::MemoryRecord::default(), sc.file.output.every_steps);
    let external = external_controller(&source);
    let sim = Simulation::build(sc.model.clone(), source)?;
    let (summary, design) = crate::session::run_simulation(sim, &mut thinned)?;
    let rec = thinned.into_inner();
    let criteria = check_criteria(&sc.file.criteria, &summary);
    let file = SummaryFile::new(sc, &summary, &criteria, design).external(external);
    let summary_json =
        serde_json::to_value(&file).map_err(|e| Error::Write { path: "summary".into(), message: e.to_string() })?;
    let columns = rec.layout.names();
    let mut values = Vec::with_capacity(rec.rows.len() * columns.len());
    for r in &rec.rows {
        r.values_into(&rec.layout, &mut values);
    }
    Ok(MemoryRun { summary_json, columns, values })
}

/// Run `sc`, writing `timeseries.csv`, `summary.json`, `force_tracking.png` and (gait)
/// `knee_tracking.png` into `dir` (which must exist). `extra`: another sink fed the same rows.
pub fn run_into(
    sc: &ResolvedScenario,
    dir: &Path,
    title: &str,
    extra: Option<&mut dyn RecordSink>,
) -> Result<RunReport> {
    run_into_with(sc, ControllerSource::Model, dir, title, extra)
}

/// [`run_into`] with the controller from `source` (the caller's [`DiscreteController`]).
pub fn run_into_with(
    sc: &ResolvedScenario,
    source: ControllerSource,
    dir: &Path,
    title: &str,
    extra: Option<&mut dyn RecordSink>,
) -> Result<RunReport> {
    run_into_compared(sc, source, dir, title, extra, None)
}

/// [`run_into_with`], its muscle figures compared with `baseline`'s.
pub fn run_into_compared(
    sc: &ResolvedScenario,
    source: ControllerSource,
    dir: &Path,
    title: &str,
    extra: Option<&mut dyn RecordSink>,
    baseline: Option<crate::metrics::muscles::MetabolicsSummary>,
) -> Result<RunReport> {
    let mut files = RunFiles::create(dir, &sc.file.output)?.external(external_controller(&source)).baseline(baseline);
    let sim = Simulation::build(sc.model.clone(), source)?;
    let mut sinks: Vec<&mut dyn RecordSink> = vec![&mut files];
    if let Some(e) = extra {
        sinks.push(e);
    }
    let (summary, design) = crate::session::run_simulation(sim, &mut Tee(sinks))?;
    files.finish(sc, title, summary, design)
}

/// The scenario `sc` without the device's help, as `exoleg run --baseline` runs it: the
/// exoskeleton worn with its cylinder disconnected (`actuator.mode = "free"`), an ideal device
/// giving no moment; every other key as it is.
pub fn baseline_scenario(sc: &crate::scenario::Scenario) -> crate::scenario::Scenario {
    let mut b = sc.clone();
    b.file.actuator.mode = crate::hydraulics::ActuatorMode::Free;
    if b.file.controller.kind == crate::control::ControllerKind::IdealMoment {
        b.file.controller.ideal.max_nm_per_kg = 0.0;
    }
    b
}

/// What the wearer's muscles cost in `sc`'s baseline ([`baseline_scenario`]), run in memory.
/// Errors when the scenario has no muscles (`wearer.muscles = true` or `wearer.model =
/// "muscles"` is needed).
pub fn baseline_metabolics(
    sc: &crate::scenario::Scenario,
    res: &crate::scenario::Resources,
) -> Result<crate::metrics::muscles::MetabolicsSummary> {
    let w = &sc.file.wearer;
    if !w.muscles && w.model != crate::human::WearerModel::Muscles {
        return Err(Error::input(
            &sc.source_name,
            "--baseline",
            "compares what the muscles cost: set wearer.muscles = true (or wearer.model = \"muscles\")",
        ));
    }
    let b = baseline_scenario(sc).resolve(res)?;
    let summary = crate::session::run(&b.model, &mut crate::record::NullSink)?;
    summary.wearer.and_then(|w| w.metabolics).ok_or_else(|| {
        Error::input(
            &sc.source_name,
            "--baseline",
            "the baseline run has no muscle figures (no samples after metrics.settle_s)",
        )
    })
}

/// The files of one run as they are written: `timeseries.csv` streamed, the plots' rows kept
/// (bounded); [`RunFiles::finish`] adds `summary.json` and the plots. A [`RecordSink`].
pub struct RunFiles {
    dir: std::path::PathBuf,
    csv: crate::record::EveryNth<crate::output::TimeSeriesSink>,
    plots: PlotBuffer,
    external: Option<String>,
    baseline: Option<crate::metrics::muscles::MetabolicsSummary>,
}

impl RunFiles {
    /// Start writing into `dir` (which must exist) as `output` says: one time-series row in
    /// `every_steps`, as `timeseries.csv` or `timeseries.parquet`.
    pub fn create(dir: &Path, output: &crate::scenario::OutputSection) -> Result<Self> {
        let parquet = output.format == crate::scenario::OutputFormat::Parquet;
        Ok(Self {
            dir: dir.to_path_buf(),
            csv: crate::record::EveryNth::new(crate::output::TimeSeriesSink::create(dir, parquet)?, output.every_steps),
            plots: PlotBuffer::new(),
            external: None,
            baseline: None,
        })
    }

    /// Name the controller from outside the scenario that makes the run ([`external_controller`]).
    pub fn external(mut self, controller: Option<String>) -> Self {
        self.external = controller;
        self
    }

    /// Compare the run's muscle figures with `baseline`'s (`exoleg run --baseline`).
    pub fn baseline(mut self, baseline: Option<crate::metrics::muscles::MetabolicsSummary>) -> Self {
        self.baseline = baseline;
        self
    }

    /// Close `timeseries.csv`, write `summary.json` (figures, criteria, inputs, the scenario)
    /// and the plots titled `title`.
    pub fn finish(
        self,
        sc: &ResolvedScenario,
        title: &str,
        mut summary: Summary,
        design: Option<serde_json::Value>,
    ) -> Result<RunReport> {
        if let (Some(b), Some(m)) = (&self.baseline, summary.wearer.as_mut().and_then(|w| w.metabolics.as_mut())) {
            m.against(b);
        }
        self.csv.into_inner().finish()?;
        let criteria = check_criteria(&sc.file.criteria, &summary);
        let file = SummaryFile::new(sc, &summary, &criteria, design).external(self.external.clone());
        write_json(&self.dir.join("summary.json"), &file)?;
        force_tracking_png(&self.dir.join("force_tracking.png"), &self.plots, title)?;
        if self.plots.has_knee() {
            knee_tracking_png(&self.dir.join("knee_tracking.png"), &self.plots, title)?;
        }
        crate::output::indicators::write_indicators(&self.dir, &summary)?;
        if let Some(w) = summary.wearer.as_ref() {
            if let Some(c) = w.cycle.as_ref() {
                let muscles = w.metabolics.as_ref().and_then(|m| m.cycle.as_ref());
                crate::output::wearer_png(
                    &self.dir.join("wearer.png"),
                    c,
                    muscles,
                    sc.file.cuff_limits.comfort_n,
                    title,
                )?;
            }
        }
        Ok(RunReport { summary, criteria })
    }
}

impl RecordSink for RunFiles {
    fn start(&mut self, layout: &crate::record::Layout) -> Result<()> {
        self.csv.start(layout)?;
        self.plots.start(layout)
    }
    fn row(&mut self, row: &crate::record::Row) -> Result<()> {
        self.csv.row(row)?;
        self.plots.row(row)
    }
}

/// Write `leg_motion.gif` of a leg run whose rows `anim` collected.
pub fn write_animation(sc: &ResolvedScenario, anim: &crate::output::animate::Animation, path: &Path) -> Result<()> {
    let Some(leg) = sc.model.leg() else { return Ok(()) };
    let f = &sc.file;
    let cuff = (f.human.mode == crate::human::HumanMode::Cuff).then_some(leg.cuff_point_m);
    let ground_z_m = match (&leg.ground, &leg.body) {
        (Some(g), None) => Some(g.height_m),
        _ => None,
    };
    let scene = crate::output::animate::Scene { model: &leg.model, cuff_m: cuff, ground_z_m };
    crate::output::animate::write_gif(path, anim, &scene)
}

/// A run of a resolved scenario with the caller's controller (or the scenario's own): the same
/// outputs, summary, criteria and plots as `exoleg run`.
///
/// ```no_run
/// # use exoleg::control::{ControlOutput, ControlStop, DiscreteController, SampleInput};
/// struct Pi { ki: f64, integral: f64 }
/// impl DiscreteController for Pi {
///     fn kind(&self) -> &str { "pi" }
///     fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
///         let e = s.r.value - s.y.force_n;
///         self.integral += e * s.period_s;
///         Ok(ControlOutput::command(1e-4 * e + self.ki * self.integral))
///     }
/// }
/// let sc = exoleg::load(None, &["controller.sample_period_s=0.001"]).unwrap();
/// let report = exoleg::study::RunBuilder::new(&sc)
///     .controller(Box::new(Pi { ki: 1e-3, integral: 0.0 }))
///     .write_to(std::path::Path::new("out/pi"))
///     .unwrap();
/// println!("{}", report.summary.max_abs_force_error_n);
/// ```
pub struct RunBuilder<'a> {
    sc: &'a ResolvedScenario,
    source: ControllerSource,
    animate: bool,
    baseline: Option<crate::metrics::muscles::MetabolicsSummary>,
}

impl<'a> RunBuilder<'a> {
    /// A run of `sc` with its own controller until [`Self::controller`] says otherwise.
    pub fn new(sc: &'a ResolvedScenario) -> Self {
        Self { sc, source: ControllerSource::Model, animate: false, baseline: None }
    }

    /// Put the caller's sampled controller in the loop (`controller.sample_period_s` > 0).
    pub fn controller(mut self, ctrl: Box<dyn DiscreteController>) -> Self {
        self.source = ControllerSource::Discrete(ctrl);
        self
    }

    /// Compare the run's muscle figures with a baseline's ([`baseline_metabolics`]):
    /// `summary.json` `wearer.metabolics.change_pct` and the effort's change.
    pub fn baseline(mut self, b: Option<crate::metrics::muscles::MetabolicsSummary>) -> Self {
        self.baseline = b;
        self
    }

    /// Also write `leg_motion.gif` (leg runs).
    pub fn animate(mut self, on: bool) -> Self {
        self.animate = on;
        self
    }

    /// Run and write the outputs into `out` as `exoleg run --out` does: into a temporary
    /// folder, renamed into place only when the run completed (nothing is half-written).
    pub fn write_to(self, out: &Path) -> Result<RunReport> {
        let dir = crate::output::OutputDir::prepare_with_inputs(out, "--out", &self.sc.input_paths())?;
        self.write_into(dir)
    }

    /// [`Self::write_to`] into a folder prepared beforehand (checked before anything else
    /// starts: `exoleg hil` prepares it before its port opens).
    pub fn write_into(self, dir: crate::output::OutputDir) -> Result<RunReport> {
        let title = run_title(self.sc);
        let report = if self.animate && self.sc.model.leg().is_some() {
            let mut anim = crate::output::animate::Animation::new(self.sc.model.steps, self.sc.model.dt_s);
            let r = run_into_compared(self.sc, self.source, dir.path(), &title, Some(&mut anim), self.baseline)?;
            write_animation(self.sc, &anim, &dir.path().join("leg_motion.gif"))?;
            r
        } else {
            run_into_compared(self.sc, self.source, dir.path(), &title, None, self.baseline)?
        };
        dir.commit()?;
        Ok(report)
    }

    /// Run in memory: `summary.json`'s content and the columns of `timeseries.csv`.
    pub fn in_memory(self) -> Result<MemoryRun> {
        run_to_memory_with(self.sc, self.source)
    }
}
