//! Checks of the far field against closed forms.

use super::*;
use crate::bodies::shapes::{bessel_j, Bar, BeamSupport, Membrane, Plate, StiffString, Tube};

fn dir(polar_deg: f64, azimuth_deg: f64) -> Direction {
    Direction {
        polar_deg,
        azimuth_deg,
    }
}

fn plate_ss() -> Plate {
    let al = material("aluminium").unwrap();
    Plate::new(0.4, 0.3, 0.002, &al, PlateEdges::SimplySupported)
}

fn drum() -> Membrane {
    Membrane {
        radius_m: 0.18,
        tension_n_per_m: 3000.0,
        areal_density_kg_m2: 0.26,
    }
}

fn rosewood_bar() -> Bar {
    Bar::new(
        0.4,
        0.06,
        0.02,
        &material("rosewood").unwrap(),
        BeamSupport::FreeFree,
    )
}

fn wavenumbers(mode: &ShapeMode, d: Direction, c: f64) -> (f64, f64, f64) {
    let k = mode.omega() / c;
    let sp = d.polar_deg.to_radians().sin();
    let (sa, ca) = d.azimuth_deg.to_radians().sin_cos();
    (k, k * sp * ca, k * sp * sa)
}

/// `integral_0^a sin(m pi x / a) exp(i kappa (x - a/2)) dx = p (exp(-i
/// kappa a / 2) - (-1)^m exp(i kappa a / 2)) / (p^2 - kappa^2)`, `p = m
/// pi / a` (from `sin = (e^(ipx) - e^(-ipx)) / (2i)` and `e^(ipa) =
/// (-1)^m`).
fn sine_transform(m: usize, a: f64, kappa: f64) -> (f64, f64) {
    let p = m as f64 * PI / a;
    let sign = if m.is_multiple_of(2) { 1.0 } else { -1.0 };
    let (s, c) = (0.5 * kappa * a).sin_cos();
    let d = p * p - kappa * kappa;
    assert!(
        d.abs() > 1e-3 * p * p,
        "too close to the removable singularity"
    );
    // exp(-i h) - sign exp(i h) = (c - sign c) + i (-s - sign s)
    (p * (c - sign * c) / d, p * (-s - sign * s) / d)
}

fn cmul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

#[test]
fn gauss_legendre_rules_are_exact_for_their_degree() {
    for n in [1usize, 2, 5, 32, 33, 4096] {
        let r = gauss_legendre(n);
        let sum: f64 = r.iter().map(|p| p.1).sum();
        assert!((sum - 2.0).abs() < 1e-13, "n {n}: sum of weights {sum}");
        // integral x^(2n-2) = 2 / (2n - 1), the highest even degree < 2n.
        let deg = 2 * n - 2;
        // x^deg near x = 1 turns a node's rounding error d into a
        // relative error deg * d: up to ~1e-12 for n = 4096.
        let q: f64 = r.iter().map(|&(x, w)| w * x.powi(deg as i32)).sum();
        let want = 2.0 / (deg as f64 + 1.0);
        let tol = 1e-14 * (deg as f64 + 10.0);
        assert!((q / want - 1.0).abs() < tol, "n {n}: {q} vs {want}");
    }
    // A 4096-node rule integrates cos(1000 x) to its closed form.
    let q: f64 = gauss_legendre(4096)
        .iter()
        .map(|&(x, w)| w * (1000.0 * x).cos())
        .sum();
    let want = 2.0 * 1000f64.sin() / 1000.0;
    println!("GL 4096: cos(1000 x) error {:.1e}", (q - want).abs());
    assert!((q - want).abs() < 1e-13);
}

