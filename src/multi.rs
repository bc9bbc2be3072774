//! Several contacts at once: one modal object struck by up to
//! [`MAX_CONTACTS`] point-mass hammers, each through a linear spring-damper
//! of its own at a point of its own (two mallets of a roll, one note
//! striking twice). Every subset of contacts in contact is a phase (up to
//! 16), compiled up front; each contact has its own event function, the
//! first switch of any contact in a sample is located and taken, and every
//! contact that switches at that instant changes side together. The first
//! stage of several contacts (docs/numerics.md section 14; the scene key
//! `[[striker]]` and the render command: docs/design.md "Several
//! contacts"), checked against the independent reference solver
//! (`tests/multi_contact.rs`); the instrument and the plugin play one
//! contact ([`crate::engine`]).
//!
//! Coordinates (energy coordinates, the one-contact engine's): mode `i`
//! (unit modal mass, `q_i'' + 2 sigma_i q_i' + omega_i^2 q_i = f_i`) is
//! `a_i = omega_i q_i`, `b_i = q_i'`; a hammer in contact adds `eta_j =
//! sqrt(m_j) v_j` and `pi_j = sqrt(k_j) p_j` (`p_j = x_c,j - x_j` its
//! penetration). The energy of a phase's state `y` is `|y|^2 / 2` plus each
//! hammer's weight `m_j g x_j`; a hammer out of contact flies on its own
//! (`x_j + v_j t - g t^2 / 2`, exactly). Each phase's generator is passive
//! (skew-symmetric plus `-c_j u_j u_j^T`, `p_j' = u_j . y`) and is
//! decomposed into real 2x2 blocks (`y = V s + y*`, `y*` gravity's
//! equilibrium); a sample is one closed-form block exponential per block.
//!
//! Switching, the reference solver's semantics: flight becomes contact when
//! `p_j` crosses from `<= 0` to `> 0`, contact becomes flight when it
//! returns to `<= 0`. Entering, the spring starts unstretched (`pi_j = 0`:
//! nothing added); leaving at `p_j <= 0`, the hammer keeps its position and
//! velocity and the spring's `pi_j^2 / 2 <= ` rounding is dropped. So no
//! switch adds energy, and the phases are passive.
//!
//! The search for the first crossing of a contact's event function `psi`
//! (its penetration, signed to be positive on the current side) within a
//! step is certified: over a piece `|psi''| <= M = sum_k |r_k G_k^2|
//! e^(gamma_k h) |s_k| (+ g)` (`r` the function's row, `gamma_k` the
//! block's growth rate, 0 for a contraction, `|s_k|` at the piece's left
//! end), so a piece `[a, b]` whose ends are both above its margin (per
//! block the smaller of the curvature's `M_k (b - a)^2 / 8` and `2 |r_k|
//! |s_k|`) less the rounding band holds no crossing; a piece that crosses
//! and on which `psi` falls all the way holds one, found by regula falsi;
//! other pieces are halved, left first, down to a width of about one ulp
//! of the sample (docs/numerics.md section 14). A contact that just
//! switched starts at 0 on its new side: its Taylor bound `psi >= psi'(0)
//! t - M t^2 / 2` clears `(0, 2 psi'(0) / M)` first (without it, the
//! rounding of the change of basis could switch it straight back).

use crate::compile::{pan_gains, CompileBudget};
use crate::physics::block::{exp2, mul2, sym_growth, Mat2};
use crate::physics::decomp::{decompose_via, Form};
use crate::physics::model::LN_1000;
use crate::scene::{ObjectSpec, Quantity, Scene, SceneError};
use nalgebra::DMatrix;

/// Most contacts of one scene.
pub const MAX_CONTACTS: usize = 4;

/// Most switches taken within one sample; beyond, the rest of the sample
/// runs in its phase without a search ([`MultiStats::capped`]).
pub const MAX_SWITCHES_PER_SAMPLE: usize = 64;

/// Halving stops at pieces narrower than this fraction of the sample.
const LEAF: f64 = 1e-15;

/// Norm slots made up front: the search's stack is one slot per level of
/// halving (a leaf is about 50 levels below a sample) plus two.
const NORM_SLOTS: usize = 72;

/// Most halvings of one contact's search in one step; the pieces left
/// are counted as `uncertified` (docs/numerics.md section 14).
pub const SEARCH_BUDGET: u32 = 1 << 14;

/// A hammer with a contact of its own.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiHammer {
    /// Mass \[kg\].
    pub mass_kg: f64,
    /// Initial height of its face \[m\] (the object starts at rest).
    pub height_m: f64,
    /// Initial velocity \[m/s\], positive up.
    pub velocity_m_per_s: f64,
    /// Each mode's mass-normalised weight at its contact point
    /// \[1/sqrt(kg)\].
    pub weights: Vec<f64>,
    /// Contact stiffness `k` \[N/m\].
    pub stiffness_n_per_m: f64,
    /// Contact damping `c` \[N s/m\].
    pub damping_n_s_per_m: f64,
}

/// A modal object and the hammers that strike it.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiModel {
    /// Each mode's frequency \[Hz\].
    pub freq_hz: Vec<f64>,
    /// Each mode's decay rate `sigma = ln(1000) / T60` \[1/s\] (0: undamped).
    pub sigma: Vec<f64>,
    /// The hammers (contact `j` is hammer `j`'s), 1 to [`MAX_CONTACTS`].
    pub hammers: Vec<MultiHammer>,
    /// Gravity pulling the hammers \[m/s^2\] (0: none).
    pub gravity_m_per_s2: f64,
    /// Output channels: each mode's weight on its displacement and on its
    /// velocity (left, right).
    pub pickups: [(Vec<f64>, Vec<f64>); 2],
}

/// Why a model cannot be compiled; each names its field.
#[derive(Debug, Clone, PartialEq)]
pub enum MultiError {
    /// No hammer, or more than [`MAX_CONTACTS`].
    ContactCount(usize),
    /// A list whose length is not the number of modes.
    Length {
        /// The field.
        field: String,
        /// Its length.
        got: usize,
        /// The number of modes.
        want: usize,
    },
    /// A number out of its range (not finite, a mass or stiffness not
    /// positive, a negative damping or frequency...).
    Value {
        /// The field.
        field: String,
        /// Its value.
        value: f64,
    },
    /// Two hammers at the same contact point (the same weights).
    SamePoint(usize, usize),
    /// Compiling every phase would exceed the compile budget
    /// ([`crate::compile::CompileBudget::DEFAULT`]).
    OverBudget {
        /// Phases.
        phases: usize,
        /// The largest phase's coordinates.
        dim: usize,
        /// Estimated work \[flop\].
        flops: f64,
        /// Estimated memory \[bytes\].
        bytes: f64,
    },
    /// A phase whose generator has no block form (the dense fallback,
    /// which the several-contact engine does not take).
    Phase {
        /// The contacts in contact (bit `j` for contact `j`).
        mask: u32,
        /// Why.
        why: String,
    },
}

