//! Scene compiler: turns a validated [`Scene`] into a [`CompiledScene`] of
//! plain immutable arrays. Runs off the audio thread (it allocates and runs
//! eigensolvers); the engine only reads its output.
//!
//! A short pipeline of named stages (docs/design.md, "The compiler"), each
//! in its own module with its own tests:
//!
//! 1. [`prune`] and [`budget`]: leave out what the scene does not need, and
//!    refuse a compile that would cost too much before any O(d^3) work;
//! 2. `routes`: the struck object's model and each phase's decomposition
//!    into real 2x2 blocks (closed form, rank-one secular route, general
//!    eigensolver, dense fallback);
//! 3. `basis`: the static equilibrium under gravity and the changes of
//!    basis between the phases (one matrix-vector product per switch);
//! 4. [`rows`]: the per-sample output and contact rows over each phase's
//!    coordinates;
//! 5. [`event`] and `checks`: what the exact event search needs, the
//!    switching method each phase allows, finiteness and passivity;
//! 6. `summary`: what was built, in words.

mod basis;
pub mod budget;
pub mod cancel;
mod checks;
pub mod drive;
pub mod error;
pub mod event;
pub mod prune;
pub mod rest;
mod routes;
pub mod rows;
mod summary;

pub use budget::{CompileBudget, CompileCost};
pub use checks::{MAX_DENSE_EXACT_DIM, MAX_DENSE_EXACT_NORM_H, PASSIVITY_TOL_PER_DIM_KAPPA_U};
pub use error::{CompileError, OverBudget, PhaseKind};
pub use event::EventSearch;
pub use rows::{pan_gains, PhaseRows, RowOffsets};

use crate::physics::block::OscBlocks;
use crate::physics::decomp::{self, DecompDiagnostics, Form, PhaseDecomp};
use crate::physics::hodlr::Hodlr;
use crate::scene::{ObjectSpec, Scene, SceneError, Switching};
use nalgebra::DMatrix;

/// Largest contact-system dimension the compiler attempts whatever the
/// [`CompileBudget`] (2 * 2000 + 2): beyond it the eigensolver takes far too
/// long for an interactive instrument. The default budget refuses much
/// smaller systems (a fully coupled contact system of dimension ~2100).
pub const MAX_CONTACT_DIM: usize = 4002;

/// Lowest and highest sample rate the compiler accepts \[Hz\].
pub const RATE_RANGE_HZ: (f64, f64) = (1_000.0, 10_000_000.0);

