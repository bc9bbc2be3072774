//! Several contacts at once between modal objects, point masses and walls:
//! up to [`MAX_CONTACTS`] linear spring-dampers, each between two sides
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
use crate::engine::TimeScaleError;
use crate::physics::block::{exp2, mul2, sym_growth, Mat2, OscForm};
use crate::physics::decomp::{decompose_via, Form};
use crate::physics::model::LN_1000;
use crate::scene::{End as SceneEnd, ObjectSpec, Quantity, Scene, SceneError, Switching};
use nalgebra::DMatrix;

/// Most contacts of one scene, the scene's.
pub use crate::scene::MAX_CONTACTS;

/// Most switches taken within one sample, the engine's; beyond, the rest of
/// the sample runs in its phase without a search ([`MultiStats::capped`]).
pub use crate::engine::MAX_SWITCHES_PER_SAMPLE;

/// Halving stops at pieces narrower than this fraction of the sample.
const LEAF: f64 = 1e-15;

/// Norm slots made up front: the search's stack is one slot per level of
/// halving (a leaf is about 50 levels below a sample) plus two.
const NORM_SLOTS: usize = 72;

/// Most halvings of one contact's search in one step; the pieces left
/// are counted as `uncertified` (docs/numerics.md section 14).
pub const SEARCH_BUDGET: u32 = 1 << 14;

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
    /// The contacts, 1 to [`MAX_CONTACTS`].
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
    /// No contact, or more than [`MAX_CONTACTS`].
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
                "contacts: {n} contacts, a scene of several contacts has 1 to {MAX_CONTACTS}"
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

impl SceneNames {
    fn of(scene: &Scene) -> Self {
        let c = &scene.contact;
        let struck = if c.point.is_some() {
            "contact.point"
        } else {
            "contact.object"
        };
        let mut contacts = vec![[
            "contact".to_string(),
            struck.to_string(),
            "hammer".to_string(),
            "hammer.height_m".to_string(),
        ]];
        let mut masses = vec!["hammer".to_string()];
        for i in 0..scene.striker.len() {
            let s = format!("striker[{i}]");
            contacts.push([
                s.clone(),
                format!("{s}.point"),
                s.clone(),
                format!("{s}.height_m"),
            ]);
            masses.push(s);
        }
        for i in 0..scene.touch.len() {
            let t = format!("touch[{i}]");
            contacts.push([
                t.clone(),
                format!("{t}.lower"),
                format!("{t}.upper"),
                format!("{t}.gap_m"),
            ]);
        }
        Self {
            key: if scene.touch.is_empty() {
                "striker"
            } else {
                "touch"
            },
            contacts,
            masses,
            largest: None,
        }
    }

    /// A model's field, as [`MultiModel::validate`] names it, as the
    /// scene's.
    fn field(&self, field: &str) -> String {
        let indexed = |prefix: &str| -> Option<(usize, &str)> {
            let (i, rest) = field.strip_prefix(prefix)?.split_once(']')?;
            Some((i.parse().ok()?, rest))
        };
        if let Some((j, rest)) = indexed("contacts[") {
            if let Some(c) = self.contacts.get(j) {
                if rest.starts_with(".lower") {
                    return c[1].clone();
                }
                if rest.starts_with(".upper") {
                    return c[2].clone();
                }
                return format!("{}{rest}", c[0]);
            }
        }
        if let Some((j, rest)) = indexed("masses[") {
            if let Some(m) = self.masses.get(j) {
                return format!("{m}{rest}");
            }
        }
        match field {
            "gravity_m_per_s2" => "hammer.gravity_m_per_s2".into(),
            f if f.starts_with("freq_hz") || f.starts_with("sigma") => "object".into(),
            f if f.starts_with("pickups") => "pickup".into(),
            f if f.starts_with("masses") => "striker".into(),
            f => f.into(),
        }
    }

    /// `e` as a scene error naming the scene's field.
    fn error(&self, e: &MultiError) -> SceneError {
        let name = |j: usize| {
            self.contacts
                .get(j)
                .map_or_else(|| format!("contacts[{j}]"), |c| c[0].clone())
        };
        match e {
            MultiError::ContactCount(n) => SceneError::new(
                self.key,
                format!("{n} contacts, a scene of several contacts has 1 to {MAX_CONTACTS}"),
            ),
            MultiError::Length { field, got, want } => {
                SceneError::new(self.field(field), format!("{got} entries for {want} modes"))
            }
            MultiError::Value { field, value } => {
                SceneError::new(self.field(field), format!("{value} is out of range"))
            }
            MultiError::SamePoint(a, b) => SceneError::new(
                name(*b),
                format!(
                    "the same pair as {} (the same two sides the same way round at the same \
                     gap; two walls at one height are one surface): two contacts on one point \
                     pair; make them one contact, or set them apart with gap_m",
                    name(*a)
                ),
            ),
            MultiError::Sides { contact, part, why } => {
                let k = match *part {
                    "lower" => 1,
                    "upper" => 2,
                    "gap_m" => 3,
                    _ => 0,
                };
                let path = self
                    .contacts
                    .get(*contact)
                    .map_or_else(|| format!("contacts[{contact}]"), |c| c[k].clone());
                SceneError::new(path, why.clone())
            }
            MultiError::OverBudget {
                phases,
                dim,
                flops,
                bytes,
            } => SceneError::new(
                self.largest.clone().unwrap_or_else(|| "object".into()),
                over_budget(*phases, *dim, *flops, *bytes),
            ),
            MultiError::Phase { mask, why } => {
                let members: Vec<String> = (0..MAX_CONTACTS)
                    .filter(|j| mask & (1 << j) != 0)
                    .map(name)
                    .collect();
                SceneError::new(
                    members.first().cloned().unwrap_or_else(|| self.key.into()),
                    format!("the phase with {} in contact: {why}", members.join(", ")),
                )
            }
        }
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
    /// Per contact: the blocks its row or slope row touches (the others'
    /// weights in its bounds are 0 too: an evaluation skips them), and the
    /// entries where its row and its slope row are not 0 (its dot
    /// products sum those, in order: the dense sums' values).
    ev_blocks: Vec<Vec<usize>>,
    ev_nz: Vec<Vec<usize>>,
    evd_nz: Vec<Vec<usize>>,
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
    pub x_hammer: [f64; MAX_CONTACTS],
    /// Upper sides' velocities \[m/s\].
    pub v_hammer: [f64; MAX_CONTACTS],
    /// Lower sides' displacements \[m\] (the struck point).
    pub x_contact: [f64; MAX_CONTACTS],
    /// Lower sides' velocities \[m/s\].
    pub v_contact: [f64; MAX_CONTACTS],
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

impl MultiModel {
    fn n(&self) -> usize {
        self.freq_hz.len()
    }

    /// One modal object struck by point-mass hammers, each through a
    /// contact of its own at a point of its own (contact `j` is hammer
    /// `j`'s).
    pub fn struck(
        freq_hz: Vec<f64>,
        sigma: Vec<f64>,
        hammers: &[MultiHammer],
        gravity_m_per_s2: f64,
        pickups: [(Vec<f64>, Vec<f64>); 2],
    ) -> Self {
        Self {
            freq_hz,
            sigma,
            masses: hammers
                .iter()
                .map(|h| MultiMass {
                    mass_kg: h.mass_kg,
                    height_m: h.height_m,
                    velocity_m_per_s: h.velocity_m_per_s,
                })
                .collect(),
            contacts: hammers
                .iter()
                .enumerate()
                .map(|(j, h)| MultiContact {
                    lower: MultiEnd::Point(h.weights.clone()),
                    upper: MultiEnd::Mass(j),
                    gap_m: 0.0,
                    stiffness_n_per_m: h.stiffness_n_per_m,
                    damping_n_s_per_m: h.damping_n_s_per_m,
                })
                .collect(),
            gravity_m_per_s2,
            pickups,
        }
    }

    /// A side's initial height (the objects start at rest).
    fn rest_height(&self, e: &MultiEnd) -> f64 {
        match e {
            MultiEnd::Point(_) => 0.0,
            MultiEnd::Mass(j) => self.masses[*j].height_m,
            MultiEnd::Wall(h) => *h,
        }
    }

    /// Check every field (a clear error naming it, never a panic).
    pub fn validate(&self) -> Result<(), MultiError> {
        let n = self.n();
        let k = self.contacts.len();
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
        // every mass can be in a contact: at most two per contact
        if self.masses.len() > 2 * MAX_CONTACTS {
            return Err(MultiError::Value {
                field: "masses (more than two per contact)".into(),
                value: self.masses.len() as f64,
            });
        }
        for (j, m) in self.masses.iter().enumerate() {
            let f = |name: &str| format!("masses[{j}].{name}");
            check_value(&f("mass_kg"), m.mass_kg, m.mass_kg > 0.0)?;
            check_value(&f("height_m"), m.height_m, true)?;
            check_value(&f("velocity_m_per_s"), m.velocity_m_per_s, true)?;
        }
        for (j, c) in self.contacts.iter().enumerate() {
            let f = |name: &str| format!("contacts[{j}].{name}");
            let sides = |part: &'static str, why: String| MultiError::Sides {
                contact: j,
                part,
                why,
            };
            check_value(
                &f("stiffness_n_per_m"),
                c.stiffness_n_per_m,
                c.stiffness_n_per_m > 0.0,
            )?;
            check_value(
                &f("damping_n_s_per_m"),
                c.damping_n_s_per_m,
                c.damping_n_s_per_m >= 0.0,
            )?;
            check_value(&f("gap_m"), c.gap_m, true)?;
            for (name, e) in [("lower", &c.lower), ("upper", &c.upper)] {
                match e {
                    MultiEnd::Point(w) => {
                        len(&f(&format!("{name}.weights")), w.len())?;
                        for (i, x) in w.iter().enumerate() {
                            check_value(&f(&format!("{name}.weights[{i}]")), *x, true)?;
                        }
                    }
                    MultiEnd::Mass(m) if *m >= self.masses.len() => {
                        return Err(sides(
                            name,
                            format!("{name} is mass {m}, there are {}", self.masses.len()),
                        ));
                    }
                    MultiEnd::Mass(_) => {}
                    MultiEnd::Wall(h) => check_value(&f(&format!("{name}.wall")), *h, true)?,
                }
            }
            if matches!((&c.lower, &c.upper), (MultiEnd::Wall(_), MultiEnd::Wall(_))) {
                return Err(sides("upper", "two walls cannot touch".into()));
            }
            if c.lower == c.upper {
                return Err(sides("upper", "a side in contact with itself".into()));
            }
            let p0 = self.rest_height(&c.lower) - self.rest_height(&c.upper) - c.gap_m;
            if p0 > 0.0 {
                return Err(sides(
                    "gap_m",
                    format!("starts {p0:e} m pressed in: its sides must start apart or touching"),
                ));
            }
            if let Some(l) = self.contacts[..j]
                .iter()
                .position(|other| same_penetration(other, c))
            {
                return Err(MultiError::SamePoint(l, j));
            }
        }
        Ok(())
    }
}

impl MultiModel {
    /// Every phase's eigendecomposition and checks (about 40 d^3 flop for
    /// d coordinates) and its two bases (2 d^2 numbers) within the compile
    /// budget: refused before any of it.
    fn within_budget(&self) -> Result<(), MultiError> {
        let phases = 1usize << self.contacts.len();
        let dim = 2 * (self.n() + self.masses.len());
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
        Ok(())
    }
}

/// Two contacts with one penetration `p = x_lower - x_upper - gap`: the
/// same sides the same way round, and the same gap once a wall's height is
/// counted in it (`p = h - x_upper - gap` against a wall below, `x_lower -
/// h - gap` against one above), so a wall is told by where it is, not by
/// its kind. Such a pair is one spring-damper twice. The same sides the
/// other way round are two faces (a mass between a floor and a ceiling),
/// at another gap two stages of a contact: different contacts.
fn same_penetration(a: &MultiContact, b: &MultiContact) -> bool {
    let same_side = |x: &MultiEnd, y: &MultiEnd| match (x, y) {
        (MultiEnd::Wall(_), MultiEnd::Wall(_)) => true,
        _ => x == y,
    };
    let offset = |c: &MultiContact| {
        let wall = |e: &MultiEnd| match e {
            MultiEnd::Wall(h) => *h,
            _ => 0.0,
        };
        c.gap_m - wall(&c.lower) + wall(&c.upper)
    };
    same_side(&a.lower, &b.lower) && same_side(&a.upper, &b.upper) && offset(a) == offset(b)
}

/// The scene's objects a side of a contact names, as the model's sides
/// (docs/design.md, "Several contacts").
struct SceneSides<'a> {
    scene: &'a Scene,
    /// Per object: its first mode in the model's list (modal objects in a
    /// contact only).
    first_mode: Vec<Option<usize>>,
    n: usize,
}

