//! Tests of the kernels: both paths against plain per-sample references,
//! bit for bit where the kernels promise it (any number of samples per
//! call, any extras, the scalar sums they replace).

use super::block::run_block;
use super::matvec::mat_vec_add;
use super::sums::block_margin;
use super::*;
use crate::compile::EnergyQuad;

/// A phase of `nb` damped rotation blocks with arbitrary rows and state.
fn setup(nb: usize) -> (BlockProps, Vec<f64>, [Vec<f64>; 3]) {
    let mut p = BlockProps::new(nb);
    let mut s = vec![0.0; 2 * nb];
    for k in 0..nb {
        let th = 0.1 * k as f64 + 0.05;
        let r = 0.999 - 1e-4 * k as f64;
        p.set(
            k,
            &[r * th.cos(), r * th.sin(), -r * th.sin(), r * th.cos()],
        );
        s[k] = (k as f64).sin();
        s[nb + k] = (k as f64 * 0.7).cos();
    }
    let rows = [0, 1, 2].map(|i| {
        (0..2 * nb)
            .map(|k| ((i + 1) * k) as f64 * 1e-2 - 0.3)
            .collect::<Vec<f64>>()
    });
    (p, s, rows)
}

/// Plain per-sample reference: step, then the three rows.
/// The operands of a test pass.
fn io<'a>(
    p: &'a BlockProps,
    s: &'a [f64],
    next: &'a mut [f64],
    rows: &'a [Vec<f64>; 3],
    acc: &'a mut BlockAcc,
    out: &'a mut BlockRows,
) -> BlockIo<'a> {
    BlockIo {
        p,
        s,
        next,
        rows: Rows {
            ev: &rows[0],
            l: &rows[1],
            r: &rows[2],
        },
        acc,
        out,
    }
}

/// One step of every block, plainly (no FMA, no lanes).
fn plain_step(p: &BlockProps, s: &[f64]) -> Vec<f64> {
    let nb = p.len();
    let mut x = vec![0.0; 2 * nb];
    for b in 0..nb {
        let m = p.get(b);
        x[b] = m[0] * s[b] + m[1] * s[nb + b];
        x[nb + b] = m[2] * s[b] + m[3] * s[nb + b];
    }
    x
}

/// The state and rows of a pass with extra sums are `run_block`'s.
fn assert_plain_rows(
    path: SimdPath,
    p: &BlockProps,
    s: &[f64],
    rows: &[Vec<f64>; 3],
    next: &[f64],
    out: &BlockRows,
) {
    let (next_plain, out_plain) = run(path, p, s, rows, EPOCH);
    assert_eq!(next, &next_plain[..]);
    assert_eq!(out.ev, out_plain.ev);
    assert_eq!(out.l, out_plain.l);
    assert_eq!(out.r, out_plain.r);
}

fn reference(p: &BlockProps, s: &[f64], rows: &[Vec<f64>; 3], k: usize) -> Vec<[f64; 3]> {
    let mut s = s.to_vec();
    let mut out = Vec::new();
    for _ in 0..k {
        let x = plain_step(p, &s);
        out.push([0, 1, 2].map(|q| rows[q].iter().zip(&x).map(|(a, b)| a * b).sum()));
        s = x;
    }
    out
}

fn run(
    path: SimdPath,
    p: &BlockProps,
    s: &[f64],
    rows: &[Vec<f64>; 3],
    k: usize,
) -> (Vec<f64>, BlockRows) {
    let mut next = vec![0.0; s.len()];
    let mut acc = Box::new([[[0.0; LANES]; 3]; EPOCH]);
    let mut out = BlockRows::default();
    let io = BlockIo {
        p,
        s,
        next: &mut next,
        rows: Rows {
            ev: &rows[0],
            l: &rows[1],
            r: &rows[2],
        },
        acc: &mut acc,
        out: &mut out,
    };
    run_block(path, io, k);
    (next, out)
}

