//! Several contacts at once between modal objects, point masses and walls:
//! up to [`MAX_SPRINGS`] linear spring-dampers, each between two sides
//! (a point of a modal object, a point mass, a rigid wall): two mallets of
//! a roll, a ball between two plates, chimes that touch, a mass on a wall.
//! Every subset of contacts in contact is a phase (up to 16), compiled up
//! front; each contact has its own event function, the first switch of any
//! contact in a sample is located and taken, and every contact that
//! switches at that instant changes side together (docs/numerics.md
//! section 14; the scene keys `[[striker]]` and `[[touch]]` and the render
//! command: docs/design.md "Several contacts"), checked against the
//! independent reference solver and closed forms (`tests/multi_contact.rs`);
//! the instrument plays such a scene as a kit (`crate::instrument`,
//! docs/design.md "Played as a kit"): a throw between samples
//! ([`MultiState::strike`]), a time scale per kit voice
//! ([`MultiState::set_time_scale`]) that a bend moves
//! ([`MultiState::bend_time_scale`]), an output band
//! ([`MultiState::set_output_band`]), a state carried to a recompile
//! ([`MultiState::carry`]).
//!
//! Coordinates. The positions `z` are every mode's `q_i` (unit modal
//! mass) and `sqrt(m_j) x_j` of every mass in a closed contact (a mass in
//! no closed contact flies on its own: `x_j + v_j t - g t^2 / 2`,
//! exactly). A closed contact `c` adds `k_c (g_c . z + p0_c)^2 / 2` to the
//! potential (`p_c = g_c . z + p0_c` its penetration, `p0_c` its walls'
//! heights and gap), so the stiffness is `K = diag(omega^2, 0) + sum_c k_c
//! g_c g_c^T`. A group of masses joined only to each other (no object, no
//! wall) moves as a whole freely: its centre of mass flies like a free
//! mass, and `K` is taken on the complement `P` of those directions. The
//! phase's energy coordinates are `u = R P^T z` and `w = P^T z'`, with `R`
//! the triangular factor of the QR factorisation of the stacked rows
//! `[diag(omega); sqrt(k_c) g_c^T] P` (so `R^T R = P^T K P` without
//! forming `K`: for one hammer on one object `u` is an orthogonal turn of
//! the one-contact engine's `(omega q, sqrt(k) p)`); the energy is `|y|^2
//! / 2` plus linear terms, the generator `[[0, R], [-R^T, -P^T D P]]` is
//! skew-symmetric plus a damping (`D = diag(2 sigma, 0) + sum_c c_c g_c
//! g_c^T`), and it is decomposed into real 2x2 blocks (`y = V s + y*`,
//! `y*` the equilibrium under gravity and the springs' offsets); a sample
//! is one closed-form block exponential per block.
//!
//! Switching, the reference solver's semantics: flight becomes contact when
//! `p_c` crosses from `<= 0` to `> 0`, contact becomes flight when it
//! returns to `<= 0`. A switch goes through the physical state (every
//! `q, q'`, every mass's `x, v`), which never jumps: entering, the spring
//! starts at the penetration of the crossing (0 to rounding); leaving at
//! `p_c <= 0`, its `k p_c^2 / 2 <=` rounding is dropped. So no switch adds
//! energy beyond rounding, and the phases are passive. With the offset rod
//! ([`CompiledMulti::switching`]) each contact switches at sample instants
//! instead, with a rod of its own ([`MultiState::decide`]).
//!
//! The first crossing of a contact's event function `psi` (its
//! penetration, signed to be positive on the current side) within a step
//! is found by the one certified search of every engine
//! (`engine/search.rs`, docs/numerics.md section 6.4) on this engine's
//! model of `psi`: the contact's rows over the phase's 2x2 blocks, each
//! block exact at a node's start, plus its free sides' exact parabolas
//! (`multi/search.rs`, docs/numerics.md section 14). A whole sample whose
//! two ends clear the chord's margin needs no search.

use crate::compile::{pan_gains, CompileBudget};
use crate::engine::kernel::BlockProps;
use crate::engine::search::STACK;
use crate::engine::vmath::{self, madd, SimdPath};
use crate::engine::TimeScaleError;
use crate::physics::block::{exp2, mul2, sym_growth, Mat2, OscForm};
use crate::physics::decomp::{decompose_via, Form};
use crate::physics::model::LN_1000;
use crate::scene::{End as SceneEnd, ObjectSpec, Quantity, Scene, SceneError, Switching};
use nalgebra::DMatrix;
use phase::{StructuredProducts, SwitchScratch};

mod fast;
mod model;
mod observe;
mod phase;
mod search;
mod state;
mod step;

/// Most contacts of one scene, the scene's.
pub use crate::scene::{MAX_CONTACTS, MAX_SPRINGS};