impl std::fmt::Display for MultiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::ContactCount(n) => write!(
                f,
                "hammers: {n} contacts, a scene of several contacts has 1 to {MAX_CONTACTS}"
            ),
            Self::Length { field, got, want } => {
                write!(f, "{field}: {got} entries for {want} modes")
            }
            Self::Value { field, value } => write!(f, "{field}: {value} is out of range"),
            Self::OverBudget {
                phases,
                dim,
                flops,
                bytes,
            } => {
                let b = CompileBudget::DEFAULT;
                write!(
                    f,
                    "object.mode: {phases} phases of up to {dim} coordinates would take about \
                     {flops:.1e} flop and {:.0} MB to compile, over the compile budget ({:.1e} \
                     flop, {:.0} MB): fewer modes (max_freq_hz, max_modes) or fewer contacts",
                    bytes / 1e6,
                    b.max_flops,
                    b.max_bytes / 1e6
                )
            }
            Self::SamePoint(a, b) => write!(
                f,
                "hammers[{a}] and hammers[{b}]: two contacts on one point pair"
            ),
            Self::Phase { mask, why } => {
                write!(f, "the phase with contacts {mask:#b} in contact: {why}")
            }
        }
    }
}

impl std::error::Error for MultiError {}

/// One phase: the contacts of `mask` in contact.
#[derive(Debug, Clone)]
pub struct MultiPhase {
    /// The contacts in contact, increasing (contact `members[n]`'s `eta,
    /// pi` are `y[2N + 2n]`, `y[2N + 2n + 1]`).
    pub members: Vec<usize>,
    /// State dimension `2 N + 2 |members|`.
    pub dim: usize,
    /// Block generators (block `k` acts on `s[k], s[nb + k]`).
    pub gens: Vec<Mat2>,
    /// Each block's propagator over one sample.
    props: Vec<Mat2>,
    /// `y = V s + y_star`.
    pub v: DMatrix<f64>,
    vinv: DMatrix<f64>,
    y_star: Vec<f64>,
    /// Per contact (all of them): the row and constant of its event
    /// quantity (in contact its penetration `p_j`, out of contact its
    /// contact point's displacement `x_c,j`), its slope row `r G`, and the
    /// curvature weights `|r_k G_k^2| e^(gamma_k h)` per block.
    ev: Vec<Vec<f64>>,
    ev0: Vec<f64>,
    ev_d: Vec<Vec<f64>>,
    ev_c2: Vec<Vec<f64>>,
    /// Per contact: `|r_k| e^(gamma_k h)` per block (block `k`'s share of
    /// the function stays within it times `|s_k|`).
    ev_e: Vec<Vec<f64>>,
    /// Per contact: its contact point's velocity row and constant.
    vel: Vec<Vec<f64>>,
    vel0: Vec<f64>,
    /// Output rows and constants (left, right).
    out: [Vec<f64>; 2],
    out0: [f64; 2],
    /// Condition number of `V` (largest over smallest singular value).
    pub kappa: f64,
    /// The largest block growth over one sample, `max_k e^(gamma_k h)` (1
    /// for contractions; rounding can make an undamped block's a few ulps
    /// more): a bound taken from a state holds `n` samples later times its
    /// `n`-th power.
    pub growth: f64,
}

/// A compiled model: every phase, by its contact bit set.
#[derive(Debug, Clone)]
pub struct CompiledMulti {
    /// The model it was compiled from.
    pub model: MultiModel,
    /// Sample period \[s\].
    pub h: f64,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// `phases[mask]`.
    pub phases: Vec<MultiPhase>,
}

/// What the engine did (diagnostics, tests).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MultiStats {
    /// Switches taken (each a change of basis; simultaneous ones count
    /// once).
    pub switches: u64,
    /// Contacts started, per contact.
    pub contacts_started: [u64; MAX_CONTACTS],
    /// Samples that reached [`MAX_SWITCHES_PER_SAMPLE`].
    pub capped: u64,
    /// Pieces of the leaf width (about an ulp of the sample) at zero or
    /// within rounding of it without crossing: a touch at zero relative
    /// speed, or the instant a crossing begins (the next piece takes it);
    /// no switch.
    pub grazing: u64,
    /// Pieces left undecided: a contact's search ran out of its
    /// [`SEARCH_BUDGET`] halvings in a step (a penetration that dwells
    /// within rounding of 0 while the object rings), or its Taylor bound
    /// cleared the rest of the step while the step's end was across (a
    /// contradiction only rounding can make). No switch is taken there.
    pub uncertified: u64,
    /// Evaluations of an event function inside a step.
    pub evaluations: u64,
}

/// A located switch: contact `contact` entered (`entered`) or left
/// contact at `time_s` (since the state's start).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiSwitch {
    /// Which contact.
    pub contact: usize,
    /// Entered (true) or left.
    pub entered: bool,
    /// When \[s\].
    pub time_s: f64,
}

/// What one sample shows of each contact.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MultiObservation {
    /// Hammer heights \[m\].
    pub x_hammer: [f64; MAX_CONTACTS],
    /// Hammer velocities \[m/s\].
    pub v_hammer: [f64; MAX_CONTACTS],
    /// Each contact point's displacement \[m\].
    pub x_contact: [f64; MAX_CONTACTS],
    /// Each contact point's velocity \[m/s\].
    pub v_contact: [f64; MAX_CONTACTS],
    /// The contacts in contact (bit `j`).
    pub active: u32,
    /// Total energy \[J\] (object, hammers, springs in contact, gravity).
    pub energy: f64,
}

fn check_value(field: &str, value: f64, ok: bool) -> Result<(), MultiError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(MultiError::Value {
            field: field.into(),
            value,
        })
    }
}

impl MultiModel {
    fn n(&self) -> usize {
        self.freq_hz.len()
    }

    /// Check every field (a clear error naming it, never a panic).
    pub fn validate(&self) -> Result<(), MultiError> {
        let n = self.n();
        let k = self.hammers.len();
        if k == 0 || k > MAX_CONTACTS {
            return Err(MultiError::ContactCount(k));
        }
        let len = |field: &str, got: usize| {
            if got == n {
                Ok(())
            } else {
                Err(MultiError::Length {
                    field: field.into(),
                    got,
                    want: n,
                })
            }
        };
        len("sigma", self.sigma.len())?;
        for (c, (d, v)) in self.pickups.iter().enumerate() {
            len(&format!("pickups[{c}].displacement"), d.len())?;
            len(&format!("pickups[{c}].velocity"), v.len())?;
            for (i, x) in d.iter().chain(v).enumerate() {
                check_value(&format!("pickups[{c}][{i}]"), *x, true)?;
            }
        }
        for i in 0..n {
            check_value(
                &format!("freq_hz[{i}]"),
                self.freq_hz[i],
                self.freq_hz[i] > 0.0,
            )?;
            check_value(&format!("sigma[{i}]"), self.sigma[i], self.sigma[i] >= 0.0)?;
        }
        check_value(
            "gravity_m_per_s2",
            self.gravity_m_per_s2,
            self.gravity_m_per_s2 >= 0.0,
        )?;
        for (j, hm) in self.hammers.iter().enumerate() {
            let f = |name: &str| format!("hammers[{j}].{name}");
            check_value(&f("mass_kg"), hm.mass_kg, hm.mass_kg > 0.0)?;
            check_value(&f("height_m"), hm.height_m, true)?;
            check_value(&f("velocity_m_per_s"), hm.velocity_m_per_s, true)?;
            check_value(
                &f("stiffness_n_per_m"),
                hm.stiffness_n_per_m,
                hm.stiffness_n_per_m > 0.0,
            )?;
            check_value(
                &f("damping_n_s_per_m"),
                hm.damping_n_s_per_m,
                hm.damping_n_s_per_m >= 0.0,
            )?;
            len(&f("weights"), hm.weights.len())?;
            for (i, w) in hm.weights.iter().enumerate() {
                check_value(&f(&format!("weights[{i}]")), *w, true)?;
            }
            for (l, other) in self.hammers[..j].iter().enumerate() {
                if other.weights == hm.weights {
                    return Err(MultiError::SamePoint(l, j));
                }
            }
        }
        Ok(())
    }
}

