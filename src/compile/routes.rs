//! Stage 1 of the compiler: the struck object's model and the route each
//! phase takes to its block decomposition (docs/numerics.md, "Decomposing a
//! phase"):
//!
//! - free phase: a modal object's closed-form blocks, or the general
//!   eigensolver (strings);
//! - contact phase: modes with zero weight at the contact point stay out of
//!   the eigenproblem (exactly decoupled); the coupled part of a modal object
//!   takes the rank-one secular route, checked like any decomposition, and
//!   the general eigensolver takes over when it fails, within the budget;
//!   near-defective systems get the dense fallback.

use super::budget::CompileCost;
use super::error::{stiffness_hint, CompileError, PhaseKind};
use super::CompileOptions;
use crate::physics::decomp::{self, BlockEigen, PhaseDecomp};
use crate::physics::model::{contact_system, ContactLayout, ContactParams, ObjectModel, PointRows};
use crate::physics::{secular, DecompError, SecularError};
use crate::scene::{ObjectSpec, Scene};
use nalgebra::{DMatrix, DVector};

/// The struck object, its contact point and the contact law.
pub(super) struct Object {
    /// The model of the (pruned) struck object.
    pub obj: ObjectModel,
    /// The contact point's rows (`None`: a wall).
    pub contact_rows: Option<PointRows>,
    /// Contact stiffness, damping, hammer mass and gravity.
    pub params: ContactParams,
}

/// Build the struck object's model and find its contact point.
pub(super) fn object(scene: &Scene, spec: &ObjectSpec, ci: usize) -> Result<Object, CompileError> {
    let model = |spec: &ObjectSpec, object: usize| {
        ObjectModel::from_spec(spec).map_err(|source| CompileError::Model {
            object,
            name: spec.name().to_string(),
            source,
        })
    };
    let mut obj = model(spec, ci)?;
    // A modal object whose every mode was pruned is a rigid wall: it has no
    // points, and the hammer meets it as a wall (the scene fuzzer found
    // `[approximate] max_freq_hz` below every mode giving "no point c").
    let mut contact_point = match spec {
        ObjectSpec::Wall(_) => None,
        _ => scene.contact.point.clone(),
    };
    // a modal mallet still named here strikes a lumped string (stage 0
    // joined it to every modal object): join the models
    if let (Some(m), Some(tip), Some(p)) = (
        scene.hammer.object.as_deref(),
        scene.hammer.point.as_deref(),
        contact_point.clone(),
    ) {
        let mi = scene
            .object_index(m)
            .ok_or_else(|| CompileError::MissingObject(m.to_string()))?;
        let name = crate::scene::mallet_contact_point(&p, m, tip);
        obj = obj
            .joined_with_mallet(&model(&scene.object[mi], mi)?, &p, tip, &name)
            .ok_or_else(|| CompileError::MissingPoint(name.clone()))?;
        contact_point = Some(name);
    }
    let contact_rows = match &contact_point {
        Some(p) => Some(
            obj.point(p)
                .ok_or_else(|| CompileError::MissingPoint(p.clone()))?
                .clone(),
        ),
        None => None,
    };
    let params = ContactParams {
        k: scene.contact.stiffness_n_per_m,
        c: scene.contact.damping_n_s_per_m,
        m_h: scene.hammer.mass_kg,
        g: scene.hammer.gravity_m_per_s2,
    };
    Ok(Object {
        obj,
        contact_rows,
        params,
    })
}

/// What the decomposition stage hands on.
pub(super) struct Decomposed {
    /// Free phase of the object.
    pub free: PhaseDecomp,
    /// Contact phase of object, spring and hammer.
    pub contact: PhaseDecomp,
    /// The contact generator, its forcing (gravity) and its layout.
    pub a_c: DMatrix<f64>,
    /// See `a_c`.
    pub f_c: DVector<f64>,
    /// See `a_c`.
    pub lay: ContactLayout,
    /// Modes outside the contact eigenproblem (zero weight at the contact).
    pub uncoupled: Vec<usize>,
}

