//! Stage 2 of the compiler: the rows the engine evaluates per sample (the
//! contact point, the mixed pickups, and in contact the spring and hammer
//! coordinates), each written over its phase's coordinates, so an output is
//! one dot product with the state (docs/numerics.md, "Leaving out what a
//! scene does not need").

use super::routes::{Decomposed, Object};
use crate::physics::model::ContactLayout;
use crate::scene::{Quantity, Scene};
use nalgebra::{DMatrix, DVector};

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

/// What this stage hands on.
pub(super) struct Rows {
    /// Free-phase rows.
    pub free: PhaseRows,
    /// Contact-phase rows.
    pub contact: PhaseRows,
    /// Offsets of the contact rows.
    pub offsets: RowOffsets,
    /// Pickups left out, with why (for the summary).
    pub dropped_pickups: Vec<String>,
}

/// Constant-power pan law: gains (left, right) for pan in [-1, 1].
pub fn pan_gains(pan: f64) -> (f64, f64) {
    let theta = (pan + 1.0) * std::f64::consts::FRAC_PI_4;
    (theta.cos(), theta.sin())
}

/// `row . V` (a row over energy coordinates to one over phase coordinates).
fn row_vec(row: &DVector<f64>, v: &DMatrix<f64>) -> Vec<f64> {
    (0..v.ncols()).map(|j| row.dot(&v.column(j))).collect()
}

/// The pickups mixed per channel over the object's energy coordinates:
/// `(disp_l, disp_r, vel_l, vel_r)`, and the pickups left out. Only the
/// struck object is ever excited: a pickup elsewhere is silent forever and
/// is left out (an exact saving).
fn mixed_pickups(scene: &Scene, o: &Object) -> ([DVector<f64>; 4], Vec<String>) {
    let zero = DVector::zeros(2 * o.obj.n);
    let (mut dl, mut dr, mut vl, mut vr) = (zero.clone(), zero.clone(), zero.clone(), zero);
    let mut dropped = Vec::new();
    // a mallet joined to the struck model in stage 1 (a lumped string's)
    let mallet = scene.hammer.object.as_deref();
    for (i, p) in scene.pickup.iter().enumerate() {
        let point = if Some(p.object.as_str()) == mallet {
            format!("{}.{}", p.object, p.point)
        } else if p.object == scene.contact.object {
            p.point.clone()
        } else {
            dropped.push(format!(
                "pickup[{i}] on {:?}: object never excited",
                p.object
            ));
            continue;
        };
        let Some(rows) = o.obj.point(&point) else {
            dropped.push(format!("pickup[{i}]: every mode of its object was dropped"));
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
            // none in an expanded scene: each became a displacement and a
            // velocity pickup (`Scene::expanded`)
            Quantity::Pressure => {}
        }
    }
    ([dl, dr, vl, vr], dropped)
}

/// Unit row selecting coordinate `i` of a contact state of `lay`.
pub(super) fn unit(lay: &ContactLayout, i: usize) -> DVector<f64> {
    let mut e = DVector::zeros(lay.dim());
    e[i] = 1.0;
    e
}