impl MultiModel {
    /// The model of a scene with strikers (docs/design.md, "Several
    /// contacts"): the struck object's modes (objects from geometry and
    /// material become their modes at `rate_hz`), `[hammer]` and
    /// `[contact]` as contact 0, each `[[striker]]` as the next, the
    /// pickups on the struck object (those elsewhere hear nothing). A
    /// clear error naming the field where the scene asks for what several
    /// contacts do not take yet.
    pub fn from_scene(scene: &Scene, rate_hz: f64) -> Result<Self, SceneError> {
        scene.validate()?;
        let expanded = scene.expanded(rate_hz)?;
        let scene = &expanded;
        if scene.approximate.is_some() {
            return Err(SceneError::new(
                "approximate",
                "not with several contacts yet: remove it",
            ));
        }
        let c = &scene.contact;
        let obj = scene
            .object_index(&c.object)
            .map(|i| &scene.object[i])
            .ok_or_else(|| {
                SceneError::new("contact.object", format!("no object named {:?}", c.object))
            })?;
        let ObjectSpec::Modal(m) = obj else {
            return Err(SceneError::new(
                "contact.object",
                "several contacts strike an object with modes (kind \"modes\" or one from \
                 geometry and material), not a lumped string or a wall",
            ));
        };
        let weights_at = |field: &str, point: &str| -> Result<Vec<f64>, SceneError> {
            let k = m.points.iter().position(|p| p == point).ok_or_else(|| {
                SceneError::new(
                    field,
                    format!("object {:?} has no point {point:?}", c.object),
                )
            })?;
            Ok(m.mode.iter().map(|md| md.weights[k]).collect())
        };
        let point0 = c.point.as_deref().unwrap_or_default();
        let mut hammers = vec![MultiHammer {
            mass_kg: scene.hammer.mass_kg,
            height_m: scene.hammer.height_m,
            velocity_m_per_s: scene.hammer.velocity_m_per_s,
            weights: weights_at("contact.point", point0)?,
            stiffness_n_per_m: c.stiffness_n_per_m,
            damping_n_s_per_m: c.damping_n_s_per_m,
        }];
        for (i, st) in scene.striker.iter().enumerate() {
            hammers.push(MultiHammer {
                mass_kg: st.mass_kg,
                height_m: st.height_m,
                velocity_m_per_s: st.velocity_m_per_s,
                weights: weights_at(&format!("striker[{i}].point"), &st.point)?,
                stiffness_n_per_m: st.stiffness_n_per_m,
                damping_n_s_per_m: st.damping_n_s_per_m,
            });
        }
        let n = m.mode.len();
        let mut pickups: [(Vec<f64>, Vec<f64>); 2] =
            std::array::from_fn(|_| (vec![0.0; n], vec![0.0; n]));
        for (i, p) in scene.pickup.iter().enumerate() {
            if p.object != c.object {
                continue;
            }
            let w = weights_at(&format!("pickup[{i}].point"), &p.point)?;
            let (gl, gr) = pan_gains(p.pan);
            for (ch, g) in [(0, gl), (1, gr)] {
                let row = match p.quantity {
                    Quantity::Displacement => &mut pickups[ch].0,
                    Quantity::Velocity => &mut pickups[ch].1,
                };
                for (r, wi) in row.iter_mut().zip(&w) {
                    *r += wi * p.gain * g;
                }
            }
        }
        Ok(MultiModel {
            freq_hz: m.mode.iter().map(|md| md.freq_hz).collect(),
            sigma: m
                .mode
                .iter()
                .map(|md| md.t60_s.map_or(0.0, |t| LN_1000 / t))
                .collect(),
            hammers,
            gravity_m_per_s2: scene.hammer.gravity_m_per_s2,
            pickups,
        })
    }
}

/// The generator of phase `mask` in its energy coordinates, and gravity's
/// constant force on them.
fn generator(m: &MultiModel, members: &[usize]) -> (DMatrix<f64>, Vec<f64>) {
    let n = m.n();
    let dim = 2 * n + 2 * members.len();
    let mut a = DMatrix::zeros(dim, dim);
    let mut f = vec![0.0; dim];
    for i in 0..n {
        let w = 2.0 * std::f64::consts::PI * m.freq_hz[i];
        a[(i, n + i)] = w;
        a[(n + i, i)] = -w;
        a[(n + i, n + i)] = -2.0 * m.sigma[i];
    }
    for (pos, &j) in members.iter().enumerate() {
        let hm = &m.hammers[j];
        let (e, p) = (2 * n + 2 * pos, 2 * n + 2 * pos + 1);
        let (sk, sm, c) = (
            hm.stiffness_n_per_m.sqrt(),
            hm.mass_kg.sqrt(),
            hm.damping_n_s_per_m,
        );
        // p' = u . y
        let mut u = vec![0.0; dim];
        u[n..2 * n].copy_from_slice(&hm.weights);
        u[e] = -1.0 / sm;
        for col in 0..dim {
            a[(p, col)] += sk * u[col];
            a[(e, col)] += c / sm * u[col];
            for i in 0..n {
                a[(n + i, col)] -= c * hm.weights[i] * u[col];
            }
        }
        for i in 0..n {
            a[(n + i, p)] -= hm.weights[i] * sk;
        }
        a[(e, p)] += sk / sm;
        f[e] = -sm * m.gravity_m_per_s2;
    }
    (a, f)
}