/// One phase, ready for the engine.
#[derive(Debug, Clone)]
pub struct CompiledPhase {
    /// State dimension (even).
    pub dim: usize,
    /// Block generators (when advanced in blocks).
    pub gens: Option<Vec<[f64; 4]>>,
    /// The blocks' oscillatory splits (when advanced in blocks), so that
    /// `exp(G tau)` at a new `tau` costs one batched exp/sin/cos.
    pub osc: OscBlocks,
    /// Dense generator and its propagator over one sample (fallback).
    pub dense: Option<(DMatrix<f64>, Vec<f64>)>,
    /// Phase coordinates to energy coordinates (`y = V s`), for energy/traces.
    pub v: DMatrix<f64>,
    /// `V` by rows, nonzeros only, when it is sparse (a modal object's free
    /// phase: a permutation; the uncoupled modes of a contact phase), so
    /// the trace's energy costs O(nonzeros) per sample instead of O(dim^2)
    /// (docs/design.md, "Offline rendering").
    pub v_sparse: Option<SparseRows>,
    /// `|V s|^2` as a block-diagonal quadratic form over the blocks' state,
    /// when no row of `V` mixes two blocks (a modal object in flight; the
    /// uncoupled modes): the traced render then takes each sample's energy
    /// from the kernel pass, O(N) (docs/design.md, "Offline rendering").
    pub energy_quad: Option<EnergyQuad>,
    /// `V^{-1}` (energy coordinates to phase coordinates), for rebinding.
    pub vinv: DMatrix<f64>,
    /// Output rows.
    pub rows: PhaseRows,
    /// Decomposition checks.
    pub diag: DecompDiagnostics,
    /// Event function row for exact switching: free phase `phi = x_h + ev . s`
    /// (i.e. `-x_c`), contact phase `phi = ev . s + ev_offset` (`p_eff`).
    pub ev: Vec<f64>,
    /// `d/dtau` of `ev . s(tau)`: `ev G` (blocks) or `ev A` (dense).
    pub ev_d: Vec<f64>,
    /// Second derivative row `ev G^2`.
    pub ev_dd: Vec<f64>,
    /// `|ev_dd|_2`: with `|exp(G tau)| <= 1` it bounds `|phi''| <= |ev_dd| |s|`
    /// over any step (the curvature bound that certifies "no event").
    pub ev_dd_norm: f64,
    /// Blocks only: `c_k = |(ev_dd[k], ev_dd[nb + k])|`, the curvature weight
    /// of block `k`. Each block is a contraction on its own, so
    /// `|phi''| <= sum_k c_k |s_k| <= sqrt(sum_k c_k) sqrt(sum_k c_k |s_k|^2)`
    /// (Cauchy-Schwarz with weights `c_k`): far tighter than the global bound
    /// when the energy sits in blocks that barely move `phi`.
    pub ev_dd_block: Vec<f64>,
    /// `sum_k c_k`.
    pub ev_dd_block_sum: f64,
    /// Blocks only: `e_k = |(ev[k], ev[nb + k])|`: block `k`'s share of
    /// `phi` stays within `e_k |s_k|` over any later step (a contraction),
    /// which bounds it better than its curvature for blocks that turn by
    /// more than about 2.8 radians a step.
    pub ev_block: Vec<f64>,
    /// Blocks only: `|(ev G)_k|` and `|(ev G^4)_k|`, the slope and
    /// fourth-derivative weights of block `k`: with `phi` and `phi'` known
    /// at both ends of a sample, its cubic Hermite interpolant is within
    /// `sum_k min(c4_k dt^4 / 384, 2 e_k + 8/27 dt c1_k) |s_k|` of `phi`
    /// (the certificate a sample that fails the fast path's test tries
    /// before the search; docs/numerics.md section 6.2).
    pub ev_d_block: Vec<f64>,
    /// See `ev_d_block`.
    pub ev_d4_block: Vec<f64>,
    /// What the exact event search needs beyond the rows ([`event`]).
    pub search: EventSearch,
}

/// A quadratic form over a block phase's state that is block-diagonal:
/// `sum_k aa[k] a_k^2 + ab[k] a_k b_k + bb[k] b_k^2` with `(a_k, b_k) = (s[k],
/// s[nb + k])` (twice a phase's stored energy when its energy coordinates
/// do not mix blocks: docs/design.md, "Offline rendering").
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EnergyQuad {
    /// Weight of `a_k^2`.
    pub aa: Vec<f64>,
    /// Weight of `a_k b_k`.
    pub ab: Vec<f64>,
    /// Weight of `b_k^2`.
    pub bb: Vec<f64>,
}

/// `|V s|^2 = sum_k aa_k a_k^2 + ab_k a_k b_k + bb_k b_k^2` over `nb` blocks
/// `(a_k, b_k) = (s[k], s[nb + k])`, when every row of `V` touches one
/// block only (then `V^T V` is block-diagonal); `None` otherwise.
fn energy_quad(v: &SparseRows, nb: usize) -> Option<EnergyQuad> {
    let mut q = EnergyQuad {
        aa: vec![0.0; nb],
        ab: vec![0.0; nb],
        bb: vec![0.0; nb],
    };
    for i in 0..v.start.len().saturating_sub(1) {
        let (mut blk, mut ca, mut cb) = (None, 0.0, 0.0);
        for e in v.start[i]..v.start[i + 1] {
            let (c, x) = (v.col[e], v.val[e]);
            let (k, is_b) = if c < nb { (c, false) } else { (c - nb, true) };
            if k >= nb || blk.is_some_and(|b| b != k) {
                return None;
            }
            blk = Some(k);
            if is_b {
                cb += x;
            } else {
                ca += x;
            }
        }
        if let Some(k) = blk {
            q.aa[k] += ca * ca;
            q.ab[k] += 2.0 * ca * cb;
            q.bb[k] += cb * cb;
        }
    }
    Some(q)
}

/// A matrix by rows, nonzeros only (compressed sparse rows).
#[derive(Debug, Clone, PartialEq)]
pub struct SparseRows {
    /// Row `i` holds entries `start[i]..start[i + 1]`.
    pub start: Vec<usize>,
    /// Column of each entry, ascending within a row.
    pub col: Vec<usize>,
    /// Value of each entry.
    pub val: Vec<f64>,
}

