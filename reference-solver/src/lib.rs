//! An independent reference solution of the piecewise-linear contact between a
//! point-mass hammer and a modal object (or a rigid wall), and of several
//! such contacts between objects, point masses and walls, for testing the
//! `modal_contact` engine's exact switching at any contact stiffness.
//!
//! It shares nothing with the engine but the scene's numbers: its own model
//! description ([`Model`]), its own phase matrices in *physical* coordinates
//! `z = [q; q'; x_h; v_h]` (then the back mass's, the extra hammers' and the
//! masses' `x, v`; the engine works in energy coordinates), dense
//! matrix exponentials instead of eigen-decompositions, and bisection
//! instead of the engine's certified Newton search. The exponentials of the
//! sub-steps are taken twice, by nalgebra's Pade `exp` (f64, marching the
//! state between exact points) and by their Taylor series in double-double
//! (the exact states, see `dd`), which must agree when a phase is built: in
//! physical coordinates a stiff phase's f64 propagators carry `u |B| t` of
//! error, up to 1e-11 per sample at 1000x Nyquist, which the ill-conditioned
//! releases of overdamped contacts turned into 1e-6-sample errors. The phase
//! matrices' entries are double-double as well: the contact force `k (x_c -
//! x_h) + ...` is a small difference of large terms, and a matrix rounded to
//! f64 entry by entry is a slightly different contact (a heavy hammer pressed
//! into a light object through a stiff damped contact moved by 1e-8 relative
//! in 50 ms, which no sub-step length changed). A second,
//! unrelated integrator ([`dop853`], explicit Runge-Kutta with error
//! control) checks this one in the unit tests, together with closed forms
//! for a hammer on a rigid wall and the independence of the result from the
//! sub-step length.
//!
//! Conventions (the project's): SI units, one vertical axis, positive up.
//! Penetration `p = x_c - x_h` (object contact point minus hammer face). While
//! in contact the force on the hammer is `F = k p + c p'` (up) and the object
//! feels `-F` at the contact point; out of contact there is no force. Gravity
//! pulls the point masses only (each its own `g`), never the objects. A
//! [`Link`] is the same contact between any two bodies: `p = x_lower -
//! x_upper - gap`, `+F` on the upper side and `-F` on the lower one, where a
//! side is a point of an object (displacement `sum w_i q_i` from rest), a
//! point mass (its height) or a rigid wall (a fixed height, which takes the
//! force and does not move); the hammer's own contact is the link from its
//! contact point up to the hammer, gap 0 ([`Model::link`]).
//!
//! Physics (unit modal masses): `q_i'' + 2 sigma_i q_i' + omega_i^2 q_i = w_i
//! F_obj` with `sigma_i = ln(1000) / T60_i`, `omega_i = 2 pi f_i`, contact
//! displacement `x_c = sum w_i q_i`; hammer `m_h x_h'' = -m_h g + F_h`. Energy
//! `0.5 sum(q_i'^2 + omega_i^2 q_i^2) + 0.5 m_h v_h^2 + m_h g x_h` plus
//! `0.5 k p^2` in contact. With several contacts each object mode takes
//! `w_i F` of every contact at one of its points (the weights of a point on
//! the modes of other objects are 0), each point mass `m x'' = -m g +` the
//! forces of its contacts, and the energy adds every point mass's `0.5 m
//! v^2 + m g x` and every contact's `0.5 k p^2` (gap included) while in
//! contact.
//!
//! Switching (the engine's semantics): flight becomes contact when `p` crosses
//! from `<= 0` to `> 0`; contact becomes flight when `p` returns to `<= 0`
//! (position-based release, so a damper pulling just before release is
//! allowed). A touch at zero relative speed that does not cross is no
//! contact. Positions and velocities never jump at a switch.
//!
//! Beyond the paper's scene (for the engine's next steps, issue 17): a
//! second mass behind the hammer's face ([`BackMass`], a mallet with a ring
//! of its own), more hammers with contacts of their own on the same object
//! ([`ExtraHammer`]), more point masses without a contact of their own
//! ([`Model::masses`]), and links between any two bodies ([`Link`]: an
//! object against another object, a mass against a mass, a ball between
//! two plates, a mass on a wall or under a ceiling), up to four contacts in
//! all ([`MAX_EXTRA`] beside the hammer's). The modes of several objects
//! are concatenated in [`Model::modes`]. A gap or a wall's height is a
//! constant in the penetration: it goes into the phase matrices' affine
//! column beside gravity, and into the event function's constant term. With
//! several contacts each phase is a subset of contacts in contact (all
//! `2^K` phases are built up front), each contact has its own event
//! function, the first switch of any contact in a step is taken, and every
//! contact switched at that instant changes side together. DOP853 does the
//! same from its own right-hand side and checks links of every kind
//! (object-object, a ball between two plates, walls); several contacts are
//! also checked by the separable case (two contacts on two objects are two
//! runs), by energy and momentum and symmetry, and a link restating the
//! hammer's contact is that contact bit for bit (`tests.rs`).
//!
//! A moving surface ([`solve_on_surface`], [`dop853::solve_on_surface`]):
//! the hammer's own contact may sit on a surface whose height `s(t)` under
//! the contact point moves with time (rolling, scraping). The penetration
//! of that contact becomes `p = x_c + s(t) - x_h`, its force `F = k p + c
//! p'` with `p' = v_c + s'(t) - v_h`, on the hammer up and on the object
//! down at the contact point as before; out of contact the surface does
//! nothing, and the switching semantics are the same with `s` in `p`. The
//! surface is given by its heights `s_n` at the sample instants `t_n = n /
//! rate` (at least `N + 1` of them for `N` samples) and is linear in
//! between (first-order hold): on `[t_n, t_n+1]`, `s = s_n + v_n (t -
//! t_n)`, `v_n = (s_n+1 - s_n) rate`, so its rate jumps at the sample
//! instants. Without a surface (or where it rests at 0 over a whole
//! sample) the solvers do exactly what they do without one.
//!
//! The expm solver solves each sample exactly with the input: the state of
//! a driven phase is `[z; s; v; I; 1]`, `s' = v`, `v' = 0` inside the
//! sample, the contact force's row takes `k` in the column of `s` and `c`
//! in that of `v`, and `I' = F` is the force's impulse since the sample's
//! start. Its exponential is taken and checked as the other phases' (in
//! double-double, against Pade in f64); `s` and `v` are set to `s_n` and
//! `v_n` (double-double, `(s_n+1 - s_n) / h`, so that the flow reaches
//! `s_n+1` at the sample's end) and `I` to 0 at every sample's start, and
//! the events (crossings of `p`, `s` included) are found on the sub-steps
//! by the same bisection. DOP853 evaluates `s(t)` and `s'(t)` in its own
//! right-hand side at each stage's instant, restarts at every sample
//! instant (it lands on them anyway), and integrates `I' = F` beside the
//! state, outside its error control.
//!
//! Work and energy: [`Sample::surface_work_j`] is the work done by the
//! surface since the start, `W(t) = integral of F s'(t) dt`; inside a
//! sample the rate is the constant `v_n`, so the sample adds `v_n` times
//! the force's impulse over it, taken from the integral state `I` (not from
//! the hammer's momentum, which a back mass or a link on the hammer would
//! also change). [`Sample::energy`] stays the lab-frame energy (the
//! hammer's `0.5 m v_h^2 + m g x_h`, the modes', and `0.5 k p^2` in
//! contact with `s` in `p`), so that `E(t) - E(0) = W(t)` less what the
//! dampers take (`c p'^2` and the modes' decay).