/// `row . G` per block (`row` in block layout).
fn row_times_gens(row: &[f64], gens: &[Mat2]) -> Vec<f64> {
    let nb = gens.len();
    let mut out = vec![0.0; 2 * nb];
    for (k, g) in gens.iter().enumerate() {
        let (r0, r1) = (row[k], row[nb + k]);
        out[k] = r0 * g[0] + r1 * g[2];
        out[nb + k] = r0 * g[1] + r1 * g[3];
    }
    out
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// A row over `y` as a row over `s` and a constant (`y = V s + y*`).
fn in_phase(row_y: &[f64], v: &DMatrix<f64>, y_star: &[f64]) -> (Vec<f64>, f64) {
    let dim = row_y.len();
    let row = (0..dim)
        .map(|col| (0..dim).map(|r| row_y[r] * v[(r, col)]).sum())
        .collect();
    (row, dot(row_y, y_star))
}

impl MultiPhase {
    fn new(m: &MultiModel, mask: u32, h: f64) -> Result<Self, MultiError> {
        let n = m.n();
        let members: Vec<usize> = (0..m.hammers.len())
            .filter(|j| mask & (1 << j) != 0)
            .collect();
        let (a, f) = generator(m, &members);
        let dim = a.nrows();
        let bad = |why: String| MultiError::Phase { mask, why };
        let d = decompose_via(&a, h, None, true).map_err(|e| bad(e.to_string()))?;
        let Form::Blocks { gens } = d.form else {
            return Err(bad(format!(
                "no block form ({})",
                d.diag.fallback_reason.unwrap_or_default()
            )));
        };
        let y_star = if f.iter().any(|x| *x != 0.0) {
            let lu = a.clone().lu();
            let rhs = nalgebra::DVector::from_iterator(dim, f.iter().map(|x| -x));
            let y = lu
                .solve(&rhs)
                .ok_or_else(|| bad("no equilibrium under gravity".into()))?;
            y.iter().copied().collect()
        } else {
            vec![0.0; dim]
        };
        let props = gens.iter().map(|g| exp2(g, h)).collect();
        let growth: Vec<f64> = gens.iter().map(|g| (sym_growth(g) * h).exp()).collect();
        let growth_max = growth.iter().copied().fold(1.0, f64::max);
        let nb = gens.len();
        let (mut ev, mut ev0, mut ev_d, mut ev_c2, mut ev_e, mut vel, mut vel0) =
            (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
        for (j, hm) in m.hammers.iter().enumerate() {
            let mut row_y = vec![0.0; dim];
            if let Some(pos) = members.iter().position(|&x| x == j) {
                row_y[2 * n + 2 * pos + 1] = 1.0 / hm.stiffness_n_per_m.sqrt();
            } else {
                for i in 0..n {
                    row_y[i] = hm.weights[i] / (2.0 * std::f64::consts::PI * m.freq_hz[i]);
                }
            }
            let (r, r0) = in_phase(&row_y, &d.v, &y_star);
            let rd = row_times_gens(&r, &gens);
            let rdd = row_times_gens(&rd, &gens);
            ev_c2.push(
                (0..nb)
                    .map(|k| rdd[k].hypot(rdd[nb + k]) * growth[k])
                    .collect(),
            );
            ev_e.push((0..nb).map(|k| r[k].hypot(r[nb + k]) * growth[k]).collect());
            ev.push(r);
            ev0.push(r0);
            ev_d.push(rd);
            let mut vrow = vec![0.0; dim];
            vrow[n..2 * n].copy_from_slice(&hm.weights);
            let (vr, v0) = in_phase(&vrow, &d.v, &y_star);
            vel.push(vr);
            vel0.push(v0);
        }
        let mut out: [Vec<f64>; 2] = Default::default();
        let mut out0 = [0.0; 2];
        for c in 0..2 {
            let (disp, velo) = &m.pickups[c];
            let mut row_y = vec![0.0; dim];
            for i in 0..n {
                row_y[i] = disp[i] / (2.0 * std::f64::consts::PI * m.freq_hz[i]);
                row_y[n + i] = velo[i];
            }
            let (r, r0) = in_phase(&row_y, &d.v, &y_star);
            out[c] = r;
            out0[c] = r0;
        }
        Ok(Self {
            members,
            dim,
            gens,
            props,
            v: d.v,
            vinv: d.vinv,
            y_star,
            ev,
            ev0,
            ev_d,
            ev_c2,
            ev_e,
            vel,
            vel0,
            out,
            out0,
            kappa: d.diag.kappa,
            growth: growth_max,
        })
    }
}

impl CompiledMulti {
    /// Compile every phase (`2^K` of them) at `rate_hz`.
    pub fn new(model: &MultiModel, rate_hz: f64) -> Result<Self, MultiError> {
        model.validate()?;
        check_value("rate_hz", rate_hz, rate_hz > 0.0)?;
        // every phase's eigendecomposition and checks (about 40 d^3 flop
        // for d coordinates) and its two bases (2 d^2 numbers), refused
        // before any of it
        let k = model.hammers.len();
        let phases = 1usize << k;
        let dim = 2 * model.n() + 2 * k;
        let d = dim as f64;
        let flops = phases as f64 * 40.0 * d * d * d;
        let bytes = phases as f64 * 3.0 * d * d * 8.0;
        let budget = CompileBudget::DEFAULT;
        if flops > budget.max_flops || bytes > budget.max_bytes {
            return Err(MultiError::OverBudget {
                phases,
                dim,
                flops,
                bytes,
            });
        }
        let h = 1.0 / rate_hz;
        let phases = (0..1u32 << model.hammers.len())
            .map(|mask| MultiPhase::new(model, mask, h))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            model: model.clone(),
            h,
            rate_hz,
            phases,
        })
    }

    /// Number of contacts.
    pub fn contacts(&self) -> usize {
        self.model.hammers.len()
    }

    /// The largest condition number of the phases' `V`.
    pub fn kappa(&self) -> f64 {
        self.phases.iter().map(|p| p.kappa).fold(1.0, f64::max)
    }

    /// The largest block growth over one sample of any phase
    /// ([`MultiPhase::growth`]).
    pub fn growth(&self) -> f64 {
        self.phases.iter().map(|p| p.growth).fold(1.0, f64::max)
    }

    /// The largest phase dimension.
    pub fn max_dim(&self) -> usize {
        self.phases.iter().map(|p| p.dim).max().unwrap_or(0)
    }
}

/// The running state of a [`CompiledMulti`].
#[derive(Debug, Clone)]
pub struct MultiState {
    mask: u32,
    s: Vec<f64>,
    end: Vec<f64>,
    y: Vec<f64>,
    y2: Vec<f64>,
    /// Per block of the current phase, `|s_k|` at points of the search:
    /// slot 0 the step's start, the others the left ends of its pieces
    /// (a stack, one slot per level).
    norms: Vec<Vec<f64>>,
    /// Out of contact: each hammer's height and velocity (at the state's
    /// time).
    x_h: [f64; MAX_CONTACTS],
    v_h: [f64; MAX_CONTACTS],
    /// Per contact: a whole-sample margin (`w = h`) and the epoch of the
    /// clock (64 samples) it was taken in, in the current phase (times the
    /// phase's growth over 64 samples, it holds for every later state of
    /// the epoch).
    cached: [(u64, f64); MAX_CONTACTS],
    /// Halvings left to the current search.
    budget: u32,
    /// Samples run.
    clock: u64,
    /// What the engine did.
    pub stats: MultiStats,
    /// Every switch, when [`record`](Self::record) is on.
    pub switches: Vec<MultiSwitch>,
    record: bool,
}

/// Where a contact's search starts: its event function's value, or 0 on
/// the side it just switched to.
#[derive(Clone, Copy)]
enum Start {
    Value,
    Boundary,
}

/// Contact `j`'s event function in the current phase: its penetration in
/// contact, `x_j + v_j t - g t^2 / 2 - x_c,j(t)` in flight; positive on
/// the current side.
struct EventFn {
    inside: bool,
    x0: f64,
    v0: f64,
    g: f64,
    /// The rounding allowance of a hammer that just left (0 for the
    /// others): `4 u` times the magnitudes summed into `psi` (each block's
    /// `|r_k| |s_k|`, the constant, the hammer's height and travel). A
    /// value within it of 0 is neutral: not across.
    allow: f64,
    /// The rounding of `psi` itself (`4 u` times the same magnitudes, for
    /// every contact): a piece whose chord bound keeps `psi` above
    /// `-neutral` holds no crossing beyond rounding (docs/numerics.md
    /// section 14; the one-contact engine's neutral rule, section 6.6).
    neutral: f64,
}

impl EventFn {
    /// `psi` at `t` from the event quantity `q` (penetration or the
    /// point's displacement).
    fn psi(&self, q: f64, t: f64) -> f64 {
        if self.inside {
            q
        } else {
            self.x0 + self.v0 * t - 0.5 * self.g * t * t - q
        }
    }

