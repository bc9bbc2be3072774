//! Dot products of compiled rows with a state, each summed in order from
//! the first entry (the engine's scalar sums; the kernels' lane sums are in
//! `kernel`).

#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `[dot(rows[0], s), dot(rows[1], s), dot(rows[2], s)]` bit for bit (each
/// the same sequential sum from the same start) in one pass: each sum is a
/// chain of dependent additions, and three independent chains overlap
/// where three passes would wait for each in turn. O(N).
pub(crate) fn dot3(rows: [&[f64]; 3], s: &[f64]) -> [f64; 3] {
    let n = s.len().min(rows[0].len());
    if rows.iter().any(|r| r.len().min(s.len()) != n) {
        return rows.map(|r| dot(r, s));
    }
    let zero: f64 = std::iter::empty::<f64>().sum();
    let mut acc = [zero; 3];
    let (r0, r1, r2) = (&rows[0][..n], &rows[1][..n], &rows[2][..n]);
    for (k, &x) in s[..n].iter().enumerate() {
        acc[0] += r0[k] * x;
        acc[1] += r1[k] * x;
        acc[2] += r2[k] * x;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot3_is_three_dots_bit_for_bit() {
        for n in [0usize, 1, 2, 7, 400, 2002] {
            let row = |m: f64| -> Vec<f64> {
                (0..n)
                    .map(|k| (m * k as f64 + 0.3).sin() * 1e3f64.powf((k % 7) as f64 - 3.0))
                    .collect()
            };
            let s: Vec<f64> = (0..n).map(|k| (k as f64 * 0.77).cos()).collect();
            let (a, b, c) = (row(1.3), row(-0.4), row(2.9));
            // a row of negative zeros: the sums' starting value shows
            let z = vec![-0.0; n];
            let pos = vec![1.0; n];
            for rows in [[&a[..], &b[..], &c[..]], [&z[..], &a[..], &z[..]]] {
                for s in [&s[..], &pos[..]] {
                    let got = dot3(rows, s);
                    for q in 0..3 {
                        assert_eq!(got[q].to_bits(), dot(rows[q], s).to_bits(), "n {n} row {q}");
                    }
                }
            }
        }
    }
}