mod dd;
pub mod dop853;
mod expm;
mod phase;
#[cfg(test)]
mod tests;

pub use expm::{solve, solve_on_surface, solve_with_substeps};

/// One mode of a modal object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Frequency \[Hz\].
    pub freq_hz: f64,
    /// 60 dB decay time \[s\]; `None` = undamped.
    pub t60_s: Option<f64>,
    /// Mass-normalised weight at the contact point [1/sqrt(kg)].
    pub weight: f64,
}

impl Mode {
    /// Angular frequency `omega = 2 pi f` [rad/s].
    pub fn omega(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.freq_hz
    }

    /// Decay rate `sigma = ln(1000) / T60` [1/s] (0 when undamped).
    pub fn sigma(&self) -> f64 {
        self.t60_s.map_or(0.0, |t| 1000f64.ln() / t)
    }
}

/// The point-mass hammer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hammer {
    /// Mass \[kg\].
    pub mass_kg: f64,
    /// Initial height of the contact face \[m\] (the object starts at rest at 0).
    pub height_m: f64,
    /// Initial velocity [m/s], positive up.
    pub velocity_m_per_s: f64,
    /// Gravity [m/s^2] pulling the hammer down (0 = none).
    pub gravity_m_per_s2: f64,
}

/// The linear contact spring-damper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Stiffness `k` [N/m].
    pub stiffness_n_per_m: f64,
    /// Damping `c` [N s/m].
    pub damping_n_s_per_m: f64,
}