/// The decomposition failure of a phase, with what to change in the scene.
fn phase_error(
    phase: PhaseKind,
    source: DecompError,
    rate_hz: f64,
    scene: &Scene,
    ci: usize,
) -> CompileError {
    CompileError::Decomposition {
        phase,
        hint: stiffness_hint(phase, scene, ci),
        source,
        rate_hz,
    }
}

/// Decompose both phases. `cost` is the budget estimate (a failed secular
/// route may fall back to the general eigensolver only if that fits too).
pub(super) fn decompose(
    scene: &Scene,
    ci: usize,
    o: &Object,
    rate_hz: f64,
    cost: &CompileCost,
    opts: &CompileOptions,
) -> Result<Decomposed, CompileError> {
    let h = 1.0 / rate_hz;
    let obj = &o.obj;
    let n = obj.n;
    let free = match &obj.modal_blocks {
        Some(blocks) => {
            let pairs: Vec<(usize, usize)> = (0..n).map(|i| (i, n + i)).collect();
            decomp::from_blocks(blocks.clone(), &pairs, 2 * n, h)
        }
        None => decomp::decompose(&obj.a, h)
            .map_err(|e| phase_error(PhaseKind::Free, e, rate_hz, scene, ci))?,
    };
    let (a_c, f_c, lay) = contact_system(obj, o.contact_rows.as_ref().map(|r| &r.vel), &o.params);
    // Exact saving: modes with zero weight at the contact point are exactly
    // decoupled from the contact; only the coupled part is diagonalised.
    let uncoupled: Vec<usize> = match (&obj.modal_blocks, &o.contact_rows) {
        (Some(_), Some(rows)) if opts.exact_savings => {
            (0..n).filter(|&i| rows.vel[n + i] == 0.0).collect()
        }
        _ => Vec::new(),
    };
    let contact = contact_phase(scene, ci, o, &a_c, &lay, &uncoupled, rate_hz, cost, opts)?;
    Ok(Decomposed {
        free,
        contact,
        a_c,
        f_c,
        lay,
        uncoupled,
    })
}

/// The rank-one secular route for a modal object struck at one point (its
/// contact system is a rank-one update of diagonal modes, decomposed in
/// O(N^2)), on the coupled modes; `None` for other objects.
fn secular_route(
    o: &Object,
    uncoupled: &[usize],
) -> Option<(&'static str, Result<BlockEigen, SecularError>)> {
    let obj = &o.obj;
    let n = obj.n;
    let blocks = obj.modal_blocks.as_ref()?;
    let f_all: Vec<f64> = match &o.contact_rows {
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
        k: o.params.k,
        c: o.params.c,
        m_h: o.params.m_h,
    };
    Some(("rank-one secular eigenvectors", secular::decompose(&mc)))
}