#[test]
fn simply_supported_plate_matches_the_closed_form() {
    let p = plate_ss();
    let (a, b) = (p.length_x_m, p.length_y_m);
    let scale = 2.0 / (p.density_kg_m3 * p.thickness_m * a * b).sqrt();
    let modes = p.modes(f64::INFINITY, 40).unwrap();
    let shape = Shape::Plate(p);
    // integral |phi| dA = scale (2a / pi) (2b / pi) for every (m, n).
    let abs = scale * (2.0 * a / PI) * (2.0 * b / PI);
    let mut worst: f64 = 0.0;
    for (mm, nn) in [(1, 1), (2, 1), (3, 2)] {
        let mode = modes
            .iter()
            .find(|x| x.label == ModeLabel::Plate { m: mm, n: nn })
            .unwrap();
        // scale: shape_at at the antinode.
        let at = mode
            .shape_at(Point::Plane {
                x: a / (2.0 * mm as f64),
                y: b / (2.0 * nn as f64),
            })
            .unwrap();
        assert!((at / scale - 1.0).abs() < 1e-14);
        for c in [SOUND_SPEED_M_PER_S, 20.0, 2.3] {
            for d in [
                dir(0.0, 0.0),
                dir(60.0, 0.0),
                dir(60.0, 37.0),
                dir(30.0, 90.0),
                dir(85.0, 200.0),
            ] {
                let (_, kx, ky) = wavenumbers(mode, d, c);
                let want = cmul(sine_transform(mm, a, kx), sine_transform(nn, b, ky));
                let want = (scale * want.0, scale * want.1);
                let got = far_field(&shape, mode, d, c).unwrap();
                // Relative to |W|, or to integral |phi| where W is 0
                // (even modes straight ahead).
                let size = want.0.hypot(want.1);
                let err = dist(got, want) / if size > 1e-6 * abs { size } else { abs };
                worst = worst.max(err);
                assert!(
                    err < 1e-9,
                    "{} c {c} {d:?}: {got:?} vs {want:?}",
                    mode.label
                );
            }
        }
    }
    println!("SS plate vs closed form: worst relative error {worst:.1e}");
}

#[test]
fn plate_fundamental_straight_ahead_is_its_net_volume() {
    let p = plate_ss();
    let (a, b) = (p.length_x_m, p.length_y_m);
    let scale = 2.0 / (p.density_kg_m3 * p.thickness_m * a * b).sqrt();
    let mode = p.modes(f64::INFINITY, 1).unwrap().remove(0);
    let got = far_field(&Shape::Plate(p), &mode, dir(0.0, 0.0), SOUND_SPEED_M_PER_S).unwrap();
    let want = (2.0 * a / PI) * (2.0 * b / PI) * scale;
    let err = dist(got, (want, 0.0)) / want;
    println!(
        "plate (1,1) at polar 0: W = {:.9e}, net volume {want:.9e}, rel error {err:.1e}",
        got.0
    );
    assert!(err < 1e-12, "{got:?} vs {want}");
}

#[test]
fn free_plate_separable_path_matches_two_dimensional_quadrature() {
    let al = material("aluminium").unwrap();
    let p = Plate::new(0.4, 0.3, 0.002, &al, PlateEdges::Free);
    let (a, b) = (p.length_x_m, p.length_y_m);
    let modes = p.modes(f64::INFINITY, 12).unwrap();
    let shape = Shape::Plate(p);
    let mut worst: f64 = 0.0;
    for mode in &modes {
        let ModeLabel::Plate { m, n } = mode.label else {
            panic!()
        };
        for c in [SOUND_SPEED_M_PER_S, 5.0] {
            for d in [dir(0.0, 0.0), dir(45.0, 30.0), dir(80.0, 250.0)] {
                let (_, kx, ky) = wavenumbers(mode, d, c);
                let (re, im, abs) = oscillatory_2d(
                    |x, y| mode.shape_at(Point::Plane { x, y }),
                    ((0.0, a), (0.0, b)),
                    (a / 2.0, b / 2.0),
                    (kx, ky),
                    (m as f64 + 1.0, n as f64 + 1.0),
                    1e-12,
                )
                .unwrap();
                let got = far_field(&shape, mode, d, c).unwrap();
                let err = dist(got, (re, im)) / abs;
                worst = worst.max(err);
                assert!(err < 1e-9, "{} {d:?}: {got:?} vs {re} {im}", mode.label);
            }
        }
    }
    println!("free plate, separable vs 2-D: worst error {worst:.1e} of integral |phi|");
}