impl SparseRows {
    /// The nonzeros of `m` by rows, if there are at most `max_per_row`
    /// times as many as rows (else `None`: a dense product is as cheap).
    pub fn of(m: &DMatrix<f64>, max_per_row: usize) -> Option<Self> {
        let (rows, cols) = m.shape();
        let mut out = Self {
            start: Vec::with_capacity(rows + 1),
            col: Vec::new(),
            val: Vec::new(),
        };
        out.start.push(0);
        for i in 0..rows {
            for j in 0..cols {
                let x = m[(i, j)];
                if x != 0.0 {
                    if out.col.len() >= max_per_row * rows {
                        return None;
                    }
                    out.col.push(j);
                    out.val.push(x);
                }
            }
            out.start.push(out.col.len());
        }
        Some(out)
    }

    /// `(M x)_i`, summed over the row's nonzeros in column order: the same
    /// value, bit for bit, as the dense row sum (the skipped terms are
    /// exact zeros).
    #[inline]
    pub fn row_dot(&self, i: usize, x: impl Fn(usize) -> f64) -> f64 {
        let mut acc = 0.0;
        for e in self.start[i]..self.start[i + 1] {
            acc += self.val[e] * x(self.col[e]);
        }
        acc
    }
}

/// Nonzeros per row below which `V` is kept sparse for the trace's energy.
const SPARSE_V_PER_ROW: usize = 4;

/// `row G` for a block-diagonal or dense generator.
fn row_times_generator(
    row: &[f64],
    gens: Option<&Vec<[f64; 4]>>,
    dense: Option<&DMatrix<f64>>,
) -> Vec<f64> {
    let mut out = vec![0.0; row.len()];
    if let Some(gens) = gens {
        let nb = gens.len();
        for (k, g) in gens.iter().enumerate() {
            let (r0, r1) = (row[k], row[nb + k]);
            out[k] = r0 * g[0] + r1 * g[2];
            out[nb + k] = r0 * g[1] + r1 * g[3];
        }
    } else if let Some(a) = dense {
        for j in 0..row.len() {
            out[j] = (0..row.len()).map(|i| row[i] * a[(i, j)]).sum();
        }
    }
    out
}

impl CompiledPhase {
    fn set_event_row(&mut self, ev: Vec<f64>) {
        let dense = self.dense.as_ref().map(|d| &d.0);
        let d = row_times_generator(&ev, self.gens.as_ref(), dense);
        let dd = row_times_generator(&d, self.gens.as_ref(), dense);
        self.ev_dd_norm = dd.iter().map(|x| x * x).sum::<f64>().sqrt();
        if self.gens.is_some() {
            let nb = dd.len() / 2;
            self.ev_dd_block = (0..nb).map(|k| dd[k].hypot(dd[nb + k])).collect();
            self.ev_dd_block_sum = self.ev_dd_block.iter().sum();
            self.ev_block = (0..nb).map(|k| ev[k].hypot(ev[nb + k])).collect();
            let d3 = row_times_generator(&dd, self.gens.as_ref(), dense);
            let d4 = row_times_generator(&d3, self.gens.as_ref(), dense);
            self.ev_d_block = (0..nb).map(|k| d[k].hypot(d[nb + k])).collect();
            self.ev_d4_block = (0..nb).map(|k| d4[k].hypot(d4[nb + k])).collect();
        }
        self.search = match (&self.gens, &self.dense) {
            (Some(gens), _) => EventSearch::of_blocks(gens, &self.osc, &ev),
            (None, Some((a, _))) => EventSearch::of_dense(a, &ev),
            _ => EventSearch::default(),
        };
        self.ev = ev;
        self.ev_d = d;
        self.ev_dd = dd;
    }
}

