//! Modal mallets (docs/design.md, "Modal mallets"): a hammer whose own
//! elastic modes take part in the contact.
//!
//! A mallet is a rigid-body motion (the hammer's `mass_kg`, height and
//! velocity, gravity) plus the free modes of a modal object of the scene,
//! mass-normalised and orthogonal to the rigid motion, so its contact face
//! is at `x_h + sum_k psi_k a_k` with `psi_k` the modes' weights at the
//! touching point. The penetration is then
//!
//! `p = sum_i w_i q_i - sum_k psi_k a_k - x_h`,
//!
//! and the contact force `F` acts with `-w_i F` on the struck modes and
//! `+psi_k F` on the mallet's: exactly what a mode of the struck object
//! with contact weight `-psi_k` feels. So the mallet's modes join the
//! struck object's as more modes, with weight `-psi_k` at the contact and
//! zero at the struck object's own points: the contact is still a rank-one
//! update of a diagonal free system, and every route the compiler has for
//! a modal object (the secular equation, the structured changes of basis,
//! the strike at rest) serves it unchanged. Gravity does no work on the
//! mallet's elastic modes (they are orthogonal to the rigid motion), so it
//! stays on `x_h` alone.

use super::error::{check_max, check_min, check_non_negative, check_positive, SceneError};
use super::limits::{
    MAX_FREQ_HZ, MAX_MASS_KG, MAX_MODES_PER_OBJECT, MAX_RAYLEIGH_ALPHA_PER_S, MAX_RAYLEIGH_BETA_S,
    MAX_STIFFNESS_N_PER_M, MIN_FREQ_HZ, MIN_MASS_KG,
};
use super::{ModalSpec, ModeSpec, ObjectSpec, Scene};
use crate::bodies::chain::free_chain_modes;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Most masses in a chain (a mallet needs a handful).
pub const MAX_CHAIN_MASSES: usize = 64;

/// A free lumped chain, `kind = "chain"`: masses in a line joined by
/// springs, free at both ends, with Rayleigh damping `C = alpha M + beta
/// K`. A mallet's head and shaft: it may only be `hammer.object`, whose
/// `mass_kg` must then be the chain's total mass (its rigid motion). Its
/// elastic modes come from [`free_chain_modes`]; each decays at `sigma_j =
/// (alpha + beta omega_j^2) / 2` (Rayleigh damping keeps the modes real).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainSpec {
    /// Object name.
    pub name: String,
    /// The masses from one end to the other \[kg\].
    pub masses_kg: Vec<f64>,
    /// The springs between neighbours \[N/m\] (one fewer than masses).
    pub springs_n_per_m: Vec<f64>,
    /// Rayleigh damping, mass part \[1/s\].
    #[serde(default)]
    pub rayleigh_alpha_per_s: f64,
    /// Rayleigh damping, stiffness part \[s\].
    #[serde(default)]
    pub rayleigh_beta_s: f64,
    /// Named points: 0-based mass indices.
    pub points: BTreeMap<String, usize>,
}

impl ChainSpec {
    /// Total mass \[kg\].
    pub fn mass_kg(&self) -> f64 {
        self.masses_kg.iter().sum()
    }

