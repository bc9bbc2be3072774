//! Every SVG plot of the project's tools, with plotters: the trace of a
//! render (`cargo xtask render --plot`: hammer height and contact-point
//! displacement on top, total energy below, contact intervals shaded; drawn
//! from the render's min/max envelope) and
//! the report's work-precision diagrams (`cargo xtask report`: error
//! against CPU time per second of audio, log-log, one polyline per method
//! through its oversampling factors, the exact engine's approximation
//! settings as labelled triangles).

use crate::report::accuracy::{Row, SceneResult, APPROX_SERIES};
use anyhow::{anyhow, Result};
use modal_contact::render::{EnvelopeBucket, TraceEnvelope};
use plotters::prelude::*;
use std::path::Path;

// ------------------------------------------------------------ render trace

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-12);
    (lo - pad, hi + pad)
}

/// A min/max series through the buckets: per bucket the smaller value at
/// its start time and the larger at its end, so spikes stay visible.
fn min_max_series(
    env: &TraceEnvelope,
    pick: impl Fn(&EnvelopeBucket) -> [f64; 2],
) -> Vec<(f64, f64)> {
    let t = |i: usize| i as f64 / env.rate_hz;
    env.buckets
        .iter()
        .flat_map(|b| {
            let [lo, hi] = pick(b);
            let end = (b.start + b.len.max(1) - 1).max(b.start);
            [(t(b.start), lo), (t(end), hi)]
        })
        .collect()
}

