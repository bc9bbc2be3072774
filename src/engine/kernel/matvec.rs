//! The change of basis at a phase switch: `y += W x` for a dense
//! column-major `W` ([`mat_vec_add`]) or one in hierarchical low-rank form
//! ([`hodlr_mat_vec_add`]).

use crate::engine::vmath::{madd, SimdPath};
use crate::physics::hodlr::Hodlr;

#[inline(always)]
fn mat_vec_body<const FMA: bool>(m: &[f64], nrows: usize, x: &[f64], y: &mut [f64]) {
    let y = &mut y[..nrows];
    let ncols = x.len();
    // Four columns per pass over y: a quarter of the loads and stores of y.
    let mut j = 0;
    while j + 4 <= ncols {
        let xs = [x[j], x[j + 1], x[j + 2], x[j + 3]];
        if xs != [0.0; 4] {
            let c0 = &m[j * nrows..(j + 1) * nrows];
            let c1 = &m[(j + 1) * nrows..(j + 2) * nrows];
            let c2 = &m[(j + 2) * nrows..(j + 3) * nrows];
            let c3 = &m[(j + 3) * nrows..(j + 4) * nrows];
            for i in 0..nrows {
                let mut v = y[i];
                v = madd::<FMA>(c0[i], xs[0], v);
                v = madd::<FMA>(c1[i], xs[1], v);
                v = madd::<FMA>(c2[i], xs[2], v);
                v = madd::<FMA>(c3[i], xs[3], v);
                y[i] = v;
            }
        }
        j += 4;
    }
    for j in j..ncols {
        let xj = x[j];
        if xj == 0.0 {
            continue;
        }
        let col = &m[j * nrows..(j + 1) * nrows];
        for (yi, &mij) in y.iter_mut().zip(col) {
            *yi = madd::<FMA>(mij, xj, *yi);
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn mat_vec_avx2(m: &[f64], nrows: usize, x: &[f64], y: &mut [f64]) {
    mat_vec_body::<true>(m, nrows, x, y)
}

/// `y += M x` for a column-major `nrows x x.len()` matrix `m` (contiguous
/// columns, vectorised axpys four columns at a time; all-zero groups of `x`
/// skipped).
/// The change of basis at a phase switch. O(rows cols), allocation-free.
/// \[audio-thread\]
pub(crate) fn mat_vec_add(path: SimdPath, m: &[f64], nrows: usize, x: &[f64], y: &mut [f64]) {
    assert!(
        m.len() == nrows * x.len() && y.len() >= nrows,
        "mat_vec_add: shapes"
    );
    match path {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `run_block`.
        SimdPath::Avx2Fma(_) => unsafe { mat_vec_avx2(m, nrows, x, y) },
        _ => mat_vec_body::<false>(m, nrows, x, y),
    }
}

/// `y += W x` for a change of basis at a switch: through its hierarchical
/// form `h` when there is one (and `structured`), else through the dense
/// row-major `w` of `nrows` rows. `tmp`: scratch for [`hodlr_mat_vec_add`].
/// \[audio-thread\]
pub(crate) fn change_of_basis_add(
    path: SimdPath,
    structured: Option<&Hodlr>,
    w: &[f64],
    nrows: usize,
    x: &[f64],
    y: &mut [f64],
    tmp: &mut [Vec<f64>; 3],
) {
    match structured {
        Some(h) => {
            let [a, b, c] = tmp;
            hodlr_mat_vec_add(path, h, x, y, [a, b, c]);
        }
        None => mat_vec_add(path, w, nrows, x, y),
    }
}

/// `y += W x` for `W` in hierarchical low-rank form (the structured change
/// of basis at a switch): the permutations, then each piece through
/// [`mat_vec_add`] (a dense leaf, or `V^T` then `U` of a low-rank block).
/// O(stored entries), allocation-free: `xp`, `yp` and `t` are scratch of at
/// least `cols`, `rows` and `max_rank` entries. \[audio-thread\]
pub(crate) fn hodlr_mat_vec_add(
    path: SimdPath,
    h: &Hodlr,
    x: &[f64],
    y: &mut [f64],
    [xp, yp, t]: [&mut [f64]; 3],
) {
    let (xp, yp, t) = (&mut xp[..h.cols], &mut yp[..h.rows], &mut t[..h.max_rank]);
    for (v, &j) in xp.iter_mut().zip(&h.col_perm) {
        *v = x[j];
    }
    yp.fill(0.0);
    for p in &h.pieces {
        let xs = &xp[p.c0..p.c0 + p.nc];
        let ys = &mut yp[p.r0..p.r0 + p.nr];
        match p.rank {
            None => mat_vec_add(path, &h.data[p.off..p.off + p.nr * p.nc], p.nr, xs, ys),
            Some(r) => {
                let t = &mut t[..r];
                t.fill(0.0);
                mat_vec_add(path, &h.data[p.off..p.off + r * p.nc], r, xs, t);
                let u0 = p.off + r * p.nc;
                mat_vec_add(path, &h.data[u0..u0 + p.nr * r], p.nr, t, ys);
            }
        }
    }
    for (v, &i) in yp.iter().zip(&h.row_perm) {
        y[i] += v;
    }
}