    pub(super) fn validate(&self, base: &str) -> Result<(), SceneError> {
        let n = self.masses_kg.len();
        if !(2..=MAX_CHAIN_MASSES).contains(&n) {
            return Err(SceneError::new(
                format!("{base}.masses_kg"),
                format!("a chain has 2..={MAX_CHAIN_MASSES} masses, got {n}"),
            ));
        }
        for (i, &m) in self.masses_kg.iter().enumerate() {
            let path = format!("{base}.masses_kg[{i}]");
            check_positive(&path, m)?;
            check_min(&path, m, MIN_MASS_KG)?;
            check_max(&path, m, MAX_MASS_KG)?;
        }
        if self.springs_n_per_m.len() + 1 != n {
            return Err(SceneError::new(
                format!("{base}.springs_n_per_m"),
                format!(
                    "{n} masses need {} springs between them, got {}",
                    n - 1,
                    self.springs_n_per_m.len()
                ),
            ));
        }
        for (i, &k) in self.springs_n_per_m.iter().enumerate() {
            let path = format!("{base}.springs_n_per_m[{i}]");
            check_positive(&path, k)?;
            check_max(&path, k, MAX_STIFFNESS_N_PER_M)?;
        }
        check_non_negative(
            &format!("{base}.rayleigh_alpha_per_s"),
            self.rayleigh_alpha_per_s,
        )?;
        check_max(
            &format!("{base}.rayleigh_alpha_per_s"),
            self.rayleigh_alpha_per_s,
            MAX_RAYLEIGH_ALPHA_PER_S,
        )?;
        check_non_negative(&format!("{base}.rayleigh_beta_s"), self.rayleigh_beta_s)?;
        check_max(
            &format!("{base}.rayleigh_beta_s"),
            self.rayleigh_beta_s,
            MAX_RAYLEIGH_BETA_S,
        )?;
        for (name, &j) in &self.points {
            if name.is_empty() || j >= n {
                return Err(SceneError::new(
                    format!("{base}.points.{name}"),
                    format!("must name a mass index in 0..{n}, got {j}"),
                ));
            }
        }
        // the modes must lie where a modal object's may
        let modes = free_chain_modes(&self.masses_kg, &self.springs_n_per_m);
        let f = |m: &crate::bodies::chain::ChainMode| m.omega / (2.0 * std::f64::consts::PI);
        if let (Some(lo), Some(hi)) = (modes.first().map(f), modes.last().map(f)) {
            if !(lo >= MIN_FREQ_HZ && hi <= MAX_FREQ_HZ) {
                return Err(SceneError::new(
                    format!("{base}.springs_n_per_m"),
                    format!(
                        "the chain's modes lie at {lo:.3e}..{hi:.3e} Hz, outside {MIN_FREQ_HZ:e}..{MAX_FREQ_HZ:e} Hz"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The chain's elastic modes as a modal object (the rigid translation
    /// left to the hammer).
    pub fn to_modal(&self) -> ModalSpec {
        let modes = free_chain_modes(&self.masses_kg, &self.springs_n_per_m);
        let points: Vec<(&String, usize)> = self.points.iter().map(|(n, &j)| (n, j)).collect();
        ModalSpec {
            name: self.name.clone(),
            points: points.iter().map(|(n, _)| (*n).clone()).collect(),
            mode: modes
                .iter()
                .map(|md| {
                    let sigma = 0.5
                        * (self.rayleigh_alpha_per_s + self.rayleigh_beta_s * md.omega * md.omega);
                    ModeSpec {
                        freq_hz: md.omega / (2.0 * std::f64::consts::PI),
                        t60_s: (sigma > 0.0).then(|| 1000f64.ln() / sigma),
                        weights: points.iter().map(|&(_, j)| md.shape[j]).collect(),
                    }
                })
                .collect(),
        }
    }
}

/// The name of the contact point a mallet's join gives the struck object:
/// `"<point> against <mallet>.<tip>"`.
pub fn mallet_contact_point(point: &str, mallet: &str, tip: &str) -> String {
    format!("{point} against {mallet}.{tip}")
}

impl Scene {
    /// The mallet's keys: `hammer.object` names a modal object (or one
    /// from geometry and material) other than the struck one, which must be
    /// one of those too, and `hammer.point` one of its points.
    pub(super) fn validate_mallet(&self) -> Result<(), SceneError> {
        let h = &self.hammer;
        if let Some(ci) = self.object_index(&self.contact.object) {
            if matches!(self.object[ci], ObjectSpec::Chain(_)) {
                return Err(SceneError::new(
                    "contact.object",
                    format!(
                        "{:?} is a free chain, which only a mallet may be (hammer.object): struck, it would float away",
                        self.contact.object
                    ),
                ));
            }
        }
        let Some(name) = &h.object else {
            if h.point.is_some() {
                return Err(SceneError::new(
                    "hammer.point",
                    "a point-mass hammer has no points; name the mallet object in hammer.object or omit the key",
                ));
            }
            return Ok(());
        };
        self.check_mallet(
            ["hammer.object", "hammer.point", "hammer.mass_kg"],
            name,
            h.point.as_ref(),
            h.mass_kg,
        )
    }

    /// A mallet object `name` touching at `point`, of rigid mass `mass_kg`
    /// (the hammer's or a striker's; `fields`: where its object, point
    /// and mass are written): an object of the scene other than the
    /// struck one, with modes (a table, a free chain of exactly that mass,
    /// or one from geometry and material), and one of its points.
    pub(super) fn check_mallet(
        &self,
        [f_object, f_point, f_mass]: [&str; 3],
        name: &str,
        point: Option<&String>,
        mass_kg: f64,
    ) -> Result<(), SceneError> {
        let Some(mi) = self.object_index(name) else {
            return Err(SceneError::new(
                f_object,
                format!("no object named {name:?}"),
            ));
        };
        if name == self.contact.object {
            return Err(SceneError::new(
                f_object,
                format!(
                    "{name:?} is the struck object (contact.object); a mallet is another object"
                ),
            ));
        }
        let modal = |o: &ObjectSpec| {
            matches!(o, ObjectSpec::Modal(_) | ObjectSpec::Chain(_)) || o.physical().is_some()
        };
        let mallet = &self.object[mi];
        if let ObjectSpec::Chain(c) = mallet {
            let m = c.mass_kg();
            if !((mass_kg - m).abs() <= 1e-9 * m) {
                return Err(SceneError::new(
                    f_mass,
                    format!(
                        "a chain mallet's rigid motion is the whole chain: must be the sum of {name:?}'s masses, {m:e} kg, got {mass_kg:e}"
                    ),
                ));
            }
        }
        if !modal(mallet) {
            return Err(SceneError::new(
                f_object,
                format!(
                    "a mallet is a modal object or one from geometry and material (its free modes); {name:?} is a {}",
                    mallet.kind()
                ),
            ));
        }
        // any struck object but a chain (refused above) may take a mallet
        let points = mallet.point_names();
        match point {
            None => Err(SceneError::new(
                f_point,
                format!("missing: name the point of {name:?} that touches, one of {points:?}"),
            )),
            Some(p) if !points.contains(p) => Err(SceneError::new(
                f_point,
                format!("object {name:?} has no point {p:?}"),
            )),
            Some(_) => Ok(()),
        }
    }

    /// Join a modal mallet's modes to the struck object's (see the module
    /// documentation); called on a validated scene whose physical objects
    /// are already modal. The struck object gains the mallet's points as
    /// `"<mallet>.<point>"` (pickups on the mallet move there) and the
    /// contact point `"<point> against <mallet>.<point>"`, whose weights are
    /// the struck point's for its own modes and minus the touching point's
    /// for the mallet's. The mallet object stays in the list, unexcited. A
    /// struck wall becomes a modal object of the mallet's modes alone, its
    /// contact point `"surface against <mallet>.<point>"`.
    pub(super) fn merge_mallet(&mut self) -> Result<(), SceneError> {
        let (Some(mname), Some(tip)) = (self.hammer.object.clone(), self.hammer.point.clone())
        else {
            return Ok(());
        };
        let (Some(mi), Some(ci)) = (
            self.object_index(&mname),
            self.object_index(&self.contact.object),
        ) else {
            return Err(SceneError::new("hammer.object", "not validated"));
        };
        // a wall is a struck object without modes whose surface is the
        // contact point; a lumped string's model is joined in compile
        // stage 1 (`ObjectModel::joined_with_mallet`)
        let (struck, cp) = match (&self.object[ci], &self.contact.point) {
            (ObjectSpec::String(_), _) => return Ok(()),
            (ObjectSpec::Wall(w), None) => (
                ModalSpec {
                    name: w.name.clone(),
                    points: vec!["surface".to_string()],
                    mode: Vec::new(),
                },
                "surface".to_string(),
            ),
            (ObjectSpec::Modal(m), Some(p)) => (m.clone(), p.clone()),
            _ => {
                return Err(SceneError::new(
                    "hammer.object",
                    "a modal mallet needs a modal struck object and point, or a wall",
                ))
            }
        };
        let ObjectSpec::Modal(mallet) = self.object[mi].clone() else {
            return Err(SceneError::new("hammer.object", "not validated"));
        };
        let total = struck.mode.len() + mallet.mode.len();
        if total > MAX_MODES_PER_OBJECT {
            return Err(SceneError::new(
                "hammer.object",
                format!(
                    "the struck object's {} modes and the mallet's {} are more than the limit of {MAX_MODES_PER_OBJECT}",
                    struck.mode.len(),
                    mallet.mode.len()
                ),
            ));
        }
        let c_idx = struck.points.iter().position(|p| *p == cp);
        let t_idx = mallet.points.iter().position(|p| *p == tip);
        let (Some(c_idx), Some(t_idx)) = (c_idx, t_idx) else {
            return Err(SceneError::new("hammer.point", "not validated"));
        };
        let (points, contact_point) = joined_points(&struck, &mallet, &mname, &cp, &tip)?;
        let modes = joined_modes(&struck, &mallet, c_idx, t_idx);
        self.object[ci] = ObjectSpec::Modal(ModalSpec {
            name: struck.name.clone(),
            points,
            mode: modes,
        });
        for pk in &mut self.pickup {
            if pk.object == mname {
                pk.object = struck.name.clone();
                pk.point = format!("{mname}.{}", pk.point);
            }
        }
        self.contact.point = Some(contact_point);
        self.hammer.object = None;
        self.hammer.point = None;
        Ok(())
    }
}

/// The points of the struck object (struck at `cp`) joined with the
/// modal mallet `mname` (touching with `tip`): its own, the mallet's as
/// `"<mallet>.<point>"`, then the contact point `"<cp> against
/// <mallet>.<tip>"`, which is returned too; an error when one of the new
/// names is taken.
fn joined_points(
    struck: &ModalSpec,
    mallet: &ModalSpec,
    mname: &str,
    cp: &str,
    tip: &str,
) -> Result<(Vec<String>, String), SceneError> {
    let renamed: Vec<String> = mallet
        .points
        .iter()
        .map(|p| format!("{mname}.{p}"))
        .collect();
    let contact_point = format!("{cp} against {mname}.{tip}");
    let mut points = struck.points.clone();
    for p in renamed.iter().chain(std::iter::once(&contact_point)) {
        if points.contains(p) {
            return Err(SceneError::new(
                "hammer.point",
                format!(
                    "the struck object {:?} already has a point {p:?}, the name the mallet's point takes when joined; rename one",
                    struck.name
                ),
            ));
        }
        points.push(p.clone());
    }
    Ok((points, contact_point))
}

/// The modes of the struck object joined with a modal mallet, over the
/// points of [`joined_points`]: the struck object's modes (zero on the
/// mallet's points, the struck point's weight `c_idx` at the contact
/// point), then the mallet's (zero on the struck object's points, minus
/// its touching point's weight `t_idx` at the contact point).
fn joined_modes(
    struck: &ModalSpec,
    mallet: &ModalSpec,
    c_idx: usize,
    t_idx: usize,
) -> Vec<ModeSpec> {
    let total = struck.mode.len() + mallet.mode.len();
    let (np, nq) = (struck.points.len(), mallet.points.len());
    let mut modes: Vec<ModeSpec> = Vec::with_capacity(total);
    for m in &struck.mode {
        let mut w = m.weights.clone();
        w.resize(np + nq, 0.0);
        w.push(m.weights[c_idx]);
        modes.push(ModeSpec {
            weights: w,
            ..m.clone()
        });
    }
    for m in &mallet.mode {
        let mut w = vec![0.0; np];
        w.extend_from_slice(&m.weights);
        w.push(-m.weights[t_idx]);
        modes.push(ModeSpec {
            weights: w,
            ..m.clone()
        });
    }
    modes
}