/// A second point mass behind the hammer's face, joined to it by a
/// spring-damper: the simplest mallet with a ring of its own (a head on a
/// flexible shaft, lumped), in physical coordinates. Its position `x_b` is
/// measured from where it rests relative to the face, so the spring pulls
/// with `k_s (x_b - x_h) + c_s (v_b - v_h)`; gravity pulls it too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BackMass {
    /// Mass \[kg\].
    pub mass_kg: f64,
    /// Spring to the face \[N/m\].
    pub spring_n_per_m: f64,
    /// Dashpot to the face \[N s/m\].
    pub damping_n_s_per_m: f64,
}

/// Another point-mass hammer with a contact of its own on the same modal
/// object (several contacts at once): its own contact point (a weight per
/// mode) and contact law. Its state `x_k, v_k` follows the first hammer's
/// (and the back mass's) in `z`.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraHammer {
    /// The hammer.
    pub hammer: Hammer,
    /// Each mode's weight at this hammer's contact point [1/sqrt(kg)].
    pub weights: Vec<f64>,
    /// The contact law.
    pub contact: Contact,
}

/// One side of a link.
#[derive(Debug, Clone, PartialEq)]
pub enum End {
    /// A point of the modal object(s): one weight per mode of `Model::modes` (all modes; zeros on modes of other objects).
    Point(Vec<f64>),
    /// A point mass: 0 the hammer, 1..=extra.len() the extra hammers, then `masses[k]` is extra.len() + 1 + k.
    Mass(usize),
    /// A rigid wall at this height \[m\].
    Wall(f64),
}

/// A contact between two bodies: penetration `p = x(lower) - x(upper) -
/// gap_m`; in contact (`p > 0` crossing semantics exactly as the existing
/// contacts) the force `F = k p + c p'` pushes `upper` up (`+F`) and `lower`
/// down (`-F`); a Point side receives the force through its weights (`q_i''
/// += w_i` times the force on it); a Wall side receives nothing.
///
/// Positions are displacements from rest for a point of an object and
/// heights for a point mass, so `gap_m` is the clearance at rest: a point
/// of another object `d` above this one's at rest touches it when `x(lower)
/// - x(upper) > d`. A hammer's own contact is the link `lower =` its
/// contact point, `upper =` the hammer, gap 0 ([`Model::link`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// The side pushed down.
    pub lower: End,
    /// The side pushed up.
    pub upper: End,
    /// Offset of the penetration \[m\] (clearance at rest; negative for an
    /// overlap, e.g. the thickness of a mass whose height is its bottom face).
    pub gap_m: f64,
    /// The contact law.
    pub contact: Contact,
}

/// Most contacts beyond the hammer's (extra hammers and links together: at
/// most four contacts).
pub const MAX_EXTRA: usize = 3;

/// A scene: a modal object (no modes = a rigid wall at height 0), a hammer
/// and the contact between them, and up to [`MAX_EXTRA`] more contacts:
/// hammers with contacts of their own, and links between any two bodies
/// (points of the objects, point masses, walls).
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// The modes of the struck object (of several objects, concatenated:
    /// each contact point weighs 0 on the modes of the other objects);
    /// empty for a rigid wall.
    pub modes: Vec<Mode>,
    /// The hammer (with a back mass: its face).
    pub hammer: Hammer,
    /// The contact law.
    pub contact: Contact,
    /// A mass behind the face, `None` for a point-mass hammer. The
    /// physical state is then `[q; q'; x_h; v_h; x_b; v_b]`.
    pub back: Option<BackMass>,
    /// More hammers with contacts of their own (contact `k + 1` is
    /// `extra[k]`'s); empty for the one contact of the paper.
    pub extra: Vec<ExtraHammer>,
    /// More point masses without a contact of their own (mass
    /// `extra.len() + 1 + k` of [`End::Mass`]): each with its own initial
    /// height, velocity and gravity, state `x, v` after the extra hammers'
    /// in `z`. They touch anything through [`Model::links`] only.
    pub masses: Vec<Hammer>,
    /// Contacts between any two bodies (contact `extra.len() + 1 + k` is
    /// `links[k]`).
    pub links: Vec<Link>,
}