    /// `psi'` at `t` from the quantity's slope `dq`.
    fn dpsi(&self, dq: f64, t: f64) -> f64 {
        if self.inside {
            dq
        } else {
            self.v0 - self.g * t - dq
        }
    }

    /// Across (contact ends at `p <= 0`, starts at `p > 0`), beyond the
    /// rounding allowance: a `psi` within it of 0 is the rounding of a
    /// touch, not a crossing (docs/numerics.md section 14).
    fn crossed(&self, psi: f64) -> bool {
        psi < -self.allow
    }
}

/// A piece of the search: gravity's curvature, the norm slot of its left
/// end and the first free slot.
#[derive(Clone, Copy)]
struct Piece {
    g_curv: f64,
    left: usize,
    free: usize,
}

impl MultiState {
    /// The model's initial state: the object at rest, the hammers in
    /// flight where the model puts them.
    pub fn new(sc: &CompiledMulti) -> Self {
        let dim = sc.max_dim();
        let mut x_h = [0.0; MAX_CONTACTS];
        let mut v_h = [0.0; MAX_CONTACTS];
        for (j, hm) in sc.model.hammers.iter().enumerate() {
            x_h[j] = hm.height_m;
            v_h[j] = hm.velocity_m_per_s;
        }
        Self {
            mask: 0,
            s: {
                let mut s = Vec::with_capacity(dim);
                s.resize(sc.phases[0].dim, 0.0);
                s
            },
            end: vec![0.0; dim],
            y: vec![0.0; dim],
            y2: vec![0.0; dim],
            norms: vec![vec![0.0; dim / 2]; NORM_SLOTS],
            x_h,
            v_h,
            cached: [(u64::MAX, 0.0); MAX_CONTACTS],
            budget: SEARCH_BUDGET,
            clock: 0,
            stats: MultiStats::default(),
            switches: Vec::new(),
            record: false,
        }
    }

    /// Keep every switch in [`switches`](Self::switches) (tests).
    pub fn record(&mut self, on: bool) {
        self.record = on;
    }

    /// The contacts in contact (bit `j`).
    pub fn active(&self) -> u32 {
        self.mask
    }

    /// One sample: the output `[left, right]` of the current state (the
    /// one-contact engine's convention: sample `n` is time `n / fs`), then
    /// advance one step.
    pub fn tick(&mut self, sc: &CompiledMulti) -> [f64; 2] {
        let out = self.output(sc);
        self.step(sc);
        out
    }

    /// The output `[left, right]` of the current state.
    pub fn output(&self, sc: &CompiledMulti) -> [f64; 2] {
        let ph = &sc.phases[self.mask as usize];
        [
            dot(&ph.out[0], &self.s) + ph.out0[0],
            dot(&ph.out[1], &self.s) + ph.out0[1],
        ]
    }

    /// Advance one sample, switching wherever a contact crosses.
    pub fn step(&mut self, sc: &CompiledMulti) {
        let h = sc.h;
        let mut t = 0.0;
        let mut starts = [Start::Value; MAX_CONTACTS];
        let mut taken = 0;
        while t < h {
            let ph = &sc.phases[self.mask as usize];
            let rem = h - t;
            let nb = ph.gens.len();
            if t == 0.0 {
                step_blocks(&ph.props, &self.s, &mut self.end[..ph.dim], nb);
            } else {
                step_to(&ph.gens, rem, &self.s, &mut self.end[..ph.dim]);
            }
            if taken >= MAX_SWITCHES_PER_SAMPLE {
                self.stats.capped += 1;
                self.s.copy_from_slice(&self.end[..ph.dim]);
                self.fly(sc, rem);
                break;
            }
            // the first crossing of any contact, and every contact that
            // crosses then
            let mut first: Option<f64> = None;
            let mut who = 0u32;
            for j in 0..sc.contacts() {
                let Some(tj) = self.first_crossing(sc, j, rem, starts[j]) else {
                    continue;
                };
                let tol = LEAF * h * 4.0;
                match first {
                    Some(f) if tj > f + tol => {}
                    Some(f) if tj >= f - tol => who |= 1 << j,
                    _ => {
                        first = Some(tj);
                        who = 1 << j;
                    }
                }
            }
            let Some(tau) = first else {
                self.s.copy_from_slice(&self.end[..ph.dim]);
                self.fly(sc, rem);
                break;
            };
            let tau = tau.min(rem);
            if tau < rem {
                step_to(&ph.gens, tau, &self.s, &mut self.end[..ph.dim]);
            }
            self.s.copy_from_slice(&self.end[..ph.dim]);
            self.fly(sc, tau);
            t = if tau < rem { t + tau } else { h };
            starts = self.switch(sc, who, self.clock as f64 * h + t);
            taken += 1;
        }
        self.clock += 1;
    }

    /// The hammers out of contact fly `dt` on.
    fn fly(&mut self, sc: &CompiledMulti, dt: f64) {
        let g = sc.model.gravity_m_per_s2;
        for j in 0..sc.contacts() {
            if self.mask & (1 << j) == 0 {
                self.x_h[j] += self.v_h[j] * dt - 0.5 * g * dt * dt;
                self.v_h[j] -= g * dt;
            }
        }
    }

    /// Contact `j`'s event function over `[0, rem]` of the current phase
    /// from the state `s` (its end state in `end`): its first crossing, if
    /// any (docs: the module's).
    fn first_crossing(
        &mut self,
        sc: &CompiledMulti,
        j: usize,
        rem: f64,
        start: Start,
    ) -> Option<f64> {
        let ph = &sc.phases[self.mask as usize];
        let nb = ph.gens.len();
        let inside = self.mask & (1 << j) != 0;
        let g = sc.model.gravity_m_per_s2;
        let mut f = EventFn {
            inside,
            x0: self.x_h[j],
            v0: self.v_h[j],
            g,
            allow: 0.0,
            neutral: 0.0,
        };
        let row = &ph.ev[j];
        let q0 = dot(row, &self.s) + ph.ev0[j];
        let q_end = dot(row, &self.end[..ph.dim]) + ph.ev0[j];
        let psi_end = f.psi(q_end, rem);
        // a whole sample that clears the epoch's margin holds no crossing
        let epoch = self.clock / 64;
        let whole = matches!(start, Start::Value) && rem == sc.h;
        if whole && self.cached[j].0 == epoch {
            let p0 = f.psi(q0, 0.0);
            if psi_end.min(p0) > self.cached[j].1 {
                return None;
            }
        }
        let d0 = f.dpsi(dot(&ph.ev_d[j], &self.s), 0.0);
        let mut mag = ph.ev0[j].abs();
        for k in 0..nb {
            self.norms[0][k] = (self.s[k] * self.s[k] + self.s[nb + k] * self.s[nb + k]).sqrt();
            mag += ph.ev_e[j][k] * self.norms[0][k];
        }
        if !inside {
            mag += f.x0.abs() + f.v0.abs() * rem + g * rem * rem;
        }
        f.neutral = 4.0 * f64::EPSILON / 2.0 * mag;
        // only for a hammer that just left: its flight starts at 0 and a
        // rounding-level value of the wrong sign is no new contact
        if matches!(start, Start::Boundary) && !inside {
            f.allow = f.neutral;
        }
        self.budget = SEARCH_BUDGET;
        let g_curv = if inside { 0.0 } else { g };
        let m = self.curvature(ph, j, g_curv, 0);
        if whole && self.cached[j].0 != epoch {
            // for the rest of the epoch: at most 64 samples of growth
            let later = ph.growth.powi(64);
            self.cached[j] = (epoch, self.margin(ph, j, rem, g_curv, 0) * later);
        }
        let (a, psi_a, da) = match start {
            Start::Value => (0.0, f.psi(q0, 0.0), d0),
            // a contact that just switched, moving back towards the side it
            // left (a touch at rounding level): from 0, searched as any
            // piece, crossing back only where psi is across beyond rounding
            Start::Boundary if !(d0 > 0.0) => (0.0, 0.0, d0),
            Start::Boundary => {
                // psi >= d0 t - m t^2 / 2 > 0 on (0, 2 d0 / m)
                let clear = if m > 0.0 { 2.0 * d0 / m } else { f64::INFINITY };
                if clear >= rem {
                    if f.crossed(psi_end) {
                        self.stats.uncertified += 1;
                    }
                    return None;
                }
                let a = clear * (1.0 - 1e-9);
                let (q, dq) = self.eval(ph, j, a, Some(1));
                (a, f.psi(q, a), f.dpsi(dq, a))
            }
        };
        if f.crossed(psi_a) {
            return Some(a);
        }
        let slot = if a > 0.0 { 1 } else { 0 };
        let piece = Piece {
            g_curv,
            left: slot,
            free: slot + 1,
        };
        self.search(sc, j, &f, (a, psi_a, da), (rem, psi_end), piece)
    }