impl SceneSides<'_> {
    fn object(&self, field: &str, name: &str) -> Result<usize, SceneError> {
        self.scene
            .object_index(name)
            .ok_or_else(|| SceneError::new(field, format!("no object named {name:?}")))
    }

    /// The weights of object `name`'s point `point` over the model's modes.
    fn point(&self, field: &str, name: &str, point: &str) -> Result<Vec<f64>, SceneError> {
        let o = self.object(field, name)?;
        let ObjectSpec::Modal(m) = &self.scene.object[o] else {
            return Err(SceneError::new(field, format!("{name:?} has no modes")));
        };
        let k = m.points.iter().position(|p| p == point).ok_or_else(|| {
            SceneError::new(field, format!("object {name:?} has no point {point:?}"))
        })?;
        let first = self.first_mode[o].expect("every object in a contact has its modes placed");
        let mut w = vec![0.0; self.n];
        for (i, md) in m.mode.iter().enumerate() {
            w[first + i] = md.weights[k];
        }
        Ok(w)
    }

    /// A touch's side: the hammer, a wall, or a point of an object.
    fn side(&self, field: &str, end: &SceneEnd) -> Result<MultiEnd, SceneError> {
        if end.object == crate::scene::HAMMER_SIDE {
            return Ok(MultiEnd::Mass(0));
        }
        let o = self.object(field, &end.object)?;
        match (&self.scene.object[o], &end.point) {
            (ObjectSpec::Wall(_), _) => Ok(MultiEnd::Wall(0.0)),
            (_, Some(p)) => Ok(MultiEnd::Point(self.point(field, &end.object, p)?)),
            (_, None) => Err(SceneError::new(
                field,
                format!("{:?} needs a point", end.object),
            )),
        }
    }
}