/// Most switches taken within one sample, the engine's; beyond, the rest of
/// the sample runs in its phase without a search ([`MultiStats::capped`]).
pub use crate::engine::MAX_SWITCHES_PER_SAMPLE;

/// A point-mass hammer with a contact of its own on the struck object
/// (the simple case, [`MultiModel::struck`]).
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

/// A point mass: a hammer, a ball.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiMass {
    /// Mass \[kg\].
    pub mass_kg: f64,
    /// Initial height of its face \[m\].
    pub height_m: f64,
    /// Initial velocity \[m/s\], positive up.
    pub velocity_m_per_s: f64,
}

/// One side of a contact.
#[derive(Debug, Clone, PartialEq)]
pub enum MultiEnd {
    /// A point of the modal objects: each mode's mass-normalised weight
    /// there \[1/sqrt(kg)\] (0 on the modes of other objects).
    Point(Vec<f64>),
    /// Point mass `j` of [`MultiModel::masses`].
    Mass(usize),
    /// A rigid wall at this height \[m\].
    Wall(f64),
}

/// A linear spring-damper between two sides: penetration `p = x_lower -
/// x_upper - gap`; in contact (`p > 0`) the force `F = k p + c p'` pushes
/// the upper side up and the lower side down.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiContact {
    /// The side below.
    pub lower: MultiEnd,
    /// The side above.
    pub upper: MultiEnd,
    /// How far the upper side rests above the lower one \[m\] (a mass's
    /// height already counts from 0).
    pub gap_m: f64,
    /// Stiffness `k` \[N/m\].
    pub stiffness_n_per_m: f64,
    /// Damping `c` \[N s/m\].
    pub damping_n_s_per_m: f64,
}

/// Modal objects (their modes side by side), point masses, walls and the
/// contacts between them.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiModel {
    /// Each mode's frequency \[Hz\] (every object's modes, one list).
    pub freq_hz: Vec<f64>,
    /// Each mode's decay rate `sigma = ln(1000) / T60` \[1/s\] (0: undamped).
    pub sigma: Vec<f64>,
    /// The point masses.
    pub masses: Vec<MultiMass>,
    /// The contacts, 1 to [`MAX_SPRINGS`].
    pub contacts: Vec<MultiContact>,
    /// Gravity pulling the masses \[m/s^2\] (0: none).
    pub gravity_m_per_s2: f64,
    /// Output channels: each mode's weight on its displacement and on its
    /// velocity (left, right).
    pub pickups: [(Vec<f64>, Vec<f64>); 2],
}

/// Why a model cannot be compiled; each names its field.
#[derive(Debug, Clone, PartialEq)]
pub enum MultiError {
    /// No contact, or more than [`MAX_SPRINGS`].
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
    /// Two contacts with one penetration: the same two sides the same way
    /// round at the same gap, a wall's height counted in the gap (one
    /// spring-damper twice). The other way round they are two faces (a
    /// floor and a ceiling), at another gap two stages: both allowed.
    SamePoint(usize, usize),
    /// A contact whose sides cannot touch: a side in contact with itself,
    /// two walls, a mass that does not exist, one that starts pressed in.
    Sides {
        /// The contact.
        contact: usize,
        /// Its part at fault: `"lower"`, `"upper"` or `"gap_m"` (the
        /// sides' start).
        part: &'static str,
        /// Why.
        why: String,
    },
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
                "contacts: {n} contacts, a scene of several contacts has 1 to {MAX_SPRINGS}"
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
            } => write!(
                f,
                "object.mode: {}",
                over_budget(*phases, *dim, *flops, *bytes)
            ),
            Self::SamePoint(a, b) => write!(
                f,
                "contacts[{a}] and contacts[{b}]: two contacts on one point pair"
            ),
            Self::Sides { contact, why, .. } => write!(f, "contacts[{contact}]: {why}"),
            Self::Phase { mask, why } => {
                write!(f, "the phase with contacts {mask:#b} in contact: {why}")
            }
        }
    }
}

impl std::error::Error for MultiError {}

fn over_budget(phases: usize, dim: usize, flops: f64, bytes: f64) -> String {
    let b = CompileBudget::DEFAULT;
    format!(
        "{phases} phases of up to {dim} coordinates would take about {flops:.1e} flop and {:.0} \
         MB to compile, over the compile budget ({:.1e} flop, {:.0} MB): fewer modes \
         (max_freq_hz, max_modes) or fewer contacts",
        bytes / 1e6,
        b.max_flops,
        b.max_bytes / 1e6
    )
}

impl MultiError {
    /// The refusal of a model made by [`MultiModel::from_scene`] from
    /// `scene`, as a scene error naming the scene's field: `contact`,
    /// `striker[i]`, `touch[i]` and their keys, `hammer`, a pickup...
    /// (what a compile of the model refuses, [`CompiledMulti::new`]).
    pub fn in_scene(&self, scene: &Scene) -> SceneError {
        SceneNames::of(scene).error(self)
    }
}

