//! A second, unrelated solver to check the expm reference against: Dormand
//! and Prince's explicit Runge-Kutta 8(5,3) ("DOP853", Hairer, Norsett and
//! Wanner, *Solving ODEs I*, section II.10) with step-size control, on the
//! right-hand side written directly from the physics (no phase matrices, no
//! exponential, no balancing), in physical coordinates.
//!
//! Steps land on every sample instant. After each accepted step the same
//! switching semantics as the reference are applied, contact by contact: a
//! crossing of `p` is bracketed by the step's ends (or by an interior
//! extremum of `p`, found by bisection on `p'`), then located by bisection
//! where every trial point is a fresh single DOP853 step of length `tau`
//! from the step's start (a re-integration: a shorter step of an accepted
//! step is at least as accurate); the earliest switch of any contact is
//! taken and every contact switched there changes side. Every contact is a
//! [`crate::Link`] here ([`Model::link`]), whose force the right-hand side
//! takes from its two sides. It is far slower than the expm solver and only
//! meant for moderately stiff cases in the unit tests.

use crate::{record_switch, switched, toward, ContactInterval, End, Link, Model, Solution, Stats};

/// Stage coefficients `a[s][j]`, `j < s`, stages 2..=12 (Hairer's DOP853).
const A: [[f64; 12]; 12] = {
    let mut a = [[0.0; 12]; 12];
    a[1][0] = 0.05260015195876773;
    a[2][0] = 0.0197250569845379;
    a[2][1] = 0.0591751709536137;
    a[3][0] = 0.02958758547680685;
    a[3][2] = 0.08876275643042054;
    a[4][0] = 0.2413651341592667;
    a[4][2] = -0.8845494793282861;
    a[4][3] = 0.924834003261792;
    a[5][0] = 0.037037037037037035;
    a[5][3] = 0.17082860872947386;
    a[5][4] = 0.12546768756682242;
    a[6][0] = 0.037109375;
    a[6][3] = 0.17025221101954405;
    a[6][4] = 0.06021653898045596;
    a[6][5] = -0.017578125;
    a[7][0] = 0.03709200011850479;
    a[7][3] = 0.17038392571223998;
    a[7][4] = 0.10726203044637328;
    a[7][5] = -0.015319437748624402;
    a[7][6] = 0.008273789163814023;
    a[8][0] = 0.6241109587160757;
    a[8][3] = -3.3608926294469414;
    a[8][4] = -0.868219346841726;
    a[8][5] = 27.59209969944671;
    a[8][6] = 20.154067550477894;
    a[8][7] = -43.48988418106996;
    a[9][0] = 0.47766253643826434;
    a[9][3] = -2.4881146199716677;
    a[9][4] = -0.590290826836843;
    a[9][5] = 21.230051448181193;
    a[9][6] = 15.279233632882423;
    a[9][7] = -33.28821096898486;
    a[9][8] = -0.020331201708508627;
    a[10][0] = -0.9371424300859873;
    a[10][3] = 5.186372428844064;
    a[10][4] = 1.0914373489967295;
    a[10][5] = -8.149787010746927;
    a[10][6] = -18.52006565999696;
    a[10][7] = 22.739487099350505;
    a[10][8] = 2.4936055526796523;
    a[10][9] = -3.0467644718982196;
    a[11][0] = 2.273310147516538;
    a[11][3] = -10.53449546673725;
    a[11][4] = -2.0008720582248625;
    a[11][5] = -17.9589318631188;
    a[11][6] = 27.94888452941996;
    a[11][7] = -2.8589982771350235;
    a[11][8] = -8.87285693353063;
    a[11][9] = 12.360567175794303;
    a[11][10] = 0.6433927460157636;
    a
};

/// Stage instants `c[s]` as fractions of the step: the rows' sums of [`A`]
/// (the right-hand side depends on time through a moving surface).
const C: [f64; 12] = {
    let mut c = [0.0; 12];
    let mut s = 0;
    while s < 12 {
        let mut j = 0;
        while j < 12 {
            c[s] += A[s][j];
            j += 1;
        }
        s += 1;
    }
    c
};

