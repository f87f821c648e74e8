//! Plots with plotters' bitmap backend and an embedded font (no system fonts needed).

use super::write_atomic;
use crate::error::{Error, Result};
use crate::record::{Layout, RecordSink, Row};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

mod figures;
pub use figures::*;

/// Largest number of buckets a [`PlotBuffer`] keeps (each holds the min and max of every
/// series over the rows it covers).
pub const PLOT_BUCKETS: usize = 4096;

/// The series the plots draw.
const SERIES: usize = 8;
const REF_FORCE: usize = 0;
const LOAD_FORCE: usize = 1;
const FORCE_ERROR: usize = 2;
const VALVE: usize = 3;
const REF_KNEE: usize = 4;
const KNEE: usize = 5;
const KNEE_ERROR: usize = 6;
const STANCE: usize = 7;

/// A bounded, decimated copy of a run for its plots: rows are grouped into buckets of `k`
/// consecutive rows, each keeping the min and max of every plotted series, and `k` doubles
/// (neighbouring buckets merge) whenever the buffer is full. Peaks survive decimation.
#[derive(Debug, Clone, Default)]
pub struct PlotBuffer {
    rows_per_bucket: usize,
    t: Vec<f64>,
    lo: Vec<[f64; SERIES]>,
    hi: Vec<[f64; SERIES]>,
    filled: usize,
    knee: bool,
    stance: bool,
}

impl PlotBuffer {
    /// An empty buffer.
    pub fn new() -> Self {
        Self { rows_per_bucket: 1, ..Default::default() }
    }

    fn values(r: &Row) -> [f64; SERIES] {
        let nan = f64::NAN;
        let knee = r.leg.map_or(nan, |l| l.knee_angle_deg);
        let stance = r.contact.map_or(nan, |c| if c.ground_reaction_vertical_n > 0.0 { 1.0 } else { 0.0 });
        [
            r.ref_force_n,
            r.load_force_n,
            r.force_error_n,
            r.valve_command,
            r.ref_knee_deg.unwrap_or(nan),
            knee,
            r.knee_error_deg().unwrap_or(nan),
            stance,
        ]
    }

    /// Halve the buckets (the buffer is full and every bucket complete; the count is even).
    fn merge_pairs(&mut self) {
        let n = self.t.len() / 2;
        for i in 0..n {
            let (a, b) = (2 * i, 2 * i + 1);
            self.t[i] = self.t[a];
            for j in 0..SERIES {
                self.lo[i][j] = self.lo[a][j].min(self.lo[b][j]);
                self.hi[i][j] = self.hi[a][j].max(self.hi[b][j]);
            }
        }
        self.t.truncate(n);
        self.lo.truncate(n);
        self.hi.truncate(n);
        self.rows_per_bucket *= 2;
    }

    /// One series as (t, value) points: each bucket's min, then its max.
    fn points(&self, j: usize) -> Vec<(f64, f64)> {
        let mut p = Vec::with_capacity(2 * self.t.len());
        for i in 0..self.t.len() {
            let (a, b) = (self.lo[i][j], self.hi[i][j]);
            if a.is_finite() {
                p.push((self.t[i], a));
            }
            if b.is_finite() && b != a {
                p.push((self.t[i], b));
            }
        }
        p
    }

    /// Number of buckets held (at most [`PLOT_BUCKETS`]).
    pub fn buckets(&self) -> usize {
        self.t.len()
    }

    /// Smallest and largest force error kept (N): decimation keeps every extreme.
    pub fn force_error_range_n(&self) -> (f64, f64) {
        let lo = self.lo.iter().map(|v| v[FORCE_ERROR]).fold(f64::INFINITY, f64::min);
        let hi = self.hi.iter().map(|v| v[FORCE_ERROR]).fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    }

    /// Whether the run has a knee reference (gait plots).
    pub fn has_knee(&self) -> bool {
        self.knee
    }

