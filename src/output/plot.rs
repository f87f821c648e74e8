//! Plots with plotters' bitmap backend and an embedded font (no system fonts needed).

use super::write_atomic;
use crate::error::{Error, Result};
use crate::sim::Record;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

/// Register the embedded DejaVu Sans font under the family name "sans-serif".
fn ensure_font() {
    FONT.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// One panel: several named series over a shared time axis.
pub struct Panel<'a> {
    /// Y-axis label with unit.
    pub y_label: &'a str,
    /// (legend, values, colour).
    pub series: Vec<(&'a str, &'a [f64], RGBColor)>,
}

fn range(panel: &Panel) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (_, v, _) in &panel.series {
        for x in v.iter() {
            lo = lo.min(*x);
            hi = hi.max(*x);
        }
    }
    if !lo.is_finite() || !hi.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-12 * hi.abs().max(1.0));
    (lo - pad, hi + pad)
}

/// Draw stacked panels sharing the time axis into a PNG at `path` (atomic write).
pub fn stacked_png(path: &Path, title: &str, t_s: &[f64], panels: &[Panel]) -> Result<()> {
    ensure_font();
    let (w, h) = (1200u32, 300 * panels.len() as u32 + 60);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    let perr = |e: String| Error::Write { path: path.to_path_buf(), message: format!("plot: {e}") };
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| perr(e.to_string()))?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(|e| perr(e.to_string()))?;
        let areas = root.split_evenly((panels.len(), 1));
        let (t0, t1) = (t_s.first().copied().unwrap_or(0.0), t_s.last().copied().unwrap_or(1.0).max(1e-9));
        for (area, p) in areas.iter().zip(panels) {
            let (lo, hi) = range(p);
            let mut chart = ChartBuilder::on(area)
                .margin(8)
                .x_label_area_size(36)
                .y_label_area_size(80)
                .build_cartesian_2d(t0..t1, lo..hi)
                .map_err(|e| perr(e.to_string()))?;
            chart
                .configure_mesh()
                .x_desc("time (s)")
                .y_desc(p.y_label)
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(|e| perr(e.to_string()))?;
            for (name, v, c) in &p.series {
                let c = *c;
                chart
                    .draw_series(LineSeries::new(t_s.iter().copied().zip(v.iter().copied()), c.stroke_width(2)))
                    .map_err(|e| perr(e.to_string()))?
                    .label(*name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
            }
            draw_legend(&mut chart).map_err(perr)?;
        }
        root.present().map_err(|e| perr(e.to_string()))?;
    }
    let img = image_png(&buf, w, h).map_err(perr)?;
    write_atomic(path, &img)
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

/// The paper's Figure 5 layout: reference vs load force, tracking error, control input.
pub fn force_tracking_png(path: &Path, r: &Record, title: &str) -> Result<()> {
    stacked_png(
        path,
        title,
        &r.t_s,
        &[
            Panel {
                y_label: "force (N)",
                series: vec![("F_d desired", &r.ref_force_n, BLACK), ("F_L load", &r.load_force_n, BLUE)],
            },
            Panel { y_label: "error F_L - F_d (N)", series: vec![("tracking error", &r.force_error_n, RED)] },
            Panel { y_label: "valve command u", series: vec![("u", &r.valve_command, RGBColor(0, 128, 0))] },
        ],
    )
}

/// Gait runs: desired vs actual knee angle, desired vs load force, and both errors.
pub fn knee_tracking_png(path: &Path, r: &Record, title: &str) -> Result<()> {
    let q = r.extra_column("knee_angle_deg").unwrap_or(&[]);
    let qe: Vec<f64> = crate::metrics::knee_error_deg(r).unwrap_or_default();
    stacked_png(
        path,
        title,
        &r.t_s,
        &[
            Panel {
                y_label: "knee flexion (deg)",
                series: vec![("desired", &r.ref_knee_deg, BLACK), ("actual", q, BLUE)],
            },
            Panel { y_label: "knee error (deg)", series: vec![("actual - desired", &qe, RED)] },
            Panel {
                y_label: "cylinder force (N)",
                series: vec![("F_d desired", &r.ref_force_n, BLACK), ("F_L load", &r.load_force_n, BLUE)],
            },
            Panel { y_label: "force error (N)", series: vec![("F_L - F_d", &r.force_error_n, RED)] },
        ],
    )
}

/// Histograms of sweep results, one panel per metric, with the criterion limit marked.
pub fn histograms_png(path: &Path, title: &str, panels: &[(&str, Vec<f64>, Option<f64>)]) -> Result<()> {
    ensure_font();
    let (w, h) = (1000u32, 280 * panels.len().max(1) as u32 + 60);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    let perr = |e: String| Error::Write { path: path.to_path_buf(), message: format!("plot: {e}") };
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| perr(e.to_string()))?;
        let root = root.titled(title, ("sans-serif", 20)).map_err(|e| perr(e.to_string()))?;
        for (area, (label, vals, limit)) in root.split_evenly((panels.len().max(1), 1)).iter().zip(panels) {
            let lo = vals.iter().copied().fold(f64::INFINITY, f64::min).min(limit.unwrap_or(f64::INFINITY));
            let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max).max(limit.unwrap_or(f64::NEG_INFINITY));
            let (lo, hi) = match (lo.is_finite(), hi.is_finite()) {
                (true, true) if hi > lo => (lo, hi),
                (true, _) => (lo - 0.5, lo + 0.5),
                _ => (0.0, 1.0), // no finished run and no limit: an empty panel
            };
            let bins = 20usize;
            let width = (hi - lo) / bins as f64;
            let mut counts = vec![0u32; bins];
            for v in vals {
                let i = (((v - lo) / width) as usize).min(bins - 1);
                counts[i] += 1;
            }
            let top = counts.iter().copied().max().unwrap_or(1).max(1) as f64 * 1.1;
            let mut chart = ChartBuilder::on(area)
                .margin(8)
                .x_label_area_size(36)
                .y_label_area_size(50)
                .build_cartesian_2d(lo..hi + 1e-12, 0.0..top)
                .map_err(|e| perr(e.to_string()))?;
            chart
                .configure_mesh()
                .x_desc(*label)
                .y_desc("runs")
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(|e| perr(e.to_string()))?;
            chart
                .draw_series(counts.iter().enumerate().map(|(i, c)| {
                    let x0 = lo + i as f64 * width;
                    Rectangle::new([(x0, 0.0), (x0 + width, *c as f64)], BLUE.mix(0.6).filled())
                }))
                .map_err(|e| perr(e.to_string()))?;
            if let Some(l) = limit {
                chart
                    .draw_series(LineSeries::new(vec![(*l, 0.0), (*l, top)], RED.stroke_width(3)))
                    .map_err(|e| perr(e.to_string()))?
                    .label("criterion limit")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(3)));
                draw_legend(&mut chart).map_err(perr)?;
            }
        }
        root.present().map_err(|e| perr(e.to_string()))?;
    }
    let img = image_png(&buf, w, h).map_err(perr)?;
    write_atomic(path, &img)
}