/// Where one side of a contact is in a phase: rows over `s` and
/// constants for its position and velocity, plus the flight slot it rides
/// (a free mass, or the centre of a free group).
#[derive(Debug, Clone)]
struct SideRows {
    pos: Vec<f64>,
    pos0: f64,
    vel: Vec<f64>,
    vel0: f64,
    fly: Option<usize>,
}

/// One phase: the contacts of `mask` in contact.
#[derive(Debug, Clone)]
pub struct MultiPhase {
    /// The contacts in contact, increasing.
    pub members: Vec<usize>,
    /// State dimension `2 (N + masses in contact - free groups)`.
    pub dim: usize,
    /// Block generators (block `k` acts on `s[k], s[nb + k]`).
    pub gens: Vec<Mat2>,
    /// Each block's oscillatory split, made once (`exp(G t)` at a new `t`
    /// is then a sine, a cosine and an exponential; none: [`exp2`]).
    forms: Vec<Option<OscForm>>,
    /// The masses in a closed contact (`z[N + b]` is `sqrt(m) x` of
    /// `bound[b]`), and per mass its place there.
    bound: Vec<usize>,
    place: Vec<Option<usize>>,
    /// Groups of masses joined only to each other: their masses (the first
    /// one's flight slot carries the group's centre).
    groups: Vec<Vec<usize>>,
    /// Per mass: the slot whose flight it rides (itself when free, its
    /// group's first mass in a free group, none when held).
    fly_of: Vec<Option<usize>>,
    /// The slots that fly in this phase.
    flyers: Vec<usize>,
    /// The phase's rows of the physical state, straight from the block
    /// state `s` (`y = [u; w] = V s + y*`; `Q` the thin factor of
    /// `[diag(omega); sqrt(k_c) g_c^T] P = Q R`, so `Q u = (omega q,
    /// sqrt(k_c) (p_c - p0_c))`, the one-contact engine's energy
    /// coordinates; `P` the positions `z` of the reduced ones, `Z = P
    /// R^-1`): `Q V_u` and `Q u*`, `P V_w` and `P w*`, the held masses' rows
    /// of `Z V_u` and `Z u*` (the trace's coupled energy and masses, the
    /// output band), and `V^-1 y*`.
    qv: DMatrix<f64>,
    qv0: Vec<f64>,
    pv: DMatrix<f64>,
    pv0: Vec<f64>,
    zv: DMatrix<f64>,
    zv0: Vec<f64>,
    /// A switch's products, on the coupled part alone (a free mode's block
    /// is its own `(omega q, q')`, so its rows and columns of every product
    /// are 0 but its own 1): `qv_c`, `pv_c`, `zv_c` (the rows of `Q V_u`,
    /// `P V_w`, `Z V_u`) on the coupled entries of `s` (columns,
    /// `coupled`) into the rows `qv_rows` of `Q u` (the coupled modes,
    /// then the closed contacts), `pv_rows` of `z'` (the coupled modes,
    /// then the held masses) and `bound_rows` (every held mass); `vq_c` and
    /// `vp_c` (of `V^-1_u Q^T` and `V^-1_w P^T`) from those same rows into
    /// the coupled entries. A switch costs four products of about `d x d /
    /// 2` for the `d` coordinates of the coupled parts it leaves and enters
    /// and O(N) for the free modes (the sums are the dense products', whose
    /// other terms are 0).
    qv_c: DMatrix<f64>,
    qv_rows: Vec<usize>,
    pv_c: DMatrix<f64>,
    pv_rows: Vec<usize>,
    zv_c: DMatrix<f64>,
    bound_rows: Vec<usize>,
    vq_c: DMatrix<f64>,
    vp_c: DMatrix<f64>,
    /// The four products above (`qv_c`, `pv_c`, `vq_c`, `vp_c`) in
    /// hierarchical low-rank form where that pays.
    structured: StructuredProducts,
    /// The free modes' blocks: the mode and the entries of `s` holding its
    /// `omega q` and `q'`.
    free_blocks: Vec<(usize, usize, usize)>,
    s_star: Vec<f64>,
    /// Each closed contact's `p0_c`.
    p0: Vec<f64>,
    /// Per closed contact: how the block state's equilibrium moves per
    /// metre of an offset rod in it, `V^-1 dy*/dd_c` (the rod shortens the
    /// spring's rest length: `p0_c -> p0_c - d_c`; docs/numerics.md
    /// section 14, "The offset rod per contact").
    rod_s: Vec<Vec<f64>>,
    /// Per contact (all of them): the row and constant of its penetration
    /// (without the flights), its slope row `r G`, and the curvature
    /// weights `|r_k G_k^2|` per block (times each block's growth over the
    /// step, [`PhaseTables::growth`], they bound its share of `psi''`).
    ev: Vec<Vec<f64>>,
    ev0: Vec<f64>,
    ev_d: Vec<Vec<f64>>,
    ev_c2: Vec<Vec<f64>>,
    /// Per contact: `|r_k|` per block (block `k`'s share of the function
    /// stays within it times its growth times `|s_k|`).
    ev_e: Vec<Vec<f64>>,
    /// Per contact: the flights in its penetration (lower side's adds,
    /// upper side's subtracts; none when both ride the same one).
    ev_fly: Vec<(Option<usize>, Option<usize>)>,
    /// Per contact: the block kernel's event row that sums its row
    /// (`multi/fast.rs`): a contact in the shadow of an open stage below
    /// ([`shadow`](Self::shadow)) reads the row of the lowest stage down
    /// that chain (the same numbers: only the constant differs), any other
    /// contact its own; `None` for a row beyond the kernel's `EVENT_ROWS`,
    /// and then the block path does not run in this phase.
    kernel_row: Vec<Option<usize>>,
    /// Whether every contact has a kernel row.
    kernel_ready: bool,
    /// The observation rows the kernel sums beside contact 0's row for
    /// [`kernel_row`](Self::kernel_row) (0, 1 or 3: a law whose pieces are
    /// all open reads its first piece's row alone).
    kernel_obs: usize,
    /// Per contact: the open stage below it whose row and flights are its
    /// own, and how much deeper it lies (`d > 0`), while both are open
    /// (a law's further piece in flight); `None` otherwise. Its
    /// penetration is that stage's less `d` at every instant, so it
    /// cannot cross before that stage does: the step's search leaves it
    /// out, and the block path's certificate of that stage implies its own
    /// where its margin is within `d / 2` of the stage's
    /// (docs/numerics.md section 14, "Stages in flight").
    shadow: Vec<Option<(usize, f64)>>,
    /// Per contact: the blocks its row or slope row touches (the others'
    /// weights in its bounds are 0 too: an evaluation skips them), and the
    /// entries where its row and its slope row are not 0 (its dot
    /// products sum those, in order: the dense sums' values).
    ev_blocks: Vec<Vec<usize>>,
    ev_nz: Vec<Vec<usize>>,
    evd_nz: Vec<Vec<usize>>,
    /// What the certified search's bounds take beyond those rows.
    search: SearchRows,
    /// Per contact: where its lower and upper sides are (the trace).
    sides: Vec<[SideRows; 2]>,
    /// The entries of `s` the coupled part moves, and its modes.
    coupled: Vec<usize>,
    coupled_modes: Vec<usize>,
    /// Output rows and constants (left, right) of the displacement
    /// pickups and of the velocity pickups (a time scale `s` takes the
    /// second times `s`: physical velocities are `s` times the model's).
    out_d: [Vec<f64>; 2],
    out_d0: [f64; 2],
    out_v: [Vec<f64>; 2],
    out_v0: [f64; 2],
    /// Condition number of `V` (largest over smallest singular value).
    pub kappa: f64,
    /// The largest block growth over one sample, `max_k e^(gamma_k h)` (1
    /// for contractions; rounding can make an undamped block's a few ulps
    /// more): a bound taken from a state holds `n` samples later times its
    /// `n`-th power.
    pub growth: f64,
}