    /// How far contact `j`'s event function may stray from the chord over
    /// a piece of width `w` of the current step: per block the smaller of
    /// its curvature's share `c_k |s_k| w^2 / 8` and `2 e_k |s_k|` (its
    /// share of the function and of the chord both stay within `e_k
    /// |s_k|`), plus the falling hammer's exact `g w^2 / 8`; the one-contact
    /// engine's margin (docs/numerics.md section 6.2), with `|s_k|` taken at
    /// the piece's left end (in slot `slot`): every block is a contraction
    /// (up to its growth factor), so it bounds the piece.
    fn margin(&self, ph: &MultiPhase, j: usize, w: f64, g_curv: f64, slot: usize) -> f64 {
        let h = w * w / 8.0;
        let mut acc = g_curv * h;
        let norms = &self.norms[slot];
        for k in 0..ph.gens.len() {
            acc += (ph.ev_c2[j][k] * h).min(2.0 * ph.ev_e[j][k]) * norms[k];
        }
        acc * (1.0 + 1e-12)
    }

    /// A bound on `|psi''|` over a piece from the norms at its left end (in
    /// slot `slot`): `sum_k c_k |s_k| + g`.
    fn curvature(&self, ph: &MultiPhase, j: usize, g_curv: f64, slot: usize) -> f64 {
        let norms = &self.norms[slot];
        let mut m = g_curv;
        for k in 0..ph.gens.len() {
            m += ph.ev_c2[j][k] * norms[k];
        }
        m * (1.0 + 1e-12)
    }

    /// The event quantity of contact `j` and its slope at `t` into the
    /// current step, and each block's `|s_k(t)|` into slot `slot`.
    fn eval(&mut self, ph: &MultiPhase, j: usize, t: f64, slot: Option<usize>) -> (f64, f64) {
        self.stats.evaluations += 1;
        let nb = ph.gens.len();
        if let Some(slot) = slot {
            while self.norms.len() <= slot {
                self.norms.push(Vec::new());
            }
            self.norms[slot].resize(nb, 0.0);
        }
        let (row, row_d) = (&ph.ev[j], &ph.ev_d[j]);
        let (mut q, mut dq) = (ph.ev0[j], 0.0);
        for (k, g) in ph.gens.iter().enumerate() {
            let p = exp2(g, t);
            let (x0, x1) = mul2(&p, self.s[k], self.s[nb + k]);
            if let Some(slot) = slot {
                self.norms[slot][k] = (x0 * x0 + x1 * x1).sqrt();
            }
            q += row[k] * x0 + row[nb + k] * x1;
            dq += row_d[k] * x0 + row_d[nb + k] * x1;
        }
        (q, dq)
    }

    /// The first crossing in `(a, b]` (none before `a`; `da` the slope at
    /// `a`), halving left first; a piece that crosses and on which `psi`
    /// certainly falls all the way (`psi'(a) + M (b - a) < 0`) holds one
    /// crossing, found by [`refine`](Self::refine).
    fn search(
        &mut self,
        sc: &CompiledMulti,
        j: usize,
        f: &EventFn,
        (a, pa, da): (f64, f64, f64),
        (b, pb): (f64, f64),
        piece: Piece,
    ) -> Option<f64> {
        let w = b - a;
        let ph = &sc.phases[self.mask as usize];
        if !f.crossed(pb)
            && pa.min(pb) - self.margin(ph, j, w, piece.g_curv, piece.left) > -f.neutral
        {
            return None;
        }
        if f.crossed(pb) && da + self.curvature(ph, j, piece.g_curv, piece.left) * w < 0.0 {
            return Some(self.refine(sc, j, f, (a, pa), (b, pb)));
        }
        let mid = a + 0.5 * w;
        if w <= LEAF * sc.h || mid <= a || mid >= b {
            if f.crossed(pb) {
                return Some(b);
            }
            self.stats.grazing += 1;
            return None;
        }
        if self.budget == 0 {
            // a piece left undecided (counted; never on the tests' cases
            // but the dwelling ones, docs/numerics.md section 14)
            if f.crossed(pb) {
                return Some(b);
            }
            self.stats.uncertified += 1;
            return None;
        }
        self.budget -= 1;
        // the midpoint's norms in `free`: the left half keeps `left` and
        // stacks above `free`, the right half starts from `free`
        let (q, dq) = self.eval(ph, j, mid, Some(piece.free));
        let (pm, dm) = (f.psi(q, mid), f.dpsi(dq, mid));
        let left_half = Piece {
            free: piece.free + 1,
            ..piece
        };
        if let Some(t) = self.search(sc, j, f, (a, pa, da), (mid, pm), left_half) {
            return Some(t);
        }
        let right_half = Piece {
            left: piece.free,
            free: piece.free + 1,
            ..piece
        };
        self.search(sc, j, f, (mid, pm, dm), (b, pb), right_half)
    }

    /// The one crossing of a piece on which `psi` falls all the way,
    /// `psi(a)` on this side and `psi(b)` across: regula falsi with the
    /// Illinois halving, a halving step whenever the bracket shrinks by
    /// less than half, until it is a leaf wide; its right end.
    fn refine(
        &mut self,
        sc: &CompiledMulti,
        j: usize,
        f: &EventFn,
        (mut a, mut pa): (f64, f64),
        (mut b, mut pb): (f64, f64),
    ) -> f64 {
        let ph = &sc.phases[self.mask as usize];
        let mut side = 0i8;
        let mut bisect = false;
        // no point nearer an end than half a leaf: a secant that lands on
        // the root from this side is followed by one just across it
        let tol = 0.5 * LEAF * sc.h;
        while b - a > LEAF * sc.h {
            let w = b - a;
            let t = if bisect {
                a + 0.5 * w
            } else {
                let t = a + pa / (pa - pb) * w;
                if t.is_finite() {
                    t.clamp(a + tol, b - tol)
                } else {
                    a + 0.5 * w
                }
            };
            if t <= a || t >= b {
                break;
            }
            let (q, _) = self.eval(ph, j, t, None);
            let pt = f.psi(q, t);
            if f.crossed(pt) {
                b = t;
                pb = pt;
                if side == 1 {
                    pa *= 0.5;
                }
                side = 1;
            } else {
                a = t;
                pa = pt;
                if side == -1 {
                    pb *= 0.5;
                }
                side = -1;
            }
            bisect = b - a > 0.5 * w;
        }
        b
    }

