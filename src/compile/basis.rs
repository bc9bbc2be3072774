//! Stage 3 of the compiler: the contact phase's static equilibrium under
//! gravity and the changes of basis between the phases, so a switch is one
//! matrix-vector product (docs/numerics.md, "Gravity" and "Exact
//! switching").

use super::error::CompileError;
use super::routes::Decomposed;
use super::rows::unit;
use super::CompiledPhase;
use crate::physics::hodlr::{frequency_order, Hodlr};
use crate::physics::linalg::matmul;
use nalgebra::{DMatrix, DVector};

/// The contact phase's static equilibrium `y* = -A^-1 f` in energy
/// coordinates (zero without gravity: no affine term at all).
pub(super) fn equilibrium(d: &Decomposed, gravity: bool) -> Result<DVector<f64>, CompileError> {
    if !gravity {
        return Ok(DVector::zeros(d.lay.dim()));
    }
    let sol =
        crate::physics::linalg::solve(&d.a_c, &(-&d.f_c)).ok_or(CompileError::NoEquilibrium)?;
    if sol.iter().any(|x| !x.is_finite()) {
        return Err(CompileError::NoEquilibrium);
    }
    Ok(sol)
}

/// The changes of basis between the phases.
pub(super) struct Basis {
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
}

/// Build the changes of basis. `E` embeds the object's energy coordinates
/// into the contact system's; `W_cf = V_c^-1 E V_f`, `W_fc = V_f^-1 E^T V_c`.
pub(super) fn changes(d: &Decomposed, y_star: &DVector<f64>) -> Result<Basis, CompileError> {
    let lay = &d.lay;
    let (dim_c, dim_f) = (lay.dim(), d.free.v.nrows());
    let mut emb_m = DMatrix::zeros(dim_c, dim_f);
    for j in 0..dim_f {
        emb_m[(lay.embed(j), j)] = 1.0;
    }
    let (con, free) = (&d.contact, &d.free);
    let w_cf = matmul(&matmul(&con.vinv, &emb_m), &free.v);
    let col_pi: Vec<f64> = (&con.vinv * &unit(lay, lay.pi())).iter().cloned().collect();
    let col_eta: Vec<f64> = (&con.vinv * &unit(lay, lay.eta()))
        .iter()
        .cloned()
        .collect();
    let s_star_v = &con.vinv * y_star;
    let w_fc = matmul(&matmul(&free.vinv, &emb_m.transpose()), &con.v);
    let s_f_star: Vec<f64> = (&w_fc * &s_star_v).iter().cloned().collect();
    let s_star: Vec<f64> = s_star_v.iter().cloned().collect();
    if w_cf.iter().chain(w_fc.iter()).any(|x| !x.is_finite()) {
        return Err(CompileError::NonFinite("change of basis"));
    }
    Ok(Basis {
        w_cf,
        col_pi,
        col_eta,
        s_star,
        w_fc,
        s_f_star,
    })
}

/// The changes of basis in hierarchical low-rank form (`W_cf`, `W_fc`),
/// when both phases are advanced in 2x2 blocks (the bases can then be
/// ordered by frequency) and the form pays: O(N r log N) per switch instead
/// of O(N^2) (docs/numerics.md, "Structured changes of basis"). Each is
/// `Err(why)` where the dense product stays.
pub(super) fn structured(
    free: &CompiledPhase,
    contact: &CompiledPhase,
    basis: &Basis,
) -> [Result<Hodlr, String>; 2] {
    let (Some(fg), Some(cg)) = (&free.gens, &contact.gens) else {
        let why = || "a phase is stepped densely".to_string();
        return [Err(why()), Err(why())];
    };
    let (fo, co) = (frequency_order(fg), frequency_order(cg));
    [
        Hodlr::try_build(&basis.w_cf, &co, &fo),
        Hodlr::try_build(&basis.w_fc, &fo, &co),
    ]
}

#[cfg(test)]
mod tests {
    use crate::compile::compile_one;
    use crate::presets;

    /// Going free -> contact -> free returns the object's state: `W_fc W_cf`
    /// is the identity on the object's coordinates (the contact system
    /// embeds the object exactly), on every preset; and the equilibrium
    /// under gravity is a fixed point of the contact phase.
    #[test]
    fn round_trip_of_the_changes_of_basis_is_the_identity() {
        let mut worst: f64 = 0.0;
        for i in presets::one_contact() {
            let sc = compile_one(&presets::scene(i).unwrap(), 44100.0).unwrap();
            let p = &sc.w_fc * &sc.w_cf;
            let n = p.nrows();
            let e = (p - nalgebra::DMatrix::<f64>::identity(n, n)).norm() / (n as f64).sqrt();
            worst = worst.max(e);
            assert!(e < 1e-12, "preset {i}: {e:e}");
        }
        println!("W_fc W_cf - I: worst {worst:.1e}");
        // gravity: the equilibrium is the contact state with zero
        // phase coordinates, i.e. s_star maps back to the offsets' hammer
        let bounce = compile_one(
            &presets::scene(presets::index_of("paper-bounce").unwrap()).unwrap(),
            44100.0,
        )
        .unwrap();
        assert!(bounce.offsets.pi > 0.0, "the hammer rests on the spring");
        let m_g = bounce.m_h * bounce.g;
        // spring force k p_eff = m g at rest: pi = sqrt(k) p_eff = m g / sqrt(k)
        let want = m_g / bounce.sk;
        assert!(
            (bounce.offsets.pi - want).abs() < 1e-9 * want,
            "{} vs {want}",
            bounce.offsets.pi
        );
    }
}