/// 8th-order weights.
const B: [f64; 12] = [
    0.054293734116568765,
    0.0,
    0.0,
    0.0,
    0.0,
    4.450312892752409,
    1.8915178993145003,
    -5.801203960010585,
    0.3111643669578199,
    -0.1521609496625161,
    0.20136540080403034,
    0.04471061572777259,
];

/// 3rd-order error weights `b - b_hat3` (the differences from [`B`]).
const E3_SHIFT: [(usize, f64); 3] = [
    (0, 0.2440944881889764),
    (8, 0.7338466882816118),
    (11, 0.022058823529411766),
];

/// 5th-order error weights.
const E5: [f64; 12] = [
    0.01312004499419488,
    0.0,
    0.0,
    0.0,
    0.0,
    -1.2251564463762044,
    -0.4957589496572502,
    1.6643771824549864,
    -0.35032884874997366,
    0.3341791187130175,
    0.08192320648511571,
    -0.022355307863886294,
];

/// The right-hand side `z' = f(z)` of the phase with the contacts `active`
/// (bit `c` for contact `c`, `links[c]` its link), from the physics: each
/// contact's force `F = k p + c p'` from its two sides, `-F` on the lower
/// one and `+F` on the upper one (through its weights on a point of an
/// object, divided by the mass on a point mass, nothing on a wall).
///
/// `surface`: the surface's height and rate `(s(t), s'(t))` under the
/// hammer's contact at this instant, which then adds `k s + c s'` to its
/// force, and the state carries the force's impulse `I' = F` after `z`.
fn rhs(
    model: &Model,
    links: &[Link],
    active: u32,
    surface: Option<(f64, f64)>,
    z: &[f64],
    out: &mut [f64],
) {
    let n = model.n_modes();
    for (i, md) in model.modes.iter().enumerate() {
        let w = md.omega();
        out[i] = z[n + i];
        out[n + i] = -w * w * z[i] - 2.0 * md.sigma() * z[n + i];
    }
    let (g_back, _, v_b) = model.back_force(z);
    out[2 * n] = z[2 * n + 1];
    out[2 * n + 1] = -model.hammer.gravity_m_per_s2 + g_back / model.hammer.mass_kg;
    if let Some(b) = model.back {
        out[2 * n + 2] = v_b;
        out[2 * n + 3] = -model.hammer.gravity_m_per_s2 - g_back / b.mass_kg;
    }
    for i in 1..model.n_masses() {
        let j = model.mass_index(i);
        out[j] = z[j + 1];
        out[j + 1] = -model.mass_of(i).gravity_m_per_s2;
    }
    if surface.is_some() {
        out[model.state_dim()] = 0.0;
    }
    for (c, l) in links.iter().enumerate() {
        if active & (1 << c) == 0 {
            continue;
        }
        let ((x_l, v_l), (x_u, v_u)) = model.sides(l, z);
        let (k, d) = (l.contact.stiffness_n_per_m, l.contact.damping_n_s_per_m);
        let f = match surface {
            Some((s, v)) if c == 0 => {
                let f = k * (x_l + s - x_u) + d * (v_l + v - v_u);
                out[model.state_dim()] = f;
                f
            }
            _ => k * (x_l - x_u) + d * (v_l - v_u),
        };
        for (end, s) in [(&l.lower, -1.0), (&l.upper, 1.0)] {
            match end {
                End::Point(w) => {
                    for (i, w) in w.iter().enumerate() {
                        out[n + i] += s * w * f;
                    }
                }
                End::Mass(i) => {
                    out[model.mass_index(*i) + 1] += s * f / model.mass_of(*i).mass_kg;
                }
                End::Wall(_) => {}
            }
        }
    }
}