#[test]
fn both_paths_match_a_plain_reference() {
    println!("path {}", SimdPath::detect().name());
    for nb in [1, 3, 8, 37, 100] {
        let (p, s, rows) = setup(nb);
        let want = reference(&p, &s, &rows, EPOCH);
        for path in [SimdPath::detect(), SimdPath::Generic] {
            let (_, out) = run(path, &p, &s, &rows, EPOCH);
            let mut worst = 0.0f64;
            for (j, w) in want.iter().enumerate() {
                for (q, got) in [out.ev[j], out.l[j], out.r[j]].iter().enumerate() {
                    let scale = rows[q].iter().map(|x| x.abs()).sum::<f64>() * 2.0;
                    worst = worst.max((got - w[q]).abs() / scale);
                }
            }
            println!(
                "{nb} blocks, {path:?}: worst rel. deviation {worst:.1e} over {EPOCH} samples"
            );
            assert!(worst < 1e-13, "{nb} blocks {path:?}: {worst}");
        }
    }
}

/// The extras' inputs over `nb` blocks: a quadratic form, a slope row and
/// three observation rows.
struct ExtraRows {
    quad: EnergyQuad,
    drow: Vec<f64>,
    orows: [Vec<f64>; 3],
}

fn extra_rows(nb: usize) -> ExtraRows {
    ExtraRows {
        quad: EnergyQuad {
            aa: (0..nb).map(|k| 1.0 + 0.1 * k as f64).collect(),
            ab: (0..nb).map(|k| 0.3 - 0.01 * k as f64).collect(),
            bb: (0..nb).map(|k| 2.0 - 0.005 * k as f64).collect(),
        },
        drow: (0..2 * nb)
            .map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.7)
            .collect(),
        orows: [0, 1, 2].map(|i| {
            (0..2 * nb)
                .map(|k| ((k * (i + 3)) % 7) as f64 * 0.21 - 0.5)
                .collect::<Vec<f64>>()
        }),
    }
}

/// What a kernel run wrote beside its state and rows: the quadratic form,
/// the slope row and the observation rows of every stepped state (NaN
/// where not written).
struct ExtrasOut {
    qout: Box<[f64; EPOCH]>,
    dout: Box<[f64; EPOCH]>,
    oout: BlockRows,
}

/// Run `EPOCH` samples from `s` on `path` with the extras `which` (the
/// quadratic form, the slope row, 0, 1 or 3 observation rows), check that
/// the state and rows are `run_block`'s, and return what the extras wrote.
fn run_with_extras(
    path: SimdPath,
    (p, s, rows): (&BlockProps, &[f64], &[Vec<f64>; 3]),
    x: &ExtraRows,
    (with_q, with_d, n_obs): (bool, bool, usize),
) -> ExtrasOut {
    let mut next = vec![0.0; s.len()];
    let mut acc = Box::new([[[0.0; LANES]; 3]; EPOCH]);
    let mut out = BlockRows::default();
    let mut qacc = Box::new([[0.0; LANES]; EPOCH]);
    let mut qout = Box::new([f64::NAN; EPOCH]);
    let mut dacc = Box::new([[0.0; LANES]; EPOCH]);
    let mut dout = Box::new([f64::NAN; EPOCH]);
    let mut oacc = Box::new([[[0.0; LANES]; 3]; EPOCH]);
    let mut oout = BlockRows {
        ev: [f64::NAN; EPOCH],
        l: [f64::NAN; EPOCH],
        r: [f64::NAN; EPOCH],
    };
    let extras = Extras {
        quad: with_q.then_some(QuadIo {
            quad: &x.quad,
            acc: &mut qacc,
            out: &mut qout,
        }),
        slope: with_d.then_some(SlopeIo {
            row: &x.drow,
            acc: &mut dacc,
            out: &mut dout,
        }),
        obs: (n_obs > 0).then_some(ObsIo {
            rows: Rows {
                ev: &x.orows[0],
                l: &x.orows[1],
                r: &x.orows[2],
            },
            all: n_obs == 3,
            acc: &mut oacc,
            out: &mut oout,
        }),
    };
    let io = io(p, s, &mut next, rows, &mut acc, &mut out);
    run_block_with(path, io, extras, EPOCH);
    assert_plain_rows(path, p, s, rows, &next, &out);
    ExtrasOut { qout, dout, oout }
}

