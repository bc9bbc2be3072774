//! SVG plot of a render's trace: hammer height and contact-point displacement
//! (top), total energy (bottom), contact intervals shaded.

use anyhow::{anyhow, Result};
use modal_contact::render::TraceRow;
use plotters::prelude::*;
use std::path::Path;

/// Most points drawn per series; longer traces are decimated by min/max per
/// bucket so spikes stay visible.
const MAX_POINTS: usize = 4000;

fn decimate(xs: &[(f64, f64)]) -> Vec<(f64, f64)> {
    if xs.len() <= MAX_POINTS {
        return xs.to_vec();
    }
    let bucket = xs.len().div_ceil(MAX_POINTS / 2);
    let mut out = Vec::with_capacity(MAX_POINTS + 2);
    for chunk in xs.chunks(bucket) {
        let (mut lo, mut hi) = (chunk[0], chunk[0]);
        for p in chunk {
            if p.1 < lo.1 {
                lo = *p;
            }
            if p.1 > hi.1 {
                hi = *p;
            }
        }
        if lo.0 <= hi.0 {
            out.push(lo);
            out.push(hi);
        } else {
            out.push(hi);
            out.push(lo);
        }
    }
    out
}

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

/// Write the plot to `path` (SVG).
pub fn plot_trace(rows: &[TraceRow], title: &str, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (1100, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let (top, bottom) = root.split_vertically(420);
    let t_end = rows.last().map_or(1.0, |r| r.t);
    let xh: Vec<(f64, f64)> = rows.iter().map(|r| (r.t, r.obs.x_hammer)).collect();
    let xc: Vec<(f64, f64)> = rows.iter().map(|r| (r.t, r.obs.x_contact)).collect();
    let en: Vec<(f64, f64)> = rows.iter().map(|r| (r.t, r.obs.energy)).collect();
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
    // contact intervals
    let mut start = None;
    for r in rows {
        match (start, r.obs.in_contact) {
            (None, true) => start = Some(r.t),
            (Some(s), false) => {
                ch.draw_series(std::iter::once(Rectangle::new(
                    [(s, ylo), (r.t, yhi)],
                    RGBColor(255, 200, 200).mix(0.5).filled(),
                )))
                .map_err(|e| anyhow!("{e}"))?;
                start = None;
            }
            _ => {}
        }
    }
    ch.draw_series(LineSeries::new(decimate(&xh), &BLUE))
        .map_err(|e| anyhow!("{e}"))?
        .label("hammer height x_hammer")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    ch.draw_series(LineSeries::new(decimate(&xc), &RED))
        .map_err(|e| anyhow!("{e}"))?
        .label("contact point x_contact (shaded: in contact)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    ch.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;

    let (elo, ehi) = range(en.iter().map(|p| p.1));
    let mut ce = ChartBuilder::on(&bottom)
        .caption("total energy [J]", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..t_end, elo..ehi)
        .map_err(|e| anyhow!("{e}"))?;
    ce.configure_mesh()
        .x_desc("t [s]")
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    ce.draw_series(LineSeries::new(decimate(&en), &BLACK))
        .map_err(|e| anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}
