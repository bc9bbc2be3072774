//! The plots of `cargo xtask compare-real` (SVG, plotters, in the style of
//! `crate::plot`): the recording's and the render's spectra overlaid (dB
//! against log frequency) and their partials' T60 against frequency.

use super::analysis::{Spectrum, T60};
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

/// The recording's colour.
const REAL: RGBColor = RGBColor(31, 119, 180);
/// The render's colour.
const RENDER: RGBColor = RGBColor(214, 39, 40);

const F_LO: f64 = 20.0;
const F_HI: f64 = 20000.0;
const DB_LO: f64 = -100.0;

/// A spectrum on a log-frequency grid of `cells` cells from [`F_LO`] to
/// [`F_HI`], each the largest bin inside it (peaks stay visible), in dB
/// relative to the largest bin, floored at [`DB_LO`].
fn log_cells(s: &Spectrum, cells: usize) -> Vec<(f64, f64)> {
    let top = s.power.iter().copied().fold(0.0f64, f64::max).max(1e-300);
    let ratio = (F_HI / F_LO).ln();
    let mut out = Vec::with_capacity(cells);
    for c in 0..cells {
        let a = F_LO * (ratio * c as f64 / cells as f64).exp();
        let b = F_LO * (ratio * (c + 1) as f64 / cells as f64).exp();
        let (k0, k1) = ((a / s.df).ceil() as usize, (b / s.df).floor() as usize);
        let p = if k1 >= k0 && k0 < s.power.len() {
            s.power[k0..=k1.min(s.power.len() - 1)]
                .iter()
                .copied()
                .fold(0.0f64, f64::max)
        } else {
            // a cell narrower than a bin: the nearest bin
            s.power[(((a * b).sqrt() / s.df).round() as usize).min(s.power.len() - 1)]
        };
        out.push((
            (a * b).sqrt(),
            (10.0 * (p / top + 1e-300).log10()).max(DB_LO),
        ));
    }
    out
}

/// The recording's (`real`) and the render's spectra overlaid, the
/// recording's compared partials marked.
pub(crate) fn spectra(
    real: &Spectrum,
    render: &Spectrum,
    marks: &[f64],
    title: &str,
    path: &Path,
) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<_>| anyhow!("plot {}: {e:?}", path.display());
    let root = SVGBackend::new(path, (1000, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let mut ch = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d((F_LO..F_HI).log_scale(), DB_LO..5.0)
        .map_err(e)?;
    ch.configure_mesh()
        .x_desc("frequency [Hz]")
        .y_desc("energy per bin [dB re its largest]")
        .x_label_formatter(&|v| {
            if *v >= 1000.0 {
                format!("{}k", v / 1000.0)
            } else {
                format!("{v}")
            }
        })
        .draw()
        .map_err(e)?;
    ch.draw_series(LineSeries::new(log_cells(real, 900), REAL.stroke_width(1)))
        .map_err(e)?
        .label("recording (FluidR3)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], REAL.stroke_width(2)));
    ch.draw_series(LineSeries::new(
        log_cells(render, 900),
        RENDER.stroke_width(1),
    ))
    .map_err(e)?
    .label("render (preset)")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RENDER.stroke_width(2)));
    ch.draw_series(
        marks
            .iter()
            .filter(|f| (F_LO..F_HI).contains(*f))
            .map(|&f| TriangleMarker::new((f, 2.0), 5, REAL.filled())),
    )
    .map_err(e)?
    .label("the recording's strongest partials")
    .legend(|(x, y)| TriangleMarker::new((x + 10, y), 5, REAL.filled()));
    ch.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

/// T60 against frequency of the recording's (`real`) and the render's
/// strongest partials; partials without a fit are left out (counted in
/// the legend).
pub(crate) fn decays(
    real: &[(f64, T60)],
    render: &[(f64, T60)],
    title: &str,
    path: &Path,
) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<_>| anyhow!("plot {}: {e:?}", path.display());
    let pts = |d: &[(f64, T60)]| -> Vec<(f64, f64)> {
        d.iter()
            .filter_map(|(f, t)| t.seconds().map(|s| (*f, s)))
            .filter(|(f, s)| *f > F_LO && *f < F_HI && *s > 0.0 && s.is_finite())
            .collect()
    };
    let (pr, pg) = (pts(real), pts(render));
    let all: Vec<f64> = pr.iter().chain(&pg).map(|p| p.1).collect();
    let lo = all.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = all.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi) = if all.is_empty() {
        (0.01, 10.0)
    } else {
        (lo / 2.0, hi * 2.0)
    };
    let root = SVGBackend::new(path, (1000, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let mut ch = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((F_LO..F_HI).log_scale(), (lo..hi).log_scale())
        .map_err(e)?;
    ch.configure_mesh()
        .x_desc("partial frequency [Hz]")
        .y_desc("T60 [s]")
        .x_label_formatter(&|v| {
            if *v >= 1000.0 {
                format!("{}k", v / 1000.0)
            } else {
                format!("{v}")
            }
        })
        .y_label_formatter(&|v| format!("{v:.2}"))
        .draw()
        .map_err(e)?;
    let label = |what: &str, d: &[(f64, T60)], shown: usize| {
        let missing = d.len() - shown;
        if missing > 0 {
            format!("{what} ({missing} of {} partials without a fit)", d.len())
        } else {
            what.to_string()
        }
    };
    ch.draw_series(pr.iter().map(|&p| Circle::new(p, 5, REAL.filled())))
        .map_err(e)?
        .label(label("recording (FluidR3)", real, pr.len()))
        .legend(|(x, y)| Circle::new((x + 10, y), 5, REAL.filled()));
    ch.draw_series(
        pg.iter()
            .map(|&p| TriangleMarker::new(p, 6, RENDER.filled())),
    )
    .map_err(e)?
    .label(label("render (preset)", render, pg.len()))
    .legend(|(x, y)| TriangleMarker::new((x + 10, y), 6, RENDER.filled()));
    ch.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}