impl Model {
    /// Number of modes `N` (the physical state has `2 N + 2` entries, `2 N
    /// + 4` with a back mass, and two per extra hammer and per mass).
    pub fn n_modes(&self) -> usize {
        self.modes.len()
    }

    /// Length of the physical state `z`.
    pub fn state_dim(&self) -> usize {
        2 * self.n_modes()
            + 2
            + if self.back.is_some() { 2 } else { 0 }
            + 2 * self.extra.len()
            + 2 * self.masses.len()
    }

    /// Number of contacts (1 + extra hammers + links).
    pub fn n_contacts(&self) -> usize {
        1 + self.extra.len() + self.links.len()
    }

    /// Number of point masses [`End::Mass`] can name (the hammer, the extra
    /// hammers, the masses; not the back mass, which touches nothing).
    pub fn n_masses(&self) -> usize {
        1 + self.extra.len() + self.masses.len()
    }

    /// Index of point mass `i`'s height in `z` (its velocity follows): the
    /// hammer's after the modes, the others' after the back mass's, in
    /// order.
    pub fn mass_index(&self, i: usize) -> usize {
        let n = self.n_modes();
        if i == 0 {
            2 * n
        } else {
            2 * n + 2 + if self.back.is_some() { 2 } else { 0 } + 2 * (i - 1)
        }
    }

    /// Point mass `i` (numbered as in [`End::Mass`]).
    pub fn mass_of(&self, i: usize) -> &Hammer {
        let e = self.extra.len();
        if i == 0 {
            &self.hammer
        } else if i <= e {
            &self.extra[i - 1].hammer
        } else {
            &self.masses[i - 1 - e]
        }
    }

    /// Contact `c`'s law.
    pub fn contact_of(&self, c: usize) -> &Contact {
        let e = self.extra.len();
        if c == 0 {
            &self.contact
        } else if c <= e {
            &self.extra[c - 1].contact
        } else {
            &self.links[c - 1 - e].contact
        }
    }

    /// Contact `c` as a link: a hammer's contact (`c <= extra.len()`) is
    /// the link from its contact point (lower) to the hammer (upper) with no
    /// gap, so that every contact is handled by the same code (phase
    /// matrices, event rows, right-hand side).
    pub fn link(&self, c: usize) -> Link {
        let e = self.extra.len();
        if c == 0 {
            Link {
                lower: End::Point(self.modes.iter().map(|m| m.weight).collect()),
                upper: End::Mass(0),
                gap_m: 0.0,
                contact: self.contact,
            }
        } else if c <= e {
            Link {
                lower: End::Point(self.extra[c - 1].weights.clone()),
                upper: End::Mass(c),
                gap_m: 0.0,
                contact: self.extra[c - 1].contact,
            }
        } else {
            self.links[c - 1 - e].clone()
        }
    }

    /// Position and velocity of one side in `z`: a point's weighted sums of
    /// the modes, a mass's entries, a wall's height at rest.
    pub fn side(&self, e: &End, z: &[f64]) -> (f64, f64) {
        match e {
            End::Point(w) => {
                let n = self.n_modes();
                let (mut x, mut v) = (0.0, 0.0);
                for (i, w) in w.iter().enumerate() {
                    x += w * z[i];
                    v += w * z[n + i];
                }
                (x, v)
            }
            End::Mass(i) => {
                let j = self.mass_index(*i);
                (z[j], z[j + 1])
            }
            End::Wall(h) => (*h, 0.0),
        }
    }

    /// The two sides of link `l` in `z`: `((x_lower - gap, v_lower),
    /// (x_upper, v_upper))`, so that `p = first.0 - second.0` and `p' =
    /// first.1 - second.1` (see [`Model::contact_pair`]).
    pub fn sides(&self, l: &Link, z: &[f64]) -> ((f64, f64), (f64, f64)) {
        let (x_l, v_l) = self.side(&l.lower, z);
        ((x_l - l.gap_m, v_l), self.side(&l.upper, z))
    }

