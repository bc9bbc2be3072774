//! Checks of the radiated power against closed forms and against the far
//! field integrated by brute force over the half sphere.

use super::*;
use crate::bodies::materials::material;
use crate::bodies::radiation::{far_field, Direction};
use crate::bodies::shapes::{
    Bar, BeamSupport, Membrane, Plate, PlateEdges, Point, StiffString, Tube,
};

/// `J` from the decay rate (the module's formula read backwards).
fn j_of(shape: &Shape, mode: &ShapeMode) -> f64 {
    let sigma = radiation_decay_rate(shape, mode).unwrap();
    let w = mode.omega();
    sigma * 8.0 * PI * PI * SOUND_SPEED_M_PER_S / (AIR_DENSITY_KG_PER_M3 * w * w)
}

/// `integral |W|^2 dOmega` over the half sphere straight from
/// [`far_field`]: Gauss-Legendre in the polar angle, the trapezoid rule
/// (exact for a periodic trigonometric polynomial) in the azimuth.
fn j_brute(shape: &Shape, mode: &ShapeMode, n_polar: usize, n_azimuth: usize) -> f64 {
    let rule = super::rule(n_polar.trailing_zeros() as usize - 5);
    assert_eq!(rule.len(), n_polar);
    let mut sum = 0.0;
    for &(t, w) in rule {
        let theta = 0.25 * PI * (t + 1.0);
        let mut ring = 0.0;
        for j in 0..n_azimuth {
            let az = 360.0 * j as f64 / n_azimuth as f64;
            let d = Direction {
                polar_deg: theta.to_degrees(),
                azimuth_deg: az,
            };
            let (re, im) = far_field(shape, mode, d, SOUND_SPEED_M_PER_S).unwrap();
            ring += re * re + im * im;
        }
        sum += w * theta.sin() * ring * 2.0 * PI / n_azimuth as f64;
    }
    sum * 0.25 * PI
}

#[test]
fn the_factorised_power_matches_the_far_field_over_the_half_sphere() {
    let al = material("aluminium").unwrap();
    let bar = Shape::Bar(
        Bar::new(0.1534, 0.03, 0.008, &al, BeamSupport::FreeFree).with_torsion(al.shear_modulus_pa),
    );
    let tube = Shape::Tube(Tube::new(0.6, 0.032, 0.029, &al));
    let drum = Shape::Membrane(Membrane {
        radius_m: 0.18,
        tension_n_per_m: 3000.0,
        areal_density_kg_m2: 0.26,
    });
    // waves faster than sound (480 m/s): k sin(theta) crosses each mode's
    // radial wavenumber, where Lommel's closed form cancels and the
    // quadrature takes over
    let fast_drum = Shape::Membrane(Membrane {
        radius_m: 0.18,
        tension_n_per_m: 60000.0,
        areal_density_kg_m2: 0.26,
    });
    // a piano-like wire, waves near the speed of sound (324 m/s, faster
    // up the series with its stiffness): the sine's closed form and, where
    // k u meets its wavenumber, the quadrature
    let steel = material("steel").unwrap();
    let wire = Shape::StiffString(StiffString::round_wire(0.62, 648.8, 0.001, &steel));
    let mut worst: f64 = 0.0;
    for (shape, max_hz, picks) in [
        (&wire, 6000.0, &[0usize, 1, 4, 9, 17][..]),
        (&bar, 20000.0, &[0, 1, 2, 3, 4][..]),
        (&tube, 6000.0, &[0, 3, 6][..]),
        (&drum, 700.0, &[0, 1, 2, 3, 4, 5][..]),
        (&fast_drum, 4000.0, &[0, 1, 3, 5][..]),
    ] {
        let modes = shape.modes(max_hz, 400).unwrap();
        for &i in picks {
            let Some(m) = modes.get(i) else { continue };
            let fast = j_of(shape, m);
            let slow = j_brute(shape, m, 128, 256);
            let rel = (fast - slow).abs() / slow.abs().max(1e-300);
            println!(
                "{} {:>9.1} Hz: J {fast:.6e} brute {slow:.6e} rel {rel:.1e}",
                m.label, m.freq_hz
            );
            assert!(rel < 1e-5, "{} {}: {fast} vs {slow}", m.label, m.freq_hz);
            worst = worst.max(rel);
        }
    }
    println!("worst relative difference {worst:.1e}");
}