/// Draw the render's plot from its envelope (at most
/// [`modal_contact::render::ENVELOPE_BUCKETS`] buckets, whatever the
/// length) to `path` (SVG).
pub fn plot_envelope(env: &TraceEnvelope, title: &str, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (1100, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let (top, bottom) = root.split_vertically(420);
    let t = |i: usize| i as f64 / env.rate_hz;
    let t_end = t(env.samples.saturating_sub(1)).max(1.0 / env.rate_hz);
    let xh = min_max_series(env, |b| b.x_hammer);
    let xc = min_max_series(env, |b| b.x_contact);
    let (ylo, yhi) = range(xh.iter().chain(&xc).map(|p| p.1));
    let mut ch = ChartBuilder::on(&top)
        .caption(
            format!("{title}: hammer height and contact-point displacement [m]"),
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..t_end, ylo..yhi)
        .map_err(|e| anyhow!("{e}"))?;
    ch.configure_mesh()
        .x_desc("t [s]")
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    // contact intervals: runs of buckets that hold a contact sample
    let mut start = None;
    let mut spans = Vec::new();
    for b in &env.buckets {
        match (start, b.in_contact) {
            (None, true) => start = Some(t(b.start)),
            (Some(s), false) => {
                spans.push((s, t(b.start)));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        spans.push((s, t_end));
    }
    ch.draw_series(spans.into_iter().map(|(s, e)| {
        Rectangle::new(
            [(s, ylo), (e, yhi)],
            RGBColor(255, 200, 200).mix(0.5).filled(),
        )
    }))
    .map_err(|e| anyhow!("{e}"))?;
    ch.draw_series(LineSeries::new(xh, &BLUE))
        .map_err(|e| anyhow!("{e}"))?
        .label("hammer height x_hammer")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    ch.draw_series(LineSeries::new(xc, &RED))
        .map_err(|e| anyhow!("{e}"))?
        .label("contact point x_contact (shaded: in contact)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    ch.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;

    let en: Vec<(f64, f64)> = std::iter::once((0.0, env.energy_start))
        .chain(
            env.buckets
                .iter()
                .map(|b| (t(b.start + b.len.max(1) - 1), b.energy_end)),
        )
        .collect();
    let (elo, ehi) = range(en.iter().map(|p| p.1));
    let mut ce = ChartBuilder::on(&bottom)
        .caption("total energy [J] (at bucket ends)", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..t_end, elo..ehi)
        .map_err(|e| anyhow!("{e}"))?;
    ce.configure_mesh()
        .x_desc("t [s]")
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    ce.draw_series(LineSeries::new(en, &BLACK))
        .map_err(|e| anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

// ---------------------------------------------------- work-precision diagram

const COLORS: [RGBColor; 6] = [
    RGBColor(0, 0, 0),
    RGBColor(120, 120, 120),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
];

/// Colour of the approximation settings (not used by any method).
const SETTINGS_COLOR: RGBColor = RGBColor(255, 127, 14);

/// The error a plot shows for a row: pickup velocity over the window, or the
/// hammer trajectory when the scene has no pickup signal.
fn metric(res: &SceneResult, r: &Row) -> Option<f64> {
    if res.has_pickup {
        r.pick_full
    } else {
        r.hammer
    }
}

/// How a series is drawn.
#[derive(Clone, Copy, PartialEq)]
enum Style {
    /// An integrator through its oversampling factors: polyline and dots,
    /// each dot labelled with its factor when there are several.
    Method,
    /// Independent settings of one method (the approximations): triangles,
    /// each labelled with its setting, no line.
    Settings,
}

/// One plotted series: name, points `(cpu s/s, error, label)`, style, and
/// the rows that could not be drawn on log axes.
struct Series {
    name: String,
    pts: Vec<(f64, f64, String)>,
    style: Style,
    /// Rows that diverged.
    diverged: usize,
    /// Other rows without a positive finite error and time (e.g. error 0).
    undrawable: usize,
}

impl Series {
    /// The drawable points of some rows.
    fn new<'a>(
        res: &SceneResult,
        name: &str,
        style: Style,
        rows: impl Iterator<Item = (&'a Row, String)>,
    ) -> Self {
        let mut s = Series {
            name: name.to_string(),
            pts: Vec::new(),
            style,
            diverged: 0,
            undrawable: 0,
        };
        for (r, label) in rows {
            if r.diverged {
                s.diverged += 1;
                continue;
            }
            match metric(res, r) {
                Some(y) if y.is_finite() && y > 0.0 && r.cpu_per_s > 0.0 => {
                    s.pts.push((r.cpu_per_s, y, label));
                }
                _ => s.undrawable += 1,
            }
        }
        s
    }

    fn legend(&self) -> String {
        let mut notes = Vec::new();
        if self.diverged > 0 {
            notes.push(format!("{} not shown: diverged", self.diverged));
        }
        if self.undrawable > 0 {
            notes.push(format!("{} not shown: error 0 or n/a", self.undrawable));
        }
        if notes.is_empty() {
            self.name.clone()
        } else {
            format!("{} ({})", self.name, notes.join("; "))
        }
    }
}

/// Write the work-precision diagram of one accuracy scene of the report.
pub fn plot_work_precision(res: &SceneResult, path: &Path) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<_>| anyhow!("plot {}: {e:?}", path.display());
    let series = work_precision_series(res);
    let (x0, x1, y0, y1) = axis_ranges(&series);

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
    for (i, sr) in series.iter().enumerate() {
        let color = match sr.style {
            Style::Method => COLORS[i % COLORS.len()],
            Style::Settings => SETTINGS_COLOR,
        };
        let label = sr.legend();
        let xy = || sr.pts.iter().map(|(x, y, _)| (*x, *y));
        match sr.style {
            Style::Method => {
                chart
                    .draw_series(LineSeries::new(xy(), color.stroke_width(2)))
                    .map_err(e)?
                    .label(label)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
                chart
                    .draw_series(xy().map(|p| Circle::new(p, 4, color.filled())))
                    .map_err(e)?;
            }
            Style::Settings => {
                chart
                    .draw_series(xy().map(|p| TriangleMarker::new(p, 6, color.filled())))
                    .map_err(e)?
                    .label(label)
                    .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 6, color.filled()));
            }
        }
        // label the oversampling factor (method with several points) next to
        // each point, or the setting beside its triangle without overlaps
        match sr.style {
            Style::Method if sr.pts.len() > 1 => {
                chart
                    .draw_series(sr.pts.iter().map(|(x, y, l)| {
                        Text::new(l.clone(), (*x, *y), ("sans-serif", 11).into_font())
                    }))
                    .map_err(e)?;
            }
            Style::Method => {}
            Style::Settings => {
                let px: Vec<(i32, i32, usize)> = sr
                    .pts
                    .iter()
                    .map(|(x, y, l)| {
                        let (u, v) = chart.backend_coord(&(*x, *y));
                        (u, v, l.chars().count())
                    })
                    .collect();
                let offsets = place_labels(&px);
                chart
                    .draw_series(sr.pts.iter().zip(offsets).map(|((x, y, l), off)| {
                        EmptyElement::at((*x, *y))
                            + Text::new(l.clone(), off, ("sans-serif", 11).into_font())
                    }))
                    .map_err(e)?;
            }
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

/// The work-precision diagram's series: one per method (a point per
/// oversampling), and the approximation settings if any.
fn work_precision_series(res: &SceneResult) -> Vec<Series> {
    let mut methods: Vec<String> = Vec::new();
    for r in &res.rows {
        if !methods.contains(&r.method) {
            methods.push(r.method.clone());
        }
    }
    // points per method: (cpu s/s, error), finite and positive only
    let mut series: Vec<Series> = methods
        .iter()
        .map(|m| {
            let rows = res.rows.iter().filter(|r| &r.method == m);
            Series::new(res, m, Style::Method, rows.map(|r| (r, r.os.to_string())))
        })
        .collect();
    if !res.approx.is_empty() {
        let rows = res.approx.iter().map(|a| (&a.row, a.label.clone()));
        series.push(Series::new(res, APPROX_SERIES, Style::Settings, rows));
    }
    series
}

/// The axes' ranges `(x0, x1, y0, y1)` of the work-precision diagram: the
/// points' with a margin (log scale), or a default without a point.
fn axis_ranges(series: &[Series]) -> (f64, f64, f64, f64) {
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.pts.iter().map(|(x, y, _)| (*x, *y)))
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
    (x0, x1, y0, y1)
}

/// Offsets (pixels, top-left corner of the text) for labels of `chars`
/// characters (11 px sans-serif) next to markers at pixel positions
/// `(u, v)`: the first of right, left, above, below, and the four diagonal
/// places whose box overlaps neither an earlier label nor any marker.
fn place_labels(px: &[(i32, i32, usize)]) -> Vec<(i32, i32)> {
    const CHAR_W: i32 = 6;
    const H: i32 = 12;
    const MARK: i32 = 7;
    type Rect = (i32, i32, i32, i32);
    let overlaps = |a: Rect, b: Rect| a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3;
    let mut taken: Vec<Rect> = px
        .iter()
        .map(|&(u, v, _)| (u - MARK, v - MARK, u + MARK, v + MARK))
        .collect();
    px.iter()
        .map(|&(u, v, n)| {
            let w = CHAR_W * n as i32;
            let candidates = [
                (MARK + 2, -H / 2),
                (-MARK - 2 - w, -H / 2),
                (-w / 2, -MARK - H - 1),
                (-w / 2, MARK + 1),
                (MARK, -MARK - H),
                (MARK, MARK),
                (-MARK - w, -MARK - H),
                (-MARK - w, MARK),
            ];
            let off = candidates
                .into_iter()
                .find(|&(dx, dy)| {
                    let r = (u + dx, v + dy, u + dx + w, v + dy + H);
                    !taken.iter().any(|&t| overlaps(r, t))
                })
                .unwrap_or(candidates[0]);
            taken.push((u + off.0, v + off.1, u + off.0 + w, v + off.1 + H));
            off
        })
        .collect()
}