/// The `n_obs` observation rows asked for are bit for bit those rows
/// summed as the rows of `run_block` (`as_rows`); the others are left
/// alone.
fn assert_obs_rows(n_obs: usize, oout: &BlockRows, as_rows: &BlockRows, case: &str) {
    let bits = |x: &[f64; EPOCH]| x.map(f64::to_bits);
    match n_obs {
        0 => assert!(oout.ev.iter().all(|x| x.is_nan()), "{case}"),
        1 => {
            assert_eq!(bits(&oout.ev), bits(&as_rows.ev), "{case}");
            assert!(oout.l.iter().chain(&oout.r).all(|x| x.is_nan()), "{case}");
        }
        _ => {
            assert_eq!(bits(&oout.ev), bits(&as_rows.ev), "{case}");
            assert_eq!(bits(&oout.l), bits(&as_rows.l), "{case}");
            assert_eq!(bits(&oout.r), bits(&as_rows.r), "{case}");
        }
    }
}

/// The worst relative deviations, over the `EPOCH` stepped states from
/// `s`, of the quadratic form (`with_q`) and the slope row (`with_d`) a
/// run wrote from a plain reference (0 for an extra not run).
fn extras_deviation(
    (p, s): (&BlockProps, &[f64]),
    inputs: &ExtraRows,
    out: &ExtrasOut,
    (with_q, with_d): (bool, bool),
) -> (f64, f64) {
    let nb = p.len();
    let (quad, drow) = (&inputs.quad, &inputs.drow);
    let (mut worst_q, mut worst_d) = (0.0f64, 0.0f64);
    let mut st = s.to_vec();
    for j in 0..EPOCH {
        let x = plain_step(p, &st);
        if with_q {
            let (mut want, mut scale) = (0.0, 0.0);
            for b in 0..nb {
                let (a, c) = (x[b], x[nb + b]);
                want += quad.aa[b] * a * a + quad.ab[b] * a * c + quad.bb[b] * c * c;
                scale += quad.aa[b] * a * a + quad.ab[b].abs() * (a * c).abs() + quad.bb[b] * c * c;
            }
            worst_q = worst_q.max((out.qout[j] - want).abs() / scale);
        }
        if with_d {
            let want: f64 = drow.iter().zip(&x).map(|(a, b)| a * b).sum();
            let scale: f64 = drow.iter().zip(&x).map(|(a, b)| (a * b).abs()).sum();
            worst_d = worst_d.max((out.dout[j] - want).abs() / scale);
        }
        st = x;
    }
    (worst_q, worst_d)
}

/// Every choice of extras (quadratic form, slope row, 0, 1 or 3
/// observation rows; each of the 12 kernels on both paths): the same
/// state and rows as `run_block` bit for bit, each observation row
/// bit for bit what the same row gives as a row of `run_block` (the
/// one summation order), the rows not asked for left alone, and per
/// sample the quadratic form and the slope row of a plain reference to
/// rounding, whatever the number of blocks (partial groups included).
#[test]
fn extras_match_a_plain_reference_and_leave_the_rows_alone() {
    for nb in [1, 3, 8, 37, 100] {
        let (p, s, rows) = setup(nb);
        let x = extra_rows(nb);
        for path in [SimdPath::detect(), SimdPath::Generic] {
            let (_, as_rows) = run(path, &p, &s, &x.orows, EPOCH);
            let (mut worst_q, mut worst_d) = (0.0f64, 0.0f64);
            for (with_q, with_d, n_obs) in
                (0..12).map(|c| (c % 2 == 1, c / 2 % 2 == 1, [0, 1, 3][c / 4]))
            {
                let out = run_with_extras(path, (&p, &s, &rows), &x, (with_q, with_d, n_obs));
                let case = format!("{nb} blocks {path:?} quad {with_q} slope {with_d} obs {n_obs}");
                assert_obs_rows(n_obs, &out.oout, &as_rows, &case);
                assert_eq!(out.qout.iter().all(|x| x.is_nan()), !with_q, "{case}");
                assert_eq!(out.dout.iter().all(|x| x.is_nan()), !with_d, "{case}");
                let (q, d) = extras_deviation((&p, &s), &x, &out, (with_q, with_d));
                worst_q = worst_q.max(q);
                worst_d = worst_d.max(d);
            }
            println!(
                "{nb} blocks, {path:?}: quadratic form worst rel. deviation {worst_q:.1e}, slope row {worst_d:.1e}"
            );
            assert!(worst_q < 1e-14, "{nb} blocks {path:?}: {worst_q}");
            assert!(worst_d < 1e-13, "{nb} blocks {path:?}: {worst_d}");
        }
    }
}