/// The integrator's working set for one model.
struct Dop<'a> {
    model: &'a Model,
    /// Every contact as a link ([`Model::link`]), built once.
    links: Vec<Link>,
    /// Absolute tolerance per component of `z` (not of the impulse after
    /// it on a surface, which the error control leaves out).
    atol: Vec<f64>,
    rtol: f64,
    k: [Vec<f64>; 12],
    tmp: Vec<f64>,
    /// The surface over the current sample, `(s_n, v_n)`: height at its
    /// start and rate (`None` without a surface).
    surface: Option<(f64, f64)>,
    /// Time since the sample's start of the state steps start from \[s\].
    t0: f64,
}

impl Dop<'_> {
    /// One step of length `h` from `z` with the contacts `active`: the new
    /// state and the error norm (Hairer's combined 5th/3rd-order estimate;
    /// accept when `<= 1`).
    fn step(&mut self, active: u32, z: &[f64], h: f64) -> (Vec<f64>, f64) {
        let dim = z.len();
        let sf = self.surface_at(0.0);
        rhs(self.model, &self.links, active, sf, z, &mut self.k[0]);
        for s in 1..12 {
            for i in 0..dim {
                let mut acc = 0.0;
                for j in 0..s {
                    acc += A[s][j] * self.k[j][i];
                }
                self.tmp[i] = z[i] + h * acc;
            }
            let sf = self.surface_at(C[s] * h);
            rhs(
                self.model,
                &self.links,
                active,
                sf,
                &self.tmp,
                &mut self.k[s],
            );
        }
        let mut z1 = vec![0.0; dim];
        let (mut e5n, mut e3n) = (0.0, 0.0);
        for i in 0..dim {
            let mut acc = 0.0;
            let mut e5 = 0.0;
            for j in 0..12 {
                acc += B[j] * self.k[j][i];
                e5 += E5[j] * self.k[j][i];
            }
            let mut e3 = acc;
            for (j, d) in E3_SHIFT {
                e3 -= d * self.k[j][i];
            }
            z1[i] = z[i] + h * acc;
            // the impulse (past the tolerances) rides along: a quadrature
            // of the force, as accurate as the state it is of
            if i >= self.atol.len() {
                continue;
            }
            let sc = self.atol[i] + self.rtol * z[i].abs().max(z1[i].abs());
            e5n += (e5 / sc).powi(2);
            e3n += (e3 / sc).powi(2);
        }
        let err = if e5n == 0.0 && e3n == 0.0 {
            0.0
        } else {
            h.abs() * e5n / ((e5n + 0.01 * e3n) * self.atol.len() as f64).sqrt()
        };
        (z1, err)
    }

    /// The surface's height and rate `tau` seconds after [`Dop::t0`]
    /// (linear inside the sample), if any.
    fn surface_at(&self, tau: f64) -> Option<(f64, f64)> {
        self.surface.map(|(s, v)| (s + v * (self.t0 + tau), v))
    }

    /// Contact `c`'s `(p, p')` in `z`, `tau` seconds after [`Dop::t0`].
    fn event(&self, c: usize, z: &[f64], tau: f64) -> (f64, f64) {
        let ((x_l, v_l), (x_u, v_u)) = self.model.sides(&self.links[c], z);
        match self.surface_at(tau) {
            Some((s, v)) if c == 0 => (x_l + s - x_u, v_l + v - v_u),
            _ => (x_l - x_u, v_l - v_u),
        }
    }

    /// Bisection on `[a, b]` for contact `c` (`a` not switched, `b`
    /// switched with state `zb`), trial points re-integrated from `z0` with
    /// the contacts `active`.
    #[allow(clippy::too_many_arguments)]
    fn bisect(
        &mut self,
        active: u32,
        c: usize,
        z0: &[f64],
        mut a: f64,
        mut b: f64,
        mut zb: Vec<f64>,
        tol: f64,
    ) -> (f64, Vec<f64>) {
        let inc = active & (1 << c) != 0;
        loop {
            let mid = 0.5 * (a + b);
            if b - a <= tol || mid <= a || mid >= b {
                return (b, zb);
            }
            let zm = self.step(active, z0, mid).0;
            if switched(inc, self.event(c, &zm, mid).0) {
                b = mid;
                zb = zm;
            } else {
                a = mid;
            }
        }
    }

    /// First switch of any contact inside the accepted step `z0 -> z1` of
    /// length `hs` (the earliest of each contact's first, as the expm
    /// solver takes it).
    fn search(
        &mut self,
        active: u32,
        z0: &[f64],
        z1: &[f64],
        hs: f64,
        tol: f64,
        stats: &mut Stats,
    ) -> Option<(f64, Vec<f64>)> {
        let mut best: Option<(f64, Vec<f64>)> = None;
        for c in 0..self.links.len() {
            if let Some((tau, z)) = self.search_contact(active, c, z0, z1, hs, tol, stats) {
                if best.as_ref().is_none_or(|(b, _)| tau < *b) {
                    best = Some((tau, z));
                }
            }
        }
        best
    }

    /// [`Dop::search`] for contact `c` alone.
    #[allow(clippy::too_many_arguments)]
    fn search_contact(
        &mut self,
        active: u32,
        c: usize,
        z0: &[f64],
        z1: &[f64],
        hs: f64,
        tol: f64,
        stats: &mut Stats,
    ) -> Option<(f64, Vec<f64>)> {
        let inc = active & (1 << c) != 0;
        let (p1, d1) = self.event(c, z1, hs);
        if switched(inc, p1) {
            return Some(self.bisect(active, c, z0, 0.0, hs, z1.to_vec(), tol));
        }
        let (_, d0) = self.event(c, z0, 0.0);
        if !(toward(inc, d0) > 0.0 && toward(inc, d1) <= 0.0) {
            return None;
        }
        stats.extremum_searches += 1;
        let (mut lo, mut hi) = (0.0, hs);
        loop {
            let mid = 0.5 * (lo + hi);
            if hi - lo <= tol || mid <= lo || mid >= hi {
                break;
            }
            let zm = self.step(active, z0, mid).0;
            let (pm, dm) = self.event(c, &zm, mid);
            if switched(inc, pm) {
                return Some(self.bisect(active, c, z0, 0.0, mid, zm, tol));
            }
            if toward(inc, dm) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let zh = self.step(active, z0, hi).0;
        if switched(inc, self.event(c, &zh, hi).0) {
            return Some(self.bisect(active, c, z0, 0.0, hi, zh, tol));
        }
        None
    }
}

