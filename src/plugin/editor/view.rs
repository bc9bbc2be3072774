//! Drawing the live view and the spectrum with egui's painter.

use super::super::live::{LiveHistory, VoiceHistory, DECIMATION};
use super::super::user_scene::{CompileReport, NoSpectrum};
use egui::{self, pos2, Color32, Rect, Sense, Shape, Stroke};

/// A colour per voice (repeats every eight).
fn voice_colour(v: usize) -> Color32 {
    const C: [(u8, u8, u8); 8] = [
        (90, 170, 255),
        (255, 170, 60),
        (120, 220, 120),
        (240, 100, 160),
        (200, 200, 90),
        (150, 130, 255),
        (90, 220, 220),
        (255, 120, 90),
    ];
    let (r, g, b) = C[v % C.len()];
    Color32::from_rgb(r, g, b)
}

/// `C4` for 60.
pub(super) fn note_name(key: u8) -> String {
    const N: [&str; 12] = [
        "C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B",
    ];
    format!("{}{}", N[usize::from(key % 12)], i32::from(key / 12) - 1)
}

fn frame(ui: &mut egui::Ui, height: f32, title: &str) -> (Rect, egui::Painter) {
    ui.label(egui::RichText::new(title).strong());
    let w = ui.available_width();
    let (resp, painter) = ui.allocate_painter(egui::vec2(w, height), Sense::hover());
    painter.rect_filled(resp.rect, 4.0, Color32::from_gray(24));
    (resp.rect.shrink(4.0), painter)
}

/// Hammer height and contact-point displacement of every sounding voice
/// over the last 100 ms (contact intervals shaded), and the energy on a log
/// scale.
pub(super) fn live_view(ui: &mut egui::Ui, h: &LiveHistory, rate_hz: f64, dropped: u64) {
    let span = LiveHistory::span_groups(rate_hz) as f64;
    let now = h.now_group as f64;
    let x_of = |g: u64, r: &Rect| r.right() - ((now - g as f64) / span) as f32 * r.width();
    let voices: Vec<_> = h.sounding().collect();
    motion_view(ui, &voices, &x_of, dropped);
    energy_view(ui, &voices, &x_of);
}

/// The hammer and contact-point traces of `voices` (`x_of`: a group's
/// abscissa in a rectangle), their contact intervals shaded.
fn motion_view(
    ui: &mut egui::Ui,
    voices: &[(usize, &VoiceHistory)],
    x_of: &impl Fn(u64, &Rect) -> f32,
    dropped: u64,
) {
    // common vertical scale: the contact points' largest excursion (a
    // hammer that flies off after its bounce leaves the picture)
    let mut m: f32 = 1e-9;
    for (_, v) in voices {
        for p in &v.points {
            m = m.max(p.2.abs());
        }
    }
    m *= 1.5;
    let (r, painter) = frame(
        ui,
        170.0,
        "Hammer (thin) and contact point (thick), last 100 ms",
    );
    let painter = painter.with_clip_rect(r);
    let y_of = |x: f32| r.center().y - x / m * 0.45 * r.height();
    painter.line_segment(
        [pos2(r.left(), y_of(0.0)), pos2(r.right(), y_of(0.0))],
        Stroke::new(1.0, Color32::from_gray(70)),
    );
    for (vi, v) in voices {
        let c = voice_colour(*vi);
        contact_bands(&painter, v, x_of, r, c);
        let hammer: Vec<_> = v
            .points
            .iter()
            .map(|p| pos2(x_of(p.0, &r), y_of(p.1)))
            .collect();
        let contact: Vec<_> = v
            .points
            .iter()
            .map(|p| pos2(x_of(p.0, &r), y_of(p.2)))
            .collect();
        painter.add(Shape::line(hammer, Stroke::new(1.0, c.gamma_multiply(0.8))));
        painter.add(Shape::line(contact, Stroke::new(2.0, c)));
        if let Some(p) = v.points.back() {
            painter.text(
                pos2(r.right() - 4.0, y_of(p.2)),
                egui::Align2::RIGHT_BOTTOM,
                note_name(v.key),
                egui::FontId::proportional(11.0),
                c,
            );
        }
    }
    painter.text(
        r.left_top(),
        egui::Align2::LEFT_TOP,
        format!(
            "{:.4} mm full scale, {} voices, 1 point per {DECIMATION} samples{}",
            m * 1e3,
            voices.len(),
            if dropped > 0 {
                format!(", {dropped} frames dropped")
            } else {
                String::new()
            }
        ),
        egui::FontId::proportional(11.0),
        Color32::from_gray(160),
    );
}

