//! Scene builders of the report: the accuracy scenes (NUMERICS.md section 3)
//! and the extreme cases of section 4.
//!
//! Every accuracy scene has exactly one pickup with `pan = -1`, so the
//! engine's left channel is the pickup times `gain * cos(0) = gain`, the same
//! signal the competitors produce (gain-weighted sum, pan ignored).

use anyhow::{anyhow, Context, Result};
use modal_contact::scene::Scene;
use std::f64::consts::PI;
use std::path::Path;

/// Output rate of every report run [Hz].
pub const RATE: f64 = 44_100.0;
/// Nyquist frequency at [`RATE`].
pub const NYQ: f64 = RATE / 2.0;

/// Parse a scene from TOML text.
pub fn parse(text: &str) -> Result<Scene> {
    Scene::from_toml_str(text).map_err(|e| anyhow!("{e}\n{text}"))
}

/// A preset with its pickups replaced by the first one, panned hard left.
pub fn preset_single_pickup(root: &Path, name: &str) -> Result<Scene> {
    let path = root.join("presets").join(format!("{name}.toml"));
    let mut sc = Scene::from_file(&path).with_context(|| format!("{}", path.display()))?;
    sc.pickup.truncate(1);
    let p = sc
        .pickup
        .first_mut()
        .ok_or_else(|| anyhow!("{name}: no pickup"))?;
    p.pan = -1.0;
    Ok(sc)
}

/// Options of [`modal_scene`].
#[derive(Debug, Clone, Copy)]
pub struct ModalOpts {
    /// Number of modes, geometric from `f_lo` to `f_hi` [Hz].
    pub n: usize,
    pub f_lo: f64,
    pub f_hi: f64,
    /// T60 falling from 2 s (low) to 0.1 s (top mode) when damped.
    pub damped: bool,
    /// Hammer mass [kg] (mode 0 has effective mass 1 kg at the contact).
    pub m_h: f64,
    /// Contact stiffness [N/m] and damping [N s/m].
    pub k: f64,
    pub c: f64,
    /// Gravity [m/s^2]; with gravity the hammer is dropped from 1 cm.
    pub g: f64,
    /// Initial height when there is no gravity (then v0 = -1 m/s).
    pub height: f64,
}

/// A modal object with `n` modes (mode 0: unit effective mass at the contact),
/// struck by a point-mass hammer; one velocity pickup, panned hard left.
pub fn modal_scene(name: &str, o: ModalOpts) -> Result<Scene> {
    let mut text = format!(
        "version = 1\nname = \"{name}\"\n[[object]]\nname = \"o\"\nkind = \"modal\"\npoints = [\"c\", \"p\"]\n"
    );
    for i in 0..o.n {
        let f = if o.n == 1 {
            o.f_lo
        } else {
            o.f_lo * (o.f_hi / o.f_lo).powf(i as f64 / (o.n - 1) as f64)
        };
        let w = 1.0 / (1.0 + 0.1 * i as f64).sqrt();
        let wp = if i % 2 == 0 { 0.7 * w } else { -0.5 * w };
        text += &format!("[[object.mode]]\nfreq_hz = {f:e}\nweights = [{w:e}, {wp:e}]\n");
        if o.damped {
            // 2 s at f_lo down to 0.1 s at f_hi (geometric)
            let x = if o.n == 1 {
                0.0
            } else {
                i as f64 / (o.n - 1) as f64
            };
            text += &format!("t60_s = {:e}\n", 2.0 * (0.05f64).powf(x));
        }
    }
    let (height, v) = if o.g > 0.0 {
        (0.01, 0.0)
    } else {
        (o.height, -1.0)
    };
    text += &hammer_contact_pickup(o.m_h, height, v, o.g, o.k, o.c);
    parse(&text)
}

/// The scene text after the modes of object `o` (points `c`, `p`): the
/// hammer, the contact at `c` and one velocity pickup at `p`, panned hard left.
fn hammer_contact_pickup(m_h: f64, height: f64, v0: f64, g: f64, k: f64, c: f64) -> String {
    format!(
        "[hammer]\nmass_kg = {m_h:e}\nheight_m = {height:e}\nvelocity_m_per_s = {v0:e}\ngravity_m_per_s2 = {g:e}\n\
         [contact]\nobject = \"o\"\npoint = \"c\"\nstiffness_n_per_m = {k:e}\ndamping_n_s_per_m = {c:e}\n\
         [[pickup]]\nobject = \"o\"\npoint = \"p\"\nquantity = \"velocity\"\ngain = 1.0\npan = -1.0\n"
    )
}