    /// Contact `c`'s lower side (for a hammer's contact: its contact point's
    /// displacement and velocity) less the gap, and its upper side (the
    /// hammer's height and velocity): the penetration is `first.0 -
    /// second.0`.
    pub fn contact_pair(&self, c: usize, z: &[f64]) -> ((f64, f64), (f64, f64)) {
        self.sides(&self.link(c), z)
    }

    /// Checks the model's shape (panics with the reason): at most four
    /// contacts, a weight per mode at every point, masses that exist, and
    /// links between two different bodies.
    pub fn check(&self) {
        assert!(
            self.n_contacts() <= MAX_EXTRA + 1,
            "at most {} contacts (extra hammers and links), not {}",
            MAX_EXTRA + 1,
            self.n_contacts()
        );
        let n = self.n_modes();
        for (k, x) in self.extra.iter().enumerate() {
            assert_eq!(x.weights.len(), n, "extra hammer {k}: one weight per mode");
        }
        for (k, l) in self.links.iter().enumerate() {
            for e in [&l.lower, &l.upper] {
                match e {
                    End::Point(w) => {
                        assert_eq!(w.len(), n, "link {k}: one weight per mode at a point")
                    }
                    End::Mass(i) => assert!(
                        *i < self.n_masses(),
                        "link {k}: mass {i} of {}",
                        self.n_masses()
                    ),
                    End::Wall(_) => {}
                }
            }
            assert!(
                !matches!((&l.lower, &l.upper), (End::Wall(_), End::Wall(_))),
                "link {k}: two walls"
            );
            assert!(
                !matches!((&l.lower, &l.upper), (End::Mass(a), End::Mass(b)) if a == b),
                "link {k}: a mass against itself"
            );
        }
    }

    /// Energy with the springs of the contacts in the bit set `active`: the
    /// first hammer's part ([`Model::energy`]), every other point mass's
    /// kinetic and gravitational energy, and each other active contact's
    /// `0.5 k p^2`.
    pub fn energy_of(&self, z: &[f64], active: u32) -> f64 {
        self.energy_on(z, active, 0.0)
    }

    /// [`Model::energy_of`] with the surface at height `surface_m` under
    /// the hammer's contact (its spring's `p` includes it).
    pub(crate) fn energy_on(&self, z: &[f64], active: u32, surface_m: f64) -> f64 {
        let mut e = self.energy_at(z, active & 1 != 0, surface_m);
        for i in 1..self.n_masses() {
            let j = self.mass_index(i);
            let (x, v) = (z[j], z[j + 1]);
            let h = self.mass_of(i);
            let m = h.mass_kg;
            e += 0.5 * m * v * v + m * h.gravity_m_per_s2 * x;
        }
        for c in (1..self.n_contacts()).filter(|c| active & (1 << c) != 0) {
            let ((x_l, _), (x_u, _)) = self.contact_pair(c, z);
            let p = x_l - x_u;
            e += 0.5 * self.contact_of(c).stiffness_n_per_m * p * p;
        }
        e
    }

    /// Force of the back mass's spring-damper on the face (up) in `z`, and
    /// the back mass's position and velocity (zeros without one).
    pub fn back_force(&self, z: &[f64]) -> (f64, f64, f64) {
        let n = self.n_modes();
        match self.back {
            Some(b) => {
                let (x_b, v_b) = (z[2 * n + 2], z[2 * n + 3]);
                let f = b.spring_n_per_m * (x_b - z[2 * n])
                    + b.damping_n_s_per_m * (v_b - z[2 * n + 1]);
                (f, x_b, v_b)
            }
            None => (0.0, 0.0, 0.0),
        }
    }

    /// Total energy \[J\] of the physical state `z = [q; q'; x_h; v_h]`, with
    /// the contact spring's `0.5 k p^2` when `in_contact` (the first
    /// hammer's part only: [`Model::energy_of`] adds the other point
    /// masses and contacts).
    pub fn energy(&self, z: &[f64], in_contact: bool) -> f64 {
        self.energy_at(z, in_contact, 0.0)
    }

