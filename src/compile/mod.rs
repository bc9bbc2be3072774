//! Scene compiler: turns a validated [`Scene`] into a [`CompiledScene`] of plain
//! immutable arrays. Runs off the audio thread (it allocates and runs
//! eigensolvers); the engine only reads its output.
//!
//! What it builds (paper sections 2.1-2.3, NUMERICS.md section 2):
//! - the free phase of the struck object in real 2x2 blocks (closed form per
//!   mode for modal objects; checked eigen blocks or dense fallback for lumped
//!   objects), the hammer in closed form (never diagonalised);
//! - the contact phase of object + hammer + spring-damper, decomposed and
//!   checked the same way;
//! - the changes of basis between the two phases (O(N^2) per switch) and the
//!   output rows (O(N) per sample);
//! - gravity as a shift to the contact phase's static equilibrium, so stepping
//!   stays homogeneous (no affine term per sample).

pub mod budget;
pub mod event;
pub mod prune;

pub use budget::{CompileBudget, CompileCost};
pub use event::EventSearch;

use crate::physics::block::OscBlocks;
use crate::physics::decomp::{self, DecompDiagnostics, Form, PhaseDecomp};
use crate::physics::model::{contact_system, ContactLayout, ContactParams, ObjectModel};
use crate::physics::secular;
use crate::scene::{ObjectSpec, Quantity, Scene, Switching};
use nalgebra::{DMatrix, DVector};
use std::fmt;

/// Largest contact-system dimension the compiler attempts whatever the
/// [`CompileBudget`] (2 * 2000 + 2): beyond it the eigensolver takes far too
/// long for an interactive instrument. The default budget refuses much
/// smaller systems (a fully coupled contact system of dimension ~2100).
pub const MAX_CONTACT_DIM: usize = 4002;
/// Largest dense-fallback phase for which exact switching is offered (its
/// partial steps cost O(dim^2) per Taylor term; near-defective phases are in
/// practice the 2x2 hammer-on-wall case).
pub const MAX_DENSE_EXACT_DIM: usize = 16;
/// Largest `|A|_F h` of a dense-fallback phase for which exact switching is
/// offered: the engine's partial dense steps take `ceil(|A|_F tau / 0.5)`
/// Taylor sub-steps of 20 mat-vecs each, per event-function evaluation, so a
/// very stiff or very damped dense phase (found by tests/fuzz_scenes.rs:
/// `|A| h ~ 1e6` made one sample take minutes) gets the offset rod instead.
/// 8 allows 16 sub-steps (~80k flops per evaluation at dimension 16).
pub const MAX_DENSE_EXACT_NORM_H: f64 = 8.0;

/// Passivity check of every compiled propagator: its largest singular value
/// over one sample, in energy coordinates, may exceed 1 by at most this many
/// units of `dim * kappa(V) * u` (the rounding of forming `V exp(G h) V^-1`,
/// or of the dense `exp(A h)` with `kappa = 1`). A larger excess means the
/// decomposition or the Pade exponential is not accurate enough for the
/// phase to be passive in f64, and stepping it could create energy
/// (tests/fuzz_scenes.rs found a dense contact phase with `|A| h = 1.6e9`
/// and `sigma_max - 1 = 4.5e-8`): such a scene is refused.
pub const PASSIVITY_TOL_PER_DIM_KAPPA_U: f64 = 16.0;

/// Why a scene could not be compiled.
#[derive(Debug, Clone, PartialEq)]
pub struct CompileError(pub String);

impl fmt::Display for CompileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "cannot compile scene: {}", self.0)
    }
}

impl std::error::Error for CompileError {}

/// Output rows of one phase, over that phase's coordinates.
#[derive(Debug, Clone)]
pub struct PhaseRows {
    /// Displacement of the contact point.
    pub x_c: Vec<f64>,
    /// Velocity of the contact point.
    pub v_c: Vec<f64>,
    /// Displacement pickups mixed for the left / right channel.
    pub disp_l: Vec<f64>,
    /// See `disp_l`.
    pub disp_r: Vec<f64>,
    /// Velocity pickups mixed for the left / right channel.
    pub vel_l: Vec<f64>,
    /// See `vel_l`.
    pub vel_r: Vec<f64>,
    /// Contact phase only: `pi = sqrt(k) p_eff`.
    pub pi: Vec<f64>,
    /// Contact phase only: `eta = sqrt(m_h) v_h`.
    pub eta: Vec<f64>,
}