/// A compiled scene: everything the engine needs, immutable.
#[derive(Debug, Clone)]
pub struct CompiledScene {
    /// Scene name.
    pub name: String,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Sample period \[s\].
    pub h: f64,
    /// Switching method.
    pub switching: Switching,
    /// Hammer mass \[kg\].
    pub m_h: f64,
    /// Gravity \[m/s^2\].
    pub g: f64,
    /// Initial hammer height \[m\] and velocity \[m/s\].
    pub hammer_x0: f64,
    /// See `hammer_x0`.
    pub hammer_v0: f64,
    /// Contact stiffness \[N/m\] and its square root.
    pub k: f64,
    /// `sqrt(k)`.
    pub sk: f64,
    /// Contact damping \[N s/m\].
    pub c: f64,
    /// `sqrt(m_h)`.
    pub sm: f64,
    /// Free phase of the struck object (the hammer is separate, closed form).
    pub free: CompiledPhase,
    /// Contact phase (object + spring + hammer).
    pub contact: CompiledPhase,
    /// Free -> contact: `s_c = W_cf s_f + col_pi pi + col_eta eta - s_star`.
    pub w_cf: DMatrix<f64>,
    /// See `w_cf`.
    pub col_pi: Vec<f64>,
    /// See `w_cf`.
    pub col_eta: Vec<f64>,
    /// Static equilibrium of the contact phase in its coordinates.
    pub s_star: Vec<f64>,
    /// Contact -> free: `s_f = W_fc s_c + s_f_star`.
    pub w_fc: DMatrix<f64>,
    /// `W_fc s_star`.
    pub s_f_star: Vec<f64>,
    /// `W_cf` and `W_fc` in hierarchical low-rank form where that pays
    /// (large modal objects; docs/numerics.md, "Structured changes of
    /// basis"): the engine's switches use these instead of the dense
    /// matrices.
    pub w_cf_h: Option<Hodlr>,
    /// See `w_cf_h`.
    pub w_fc_h: Option<Hodlr>,
    /// Constants of the contact rows.
    pub offsets: RowOffsets,
    /// A strike on the object at rest, precomputed so that its two switches
    /// cost O(N) (`None` when the contact is affine or not in block form;
    /// [`rest`]).
    pub rest: Option<rest::RestStrike>,
    /// The contact driven over a surface (`[drive]`; [`drive`]): the
    /// engine follows the profile sample by sample. `None`: struck.
    pub drive: Option<drive::DrivePlan>,
    /// Human-readable summary of what was built.
    pub summary: String,
    /// Estimated nodes per sample the exact event search needs near a
    /// switch to resolve the fastest terms (0 with the offset rod): the
    /// compile summary's `event search` line. The plugin warns above
    /// [`REALTIME_SEARCH_NODES`].
    pub search_nodes_estimate: f64,
}

impl CompiledScene {
    /// Multiply-adds of the two changes of basis of a strike on a ringing
    /// object (enter and leave contact): the stored entries of the
    /// hierarchical forms, or of the dense matrices. \[any-thread\]
    pub fn switch_multiply_adds(&self) -> usize {
        let cf = self.w_cf_h.as_ref().map_or(self.w_cf.len(), Hodlr::stored);
        let fc = self.w_fc_h.as_ref().map_or(self.w_fc.len(), Hodlr::stored);
        cf + fc
    }
}

/// Event-search nodes per sample beyond which a sample holding a switch may
/// take longer than a 44.1 kHz sample period (measured 0.2-0.3 us per node
/// plus the changes of basis; docs/numerics.md, "Why it terminates, and what it costs").
pub const REALTIME_SEARCH_NODES: f64 = 32.0;

/// The longest contact of a strike from rest that the compiler precomputes
/// \[s\] ([`rest`]).
pub const REST_T_MAX_S: f64 = 1.0;

/// Compile a scene of one contact for a sample rate (a scene of several
/// is refused: [`crate::play::compile`] takes every scene).
pub fn compile_one(scene: &Scene, rate_hz: f64) -> Result<CompiledScene, CompileError> {
    compile_with(scene, rate_hz, None)
}

/// What the compiler may leave out (docs/numerics.md, "Leaving out what a
/// scene does not need").
#[derive(Debug, Clone, Copy)]
pub struct CompileOptions {
    /// Exact savings (no approximation): drop modes that are zero at the
    /// contact point and at every pickup, keep modes with zero contact weight
    /// out of the contact eigenproblem. On by default; off only to test that
    /// they change nothing.
    pub exact_savings: bool,
    /// Apply the scene's opt-in `[approximate]` settings.
    pub approximations: bool,
    /// Largest estimated cost of a compile: a scene above it is refused
    /// before any O(d^3) work (see [`budget`]).
    pub budget: CompileBudget,
}

