//! The trace CSV's numbers: each the shortest decimal text that reads back
//! to it exactly, written straight into a buffer.

/// Room for one number and its separator in [`put_numbers`]: a number is
/// at most 24 bytes (`-2.2250738585072014e-308`), a separator at most 8.
pub const NUMBER_ROOM: usize = 32;

/// Write `xs` to `out[at..]`, each as the shortest decimal text that reads
/// back to it exactly, as zmij (Schubfach) spells it: a decimal fraction
/// for exponents -5 to 15 (`0.00036`, `-123.5`, `0.0`), else scientific
/// (`1.5e-7`, `1e+20`); `NaN`, `inf`, `-inf` (which a trace never holds).
/// After number `k` comes `sep(k)` (at most 8 bytes: a separator).
/// `out[at..]` must have room for [`NUMBER_ROOM`] bytes per number; returns
/// the end of what was written.
///
/// Every CSV reader reads these (Rust's `parse`, Python's `float`, NumPy);
/// tested to read back bit for bit, with as many digits as core's shortest,
/// on numbers of every magnitude. The digits are not moved into core's
/// `{:e}` spelling: that move costs as much again as finding them.
///
/// Up to 8 numbers are formatted first and then moved with fixed-size
/// copies straight into `out`: a copy call per number took a fifth of the
/// text's time, and a load that spans several stores made just before it
/// (zmij writes its digits in pieces of several sizes) waits for them,
/// which the other numbers' work hides (docs/design.md, "Offline
/// rendering").
pub fn put_numbers(
    out: &mut [u8],
    mut at: usize,
    xs: &[f64],
    sep: impl Fn(usize) -> &'static [u8],
) -> usize {
    const BATCH: usize = 8;
    let mut fmts = [(); BATCH].map(|_| zmij::Buffer::new());
    for (c, batch) in xs.chunks(BATCH).enumerate() {
        let mut texts: [&[u8]; BATCH] = [&[]; BATCH];
        for ((f, &x), t) in fmts.iter_mut().zip(batch).zip(&mut texts) {
            *t = f.format(x).as_bytes();
        }
        for (j, s) in texts[..batch.len()].iter().enumerate() {
            copy_short(out, at, s);
            at += s.len();
            let p = sep(c * BATCH + j);
            copy_short(out, at, p);
            at += p.len();
        }
    }
    at
}

/// Append `xs` to `buf` as [`put_numbers`] writes them.
pub fn push_numbers(buf: &mut Vec<u8>, xs: &[f64], sep: impl Fn(usize) -> &'static [u8]) {
    let at = buf.len();
    buf.resize(at + xs.len() * NUMBER_ROOM, 0);
    let end = put_numbers(buf, at, xs, sep);
    buf.truncate(end);
}

/// Copy `s` (at most 32 bytes) to `o[at..]` in at most two fixed-size,
/// overlapping copies (no call, no per-byte loop beyond 3 bytes).
#[inline(always)]
fn copy_short(o: &mut [u8], at: usize, s: &[u8]) {
    let n = s.len();
    if n >= 16 {
        o[at..at + 16].copy_from_slice(&s[..16]);
        o[at + n - 16..at + n].copy_from_slice(&s[n - 16..]);
    } else if n >= 8 {
        o[at..at + 8].copy_from_slice(&s[..8]);
        o[at + n - 8..at + n].copy_from_slice(&s[n - 8..]);
    } else if n >= 4 {
        o[at..at + 4].copy_from_slice(&s[..4]);
        o[at + n - 4..at + n].copy_from_slice(&s[n - 4..]);
    } else {
        for (d, &c) in o[at..at + n].iter_mut().zip(s) {
            *d = c;
        }
    }
}