/// What the certified search (`engine/search.rs`, through
/// `multi/search.rs`) needs of a phase beyond its event rows: per contact
/// the curvature row `r G^2` (the model's `psi''`), and per block the
/// slope and third-derivative weights `|r_k G_k|` and `|r_k G_k^3|` (times
/// the block's growth they bound its share of `psi'` and `psi'''`); per
/// block the spectral radius of its generator (how fast it turns: a node
/// of width `w` resolves it when `rho w <= THETA_RESOLVED`).
#[derive(Debug, Clone, Default)]
struct SearchRows {
    ev_dd: Vec<Vec<f64>>,
    c1: Vec<Vec<f64>>,
    c3: Vec<Vec<f64>>,
    /// `|(r G^4)_k|`: the fourth derivative's weights (the Hermite
    /// certificates' remainder, docs/numerics.md section 14).
    c4: Vec<Vec<f64>>,
    rho: Vec<f64>,
}

/// The largest eigenvalue magnitude of a 2x2 generator.
fn spectral_radius(g: &Mat2) -> f64 {
    let half_tr = 0.5 * (g[0] + g[3]);
    let det = g[0] * g[3] - g[1] * g[2];
    let disc = half_tr * half_tr - det;
    if disc < 0.0 {
        det.sqrt()
    } else {
        half_tr.abs() + disc.sqrt()
    }
}