    /// Intervals (s) in which the foot was on the ground (any row of a bucket in contact).
    fn stance_intervals(&self) -> Vec<(f64, f64)> {
        if !self.stance {
            return Vec::new();
        }
        let mut out: Vec<(f64, f64)> = Vec::new();
        for i in 0..self.t.len() {
            if self.hi[i][STANCE] == 1.0 {
                let end = self.t.get(i + 1).copied().unwrap_or(self.t[i]);
                match out.last_mut() {
                    Some(last) if last.1 == self.t[i] => last.1 = end,
                    _ => out.push((self.t[i], end)),
                }
            }
        }
        out
    }

    /// Time span (s).
    fn span(&self) -> (f64, f64) {
        (self.t.first().copied().unwrap_or(0.0), self.t.last().copied().unwrap_or(1.0))
    }
}

impl RecordSink for PlotBuffer {
    fn start(&mut self, layout: &Layout) -> Result<()> {
        *self = Self::new();
        self.knee = layout.knee_reference && layout.leg;
        self.stance = layout.contact;
        Ok(())
    }

    fn row(&mut self, r: &Row) -> Result<()> {
        let v = Self::values(r);
        if !self.t.is_empty() && self.filled < self.rows_per_bucket {
            let (lo, hi) = (self.lo.last_mut().unwrap(), self.hi.last_mut().unwrap());
            for j in 0..SERIES {
                lo[j] = lo[j].min(v[j]);
                hi[j] = hi[j].max(v[j]);
            }
            self.filled += 1;
            return Ok(());
        }
        if self.t.len() == PLOT_BUCKETS {
            self.merge_pairs();
        }
        self.t.push(r.t_s);
        self.lo.push(v);
        self.hi.push(v);
        self.filled = 1;
        Ok(())
    }
}

static FONT: Once = Once::new();

/// Register the embedded DejaVu Sans font under the family name "sans-serif".
pub(super) fn ensure_font() {
    FONT.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// One named series of (t, value) points with its colour.
pub type Series<'a> = (&'a str, Vec<(f64, f64)>, RGBColor);

/// One panel: several named series over a shared time axis.
pub struct Panel<'a> {
    /// Y-axis label with unit.
    pub y_label: &'a str,
    /// (legend, points, colour).
    pub series: Vec<Series<'a>>,
}

/// The largest magnitude a plot's axis spans: its range, padding and ticks stay finite (a
/// range of +-f64::MAX overflows to infinity and the ticks never end).
const AXIS_LIMIT: f64 = 1e300;

/// A panel's y range: its values' (finite ones, clamped to +-[`AXIS_LIMIT`]) with 5 % padding.
fn range(panel: &Panel) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (_, v, _) in &panel.series {
        for (_, x) in v.iter().filter(|(_, x)| x.is_finite()) {
            lo = lo.min(x.clamp(-AXIS_LIMIT, AXIS_LIMIT));
            hi = hi.max(x.clamp(-AXIS_LIMIT, AXIS_LIMIT));
        }
    }
    if !lo.is_finite() || !hi.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-12 * hi.abs().max(1.0));
    (lo - pad, hi + pad)
}

/// Draw stacked panels sharing the time axis `t_span` into a PNG at `path` (atomic write);
/// `shade`: time intervals to shade in every panel (stance phases).
pub fn stacked_png(path: &Path, title: &str, t_span: (f64, f64), panels: &[Panel], shade: &[(f64, f64)]) -> Result<()> {
    panels_png(path, title, "time (s)", t_span, panels, shade)
}

/// Draw stacked panels sharing an x axis (`x_label`, the span `x_span`; the series' points
/// are (x, value)) into a PNG at `path` (atomic write); `shade`: x intervals to shade in every
/// panel.
pub fn panels_png(
    path: &Path,
    title: &str,
    x_label: &str,
    x_span: (f64, f64),
    panels: &[Panel],
    shade: &[(f64, f64)],
) -> Result<()> {
    panels_with_lanes_png(path, title, x_label, x_span, panels, shade, None)
}