    /// [`Model::energy`] with the surface at height `surface_m` under the
    /// contact: the spring's `p = x_c + s - x_h`.
    fn energy_at(&self, z: &[f64], in_contact: bool, surface_m: f64) -> f64 {
        let n = self.n_modes();
        let mut e = 0.0;
        for (i, md) in self.modes.iter().enumerate() {
            let w = md.omega();
            e += 0.5 * (z[n + i] * z[n + i] + w * w * z[i] * z[i]);
        }
        let (x_h, v_h) = (z[2 * n], z[2 * n + 1]);
        let m = self.hammer.mass_kg;
        e += 0.5 * m * v_h * v_h + m * self.hammer.gravity_m_per_s2 * x_h;
        if let Some(b) = self.back {
            let (x_b, v_b) = (z[2 * n + 2], z[2 * n + 3]);
            let s = x_b - x_h;
            e += 0.5 * b.mass_kg * v_b * v_b
                + b.mass_kg * self.hammer.gravity_m_per_s2 * x_b
                + 0.5 * b.spring_n_per_m * s * s;
        }
        if in_contact {
            let p = self.penetration(z) + surface_m;
            e += 0.5 * self.contact.stiffness_n_per_m * p * p;
        }
        e
    }

    /// Contact-point displacement and velocity `(x_c, v_c)` of `z`.
    pub fn contact_point(&self, z: &[f64]) -> (f64, f64) {
        let n = self.n_modes();
        let mut x = 0.0;
        let mut v = 0.0;
        for (i, md) in self.modes.iter().enumerate() {
            x += md.weight * z[i];
            v += md.weight * z[n + i];
        }
        (x, v)
    }

    /// Penetration `p = x_c - x_h` of `z`.
    pub fn penetration(&self, z: &[f64]) -> f64 {
        self.contact_point(z).0 - z[2 * self.n_modes()]
    }

    /// Initial physical state: objects at rest, every point mass at its
    /// initial height and velocity.
    pub fn initial_state(&self) -> Vec<f64> {
        let n = self.n_modes();
        let mut z = vec![0.0; self.state_dim()];
        z[2 * n] = self.hammer.height_m;
        z[2 * n + 1] = self.hammer.velocity_m_per_s;
        if self.back.is_some() {
            // at rest relative to the face, moving with it
            z[2 * n + 2] = self.hammer.height_m;
            z[2 * n + 3] = self.hammer.velocity_m_per_s;
        }
        for i in 1..self.n_masses() {
            let (j, h) = (self.mass_index(i), self.mass_of(i));
            z[j] = h.height_m;
            z[j + 1] = h.velocity_m_per_s;
        }
        z
    }

    /// The same model slightly disturbed, to measure how fast the motion
    /// forgets its initial state (see [`horizon`]): under gravity with a
    /// non-zero initial height, the height scaled by `1 + rel`; otherwise the
    /// hammer mass scaled by `1 + rel`.
    ///
    /// Why not always the initial height or velocity: without gravity the
    /// system is homogeneous (the switching surface `p = 0` and every force
    /// are linear, the object starts at rest), so scaling the initial
    /// velocity scales the whole solution and changes no contact instant,
    /// and autonomous, so a different initial height only shifts the whole
    /// motion in time. Neither grows, however chaotic the motion, and the
    /// horizon would measure rounding instead. Gravity breaks both
    /// symmetries; the mass perturbation breaks them everywhere.
    ///
    /// The [`Model::masses`] are disturbed the same way, each by its own
    /// rule: a scene may leave the hammer out of the motion (parked, its
    /// contact never touched) and play entirely between masses and links,
    /// where a disturbed hammer alone would change nothing. (A gap or a
    /// wall off 0 breaks the homogeneity too, but not the autonomy.) The
    /// extra hammers are left as they were, so that scenes without masses
    /// are disturbed as before.
    pub fn perturbed(&self, rel: f64) -> Model {
        let mut m = self.clone();
        for h in std::iter::once(&mut m.hammer).chain(m.masses.iter_mut()) {
            if h.gravity_m_per_s2 > 0.0 && h.height_m != 0.0 {
                h.height_m *= 1.0 + rel;
            } else {
                h.mass_kg *= 1.0 + rel;
            }
        }
        m
    }

    /// The observation of `z` with the contacts in `active` (see
    /// [`Sample`]).
    pub fn observe_of(&self, z: &[f64], active: u32) -> Sample {
        self.observe_on(z, active, 0.0)
    }