/// A compiled model: every phase that can be reached, by its contact bit
/// set.
#[derive(Debug, Clone)]
pub struct CompiledMulti {
    /// The model it was compiled from.
    pub model: MultiModel,
    /// Sample period \[s\].
    pub h: f64,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// The phases that can be reached ([`MultiModel::reachable_masks`]),
    /// in increasing order of their masks: `phases[slot(mask)]`, the
    /// phase with no contact closed first.
    pub phases: Vec<MultiPhase>,
    /// Per mask: its phase's index in `phases`, or `u32::MAX` for a mask
    /// that is never reached.
    slots: Vec<u32>,
    /// Per contact: the bit of its stage below, or 0
    /// ([`MultiModel::stage_below`]).
    below: [u32; MAX_SPRINGS],
    /// How contacts switch: exactly, where each crosses, or with an
    /// offset rod per contact at sample instants (the paper's method;
    /// docs/numerics.md section 14, "The offset rod per contact").
    pub switching: Switching,
}

/// What the engine did (diagnostics, tests).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MultiStats {
    /// Switches taken (each a change of basis; simultaneous ones count
    /// once).
    pub switches: u64,
    /// Contacts started, per contact.
    pub contacts_started: [u64; MAX_SPRINGS],
    /// Samples that reached [`MAX_SWITCHES_PER_SAMPLE`].
    pub capped: u64,
    /// Switches whose contacts [`CompiledMulti::staged`] changed (a stage
    /// taken in or out with the one below it).
    pub staged: u64,
    /// Neutral and resolution-sized nodes of the certified search that
    /// ended with `psi > 0`: a touch at zero relative speed within
    /// rounding, no switch (the one-contact engine's
    /// [`ExactStats::grazing`](crate::engine::ExactStats::grazing)).
    pub grazing: u64,
    /// Nodes the search left undecided (none can be: its stack is as deep
    /// as the root resolution; kept as a diagnostic the tests assert is 0).
    pub uncertified: u64,
    /// Evaluations of an event function inside a step (a node's bounds or
    /// a value).
    pub evaluations: u64,
    /// Samples the block path stepped and certified.
    pub kernel_samples: u64,
    /// Samples the block path stepped past one that failed its
    /// certificate, thrown away (stepped again by the search).
    pub kernel_discarded: u64,
    /// Contacts' samples (or rests of a sample) the Hermite certificates
    /// cleared without a search, where the chord's margin did not.
    pub hermite_cleared: u64,
    /// Contacts' searches left out as stages in flight behind their open
    /// stage below (`MultiPhase::shadow`).
    pub shadowed: u64,
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

/// Why [`MultiState::strike`] struck nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StrikeRefused {
    /// The contact's upper side is not a mass.
    NotAMass,
    /// The height or the velocity is not a finite number (or the height
    /// is negative).
    NotFinite,
    /// The mass has no place with its contacts open: a side above it is
    /// lower than a side below it (less their gaps).
    Wedged,
}

/// What one sample shows of each contact: its upper side (the hammer of a
/// hammer's contact) and its lower side (the struck point).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MultiObservation {
    /// Upper sides' heights \[m\] (a hammer's face).
    pub x_hammer: [f64; MAX_SPRINGS],
    /// Upper sides' velocities \[m/s\].
    pub v_hammer: [f64; MAX_SPRINGS],
    /// Lower sides' displacements \[m\] (the struck point).
    pub x_contact: [f64; MAX_SPRINGS],
    /// Lower sides' velocities \[m/s\].
    pub v_contact: [f64; MAX_SPRINGS],
    /// The contacts in contact (bit `j`).
    pub active: u32,
    /// Total energy \[J\] (objects, masses, springs in contact, gravity).
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