/// Lanes of a panel drawn below the others: one per row, a value in 0..1 drawn in its lane
/// over the x span, with the x windows marked where it is expected on (`wearer.png`'s muscle
/// activations against normative EMG).
pub struct Lanes<'a> {
    /// Y-axis label.
    pub y_label: &'a str,
    /// Per lane: its name, its values at x = 0.5, 1.5, ... (0..1), its expected-on windows.
    pub rows: Vec<Lane<'a>>,
}

/// One lane of [`Lanes`]: name, values, expected-on x windows.
pub type Lane<'a> = (&'a str, Vec<f64>, Vec<(f64, f64)>);

/// [`panels_png`] with [`Lanes`] as a last, taller panel.
fn panels_with_lanes_png(
    path: &Path,
    title: &str,
    x_label: &str,
    x_span: (f64, f64),
    panels: &[Panel],
    shade: &[(f64, f64)],
    lanes: Option<&Lanes>,
) -> Result<()> {
    ensure_font();
    let lanes_h = lanes.map_or(0, |l| 40 * l.rows.len() as u32 + 80);
    let (w, h) = (1200u32, 300 * panels.len() as u32 + 60 + lanes_h);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    let perr = |e: String| Error::Write { path: path.to_path_buf(), message: format!("plot: {e}") };
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| perr(e.to_string()))?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(|e| perr(e.to_string()))?;
        let (top, bottom) = root.split_vertically(h - 60 - lanes_h + 30);
        let areas = top.split_evenly((panels.len(), 1));
        let (t0, t1) = (x_span.0, x_span.1.max(x_span.0 + 1e-9));
        for (area, p) in areas.iter().zip(panels) {
            draw_panel(area, p, (t0, t1), x_label, shade).map_err(perr)?;
        }
        if let Some(l) = lanes {
            draw_lanes(&bottom, l, (t0, t1), x_label).map_err(perr)?;
        }
        root.present().map_err(|e| perr(e.to_string()))?;
    }
    let img = image_png(&buf, w, h).map_err(perr)?;
    write_atomic(path, &img)
}