    /// [`Model::observe_of`] with the surface at height `surface_m` under
    /// the hammer's contact (in the energy, and in [`Sample::surface_m`];
    /// the work is the solver's to fill in).
    pub(crate) fn observe_on(&self, z: &[f64], active: u32, surface_m: f64) -> Sample {
        let mut s = self.observe(z, active & 1 != 0);
        s.energy = self.energy_on(z, active, surface_m);
        s.surface_m = surface_m;
        s.active = active;
        for c in 1..self.n_contacts() {
            let l = self.link(c);
            let (x_u, v_u) = self.side(&l.upper, z);
            let (x_l, v_l) = self.side(&l.lower, z);
            s.extra[c - 1] = [x_u, v_u, x_l, v_l];
        }
        s
    }

    /// The observation of `z` at time `t` (see [`Sample`]).
    pub fn observe(&self, z: &[f64], in_contact: bool) -> Sample {
        let n = self.n_modes();
        let (x_c, v_c) = self.contact_point(z);
        let (_, x_back, v_back) = self.back_force(z);
        Sample {
            x_back,
            v_back,
            active: in_contact as u32,
            extra: [[0.0; 4]; MAX_EXTRA],
            x_hammer: z[2 * n],
            v_hammer: z[2 * n + 1],
            x_contact: x_c,
            v_contact: v_c,
            in_contact,
            energy: self.energy(z, in_contact),
            surface_m: 0.0,
            surface_work_j: 0.0,
        }
    }
}

/// The state at one sample instant, physical units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Hammer contact-face height \[m\].
    pub x_hammer: f64,
    /// Hammer velocity [m/s].
    pub v_hammer: f64,
    /// Object displacement at the contact point \[m\].
    pub x_contact: f64,
    /// Object velocity at the contact point [m/s].
    pub v_contact: f64,
    /// In contact at this instant (after any switch located exactly here).
    pub in_contact: bool,
    /// Total energy \[J\] (lab frame: on a moving surface the hammer's
    /// contact spring's `0.5 k p^2` has the surface in `p`).
    pub energy: f64,
    /// Back mass position \[m\] (0 without one).
    pub x_back: f64,
    /// Back mass velocity \[m/s\] (0 without one).
    pub v_back: f64,
    /// The contacts in contact (bit `c` for contact `c`).
    pub active: u32,
    /// Contact `c + 1`'s upper side's height and velocity and its lower
    /// side's (the gap not subtracted): for an extra hammer, the hammer's
    /// height and velocity and its contact point's displacement and
    /// velocity, as the first contact's columns above; for a link, its
    /// [`Link::upper`] in the "hammer" columns and its [`Link::lower`] in
    /// the "contact point" columns (a wall: its height, velocity 0). Zeros
    /// past the model's contacts.
    pub extra: [[f64; 4]; MAX_EXTRA],
    /// Height of the moving surface under the hammer's contact \[m\] (0
    /// without a surface; see [`solve_on_surface`]).
    pub surface_m: f64,
    /// Work done by the moving surface on the bodies since the start \[J\]:
    /// `integral of F v dt`, `F` the hammer's contact force, `v` the
    /// surface's rate (0 without a surface).
    pub surface_work_j: f64,
}

/// One contact: from `start_s` to `end_s` \[s\], `end_s = None` if still in
/// contact at the end of the run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactInterval {
    /// Which contact (0: the first hammer's).
    pub contact: usize,
    /// Instant the penetration became positive \[s\].
    pub start_s: f64,
    /// Instant it returned to zero \[s\], if it did within the run.
    pub end_s: Option<f64>,
}

/// What a solver did (diagnostics).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    /// Sub-steps per sample in flight and in contact (expm solver; 0 for
    /// the adaptive one).
    pub substeps_per_sample: [usize; 2],
    /// Steps taken (sub-steps, partial steps, accepted adaptive steps).
    pub steps: u64,
    /// Rejected adaptive steps (0 for the expm solver).
    pub rejected: u64,
    /// Switches located.
    pub switches: u64,
    /// Interior extrema of the penetration searched for a hidden crossing.
    pub extremum_searches: u64,
    /// Balanced norms `|B|_1` of the flight and contact matrices [1/s]
    /// (expm solver).
    pub norms: [f64; 2],
}