impl MultiModel {
    /// The model of a scene with strikers or touches (docs/design.md,
    /// "Several contacts"): every modal object in a contact (objects from
    /// geometry and material become their modes at `rate_hz`), mass 0 the
    /// `[hammer]` and mass `1 + i` striker `i`; contact 0 is `[contact]`,
    /// then each `[[striker]]`'s, then each `[[touch]]`; the pickups on
    /// objects in a contact (those elsewhere hear nothing). A clear error
    /// naming the field where the scene asks for what several contacts do
    /// not take yet; the model's own checks and the compile budget are
    /// taken here too, each refusal naming the scene's field
    /// ([`MultiError::in_scene`]).
    pub fn from_scene(scene: &Scene, rate_hz: f64) -> Result<Self, SceneError> {
        scene.validate()?;
        let mut names = SceneNames::of(scene);
        let given = scene;
        let original_mallet = scene.hammer.object.clone().zip(scene.hammer.point.clone());
        let expanded = scene.expanded(rate_hz)?;
        let scene = &expanded;
        if scene.approximate.is_some() {
            return Err(SceneError::new(
                "approximate",
                "not with several contacts yet: remove it",
            ));
        }
        // the objects in a contact, by name
        let mut named: Vec<(String, &str)> = vec![("contact.object".into(), &scene.contact.object)];
        for (i, st) in scene.striker.iter().enumerate() {
            if let Some(m) = &st.mallet {
                named.push((format!("striker[{i}].mallet.object"), &m.object));
            }
        }
        for (i, t) in scene.touch.iter().enumerate() {
            for (side, e) in [("lower", &t.lower), ("upper", &t.upper)] {
                if e.object != crate::scene::HAMMER_SIDE {
                    named.push((format!("touch[{i}].{side}.object"), &e.object));
                }
            }
        }
        let mut first_mode = vec![None; scene.object.len()];
        let (mut freq_hz, mut sigma) = (vec![], vec![]);
        let mut most = 0;
        for (field, name) in named {
            let field = field.as_str();
            let o = scene
                .object_index(name)
                .ok_or_else(|| SceneError::new(field, format!("no object named {name:?}")))?;
            match &scene.object[o] {
                ObjectSpec::Modal(m) => {
                    if first_mode[o].is_none() {
                        first_mode[o] = Some(freq_hz.len());
                        for md in &m.mode {
                            freq_hz.push(md.freq_hz);
                            sigma.push(md.t60_s.map_or(0.0, |t| LN_1000 / t));
                        }
                        if m.mode.len() > most {
                            most = m.mode.len();
                            names.largest =
                                given.object_index(name).map(|o| format!("object[{o}]"));
                        }
                    }
                }
                ObjectSpec::Wall(_) => {}
                _ => {
                    return Err(SceneError::new(
                        field,
                        format!(
                            "several contacts touch objects with modes (kind \"modal\" or one \
                             from geometry and material) and walls, not {:?} (a lumped string)",
                            name
                        ),
                    ))
                }
            }
        }
        let n = freq_hz.len();
        let sides = SceneSides {
            scene,
            first_mode,
            n,
        };
        let c = &scene.contact;
        let lower0 = match &c.point {
            Some(p) => MultiEnd::Point(sides.point("contact.point", &c.object, p)?),
            None => sides.side(
                "contact.object",
                &SceneEnd {
                    object: c.object.clone(),
                    point: None,
                },
            )?,
        };
        let mut masses = vec![MultiMass {
            mass_kg: scene.hammer.mass_kg,
            height_m: scene.hammer.height_m,
            velocity_m_per_s: scene.hammer.velocity_m_per_s,
        }];
        let mut contacts = vec![MultiContact {
            lower: lower0,
            upper: MultiEnd::Mass(0),
            gap_m: 0.0,
            stiffness_n_per_m: c.stiffness_n_per_m,
            damping_n_s_per_m: c.damping_n_s_per_m,
        }];
        for (i, st) in scene.striker.iter().enumerate() {
            masses.push(MultiMass {
                mass_kg: st.mass_kg,
                height_m: st.height_m,
                velocity_m_per_s: st.velocity_m_per_s,
            });
            let mut w = sides.point(&format!("striker[{i}].point"), &c.object, &st.point)?;
            // a modal mallet's face is `x_j + psi . a` (its own modes, in
            // the list beside the struck object's): the struck point takes
            // `-psi` on them, as `[contact]`'s does for the hammer's mallet
            if let Some(m) = &st.mallet {
                let field = format!("striker[{i}].mallet.point");
                let tip = m.point.as_deref().unwrap_or_default();
                let psi = sides.point(&field, &m.object, tip)?;
                for (a, b) in w.iter_mut().zip(&psi) {
                    *a -= b;
                }
            }
            contacts.push(MultiContact {
                lower: MultiEnd::Point(w),
                upper: MultiEnd::Mass(i + 1),
                gap_m: 0.0,
                stiffness_n_per_m: st.stiffness_n_per_m,
                damping_n_s_per_m: st.damping_n_s_per_m,
            });
        }
        // a modal mallet's face is `x_h + psi . a` (its modes joined to the
        // struck object's, docs/design.md "Modal mallets"): the side it
        // touches takes `-psi` on them, as `[contact]`'s point does
        let face = match (&original_mallet, &c.point) {
            (Some((mallet, tip)), Some(_)) => {
                Some(sides.point("hammer.point", &c.object, &format!("{mallet}.{tip}"))?)
            }
            _ => None,
        };
        // a touch's side on the hammer: its face, or a point of its modal
        // mallet (`x_h + psi_p . a`, the same form with that point's psi)
        let psi_of = |field: String, e: &SceneEnd| -> Result<Option<Vec<f64>>, SceneError> {
            match (&original_mallet, &e.point) {
                (Some((mallet, _)), Some(p)) => Ok(Some(sides.point(
                    &field,
                    &c.object,
                    &format!("{mallet}.{p}"),
                )?)),
                _ => Ok(face.clone()),
            }
        };
        let less_face = |e: MultiEnd, gap: f64, below: bool, psi: Option<Vec<f64>>| {
            let Some(psi) = psi else {
                return (e, gap);
            };
            match e {
                MultiEnd::Point(w) => (
                    MultiEnd::Point(w.iter().zip(psi).map(|(a, b)| a - b).collect()),
                    gap,
                ),
                // p = h - x_h - psi a - gap = (-psi a) - x_h - (gap - h), or
                // p = x_h + psi a - h - gap = x_h - (-psi a) - (gap + h)
                MultiEnd::Wall(h) => (
                    MultiEnd::Point(psi.iter().map(|x| -x).collect()),
                    if below { gap - h } else { gap + h },
                ),
                MultiEnd::Mass(j) => (MultiEnd::Mass(j), gap),
            }
        };
        for (i, t) in scene.touch.iter().enumerate() {
            let mut lower = sides.side(&format!("touch[{i}].lower"), &t.lower)?;
            let mut upper = sides.side(&format!("touch[{i}].upper"), &t.upper)?;
            let mut gap = t.gap_m;
            if upper == MultiEnd::Mass(0) {
                let psi = psi_of(format!("touch[{i}].upper.point"), &t.upper)?;
                (lower, gap) = less_face(lower, gap, true, psi);
            } else if lower == MultiEnd::Mass(0) {
                let psi = psi_of(format!("touch[{i}].lower.point"), &t.lower)?;
                (upper, gap) = less_face(upper, gap, false, psi);
            }
            contacts.push(MultiContact {
                lower,
                upper,
                gap_m: gap,
                stiffness_n_per_m: t.stiffness_n_per_m,
                damping_n_s_per_m: t.damping_n_s_per_m,
            });
        }
        let mut pickups: [(Vec<f64>, Vec<f64>); 2] =
            std::array::from_fn(|_| (vec![0.0; n], vec![0.0; n]));
        for (i, p) in scene.pickup.iter().enumerate() {
            let placed = scene
                .object_index(&p.object)
                .is_some_and(|o| sides.first_mode[o].is_some());
            if !placed {
                continue;
            }
            let w = sides.point(&format!("pickup[{i}].point"), &p.object, &p.point)?;
            let (gl, gr) = pan_gains(p.pan);
            for (ch, g) in [(0, gl), (1, gr)] {
                let row = match p.quantity {
                    Quantity::Displacement => &mut pickups[ch].0,
                    Quantity::Velocity => &mut pickups[ch].1,
                    // none in an expanded scene: each became a displacement
                    // and a velocity pickup (`Scene::expanded`)
                    Quantity::Pressure => continue,
                };
                for (r, wi) in row.iter_mut().zip(&w) {
                    *r += wi * p.gain * g;
                }
            }
        }
        let model = MultiModel {
            freq_hz,
            sigma,
            masses,
            contacts,
            gravity_m_per_s2: scene.hammer.gravity_m_per_s2,
            pickups,
        };
        model
            .validate()
            .and_then(|()| model.within_budget())
            .map_err(|e| names.error(&e))?;
        Ok(model)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// [`dot`] with four partial sums (the compiler keeps them in vector
/// registers): the outputs' rows, every sample.
fn dot4(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a4, b4) = (a[..n].chunks_exact(4), b[..n].chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut acc = [0.0f64; 4];
    for (x, y) in a4.zip(b4) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
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

impl Layout {
    fn new(m: &MultiModel, members: &[usize]) -> Self {
        let nm = m.masses.len();
        let mut parent: Vec<usize> = (0..nm).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        let mut in_contact = vec![false; nm];
        let mut held = vec![false; nm];
        for &c in members {
            let ct = &m.contacts[c];
            match (&ct.lower, &ct.upper) {
                (MultiEnd::Mass(a), MultiEnd::Mass(b)) => {
                    in_contact[*a] = true;
                    in_contact[*b] = true;
                    let (ra, rb) = (root(&mut parent, *a), root(&mut parent, *b));
                    parent[ra] = rb;
                }
                (MultiEnd::Mass(a), _) | (_, MultiEnd::Mass(a)) => {
                    in_contact[*a] = true;
                    held[*a] = true;
                }
                _ => {}
            }
        }
        let mut root_held = vec![false; nm];
        for j in 0..nm {
            if held[j] {
                let r = root(&mut parent, j);
                root_held[r] = true;
            }
        }
        let mut bound = vec![];
        let mut place = vec![None; nm];
        let mut group_of_root: Vec<Option<usize>> = vec![None; nm];
        let mut groups: Vec<Vec<usize>> = vec![];
        let mut fly_of = vec![None; nm];
        for j in 0..nm {
            if !in_contact[j] {
                fly_of[j] = Some(j);
                continue;
            }
            place[j] = Some(bound.len());
            bound.push(j);
            let r = root(&mut parent, j);
            if !root_held[r] {
                let g = *group_of_root[r].get_or_insert_with(|| {
                    groups.push(vec![]);
                    groups.len() - 1
                });
                groups[g].push(j);
                fly_of[j] = Some(groups[g][0]);
            }
        }
        Self {
            bound,
            place,
            groups,
            fly_of,
        }
    }
}

impl MultiPhase {
    fn new(m: &MultiModel, mask: u32, h: f64) -> Result<Self, MultiError> {
        let n = m.n();
        let g = m.gravity_m_per_s2;
        let members: Vec<usize> = (0..m.contacts.len())
            .filter(|j| mask & (1 << j) != 0)
            .collect();
        let bad = |why: String| MultiError::Phase { mask, why };
        let lay = Layout::new(m, &members);
        let nz = n + lay.bound.len();
        let sqm = |j: usize| m.masses[j].mass_kg.sqrt();
        // each closed contact's row over z and constant: p = g . z + p0
        let row_z = |e: &MultiEnd| -> (Vec<f64>, f64) {
            let mut r = vec![0.0; nz];
            match e {
                MultiEnd::Point(w) => {
                    r[..n].copy_from_slice(w);
                    (r, 0.0)
                }
                MultiEnd::Mass(j) => {
                    if let Some(b) = lay.place[*j] {
                        r[n + b] = 1.0 / sqm(*j);
                    }
                    (r, 0.0)
                }
                MultiEnd::Wall(hw) => (r, *hw),
            }
        };
        let contact_z = |c: usize| {
            let ct = &m.contacts[c];
            let (rl, cl) = row_z(&ct.lower);
            let (ru, cu) = row_z(&ct.upper);
            let r: Vec<f64> = rl.iter().zip(&ru).map(|(a, b)| a - b).collect();
            (r, cl - cu - ct.gap_m)
        };
        let rows: Vec<(Vec<f64>, f64)> = members.iter().map(|&c| contact_z(c)).collect();
        let p0: Vec<f64> = rows.iter().map(|r| r.1).collect();
        // the modes no closed contact touches keep their free 2x2 blocks
        // (exactly, and degenerate modes need no eigenvectors); the others
        // and the held masses are the coupled part, `zc`
        let (cm, fm): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| rows.iter().any(|r| r.0[i] != 0.0));
        let zc_of: Vec<usize> = cm
            .iter()
            .copied()
            .chain((0..lay.bound.len()).map(|b| n + b))
            .collect();
        let nzc = zc_of.len();
        // P_c: the identity but on each free group, where it is an
        // orthonormal basis of the complement of the group's centre
        // direction e (sqrt(m_j) / sqrt(M)): the columns of the Householder
        // reflection that takes e to the group's first axis, but the first
        let nrc = nzc - lay.groups.len();
        let mut pc = DMatrix::zeros(nzc, nrc);
        let mut col = 0;
        let at_zc = |zi: usize| zc_of.iter().position(|&x| x == zi).expect("coupled");
        let mut in_group = vec![false; nzc];
        for grp in &lay.groups {
            for &j in grp {
                in_group[at_zc(n + lay.place[j].expect("grouped masses are bound"))] = true;
            }
        }
        for r in 0..nzc {
            if !in_group[r] {
                pc[(r, col)] = 1.0;
                col += 1;
            }
        }
        for grp in &lay.groups {
            let total: f64 = grp.iter().map(|&j| m.masses[j].mass_kg).sum();
            let idx: Vec<usize> = grp
                .iter()
                .map(|&j| at_zc(n + lay.place[j].expect("bound")))
                .collect();
            let e: Vec<f64> = grp
                .iter()
                .map(|&j| (m.masses[j].mass_kg / total).sqrt())
                .collect();
            // v = e + e_0 (e_0 > 0, no cancellation); H = I - 2 v v^T / |v|^2
            let mut v = e.clone();
            v[0] += 1.0;
            let vv = dot(&v, &v);
            for c in 1..grp.len() {
                for (a, &ra) in idx.iter().enumerate() {
                    let delta = if a == c { 1.0 } else { 0.0 };
                    pc[(ra, col)] = delta - 2.0 * v[a] * v[c] / vv;
                }
                col += 1;
            }
        }
        // F_c P_c with F_c = [diag(omega); sqrt(k_c) g_c^T] on zc, its QR;
        // the damping and the constant forces on zc
        let ncm = cm.len();
        let mut fc = DMatrix::zeros(ncm + members.len(), nzc);
        let mut damping = DMatrix::zeros(nzc, nzc);
        for (a, &i) in cm.iter().enumerate() {
            fc[(a, a)] = two_pi() * m.freq_hz[i];
            damping[(a, a)] = 2.0 * m.sigma[i];
        }
        let mut force = vec![0.0; nzc];
        // per closed contact: the force per metre of a rod in it (on zc)
        let mut rod_force = vec![vec![0.0; nzc]; members.len()];
        for (pos, &c) in members.iter().enumerate() {
            let ct = &m.contacts[c];
            let gz: Vec<f64> = zc_of.iter().map(|&zi| rows[pos].0[zi]).collect();
            let sk = ct.stiffness_n_per_m.sqrt();
            for (colz, x) in gz.iter().enumerate() {
                fc[(ncm + pos, colz)] = sk * x;
            }
            for a in 0..nzc {
                force[a] -= ct.stiffness_n_per_m * p0[pos] * gz[a];
                rod_force[pos][a] = ct.stiffness_n_per_m * gz[a];
                for b in 0..nzc {
                    damping[(a, b)] += ct.damping_n_s_per_m * gz[a] * gz[b];
                }
            }
        }
        for (b, &j) in lay.bound.iter().enumerate() {
            force[ncm + b] -= g * sqm(j);
        }
        let (qc, rc) = if nrc == 0 {
            (DMatrix::zeros(fc.nrows(), 0), DMatrix::zeros(0, 0))
        } else {
            let qr = (&fc * &pc).qr();
            let (q, r) = (qr.q(), qr.r());
            let rmax = (0..nrc).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
            if (0..nrc).any(|i| !(r[(i, i)].abs() > rmax * 1e-15)) {
                return Err(bad("its stiffness is singular".into()));
            }
            (q, r)
        };
        let rinv = rc
            .clone()
            .solve_upper_triangular(&DMatrix::identity(nrc, nrc))
            .ok_or_else(|| bad("its stiffness is singular".into()))?;
        let zc = &pc * &rinv;
        let dt = pc.transpose() * &damping * &pc;
        let dimc = 2 * nrc;
        let mut a = DMatrix::zeros(dimc, dimc);
        for i in 0..nrc {
            for j in 0..nrc {
                a[(i, nrc + j)] = rc[(i, j)];
                a[(nrc + j, i)] = -rc[(i, j)];
                a[(nrc + i, nrc + j)] = -dt[(i, j)];
            }
        }
        let mut fy = vec![0.0; dimc];
        for i in 0..nrc {
            fy[nrc + i] = (0..nzc).map(|a| pc[(a, i)] * force[a]).sum();
        }
        let (gens_c, vc, vinvc, kappa) = if dimc == 0 {
            (vec![], DMatrix::zeros(0, 0), DMatrix::zeros(0, 0), 1.0)
        } else {
            let d = decompose_via(&a, h, None, true).map_err(|e| bad(e.to_string()))?;
            let Form::Blocks { gens } = d.form else {
                return Err(bad(format!(
                    "no block form ({})",
                    d.diag.fallback_reason.unwrap_or_default()
                )));
            };
            (gens, d.v, d.vinv, d.diag.kappa)
        };
        // the equilibrium `A y* + f = 0`, and per closed contact its move
        // per metre of a rod
        let lu = (dimc > 0).then(|| a.clone().lu());
        let solve = |f: &[f64], why: &str| -> Result<Vec<f64>, MultiError> {
            if f.iter().all(|x| *x == 0.0) {
                return Ok(vec![0.0; dimc]);
            }
            let rhs = nalgebra::DVector::from_iterator(dimc, f.iter().map(|x| -x));
            let y = lu
                .as_ref()
                .and_then(|lu| lu.solve(&rhs))
                .ok_or_else(|| bad(why.into()))?;
            Ok(y.iter().copied().collect())
        };
        let yc_star = solve(&fy, "no equilibrium under gravity")?;
        let mut rod_yc = Vec::with_capacity(members.len());
        for rf in &rod_force {
            let mut f = vec![0.0; dimc];
            for i in 0..nrc {
                f[nrc + i] = (0..nzc).map(|a| pc[(a, i)] * rf[a]).sum();
            }
            rod_yc.push(solve(&f, "no equilibrium with an offset rod")?);
        }
        // the whole phase: y = [u_c, u_free; w_c, w_free], the free modes'
        // u = omega q and w = q'; s = [first components of the coupled
        // blocks, of the free blocks; second components of each]
        let nr = nrc + fm.len();
        let dim = 2 * nr;
        let nbc = gens_c.len();
        let nb = nbc + fm.len();
        let ymap = |r: usize| if r < nrc { r } else { nr + r - nrc };
        let smap = |c: usize| if c < nbc { c } else { nb + c - nbc };
        let mut gens = gens_c;
        let (mut v, mut vinv) = (DMatrix::zeros(dim, dim), DMatrix::zeros(dim, dim));
        for r in 0..dimc {
            for c in 0..dimc {
                v[(ymap(r), smap(c))] = vc[(r, c)];
                vinv[(smap(r), ymap(c))] = vinvc[(r, c)];
            }
        }
        let mut y_star = vec![0.0; dim];
        for (r, y) in yc_star.iter().enumerate() {
            y_star[ymap(r)] = *y;
        }
        // V^-1 on the coupled part only (a constant force leaves the free
        // modes alone)
        let rod_s: Vec<Vec<f64>> = rod_yc
            .iter()
            .map(|yc| {
                let mut rs = vec![0.0; dim];
                for r in 0..dimc {
                    rs[smap(r)] = (0..dimc).map(|c| vinvc[(r, c)] * yc[c]).sum();
                }
                rs
            })
            .collect();
        let mut p = DMatrix::zeros(nz, nr);
        let mut z_of_u = DMatrix::zeros(nz, nr);
        let mut q = DMatrix::zeros(n + members.len(), nr);
        for (r, &zi) in zc_of.iter().enumerate() {
            for c in 0..nrc {
                p[(zi, c)] = pc[(r, c)];
                z_of_u[(zi, c)] = zc[(r, c)];
            }
        }
        for r in 0..qc.nrows() {
            let row = if r < ncm { cm[r] } else { n + r - ncm };
            for c in 0..nrc {
                q[(row, c)] = qc[(r, c)];
            }
        }
        for (j, &i) in fm.iter().enumerate() {
            let w = two_pi() * m.freq_hz[i];
            gens.push([0.0, w, -w, -2.0 * m.sigma[i]]);
            v[(nrc + j, nbc + j)] = 1.0;
            v[(nr + nrc + j, nb + nbc + j)] = 1.0;
            vinv[(nbc + j, nrc + j)] = 1.0;
            vinv[(nb + nbc + j, nr + nrc + j)] = 1.0;
            p[(i, nrc + j)] = 1.0;
            z_of_u[(i, nrc + j)] = 1.0 / w;
            q[(i, nrc + j)] = 1.0;
        }
        let growth: Vec<f64> = gens.iter().map(|g| (sym_growth(g) * h).exp()).collect();
        let growth_max = growth.iter().copied().fold(1.0, f64::max);
        let nb = gens.len();
        // a side's position: a row over y, a constant and a flight; a
        // point's modes through Q's rows (`q_i = (Q u)_i / omega_i`, an
        // orthonormal basis), a held mass through `Z`
        let side_y = |e: &MultiEnd| -> (Vec<f64>, f64, Option<usize>) {
            let mut pos = vec![0.0; dim];
            match e {
                MultiEnd::Point(w) => {
                    for (c, x) in pos.iter_mut().enumerate().take(nr) {
                        *x = (0..n)
                            .map(|i| w[i] * q[(i, c)] / (two_pi() * m.freq_hz[i]))
                            .sum();
                    }
                    (pos, 0.0, None)
                }
                MultiEnd::Mass(j) => match lay.place[*j] {
                    Some(b) => {
                        for (c, x) in pos.iter_mut().enumerate().take(nr) {
                            *x = z_of_u[(n + b, c)] / sqm(*j);
                        }
                        (pos, 0.0, lay.fly_of[*j])
                    }
                    None => (pos, 0.0, Some(*j)),
                },
                MultiEnd::Wall(hw) => (pos, *hw, None),
            }
        };
        let (mut ev, mut ev0, mut ev_d, mut ev_c2, mut ev_e, mut ev_fly) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        for (j, ct) in m.contacts.iter().enumerate() {
            let (row_y, c0, fly) = match members.iter().position(|&c| c == j) {
                // closed: its penetration is a coordinate of Q u, exactly
                // (`sqrt(k) (p - p0)`), not a difference of two sides
                Some(pos) => {
                    let mut row = vec![0.0; dim];
                    let sk = ct.stiffness_n_per_m.sqrt();
                    for (c, x) in row.iter_mut().enumerate().take(nr) {
                        *x = q[(n + pos, c)] / sk;
                    }
                    (row, p0[pos], (None, None))
                }
                None => {
                    let (lo, lo0, lo_fly) = side_y(&ct.lower);
                    let (up, up0, up_fly) = side_y(&ct.upper);
                    let row: Vec<f64> = lo.iter().zip(&up).map(|(a, b)| a - b).collect();
                    let fly = if lo_fly == up_fly {
                        (None, None)
                    } else {
                        (lo_fly, up_fly)
                    };
                    (row, lo0 - up0 - ct.gap_m, fly)
                }
            };
            let (r, r0) = in_phase(&row_y, &v, &y_star);
            let r0 = r0 + c0;
            let rd = row_times_gens(&r, &gens);
            let rdd = row_times_gens(&rd, &gens);
            ev_c2.push((0..nb).map(|k| rdd[k].hypot(rdd[nb + k])).collect());
            ev_e.push((0..nb).map(|k| r[k].hypot(r[nb + k])).collect());
            ev.push(r);
            ev0.push(r0);
            ev_d.push(rd);
            ev_fly.push(fly);
        }
        // each side's position and velocity straight from s (the trace)
        let side_v = |e: &MultiEnd| -> (Vec<f64>, Option<usize>) {
            let mut vel = vec![0.0; dim];
            match e {
                MultiEnd::Point(w) => {
                    for c in 0..nr {
                        vel[nr + c] = (0..n).map(|i| w[i] * p[(i, c)]).sum();
                    }
                    (vel, None)
                }
                MultiEnd::Mass(j) => match lay.place[*j] {
                    Some(b) => {
                        for c in 0..nr {
                            vel[nr + c] = p[(n + b, c)] / sqm(*j);
                        }
                        (vel, lay.fly_of[*j])
                    }
                    None => (vel, Some(*j)),
                },
                MultiEnd::Wall(_) => (vel, None),
            }
        };
        let sides: Vec<[SideRows; 2]> = m
            .contacts
            .iter()
            .map(|ct| {
                [&ct.lower, &ct.upper].map(|e| {
                    let (pos_y, c0, fly) = side_y(e);
                    let (vel_y, _) = side_v(e);
                    let (pos, pos0) = in_phase(&pos_y, &v, &y_star);
                    let (vel, vel0) = in_phase(&vel_y, &v, &y_star);
                    SideRows {
                        pos,
                        pos0: pos0 + c0,
                        vel,
                        vel0,
                        fly,
                    }
                })
            })
            .collect();
        // the entries of s the coupled part moves (the free modes' blocks
        // are their own (omega q, q'))
        let coupled: Vec<usize> = (0..dimc).map(smap).collect();
        let (mut out_d, mut out_v): ([Vec<f64>; 2], [Vec<f64>; 2]) = Default::default();
        let (mut out_d0, mut out_v0) = ([0.0; 2], [0.0; 2]);
        for c in 0..2 {
            let (disp, velo) = &m.pickups[c];
            let (mut row_d, mut row_v) = (vec![0.0; dim], vec![0.0; dim]);
            for col in 0..nr {
                row_d[col] = (0..n)
                    .map(|i| disp[i] * q[(i, col)] / (two_pi() * m.freq_hz[i]))
                    .sum();
                row_v[nr + col] = (0..n).map(|i| velo[i] * p[(i, col)]).sum();
            }
            (out_d[c], out_d0[c]) = in_phase(&row_d, &v, &y_star);
            (out_v[c], out_v0[c]) = in_phase(&row_v, &v, &y_star);
        }
        let mut flyers: Vec<usize> = (0..m.masses.len())
            .filter(|&j| lay.place[j].is_none())
            .collect();
        flyers.extend(lay.groups.iter().map(|grp| grp[0]));
        let (v_u, v_w) = (v.rows(0, nr), v.rows(nr, nr));
        let (u_star, w_star) = (
            DMatrix::from_column_slice(nr, 1, &y_star[..nr]),
            DMatrix::from_column_slice(nr, 1, &y_star[nr..]),
        );
        let z_m = z_of_u.rows(n, lay.bound.len());
        let col = |x: DMatrix<f64>| x.as_slice().to_vec();
        let s_star = col(&vinv * DMatrix::from_column_slice(dim, 1, &y_star));
        let (qv, pv, zv) = (&q * v_u, &p * v_w, z_m * v_u);
        let vq = vinv.columns(0, nr) * q.transpose();
        let vp = vinv.columns(nr, nr) * p.transpose();
        let qv_rows: Vec<usize> = cm.iter().copied().chain(n..n + members.len()).collect();
        let pv_rows: Vec<usize> = cm.iter().copied().chain(n..n + lay.bound.len()).collect();
        let nbnd = lay.bound.len();
        let qv_c = DMatrix::from_fn(qv_rows.len(), coupled.len(), |r, c| {
            qv[(qv_rows[r], coupled[c])]
        });
        let pv_c = DMatrix::from_fn(pv_rows.len(), coupled.len(), |r, c| {
            pv[(pv_rows[r], coupled[c])]
        });
        let zv_c = DMatrix::from_fn(nbnd, coupled.len(), |r, c| zv[(r, coupled[c])]);
        let vq_c = DMatrix::from_fn(coupled.len(), qv_rows.len(), |r, c| {
            vq[(coupled[r], qv_rows[c])]
        });
        let vp_c = DMatrix::from_fn(coupled.len(), pv_rows.len(), |r, c| {
            vp[(coupled[r], pv_rows[c])]
        });
        let free_blocks: Vec<(usize, usize, usize)> = fm
            .iter()
            .enumerate()
            .map(|(j, &i)| (i, nbc + j, nb + nbc + j))
            .collect();
        let forms = gens.iter().map(OscForm::of).collect();
        let ev_blocks = ev
            .iter()
            .zip(&ev_d)
            .map(|(r, d): (&Vec<f64>, &Vec<f64>)| {
                (0..nb)
                    .filter(|&k| r[k] != 0.0 || r[nb + k] != 0.0 || d[k] != 0.0 || d[nb + k] != 0.0)
                    .collect()
            })
            .collect();
        let nz_of = |rows: &[Vec<f64>]| -> Vec<Vec<usize>> {
            rows.iter()
                .map(|r| (0..r.len()).filter(|&i| r[i] != 0.0).collect())
                .collect()
        };
        let (ev_nz, evd_nz) = (nz_of(&ev), nz_of(&ev_d));
        Ok(Self {
            members,
            dim,
            forms,
            ev_blocks,
            ev_nz,
            evd_nz,
            gens,
            qv0: col(&q * &u_star),
            pv0: col(&p * &w_star),
            zv0: col(z_m * &u_star),
            qv,
            pv,
            zv,
            qv_c,
            qv_rows,
            pv_c,
            pv_rows,
            zv_c,
            bound_rows: (0..nbnd).collect(),
            vq_c,
            vp_c,
            free_blocks,
            s_star,
            bound: lay.bound,
            place: lay.place,
            groups: lay.groups,
            fly_of: lay.fly_of,
            flyers,
            p0,
            rod_s,
            ev,
            ev0,
            ev_d,
            ev_c2,
            ev_e,
            ev_fly,
            sides,
            coupled,
            coupled_modes: cm,
            out_d,
            out_d0,
            out_v,
            out_v0,
            kappa,
            growth: growth_max,
        })
    }
}

impl MultiPhase {
    /// Block `k`'s `exp(G_k t)` (what [`exp2`] gives, its split made once).
    #[inline]
    fn exp_block(&self, k: usize, t: f64) -> Mat2 {
        match &self.forms[k] {
            Some(f) => f.exp(t),
            None => exp2(&self.gens[k], t),
        }
    }
}

impl CompiledMulti {
    /// Compile every phase (`2^K` of them) at `rate_hz`.
    pub fn new(model: &MultiModel, rate_hz: f64) -> Result<Self, MultiError> {
        model.validate()?;
        check_value("rate_hz", rate_hz, rate_hz > 0.0)?;
        model.within_budget()?;
        let k = model.contacts.len();
        let h = 1.0 / rate_hz;
        let phases = (0..1u32 << k)
            .map(|mask| MultiPhase::new(model, mask, h))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            model: model.clone(),
            h,
            rate_hz,
            phases,
            switching: Switching::Exact,
        })
    }

