//! Surface profiles for a driven contact (docs/design.md, "Rolling and
//! scraping"): heights along a path, tabulated on an even grid, and what a
//! rolling ball of a given radius sees of them.
//!
//! - [`ridges`]: periodic sawtooth ridges (a guiro, a ratchet);
//! - [`fractal`]: random roughness of a given RMS height, correlation
//!   length and spectral exponent, seeded, periodic over its length;
//! - [`scaled`]: any sampled profile (a WAV file's samples) scaled to a
//!   peak height;
//! - [`roll`]: the rolling filter, the height of the lowest point of a
//!   ball of radius `r` resting on the profile above each path position.
//!
//! Pure functions of plain numbers; nothing here knows about scenes.

use realfft::RealFftPlanner;

/// A profile: heights \[m\] at `x = i dx` for `i = 0 .. heights.len()`,
/// linear between them. Periodic: the point after the last is the first
/// (the path wraps with period `heights.len() dx`); else the ends are
/// held.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// Grid spacing \[m\].
    pub dx: f64,
    /// Heights \[m\].
    pub heights: Vec<f64>,
    /// Whether the path wraps.
    pub periodic: bool,
}

impl Profile {
    /// Path length the profile covers \[m\] (its period when periodic).
    pub fn length(&self) -> f64 {
        let n = self.heights.len();
        if self.periodic {
            n as f64 * self.dx
        } else {
            n.saturating_sub(1) as f64 * self.dx
        }
    }

    /// The height at path position `x` \[m\], linear between grid points:
    /// wrapped when periodic, else the end values beyond the ends.
    pub fn at(&self, x: f64) -> f64 {
        let n = self.heights.len();
        if n == 0 || !x.is_finite() {
            return 0.0;
        }
        if n == 1 {
            return self.heights[0];
        }
        let u = x / self.dx;
        if self.periodic {
            let u = u.rem_euclid(n as f64);
            let i = (u.floor() as usize).min(n - 1);
            let f = u - i as f64;
            let (a, b) = (self.heights[i], self.heights[(i + 1) % n]);
            a + f * (b - a)
        } else if u <= 0.0 {
            self.heights[0]
        } else if u >= (n - 1) as f64 {
            self.heights[n - 1]
        } else {
            let i = u.floor() as usize;
            let f = u - i as f64;
            let (a, b) = (self.heights[i], self.heights[i + 1]);
            a + f * (b - a)
        }
    }
}

/// Sawtooth ridges: `round(length / spacing)` of them (at least one),
/// each rising from 0 to `depth` over `rise` of its spacing and falling
/// back over the rest, `points_per_ridge` grid points each (the corners
/// on grid points when `rise * points_per_ridge` is whole).
pub fn ridges(
    length: f64,
    spacing: f64,
    depth: f64,
    rise: f64,
    points_per_ridge: usize,
    periodic: bool,
) -> Profile {
    let count = ((length / spacing).round() as usize).max(1);
    let per = points_per_ridge.max(2);
    let dx = spacing / per as f64;
    let n = count * per + usize::from(!periodic);
    let heights = (0..n)
        .map(|i| {
            let u = (i % per) as f64 / per as f64;
            if u <= rise {
                depth * u / rise
            } else {
                depth * (1.0 - u) / (1.0 - rise)
            }
        })
        .collect();
    Profile {
        dx,
        heights,
        periodic,
    }
}