/// Constants added to the contact rows (the static equilibrium under gravity).
#[derive(Debug, Clone, Copy, Default)]
pub struct RowOffsets {
    /// Added to `x_c`.
    pub x_c: f64,
    /// Added to `v_c` (0 at equilibrium, kept for clarity).
    pub v_c: f64,
    /// Added to the mixed outputs.
    pub disp_l: f64,
    /// See `disp_l`.
    pub disp_r: f64,
    /// Added to `pi`.
    pub pi: f64,
    /// Added to `eta`.
    pub eta: f64,
}

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
    /// What the exact event search needs beyond the rows ([`event`]).
    pub search: EventSearch,
}

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
    /// Sample rate [Hz].
    pub rate_hz: f64,
    /// Sample period [s].
    pub h: f64,
    /// Switching method.
    pub switching: Switching,
    /// Hammer mass [kg].
    pub m_h: f64,
    /// Gravity [m/s^2].
    pub g: f64,
    /// Initial hammer height [m] and velocity [m/s].
    pub hammer_x0: f64,
    /// See `hammer_x0`.
    pub hammer_v0: f64,
    /// Contact stiffness [N/m] and its square root.
    pub k: f64,
    /// `sqrt(k)`.
    pub sk: f64,
    /// Contact damping [N s/m].
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
    /// Constants of the contact rows.
    pub offsets: RowOffsets,
    /// Human-readable summary of what was built.
    pub summary: String,
    /// Estimated nodes per sample the exact event search needs near a
    /// switch to resolve the fastest terms (0 with the offset rod): the
    /// compile summary's `event search` line. The plugin warns above
    /// [`REALTIME_SEARCH_NODES`].
    pub search_nodes_estimate: f64,
}

/// Event-search nodes per sample beyond which a sample holding a switch may
/// take longer than a 44.1 kHz sample period (measured 0.2-0.3 us per node
/// plus the changes of basis; docs/numerics.md section 6.5).
pub const REALTIME_SEARCH_NODES: f64 = 32.0;

fn row_vec(row: &DVector<f64>, v: &DMatrix<f64>) -> Vec<f64> {
    (0..v.ncols()).map(|j| row.dot(&v.column(j))).collect()
}

/// Constant-power pan law: gains (left, right) for pan in [-1, 1].
pub fn pan_gains(pan: f64) -> (f64, f64) {
    let theta = (pan + 1.0) * std::f64::consts::FRAC_PI_4;
    (theta.cos(), theta.sin())
}

/// What to change when a phase is too stiff or too damped for f64.
fn stiffness_hint(what: &str, scene: &Scene, ci: usize) -> String {
    let obj = match &scene.object[ci] {
        ObjectSpec::String(_) => format!(
            "lower object[{ci}]'s damping (dashpots, rayleigh_alpha_per_s, rayleigh_beta_s) or spring_n_per_m, or raise its mass_kg"
        ),
        ObjectSpec::Modal(_) => format!(
            "lengthen the shortest t60_s of object[{ci}] or lower its weights at the contact point (|w| is 1/sqrt(effective mass))"
        ),
        ObjectSpec::Wall(_) => String::new(),
    };
    if what == "free" {
        obj
    } else if obj.is_empty() {
        "lower contact.stiffness_n_per_m or contact.damping_n_s_per_m, or raise hammer.mass_kg"
            .into()
    } else {
        format!("lower contact.stiffness_n_per_m or contact.damping_n_s_per_m, raise hammer.mass_kg, or {obj}")
    }
}

/// A decomposition failure of one phase, with what it means for the scene.
fn phase_error(what: &str, e: &str, rate_hz: f64, scene: &Scene, ci: usize) -> CompileError {
    CompileError(format!(
        "{what} phase: {e}. Its generator is too stiff or too damped to be advanced in f64 at {rate_hz} Hz: {}",
        stiffness_hint(what, scene, ci)
    ))
}

/// Compile a scene for a sample rate.
pub fn compile(scene: &Scene, rate_hz: f64) -> Result<CompiledScene, CompileError> {
    compile_with(scene, rate_hz, None)
}