impl CompileOptions {
    /// The defaults, usable in `const` contexts (`..CompileOptions::DEFAULT`).
    pub const DEFAULT: Self = Self {
        exact_savings: true,
        approximations: true,
        budget: CompileBudget::DEFAULT,
    };
}

impl Default for CompileOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Compile, optionally overriding the scene's switching method.
pub fn compile_with(
    scene: &Scene,
    rate_hz: f64,
    switching: Option<Switching>,
) -> Result<CompiledScene, CompileError> {
    compile_opts(scene, rate_hz, switching, &CompileOptions::default())
}

/// A decomposed phase made ready for the engine: the dense fallback's
/// one-sample propagator (row-major for the engine's mat-vec) or the
/// blocks' oscillatory splits.
fn to_phase(
    kind: PhaseKind,
    d: PhaseDecomp,
    rows: PhaseRows,
    h: f64,
    scene: &Scene,
    ci: usize,
) -> Result<CompiledPhase, CompileError> {
    let dim = d.v.nrows();
    let (gens, dense) = match d.form {
        Form::Blocks { gens } => (Some(gens), None),
        Form::Dense { a } => {
            let phi = decomp::dense_exp(&a, h).map_err(|source| CompileError::Decomposition {
                phase: kind,
                source,
                rate_hz: 1.0 / h,
                hint: error::stiffness_hint(kind, scene, ci),
            })?;
            let flat: Vec<f64> = (0..dim)
                .flat_map(|i| (0..dim).map(move |j| (i, j)))
                .map(|(i, j)| phi[(i, j)])
                .collect();
            (None, Some((a, flat)))
        }
    };
    let osc = gens.as_deref().map(OscBlocks::of).unwrap_or_default();
    let v_sparse = SparseRows::of(&d.v, SPARSE_V_PER_ROW);
    let energy_quad = match (&gens, &v_sparse) {
        (Some(g), Some(sp)) => energy_quad(sp, g.len()),
        _ => None,
    };
    Ok(CompiledPhase {
        dim,
        gens,
        osc,
        dense,
        v_sparse,
        energy_quad,
        v: d.v,
        vinv: d.vinv,
        rows,
        diag: d.diag,
        ev: Vec::new(),
        ev_d: Vec::new(),
        ev_dd: Vec::new(),
        ev_dd_norm: 0.0,
        ev_dd_block: Vec::new(),
        ev_dd_block_sum: 0.0,
        ev_block: Vec::new(),
        ev_d_block: Vec::new(),
        ev_d4_block: Vec::new(),
        search: EventSearch::default(),
    })
}

/// Compile with explicit [`CompileOptions`]: the stages of the module doc,
/// in order.
pub fn compile_opts(
    scene: &Scene,
    rate_hz: f64,
    switching: Option<Switching>,
    opts: &CompileOptions,
) -> Result<CompiledScene, CompileError> {
    check_request(scene, rate_hz)?;
    // 0. objects described by geometry and material become their modes at
    // this rate (docs/design.md, "Objects from geometry and material")
    let original = scene;
    let expanded = scene.expanded(rate_hz)?;
    let scene = &expanded;
    scene.validate()?;
    let asked = switching.or(scene.contact.switching).unwrap_or_default();
    let h = 1.0 / rate_hz;
    let ci = scene
        .object_index(&scene.contact.object)
        .ok_or_else(|| CompileError::MissingObject(scene.contact.object.clone()))?;
    // 1. leave out what is not needed; refuse before any O(d^2) allocation
    // or O(d^3) work when too big
    let (spec, dropped_modes) = prune::prune_object(scene, ci, rate_hz, opts);
    let cost = checked_cost(scene, &spec, ci, opts)?;
    // 2. to 5.
    let ph = phases(scene, &spec, ci, rate_hz, &cost, asked, opts)?;
    // 5b. a strike on the object at rest (not where a moving surface
    // changes the hammer's motion every sample)
    let drive = scene.drive.as_ref().map(drive::plan).transpose()?;
    let rest = if drive.is_some() {
        None
    } else {
        rest_strike(&ph, h)
    };
    cancel::check().map_err(|_| CompileError::Cancelled)?;
    // 6. summary
    let (mut summary, search_nodes_estimate) =
        describe(original, scene, ci, rate_hz, &spec, &dropped_modes, &ph);
    summary.push_str(&summary::rest_line(rest.as_ref(), h));
    let [w_cf_h, w_fc_h] = basis::structured(&ph.free, &ph.contact, &ph.basis);
    summary.push_str(&summary::structured_line(
        [&w_cf_h, &w_fc_h],
        ph.free.dim * ph.contact.dim,
    ));
    let (w_cf_h, w_fc_h) = (w_cf_h.ok(), w_fc_h.ok());
    let p = ph.object.params;
    Ok(CompiledScene {
        name: scene.name.clone(),
        rate_hz,
        h,
        switching: ph.switching,
        m_h: p.m_h,
        g: p.g,
        hammer_x0: scene.hammer.height_m,
        hammer_v0: scene.hammer.velocity_m_per_s,
        k: p.k,
        sk: p.k.sqrt(),
        c: p.c,
        sm: p.m_h.sqrt(),
        free: ph.free,
        contact: ph.contact,
        w_cf: ph.basis.w_cf,
        col_pi: ph.basis.col_pi,
        col_eta: ph.basis.col_eta,
        s_star: ph.basis.s_star,
        w_fc: ph.basis.w_fc,
        s_f_star: ph.basis.s_f_star,
        w_cf_h,
        w_fc_h,
        offsets: ph.offsets,
        rest,
        drive,
        summary,
        search_nodes_estimate,
    })
}