/// SplitMix64: the seeded random numbers of [`fractal`] (a fixed,
/// documented generator, so a seed gives the same surface everywhere).
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A uniform number in `(0, 1)`.
fn uniform(state: &mut u64) -> f64 {
    ((splitmix(state) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
}

/// Random roughness over `length` on `n` grid points (periodic): every
/// harmonic `k_m = 2 pi m / length` up to the grid's Nyquist with
/// amplitude `(1 + (k_m l)^2)^(-exponent / 4)` (a power spectrum
/// `(1 + (k l)^2)^(-exponent / 2)`), complex Gaussian (Box-Muller from
/// SplitMix64 seeded with `seed`), no mean; then scaled so the RMS height
/// is `rms` exactly. An inverse real FFT makes the heights.
pub fn fractal(
    length: f64,
    n: usize,
    rms: f64,
    correlation: f64,
    exponent: f64,
    seed: u64,
) -> Profile {
    let n = n.max(4) & !1;
    let dx = length / n as f64;
    let mut planner = RealFftPlanner::<f64>::new();
    let ifft = planner.plan_fft_inverse(n);
    let mut spectrum = ifft.make_input_vec();
    let mut state = seed;
    let bins = spectrum.len();
    for (m, c) in spectrum.iter_mut().enumerate() {
        // Box-Muller: two Gaussians for the real and imaginary parts
        let (u1, u2) = (uniform(&mut state), uniform(&mut state));
        let r = (-2.0 * u1.ln()).sqrt();
        let th = 2.0 * std::f64::consts::PI * u2;
        if m == 0 || m == bins - 1 {
            // no mean; the Nyquist bin must be real, and is left out
            *c = realfft::num_complex::Complex::new(0.0, 0.0);
            continue;
        }
        let k = 2.0 * std::f64::consts::PI * m as f64 / length;
        let a = (1.0 + (k * correlation).powi(2)).powf(-exponent / 4.0);
        *c = realfft::num_complex::Complex::new(a * r * th.cos(), a * r * th.sin());
    }
    let mut heights = ifft.make_output_vec();
    ifft.process(&mut spectrum, &mut heights)
        .expect("buffers from the plan");
    let now = (heights.iter().map(|h| h * h).sum::<f64>() / n as f64).sqrt();
    let g = if now > 0.0 { rms / now } else { 0.0 };
    heights.iter_mut().for_each(|h| *h *= g);
    Profile {
        dx,
        heights,
        periodic: true,
    }
}

/// A sampled profile (e.g. a WAV file's samples) spread evenly over
/// `length`, its mean removed and scaled so the largest `|height|` is
/// `depth` (all zero stays zero).
pub fn scaled(samples: &[f64], length: f64, depth: f64, periodic: bool) -> Profile {
    let n = samples.len().max(1);
    let mean = samples.iter().sum::<f64>() / n as f64;
    let peak = samples.iter().map(|s| (s - mean).abs()).fold(0.0, f64::max);
    let g = if peak > 0.0 { depth / peak } else { 0.0 };
    let spans = if periodic { n } else { (n - 1).max(1) };
    Profile {
        dx: length / spans as f64,
        heights: samples.iter().map(|s| (s - mean) * g).collect(),
        periodic,
    }
}

/// The rolling filter: above each grid point, the height of the lowest
/// point of a ball of radius `radius` lowered onto the profile there,
/// `max over |u| <= r of h(x + u) + sqrt(r^2 - u^2) - r`, the maximum
/// over the grid points within the radius (the profile's corners are grid
/// points; between them a ball of radius `r` over a segment of length
/// `dx` may sit up to `dx^2 / (8 r)` higher, which this leaves out). A
/// ball cannot reach into a hollow narrower than itself: the contact
/// follows this profile instead of the surface (the rolling filter of
/// Rath's rolling model, here the exact geometric construction). Radius 0:
/// the profile itself.
///
/// The maxima are found in `O((n + w) log n)` for `w = r / dx` grid points
/// under the ball, not `O(n w)`: the ball's lift `l(u) = sqrt(r^2 - u^2) -
/// r` is concave, so the matrix `A[i][k] = h[k] + l(k - i)` has the Monge
/// property `A[i][k] + A[i'][k'] >= A[i][k'] + A[i'][k]` for `i < i'`, `k <
/// k'` (the inner offsets' lifts sum to at least the outer ones'), and the
/// leftmost maximum of row `i` moves right with `i`. Each middle row is
/// scanned between its neighbours' maxima, halving the rows each time.
/// The lift's second differences (at least `dx^2 / r`) are many orders
/// above the sums' rounding, so the floating-point matrix keeps the
/// property and the result is the brute-force maximum bit for bit (the
/// same sums compared; tested).
pub fn roll(p: &Profile, radius: f64) -> Profile {
    let n = p.heights.len();
    let w = (radius / p.dx).floor() as usize;
    if radius <= 0.0 || n == 0 || w == 0 {
        return p.clone();
    }
    let lift = ball_lift(radius, p.dx, w);
    // the heights in extended coordinates: row i's columns are t in
    // i ..= i + 2 w, grid point t - w (wrapped when periodic; beyond the
    // ends of an open path nothing to touch)
    let h = &p.heights;
    let ext: Vec<f64> = (0..n + 2 * w)
        .map(|t| {
            let i = t as isize - w as isize;
            if p.periodic {
                h[i.rem_euclid(n as isize) as usize]
            } else if i >= 0 && (i as usize) < n {
                h[i as usize]
            } else {
                f64::NEG_INFINITY
            }
        })
        .collect();
    let mut heights = vec![0.0; n];
    row_maxima(&ext, &lift, w, (0, n), (0, n + 2 * w - 1), &mut heights);
    Profile {
        dx: p.dx,
        heights,
        periodic: p.periodic,
    }
}

/// The ball's lift `sqrt(r^2 - u^2) - r` at `u = j dx`, `j = 0 ..= w`.
fn ball_lift(radius: f64, dx: f64, w: usize) -> Vec<f64> {
    (0..=w)
        .map(|j| {
            let u = j as f64 * dx;
            (radius * radius - u * u).max(0.0).sqrt() - radius
        })
        .collect()
}

/// The maxima of rows `rows.0 .. rows.1` of `A[i][t] = ext[t] + lift[|t -
/// i - w|]` (`|t - i - w| <= w`), their leftmost maxima known to lie in
/// columns `cols.0 ..= cols.1`, into `out` (`roll`).
fn row_maxima(
    ext: &[f64],
    lift: &[f64],
    w: usize,
    rows: (usize, usize),
    cols: (usize, usize),
    out: &mut [f64],
) {
    if rows.0 >= rows.1 {
        return;
    }
    let mid = rows.0 + (rows.1 - rows.0) / 2;
    let (from, to) = (cols.0.max(mid), cols.1.min(mid + 2 * w));
    let (mut best, mut arg) = (f64::NEG_INFINITY, from);
    for (t, &e) in ext.iter().enumerate().take(to + 1).skip(from) {
        let v = e + lift[t.abs_diff(mid + w)];
        if v > best {
            (best, arg) = (v, t);
        }
    }
    out[mid] = best;
    row_maxima(ext, lift, w, (rows.0, mid), (cols.0, arg), out);
    row_maxima(ext, lift, w, (mid + 1, rows.1), (arg, cols.1), out);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball over a rectangular notch narrower than itself dips by the
    /// circle's sagitta `r - sqrt(r^2 - (w/2)^2)` (when the notch is
    /// deeper), and rests on the rim elsewhere: the geometric construction.
    #[test]
    fn a_ball_over_a_notch_dips_by_the_sagitta() {
        let (r, w, d, dx) = (5e-3, 4e-3, 2e-3, 1e-5);
        let n = 2001;
        let x0 = (n / 2) as f64 * dx;
        let heights = (0..n)
            .map(|i| {
                if ((i as f64 * dx) - x0).abs() < w / 2.0 {
                    -d
                } else {
                    0.0
                }
            })
            .collect();
        let p = Profile {
            dx,
            heights,
            periodic: false,
        };
        let b = roll(&p, r);
        let sag = r - (r * r - (w / 2.0) * (w / 2.0)).sqrt();
        let mid = b.heights[n / 2];
        println!("dip {mid:e} against -{sag:e}");
        // the rim is the nearest grid point outside the notch: within dx
        // of w / 2, which moves the dip by at most its slope w / (2 r) dx
        assert!(
            (mid + sag).abs() < dx * w / (2.0 * r) * 1.01,
            "{mid} vs {}",
            -sag
        );
        // far from the notch, on the flat: 0
        assert_eq!(b.heights[10], 0.0);
        // never below the surface
        assert!(b.heights.iter().zip(&p.heights).all(|(b, h)| b >= h));
    }

    /// The rolling filter by brute force: every grid point under the ball.
    fn roll_brute(p: &Profile, radius: f64) -> Profile {
        let n = p.heights.len();
        let w = (radius / p.dx).floor() as usize;
        if radius <= 0.0 || n == 0 || w == 0 {
            return p.clone();
        }
        let lift = ball_lift(radius, p.dx, w);
        let h = &p.heights;
        let get = |i: isize| -> Option<f64> {
            if p.periodic {
                Some(h[i.rem_euclid(n as isize) as usize])
            } else if i >= 0 && (i as usize) < n {
                Some(h[i as usize])
            } else {
                None
            }
        };
        let heights = (0..n as isize)
            .map(|i| {
                let mut best = h[i as usize];
                for (j, &l) in lift.iter().enumerate().skip(1) {
                    let j = j as isize;
                    for v in [get(i - j), get(i + j)].into_iter().flatten() {
                        best = best.max(v + l);
                    }
                }
                best
            })
            .collect();
        Profile {
            dx: p.dx,
            heights,
            periodic: p.periodic,
        }
    }

    /// The halving search gives the brute-force maxima bit for bit: rough
    /// surfaces open and periodic, ridges, a notch, balls from two grid
    /// steps to wider than the whole path (a periodic path then wraps
    /// under the ball more than once).
    #[test]
    fn the_rolling_filter_is_the_brute_force_maximum_bit_for_bit() {
        let mut cases = Vec::new();
        for (seed, periodic) in [(1, false), (2, true), (3, false)] {
            let mut p = fractal(0.05, 1 << 11, 2e-6, 3e-4, 2.0, seed);
            p.periodic = periodic;
            cases.push(p);
        }
        cases.push(ridges(0.05, 4e-3, 1e-3, 0.5, 64, false));
        cases.push(ridges(0.05, 4e-3, 1e-3, 0.5, 64, true));
        let dx = cases[0].dx;
        let mut checked = 0;
        for p in &cases {
            let len = p.heights.len() as f64 * p.dx;
            for r in [2.5 * p.dx, 1e-3, 8e-3, 3.0 * len] {
                let (fast, brute) = (roll(p, r), roll_brute(p, r));
                assert_eq!(fast.heights.len(), brute.heights.len());
                for (i, (a, b)) in fast.heights.iter().zip(&brute.heights).enumerate() {
                    assert_eq!(a.to_bits(), b.to_bits(), "r {r}, point {i}: {a:e} vs {b:e}");
                }
                checked += fast.heights.len();
            }
        }
        println!("{checked} points equal bit for bit (grid {dx:e} m)");
    }

    /// Over a sinusoid whose curvature is everywhere below `1 / r` the ball
    /// touches its crests and its troughs (where the ball's lowest point
    /// is the point of contact: the filtered profile equals the surface
    /// there) and sits above it on the slopes, where it touches off its
    /// lowest point; over a steeper one it bridges the troughs.
    #[test]
    fn a_ball_follows_a_gentle_sinusoid_and_bridges_a_sharp_one() {
        let (lambda, r) = (0.01, 2e-3);
        let n = 1000;
        let dx = lambda / n as f64;
        let wave = |a: f64| Profile {
            dx,
            heights: (0..n)
                .map(|i| a * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos())
                .collect(),
            periodic: true,
        };
        let k = 2.0 * std::f64::consts::PI / lambda;
        // curvature a k^2 = 0.5 / r: the ball reaches the trough
        let a = 0.5 / (r * k * k);
        let gentle = wave(a);
        let b = roll(&gentle, r);
        let (crest, trough) = (b.heights[0] - a, b.heights[n / 2] + a);
        println!("gentle (amplitude {a:e}): crest {crest:e}, trough {trough:e}");
        assert_eq!(crest, 0.0);
        // the grid points beside the trough's: within the sagitta of a grid step
        assert!(trough.abs() <= dx * dx / r, "{trough:e}");
        assert!(b.heights.iter().zip(&gentle.heights).all(|(b, h)| b >= h));
        // on the steepest slope the ball touches uphill of its lowest point
        let q = n / 4;
        assert!(b.heights[q] > gentle.heights[q] + 1e-3 * a);
        // curvature 4 / r: the trough is bridged, higher than the surface
        let sharp = wave(4.0 / (r * k * k));
        let b = roll(&sharp, r);
        assert_eq!(b.heights[0], sharp.heights[0]);
        assert!(b.heights[n / 2] > sharp.heights[n / 2] + 1e-6);
    }

    /// The roughness has the RMS asked for, no mean, is the same for the
    /// same seed and another for another seed, and its spectrum falls
    /// above the correlation length's wavenumber as the exponent says.
    #[test]
    fn roughness_has_its_rms_and_spectrum() {
        let (len, l) = (0.5, 2e-3);
        let p = fractal(len, 1 << 14, 1e-5, l, 2.0, 7);
        let n = p.heights.len() as f64;
        let rms = (p.heights.iter().map(|h| h * h).sum::<f64>() / n).sqrt();
        let mean = p.heights.iter().sum::<f64>() / n;
        assert!((rms / 1e-5 - 1.0).abs() < 1e-12, "rms {rms:e}");
        assert!(mean.abs() < 1e-12 * 1e-5 * n, "mean {mean:e}");
        assert_eq!(p, fractal(len, 1 << 14, 1e-5, l, 2.0, 7));
        assert_ne!(p.heights, fractal(len, 1 << 14, 1e-5, l, 2.0, 8).heights);
        // slopes: differences grow with the spectrum's high end; the
        // rougher exponent has the larger slope RMS at the same height RMS
        let slope = |p: &Profile| {
            let s: f64 = p
                .heights
                .windows(2)
                .map(|w| ((w[1] - w[0]) / p.dx).powi(2))
                .sum();
            (s / n).sqrt()
        };
        let rough = fractal(len, 1 << 14, 1e-5, l, 1.5, 7);
        let smooth = fractal(len, 1 << 14, 1e-5, l, 3.0, 7);
        println!(
            "slope rms: exponent 1.5 {:e}, 2 {:e}, 3 {:e}",
            slope(&rough),
            slope(&p),
            slope(&smooth)
        );
        assert!(slope(&rough) > 2.0 * slope(&p) && slope(&p) > 2.0 * slope(&smooth));
    }

    /// Ridges rise and fall as asked, their corners on grid points.
    #[test]
    fn ridges_are_sawtooth() {
        let p = ridges(0.01, 0.002, 1e-4, 0.75, 64, true);
        assert_eq!(p.heights.len(), 5 * 64);
        assert_eq!(p.heights[0], 0.0);
        assert_eq!(p.heights[48], 1e-4);
        assert!((p.at(0.002 * 0.375) - 0.5e-4).abs() < 1e-18);
        // wraps with the period of the five ridges
        assert!((p.at(0.01 + 0.001) - p.at(0.001)).abs() < 1e-18);
        let open = ridges(0.01, 0.002, 1e-4, 0.75, 64, false);
        assert_eq!(open.at(1.0), open.heights[open.heights.len() - 1]);
    }
}