/// What the compiler may leave out (DESIGN/issue: "leave out what a scene
/// does not need").
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

/// Compile with explicit [`CompileOptions`].
pub fn compile_opts(
    scene: &Scene,
    rate_hz: f64,
    switching: Option<Switching>,
    opts: &CompileOptions,
) -> Result<CompiledScene, CompileError> {
    scene.validate().map_err(|e| CompileError(e.to_string()))?;
    if !(rate_hz.is_finite() && (1000.0..=10_000_000.0).contains(&rate_hz)) {
        return Err(CompileError(format!(
            "sample rate must be in 1 kHz..10 MHz, got {rate_hz}"
        )));
    }
    let switching = switching.or(scene.contact.switching).unwrap_or_default();
    let h = 1.0 / rate_hz;
    let ci = scene
        .object_index(&scene.contact.object)
        .ok_or_else(|| CompileError("contact object missing".into()))?;
    let (spec, dropped_modes) = prune::prune_object(scene, ci, rate_hz, opts);
    let spec = &spec;
    // Budget: estimate before building anything of size O(d^2) or doing any
    // O(d^3) work.
    let cost = CompileCost::estimate(
        spec,
        scene.contact.point.as_deref(),
        scene.hammer.gravity_m_per_s2 != 0.0,
        opts.exact_savings,
    );
    if cost.contact_dim > MAX_CONTACT_DIM {
        return Err(CompileError(format!(
            "contact system of dimension {} exceeds the limit {MAX_CONTACT_DIM} (object[{ci}] {:?}: use fewer modes or masses); not attempted",
            cost.contact_dim,
            scene.contact.object
        )));
    }
    cost.check(&opts.budget, scene, ci).map_err(CompileError)?;
    let obj = ObjectModel::from_spec(spec)
        .map_err(|e| CompileError(format!("object[{ci}] {:?}: {e}", scene.contact.object)))?;
    // A modal object whose every mode was pruned is a rigid wall: it has no
    // points, and the hammer meets it as a wall (tests/fuzz_scenes.rs found
    // `[approximate] max_freq_hz` below every mode giving "no point c").
    let contact_point = match spec {
        ObjectSpec::Wall(_) => None,
        _ => scene.contact.point.as_ref(),
    };
    let contact_rows = match contact_point {
        Some(p) => Some(
            obj.point(p)
                .ok_or_else(|| CompileError(format!("no point {p}")))?
                .clone(),
        ),
        None => None,
    };
    let n = obj.n;
    let params = ContactParams {
        k: scene.contact.stiffness_n_per_m,
        c: scene.contact.damping_n_s_per_m,
        m_h: scene.hammer.mass_kg,
        g: scene.hammer.gravity_m_per_s2,
    };

    // --- free phase of the object
    let free_dec: PhaseDecomp = match &obj.modal_blocks {
        Some(blocks) => {
            let pairs: Vec<(usize, usize)> = (0..n).map(|i| (i, n + i)).collect();
            decomp::from_blocks(blocks.clone(), &pairs, 2 * n, h)
        }
        None => {
            decomp::decompose(&obj.a, h).map_err(|e| phase_error("free", &e, rate_hz, scene, ci))?
        }
    };

    // --- contact phase
    let (a_c, f_c, lay): (DMatrix<f64>, DVector<f64>, ContactLayout) =
        contact_system(&obj, contact_rows.as_ref().map(|r| &r.vel), &params);
    // Exact saving: modes with zero weight at the contact point are exactly
    // decoupled from the contact; only the coupled part is diagonalised.
    let uncoupled: Vec<usize> = match (&obj.modal_blocks, &contact_rows) {
        (Some(_), Some(rows)) if opts.exact_savings => {
            (0..n).filter(|&i| rows.vel[n + i] == 0.0).collect()
        }
        _ => Vec::new(),
    };
    // A modal object struck at one point: its contact system is a rank-one
    // update of diagonal modes, decomposed in O(N^2) through the secular
    // equation (NUMERICS.md section 6), checked like any decomposition; the
    // general eigensolver takes over if it fails.
    let secular = || -> Option<(&'static str, Result<decomp::BlockEigen, String>)> {
        let blocks = obj.modal_blocks.as_ref()?;
        let f_all: Vec<f64> = match &contact_rows {
            Some(rows) => (0..n).map(|i| rows.vel[n + i]).collect(),
            None => Vec::new(),
        };
        let keep: Vec<usize> = (0..f_all.len())
            .filter(|i| uncoupled.binary_search(i).is_err())
            .collect();
        let omega: Vec<f64> = keep.iter().map(|&i| blocks[i][1]).collect();
        let sigma: Vec<f64> = keep.iter().map(|&i| -0.5 * blocks[i][3]).collect();
        let f: Vec<f64> = keep.iter().map(|&i| f_all[i]).collect();
        let mc = secular::ModalContact {
            omega: &omega,
            sigma: &sigma,
            f: &f,
            k: params.k,
            c: params.c,
            m_h: params.m_h,
        };
        Some(("rank-one secular eigenvectors", secular::decompose(&mc)))
    };
    // A failed secular route falls back to the general eigensolver only if
    // that fits the budget too.
    let general_ok = cost.general_fits(&opts.budget);
    let contact_error = |e: String| {
        if e.contains(decomp::GENERAL_OVER_BUDGET) {
            CompileError(format!(
                "contact phase: {e} (estimate {:.1e} flops, {:.0} MB); not attempted",
                cost.general().flops,
                cost.general().bytes / 1e6
            ))
        } else {
            phase_error("contact", &e, rate_hz, scene, ci)
        }
    };
    let mut con_dec = None;
    if !uncoupled.is_empty() {
        let blocks = obj.modal_blocks.as_ref().expect("modal");
        let is_unc = |i: usize| uncoupled.binary_search(&i).is_ok();
        let coupled: Vec<usize> = (0..lay.dim())
            .filter(|&r| {
                let mode = if r < n {
                    Some(r)
                } else if r > n && r < 2 * n + 1 {
                    Some(r - n - 1)
                } else {
                    None
                };
                !mode.is_some_and(is_unc)
            })
            .collect();
        let pairs: Vec<(usize, usize)> = uncoupled.iter().map(|&i| (i, n + 1 + i)).collect();
        let gens: Vec<[f64; 4]> = uncoupled.iter().map(|&i| blocks[i]).collect();
        con_dec = decomp::decompose_split(&a_c, &coupled, &pairs, &gens, h, secular(), general_ok)
            .map_err(contact_error)?;
        if con_dec.is_none() {
            // The coupled part needs the dense fallback: the whole contact
            // system is decomposed instead, which the estimate did not count.
            let whole = CompileCost::from_dims(n, n, false, lay.dim(), params.g != 0.0, false);
            whole
                .check(&opts.budget, scene, ci)
                .map_err(|e| CompileError(format!("the coupled modes are near-defective, so the whole contact system must be decomposed: {e}")))?;
        }
    }
    let con_dec = match con_dec {
        Some(d) => d,
        None if uncoupled.is_empty() => {
            decomp::decompose_via(&a_c, h, secular(), general_ok).map_err(contact_error)?
        }
        None => decomp::decompose(&a_c, h)
            .map_err(|e| phase_error("contact", &e, rate_hz, scene, ci))?,
    };

    // static equilibrium y* = -A^{-1} f (only with gravity: no affine term otherwise)
    let y_star: DVector<f64> = if params.g != 0.0 {
        let sol = crate::physics::linalg::solve(&a_c, &(-&f_c))
            .ok_or_else(|| CompileError("contact system is singular under gravity".into()))?;
        if sol.iter().any(|x| !x.is_finite()) {
            return Err(CompileError("static equilibrium is not finite".into()));
        }
        sol
    } else {
        DVector::zeros(lay.dim())
    };

    // --- rows in physical (energy) coordinates
    let dim_f = 2 * n;
    let dim_c = lay.dim();
    let zero_f = DVector::zeros(dim_f);
    let xc_f = contact_rows
        .as_ref()
        .map_or(zero_f.clone(), |r| r.disp.clone());
    let vc_f = contact_rows
        .as_ref()
        .map_or(zero_f.clone(), |r| r.vel.clone());
    let mut dl = zero_f.clone();
    let mut dr = zero_f.clone();
    let mut vl = zero_f.clone();
    let mut vr = zero_f.clone();
    let mut dropped_pickups = Vec::new();
    for (i, p) in scene.pickup.iter().enumerate() {
        if p.object != scene.contact.object {
            // Only the struck object is ever excited: a pickup elsewhere is
            // silent forever, so it is left out (exact saving).
            dropped_pickups.push(format!(
                "pickup[{i}] on {:?}: object never excited",
                p.object
            ));
            continue;
        }
        let Some(rows) = obj.point(&p.point) else {
            dropped_pickups.push(format!("pickup[{i}]: every mode of its object was dropped"));
            continue;
        };
        let (gl, gr) = pan_gains(p.pan);
        match p.quantity {
            Quantity::Displacement => {
                dl += &rows.disp * (p.gain * gl);
                dr += &rows.disp * (p.gain * gr);
            }
            Quantity::Velocity => {
                vl += &rows.vel * (p.gain * gl);
                vr += &rows.vel * (p.gain * gr);
            }
        }
    }

    let free_rows = PhaseRows {
        x_c: row_vec(&xc_f, &free_dec.v),
        v_c: row_vec(&vc_f, &free_dec.v),
        disp_l: row_vec(&dl, &free_dec.v),
        disp_r: row_vec(&dr, &free_dec.v),
        vel_l: row_vec(&vl, &free_dec.v),
        vel_r: row_vec(&vr, &free_dec.v),
        pi: Vec::new(),
        eta: Vec::new(),
    };
    let mut e_pi = DVector::zeros(dim_c);
    e_pi[lay.pi()] = 1.0;
    let mut e_eta = DVector::zeros(dim_c);
    e_eta[lay.eta()] = 1.0;
    let emb = |r: &DVector<f64>| lay.embed_row(r);
    let (xc_c, vc_c) = (emb(&xc_f), emb(&vc_f));
    let (dl_c, dr_c, vl_c, vr_c) = (emb(&dl), emb(&dr), emb(&vl), emb(&vr));
    let con_rows = PhaseRows {
        x_c: row_vec(&xc_c, &con_dec.v),
        v_c: row_vec(&vc_c, &con_dec.v),
        disp_l: row_vec(&dl_c, &con_dec.v),
        disp_r: row_vec(&dr_c, &con_dec.v),
        vel_l: row_vec(&vl_c, &con_dec.v),
        vel_r: row_vec(&vr_c, &con_dec.v),
        pi: row_vec(&e_pi, &con_dec.v),
        eta: row_vec(&e_eta, &con_dec.v),
    };
    let offsets = RowOffsets {
        x_c: xc_c.dot(&y_star),
        v_c: vc_c.dot(&y_star),
        disp_l: dl_c.dot(&y_star),
        disp_r: dr_c.dot(&y_star),
        pi: y_star[lay.pi()],
        eta: y_star[lay.eta()],
    };

    // --- changes of basis
    // E: z (object) -> y (contact)
    let mut emb_m = DMatrix::zeros(dim_c, dim_f);
    for j in 0..dim_f {
        emb_m[(lay.embed(j), j)] = 1.0;
    }
    use crate::physics::linalg::matmul;
    let w_cf = matmul(&matmul(&con_dec.vinv, &emb_m), &free_dec.v);
    let col_pi: Vec<f64> = (&con_dec.vinv * &e_pi).iter().cloned().collect();
    let col_eta: Vec<f64> = (&con_dec.vinv * &e_eta).iter().cloned().collect();
    let s_star_v = &con_dec.vinv * &y_star;
    let w_fc = matmul(&matmul(&free_dec.vinv, &emb_m.transpose()), &con_dec.v);
    let s_f_star: Vec<f64> = (&w_fc * &s_star_v).iter().cloned().collect();
    let s_star: Vec<f64> = s_star_v.iter().cloned().collect();

    let to_phase =
        |what: &str, d: PhaseDecomp, rows: PhaseRows| -> Result<CompiledPhase, CompileError> {
            let dim = d.v.nrows();
            let (gens, dense) = match d.form {
                Form::Blocks { gens } => (Some(gens), None),
                Form::Dense { a } => {
                    let phi = decomp::dense_exp(&a, h)
                        .map_err(|e| phase_error(what, &e, rate_hz, scene, ci))?;
                    // row-major for the engine's mat-vec
                    let flat: Vec<f64> = (0..dim)
                        .flat_map(|i| (0..dim).map(move |j| (i, j)))
                        .map(|(i, j)| phi[(i, j)])
                        .collect();
                    (None, Some((a, flat)))
                }
            };
            let osc = gens.as_deref().map(OscBlocks::of).unwrap_or_default();
            Ok(CompiledPhase {
                dim,
                gens,
                osc,
                dense,
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
                search: EventSearch::default(),
            })
        };
    let mut free = to_phase("free", free_dec, free_rows)?;
    let mut contact = to_phase("contact", con_dec, con_rows)?;
    let sk = params.k.sqrt();
    free.set_event_row(free.rows.x_c.iter().map(|x| -x).collect());
    contact.set_event_row(contact.rows.pi.iter().map(|x| x / sk).collect());
    // Exact switching needs partial steps exp(A tau) for any tau: O(N) in
    // blocks, but a Taylor series of mat-vecs for a dense fallback phase,
    // which is only affordable for small dense systems.
    let mut switching = switching;
    let mut switching_note = None;
    if switching == Switching::Exact {
        for ph in [&free, &contact] {
            let Some((a, _)) = &ph.dense else { continue };
            let norm_h = a.norm() * h;
            if ph.dim > MAX_DENSE_EXACT_DIM {
                switching = Switching::OffsetRod;
                switching_note = Some(format!(
                    "exact switching needs partial dense steps of dimension {} > {MAX_DENSE_EXACT_DIM}: using the offset rod",
                    ph.dim
                ));
            } else if !(norm_h <= MAX_DENSE_EXACT_NORM_H) {
                switching = Switching::OffsetRod;
                switching_note = Some(format!(
                    "exact switching needs partial dense steps with |A| h = {norm_h:.1e} > {MAX_DENSE_EXACT_NORM_H} (too many Taylor sub-steps): using the offset rod"
                ));
            }
        }
    }

    for (what, ph) in [("free", &free), ("contact", &contact)] {
        let all_finite = ph.v.iter().all(|x| x.is_finite())
            && ph.gens.iter().flatten().flatten().all(|x| x.is_finite());
        if !all_finite {
            return Err(CompileError(format!("{what} phase has non-finite entries")));
        }
    }
    for (what, ph) in [("free", &free), ("contact", &contact)] {
        let d = &ph.diag;
        let kappa = if ph.dense.is_some() || !d.kappa.is_finite() {
            1.0
        } else {
            d.kappa.max(1.0)
        };
        let tol = PASSIVITY_TOL_PER_DIM_KAPPA_U * ph.dim as f64 * kappa * (f64::EPSILON / 2.0);
        if !(d.sigma_max - 1.0 <= tol) {
            let norm_h = match &ph.dense {
                Some((a, _)) => a.norm() * h,
                None => {
                    ph.gens
                        .iter()
                        .flatten()
                        .map(|g| g.iter().map(|x| x * x).sum::<f64>().sqrt())
                        .fold(0.0, f64::max)
                        * h
                }
            };
            return Err(CompileError(format!(
                "{what} phase is not passive in f64 at {rate_hz} Hz: its one-sample propagator ({}) has largest singular value 1 + {:.1e} > 1 + {tol:.1e}, so stepping it could create energy. \
                 The phase is too stiff or too damped for this rate (|A| h = {norm_h:.1e}): {}",
                d.method,
                d.sigma_max - 1.0,
                stiffness_hint(what, scene, ci)
            )));
        }
    }
    if w_cf.iter().chain(w_fc.iter()).any(|x| !x.is_finite()) {
        return Err(CompileError(
            "change of basis has non-finite entries".into(),
        ));
    }

    let mut summary = String::new();
    let mut search_nodes_estimate = 0.0;
    {
        use std::fmt::Write;
        let kind = match spec {
            ObjectSpec::Modal(_) => "modal",
            ObjectSpec::String(_) => "string",
            ObjectSpec::Wall(_) => "wall",
        };
        let _ = writeln!(
            summary,
            "scene {:?} at {rate_hz} Hz, switching {}",
            scene.name,
            switching.as_str()
        );
        let _ = writeln!(
            summary,
            "struck object {:?} ({kind}, {n} degrees of freedom); hammer {} kg, g = {} m/s^2",
            obj.name, params.m_h, params.g
        );
        for (what, ph) in [("free", &free), ("contact", &contact)] {
            let d = &ph.diag;
            let _ = writeln!(
                summary,
                "{what} phase: dim {}, {}, residual {:.1e}, kappa(V) {}{:.2}, |V exp(Gh) V^-1 - exp(Ah)| {:.1e}, sigma_max(P) - 1 {} {:.1e}{}{}",
                d.dim,
                d.method,
                d.residual,
                if d.estimated { ">= " } else { "" },
                d.kappa,
                d.expm_rel_diff,
                if d.estimated { ">=" } else { "=" },
                d.sigma_max - 1.0,
                if d.estimated {
                    " (power-iteration estimates: dimension above the dense checks)"
                } else {
                    ""
                },
                d.fallback_reason
                    .as_ref()
                    .map(|r| format!(" (fallback: {r})"))
                    .unwrap_or_default()
            );
        }
        let _ = writeln!(
            summary,
            "gravity: {}",
            if params.g != 0.0 {
                "static-equilibrium shift in contact, parabola in flight"
            } else {
                "none (homogeneous stepping, no affine term)"
            }
        );
        if let Some(n) = &switching_note {
            let _ = writeln!(summary, "{n}");
        }
        if switching == Switching::Exact {
            // What the event search costs where a switch is near (see
            // docs/numerics.md): fast terms are evaluated on nodes no wider
            // than THETA_RESOLVED / |mu| while they can change the sign.
            let mut parts = Vec::new();
            let mut worst_nodes: f64 = 0.0;
            for (what, ph) in [("free", &free), ("contact", &contact)] {
                if ph.dense.is_some() {
                    parts.push(format!("{what}: dense ({} dims)", ph.dim));
                    continue;
                }
                let (slow, fast, top) = ph.search.split_at(h);
                worst_nodes = worst_nodes.max((top / event::THETA_RESOLVED).ceil());
                parts.push(format!(
                    "{what}: {slow} slow terms in one polynomial, {fast} fast (fastest |mu| h = {top:.1}), {} whole blocks",
                    ph.search.whole.len()
                ));
            }
            search_nodes_estimate = worst_nodes;
            let _ = writeln!(
                summary,
                "event search: {}; near a switch it examines up to ~{worst_nodes:.0} nodes per sample to resolve the fast terms, plus up to {:.0} per tangency (estimate; each node costs the fast terms and the polynomial)",
                parts.join("; "),
                event::NODES_PER_ROOT
            );
        }
        let n_total = match &scene.object[ci] {
            ObjectSpec::Modal(m) => m.mode.len(),
            _ => n,
        };
        let _ = writeln!(
            summary,
            "modes: {n} kept of {n_total}; {} outside the contact eigenproblem (zero weight at the contact point)",
            uncoupled.len()
        );
        for d in &dropped_modes {
            let _ = writeln!(summary, "dropped {d}");
        }
        if params.c == 0.0 {
            let _ = writeln!(summary, "contact damping 0: no velocity coupling term");
        }
        for d in &dropped_pickups {
            let _ = writeln!(summary, "dropped {d}");
        }
        let cost = |ph: &CompiledPhase| match (&ph.gens, &ph.dense) {
            (Some(_), _) => format!("{} blocks (~{} flops/sample)", ph.dim / 2, ph.dim * 5),
            (_, Some(_)) => format!(
                "dense {0}x{0} (~{1} flops/sample)",
                ph.dim,
                2 * ph.dim * ph.dim
            ),
            _ => "empty".into(),
        };
        let _ = writeln!(
            summary,
            "cost: free {}, contact {}, switch ~{} flops",
            cost(&free),
            cost(&contact),
            2 * dim_c * dim_f
        );
    }

    Ok(CompiledScene {
        name: scene.name.clone(),
        rate_hz,
        h,
        switching,
        m_h: params.m_h,
        g: params.g,
        hammer_x0: scene.hammer.height_m,
        hammer_v0: scene.hammer.velocity_m_per_s,
        k: params.k,
        sk: params.k.sqrt(),
        c: params.c,
        sm: params.m_h.sqrt(),
        free,
        contact,
        w_cf,
        col_pi,
        col_eta,
        s_star,
        w_fc,
        s_f_star,
        offsets,
        summary,
        search_nodes_estimate,
    })
}