#[test]
fn a_compact_face_radiates_as_a_baffled_monopole() {
    // membrane (0,1): V = integral phi dA = 2 sqrt(pi) a / (j01 sqrt(sigma))
    let (a, s) = (0.1, 0.26);
    let drum = Shape::Membrane(Membrane {
        radius_m: a,
        tension_n_per_m: 1.0,
        areal_density_kg_m2: s,
    });
    let m = &drum.modes(100.0, 1).unwrap()[0];
    let j01 = 2.404_825_557_695_773;
    let v = 2.0 * PI.sqrt() * a / (j01 * s.sqrt());
    let ka = m.omega() / SOUND_SPEED_M_PER_S * a;
    let ratio = j_of(&drum, m) / (2.0 * PI * v * v);
    println!("membrane (0,1) ka {ka:.2e}: J / (2 pi V^2) = {ratio:.8}");
    assert!((ratio - 1.0).abs() < 1e-3, "{ratio}");
    // a small cantilever's first mode: V from the shape by Gauss-Legendre
    let al = material("aluminium").unwrap();
    let (l, b) = (0.05, 0.01);
    let reed = Shape::Bar(Bar::new(l, b, 2e-4, &al, BeamSupport::ClampedFree));
    let m = &reed.modes(1000.0, 1).unwrap()[0];
    let v: f64 = super::rule(2)
        .iter()
        .map(|&(t, w)| w * m.shape_at(Point::Line(0.5 * l * (t + 1.0))).unwrap())
        .sum::<f64>()
        * 0.5
        * l
        * b;
    let kl = m.omega() / SOUND_SPEED_M_PER_S * l;
    let ratio = j_of(&reed, m) / (2.0 * PI * v * v);
    println!(
        "cantilever {:.1} Hz, kL {kl:.2e}: J / (2 pi V^2) = {ratio:.6}",
        m.freq_hz
    );
    assert!((ratio - 1.0).abs() < 1e-3, "{ratio}");
}

#[test]
fn a_wide_bar_far_above_coincidence_radiates_as_maidanik_says() {
    // sigma -> rho0 c / (2 rho h) / sqrt(1 - f_c / f) for a face wide
    // against the wavelength: a 1 m x 0.6 m x 2 mm aluminium bar, f_c about
    // 6.4 kHz (its bending stiffness per width E h^3 / 12)
    let al = material("aluminium").unwrap();
    let (l, b, h) = (1.0, 0.6, 0.002);
    let bar = Shape::Bar(Bar::new(l, b, h, &al, BeamSupport::FreeFree));
    let rho_h = al.density_kg_m3 * h;
    let d = al.youngs_modulus_pa * h.powi(3) / 12.0;
    let c = SOUND_SPEED_M_PER_S;
    let f_c = c * c / (2.0 * PI) * (rho_h / d).sqrt();
    let modes = bar.modes(20000.0, 400).unwrap();
    let mut checked = 0;
    for m in modes.iter().filter(|m| m.freq_hz > 2.0 * f_c).step_by(3) {
        let sigma = radiation_decay_rate(&bar, m).unwrap();
        let want = AIR_DENSITY_KG_PER_M3 * c / (2.0 * rho_h) / (1.0 - f_c / m.freq_hz).sqrt();
        println!(
            "{} {:.0} Hz (f_c {f_c:.0} Hz): sigma {sigma:.4} 1/s, Maidanik {want:.4}, ratio {:.4}",
            m.label,
            m.freq_hz,
            sigma / want
        );
        assert!(
            (sigma / want - 1.0).abs() < 0.01,
            "{} {}",
            m.label,
            m.freq_hz
        );
        checked += 1;
    }
    assert!(checked >= 3);
}

#[test]
fn plates_and_mismatched_modes_are_refused() {
    let al = material("aluminium").unwrap();
    let plate = Shape::Plate(Plate::new(
        0.4,
        0.3,
        0.002,
        &al,
        PlateEdges::SimplySupported,
    ));
    let m = &plate.modes(2000.0, 4).unwrap()[0];
    let e = radiation_decay_rate(&plate, m).unwrap_err();
    assert!(e.contains("plates"), "{e}");
    let drum = Shape::Membrane(Membrane {
        radius_m: 0.18,
        tension_n_per_m: 3000.0,
        areal_density_kg_m2: 0.26,
    });
    let e = radiation_decay_rate(&drum, m).unwrap_err();
    assert!(e.contains("not a mode of a membrane"), "{e}");
}
