//! Stage 6 of the compiler: the human-readable summary of what was built
//! (printed by the render command, logged by the plugin), and the estimate
//! of the exact event search's cost that comes with it.

use super::event::{NODES_PER_ROOT, THETA_RESOLVED};
use super::CompiledPhase;
use crate::physics::model::ContactParams;
use crate::scene::{ObjectSpec, Scene, Switching};
use std::fmt::Write;

/// Everything the summary reports.
pub(super) struct Facts<'a> {
    pub scene: &'a Scene,
    pub ci: usize,
    pub rate_hz: f64,
    pub switching: Switching,
    pub switching_note: Option<&'a str>,
    pub object_name: &'a str,
    /// Degrees of freedom kept.
    pub n: usize,
    pub kind: &'static str,
    pub params: &'a ContactParams,
    pub free: &'a CompiledPhase,
    pub contact: &'a CompiledPhase,
    pub uncoupled: usize,
    pub dropped_modes: &'a [String],
    pub dropped_pickups: &'a [String],
    /// A modal mallet's name and how many modes of it joined the struck
    /// object's (docs/design.md, "Modal mallets").
    pub mallet: Option<(&'a str, usize)>,
}

fn phase_line(what: &str, ph: &CompiledPhase) -> String {
    let d = &ph.diag;
    // the diagnostics mark a check that was not made with NaN (a closed
    // form's exact 2x2 exponentials are not compared with a dense one)
    let checked = |x: f64| {
        if x.is_nan() {
            "not computed".to_string()
        } else {
            format!("{x:.1e}")
        }
    };
    format!(
        "{what} phase: dim {}, {}, residual {}, kappa(V) {}{:.2}, |V exp(Gh) V^-1 - exp(Ah)| {}, sigma_max(P) - 1 {} {:.1e}{}{}",
        d.dim,
        d.method,
        checked(d.residual),
        if d.estimated { ">= " } else { "" },
        d.kappa,
        checked(d.expm_rel_diff),
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
    )
}

/// The event search's cost: one line for the summary and the estimated
/// nodes per sample to resolve the fastest terms (docs/numerics.md, "Why
/// it terminates, and what it costs"): fast terms are evaluated on nodes no
/// wider than `THETA_RESOLVED / |mu|` while they can change the sign.
fn search_line(f: &Facts) -> (String, f64) {
    let h = 1.0 / f.rate_hz;
    let mut parts = Vec::new();
    let mut worst_nodes: f64 = 0.0;
    for (what, ph) in [("free", f.free), ("contact", f.contact)] {
        if ph.dense.is_some() {
            parts.push(format!("{what}: dense ({} dims)", ph.dim));
            continue;
        }
        let (slow, fast, top) = ph.search.split_at(h);
        worst_nodes = worst_nodes.max((top / THETA_RESOLVED).ceil());
        parts.push(format!(
            "{what}: {slow} slow terms in one polynomial, {fast} fast (fastest |mu| h = {top:.1}), {} whole blocks",
            ph.search.whole.len()
        ));
    }
    let line = format!(
        "event search: {}; near a switch it examines up to ~{worst_nodes:.0} nodes per sample to resolve the fast terms, plus up to {NODES_PER_ROOT:.0} per tangency (estimate; each node costs the fast terms and the polynomial)",
        parts.join("; ")
    );
    (line, worst_nodes)
}

/// The summary text and the event search's estimated nodes per sample (0
/// with the offset rod).
pub(super) fn write(f: &Facts) -> (String, f64) {
    let mut s = String::new();
    let p = f.params;
    let _ = writeln!(
        s,
        "scene {:?} at {} Hz, switching {}",
        f.scene.name,
        f.rate_hz,
        f.switching.as_str()
    );
    let mallet = f.mallet.map_or(String::new(), |(name, k)| {
        format!(", a modal mallet ({name:?}: its {k} modes joined to the struck object's)")
    });
    let _ = writeln!(
        s,
        "struck object {:?} ({}, {} degrees of freedom); hammer {} kg{mallet}, g = {} m/s^2",
        f.object_name, f.kind, f.n, p.m_h, p.g
    );
    let _ = writeln!(s, "{}", phase_line("free", f.free));
    let _ = writeln!(s, "{}", phase_line("contact", f.contact));
    let _ = writeln!(
        s,
        "gravity: {}",
        if p.g != 0.0 {
            "static-equilibrium shift in contact, parabola in flight"
        } else {
            "none (homogeneous stepping, no affine term)"
        }
    );
    if let Some(n) = f.switching_note {
        let _ = writeln!(s, "{n}");
    }
    let mut nodes = 0.0;
    if f.switching == Switching::Exact {
        let (line, n) = search_line(f);
        nodes = n;
        let _ = writeln!(s, "{line}");
    }
    let n_total = match &f.scene.object[f.ci] {
        ObjectSpec::Modal(m) => m.mode.len(),
        _ => f.n,
    };
    let _ = writeln!(
        s,
        "modes: {} kept of {n_total}; {} outside the contact eigenproblem (zero weight at the contact point)",
        f.n, f.uncoupled
    );
    for d in f.dropped_modes {
        let _ = writeln!(s, "dropped {d}");
    }
    if p.c == 0.0 {
        let _ = writeln!(s, "contact damping 0: no velocity coupling term");
    }
    for d in f.dropped_pickups {
        let _ = writeln!(s, "dropped {d}");
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
        s,
        "cost: free {}, contact {}, switch ~{} flops",
        cost(f.free),
        cost(f.contact),
        2 * f.contact.dim * f.free.dim
    );
    (s, nodes)
}

/// The summary's line on strikes from rest ([`super::rest`]).
pub(super) fn rest_line(rest: Option<&super::rest::RestStrike>, h: f64) -> String {
    match rest {
        Some(r) => {
            let later = match r.later.last() {
                None => format!(
                    "no later switch stored (none within {:.0} ms, or a flight whose energy \
                     is not block-diagonal)",
                    super::rest::REST_SEQ_T_MAX_S * 1e3
                ),
                Some(last) => format!(
                    "then {} more switches stored, O(N) too (the hammer meets the object again; \
                     up to {:.2} ms after the first entry)",
                    r.later.len(),
                    last.t * 1e3
                ),
            };
            format!(
                "strike from rest: contact {:.4} ms ({:.2} samples), both switches O(N); {later}\n",
                r.t_r * 1e3,
                r.t_r / h
            )
        }
        None => "strike from rest: not precomputed (affine or dense contact, or a contact \
                 longer than 1 s): switches take the dense products\n"
            .into(),
    }
}

/// The summary's line on the switches' changes of basis: hierarchical
/// with its size, ranks and measured check, or dense and why.
pub(super) fn structured_line(
    forms: [&Result<crate::physics::hodlr::Hodlr, String>; 2],
    dense: usize,
) -> String {
    let parts: Vec<String> = ["W_cf", "W_fc"]
        .iter()
        .zip(forms)
        .map(|(name, form)| match form {
            Ok(h) => format!(
                "{name} hierarchical ({:.0} % of the dense entries, ranks <= {}, \
                 within {:.1} u |W| |x| of the dense product)",
                100.0 * h.stored() as f64 / dense as f64,
                h.max_rank,
                h.check_u
            ),
            Err(why) => format!("{name} dense ({why})"),
        })
        .collect();
    format!("changes of basis: {}\n", parts.join("; "))
}
