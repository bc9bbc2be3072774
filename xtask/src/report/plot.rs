//! Work-precision diagrams (SVG): error against CPU time per second of audio,
//! log-log, one polyline per method through its oversampling factors.

use super::accuracy::SceneResult;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

const COLORS: [RGBColor; 6] = [
    RGBColor(0, 0, 0),
    RGBColor(120, 120, 120),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
];

/// The error a plot shows for a row: pickup velocity over the window, or the
/// hammer trajectory when the scene has no pickup signal.
fn metric(res: &SceneResult, r: &super::accuracy::Row) -> Option<f64> {
    if res.has_pickup {
        r.pick_full
    } else {
        r.hammer
    }
}

/// A method's points `(cpu s/s, error, oversampling)` and how many of its
/// rows could not be drawn.
type Series = (String, Vec<(f64, f64, usize)>, usize);

/// Write the diagram of one scene.
pub fn plot_scene(res: &SceneResult, path: &Path) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<_>| anyhow!("plot {}: {e:?}", path.display());
    let mut methods: Vec<String> = Vec::new();
    for r in &res.rows {
        if !methods.contains(&r.method) {
            methods.push(r.method.clone());
        }
    }
    // points per method: (cpu s/s, error), finite and positive only
    let series: Vec<Series> = methods
        .iter()
        .map(|m| {
            let rows: Vec<_> = res.rows.iter().filter(|r| &r.method == m).collect();
            let pts: Vec<(f64, f64, usize)> = rows
                .iter()
                .filter(|r| !r.diverged)
                .filter_map(|r| {
                    let y = metric(res, r)?;
                    (y.is_finite() && y > 0.0 && r.cpu_per_s > 0.0).then_some((
                        r.cpu_per_s,
                        y,
                        r.os,
                    ))
                })
                .collect();
            let dropped = rows.len() - pts.len();
            (m.clone(), pts, dropped)
        })
        .collect();
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|(_, p, _)| p.iter().map(|(x, y, _)| (*x, *y)))
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in &all {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    if all.is_empty() {
        (x0, x1, y0, y1) = (1e-4, 1.0, 1e-12, 1.0);
    }
    let (x0, x1) = (x0 / 2.0, x1 * 2.0);
    let (y0, y1) = (y0 / 5.0, (y1 * 5.0).max(2.0));

    let root = SVGBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let what = if res.has_pickup {
        "relative L2 error of the pickup velocity"
    } else {
        "relative L2 error of the hammer height (no pickup)"
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: {what} vs CPU time", res.name),
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("CPU seconds per second of audio (median, stepping loop)")
        .y_desc("relative L2 error vs reference")
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(e)?;
    for (i, (name, pts, dropped)) in series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let label = if *dropped > 0 {
            format!("{name} ({dropped} not shown: diverged)")
        } else {
            name.clone()
        };
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|(x, y, _)| (*x, *y)),
                color.stroke_width(2),
            ))
            .map_err(e)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart
            .draw_series(
                pts.iter()
                    .map(|(x, y, _)| Circle::new((*x, *y), 4, color.filled())),
            )
            .map_err(e)?;
        // label the oversampling factor next to each competitor point
        if pts.len() > 1 {
            chart
                .draw_series(pts.iter().map(|(x, y, os)| {
                    Text::new(format!("{os}"), (*x, *y), ("sans-serif", 11).into_font())
                }))
                .map_err(e)?;
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}