/// Voice `v`'s contact intervals in `r`: one band of colour `c` per run
/// of points in contact.
fn contact_bands(
    painter: &egui::Painter,
    v: &VoiceHistory,
    x_of: &impl Fn(u64, &Rect) -> f32,
    r: Rect,
    c: Color32,
) {
    let mut run: Option<u64> = None;
    let mut last = 0;
    for p in v
        .points
        .iter()
        .chain(std::iter::once(&(u64::MAX, 0.0, 0.0, false)))
    {
        match (run, p.3) {
            (None, true) => run = Some(p.0),
            (Some(a), false) => {
                let b = last + 1;
                let band =
                    Rect::from_x_y_ranges(x_of(a, &r)..=x_of(b, &r).min(r.right()), r.y_range());
                painter.rect_filled(band, 0.0, c.gamma_multiply(0.25));
                run = None;
            }
            _ => {}
        }
        last = p.0;
    }
}

/// The energy of `voices`, log scale: 90 dB below the largest shown.
fn energy_view(
    ui: &mut egui::Ui,
    voices: &[(usize, &VoiceHistory)],
    x_of: &impl Fn(u64, &Rect) -> f32,
) {
    let (r, painter) = frame(ui, 110.0, "Energy (log scale, 90 dB)");
    let e_max = voices
        .iter()
        .flat_map(|(_, v)| v.energy.iter().map(|e| e.1))
        .filter(|e| e.is_finite())
        .fold(1e-30f64, f64::max);
    let top = e_max.log10();
    let y_of = |e: f64| {
        let d = ((top - e.max(1e-300).log10()) / 9.0).clamp(0.0, 1.0);
        r.top() + d as f32 * r.height()
    };
    for (vi, v) in voices {
        let pts: Vec<_> = v
            .energy
            .iter()
            .map(|e| pos2(x_of(e.0, &r), y_of(e.1)))
            .collect();
        painter.add(Shape::line(pts, Stroke::new(1.5, voice_colour(*vi))));
    }
    painter.text(
        r.left_top(),
        egui::Align2::LEFT_TOP,
        if voices.is_empty() {
            "no voice sounding: play a pad or a note".to_string()
        } else {
            format!("top {e_max:.2e} J")
        },
        egui::FontId::proportional(11.0),
        Color32::from_gray(160),
    );
}

/// The struck object's modes at the root note: level against frequency
/// (log axes); kept modes in colour (a modal mallet's in orange), modes the
/// compiler leaves out in grey, modes above the output band in red. Without
/// modes, why: plainly for a lumped string or a wall, in red for an error.
pub(super) fn spectrum(ui: &mut egui::Ui, report: &CompileReport) {
    let (r, painter) = frame(
        ui,
        120.0,
        "Mode spectrum at the root note (level re the loudest)",
    );
    if report.spectrum.is_empty() {
        let (text, colour) = match &report.no_spectrum {
            Some(NoSpectrum::NoModes(why)) => (why.clone(), Color32::from_gray(150)),
            Some(NoSpectrum::Failed(e)) => {
                (format!("No spectrum: {e}"), Color32::from_rgb(240, 90, 80))
            }
            None => ("no scene compiled yet".to_string(), Color32::from_gray(150)),
        };
        painter.text(
            r.center(),
            egui::Align2::CENTER_CENTER,
            text,
            egui::FontId::proportional(12.0),
            colour,
        );
        return;
    }
    let (f_lo, f_hi) = (20f64.log10(), (report.rate_hz.max(1000.0)).log10());
    let x_of = |f: f64| {
        r.left() + ((f.max(1.0).log10() - f_lo) / (f_hi - f_lo)).clamp(0.0, 1.0) as f32 * r.width()
    };
    let y_of = |lvl: f64| {
        let db = 20.0 * lvl.max(1e-6).log10();
        r.top() + (-db / 80.0).clamp(0.0, 1.0) as f32 * r.height()
    };
    let nyq = x_of(report.rate_hz / 2.0);
    painter.line_segment(
        [pos2(nyq, r.top()), pos2(nyq, r.bottom())],
        Stroke::new(1.0, Color32::from_rgb(160, 60, 60)),
    );
    let (mut kept, mut mallet) = (0, 0);
    for m in &report.spectrum {
        let colour = if m.pruned.is_some() {
            Color32::from_gray(110)
        } else if m.out_of_band {
            Color32::from_rgb(220, 80, 80)
        } else if m.mallet {
            mallet += 1;
            Color32::from_rgb(240, 170, 70)
        } else {
            kept += 1;
            Color32::from_rgb(110, 200, 255)
        };
        let x = x_of(m.freq_hz);
        painter.line_segment(
            [pos2(x, r.bottom()), pos2(x, y_of(m.level))],
            Stroke::new(2.0, colour),
        );
    }
    painter.text(
        r.left_top(),
        egui::Align2::LEFT_TOP,
        format!(
            "{kept} modes heard{}, {} left out (grey), {} above the band (red); 20 Hz .. {:.0} kHz, 0 .. -80 dB",
            if mallet > 0 {
                format!(" and {mallet} of the mallet (orange)")
            } else {
                String::new()
            },
            report.spectrum.iter().filter(|m| m.pruned.is_some()).count(),
            report.spectrum.iter().filter(|m| m.pruned.is_none() && m.out_of_band).count(),
            report.rate_hz / 1000.0
        ),
        egui::FontId::proportional(11.0),
        Color32::from_gray(170),
    );
}