/// The checks before any work: a valid scene, a sample rate in
/// [`RATE_RANGE_HZ`], and one contact (a scene of several runs on the
/// several-contact engine).
fn check_request(scene: &Scene, rate_hz: f64) -> Result<(), CompileError> {
    scene.validate()?;
    if !(rate_hz.is_finite() && (RATE_RANGE_HZ.0..=RATE_RANGE_HZ.1).contains(&rate_hz)) {
        return Err(CompileError::SampleRate(rate_hz));
    }
    if scene.several_contacts() {
        let key = if scene.striker.is_empty() {
            "touch"
        } else {
            "striker"
        };
        return Err(CompileError::Scene(SceneError::new(
            key,
            "a scene of several contacts runs on the several-contact engine \
             (`modal_contact::compile` compiles either kind, `cargo xtask render` renders it, \
             and the instrument plays it as a kit: docs/design.md \"Several contacts\"); \
             `compile_one` and the report take one contact",
        )));
    }
    Ok(())
}

/// Stage 1's refusal: the estimated cost of compiling the pruned struck
/// object `spec`, refused when its contact system is beyond
/// [`MAX_CONTACT_DIM`] or the compile beyond `opts.budget`.
fn checked_cost(
    scene: &Scene,
    spec: &ObjectSpec,
    ci: usize,
    opts: &CompileOptions,
) -> Result<CompileCost, CompileError> {
    let mut cost = CompileCost::estimate(
        spec,
        scene.contact.point.as_deref(),
        scene.hammer.gravity_m_per_s2 != 0.0,
        opts.exact_savings,
    );
    // a lumped string with a modal mallet: the general eigensolver takes
    // the string's masses and the mallet's modes together
    if let (ObjectSpec::String(st), Some(ObjectSpec::Modal(m))) = (
        spec,
        scene
            .hammer
            .object
            .as_deref()
            .and_then(|m| scene.object_index(m))
            .map(|mi| &scene.object[mi]),
    ) {
        let n = st.masses + m.mode.len();
        cost = CompileCost::from_dims(n, n, true, 2 * n + 2, cost.gravity, false);
    }
    if cost.contact_dim > MAX_CONTACT_DIM {
        return Err(CompileError::TooLarge {
            dim: cost.contact_dim,
            limit: MAX_CONTACT_DIM,
            object: scene.contact.object.clone(),
        });
    }
    cost.check(&opts.budget, scene, ci)
        .map_err(CompileError::OverBudget)?;
    Ok(cost)
}

/// The two phases of the struck object and what joins them: stages 2 to 5
/// of the module doc.
struct Phases {
    /// The struck object's model and the contact's parameters.
    object: routes::Object,
    /// The changes of basis between the phases.
    basis: basis::Basis,
    /// Offsets of the contact rows.
    offsets: RowOffsets,
    /// Pickups left out, with why.
    dropped_pickups: Vec<String>,
    /// Modes the contact leaves uncoupled.
    uncoupled: usize,
    /// The free phase, with its event row.
    free: CompiledPhase,
    /// The contact phase, with its event row.
    contact: CompiledPhase,
    /// The switching method the phases allow.
    switching: Switching,
    /// Why it is not the one asked for, if it is not.
    switching_note: Option<String>,
}