/// One panel of lines over `t` with the shaded x spans.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Panel,
    (t0, t1): (f64, f64),
    x_label: &str,
    shade: &[(f64, f64)],
) -> std::result::Result<(), String> {
    let (lo, hi) = range(p);
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(80)
        .build_cartesian_2d(t0..t1, lo..hi)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(p.y_label)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(
            shade.iter().map(|&(a, b)| Rectangle::new([(a, lo), (b, hi)], RGBColor(200, 200, 200).mix(0.4).filled())),
        )
        .map_err(|e| e.to_string())?;
    for (name, v, c) in &p.series {
        let c = *c;
        // A value beyond the axis is drawn at its edge (no line to a pixel 1e300 away).
        let on_axis = v.iter().map(|&(x, y)| (x, if y.is_nan() { y } else { y.clamp(lo, hi) }));
        chart
            .draw_series(LineSeries::new(on_axis, c.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    draw_legend(&mut chart)
}

/// The lanes panel: lane i spans i..i+1 on the y axis, its windows shaded, its values drawn
/// at i + 0.05 + 0.9 v.
fn draw_lanes<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    l: &Lanes,
    (t0, t1): (f64, f64),
    x_label: &str,
) -> std::result::Result<(), String> {
    let n = l.rows.len().max(1);
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(80)
        .build_cartesian_2d(t0..t1, 0.0..n as f64)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(l.y_label)
        .y_labels(n + 1)
        .y_label_formatter(&|_| String::new())
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, (name, values, windows)) in l.rows.iter().enumerate() {
        let y0 = i as f64;
        let at = (t0 + 0.005 * (t1 - t0), y0 + 0.95);
        chart
            .draw_series(std::iter::once(Text::new(name.to_string(), at, ("sans-serif", 14))))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(windows.iter().map(|&(a, b)| {
                Rectangle::new([(a, y0 + 0.03), (b, y0 + 0.97)], RGBColor(180, 180, 180).mix(0.5).filled())
            }))
            .map_err(|e| e.to_string())?;
        let pts = values
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(k, v)| (k as f64 + 0.5, y0 + 0.05 + 0.9 * v.clamp(0.0, 1.0)));
        chart.draw_series(LineSeries::new(pts, BLUE.stroke_width(2))).map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// The legend box every panel uses.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> std::result::Result<(), String> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| e.to_string())
}

/// Encode an RGB buffer as PNG bytes (through plotters' bitmap encoder via a temp file is
/// not atomic, so encode in memory with the `image` crate plotters already depends on).
fn image_png(rgb: &[u8], w: u32, h: u32) -> std::result::Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(rgb, w, h, image::ColorType::Rgb8)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// The colour of a margin to a limit (% of the limit left; negative: broken by that much):
/// green at 100 %, yellow at 0, red at -100 % and beyond; None (a failed run) black.
pub fn margin_colour(margin_pct: Option<f64>) -> RGBColor {
    let lerp = |a: (u8, u8, u8), b: (u8, u8, u8), f: f64| {
        let m = |x: u8, y: u8| (x as f64 + (y as f64 - x as f64) * f.clamp(0.0, 1.0)).round() as u8;
        RGBColor(m(a.0, b.0), m(a.1, b.1), m(a.2, b.2))
    };
    let (green, yellow, orange, red) = ((46, 160, 67), (250, 220, 60), (245, 130, 40), (170, 20, 20));
    match margin_pct {
        None => RGBColor(0, 0, 0),
        Some(m) if m >= 0.0 => lerp(yellow, green, m / 100.0),
        Some(m) if m >= -20.0 => lerp(yellow, orange, -m / 20.0),
        Some(m) => lerp(orange, red, (-m - 20.0) / 80.0),
    }
}

/// A heat map (`title`'s parts between "; " on lines of their own): one row per `rows`
/// label, one column per `cols` label, each cell coloured by
/// its margin ([`margin_colour`]) with its text (`cells[r][c]`: margin %, None for a failed
/// run; `marks[r][c]`: drawn with a frame and a `!`), a colour bar explaining `legend`.
pub fn heatmap_png(
    path: &Path,
    title: &str,
    rows: &[String],
    cols: &[String],
    cells: &[Vec<Option<f64>>],
    marks: &[Vec<bool>],
    legend: &str,
) -> Result<()> {
    heatmap_png_scaled(path, title, rows, cols, cells, marks, legend, HeatScale::Margin)
}

/// How a heat map colours its cells.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HeatScale {
    /// A margin to a limit (%; [`margin_colour`]), the colour bar -100..100 %.
    Margin,
    /// A change (%; [`change_colour`]): blue a fall, white none, red a rise, full colour at
    /// +-`span_pct`; None drawn black ("failed").
    Change {
        /// The change of full colour (%).
        span_pct: f64,
    },
}

impl HeatScale {
    fn colour(self, v: Option<f64>) -> RGBColor {
        match self {
            Self::Margin => margin_colour(v),
            Self::Change { span_pct } => change_colour(v, span_pct),
        }
    }

    /// The colour bar's range and its ticks.
    fn bar(self) -> (f64, f64, Vec<f64>) {
        match self {
            Self::Margin => (-100.0, 100.0, vec![-100.0, -50.0, 0.0, 50.0, 100.0]),
            Self::Change { span_pct: s } => (-s, s, vec![-s, -s / 2.0, 0.0, s / 2.0, s]),
        }
    }
}

/// The colour of a change (%): blue at -`span_pct` and below, white at 0, red at +`span_pct`
/// and above; None black.
pub fn change_colour(change_pct: Option<f64>, span_pct: f64) -> RGBColor {
    let lerp = |a: (u8, u8, u8), b: (u8, u8, u8), f: f64| {
        let m = |x: u8, y: u8| (x as f64 + (y as f64 - x as f64) * f.clamp(0.0, 1.0)).round() as u8;
        RGBColor(m(a.0, b.0), m(a.1, b.1), m(a.2, b.2))
    };
    let (blue, white, red) = ((40, 90, 200), (255, 255, 255), (200, 40, 40));
    match change_pct {
        None => RGBColor(0, 0, 0),
        Some(c) if c < 0.0 => lerp(white, blue, -c / span_pct.max(1e-9)),
        Some(c) => lerp(white, red, c / span_pct.max(1e-9)),
    }
}