/// A driven scene's path: the profile the contact follows (each column
/// from its lowest to its highest height, scaled to the frame), and where
/// each sounding voice is on it (a line in the voice's colour).
pub(super) fn path_view(ui: &mut egui::Ui, report: &CompileReport, h: &LiveHistory) {
    let Some(path) = &report.path else {
        return;
    };
    let (r, painter) = frame(
        ui,
        70.0,
        &format!(
            "Path: the surface under the contact, 0 .. {:.0} mm{}",
            1e3 * path.length_m,
            if path.periodic { " (wraps)" } else { "" }
        ),
    );
    let (lo, hi) = path
        .columns
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &(l, u)| {
            (a.min(l), b.max(u))
        });
    if !(hi > lo) || path.columns.is_empty() {
        return;
    }
    let y_of = |v: f32| r.bottom() - (v - lo) / (hi - lo) * r.height();
    let w = r.width() / path.columns.len() as f32;
    for (c, &(l, u)) in path.columns.iter().enumerate() {
        let x = r.left() + (c as f32 + 0.5) * w;
        painter.line_segment(
            [pos2(x, y_of(l)), pos2(x, y_of(u) - 0.5)],
            Stroke::new(w.max(1.0), Color32::from_gray(150)),
        );
    }
    for (v, vh) in h.sounding() {
        let Some(at) = vh.path_m else { continue };
        let len = path.length_m as f32;
        let at = if path.periodic {
            at.rem_euclid(len)
        } else {
            at.clamp(0.0, len)
        };
        let x = r.left() + at / len * r.width();
        painter.line_segment(
            [pos2(x, r.top()), pos2(x, r.bottom())],
            Stroke::new(2.0, voice_colour(v)),
        );
    }
}

/// The last import of a recording ("Import recording..."): while it runs,
/// the file's name; when done, the recording's spectrum (grey) with the
/// fitted modes' (orange) over it and the modes as ticks, 20 Hz to Nyquist,
/// 0 to -80 dB re the recording's largest; when refused, why. Returns
/// whether the user closed it.
pub(super) fn import_view(ui: &mut egui::Ui, im: &super::ImportView) -> bool {
    use super::ImportView;
    let closed = ui
        .horizontal(|ui| {
            let title = match im {
                ImportView::Running(name) => format!("Importing {name}\u{2026}"),
                ImportView::Done(a) => format!("Imported {} as {}", a.name, a.path.display()),
                ImportView::Failed(_) => "Import refused".to_string(),
            };
            ui.label(egui::RichText::new(title).strong());
            !matches!(im, ImportView::Running(_)) && ui.small_button("close").clicked()
        })
        .inner;
    let a = match im {
        ImportView::Running(_) => return closed,
        ImportView::Failed(e) => {
            ui.colored_label(Color32::from_rgb(240, 90, 80), e);
            return closed;
        }
        ImportView::Done(a) => a,
    };
    ui.label(egui::RichText::new(&a.summary).small());
    let (r, painter) = frame(
        ui,
        120.0,
        "Recording (grey) and fitted modes (orange), first 0.5 s",
    );
    let s = &a.spectrum;
    let (Some(&lo), Some(&hi)) = (s.freqs_hz.first(), s.freqs_hz.last()) else {
        return closed;
    };
    let (f_lo, f_hi) = (lo.log10(), hi.log10().max(lo.log10() + 1e-3));
    let x_of = |f: f64| {
        r.left() + ((f.max(1.0).log10() - f_lo) / (f_hi - f_lo)).clamp(0.0, 1.0) as f32 * r.width()
    };
    let y_of = |db: f64| r.top() + (-db / 80.0).clamp(0.0, 1.0) as f32 * r.height();
    for &(f, db) in &s.modes {
        let x = x_of(f);
        painter.line_segment(
            [
                pos2(x, r.bottom()),
                pos2(
                    x,
                    r.bottom() - 6.0 - (1.0 + db / 80.0).clamp(0.0, 1.0) as f32 * 10.0,
                ),
            ],
            Stroke::new(1.0, Color32::from_rgb(240, 170, 70)),
        );
    }
    for (levels, colour, width) in [
        (&s.recording_db, Color32::from_gray(170), 1.5),
        (&s.fit_db, Color32::from_rgb(240, 170, 70), 1.0),
    ] {
        let points = s
            .freqs_hz
            .iter()
            .zip(levels.iter())
            .map(|(&f, &db)| pos2(x_of(f), y_of(db)))
            .collect();
        painter.add(Shape::line(points, Stroke::new(width, colour)));
    }
    closed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn note_names() {
        assert_eq!(note_name(60), "C4");
        assert_eq!(note_name(57), "A3");
        assert_eq!(note_name(0), "C-1");
    }
}