/// A run of `n` samples: `n + 1` rows (row 0 = initial state) and the contact
/// intervals.
#[derive(Debug, Clone)]
pub struct Solution {
    /// Sample rate \[Hz\] of the rows.
    pub rate_hz: f64,
    /// State at every sample instant `i / rate_hz`, `i = 0..=n`.
    pub samples: Vec<Sample>,
    /// Every contact, in order.
    pub contacts: Vec<ContactInterval>,
    /// Diagnostics.
    pub stats: Stats,
}

impl Solution {
    /// Hammer height per row.
    pub fn x_hammer(&self) -> Vec<f64> {
        self.samples.iter().map(|s| s.x_hammer).collect()
    }

    /// Hammer velocity per row.
    pub fn v_hammer(&self) -> Vec<f64> {
        self.samples.iter().map(|s| s.v_hammer).collect()
    }

    /// Contact-point displacement per row.
    pub fn x_contact(&self) -> Vec<f64> {
        self.samples.iter().map(|s| s.x_contact).collect()
    }
}

/// Predictability horizon of two runs of the same length: the largest
/// sample index `N` such that over the window `[0, N]` the relative L2
/// difference (`|a - b| / |b|`, a window where both are zero agrees) of each
/// of hammer height, hammer velocity and contact-point displacement is at
/// most `tol`, and so is each of the same three columns of every other
/// contact ([`Sample::extra`]: upper side's height and velocity, lower
/// side's height; all zeros, so agreeing, past the model's contacts). A
/// link's bodies can rattle on their own while the hammer flies free.
///
/// With `b` a run of [`Model::perturbed`] by a tiny relative amount, this is
/// where the motion stops being predictable: a chaotic rattle amplifies any
/// difference (rounding, or another correct solver's truncation error) by the
/// same factor, so two correct solvers may only be compared on the window
/// where a perturbation much larger than their errors has not yet grown past
/// the comparison tolerance. The largest agreeing window, not the first
/// failing one: just after the first contact starts, the contact-point
/// displacement is tiny and a shifted start is a large relative difference
/// for a few samples, which longer windows average out.
pub fn horizon(a: &Solution, b: &Solution, tol: f64) -> usize {
    const K: usize = 3 * (MAX_EXTRA + 1);
    let trace = |s: &Sample, k: usize| match k {
        0 => s.x_hammer,
        1 => s.v_hammer,
        2 => s.x_contact,
        _ => s.extra[k / 3 - 1][k % 3],
    };
    let mut num = [0.0; K];
    let mut den = [0.0; K];
    let mut last = 0;
    let len = a.samples.len().min(b.samples.len());
    for i in 0..len {
        let mut agree = true;
        for k in 0..K {
            let (x, y) = (trace(&a.samples[i], k), trace(&b.samples[i], k));
            num[k] += (x - y) * (x - y);
            den[k] += y * y;
            agree &= num[k] <= tol * tol * den[k];
        }
        if agree {
            last = i;
        }
    }
    last
}

/// Record that contact `c` switched at `t_s`: a new interval when it
/// `entered`, else the end of its open one (both solvers' bookkeeping).
pub(crate) fn record_switch(
    contacts: &mut Vec<ContactInterval>,
    c: usize,
    entered: bool,
    t_s: f64,
) {
    if entered {
        contacts.push(ContactInterval {
            contact: c,
            start_s: t_s,
            end_s: None,
        });
    } else if let Some(open) = contacts
        .iter_mut()
        .rev()
        .find(|x| x.contact == c && x.end_s.is_none())
    {
        open.end_s = Some(t_s);
    }
}

/// Which side of the switching surface counts as "switched" in each phase:
/// in flight the state has switched once `p > 0`, in contact once `p <= 0`.
#[inline]
pub(crate) fn switched(in_contact: bool, p: f64) -> bool {
    if in_contact {
        p <= 0.0
    } else {
        p > 0.0
    }
}

/// Rate at which `p` moves toward switching (`p'` in flight, `-p'` in
/// contact): an interior maximum of it means a hidden crossing is possible.
#[inline]
pub(crate) fn toward(in_contact: bool, dp: f64) -> f64 {
    if in_contact {
        -dp
    } else {
        dp
    }
}

/// Time resolution of located switches, as a fraction of a sample period:
/// `1e-15`, about the rounding of a time inside a sample.
pub const TIME_RESOLUTION: f64 = 1e-15;