/// [`heatmap_png`] with the cells coloured by `scale`.
#[allow(clippy::too_many_arguments)] // the heat map's parts, as heatmap_png's
pub fn heatmap_png_scaled(
    path: &Path,
    title: &str,
    rows: &[String],
    cols: &[String],
    cells: &[Vec<Option<f64>>],
    marks: &[Vec<bool>],
    legend: &str,
    scale: HeatScale,
) -> Result<()> {
    ensure_font();
    let lines: Vec<&str> = title.split("; ").collect();
    let (cell_w, cell_h, left) = (74i32, 22i32, 260i32);
    let top = 50 + 22 * lines.len() as i32;
    let w = (left + cell_w * cols.len().max(1) as i32 + 40) as u32;
    let h = (top + cell_h * rows.len().max(1) as i32 + 110) as u32;
    let mut buf = vec![0u8; (w * h * 3) as usize];
    let perr = |e: String| Error::Write { path: path.to_path_buf(), message: format!("plot: {e}") };
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| perr(e.to_string()))?;
        let font = |s: i32| ("sans-serif", s).into_font();
        let d = |e: DrawingAreaErrorKind<_>| perr(e.to_string());
        for (i, l) in lines.iter().enumerate() {
            root.draw_text(l, &font(17).color(&BLACK), (10, 10 + 22 * i as i32)).map_err(d)?;
        }
        for (c, label) in cols.iter().enumerate() {
            let x = left + c as i32 * cell_w + 6;
            root.draw_text(label, &font(13).color(&BLACK), (x, top - 20)).map_err(d)?;
        }
        for (r, label) in rows.iter().enumerate() {
            let y = top + r as i32 * cell_h;
            root.draw_text(label, &font(13).color(&BLACK), (10, y + 4)).map_err(d)?;
            for c in 0..cols.len() {
                let (x0, m) = (left + c as i32 * cell_w, cells[r][c]);
                let fill = scale.colour(m);
                root.draw(&Rectangle::new([(x0, y), (x0 + cell_w - 2, y + cell_h - 2)], fill.filled())).map_err(d)?;
                let text = match m {
                    None => "failed".to_string(),
                    Some(m) if matches!(scale, HeatScale::Change { .. }) => format!("{m:+.1}"),
                    Some(m) if marks[r][c] => format!("! {m:.0}"),
                    Some(m) => format!("{m:.0}"),
                };
                let dark = match scale {
                    HeatScale::Margin => m.is_none_or(|m| m < -60.0),
                    HeatScale::Change { span_pct } => m.is_none_or(|m| m.abs() > 0.6 * span_pct),
                };
                let ink = if dark { WHITE } else { BLACK };
                root.draw_text(&text, &font(12).color(&ink), (x0 + 8, y + 4)).map_err(d)?;
                if marks[r][c] {
                    root.draw(&Rectangle::new([(x0, y), (x0 + cell_w - 2, y + cell_h - 2)], BLACK.stroke_width(2)))
                        .map_err(d)?;
                }
            }
        }
        // The colour bar over the scale's range.
        let y = top + cell_h * rows.len() as i32 + 30;
        let bar_w = (w as i32 - left - 60).max(200);
        let (lo, hi, ticks) = scale.bar();
        for i in 0..bar_w {
            let m = lo + (hi - lo) * i as f64 / bar_w as f64;
            root.draw(&Rectangle::new([(left + i, y), (left + i + 1, y + 14)], scale.colour(Some(m)).filled()))
                .map_err(d)?;
        }
        for m in ticks {
            let x = left + ((m - lo) / (hi - lo) * bar_w as f64) as i32;
            root.draw_text(&format!("{m}"), &font(12).color(&BLACK), (x - 8, y + 18)).map_err(d)?;
        }
        root.draw_text(legend, &font(13).color(&BLACK), (10, y + 40)).map_err(d)?;
        root.present().map_err(|e| perr(e.to_string()))?;
    }
    let img = image_png(&buf, w, h).map_err(perr)?;
    write_atomic(path, &img)
}