    /// Switch the contacts of `who` at the state's time `time_s`: each
    /// enters (spring unstretched) or leaves (hammer where the face is);
    /// a change of basis through the energy coordinates, O(dim^2). Returns
    /// where each contact's next search starts.
    fn switch(&mut self, sc: &CompiledMulti, who: u32, time_s: f64) -> [Start; MAX_CONTACTS] {
        let n = sc.model.n();
        let old = &sc.phases[self.mask as usize];
        // y = V s + y*
        mat_vec(&old.v, &self.s, &old.y_star, &mut self.y[..old.dim]);
        // the hammers' physical states before the switch
        let mut x = self.x_h;
        let mut v = self.v_h;
        let mut p_left = [0.0; MAX_CONTACTS];
        for (pos, &j) in old.members.iter().enumerate() {
            let hm = &sc.model.hammers[j];
            let x_c: f64 = (0..n)
                .map(|i| {
                    hm.weights[i] * self.y[i] / (2.0 * std::f64::consts::PI * sc.model.freq_hz[i])
                })
                .sum();
            let p = self.y[2 * n + 2 * pos + 1] / hm.stiffness_n_per_m.sqrt();
            p_left[j] = p;
            x[j] = x_c - p;
            v[j] = self.y[2 * n + 2 * pos] / hm.mass_kg.sqrt();
        }
        let new_mask = self.mask ^ who;
        let new = &sc.phases[new_mask as usize];
        // the new phase's energy coordinates
        self.y2[..2 * n].copy_from_slice(&self.y[..2 * n]);
        for (pos, &j) in new.members.iter().enumerate() {
            let hm = &sc.model.hammers[j];
            let was = old.members.iter().position(|&x| x == j);
            let (eta, pi) = match was {
                Some(p) => (self.y[2 * n + 2 * p], self.y[2 * n + 2 * p + 1]),
                // entering: the spring starts unstretched
                None => (hm.mass_kg.sqrt() * v[j], 0.0),
            };
            self.y2[2 * n + 2 * pos] = eta;
            self.y2[2 * n + 2 * pos + 1] = pi;
        }
        for j in 0..sc.contacts() {
            if who & (1 << j) != 0 {
                let entered = new_mask & (1 << j) != 0;
                if entered {
                    self.stats.contacts_started[j] += 1;
                }
                if self.record {
                    self.switches.push(MultiSwitch {
                        contact: j,
                        entered,
                        time_s,
                    });
                }
            }
        }
        // s = V^-1 (y - y*)
        for (y, ys) in self.y2[..new.dim].iter_mut().zip(&new.y_star) {
            *y -= ys;
        }
        self.s.resize(new.dim, 0.0);
        mat_vec(&new.vinv, &self.y2[..new.dim], &[], &mut self.s);
        // a hammer that left is placed from its point as the new phase
        // computes it (its event row), so its flight starts exactly at the
        // penetration it left with, without the change of basis's rounding
        // between the two bases' views of the point
        for j in 0..sc.contacts() {
            if who & (1 << j) != 0 && new_mask & (1 << j) == 0 {
                x[j] = dot(&new.ev[j], &self.s) + new.ev0[j] - p_left[j];
            }
        }
        self.x_h = x;
        self.v_h = v;
        self.mask = new_mask;
        self.cached = [(u64::MAX, 0.0); MAX_CONTACTS];
        self.stats.switches += 1;
        std::array::from_fn(|j| {
            if who & (1 << j) != 0 {
                Start::Boundary
            } else {
                Start::Value
            }
        })
    }

    /// The state now: each hammer, each contact point, the energy.
    pub fn observe(&self, sc: &CompiledMulti) -> MultiObservation {
        let ph = &sc.phases[self.mask as usize];
        let n = sc.model.n();
        let mut o = MultiObservation {
            active: self.mask,
            ..Default::default()
        };
        let mut y = vec![0.0; ph.dim];
        for (r, yr) in y.iter_mut().enumerate() {
            *yr = ph.y_star[r] + (0..ph.dim).map(|c| ph.v[(r, c)] * self.s[c]).sum::<f64>();
        }
        let g = sc.model.gravity_m_per_s2;
        let mut e = 0.5 * dot(&y, &y);
        for (j, hm) in sc.model.hammers.iter().enumerate() {
            // in contact its penetration, in flight its point's displacement
            let q = dot(&ph.ev[j], &self.s) + ph.ev0[j];
            let (x, v, xc) = match ph.members.iter().position(|&m| m == j) {
                Some(pos) => {
                    let xc: f64 = (0..n)
                        .map(|i| {
                            hm.weights[i] * y[i]
                                / (2.0 * std::f64::consts::PI * sc.model.freq_hz[i])
                        })
                        .sum();
                    (xc - q, y[2 * n + 2 * pos] / hm.mass_kg.sqrt(), xc)
                }
                None => {
                    e += 0.5 * hm.mass_kg * self.v_h[j] * self.v_h[j];
                    (self.x_h[j], self.v_h[j], q)
                }
            };
            e += hm.mass_kg * g * x;
            o.x_hammer[j] = x;
            o.v_hammer[j] = v;
            o.x_contact[j] = xc;
            o.v_contact[j] = dot(&ph.vel[j], &self.s) + ph.vel0[j];
        }
        o.energy = e;
        o
    }
}

/// `out = M x + c` (`c` empty: 0) for a square column-major `M`, by
/// columns (contiguous reads).
fn mat_vec(m: &DMatrix<f64>, x: &[f64], c: &[f64], out: &mut [f64]) {
    let n = x.len();
    if c.is_empty() {
        out.iter_mut().for_each(|o| *o = 0.0);
    } else {
        out.copy_from_slice(c);
    }
    let data = m.as_slice();
    for (col, &xc) in x.iter().enumerate() {
        if xc == 0.0 {
            continue;
        }
        for (o, a) in out.iter_mut().zip(&data[col * n..(col + 1) * n]) {
            *o += a * xc;
        }
    }
}

/// `out = P s` with one-sample block propagators.
fn step_blocks(props: &[Mat2], s: &[f64], out: &mut [f64], nb: usize) {
    for (k, p) in props.iter().enumerate() {
        let (x0, x1) = mul2(p, s[k], s[nb + k]);
        out[k] = x0;
        out[nb + k] = x1;
    }
}

/// `out = exp(G t) s`.
fn step_to(gens: &[Mat2], t: f64, s: &[f64], out: &mut [f64]) {
    let nb = gens.len();
    for (k, g) in gens.iter().enumerate() {
        let p = exp2(g, t);
        let (x0, x1) = mul2(&p, s[k], s[nb + k]);
        out[k] = x0;
        out[nb + k] = x1;
    }
}