/// Lommel: `integral_0^a J_m(alpha r) J_m(beta r) r dr = a alpha
/// J_(m+1)(alpha a) J_m(beta a) / (alpha^2 - beta^2)` when `J_m(alpha a)
/// = 0`.
fn lommel(m: usize, j: f64, a: f64, beta: f64) -> f64 {
    let alpha = j / a;
    let d = alpha * alpha - beta * beta;
    assert!(d.abs() > 1e-3 * alpha * alpha);
    a * alpha * bessel_j(m + 1, j) * bessel_j(m, beta * a) / d
}

#[test]
fn membrane_axisymmetric_modes_match_lommels_integral() {
    let mb = drum();
    let a = mb.radius_m;
    let modes = mb.modes(f64::INFINITY, 60).unwrap();
    let shape = Shape::Membrane(mb.clone());
    let mut worst: f64 = 0.0;
    let mut checked = 0;
    for mode in &modes {
        let ModeLabel::Membrane { m, n, .. } = mode.label else {
            panic!()
        };
        if m != 0 || n > 4 {
            continue;
        }
        let j = crate::bodies::shapes::bessel_j_zero(0, n).unwrap();
        // Scale and sign: Phi(0) = scale J0(0) = scale.
        let scale = mode.shape_at(Point::Polar { r: 0.0, theta: 0.0 }).unwrap();
        for c in [SOUND_SPEED_M_PER_S, 30.0, 3.0] {
            for d in [
                dir(0.0, 0.0),
                dir(30.0, 10.0),
                dir(60.0, 0.0),
                dir(89.0, 123.0),
            ] {
                let (k, _, _) = wavenumbers(mode, d, c);
                let beta = k * d.polar_deg.to_radians().sin();
                let want = 2.0 * PI * scale * lommel(0, j, a, beta);
                let got = far_field(&shape, mode, d, c).unwrap();
                let err = dist(got, (want, 0.0)) / want.abs();
                worst = worst.max(err);
                assert!(err < 1e-9, "{} c {c} {d:?}: {got:?} vs {want}", mode.label);
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 4 * 3 * 4);
    println!("membrane (0,n) vs Lommel: worst relative error {worst:.1e}");
    // m >= 1: nothing straight ahead; at an angle, Lommel times 2 pi i^m
    // cos(m psi) (or sin).
    let mut worst_m: f64 = 0.0;
    for mode in &modes {
        let ModeLabel::Membrane { m, n, sine } = mode.label else {
            panic!()
        };
        if m == 0 {
            continue;
        }
        let j = crate::bodies::shapes::bessel_j_zero(m, n).unwrap();
        let theta = if sine { PI / (2.0 * m as f64) } else { 0.0 };
        let r0 = 0.37 * a;
        let scale = mode.shape_at(Point::Polar { r: r0, theta }).unwrap() / bessel_j(m, j * r0 / a);
        // |J_m| <= 1: an upper bound of integral |phi| dA.
        let abs = scale.abs() * PI * a * a;
        let w0 = far_field(&shape, mode, dir(0.0, 17.0), SOUND_SPEED_M_PER_S).unwrap();
        assert!(w0.0.hypot(w0.1) < 1e-12 * abs, "{}: {w0:?}", mode.label);
        for (c, d) in [
            (SOUND_SPEED_M_PER_S, dir(50.0, 20.0)),
            (4.0, dir(70.0, 200.0)),
        ] {
            let (k, _, _) = wavenumbers(mode, d, c);
            let beta = k * d.polar_deg.to_radians().sin();
            let psi = d.azimuth_deg.to_radians();
            let ang = if sine {
                (m as f64 * psi).sin()
            } else {
                (m as f64 * psi).cos()
            };
            let w = 2.0 * PI * scale * ang * lommel(m, j, a, beta);
            let want = match m % 4 {
                0 => (w, 0.0),
                1 => (0.0, w),
                2 => (-w, 0.0),
                _ => (0.0, -w),
            };
            let got = far_field(&shape, mode, d, c).unwrap();
            let err = dist(got, want) / w.abs().max(1e-300);
            worst_m = worst_m.max(err);
            assert!(
                err < 1e-9,
                "{} c {c} {d:?}: {got:?} vs {want:?}",
                mode.label
            );
        }
    }
    println!("membrane m >= 1 vs Lommel: worst relative error {worst_m:.1e}");
}

#[test]
fn membrane_matches_quadrature_over_the_disk() {
    // Independent of the Jacobi-Anger reduction: Gauss-Legendre in r,
    // the trapezoidal rule (spectrally exact for periodic integrands) in
    // theta, Phi from shape_at at each point.
    let mb = drum();
    let a = mb.radius_m;
    let modes = mb.modes(f64::INFINITY, 12).unwrap();
    let shape = Shape::Membrane(mb);
    let rs = gauss_legendre(256);
    let nt = 512;
    let mut worst: f64 = 0.0;
    for mode in &modes {
        for (c, d) in [
            (SOUND_SPEED_M_PER_S, dir(0.0, 0.0)),
            (SOUND_SPEED_M_PER_S, dir(60.0, 25.0)),
            (10.0, dir(40.0, 110.0)),
            (6.0, dir(75.0, 300.0)),
        ] {
            let (_, kx, ky) = wavenumbers(mode, d, c);
            let (mut re, mut im, mut abs) = (0.0, 0.0, 0.0);
            for &(t, w) in &rs {
                let r = 0.5 * a * (1.0 + t);
                for i in 0..nt {
                    let th = 2.0 * PI * i as f64 / nt as f64;
                    let v = mode.shape_at(Point::Polar { r, theta: th }).unwrap();
                    let wt = 0.5 * a * w * r * 2.0 * PI / nt as f64;
                    let (s, co) = (kx * r * th.cos() + ky * r * th.sin()).sin_cos();
                    re += wt * v * co;
                    im += wt * v * s;
                    abs += wt * v.abs();
                }
            }
            let got = far_field(&shape, mode, d, c).unwrap();
            let err = dist(got, (re, im)) / abs;
            worst = worst.max(err);
            assert!(
                err < 1e-9,
                "{} c {c} {d:?}: {got:?} vs ({re}, {im})",
                mode.label
            );
        }
    }
    println!("membrane vs 2-D disk quadrature: worst error {worst:.1e} of integral |phi|");
}

/// `integral |phi| dA` of a bar mode by 2-D quadrature.
fn bar_abs(mode: &ShapeMode, l: f64, hw: f64) -> f64 {
    oscillatory_2d(
        |x, y| mode.shape_at(Point::Bar { x, y }),
        ((0.0, l), (-hw, hw)),
        (l / 2.0, 0.0),
        (0.0, 0.0),
        (10.0, 1.0),
        1e-12,
    )
    .unwrap()
    .2
}

#[test]
fn free_free_bar_bending_modes_are_silent_ahead_and_real_or_imaginary_by_symmetry() {
    let bar = rosewood_bar();
    let (l, hw) = (bar.length_m, bar.width_m / 2.0);
    let modes = bar.modes(f64::INFINITY, 8).unwrap();
    let shape = Shape::Bar(bar);
    let (mut ahead, mut off_axis): (f64, f64) = (0.0, 0.0);
    for mode in &modes {
        let ModeLabel::Bending { n } = mode.label else {
            panic!()
        };
        let abs = bar_abs(mode, l, hw);
        let w0 = far_field(&shape, mode, dir(0.0, 0.0), SOUND_SPEED_M_PER_S).unwrap();
        let r0 = w0.0.hypot(w0.1) / abs;
        ahead = ahead.max(r0);
        assert!(r0 < 1e-9, "{}: {w0:?}, integral |phi| {abs}", mode.label);
        let w = far_field(&shape, mode, dir(60.0, 0.0), SOUND_SPEED_M_PER_S).unwrap();
        // Mode n = 1, 3, ... is even about the centre: W real; n = 2, 4,
        // ... odd: W imaginary.
        let (big, small) = if n % 2 == 1 { (w.0, w.1) } else { (w.1, w.0) };
        println!(
            "{} ({:.1} Hz): |W(0)| / int|phi| = {r0:.1e}; W(60 deg) = ({:.4e}, {:.4e}), int|phi| {abs:.4e}",
            mode.label, mode.freq_hz, w.0, w.1
        );
        assert!(big.abs() > 1e-3 * abs, "{}: {w:?}", mode.label);
        off_axis = off_axis.max(small.abs() / abs);
        assert!(small.abs() < 1e-9 * abs, "{}: {w:?}", mode.label);
    }
    println!(
        "bar: worst |W(0)| {ahead:.1e}, worst wrong part at 60 deg {off_axis:.1e} (of int |phi|)"
    );
}

#[test]
fn strip_closed_forms_match_two_dimensional_quadrature() {
    let rw = material("rosewood").unwrap();
    let al = material("aluminium").unwrap();
    let bars = [
        Shape::Bar(rosewood_bar().with_torsion(rw.shear_modulus_pa)),
        Shape::Bar(Bar::new(0.3, 0.05, 0.01, &al, BeamSupport::ClampedFree)),
        Shape::Tube(Tube::new(1.0, 0.0254, 0.0224, &al).with_torsion(al.shear_modulus_pa)),
    ];
    let mut worst: f64 = 0.0;
    for shape in &bars {
        let (l, width) = match shape {
            Shape::Bar(b) => (b.length_m, b.width_m),
            Shape::Tube(t) => (t.length_m, t.outer_diameter_m),
            _ => unreachable!(),
        };
        let hw = width / 2.0;
        let modes = shape.modes(f64::INFINITY, 10).unwrap();
        for mode in &modes {
            let torsion = matches!(mode.label, ModeLabel::Torsion { .. });
            for (c, d) in [
                (SOUND_SPEED_M_PER_S, dir(0.0, 0.0)),
                (SOUND_SPEED_M_PER_S, dir(60.0, 0.0)),
                (SOUND_SPEED_M_PER_S, dir(45.0, 30.0)),
                (3.0, dir(60.0, 90.0)),
                (5.0, dir(80.0, 70.0)),
                (4.0, dir(20.0, 160.0)),
            ] {
                let got = far_field(shape, mode, d, c).unwrap();
                if torsion && matches!(shape, Shape::Tube(_)) {
                    assert_eq!(got, (0.0, 0.0));
                    continue;
                }
                let (_, kx, ky) = wavenumbers(mode, d, c);
                let (re, im, abs) = oscillatory_2d(
                    |x, y| mode.shape_at(Point::Bar { x, y }),
                    ((0.0, l), (-hw, hw)),
                    (l / 2.0, 0.0),
                    (kx, ky),
                    (12.0, 1.0),
                    1e-12,
                )
                .unwrap();
                let err = dist(got, (re, im)) / abs;
                worst = worst.max(err);
                assert!(
                    err < 1e-9,
                    "{} c {c} {d:?}: {got:?} vs ({re}, {im})",
                    mode.label
                );
                if torsion && d == dir(45.0, 30.0) {
                    assert!(re.hypot(im) > 1e-6 * abs, "{}", mode.label);
                }
            }
        }
    }
    println!(
        "bars and tube, 1-D + closed form in y vs 2-D: worst error {worst:.1e} of integral |phi|"
    );
    // The small-argument series of the odd moment joins the closed form.
    for z in [0.499_999_999, 0.5] {
        let g = odd_moment(z, 1.0);
        let closed = (z.sin() - z * z.cos()) / (z * z);
        assert!((g / closed - 1.0).abs() < 1e-14, "{g} vs {closed}");
    }
    assert_eq!(odd_moment(0.0, 0.03), 0.0);
    let g = odd_moment(1e-3, 1.0);
    assert!((g / (1e-3 / 3.0 - 1e-9 / 30.0) - 1.0).abs() < 1e-14);
}

#[test]
fn string_is_a_strip_of_its_wire_diameter() {
    let steel = material("steel").unwrap();
    let d = 1e-3;
    let s = StiffString::round_wire(0.65, 700.0, d, &steel);
    let modes = s.modes(f64::INFINITY, 6).unwrap();
    let scale = (2.0 / (s.linear_density_kg_m * s.length_m)).sqrt();
    let l = s.length_m;
    // integral |phi| dA = scale (2 L / pi) d
    let abs = scale * 2.0 * l / PI * d;
    let shape = Shape::StiffString(s);
    let mut worst: f64 = 0.0;
    for mode in &modes {
        let ModeLabel::String { n } = mode.label else {
            panic!()
        };
        for (c, dr) in [
            (SOUND_SPEED_M_PER_S, dir(0.0, 0.0)),
            (SOUND_SPEED_M_PER_S, dir(60.0, 0.0)),
            (2.0, dir(70.0, 50.0)),
        ] {
            let (_, kx, ky) = wavenumbers(mode, dr, c);
            let sx = sine_transform(n, l, kx);
            let y = d * sinc(ky * d / 2.0);
            let want = (scale * sx.0 * y, scale * sx.1 * y);
            let got = far_field(&shape, mode, dr, c).unwrap();
            // Relative to |W|, or to integral |phi| where W is 0 (even
            // modes straight ahead).
            let size = want.0.hypot(want.1);
            let err = dist(got, want) / if size > 1e-6 * abs { size } else { abs };
            worst = worst.max(err);
            assert!(err < 1e-9, "{} {dr:?}: {got:?} vs {want:?}", mode.label);
        }
    }
    println!("string vs closed form: worst relative error {worst:.1e}");
}

#[test]
fn invalid_input_is_an_error() {
    let p = plate_ss();
    let mode = p.modes(f64::INFINITY, 1).unwrap().remove(0);
    let shape = Shape::Plate(p);
    for d in [dir(-1.0, 0.0), dir(90.5, 0.0), dir(f64::NAN, 0.0)] {
        let e = far_field(&shape, &mode, d, SOUND_SPEED_M_PER_S).unwrap_err();
        assert!(e.contains("polar_deg"), "{e}");
    }
    let e = far_field(&shape, &mode, dir(0.0, f64::INFINITY), 343.0).unwrap_err();
    assert!(e.contains("azimuth_deg"), "{e}");
    for c in [0.0, -1.0, f64::NAN] {
        let e = far_field(&shape, &mode, dir(0.0, 0.0), c).unwrap_err();
        assert!(e.contains("sound_speed"), "{e}");
    }
    let bar_mode = rosewood_bar().modes(f64::INFINITY, 1).unwrap().remove(0);
    let e = far_field(&shape, &bar_mode, dir(0.0, 0.0), 343.0).unwrap_err();
    assert!(e.contains("bending 1") && e.contains("plate"), "{e}");
    let e = far_field(&Shape::Membrane(drum()), &mode, dir(0.0, 0.0), 343.0).unwrap_err();
    assert!(e.contains("membrane"), "{e}");
    // A phase too fast for the largest rule: an error naming the mode.
    let e = far_field(&shape, &mode, dir(90.0, 0.0), 1e-4).unwrap_err();
    assert!(e.contains("plate (1,1)") && e.contains("converge"), "{e}");
}

#[test]
fn two_hundred_modes_are_fast() {
    let al = material("aluminium").unwrap();
    let shapes = [
        ("SS plate", Shape::Plate(plate_ss())),
        (
            "free plate",
            Shape::Plate(Plate::new(0.4, 0.3, 0.002, &al, PlateEdges::Free)),
        ),
        ("membrane", Shape::Membrane(drum())),
        ("bar", Shape::Bar(rosewood_bar())),
    ];
    // The rules are computed once per process: time the largest afresh.
    let t = std::time::Instant::now();
    let largest = gauss_legendre(MAX_NODES);
    println!(
        "the {}-node rule: {:.1} ms (once per process)",
        largest.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
    for level in 0..LEVELS {
        rule(level);
    }
    for (name, shape) in &shapes {
        // The 200 lowest, or those in the audio band (a bar's 200th
        // bending mode is at several MHz).
        let modes = shape.modes(20_000.0, 200).unwrap();
        for d in [dir(30.0, 20.0), dir(90.0, 45.0)] {
            let t = std::time::Instant::now();
            let mut sum = 0.0;
            for mode in &modes {
                let w = far_field(shape, mode, d, SOUND_SPEED_M_PER_S).unwrap();
                sum += w.0.abs() + w.1.abs();
            }
            let ms = t.elapsed().as_secs_f64() * 1e3;
            println!(
                "{name}: {} modes up to {:.0} Hz toward {d:?} in {ms:.2} ms (sum |W| {sum:.3e})",
                modes.len(),
                modes.last().unwrap().freq_hz
            );
            assert!(sum.is_finite());
        }
    }
}