    /// [`new`](Self::new) with the given switching method (the scene's
    /// `contact.switching`).
    pub fn with_switching(
        model: &MultiModel,
        rate_hz: f64,
        switching: Switching,
    ) -> Result<Self, MultiError> {
        let mut sc = Self::new(model, rate_hz)?;
        sc.switching = switching;
        Ok(sc)
    }

    /// Number of contacts.
    pub fn contacts(&self) -> usize {
        self.model.contacts.len()
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

/// What a state steps a phase with at its time scale (made for each phase
/// up front, brought to the state's scale when the phase is entered).
#[derive(Debug, Clone)]
struct PhaseTables {
    /// Each block's propagator over one step.
    props: Vec<Mat2>,
    /// Each block's growth over one step, `e^(gamma_k h_s)`, and the
    /// largest (at least 1).
    growth: Vec<f64>,
    growth_max: f64,
    /// Per contact, per block: the phase's curvature weights and
    /// magnitudes times the block's growth (the search's bounds).
    ev_c2: Vec<Vec<f64>>,
    ev_e: Vec<Vec<f64>>,
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

impl PhaseTables {
    fn new(ph: &MultiPhase) -> Self {
        Self {
            props: vec![[0.0; 4]; ph.gens.len()],
            growth: vec![1.0; ph.gens.len()],
            growth_max: 1.0,
            ev_c2: ph.ev_c2.clone(),
            ev_e: ph.ev_e.clone(),
            out: [vec![0.0; ph.dim], vec![0.0; ph.dim]],
            out0: [0.0; 2],
            at: f64::NAN,
            limit: f64::INFINITY,
            muted: 0,
        }
    }

    /// Bring them to `scale` (step `h` of the model's time) and the output
    /// band `band_hz` (physical; infinite: every mode heard). O(dim), plus
    /// O(dim) per mode left out, allocation-free.
    fn make(&mut self, ph: &MultiPhase, m: &MultiModel, scale: f64, h: f64, band_hz: f64) {
        let limit = two_pi() * band_hz / scale;
        if self.at == scale && self.limit == limit {
            return;
        }
        self.growth_max = 1.0;
        for (k, g) in ph.gens.iter().enumerate() {
            self.props[k] = exp2(g, h);
            self.growth[k] = (sym_growth(g) * h).exp();
            self.growth_max = self.growth_max.max(self.growth[k]);
        }
        for (j, (c2, e)) in self.ev_c2.iter_mut().zip(&mut self.ev_e).enumerate() {
            for k in 0..ph.gens.len() {
                c2[k] = ph.ev_c2[j][k] * self.growth[k];
                e[k] = ph.ev_e[j][k] * self.growth[k];
            }
        }
        for c in 0..2 {
            for (o, (d, v)) in self.out[c]
                .iter_mut()
                .zip(ph.out_d[c].iter().zip(&ph.out_v[c]))
            {
                *o = d + scale * v;
            }
            self.out0[c] = ph.out_d0[c] + scale * ph.out_v0[c];
        }
        // a mode above the band leaves the outputs: its share of each row
        // (`q_i = (Q u)_i / omega_i`, `q'_i = (P w)_i`, the rows a switch
        // takes the physical state through) is taken out, in every phase
        // alike, so the output stays a continuous function of the
        // physical state across switches; its dynamics stay
        self.muted = 0;
        for i in 0..m.n() {
            let w = two_pi() * m.freq_hz[i];
            if !(w > limit) {
                continue;
            }
            self.muted += 1;
            for c in 0..2 {
                let (a, b) = (m.pickups[c].0[i] / w, scale * m.pickups[c].1[i]);
                if a == 0.0 && b == 0.0 {
                    continue;
                }
                for (col, o) in self.out[c].iter_mut().enumerate() {
                    *o -= a * ph.qv[(i, col)] + b * ph.pv[(i, col)];
                }
                self.out0[c] -= a * ph.qv0[i] + b * ph.pv0[i];
            }
        }
        self.at = scale;
        self.limit = limit;
    }
}

/// The running state of a [`CompiledMulti`]. A clone keeps the room its
/// vectors have (a `Vec`'s own clone keeps only its length): the clone of
/// a state made for a compile steps it without allocating, as the state
/// does.
#[derive(Debug)]
pub struct MultiState {
    mask: u32,
    /// Time scale: each sample advances the model's time by `scale h`
    /// (docs/numerics.md section 14, "Time scale").
    scale: f64,
    /// `scale h` \[s of the model's time\].
    step_h: f64,
    /// Per phase.
    tables: Vec<PhaseTables>,
    s: Vec<f64>,
    end: Vec<f64>,
    /// Per block of the current phase, `|s_k|` at points of the search:
    /// slot 0 the step's start, the others the left ends of its pieces
    /// (a stack, one slot per level).
    norms: Vec<Vec<f64>>,
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
    /// Per contact: a whole-sample margin (`w = h`) and the epoch of the
    /// clock (64 samples) it was taken in, in the current phase (times the
    /// phase's growth over 64 samples, it holds for every later state of
    /// the epoch).
    cached: [(u64, f64); MAX_CONTACTS],
    /// Halvings left to the current search.
    budget: u32,
    /// Offset rod: each contact's rod \[m\] (0 when open, and always with
    /// exact switching), the block state's equilibrium shift they make in
    /// the current phase (`shift = sum_c d_c rod_s_c`: with rods, `s` is
    /// held about the shifted equilibrium, so a sample steps it as it
    /// is, and a row's constant takes `row . shift`), whether any is not
    /// 0, those constants (per contact its penetration's, its sides'
    /// positions' and velocities', and the outputs' displacement and
    /// velocity parts), and the clock of the last decision (one per
    /// sample instant).
    rod: [f64; MAX_CONTACTS],
    shift: Vec<f64>,
    rods_on: bool,
    off_ev: [f64; MAX_CONTACTS],
    off_sides: [[(f64, f64); 2]; MAX_CONTACTS],
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
            scale: self.scale,
            step_h: self.step_h,
            tables: self.tables.clone(),
            s: with_room(&self.s, self.s.capacity()),
            end: self.end.clone(),
            norms: self
                .norms
                .iter()
                .map(|n| with_room(n, n.capacity()))
                .collect(),
            x_f: self.x_f.clone(),
            v_f: self.v_f.clone(),
            zq: self.zq.clone(),
            zv: self.zv.clone(),
            phys: self.phys.clone(),
            cached: self.cached,
            budget: self.budget,
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
    /// `psi` at `t` from the row's part `q` of the penetration.
    fn psi(&self, q: f64, t: f64) -> f64 {
        self.sign * (q + self.x0 + self.v0 * t - 0.5 * self.g * t * t)
    }

    /// `psi'` at `t` from the row's slope `dq`.
    fn dpsi(&self, dq: f64, t: f64) -> f64 {
        self.sign * (dq + self.v0 - self.g * t)
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
    /// The model's initial state: the objects at rest, the masses in
    /// flight where the model puts them.
    pub fn new(sc: &CompiledMulti) -> Self {
        let dim = sc.max_dim();
        let nz = sc.model.n() + sc.model.masses.len();
        let x_f = sc.model.masses.iter().map(|m| m.height_m).collect();
        let v_f = sc.model.masses.iter().map(|m| m.velocity_m_per_s).collect();
        // every phase's tables at scale 1 up front: a state that keeps its
        // scale never makes them on the way (a switch pays nothing more)
        let mut tables: Vec<PhaseTables> = sc.phases.iter().map(PhaseTables::new).collect();
        for (t, ph) in tables.iter_mut().zip(&sc.phases) {
            t.make(ph, &sc.model, 1.0, sc.h, f64::INFINITY);
        }
        Self {
            mask: 0,
            scale: 1.0,
            step_h: sc.h,
            tables,
            s: {
                let mut s = Vec::with_capacity(dim);
                s.resize(sc.phases[0].dim, 0.0);
                s
            },
            end: vec![0.0; dim],
            norms: vec![vec![0.0; dim / 2]; NORM_SLOTS],
            x_f,
            v_f,
            zq: vec![0.0; nz + MAX_CONTACTS],
            zv: vec![0.0; nz],
            phys: Physical::new(&sc.model),
            cached: [(u64::MAX, 0.0); MAX_CONTACTS],
            budget: SEARCH_BUDGET,
            rod: [0.0; MAX_CONTACTS],
            shift: vec![0.0; dim],
            rods_on: false,
            off_ev: [0.0; MAX_CONTACTS],
            off_sides: [[(0.0, 0.0); 2]; MAX_CONTACTS],
            off_out: [0.0; 2],
            band_hz: f64::INFINITY,
            decided: u64::MAX,
            clock: 0,
            stats: MultiStats::default(),
            switches: Vec::new(),
            record: false,
        }
    }

    /// Back to rest, as an instrument's kit wakes (docs/design.md, "Played
    /// as a kit"): every object still, every mass at its model height
    /// and still, no contact closed. The clock runs on. Allocation-free.
    /// \[audio-thread\]
    pub fn rest(&mut self, sc: &CompiledMulti) {
        self.mask = 0;
        self.tables[0].make(
            &sc.phases[0],
            &sc.model,
            self.scale,
            self.step_h,
            self.band_hz,
        );
        self.s.clear();
        self.s.resize(sc.phases[0].dim, 0.0);
        for (j, m) in sc.model.masses.iter().enumerate() {
            self.x_f[j] = m.height_m;
            self.v_f[j] = 0.0;
        }
        self.cached = [(u64::MAX, 0.0); MAX_CONTACTS];
        self.rod = [0.0; MAX_CONTACTS];
        self.set_shift(sc);
        self.decided = u64::MAX;
    }

    /// Carry the state from `from` to `to`, another compile of the same
    /// bodies (the same modes' frequencies, masses and contacts; other
    /// stiffnesses, dampings or decays: a parameter change): only while no
    /// contact is closed, through the physical state, which does not
    /// change, so neither does the energy (the objects', the masses' and
    /// gravity's; no spring is stretched). False (nothing changed) when a
    /// contact is closed or the bodies differ. The state must have been
    /// made for a compile with phases as large as `to`'s
    /// ([`MultiState::new`] of either, when both have the same layout).
    /// O(dim^2), allocation-free. \[audio-thread\]
    pub fn carry(&mut self, from: &CompiledMulti, to: &CompiledMulti) -> bool {
        let (a, b) = (&from.model, &to.model);
        let same = a.freq_hz == b.freq_hz
            && a.masses.len() == b.masses.len()
            && a.contacts.len() == b.contacts.len()
            && self.s.capacity() >= to.max_dim()
            && self.tables.len() == to.phases.len()
            && self
                .tables
                .iter()
                .zip(&to.phases)
                .all(|(t, p)| t.props.len() == p.gens.len() && t.out[0].len() == p.dim)
            && self.mask == 0;
        if !same {
            return false;
        }
        from.phases[0].physical_of(
            a,
            &self.s,
            (&self.x_f, &self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.phys,
        );
        let new = &to.phases[0];
        self.s.resize(new.dim, 0.0);
        new.state_of(
            b,
            (&self.phys, &[0.0; MAX_CONTACTS]),
            (&mut self.x_f, &mut self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.s,
        );
        // the tables were the old compile's
        for t in &mut self.tables {
            t.at = f64::NAN;
        }
        self.tables[0].make(new, b, self.scale, self.step_h, self.band_hz);
        self.cached = [(u64::MAX, 0.0); MAX_CONTACTS];
        true
    }

    /// A strike between two samples: the mass on the upper side of
    /// contact `c` is thrown from `height_m` above that contact's lower
    /// side (where it is now), or from as high as the sides above it let
    /// it be, at `velocity_m_per_s` (positive up). Its closed contacts
    /// open first, through the physical state as a switch does (their
    /// springs' energy leaves, nothing is added); its other contacts stay
    /// open where it is put (above every side it rests on, below every
    /// side above it); where no such place exists the strike is refused
    /// and nothing changes: `Err(StrikeRefused::Wedged)` (a ball pressed
    /// between two plates). O(dim) to place, O(dim^2) when a contact
    /// opens. Allocation-free. \[audio-thread\]
    pub fn strike(
        &mut self,
        sc: &CompiledMulti,
        c: usize,
        height_m: f64,
        velocity_m_per_s: f64,
    ) -> Result<(), StrikeRefused> {
        let m = &sc.model;
        let Some(MultiEnd::Mass(k)) = m.contacts.get(c).map(|ct| &ct.upper) else {
            return Err(StrikeRefused::NotAMass);
        };
        let k = *k;
        if !(height_m >= 0.0 && height_m.is_finite() && velocity_m_per_s.is_finite()) {
            return Err(StrikeRefused::NotFinite);
        }
        // the bounds its contacts put on its height, from the other sides
        // where they are now (a switch does not move them)
        let ph = &sc.phases[self.mask as usize];
        let (mut lo, mut hi, mut want) = (f64::NEG_INFINITY, f64::INFINITY, 0.0);
        let mut who = 0u32;
        for (j, ct) in m.contacts.iter().enumerate() {
            if ct.upper == MultiEnd::Mass(k) {
                let (x, _) = self.side_at(ph, j, 0);
                lo = lo.max(x - ct.gap_m);
                if j == c {
                    want = x + height_m;
                }
            } else if ct.lower == MultiEnd::Mass(k) {
                hi = hi.min(self.side_at(ph, j, 1).0 + ct.gap_m);
            } else {
                continue;
            }
            who |= 1 << j;
        }
        if !(lo <= hi) {
            return Err(StrikeRefused::Wedged);
        }
        // as high as asked, or as the sides above it let it be
        let x = want.max(lo).min(hi);
        let closed = who & self.mask;
        if closed != 0 {
            let time_s = self.clock as f64 * self.step_h;
            self.switch(sc, closed, time_s, &[0.0; MAX_CONTACTS]);
        }
        // every contact of the mass is open: it flies alone, in its slot
        debug_assert!(sc.phases[self.mask as usize].place[k].is_none());
        self.x_f[k] = x;
        self.v_f[k] = velocity_m_per_s;
        self.cached = [(u64::MAX, 0.0); MAX_CONTACTS];
        Ok(())
    }

    /// The kinetic energy \[J\] of the masses that may still land: each
    /// one in a closed contact, falling under gravity, or closing on a
    /// side of one of its open contacts (its penetration rising). A mass
    /// that flies away from everything in a scene without gravity does
    /// not count: it never comes back (the instrument's silence test).
    /// O(masses dim).
    pub fn masses_to_land(&self, sc: &CompiledMulti) -> f64 {
        let m = &sc.model;
        let ph = &sc.phases[self.mask as usize];
        let mut e = 0.0;
        for (k, ms) in m.masses.iter().enumerate() {
            let v = self.mass_at(sc, k).1;
            let lands = m.gravity_m_per_s2 > 0.0
                || m.contacts.iter().enumerate().any(|(j, ct)| {
                    if self.mask & (1 << j) != 0 {
                        ct.lower == MultiEnd::Mass(k) || ct.upper == MultiEnd::Mass(k)
                    } else if ct.upper == MultiEnd::Mass(k) {
                        self.side_at(ph, j, 0).1 > v
                    } else if ct.lower == MultiEnd::Mass(k) {
                        v > self.side_at(ph, j, 1).1
                    } else {
                        false
                    }
                });
            if lands {
                e += 0.5 * ms.mass_kg * v * v;
            }
        }
        e
    }

    /// Contact `j`'s lower (`which` 0) or upper side's position and
    /// velocity in the current phase `ph` (its rows, the rods' constants
    /// and its flight).
    fn side_at(&self, ph: &MultiPhase, j: usize, which: usize) -> (f64, f64) {
        let r = &ph.sides[j][which];
        let (ox, ov) = self.off_sides[j][which];
        let (fx, fv) = r.fly.map_or((0.0, 0.0), |k| (self.x_f[k], self.v_f[k]));
        (
            dot(&r.pos, &self.s) + r.pos0 + ox + fx,
            dot(&r.vel, &self.s) + r.vel0 + ov + fv,
        )
    }

    /// Entry `c` of the block state about the phase's own equilibrium
    /// (with rods, `s + shift`).
    fn s_own(&self, c: usize) -> f64 {
        if self.rods_on {
            self.s[c] + self.shift[c]
        } else {
            self.s[c]
        }
    }

    /// Mass `j`'s height and velocity: its flight when free, else its
    /// coordinate's rows (plus its group's flight).
    fn mass_at(&self, sc: &CompiledMulti, j: usize) -> (f64, f64) {
        let ph = &sc.phases[self.mask as usize];
        let Some(b) = ph.place[j] else {
            return (self.x_f[j], self.v_f[j]);
        };
        let n = sc.model.n();
        let sq = sc.model.masses[j].mass_kg.sqrt();
        let row = |a: &DMatrix<f64>, r: usize| -> f64 {
            ph.coupled.iter().map(|&c| a[(r, c)] * self.s_own(c)).sum()
        };
        let (mut x, mut v) = (
            (row(&ph.zv, b) + ph.zv0[b]) / sq,
            (row(&ph.pv, n + b) + ph.pv0[n + b]) / sq,
        );
        if let Some(k) = ph.fly_of[j] {
            x += self.x_f[k];
            v += self.v_f[k];
        }
        (x, v)
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
        self.decide(sc);
        let out = self.output(sc);
        self.step(sc);
        out
    }

    /// `left.len().min(right.len())` samples ([`tick`](Self::tick) each),
    /// the engine's block call for a several-contact scene: the same
    /// samples bit for bit however the caller splits its blocks.
    /// \[audio-thread\]
    pub fn process_block(&mut self, sc: &CompiledMulti, left: &mut [f64], right: &mut [f64]) {
        for (l, r) in left.iter_mut().zip(right.iter_mut()) {
            [*l, *r] = self.tick(sc);
        }
    }

    /// The output `[left, right]` of the current state.
    pub fn output(&self, _sc: &CompiledMulti) -> [f64; 2] {
        let tb = &self.tables[self.mask as usize];
        [
            dot4(&tb.out[0], &self.s) + tb.out0[0] + self.off_out[0],
            dot4(&tb.out[1], &self.s) + tb.out0[1] + self.off_out[1],
        ]
    }

    /// Play the model `scale` times faster (a note's pitch: every
    /// frequency and decay rate times `scale`, stiffness times `scale^2`,
    /// damping times `scale`, gravity times `scale^2`, masses kept: each
    /// sample advances the model's time by `scale h`). The state stays in
    /// the model's units, so a mass's physical velocity is `scale` times
    /// its velocity here, and the outputs' velocity pickups take the
    /// factor. O(N) now for the current phase, O(N) for another phase when
    /// it is first entered at this scale; allocation-free. A scale that is
    /// not finite and positive is refused ([`TimeScaleError::Invalid`], as
    /// the one-contact engine's `EngineState::set_time_scale` refuses it)
    /// and nothing changes. \[audio-thread\]
    pub fn set_time_scale(&mut self, sc: &CompiledMulti, scale: f64) -> Result<(), TimeScaleError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(TimeScaleError::Invalid);
        }
        self.scale = scale;
        self.step_h = sc.h * scale;
        self.cached = [(u64::MAX, 0.0); MAX_CONTACTS];
        let m = self.mask as usize;
        self.tables[m].make(&sc.phases[m], &sc.model, scale, self.step_h, self.band_hz);
        self.set_shift(sc);
        Ok(())
    }

    /// Leave the objects' modes whose frequency (at the current time
    /// scale, physical Hz) is above `band_hz` out of the outputs, in every
    /// phase, as the one-contact engine's output band does, so a kit voice
    /// pitched up does not alias its top modes into the audio band. The
    /// dynamics keep every mode. Infinite (the default), not a number or
    /// not positive: every mode heard. Every phase's tables are made at
    /// the band now (a state that keeps its scale makes none on the way),
    /// O(phases dim) plus O(dim) per mode left out; allocation-free.
    /// \[worker\] \[audio-thread\]
    pub fn set_output_band(&mut self, sc: &CompiledMulti, band_hz: f64) {
        self.band_hz = if band_hz > 0.0 {
            band_hz
        } else {
            f64::INFINITY
        };
        for (t, ph) in self.tables.iter_mut().zip(&sc.phases) {
            t.make(ph, &sc.model, self.scale, self.step_h, self.band_hz);
        }
        self.set_shift(sc);
    }

    /// The modes the output band leaves out in the current phase.
    pub fn band_muted_modes(&self) -> usize {
        self.tables[self.mask as usize].muted
    }

    /// Change the time scale to `scale` as a pitch bend does, without
    /// adding or removing energy (the one-contact engine's rule,
    /// `EngineState::bend_time_scale`): with no contact closed every
    /// object is in its free modes and every mass flies, so the modes'
    /// state and the masses' velocities are scaled by `s_old / s` (the
    /// physical energy, `s^2` times the model's, is unchanged: a higher
    /// pitch at the same energy is a smaller displacement; a mass keeps
    /// its physical velocity and its place). `Ok(false)` and nothing done
    /// while a contact is closed (the caller tries again later); refused
    /// with gravity, whose physical value `s^2 g` would change
    /// ([`TimeScaleError::Gravity`]), and for a scale that is not finite
    /// and positive. O(N) plus the phase's tables, allocation-free.
    /// \[audio-thread\]
    pub fn bend_time_scale(
        &mut self,
        sc: &CompiledMulti,
        scale: f64,
    ) -> Result<bool, TimeScaleError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(TimeScaleError::Invalid);
        }
        if sc.model.gravity_m_per_s2 != 0.0 {
            return Err(TimeScaleError::Gravity);
        }
        if self.mask != 0 {
            return Ok(false);
        }
        if scale == self.scale {
            return Ok(true);
        }
        // phase 0: every block is a free mode's (omega q, q'), no
        // equilibrium offset (no closed spring, no gravity)
        let r = self.scale / scale;
        for x in self.s.iter_mut() {
            *x *= r;
        }
        for v in self.v_f.iter_mut() {
            *v *= r;
        }
        self.set_time_scale(sc, scale)?;
        Ok(true)
    }

    /// The time scale ([`set_time_scale`](Self::set_time_scale)).
    pub fn time_scale(&self) -> f64 {
        self.scale
    }

    /// With the offset rod ([`CompiledMulti::switching`]), the switching
    /// decision at this sample instant (once per instant; a no-op with
    /// exact switching): an open contact whose penetration `p` is above 0
    /// closes with a rod of length `p` (its spring starts unstretched), a
    /// closed one whose `p - d` is at or below 0 opens (its spring's `k (p
    /// - d)^2 / 2` leaves). Contacts that switch here switch together,
    /// through the physical state. The trace observes after it
    /// (`crate::render::render_stream_several`). O(K dim), plus a switch. \[audio-thread\]
    pub fn decide(&mut self, sc: &CompiledMulti) {
        if sc.switching != Switching::OffsetRod || self.decided == self.clock {
            return;
        }
        self.decided = self.clock;
        let mut who = 0u32;
        let mut enter = [0.0; MAX_CONTACTS];
        for j in 0..sc.contacts() {
            let p = self.penetration(sc, j);
            if self.mask & (1 << j) != 0 {
                if !(p - self.rod[j] > 0.0) {
                    who |= 1 << j;
                }
            } else if p > 0.0 {
                who |= 1 << j;
                enter[j] = p;
            }
        }
        if who != 0 {
            let time_s = self.clock as f64 * self.step_h;
            self.switch(sc, who, time_s, &enter);
        }
    }

    /// Contact `j`'s penetration now (without its rod) \[m\]: its row,
    /// and the flights of its free sides.
    fn penetration(&self, sc: &CompiledMulti, j: usize) -> f64 {
        let ph = &sc.phases[self.mask as usize];
        let (lo, up) = ph.ev_fly[j];
        let at = |slot: Option<usize>| slot.map_or(0.0, |k| self.x_f[k]);
        dot(&ph.ev[j], &self.s) + ph.ev0[j] + self.off_ev[j] + at(lo) - at(up)
    }

    /// Contact `j`'s offset rod \[m\] (0 when open, and with exact
    /// switching).
    pub fn rod(&self, j: usize) -> f64 {
        self.rod[j]
    }

    /// Advance one sample: with exact switching, switching wherever a
    /// contact crosses; with the offset rod, in the phase its decision at
    /// the sample's start chose ([`decide`](Self::decide)).
    pub fn step(&mut self, sc: &CompiledMulti) {
        if sc.switching == Switching::OffsetRod {
            self.decide(sc);
            self.step_rod(sc);
            return;
        }
        let h = self.step_h;
        let mut t = 0.0;
        let mut starts = [Start::Value; MAX_CONTACTS];
        let mut taken: u64 = 0;
        while t < h {
            let ph = &sc.phases[self.mask as usize];
            let rem = h - t;
            let nb = ph.gens.len();
            if t == 0.0 {
                let props = &self.tables[self.mask as usize].props;
                step_blocks(props, &self.s, &mut self.end[..ph.dim], nb);
            } else {
                step_to(ph, rem, &self.s, &mut self.end[..ph.dim]);
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
                step_to(ph, tau, &self.s, &mut self.end[..ph.dim]);
            }
            self.s.copy_from_slice(&self.end[..ph.dim]);
            self.fly(sc, tau);
            t = if tau < rem { t + tau } else { h };
            starts = self.switch(sc, who, self.clock as f64 * h + t, &[0.0; MAX_CONTACTS]);
            taken += 1;
        }
        self.clock += 1;
    }

    /// One whole sample in the current phase with its rods (the state is
    /// held about the equilibrium they shift). O(dim).
    fn step_rod(&mut self, sc: &CompiledMulti) {
        let m = self.mask as usize;
        let ph = &sc.phases[m];
        let dim = ph.dim;
        let props = &self.tables[m].props;
        step_blocks(props, &self.s, &mut self.end[..dim], ph.gens.len());
        self.s.copy_from_slice(&self.end[..dim]);
        self.fly(sc, self.step_h);
        self.clock += 1;
    }

    /// The current phase's equilibrium shift of the rods, and the rows'
    /// constants it makes. O(K dim).
    fn set_shift(&mut self, sc: &CompiledMulti) {
        let ph = &sc.phases[self.mask as usize];
        let shift = &mut self.shift[..ph.dim];
        shift.fill(0.0);
        self.rods_on = false;
        for (pos, &c) in ph.members.iter().enumerate() {
            let d = self.rod[c];
            if d != 0.0 {
                self.rods_on = true;
                for (x, r) in shift.iter_mut().zip(&ph.rod_s[pos]) {
                    *x += d * r;
                }
            }
        }
        if !self.rods_on {
            // exact switching, or no rod: nothing to add (and no products)
            self.off_ev = [0.0; MAX_CONTACTS];
            self.off_sides = [[(0.0, 0.0); 2]; MAX_CONTACTS];
            self.off_out = [0.0; 2];
            return;
        }
        let shift = &self.shift[..ph.dim];
        for j in 0..sc.contacts() {
            self.off_ev[j] = dot(&ph.ev[j], shift);
            for (o, r) in self.off_sides[j].iter_mut().zip(&ph.sides[j]) {
                *o = (dot(&r.pos, shift), dot(&r.vel, shift));
            }
        }
        let tb = &self.tables[self.mask as usize];
        for (o, row) in self.off_out.iter_mut().zip(&tb.out) {
            *o = dot(&row[..ph.dim], shift);
        }
    }

    /// With rods, `s` from the shifted equilibrium to the phase's own
    /// (`sign` 1) and back (-1): the form a switch's products take.
    fn unshift(&mut self, sign: f64) {
        if self.rods_on {
            let dim = self.s.len();
            for (x, d) in self.s.iter_mut().zip(&self.shift[..dim]) {
                *x += sign * d;
            }
        }
    }

    /// The flights (free masses, centres of free groups) go `dt` on.
    fn fly(&mut self, sc: &CompiledMulti, dt: f64) {
        let g = sc.model.gravity_m_per_s2;
        for &j in &sc.phases[self.mask as usize].flyers {
            self.x_f[j] += self.v_f[j] * dt - 0.5 * g * dt * dt;
            self.v_f[j] -= g * dt;
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
        // the flights in the penetration: the lower side's less the upper's
        let (lo, up) = ph.ev_fly[j];
        let flight =
            |slot: Option<usize>| slot.map_or((0.0, 0.0, 0.0), |k| (self.x_f[k], self.v_f[k], g));
        let ((xl, vl, gl), (xu, vu, gu)) = (flight(lo), flight(up));
        let mut f = EventFn {
            sign: if inside { 1.0 } else { -1.0 },
            x0: xl - xu,
            v0: vl - vu,
            g: gl - gu,
            allow: 0.0,
            neutral: 0.0,
        };
        let (row, nz) = (&ph.ev[j], &ph.ev_nz[j]);
        let q0 = dot_at(row, &self.s, nz) + ph.ev0[j];
        let q_end = dot_at(row, &self.end, nz) + ph.ev0[j];
        let psi_end = f.psi(q_end, rem);
        // a whole sample that clears the epoch's margin holds no crossing
        let epoch = self.clock / 64;
        let whole = matches!(start, Start::Value) && rem == self.step_h;
        if whole && self.cached[j].0 == epoch {
            let p0 = f.psi(q0, 0.0);
            if psi_end.min(p0) > self.cached[j].1 {
                return None;
            }
        }
        let d0 = f.dpsi(dot_at(&ph.ev_d[j], &self.s, &ph.evd_nz[j]), 0.0);
        let mut mag = ph.ev0[j].abs();
        let ev_e = &self.tables[self.mask as usize].ev_e[j];
        // the blocks the rows touch (the others weigh 0 in every bound)
        self.norms[0][..nb].fill(0.0);
        for &k in &ph.ev_blocks[j] {
            self.norms[0][k] = (self.s[k] * self.s[k] + self.s[nb + k] * self.s[nb + k]).sqrt();
            mag += ev_e[k] * self.norms[0][k];
        }
        mag += xl.abs() + xu.abs() + (vl.abs() + vu.abs()) * rem + (gl + gu) * rem * rem;
        f.neutral = 4.0 * f64::EPSILON / 2.0 * mag;
        // only for a contact that just left: its flight starts at 0 and a
        // rounding-level value of the wrong sign is no new contact
        if matches!(start, Start::Boundary) && !inside {
            f.allow = f.neutral;
        }
        self.budget = SEARCH_BUDGET;
        let g_curv = f.g.abs();
        let m = self.curvature(ph, j, g_curv, 0);
        if whole && self.cached[j].0 != epoch {
            // for the rest of the epoch: at most 64 samples of growth
            let later = self.tables[self.mask as usize].growth_max.powi(64);
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
        let tb = &self.tables[self.mask as usize];
        let (c2, e) = (&tb.ev_c2[j], &tb.ev_e[j]);
        for k in 0..ph.gens.len() {
            acc += (c2[k] * h).min(2.0 * e[k]) * norms[k];
        }
        acc * (1.0 + 1e-12)
    }

    /// A bound on `|psi''|` over a piece from the norms at its left end (in
    /// slot `slot`): `sum_k c_k |s_k| + g`.
    fn curvature(&self, ph: &MultiPhase, j: usize, g_curv: f64, slot: usize) -> f64 {
        let norms = &self.norms[slot];
        let c2 = &self.tables[self.mask as usize].ev_c2[j];
        let mut m = g_curv;
        for k in 0..ph.gens.len() {
            m += c2[k] * norms[k];
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
        // only the blocks the rows touch: the others add 0 here and weigh
        // 0 in the bounds (their norms set to 0)
        if let Some(slot) = slot {
            self.norms[slot].fill(0.0);
        }
        for &k in &ph.ev_blocks[j] {
            let p = ph.exp_block(k, t);
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
        if w <= LEAF * self.step_h || mid <= a || mid >= b {
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
        let tol = 0.5 * LEAF * self.step_h;
        while b - a > LEAF * self.step_h {
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
    /// enters or leaves, through the physical state (which does not jump),
    /// two changes of basis, O(dim^2). Returns where each contact's next
    /// search starts.
    /// Contacts `who` change side at `time_s`; an entering contact `j`
    /// starts at the penetration `enter[j]` (0 at an exact crossing; with
    /// the offset rod, its rod), a leaving one's rod goes.
    fn switch(
        &mut self,
        sc: &CompiledMulti,
        who: u32,
        time_s: f64,
        enter: &[f64; MAX_CONTACTS],
    ) -> [Start; MAX_CONTACTS] {
        let m = &sc.model;
        let old = &sc.phases[self.mask as usize];
        self.unshift(1.0);
        // every q, q', x, v
        old.physical_of(
            m,
            &self.s,
            (&self.x_f, &self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.phys,
        );
        // each closed contact's penetration from its own coordinate
        // (exact); an entering one starts unstretched (its crossing, 0 to
        // the search's leaf), so entering adds nothing
        let mut pen = *enter;
        for (j, p) in pen.iter_mut().enumerate().take(sc.contacts()) {
            if self.mask & (1 << j) != 0 {
                *p = dot(&old.ev[j], &self.s) + old.ev0[j];
            }
        }
        let p_left = pen;
        let new_mask = self.mask ^ who;
        let new = &sc.phases[new_mask as usize];
        self.tables[new_mask as usize].make(new, m, self.scale, self.step_h, self.band_hz);
        self.s.resize(new.dim, 0.0);
        new.state_of(
            m,
            (&self.phys, &pen),
            (&mut self.x_f, &mut self.v_f),
            (&mut self.zq, &mut self.zv),
            &mut self.s,
        );
        // a mass a leaving contact sets free starts its flight exactly at the
        // penetration the contact left with, the rest of it as the new
        // phase computes it (its row), without the change of basis's
        // rounding between the two bases' views of the other side
        let mut placed = 0u64;
        for j in 0..sc.contacts() {
            if who & (1 << j) == 0 || new_mask & (1 << j) != 0 {
                continue;
            }
            let ct = &m.contacts[j];
            let freed = |e: &MultiEnd| match e {
                MultiEnd::Mass(k)
                    if new.place[*k].is_none()
                        && old.place[*k].is_some()
                        && placed & (1 << k) == 0 =>
                {
                    Some(*k)
                }
                _ => None,
            };
            let q = dot(&new.ev[j], &self.s) + new.ev0[j];
            let (lo, up) = new.ev_fly[j];
            let at = |slot: Option<usize>, x: &[f64]| slot.map_or(0.0, |k| x[k]);
            // p = q + x_lower - x_upper (flights only)
            if let Some(k) = freed(&ct.upper) {
                let x_lo = if lo == Some(k) {
                    0.0
                } else {
                    at(lo, &self.x_f)
                };
                self.x_f[k] = q + x_lo - p_left[j];
                placed |= 1 << k;
            } else if let Some(k) = freed(&ct.lower) {
                let x_up = if up == Some(k) {
                    0.0
                } else {
                    at(up, &self.x_f)
                };
                self.x_f[k] = p_left[j] - q + x_up;
                placed |= 1 << k;
            }
        }
        for j in 0..sc.contacts() {
            if who & (1 << j) != 0 {
                let entered = new_mask & (1 << j) != 0;
                self.rod[j] = if entered { enter[j] } else { 0.0 };
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
        self.mask = new_mask;
        self.set_shift(sc);
        self.unshift(-1.0);
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

    /// The state now: each contact's sides (a row each, O(dim)) and the
    /// energy (every mode, every mass's motion and weight, every closed
    /// spring), O(N) for the modes no closed contact touches (all of them
    /// in flight) and O(d^2) for the `d` coordinates of the coupled part.
    pub fn observe(&self, sc: &CompiledMulti) -> MultiObservation {
        let m = &sc.model;
        let ph = &sc.phases[self.mask as usize];
        let g = m.gravity_m_per_s2;
        let s = &self.s;
        let nb = ph.gens.len();
        let nbc = ph.coupled.len() / 2;
        // a row of a switch product on the coupled entries of s
        let row = |a: &DMatrix<f64>, r: usize| -> f64 {
            ph.coupled.iter().map(|&c| a[(r, c)] * self.s_own(c)).sum()
        };
        // the free modes: their blocks are (omega q, q')
        let mut energy = 0.0;
        for k in nbc..nb {
            energy += 0.5 * (s[k] * s[k] + s[nb + k] * s[nb + k]);
        }
        // the coupled modes, the held masses, the closed springs, each
        // from its own value (no expansion about the equilibrium, whose
        // terms could be far larger than the energy)
        for &i in &ph.coupled_modes {
            let (a, b) = (row(&ph.qv, i) + ph.qv0[i], row(&ph.pv, i) + ph.pv0[i]);
            energy += 0.5 * (a * a + b * b);
        }
        for (j, ms) in m.masses.iter().enumerate() {
            let (x, v) = self.mass_at(sc, j);
            energy += 0.5 * ms.mass_kg * v * v + ms.mass_kg * g * x;
        }
        for &c in &ph.members {
            let p = dot(&ph.ev[c], s) + ph.ev0[c] + self.off_ev[c] - self.rod[c];
            energy += 0.5 * m.contacts[c].stiffness_n_per_m * p * p;
        }
        let mut o = MultiObservation {
            active: self.mask,
            energy,
            ..Default::default()
        };
        for j in 0..ph.sides.len() {
            let ((xl, vl), (xu, vu)) = (self.side_at(ph, j, 0), self.side_at(ph, j, 1));
            o.x_hammer[j] = xu;
            o.v_hammer[j] = vu;
            o.x_contact[j] = xl;
            o.v_contact[j] = vl;
        }
        o
    }

    /// [`observe`](Self::observe) the long way, through the physical state
    /// (every `q, q'`, every mass's `x, v`) and the energy summed from it
    /// (a closed spring's from the difference of its sides): O(dim^2) a
    /// sample, for checks.
    pub fn observe_physical(&self, sc: &CompiledMulti) -> MultiObservation {
        let m = &sc.model;
        let ph = &sc.phases[self.mask as usize];
        let nz = m.n() + m.masses.len();
        let (mut zq, mut zv) = (vec![0.0; nz + MAX_CONTACTS], vec![0.0; nz]);
        let mut phys = Physical::new(m);
        let s_own: Vec<f64> = (0..self.s.len()).map(|c| self.s_own(c)).collect();
        ph.physical_of(
            m,
            &s_own,
            (&self.x_f, &self.v_f),
            (&mut zq, &mut zv),
            &mut phys,
        );
        let mut o = MultiObservation {
            active: self.mask,
            energy: phys.energy(m),
            ..Default::default()
        };
        for (j, ct) in m.contacts.iter().enumerate() {
            let (xl, vl) = phys.side(&ct.lower);
            let (xu, vu) = phys.side(&ct.upper);
            if self.mask & (1 << j) != 0 {
                let p = xl - xu - ct.gap_m - self.rod[j];
                o.energy += 0.5 * ct.stiffness_n_per_m * p * p;
            }
            o.x_hammer[j] = xu;
            o.v_hammer[j] = vu;
            o.x_contact[j] = xl;
            o.v_contact[j] = vl;
        }
        o
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

impl Physical {
    fn new(m: &MultiModel) -> Self {
        let (n, nm) = (m.n(), m.masses.len());
        Self {
            q: vec![0.0; n],
            qv: vec![0.0; n],
            x: vec![0.0; nm],
            v: vec![0.0; nm],
        }
    }

    /// A side's position and velocity.
    fn side(&self, e: &MultiEnd) -> (f64, f64) {
        match e {
            MultiEnd::Point(w) => (dot(w, &self.q), dot(w, &self.qv)),
            MultiEnd::Mass(k) => (self.x[k.to_owned()], self.v[*k]),
            MultiEnd::Wall(h) => (*h, 0.0),
        }
    }

    /// Every mode's and every mass's energy, gravity's included (the
    /// closed springs' are the caller's).
    fn energy(&self, m: &MultiModel) -> f64 {
        let mut e = 0.0;
        for i in 0..m.n() {
            let w = two_pi() * m.freq_hz[i];
            let a = w * self.q[i];
            e += 0.5 * (a * a + self.qv[i] * self.qv[i]);
        }
        for (j, ms) in m.masses.iter().enumerate() {
            e += 0.5 * ms.mass_kg * self.v[j] * self.v[j]
                + ms.mass_kg * m.gravity_m_per_s2 * self.x[j];
        }
        e
    }
}

impl MultiPhase {
    /// The physical state of the phase's `y` (the flights from `fly`).
    fn physical_of(
        &self,
        m: &MultiModel,
        s: &[f64],
        (x_f, v_f): (&[f64], &[f64]),
        (zq, zv): (&mut [f64], &mut [f64]),
        out: &mut Physical,
    ) {
        let n = m.n();
        // a free mode's block is its own (omega q, q')
        for &(i, k1, k2) in &self.free_blocks {
            out.q[i] = s[k1] / (two_pi() * m.freq_hz[i]);
            out.qv[i] = s[k2];
        }
        // the coupled modes' q from Q u = (omega q, ...), z' = P w, the
        // held masses' x from Z u (the part off the free groups' centres)
        for &r in &self.qv_rows {
            zq[r] = self.qv0[r];
        }
        mat_vec_idx(&self.qv_c, (&self.coupled, s), &self.qv_rows, zq);
        for &i in &self.coupled_modes {
            out.q[i] = zq[i] / (two_pi() * m.freq_hz[i]);
        }
        for &r in &self.pv_rows {
            zv[r] = self.pv0[r];
        }
        mat_vec_idx(&self.pv_c, (&self.coupled, s), &self.pv_rows, zv);
        for &i in &self.coupled_modes {
            out.qv[i] = zv[i];
        }
        let nb = self.bound.len();
        zq[..nb].copy_from_slice(&self.zv0);
        mat_vec_idx(&self.zv_c, (&self.coupled, s), &self.bound_rows, zq);
        for (j, ms) in m.masses.iter().enumerate() {
            match self.place[j] {
                Some(b) => {
                    let s = ms.mass_kg.sqrt();
                    let (mut x, mut v) = (zq[b] / s, zv[n + b] / s);
                    if let Some(k) = self.fly_of[j] {
                        x += x_f[k];
                        v += v_f[k];
                    }
                    out.x[j] = x;
                    out.v[j] = v;
                }
                None => {
                    out.x[j] = x_f[j];
                    out.v[j] = v_f[j];
                }
            }
        }
    }

    /// The phase's block state `s` of a physical state whose closed
    /// contacts' penetrations are `pen` (by contact), and its flights: `u =
    /// Q^T (omega q, sqrt(k_c) (p_c - p0_c))`, `w = P^T z'`, `s = V^-1 (y -
    /// y*)`.
    /// The penetrations come apart from the positions: as a difference of
    /// two sides a heavy hammer's would keep `u |x|` of error.
    fn state_of(
        &self,
        m: &MultiModel,
        (ph, pen): (&Physical, &[f64; MAX_CONTACTS]),
        (x_f, v_f): (&mut [f64], &mut [f64]),
        (zq, zv): (&mut [f64], &mut [f64]),
        s: &mut [f64],
    ) {
        let n = m.n();
        for i in 0..n {
            zq[i] = two_pi() * m.freq_hz[i] * ph.q[i];
        }
        for (pos, &c) in self.members.iter().enumerate() {
            zq[n + pos] = m.contacts[c].stiffness_n_per_m.sqrt() * (pen[c] - self.p0[pos]);
        }
        zv[..n].copy_from_slice(&ph.qv);
        for (b, &j) in self.bound.iter().enumerate() {
            zv[n + b] = m.masses[j].mass_kg.sqrt() * ph.v[j];
        }
        for (j, place) in self.place.iter().enumerate() {
            if place.is_none() {
                x_f[j] = ph.x[j];
                v_f[j] = ph.v[j];
            }
        }
        for grp in &self.groups {
            let total: f64 = grp.iter().map(|&j| m.masses[j].mass_kg).sum();
            let (mut x, mut v) = (0.0, 0.0);
            for &j in grp {
                x += m.masses[j].mass_kg * ph.x[j];
                v += m.masses[j].mass_kg * ph.v[j];
            }
            x_f[grp[0]] = x / total;
            v_f[grp[0]] = v / total;
        }
        for (o, x) in s.iter_mut().zip(&self.s_star) {
            *o = -x;
        }
        // a free mode's block is its own (omega q, q') (its `s*` is 0);
        // the coupled entries through the coupled part's products
        for &(i, k1, k2) in &self.free_blocks {
            s[k1] += zq[i];
            s[k2] += zv[i];
        }
        mat_vec_idx(&self.vq_c, (&self.qv_rows, zq), &self.coupled, s);
        mat_vec_idx(&self.vp_c, (&self.pv_rows, zv), &self.coupled, s);
    }
}
/// `out[rows[r]] += sum_c M[r, c] x[cols[c]]` for a column-major `M`, by
/// columns in the order of `cols` (increasing, as a dense product's), so
/// the sums are those of the dense product over the whole vectors whose
/// other entries of `M` are 0.
fn mat_vec_idx(m: &DMatrix<f64>, (cols, x): (&[usize], &[f64]), rows: &[usize], out: &mut [f64]) {
    let nr = rows.len();
    let data = m.as_slice();
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

/// `out = P s` with one-sample block propagators.
fn step_blocks(props: &[Mat2], s: &[f64], out: &mut [f64], nb: usize) {
    for (k, p) in props.iter().enumerate() {
        let (x0, x1) = mul2(p, s[k], s[nb + k]);
        out[k] = x0;
        out[nb + k] = x1;
    }
}

/// `out = exp(G t) s`.
fn step_to(ph: &MultiPhase, t: f64, s: &[f64], out: &mut [f64]) {
    let nb = ph.gens.len();
    for k in 0..nb {
        let p = ph.exp_block(k, t);
        let (x0, x1) = mul2(&p, s[k], s[nb + k]);
        out[k] = x0;
        out[nb + k] = x1;
    }
}