/// What a several-contact render did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MultiRenderStats {
    /// The engine's counters.
    pub stats: MultiStats,
    /// Largest absolute output sample.
    pub peak: f64,
    /// Output samples that were not finite (written as they are).
    pub nonfinite: u64,
}

/// What [`render_multi`] hands each sample's observation to.
pub type ObserveFn<'a> = dyn FnMut(usize, &MultiObservation) -> std::io::Result<()> + 'a;

/// Render `n` samples of `sc` from its initial state: the audio in chunks
/// of [`crate::render::STREAM_CHUNK`] to `audio`, and, when `observe` is
/// given, every sample's observation (sample `i` at time `i / fs`, 0 the
/// initial state, `n` of them). O(N) per sample and O(N^2) per switch;
/// observing adds O(N^2) per sample (the energy through the change of
/// basis).
pub fn render_multi(
    sc: &CompiledMulti,
    n: usize,
    mut audio: impl FnMut(&[f64], &[f64]) -> std::io::Result<()>,
    mut observe: Option<&mut ObserveFn<'_>>,
) -> std::io::Result<MultiRenderStats> {
    let mut st = MultiState::new(sc);
    let chunk = crate::render::STREAM_CHUNK;
    let (mut l, mut r) = (Vec::with_capacity(chunk), Vec::with_capacity(chunk));
    let mut out = MultiRenderStats::default();
    let mut i = 0;
    while i < n {
        l.clear();
        r.clear();
        for _ in 0..chunk.min(n - i) {
            if let Some(f) = observe.as_mut() {
                f(i, &st.observe(sc))?;
            }
            let [a, b] = st.tick(sc);
            for x in [a, b] {
                if x.is_finite() {
                    out.peak = out.peak.max(x.abs());
                } else {
                    out.nonfinite += 1;
                }
            }
            l.push(a);
            r.push(b);
            i += 1;
        }
        audio(&l, &r)?;
    }
    out.stats = st.stats;
    Ok(out)
}

/// The several-contact trace's header (docs/design.md, "Several
/// contacts"): the one-contact columns for contact 0 (`energy` the total),
/// then `x_hammer_j, v_hammer_j, x_contact_j, v_contact_j, in_contact_j`
/// for each further contact `j`.
pub fn trace_header(contacts: usize) -> String {
    let mut h = String::from("t,x_hammer,v_hammer,x_contact,v_contact,in_contact,energy");
    for j in 1..contacts {
        h.push_str(&format!(
            ",x_hammer_{j},v_hammer_{j},x_contact_{j},v_contact_{j},in_contact_{j}"
        ));
    }
    h
}

/// One trace row (without its line end) in the one-contact trace's
/// number format (shortest round-trip).
fn push_trace_row(
    buf: &mut Vec<u8>,
    fmt: &mut zmij::Buffer,
    t: f64,
    o: &MultiObservation,
    contacts: usize,
) {
    use crate::render::push_e;
    let flag = |j: usize| if o.active & (1 << j) != 0 { b'1' } else { b'0' };
    push_e(buf, fmt, t);
    for x in [o.x_hammer[0], o.v_hammer[0], o.x_contact[0], o.v_contact[0]] {
        buf.push(b',');
        push_e(buf, fmt, x);
    }
    buf.push(b',');
    buf.push(flag(0));
    buf.push(b',');
    push_e(buf, fmt, o.energy);
    for j in 1..contacts {
        for x in [o.x_hammer[j], o.v_hammer[j], o.x_contact[j], o.v_contact[j]] {
            buf.push(b',');
            push_e(buf, fmt, x);
        }
        buf.push(b',');
        buf.push(flag(j));
    }
}

/// The several-contact trace CSV, written as the render goes.
pub struct MultiTraceCsv<W: std::io::Write> {
    out: W,
    buf: Vec<u8>,
    fmt: zmij::Buffer,
    rate_hz: f64,
    contacts: usize,
}

impl<W: std::io::Write> MultiTraceCsv<W> {
    /// Write the header ([`trace_header`]).
    pub fn new(mut out: W, rate_hz: f64, contacts: usize) -> std::io::Result<Self> {
        writeln!(out, "{}", trace_header(contacts))?;
        Ok(Self {
            out,
            buf: Vec::with_capacity(1 << 16),
            fmt: zmij::Buffer::new(),
            rate_hz,
            contacts,
        })
    }

    /// Write sample `i`'s row.
    pub fn row(&mut self, i: usize, o: &MultiObservation) -> std::io::Result<()> {
        let t = i as f64 / self.rate_hz;
        push_trace_row(&mut self.buf, &mut self.fmt, t, o, self.contacts);
        self.buf.push(b'\n');
        if self.buf.len() >= 1 << 16 {
            self.out.write_all(&self.buf)?;
            self.buf.clear();
        }
        Ok(())
    }

    /// Write what is left and flush.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.out.write_all(&self.buf)?;
        self.out.flush()
    }
}

/// The several-contact trace as a NumPy `.npy` file: the CSV's columns
/// ([`trace_header`]) as named little-endian f64 fields, one record per
/// sample (`in_contact` fields 0 or 1), the numbers' own bits; the row
/// count is in the header, so [`finish`](Self::finish) checks that every
/// row came.
pub struct MultiTraceNpy<W: std::io::Write> {
    out: W,
    buf: Vec<u8>,
    rate_hz: f64,
    contacts: usize,
    rows: usize,
    written: usize,
}

impl<W: std::io::Write> MultiTraceNpy<W> {
    /// Write the header for `rows` records.
    pub fn new(mut out: W, rate_hz: f64, contacts: usize, rows: usize) -> std::io::Result<Self> {
        out.write_all(&crate::render::npy_header_with(
            &trace_header(contacts),
            rows,
        ))?;
        Ok(Self {
            out,
            buf: Vec::with_capacity(1 << 16),
            rate_hz,
            contacts,
            rows,
            written: 0,
        })
    }

    /// Write sample `i`'s record.
    pub fn row(&mut self, i: usize, o: &MultiObservation) -> std::io::Result<()> {
        if self.written == self.rows {
            return Err(std::io::Error::other(
                "more trace rows than the header says",
            ));
        }
        let flag = |j: usize| if o.active & (1 << j) != 0 { 1.0 } else { 0.0 };
        let mut put = |x: f64| self.buf.extend_from_slice(&x.to_le_bytes());
        put(i as f64 / self.rate_hz);
        for x in [
            o.x_hammer[0],
            o.v_hammer[0],
            o.x_contact[0],
            o.v_contact[0],
            flag(0),
            o.energy,
        ] {
            put(x);
        }
        for j in 1..self.contacts {
            for x in [
                o.x_hammer[j],
                o.v_hammer[j],
                o.x_contact[j],
                o.v_contact[j],
                flag(j),
            ] {
                put(x);
            }
        }
        self.written += 1;
        if self.buf.len() >= 1 << 16 {
            self.out.write_all(&self.buf)?;
            self.buf.clear();
        }
        Ok(())
    }

    /// Write what is left and flush; an error if rows are missing.
    pub fn finish(mut self) -> std::io::Result<()> {
        if self.written != self.rows {
            return Err(std::io::Error::other(format!(
                "{} of {} trace rows written",
                self.written, self.rows
            )));
        }
        self.out.write_all(&self.buf)?;
        self.out.flush()
    }
}