/// Stages 2 to 5: the model and the decompositions, the equilibrium, the
/// rows and the changes of basis, then the event rows, the switching
/// method (`asked` if the phases allow it) and the checks of finiteness
/// and passivity.
fn phases(
    scene: &Scene,
    spec: &ObjectSpec,
    ci: usize,
    rate_hz: f64,
    cost: &CompileCost,
    asked: Switching,
    opts: &CompileOptions,
) -> Result<Phases, CompileError> {
    let h = 1.0 / rate_hz;
    // 2. model and decompositions
    let object = routes::object(scene, spec, ci)?;
    cancel::check().map_err(|_| CompileError::Cancelled)?;
    let dec = routes::decompose(scene, ci, &object, rate_hz, cost, opts)?;
    cancel::check().map_err(|_| CompileError::Cancelled)?;
    // 3. equilibrium, 4. rows, and the changes of basis
    let y_star = basis::equilibrium(&dec, object.params.g != 0.0)?;
    let rows = rows::build(scene, &object, &dec, &y_star);
    let basis = basis::changes(&dec, &y_star)?;
    let uncoupled = dec.uncoupled.len();
    let mut free = to_phase(PhaseKind::Free, dec.free, rows.free, h, scene, ci)?;
    let mut contact = to_phase(PhaseKind::Contact, dec.contact, rows.contact, h, scene, ci)?;
    // 5. event rows, switching, checks
    let sk = object.params.k.sqrt();
    free.set_event_row(free.rows.x_c.iter().map(|x| -x).collect());
    contact.set_event_row(contact.rows.pi.iter().map(|x| x / sk).collect());
    let (switching, switching_note) = checks::switching(asked, [&free, &contact], h);
    checks::finite_and_passive(
        [(PhaseKind::Free, &free), (PhaseKind::Contact, &contact)],
        h,
        scene,
        ci,
    )?;
    cancel::check().map_err(|_| CompileError::Cancelled)?;
    Ok(Phases {
        object,
        basis,
        offsets: rows.offsets,
        dropped_pickups: rows.dropped_pickups,
        uncoupled,
        free,
        contact,
        switching,
        switching_note,
    })
}

/// Stage 5b: a strike on the object at rest, for a step `h`.
fn rest_strike(ph: &Phases, h: f64) -> Option<rest::RestStrike> {
    rest::rest_strike(&rest::RestInputs {
        free: &ph.free,
        contact: &ph.contact,
        col_eta: &ph.basis.col_eta,
        w_cf: &ph.basis.w_cf,
        w_fc: &ph.basis.w_fc,
        s_f_star: &ph.basis.s_f_star,
        offsets_x_eta: (ph.offsets.x_c, ph.offsets.eta),
        sm: ph.object.params.m_h.sqrt(),
        s_star: &ph.basis.s_star,
        offset_pi: ph.offsets.pi,
        h,
        t_max: REST_T_MAX_S,
    })
}

/// Stage 6: what was built, in words, and the estimated search nodes.
/// `original`: the scene as written (for the struck object's kind and the
/// mallet), `scene` as compiled.
fn describe(
    original: &Scene,
    scene: &Scene,
    ci: usize,
    rate_hz: f64,
    spec: &ObjectSpec,
    dropped_modes: &[String],
    ph: &Phases,
) -> (String, f64) {
    summary::write(&summary::Facts {
        scene,
        ci,
        rate_hz,
        switching: ph.switching,
        switching_note: ph.switching_note.as_deref(),
        object_name: &ph.object.obj.name,
        n: ph.object.obj.n,
        kind: match spec {
            ObjectSpec::Wall(_) => "wall",
            _ => original.object[ci].kind(),
        },
        params: &ph.object.params,
        free: &ph.free,
        contact: &ph.contact,
        uncoupled: ph.uncoupled,
        dropped_modes,
        dropped_pickups: &ph.dropped_pickups,
        mallet: original.hammer.object.as_deref().and_then(|m| {
            match scene.object_index(m).map(|mi| &scene.object[mi]) {
                Some(ObjectSpec::Modal(mm)) => Some((m, mm.mode.len())),
                _ => None,
            }
        }),
    })
}