/// Build every row of both phases; `y_star` is the contact phase's static
/// equilibrium (zero without gravity), whose rows become the offsets.
pub(super) fn build(scene: &Scene, o: &Object, d: &Decomposed, y_star: &DVector<f64>) -> Rows {
    let lay = &d.lay;
    let zero_f = DVector::zeros(2 * o.obj.n);
    let xc_f = o
        .contact_rows
        .as_ref()
        .map_or(zero_f.clone(), |r| r.disp.clone());
    let vc_f = o.contact_rows.as_ref().map_or(zero_f, |r| r.vel.clone());
    let ([dl, dr, vl, vr], dropped_pickups) = mixed_pickups(scene, o);
    let fv = &d.free.v;
    let free = PhaseRows {
        x_c: row_vec(&xc_f, fv),
        v_c: row_vec(&vc_f, fv),
        disp_l: row_vec(&dl, fv),
        disp_r: row_vec(&dr, fv),
        vel_l: row_vec(&vl, fv),
        vel_r: row_vec(&vr, fv),
        pi: Vec::new(),
        eta: Vec::new(),
    };
    let (e_pi, e_eta) = (unit(lay, lay.pi()), unit(lay, lay.eta()));
    let emb = |r: &DVector<f64>| lay.embed_row(r);
    let (xc_c, vc_c) = (emb(&xc_f), emb(&vc_f));
    let (dl_c, dr_c, vl_c, vr_c) = (emb(&dl), emb(&dr), emb(&vl), emb(&vr));
    let cv = &d.contact.v;
    let contact = PhaseRows {
        x_c: row_vec(&xc_c, cv),
        v_c: row_vec(&vc_c, cv),
        disp_l: row_vec(&dl_c, cv),
        disp_r: row_vec(&dr_c, cv),
        vel_l: row_vec(&vl_c, cv),
        vel_r: row_vec(&vr_c, cv),
        pi: row_vec(&e_pi, cv),
        eta: row_vec(&e_eta, cv),
    };
    let offsets = RowOffsets {
        x_c: xc_c.dot(y_star),
        v_c: vc_c.dot(y_star),
        disp_l: dl_c.dot(y_star),
        disp_r: dr_c.dot(y_star),
        pi: y_star[lay.pi()],
        eta: y_star[lay.eta()],
    };
    Rows {
        free,
        contact,
        offsets,
        dropped_pickups,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compile::compile_one;

    fn scene(pickups: &str) -> Scene {
        Scene::from_toml_str(&format!(
            "version = 1\nname = \"t\"\n[[object]]\nname = \"o\"\nkind = \"modal\"\npoints = [\"c\", \"p\"]\n\
             [[object.mode]]\nfreq_hz = 300.0\nweights = [1.0, 0.5]\n\
             [[object.mode]]\nfreq_hz = 700.0\nweights = [0.8, -0.25]\n\
             [[object]]\nname = \"other\"\nkind = \"modal\"\npoints = [\"p\"]\n[[object.mode]]\nfreq_hz = 500.0\nweights = [1.0]\n\
             [hammer]\nmass_kg = 0.01\nheight_m = 0.001\nvelocity_m_per_s = -1.0\n\
             [contact]\nobject = \"o\"\npoint = \"c\"\nstiffness_n_per_m = 1e6\ndamping_n_s_per_m = 5.0\n{pickups}"
        ))
        .unwrap()
    }

    /// The free phase's event row is `-x_c` entry for entry, on every
    /// preset (the observed block path takes the contact point's motion in
    /// flight from the engine's own event sums: src/engine/fast_path.rs,
    /// `run_kernel_rows`).
    #[test]
    fn free_event_row_is_minus_the_contact_row() {
        for i in crate::presets::one_contact() {
            let sc = compile_one(&crate::presets::scene(i).unwrap(), 44100.0).unwrap();
            let (ev, xc) = (&sc.free.ev, &sc.free.rows.x_c);
            assert_eq!(ev.len(), xc.len());
            assert!(xc.iter().any(|&x| x != 0.0));
            for (e, x) in ev.iter().zip(xc) {
                assert_eq!(e.to_bits(), (-x).to_bits(), "preset {i}");
            }
        }
    }

    /// The pan law keeps the power: gl^2 + gr^2 = 1, centre equal.
    #[test]
    fn pan_law_is_constant_power() {
        for pan in [-1.0, -0.3, 0.0, 0.6, 1.0] {
            let (l, r) = pan_gains(pan);
            assert!((l * l + r * r - 1.0).abs() < 1e-15);
        }
        let (l, r) = pan_gains(0.0);
        assert!((l - r).abs() < 1e-15);
        assert!((pan_gains(-1.0).1).abs() < 1e-16);
    }

    /// A displacement pickup's row reads the modes' displacement at the
    /// pickup point, times its gain: mode i at unit modal displacement
    /// (`xi_i = omega_i`) gives `weight * gain`; a pickup on an object that
    /// is never struck is left out and said so.
    #[test]
    fn pickup_rows_read_the_point_and_unstruck_objects_are_dropped() {
        let sc = compile_one(
            &scene(
                "[[pickup]]\nobject = \"o\"\npoint = \"p\"\nquantity = \"displacement\"\ngain = 2.0\npan = -1.0\n\
                 [[pickup]]\nobject = \"other\"\npoint = \"p\"\n",
            ),
            44100.0,
        )
        .unwrap();
        let r = &sc.free.rows;
        // free coordinates of a modal object: s[k] = omega_k q_k
        let w = [
            2.0 * std::f64::consts::PI * 300.0,
            2.0 * std::f64::consts::PI * 700.0,
        ];
        for (k, want) in [(0, 0.5 * 2.0), (1, -0.25 * 2.0)] {
            let got = r.disp_l[k] * w[k];
            assert!((got - want).abs() < 1e-12, "mode {k}: {got} vs {want}");
            assert!(r.disp_r[k].abs() < 1e-15, "panned hard left");
        }
        assert!(r.vel_l.iter().all(|&x| x == 0.0));
        assert!(
            sc.summary
                .contains("pickup[1] on \"other\": object never excited"),
            "{}",
            sc.summary
        );
    }
}