/// One call of `k` samples is bit-identical to `k` calls of one sample
/// (the engine's output must not depend on how blocks are split).
#[test]
fn k_samples_at_once_equal_k_single_samples_bit_for_bit() {
    for nb in [1, 5, 8, 13, 64] {
        let (p, s, rows) = setup(nb);
        for path in [SimdPath::detect(), SimdPath::Generic] {
            let (next_all, out_all) = run(path, &p, &s, &rows, 23);
            let mut st = s.clone();
            for j in 0..23 {
                let (next, out) = run(path, &p, &st, &rows, 1);
                assert_eq!(out.ev[0].to_bits(), out_all.ev[j].to_bits());
                assert_eq!(out.l[0].to_bits(), out_all.l[j].to_bits());
                assert_eq!(out.r[0].to_bits(), out_all.r[j].to_bits());
                st = next;
            }
            assert!(st
                .iter()
                .zip(&next_all)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
            // and the input state is left untouched
            assert_eq!(s, setup(nb).1);
        }
    }
}

#[test]
fn rows_of_uses_the_kernel_order() {
    // rows_of(s) equals the sums the kernel makes for a state stepped by
    // the identity, bit for bit.
    let nb = 21;
    let (mut p, s, rows) = setup(nb);
    for k in 0..nb {
        p.set(k, &[1.0, 0.0, 0.0, 1.0]);
    }
    let (_, out) = run(SimdPath::Generic, &p, &s, &rows, 1);
    let r = Rows {
        ev: &rows[0],
        l: &rows[1],
        r: &rows[2],
    };
    let direct = rows_of(SimdPath::Generic, &s, &r);
    assert_eq!(direct[0].to_bits(), out.ev[0].to_bits());
    assert_eq!(direct[1].to_bits(), out.l[0].to_bits());
    assert_eq!(direct[2].to_bits(), out.r[0].to_bits());
}

/// `rows_as_kernel` of a stepped state is the kernel's own sums for it,
/// bit for bit on either path (on the FMA path `rows_of` differs from them
/// in the last bits: it never fuses), with short last groups.
#[test]
fn rows_as_kernel_are_the_kernels_sums_on_each_path() {
    for nb in [1, 3, 5, 8, 13, 21, 64] {
        let (p, s, rows) = setup(nb);
        let r = Rows {
            ev: &rows[0],
            l: &rows[1],
            r: &rows[2],
        };
        for path in [SimdPath::detect(), SimdPath::Generic] {
            let (_, out) = run(path, &p, &s, &rows, 23);
            let mut st = s.clone();
            for j in 0..23 {
                let (next, _) = run(path, &p, &st, &rows, 1);
                st = next;
                let got = rows_as_kernel(path, &st, &r);
                let want = [out.ev[j], out.l[j], out.r[j]];
                assert!(
                    (0..3).all(|q| got[q].to_bits() == want[q].to_bits()),
                    "{nb} blocks {path:?}, sample {j}: {got:?} against {want:?}"
                );
            }
        }
    }
}

#[test]
fn event_rows_match_one_step_of_the_kernel_and_no_step() {
    // With the propagators: the rows of the state after one step (as the
    // kernel computes them); without: the rows of the state itself.
    for nb in [1, 3, 4, 8, 37, 100] {
        let (p, s, rows) = setup(nb);
        let stepped = reference(&p, &s, &rows, 1)[0];
        let unstepped = [0, 1, 2].map(|q| rows[q].iter().zip(&s).map(|(a, b)| a * b).sum::<f64>());
        let rr = [&rows[0][..], &rows[1][..], &rows[2][..]];
        for path in [SimdPath::detect(), SimdPath::Generic] {
            for (props, want) in [(Some(&p), stepped), (None, unstepped)] {
                let got = event_rows(path, props, &s, rr);
                for q in 0..3 {
                    let scale = rows[q].iter().map(|x| x.abs()).sum::<f64>() * 2.0;
                    let e = (got[q] - want[q]).abs() / scale;
                    assert!(e < 1e-15, "{nb} blocks {path:?} row {q}: {e:e}");
                }
            }
        }
    }
}

#[test]
fn mat_vec_add_matches_a_plain_product() {
    let (nr, nc) = (37, 29);
    let m: Vec<f64> = (0..nr * nc).map(|i| ((i * 31) % 17) as f64 - 8.0).collect();
    let mut x: Vec<f64> = (0..nc).map(|j| (j as f64).cos()).collect();
    x[3] = 0.0;
    for path in [SimdPath::detect(), SimdPath::Generic] {
        let mut y = vec![1.0; nr];
        mat_vec_add(path, &m, nr, &x, &mut y);
        for i in 0..nr {
            let want = 1.0 + (0..nc).map(|j| m[j * nr + i] * x[j]).sum::<f64>();
            assert!((y[i] - want).abs() < 1e-12, "{path:?} row {i}");
        }
    }
}

#[test]
fn vectorised_margins_and_rows_are_the_scalar_sums_bit_for_bit() {
    // every tail length, both paths, against the scalar loops the
    // engine used before (the same lanes, the same order)
    for nb in [1, 2, 3, 4, 5, 7, 8, 9, 37, 100, 1003] {
        let (_, s, rows) = setup(nb);
        let c: Vec<f64> = (0..nb)
            .map(|k| 0.3 + (k as f64 * 0.7).sin().abs())
            .collect();
        let e: Vec<f64> = (0..nb).map(|k| 1e-3 * (1.0 + (k % 5) as f64)).collect();
        let c4: Vec<f64> = (0..nb).map(|k| 10.0 + (k * k % 13) as f64).collect();
        let h = 0.37;
        let (want_e, want_w) = block_measures(&s, &c);
        let want_m = block_margin(&s, &c, &e, h);
        let r = Rows {
            ev: &rows[0],
            l: &rows[1],
            r: &rows[2],
        };
        let want_rows = [0, 1, 2].map(|q| {
            let mut acc = [0.0f64; LANES];
            for k in 0..nb {
                acc[k % LANES] += rows[q][k] * s[k];
                acc[k % LANES] += rows[q][nb + k] * s[nb + k];
            }
            lane_sum(acc)
        });
        let (dt4, tail, dt) = (1e-3, 0.2, 0.5);
        let (mut want_rem, mut want_mag) = (0.0, 0.0);
        for k in 0..nb {
            let norm = (s[k] * s[k] + s[nb + k] * s[nb + k]).sqrt();
            want_rem += super::hermite_block(c[k], c4[k], e[k], dt4, tail) * norm;
            want_mag += (e[k] + dt * c[k]) * norm;
        }
        for path in [SimdPath::detect(), SimdPath::Generic] {
            let (ge, gw, gm) = margin_sums(path, &s, &c, &e, h);
            let bits = |a: f64, b: f64| a.to_bits() == b.to_bits();
            assert!(
                bits(ge, want_e) && bits(gw, want_w) && bits(gm, want_m),
                "{nb} blocks {path:?}: margins"
            );
            let got = rows_of(path, &s, &r);
            assert!(
                (0..3).all(|q| bits(got[q], want_rows[q])),
                "{nb} blocks {path:?}: rows"
            );
            let (rem, mag) = hermite_sums(path, &s, [&c, &c4, &e], [dt4, tail, dt]);
            assert!(
                bits(rem, want_rem) && bits(mag, want_mag),
                "{nb} blocks {path:?}: Hermite sums"
            );
        }
    }
}

#[test]
fn hermite_step_is_the_scalar_step_with_lane_sums_bit_for_bit() {
    // every tail length, both paths: the stepped state is the scalar
    // step's (what `advance_by` did block by block), the sums are the
    // lanes' (block `k` into lane `k mod 4`); and the lanes' sums are
    // within the certificates' rounding allowance `(2 nb + 16) u mag`
    // of the sequential sums the engine took before
    for nb in [1, 2, 3, 4, 5, 7, 8, 9, 37, 100, 1003] {
        let (p, s, rows) = setup(nb);
        let w = |f: &dyn Fn(usize) -> f64| (0..nb).map(f).collect::<Vec<f64>>();
        let c1 = w(&|k| 0.3 + (k as f64 * 0.7).sin().abs());
        let c2 = w(&|k| 2.0 + (k as f64 * 0.3).cos());
        let c4 = w(&|k| 10.0 + (k * k % 13) as f64);
        let e = w(&|k| 1e-3 * (1.0 + (k % 5) as f64));
        let hr = HermiteRows {
            ev: &rows[0],
            ev_d: &rows[1],
            c1: &c1,
            c2: &c2,
            c4: &c4,
            e: &e,
        };
        let (dt4, tail, tau) = (1e-3, 0.2, 0.5);
        let mut want_next = s.clone();
        for k in 0..nb {
            let (a, b) = (s[k], s[nb + k]);
            let q = p.get(k);
            want_next[k] = q[0] * a + q[1] * b;
            want_next[nb + k] = q[2] * a + q[3] * b;
        }
        let (mut lanes_acc, mut seq) = ([[0.0f64; LANES]; 9], [0.0f64; 9]);
        let mut abs = [0.0f64; 9];
        for k in 0..nb {
            let (a, b) = (s[k], s[nb + k]);
            let (a1, b1) = (want_next[k], want_next[nb + k]);
            let norm = (a * a + b * b).sqrt();
            let (r, q) = (&rows[0], &rows[1]);
            let t = [
                r[k] * a + r[nb + k] * b,
                q[k] * a + q[nb + k] * b,
                r[k] * a1 + r[nb + k] * b1,
                q[k] * a1 + q[nb + k] * b1,
                super::hermite_block(c1[k], c4[k], e[k], dt4, tail) * norm,
                c4[k] * norm,
                c2[k] * norm,
                (e[k] + tau * c1[k]) * norm,
                c1[k] * norm,
            ];
            for i in 0..9 {
                lanes_acc[i][k % LANES] += t[i];
                seq[i] += t[i];
                abs[i] += t[i].abs();
            }
        }
        let want = lanes_acc.map(lane_sum);
        for i in 0..9 {
            // each order rounds within `nb u` of the magnitudes summed
            let allowance = (2 * nb + 16) as f64 * f64::EPSILON * abs[i];
            assert!(
                (want[i] - seq[i]).abs() <= allowance,
                "{nb} blocks: sum {i} reordered by {:e}, allowance {allowance:e}",
                (want[i] - seq[i]).abs()
            );
        }
        for path in [SimdPath::detect(), SimdPath::Generic] {
            let mut next = vec![f64::NAN; 2 * nb];
            let got = hermite_step_sums(path, &p, &s, &mut next, &hr, [dt4, tail, tau]);
            let bits =
                |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                bits(&next, &want_next),
                "{nb} blocks {path:?}: stepped state"
            );
            assert!(
                bits(&got, &want),
                "{nb} blocks {path:?}: sums {got:?} against {want:?}"
            );
            let mut stepped = s.clone();
            step_blocks(path, &p, &mut stepped);
            assert!(
                bits(&stepped, &want_next),
                "{nb} blocks {path:?}: step_blocks"
            );
        }
    }
}

#[test]
fn block_measures_are_block_energies() {
    let (_, s, _) = setup(9);
    let c: Vec<f64> = (0..9).map(|k| k as f64).collect();
    let (e, w) = block_measures(&s, &c);
    let e_want: f64 = s.iter().map(|x| x * x).sum();
    let w_want: f64 = (0..9)
        .map(|k| c[k] * (s[k] * s[k] + s[9 + k] * s[9 + k]))
        .sum();
    assert!((e - e_want).abs() < 1e-14 * e_want && (w - w_want).abs() < 1e-14 * w_want);
}