fn two_pi() -> f64 {
    2.0 * std::f64::consts::PI
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// [`dot`] over the entries `idx` (increasing) where `a` is not 0: the
/// same sum, without its zero terms.
fn dot_at(a: &[f64], b: &[f64], idx: &[usize]) -> f64 {
    idx.iter().map(|&i| a[i] * b[i]).sum()
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

/// A row over `y` as a row over `s` and a constant (`y = V s + y*`).
fn in_phase(row_y: &[f64], v: &DMatrix<f64>, y_star: &[f64]) -> (Vec<f64>, f64) {
    let dim = row_y.len();
    let row = (0..dim)
        .map(|col| (0..dim).map(|r| row_y[r] * v[(r, col)]).sum())
        .collect();
    (row, dot(row_y, y_star))
}

/// Which masses a phase holds and how: union-find over the closed
/// contacts between masses; a group is held when one of its masses
/// touches an object or a wall.
struct Layout {
    bound: Vec<usize>,
    place: Vec<Option<usize>>,
    groups: Vec<Vec<usize>>,
    fly_of: Vec<Option<usize>>,
}

/// What a state steps a phase with at its time scale (made for each phase
/// up front, brought to the state's scale when the phase is entered).
#[derive(Debug, Clone)]
struct PhaseTables {
    /// Each block's propagator over one step, and the same as the block
    /// kernel's arrays.
    props: Vec<Mat2>,
    soa: BlockProps,
    /// Each block's growth over one step, `e^(gamma_k h_s)`, and the
    /// largest (at least 1).
    growth: Vec<f64>,
    growth_max: f64,
    /// Per contact, per block: the phase's curvature weights and
    /// magnitudes times the block's growth (the search's bounds).
    ev_c2: Vec<Vec<f64>>,
    ev_e: Vec<Vec<f64>>,
    /// Per contact, per block: the phase's slope and third-derivative
    /// weights ([`SearchRows`]) times the block's growth.
    ev_c1: Vec<Vec<f64>>,
    ev_c3: Vec<Vec<f64>>,
    ev_c4: Vec<Vec<f64>>,
    /// Output rows and constants: displacement plus `scale` times
    /// velocity, less the modes above the output band.
    out: [Vec<f64>; 2],
    out0: [f64; 2],
    /// The scale they were made at, the band's limit then (the model's
    /// angular frequency above which a mode is left out of the outputs,
    /// `2 pi band / scale`; infinite: none) and the modes it leaves out.
    at: f64,
    limit: f64,
    muted: usize,
}

/// The running state of a [`CompiledMulti`]. A clone keeps the room its
/// vectors have (a `Vec`'s own clone keeps only its length): the clone of
/// a state made for a compile steps it without allocating, as the state
/// does.
#[derive(Debug)]
pub struct MultiState {
    mask: u32,
    /// The phase of `mask` in the compile's list (`CompiledMulti::slot`).
    slot: usize,
    /// Time scale: each sample advances the model's time by `scale h`
    /// (docs/numerics.md section 14, "Time scale").
    scale: f64,
    /// `scale h` \[s of the model's time\].
    step_h: f64,
    /// Per phase.
    tables: Vec<PhaseTables>,
    s: Vec<f64>,
    end: Vec<f64>,
    /// Per block of the current phase, `|s_k|` at the step's start (the
    /// epoch's margin).
    norms: Vec<f64>,
    /// Per flight slot (one per mass): the height and velocity of a free
    /// mass, or of the centre of a free group whose first mass it is (at
    /// the state's time).
    x_f: Vec<f64>,
    v_f: Vec<f64>,
    /// Scratch of a switch: positions and velocities in `z`, the reduced
    /// ones, and the physical state (every mode's `q, q'`, every mass's
    /// `x, v`).
    zq: Vec<f64>,
    zv: Vec<f64>,
    phys: Physical,
    /// The structured products' scratch (a box: off the state's own size).
    sw: Box<SwitchScratch>,
    /// Per contact: a whole-sample margin (`w = h`) and the epoch of the
    /// clock (64 samples) it was taken in, in the current phase (times the
    /// phase's growth over 64 samples, it holds for every later state of
    /// the epoch).
    cached: [(u64, f64); MAX_SPRINGS],
    /// The certified search's pending nodes.
    stack: [(f64, f64); STACK],
    /// The blocks' exponentials at a node or a partial step.
    trig: Trig,
    /// The kernels' path: this CPU's fastest, or the portable one
    /// ([`set_portable_kernels`](Self::set_portable_kernels)).
    simd: SimdPath,
    /// The block path's scratch, and whether it runs (a test knob: off,
    /// every sample takes the search's way).
    kern: Box<fast::Kern>,
    block_path: bool,
    /// Whether a sample the chord's margin leaves is tried by the Hermite
    /// certificates before the search (a test knob: off, the search
    /// decides every such sample).
    hermite: bool,
    /// Whether a stage in flight behind its open stage below is left out
    /// of the search and the block path's certificates
    /// ([`MultiPhase::shadow`]; a test knob: off, every contact is
    /// searched and certified).
    shadows: bool,
    /// The contacts whose block-path certificate follows from their
    /// shadowing stage's at the current margins (`fast.rs`, `implied`),
    /// set at the start of each run.
    implied: u32,
    /// How many samples the block path tries at once (`fast::SPEC_RESTART`
    /// after a sample failed, doubled after each whole run).
    spec_len: usize,
    /// Offset rod: each contact's rod \[m\] (0 when open, and always with
    /// exact switching), the block state's equilibrium shift they make in
    /// the current phase (`shift = sum_c d_c rod_s_c`: with rods, `s` is
    /// held about the shifted equilibrium, so a sample steps it as it
    /// is, and a row's constant takes `row . shift`), whether any is not
    /// 0, those constants (per contact its penetration's, its sides'
    /// positions' and velocities', and the outputs' displacement and
    /// velocity parts), and the clock of the last decision (one per
    /// sample instant).
    rod: [f64; MAX_SPRINGS],
    shift: Vec<f64>,
    rods_on: bool,
    off_ev: [f64; MAX_SPRINGS],
    off_sides: [[(f64, f64); 2]; MAX_SPRINGS],
    off_out: [f64; 2],
    decided: u64,
    /// The output band \[Hz\], physical ([`set_output_band`](Self::set_output_band)).
    band_hz: f64,
    /// Samples run.
    clock: u64,
    /// What the engine did.
    pub stats: MultiStats,
    /// Every switch, when [`record`](Self::record) is on.
    pub switches: Vec<MultiSwitch>,
    record: bool,
}

/// `v` cloned with the room `v` has.
fn with_room(v: &[f64], room: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(room.max(v.len()));
    out.extend_from_slice(v);
    out
}

impl Clone for MultiState {
    fn clone(&self) -> Self {
        Self {
            mask: self.mask,
            slot: self.slot,
            scale: self.scale,
            step_h: self.step_h,
            tables: self.tables.clone(),
            s: with_room(&self.s, self.s.capacity()),
            end: self.end.clone(),
            norms: self.norms.clone(),
            x_f: self.x_f.clone(),
            v_f: self.v_f.clone(),
            zq: self.zq.clone(),
            zv: self.zv.clone(),
            phys: self.phys.clone(),
            sw: self.sw.clone(),
            cached: self.cached,
            stack: self.stack,
            trig: self.trig.clone(),
            simd: self.simd,
            kern: self.kern.clone(),
            block_path: self.block_path,
            hermite: self.hermite,
            shadows: self.shadows,
            implied: self.implied,
            spec_len: self.spec_len,
            rod: self.rod,
            shift: self.shift.clone(),
            rods_on: self.rods_on,
            off_ev: self.off_ev,
            off_sides: self.off_sides,
            off_out: self.off_out,
            band_hz: self.band_hz,
            decided: self.decided,
            clock: self.clock,
            stats: self.stats,
            switches: self.switches.clone(),
            record: self.record,
        }
    }
}

/// Where a contact's search starts: its event function's value, or 0 on
/// the side it just switched to.
#[derive(Clone, Copy)]
enum Start {
    Value,
    Boundary,
}

/// Contact `j`'s event function in the current phase: its penetration
/// `p = q(t) + x0 + v0 t - g t^2 / 2` (`q` from the state's row, the rest
/// the flights of its free sides, the lower side's less the upper side's),
/// signed to be positive on the current side (`sign` 1 in contact, -1 in
/// flight).
struct EventFn {
    sign: f64,
    x0: f64,
    v0: f64,
    g: f64,
    /// The flights' magnitudes: heights, speeds and gravities summed (the
    /// rounding allowance's share of them).
    scale: (f64, f64, f64),
}

impl EventFn {
    /// `psi` at `t` from the row's part `q` of the penetration.
    fn psi(&self, q: f64, t: f64) -> f64 {
        self.sign * (q + self.x0 + self.v0 * t - 0.5 * self.g * t * t)
    }

    /// `psi'` at `t` from the row's slope `dq`.
    fn dpsi(&self, dq: f64, t: f64) -> f64 {
        self.sign * (dq + self.v0 - self.g * t)
    }
}

/// `out[rows[r]] += sum_c M[r, c] x[cols[c]]` for a column-major `M`, by
/// columns in the order of `cols` (increasing, as a dense product's), so
/// the sums are those of the dense product over the whole vectors whose
/// other entries of `M` are 0.
/// Rows that run without a gap (a struck object's modes, which every
/// contact couples) take a contiguous axpy per column, which the compiler
/// vectorises; the same products in the same order, so the same sums.
fn mat_vec_idx(m: &DMatrix<f64>, (cols, x): (&[usize], &[f64]), rows: &[usize], out: &mut [f64]) {
    let nr = rows.len();
    let data = m.as_slice();
    if let Some(&r0) = rows.first() {
        if rows.iter().enumerate().all(|(i, &r)| r == r0 + i) {
            let out = &mut out[r0..r0 + nr];
            for (c, &xc) in cols.iter().enumerate() {
                let v = x[xc];
                if v == 0.0 {
                    continue;
                }
                for (o, a) in out.iter_mut().zip(&data[c * nr..(c + 1) * nr]) {
                    *o += a * v;
                }
            }
            return;
        }
    }
    for (c, &xc) in cols.iter().enumerate() {
        let v = x[xc];
        if v == 0.0 {
            continue;
        }
        for (a, &r) in data[c * nr..(c + 1) * nr].iter().zip(rows) {
            out[r] += a * v;
        }
    }
}

/// `out = P s` with one-sample block propagators, in the block kernel's
/// arithmetic on `simd` (`x0 = p00 a + (p01 b)`, the first product fused on
/// the FMA path, as `engine/kernel/block.rs` steps a block): a whole sample
/// stepped here is the block path's bit for bit on either path.
/// \[audio-thread\]
fn step_blocks(simd: SimdPath, props: &[Mat2], s: &[f64], out: &mut [f64], nb: usize) {
    match simd {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdPath::Avx2Fma` holds an `Avx2Fma` token, which only `SimdPath::detect()`
        // makes, after `is_x86_feature_detected!` confirmed AVX2 and FMA on this CPU.
        SimdPath::Avx2Fma(_) => unsafe { step_blocks_fma(props, s, out, nb) },
        _ => step_blocks_body::<false>(props, s, out, nb),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn step_blocks_fma(props: &[Mat2], s: &[f64], out: &mut [f64], nb: usize) {
    step_blocks_body::<true>(props, s, out, nb);
}

#[inline(always)]
fn step_blocks_body<const FMA: bool>(props: &[Mat2], s: &[f64], out: &mut [f64], nb: usize) {
    for (k, p) in props.iter().enumerate() {
        let (a, b) = (s[k], s[nb + k]);
        out[k] = madd::<FMA>(p[0], a, p[1] * b);
        out[nb + k] = madd::<FMA>(p[2], a, p[3] * b);
    }
}

/// `out = exp(G t) s`, the blocks' exponentials in one batch.
fn step_to(
    ph: &MultiPhase,
    (simd, trig): (SimdPath, &mut Trig),
    t: f64,
    s: &[f64],
    out: &mut [f64],
) {
    let nb = ph.gens.len();
    trig.at(simd, ph, 0..nb, t);
    for k in 0..nb {
        let p = trig.exp(ph, k, k, t);
        let (x0, x1) = mul2(&p, s[k], s[nb + k]);
        out[k] = x0;
        out[nb + k] = x1;
    }
}

/// Scratch of the blocks' exponentials at one time `t`, taken in one batch
/// by the engine's vectorised `exp`, `sin` and `cos` (`engine/vmath.rs`, on
/// the state's kernel path): per listed block, `exp(m t)`, `sin(w t)`, `cos(w t)` of its
/// oscillatory form. A block without one (real eigenvalues) takes
/// [`exp2`] when asked. Sized for the largest phase; never allocates after
/// [`Trig::new`].
#[derive(Debug, Clone)]
struct Trig {
    mt: Vec<f64>,
    wt: Vec<f64>,
    e: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
}

impl Trig {
    fn new(blocks: usize) -> Self {
        let v = || vec![0.0; blocks];
        Self {
            mt: v(),
            wt: v(),
            e: v(),
            sin: v(),
            cos: v(),
        }
    }

    /// The exponentials of `blocks` (the `i`-th listed block in slot `i`)
    /// at `t`. \[audio-thread\]
    fn at(&mut self, simd: SimdPath, ph: &MultiPhase, blocks: impl Iterator<Item = usize>, t: f64) {
        let mut n = 0;
        for k in blocks {
            let (m, w) = ph.forms[k].as_ref().map_or((0.0, 0.0), |f| (f.m, f.w));
            self.mt[n] = m * t;
            self.wt[n] = w * t;
            n += 1;
        }
        vmath::exp_sincos(
            simd,
            &self.mt[..n],
            &self.wt[..n],
            &mut self.e[..n],
            &mut self.sin[..n],
            &mut self.cos[..n],
        );
    }

    /// `exp(G_k t)` of block `k`, taken by [`at`](Self::at) in slot `i`.
    #[inline]
    fn exp(&self, ph: &MultiPhase, k: usize, i: usize, t: f64) -> Mat2 {
        match &ph.forms[k] {
            Some(f) => f.exp_from(self.e[i], self.sin[i], self.cos[i]),
            None => exp2(&ph.gens[k], t),
        }
    }
}

/// A physical state: every mode's `q, q'` and every mass's `x, v`.
#[derive(Debug, Clone)]
struct Physical {
    q: Vec<f64>,
    qv: Vec<f64>,
    x: Vec<f64>,
    v: Vec<f64>,
}

/// The scene's field paths of a model's parts, in the order of
/// [`MultiModel::from_scene`] (contact 0 `[contact]`, then each
/// `[[striker]]`, then each `[[touch]]`; mass 0 `[hammer]`, then each
/// striker), so a model's refusal names what to change in the scene.
struct SceneNames {
    /// `"touch"` when the scene has touches, else `"striker"`.
    key: &'static str,
    /// Per contact: its table, its lower side, its upper side, and the
    /// field that sets where its sides start.
    contacts: Vec<[String; 4]>,
    /// Per mass: its table.
    masses: Vec<String>,
    /// The object in a contact with the most modes, when known.
    largest: Option<String>,
}
