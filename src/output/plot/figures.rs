//! The run's figures: force tracking (the paper's Figure 5 layout), knee tracking, what the
//! wearer gets, histograms.

use super::*;

/// The paper's Figure 5 layout: reference vs load force, tracking error, control input.
pub fn force_tracking_png(path: &Path, b: &PlotBuffer, title: &str) -> Result<()> {
    stacked_png(
        path,
        title,
        b.span(),
        &[
            Panel {
                y_label: "force (N)",
                series: vec![("F_d desired", b.points(REF_FORCE), BLACK), ("F_L load", b.points(LOAD_FORCE), BLUE)],
            },
            Panel { y_label: "error F_L - F_d (N)", series: vec![("tracking error", b.points(FORCE_ERROR), RED)] },
            Panel { y_label: "valve command u", series: vec![("u", b.points(VALVE), RGBColor(0, 128, 0))] },
        ],
        &[],
    )
}

/// Gait runs: desired vs actual knee angle, desired vs load force, and both errors; stance
/// shaded when the run has ground contact.
pub fn knee_tracking_png(path: &Path, b: &PlotBuffer, title: &str) -> Result<()> {
    stacked_png(
        path,
        title,
        b.span(),
        &[
            Panel {
                y_label: "knee flexion (deg)",
                series: vec![("desired", b.points(REF_KNEE), BLACK), ("actual", b.points(KNEE), BLUE)],
            },
            Panel { y_label: "knee error (deg)", series: vec![("actual - desired", b.points(KNEE_ERROR), RED)] },
            Panel {
                y_label: "cylinder force (N)",
                series: vec![("F_d desired", b.points(REF_FORCE), BLACK), ("F_L load", b.points(LOAD_FORCE), BLUE)],
            },
            Panel { y_label: "force error (N)", series: vec![("F_L - F_d", b.points(FORCE_ERROR), RED)] },
        ],
        &b.stance_intervals(),
    )
}

/// What the wearer got over the mean cycle: the device's knee moment against the
/// biological one, the cuff forces with the comfort limit, the knee angle; the data's stance
/// (0-62 %) shaded.
pub fn wearer_png(
    path: &Path,
    c: &crate::metrics::wearer::WearerCycle,
    muscles: Option<&crate::metrics::muscles::MuscleCycle>,
    comfort_n: f64,
    title: &str,
) -> Result<()> {
    let pts = |v: &[f64]| v.iter().enumerate().map(|(i, x)| (i as f64 + 0.5, *x)).collect::<Vec<_>>();
    let flat = |x: f64| vec![(0.0, x), (100.0, x)];
    let grey = RGBColor(128, 128, 128);
    let lanes = muscles.map(|m| Lanes {
        y_label: "activation (0..1; grey: Perry 1992 EMG on)",
        rows: m
            .names
            .iter()
            .zip(&m.activation)
            .map(|(n, a)| {
                let windows = crate::metrics::muscles::EMG_ON_WINDOWS
                    .iter()
                    .find(|(w, _)| w == n)
                    .map_or(Vec::new(), |(_, w)| w.to_vec());
                (n.as_str(), a.clone(), windows)
            })
            .collect(),
    });
    panels_with_lanes_png(
        path,
        title,
        "gait cycle (%, the data's clock)",
        (0.0, 100.0),
        &[
            Panel {
                y_label: "knee moment (N m, ext +)",
                series: vec![
                    ("biological (data)", pts(&c.biological_moment_nm), BLACK),
                    ("device", pts(&c.device_moment_nm), BLUE),
                    (
                        "wearer's remaining",
                        pts(&c
                            .biological_moment_nm
                            .iter()
                            .zip(&c.device_moment_nm)
                            .map(|(b, d)| b - d)
                            .collect::<Vec<_>>()),
                        RED,
                    ),
                ],
            },
            Panel {
                y_label: "cuff force (N)",
                series: vec![
                    ("thigh cuff", pts(&c.thigh_cuff_n), RGBColor(0, 128, 0)),
                    ("shank cuff", pts(&c.shank_cuff_n), RGBColor(200, 100, 0)),
                    ("comfort limit", flat(comfort_n), grey),
                    ("-comfort limit", flat(-comfort_n), grey),
                ],
            },
            Panel { y_label: "knee flexion (deg)", series: vec![("knee", pts(&c.knee_deg), BLUE)] },
        ],
        &[(0.0, 62.0)],
        lanes.as_ref(),
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