/// The plate of `presets/steel-plate.toml` (simply supported 400 x 280 x 8 mm
/// steel, Kirchhoff: `f_mn = (pi/2) sqrt(D/(rho h)) ((m/a)^2 + (n/b)^2)`,
/// mass-normalised shapes `2/sqrt(M) sin(m pi x/a) sin(n pi y/b)`, contact at
/// (0.37, 0.41), pickup at (0.72, 0.64) of (a, b), hard beater 0.04 kg with
/// k = 9.796e6 N/m, c = 124.1 N s/m, -1.5 m/s), but with every mode up to
/// `f_max_hz` instead of 8 kHz and a simpler loss model:
/// `T60 = ln(1000) / (1 + pi f eta)`, `eta = 1e-4` (no radiation term). The
/// beater starts 0.1 mm above the plate. Modes sorted by frequency.
pub fn plate_scene(name: &str, f_max_hz: f64) -> Result<Scene> {
    let (e, nu, rho, thick, a, b): (f64, f64, f64, f64, f64, f64) =
        (200e9, 0.3, 7850.0, 0.008, 0.4, 0.28);
    let d = e * thick.powi(3) / (12.0 * (1.0 - nu * nu));
    let rho_h = rho * thick;
    let s = (d / rho_h).sqrt();
    let mass = rho_h * a * b;
    let f_of =
        |m: usize, n: usize| PI / 2.0 * s * ((m as f64 / a).powi(2) + (n as f64 / b).powi(2));
    let shape = |m: usize, n: usize, x: f64, y: f64| {
        2.0 / mass.sqrt() * (m as f64 * PI * x).sin() * (n as f64 * PI * y).sin()
    };
    let mut modes = Vec::new();
    for m in 1.. {
        if f_of(m, 1) > f_max_hz {
            break;
        }
        for n in 1.. {
            let f = f_of(m, n);
            if f > f_max_hz {
                break;
            }
            modes.push((f, m, n));
        }
    }
    modes.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut text = format!(
        "version = 1\nname = \"{name}\"\n[[object]]\nname = \"o\"\nkind = \"modal\"\npoints = [\"c\", \"p\"]\n"
    );
    for (f, m, n) in modes {
        let t60 = 1000f64.ln() / (1.0 + PI * f * 1e-4);
        text += &format!(
            "[[object.mode]]\nfreq_hz = {f:e}\nt60_s = {t60:e}\nweights = [{:e}, {:e}]\n",
            shape(m, n, 0.37, 0.41),
            shape(m, n, 0.72, 0.64)
        );
    }
    text += &hammer_contact_pickup(0.04, 1e-4, -1.5, 0.0, 9.79621e6, 124.104);
    parse(&text)
}

/// A hammer against a rigid wall, no gravity, starting `height` above it at
/// `v0` (negative: down).
pub fn wall_scene(m: f64, k: f64, c: f64, height: f64, v0: f64) -> Result<Scene> {
    parse(&format!(
        "version = 1\nname = \"wall\"\n[[object]]\nname = \"floor\"\nkind = \"wall\"\n\
         [hammer]\nmass_kg = {m:e}\nheight_m = {height:e}\nvelocity_m_per_s = {v0:e}\n\
         [contact]\nobject = \"floor\"\nstiffness_n_per_m = {k:e}\ndamping_n_s_per_m = {c:e}\n"
    ))
}

/// Stiffness for contact frequency `fc` [Hz] with hammer mass `m` (rigid point).
pub fn k_for(m: f64, fc: f64) -> f64 {
    m * (2.0 * PI * fc).powi(2)
}

/// Damping for damping ratio `zeta` (rigid point).
pub fn c_for(m: f64, k: f64, zeta: f64) -> f64 {
    zeta * 2.0 * (k * m).sqrt()
}

/// NUMERICS.md S1/X1 (`fc_ratio` = 0.09) and S2/X2 (0.45): 20 modes from
/// 200 Hz to 0.82 f_Nyq, T60 2 s .. 0.1 s, m_h / m_k = 0.2, zeta_c = 0.3,
/// v0 = 1 m/s; the hammer starts 1e-5 m above the object (the first crossing
/// falls inside a sample, 0.44 sample in).
pub fn s_scene(name: &str, fc_ratio: f64) -> Result<Scene> {
    let m_h = 0.2;
    let k = k_for(m_h, fc_ratio * NYQ);
    modal_scene(
        name,
        ModalOpts {
            n: 20,
            f_lo: 200.0,
            f_hi: 0.82 * NYQ,
            damped: true,
            m_h,
            k,
            c: c_for(m_h, k, 0.3),
            g: 0.0,
            height: 1e-5,
        },
    )
}

/// The rigid-wall accuracy case: 10 g hammer, f_c = 1.59 kHz (k = 1e6 N/m),
/// zeta = 0.1, starting 0.1 mm above the wall at 1 m/s down (contact starts
/// 4.41 samples in).
pub fn wall_accuracy_scene() -> Result<Scene> {
    let (m, k) = (0.01, 1e6);
    wall_scene(m, k, c_for(m, k, 0.1), 1e-4, -1.0)
}

/// `"139 modes 365 Hz .. 33.1 kHz (48 above f_Nyq), T60 6.2 s .. 0.61 s"` for
/// the first object of a scene when it is modal (measured from the scene).
pub fn modal_summary(scene: &Scene) -> String {
    let Some(modal_contact::scene::ObjectSpec::Modal(m)) = scene.object.first() else {
        return "not a modal object".into();
    };
    let fs = m.mode.iter().map(|x| x.freq_hz);
    let (f_lo, f_hi) = fs.fold((f64::INFINITY, 0.0f64), |(a, b), f| (a.min(f), b.max(f)));
    let above = m.mode.iter().filter(|x| x.freq_hz > NYQ).count();
    let t60s: Vec<f64> = m.mode.iter().filter_map(|x| x.t60_s).collect();
    let t_hi = t60s.iter().copied().fold(0.0f64, f64::max);
    let t_lo = t60s.iter().copied().fold(f64::INFINITY, f64::min);
    format!(
        "{} modes {f_lo:.0} Hz .. {:.1} kHz ({above} above f_Nyq), T60 {t_hi:.2} s .. {t_lo:.2} s",
        m.mode.len(),
        f_hi / 1000.0
    )
}