/// Inverse mass `1 / m` a side of a contact brings to it: `sum w_i^2` for
/// a point of an object (its mass at the point for a contact much shorter
/// than its modes' periods), `1 / m` for a point mass, 0 for a wall.
fn inv_mass(model: &Model, e: &End) -> f64 {
    match e {
        End::Point(w) => w.iter().map(|w| w * w).sum(),
        End::Mass(i) => 1.0 / model.mass_of(*i).mass_kg,
        End::Wall(_) => 0.0,
    }
}

/// Energy scale of the tolerances \[J\]: what the point masses bring
/// (kinetic plus the fall to height 0).
fn energy_scale(model: &Model) -> f64 {
    let e_s: f64 = (0..model.n_masses())
        .map(|i| {
            let x = model.mass_of(i);
            0.5 * x.mass_kg * x.velocity_m_per_s * x.velocity_m_per_s
                + x.mass_kg * x.gravity_m_per_s2 * x.height_m
        })
        .sum();
    e_s
}

/// The fastest contact's angular frequency \[rad/s\] (for one contact of a
/// hammer on an object: `1/m = 1/m_h + sum w^2`).
fn contact_frequency(model: &Model, links: &[Link]) -> f64 {
    links
        .iter()
        .map(|l| {
            (l.contact.stiffness_n_per_m * (inv_mass(model, &l.lower) + inv_mass(model, &l.upper)))
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// Absolute tolerance of each state component: `rtol` times the
/// component's scale when one body holds all the energy `e_s`, `w_c` the
/// fastest contact's frequency.
fn abs_tolerances(model: &Model, rtol: f64, e_s: f64, w_c: f64) -> Vec<f64> {
    let nm = model.n_modes();
    let mut atol = vec![0.0; model.state_dim()];
    for (i, md) in model.modes.iter().enumerate() {
        // a mode holding all the energy: q' ~ sqrt(2E), q ~ sqrt(2E)/omega
        atol[i] = rtol * (2.0 * e_s).sqrt() / md.omega();
        atol[nm + i] = rtol * (2.0 * e_s).sqrt();
    }
    for i in 0..model.n_masses() {
        // a mass holding all the energy, over a contact's compression
        let x = model.mass_of(i);
        let v_s = (2.0 * e_s / x.mass_kg).sqrt();
        let j = model.mass_index(i);
        atol[j] = rtol * x.height_m.max(v_s / w_c);
        atol[j + 1] = rtol * v_s;
    }
    if model.back.is_some() {
        atol[2 * nm + 2] = atol[2 * nm];
        atol[2 * nm + 3] = atol[2 * nm + 1];
    }
    atol
}

/// A first step length \[s\] per phase (`2^n_links` of them), from the
/// flight's and the contacts' scales, at most the sample period `h`.
fn initial_step_lengths(model: &Model, n_links: usize, w_c: f64, h: f64) -> Vec<f64> {
    let w_max = model.modes.iter().map(|m| m.omega()).fold(0.0, f64::max);
    (0..1u32 << n_links)
        .map(|active| {
            if active == 0 {
                if w_max > 0.0 {
                    (0.1 / w_max).min(h)
                } else {
                    h
                }
            } else {
                (0.1 / (w_c + w_max)).min(h)
            }
        })
        .collect()
}

/// Solve `model` for `n` samples at `rate_hz` with DOP853 at relative
/// tolerance `rtol` (absolute tolerances: `rtol` times each component's
/// scale, from the initial energy; see `abs_tolerances`). Any number of
/// contacts: the first switch of any contact in a step is taken, and every
/// contact switched at that point changes side together, as in the expm
/// solver.
pub fn solve(model: &Model, rate_hz: f64, n: usize, rtol: f64) -> Solution {
    solve_driven(model, None, rate_hz, n, rtol)
}

/// [`solve`] with the hammer's contact on a moving surface (as
/// [`crate::solve_on_surface`]): its height `s(t)` and rate `s'(t)`,
/// linear between the sample instants, enter the contact's force and event
/// function at the time of each stage and trial point, the integration
/// restarts at every sample instant (the rate jumps there), and the force's
/// impulse over each sample is integrated with the state, for the work
/// [`crate::Sample::surface_work_j`].
pub fn solve_on_surface(
    model: &Model,
    surface_m: &[f64],
    rate_hz: f64,
    n: usize,
    rtol: f64,
) -> Solution {
    solve_driven(model, Some(surface_m), rate_hz, n, rtol)
}

/// The state of a run between steps.
struct Walk {
    /// The state (with the impulse after it on a surface).
    z: Vec<f64>,
    /// The contacts in contact.
    active: u32,
    /// The next step's length per phase \[s\].
    h_try: Vec<f64>,
    contacts: Vec<ContactInterval>,
    stats: Stats,
}

/// [`solve`], on the moving surface `surface_m` if any.
fn solve_driven(
    model: &Model,
    surface_m: Option<&[f64]>,
    rate_hz: f64,
    n: usize,
    rtol: f64,
) -> Solution {
    model.check();
    let h = 1.0 / rate_hz;
    if let Some(s) = surface_m {
        assert!(s.len() > n, "surface: {} heights for {n} samples", s.len());
    }
    let links: Vec<Link> = (0..model.n_contacts()).map(|c| model.link(c)).collect();
    let mut e_s = energy_scale(model);
    let mut z = model.initial_state();
    if let Some(s) = surface_m {
        // the surface may give the hammer its own speed
        let v_max = s[..=n]
            .windows(2)
            .map(|w| ((w[1] - w[0]) / h).abs())
            .fold(0.0, f64::max);
        e_s += 0.5 * model.hammer.mass_kg * v_max * v_max;
        z.push(0.0);
    }
    assert!(e_s > 0.0, "DOP853: no energy to scale the tolerances with");
    let dim = z.len();
    let w_c = contact_frequency(model, &links);
    let atol = abs_tolerances(model, rtol, e_s, w_c);
    let mut dop = Dop {
        model,
        links,
        atol,
        rtol,
        k: std::array::from_fn(|_| vec![0.0; dim]),
        tmp: vec![0.0; dim],
        surface: None,
        t0: 0.0,
    };
    let nz = model.state_dim();
    let mut walk = Walk {
        h_try: initial_step_lengths(model, dop.links.len(), w_c, h),
        active: 0,
        contacts: Vec::new(),
        stats: Stats::default(),
        z,
    };
    let mut work = 0.0;
    let mut samples = Vec::with_capacity(n + 1);
    samples.push(model.observe_on(&walk.z[..nz], 0, surface_m.map_or(0.0, |s| s[0])));
    for i in 0..n {
        dop.surface = surface_m.map(|s| (s[i], (s[i + 1] - s[i]) / h));
        if dop.surface.is_some() {
            walk.z[nz] = 0.0;
        }
        dop.sample(&mut walk, i, h);
        let s_end = surface_m.map_or(0.0, |s| s[i + 1]);
        let mut sample = model.observe_on(&walk.z[..nz], walk.active, s_end);
        if let Some((_, v)) = dop.surface {
            work += v * walk.z[nz];
            sample.surface_work_j = work;
        }
        samples.push(sample);
    }
    Solution {
        rate_hz,
        samples,
        contacts: walk.contacts,
        stats: walk.stats,
    }
}

impl Dop<'_> {
    /// Advance `walk` over sample `i` of period `h`, switching contacts at
    /// every switch inside it.
    fn sample(&mut self, walk: &mut Walk, i: usize, h: f64) {
        let tol = crate::TIME_RESOLUTION * h;
        let t_n = i as f64 * h;
        let mut t = 0.0;
        while t < h {
            let a = walk.active as usize;
            let rest = h - t;
            let clipped = walk.h_try[a] >= rest;
            let hs = if clipped { rest } else { walk.h_try[a] };
            self.t0 = t;
            let (z1, err) = self.step(walk.active, &walk.z, hs);
            let fac = 0.9 * err.powf(-1.0 / 8.0);
            if !(err <= 1.0) {
                walk.stats.rejected += 1;
                walk.h_try[a] = hs * fac.clamp(0.2, 1.0);
                continue;
            }
            walk.stats.steps += 1;
            if !clipped {
                walk.h_try[a] = hs * fac.clamp(0.2, 10.0);
            }
            match self.search(walk.active, &walk.z, &z1, hs, tol, &mut walk.stats) {
                None => {
                    walk.z = z1;
                    t = if clipped { h } else { t + hs };
                }
                Some((tau, zs)) => {
                    t = if clipped && tau >= hs { h } else { t + tau };
                    walk.stats.switches += 1;
                    // every contact switched at this point changes side
                    for c in 0..self.links.len() {
                        let inc = walk.active & (1 << c) != 0;
                        if !switched(inc, self.event(c, &zs, tau).0) {
                            continue;
                        }
                        walk.active ^= 1 << c;
                        record_switch(&mut walk.contacts, c, !inc, t_n + t);
                    }
                    walk.z = zs;
                }
            }
        }
    }
}