/// The contact phase's decomposition (see the module doc for the routes).
#[allow(clippy::too_many_arguments)]
fn contact_phase(
    scene: &Scene,
    ci: usize,
    o: &Object,
    a_c: &DMatrix<f64>,
    lay: &ContactLayout,
    uncoupled: &[usize],
    rate_hz: f64,
    cost: &CompileCost,
    opts: &CompileOptions,
) -> Result<PhaseDecomp, CompileError> {
    let h = 1.0 / rate_hz;
    let obj = &o.obj;
    let n = obj.n;
    let general_ok = cost.general_fits(&opts.budget);
    let contact_error = |e: DecompError| match e {
        DecompError::GeneralOverBudget { refused } => CompileError::GeneralOverBudget {
            refused: *refused,
            flops: cost.general().flops,
            bytes: cost.general().bytes,
        },
        e => phase_error(PhaseKind::Contact, e, rate_hz, scene, ci),
    };
    if uncoupled.is_empty() {
        return decomp::decompose_via(a_c, h, secular_route(o, uncoupled), general_ok)
            .map_err(contact_error);
    }
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
    let split = decomp::decompose_split(
        a_c,
        &coupled,
        &pairs,
        &gens,
        h,
        secular_route(o, uncoupled),
        general_ok,
    )
    .map_err(contact_error)?;
    match split {
        Some(d) => Ok(d),
        None => {
            // The coupled part needs the dense fallback: the whole contact
            // system is decomposed instead, which the estimate did not count.
            let whole = CompileCost::from_dims(n, n, false, lay.dim(), o.params.g != 0.0, false);
            whole
                .check(&opts.budget, scene, ci)
                .map_err(CompileError::OverBudget)?;
            decomp::decompose(a_c, h).map_err(contact_error)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::decomp::Form;

    fn scene(text: &str) -> Scene {
        Scene::from_toml_str(text).unwrap()
    }

    fn modal(weights: &[f64]) -> Scene {
        let mut t = String::from(
            "version = 1\nname = \"t\"\n[[object]]\nname = \"o\"\nkind = \"modal\"\npoints = [\"c\"]\n",
        );
        for (i, w) in weights.iter().enumerate() {
            t += &format!(
                "[[object.mode]]\nfreq_hz = {}\nt60_s = 1.0\nweights = [{w}]\n",
                200.0 * (i + 1) as f64
            );
        }
        t += "[hammer]\nmass_kg = 0.01\nheight_m = 0.0\nvelocity_m_per_s = -1.0\n\
              [contact]\nobject = \"o\"\npoint = \"c\"\nstiffness_n_per_m = 1e6\ndamping_n_s_per_m = 5.0\n";
        scene(&t)
    }

    fn run(sc: &Scene) -> Decomposed {
        let ci = 0;
        let o = object(sc, &sc.object[ci], ci).unwrap();
        let cost = CompileCost::estimate(&sc.object[ci], Some("c"), false, true);
        decompose(sc, ci, &o, 44100.0, &cost, &CompileOptions::default()).unwrap()
    }

    /// A modal object's free phase is its closed-form blocks; its contact
    /// phase takes the secular route.
    #[test]
    fn modal_object_takes_closed_form_and_secular_routes() {
        let d = run(&modal(&[1.0, 0.7, 0.4]));
        assert_eq!(d.free.diag.method, "closed-form modal blocks");
        assert!(matches!(d.free.form, Form::Blocks { .. }));
        assert_eq!(d.contact.diag.method, "rank-one secular eigenvectors");
        assert!(d.uncoupled.is_empty());
    }

    /// A mode at a node of the contact point stays out of the contact
    /// eigenproblem, as its own closed-form block.
    #[test]
    fn node_modes_stay_outside_the_contact_eigenproblem() {
        let d = run(&modal(&[1.0, 0.0, 0.4]));
        assert_eq!(d.uncoupled, vec![1]);
        assert!(
            d.contact
                .diag
                .method
                .contains("1 decoupled closed-form modes"),
            "{}",
            d.contact.diag.method
        );
    }

    /// A wall: the contact phase is one 2x2 block.
    #[test]
    fn wall_contact_is_one_block() {
        let sc = scene(
            "version = 1\nname = \"w\"\n[[object]]\nname = \"f\"\nkind = \"wall\"\n\
             [hammer]\nmass_kg = 0.01\nheight_m = 0.0\nvelocity_m_per_s = -1.0\n\
             [contact]\nobject = \"f\"\nstiffness_n_per_m = 1e6\ndamping_n_s_per_m = 200.0\n",
        );
        let o = object(&sc, &sc.object[0], 0).unwrap();
        assert!(o.contact_rows.is_none());
        let cost = CompileCost::estimate(&sc.object[0], None, false, true);
        let d = decompose(&sc, 0, &o, 44100.0, &cost, &CompileOptions::default()).unwrap();
        assert_eq!(d.contact.v.nrows(), 2);
        assert!(d.contact.diag.method.contains("one 2x2 block"));
    }
}
