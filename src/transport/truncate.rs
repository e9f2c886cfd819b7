//! Truncation of a transport row to its `keep` largest-magnitude Haar coefficients (module
//! docs of [`crate::transport`]): keeping the largest minimises the `ℓ²` norm of what is
//! dropped, hence the worst-case response error `‖g_drop‖ ‖L̃‖`.

use super::{HaarIndex, TransportValue};
#[cfg(doc)]
use crate::sphere::haar;

/// Reused buffers of [`truncate_global`].
#[derive(Default)]
pub(super) struct Selection {
    /// Count of coefficients per magnitude exponent (the IEEE exponent field of `|g_m|`,
    /// `2¹¹` buckets; non-negative floats order as their bit patterns, so a larger
    /// exponent field is a larger magnitude, NaN above infinity as in `f64::total_cmp`).
    hist: Vec<u32>,
    /// `(|g_m| bits, m)` of the candidates, then of the kept coefficients.
    kept: Vec<(u64, u32)>,
}

/// Buckets of [`Selection::hist`]: one per value of the 11-bit exponent field.
const BUCKETS: usize = 1 << 11;

/// The bit pattern of `|c|`, which orders as the magnitude (sign bit clear).
fn magnitude(c: f64) -> u64 {
    c.abs().to_bits()
}

/// Largest magnitude first, ties by index (the order of [`haar::keep_largest`]).
fn larger_first(a: &(u64, u32), b: &(u64, u32)) -> std::cmp::Ordering {
    b.0.cmp(&a.0).then(a.1.cmp(&b.1))
}

/// The `keep` largest-magnitude non-zero coefficients of the dense row `global` (all
/// non-zero ones for `keep == 0`) into `idx`/`val`, largest first, ties by index: the same
/// entries in the same order as [`haar::keep_largest`], without allocating; `sel` holds
/// the buffers. Returns how many were kept (`≤ idx.len()`).
///
/// Two passes over the row: a histogram of the magnitudes' exponent fields gives the
/// highest exponent `e` such that at least `k` coefficients have an exponent `≥ e`; the
/// second pass gathers those candidates (every one of the `k` largest is among them, and
/// rarely more than twice as many), and a selection and a sort of the candidates in the
/// order above leave the `k` kept.
pub(super) fn truncate_global(
    global: &[f64],
    sel: &mut Selection,
    keep: usize,
    idx: &mut [HaarIndex],
    val: &mut [TransportValue],
) -> usize {
    sel.hist.clear();
    sel.hist.resize(BUCKETS, 0);
    let mut zeros = 0usize;
    for &c in global {
        let b = magnitude(c);
        sel.hist[(b >> 52) as usize] += 1;
        zeros += usize::from(b == 0);
    }
    let nz = global.len() - zeros;
    let k = if keep == 0 { nz } else { keep }.min(nz).min(idx.len());
    if k == 0 {
        return 0;
    }
    // The exponent bucket that holds the k-th largest (bucket 0 also holds the zeros,
    // which the threshold of at least 1 leaves out).
    let mut above = 0usize;
    let mut lowest = 0u64;
    for e in (0..BUCKETS).rev() {
        above += sel.hist[e] as usize;
        if above >= k {
            lowest = (e as u64) << 52;
            break;
        }
    }
    let lowest = lowest.max(1);
    sel.kept.clear();
    sel.kept.extend(
        global
            .iter()
            .enumerate()
            .map(|(m, &c)| (magnitude(c), m as u32))
            .filter(|&(b, _)| b >= lowest),
    );
    if sel.kept.len() > k {
        sel.kept.select_nth_unstable_by(k - 1, larger_first);
        sel.kept.truncate(k);
    }
    sel.kept.sort_unstable_by(larger_first);
    for ((i, v), &(_, m)) in idx.iter_mut().zip(val.iter_mut()).zip(sel.kept.iter()) {
        // m < n_global² ≤ 65,536 (checked in `check_inputs`).
        *i = m as HaarIndex;
        *v = TransportValue::from_f64(global[m as usize]);
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::haar;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn keeps_the_entries_of_a_full_sort_in_its_order() {
        // Reference: haar::keep_largest (a sort of every non-zero coefficient by magnitude,
        // ties by index). Rows with zeros, repeated magnitudes of both signs (ties),
        // magnitudes spread over many exponents (the radix buckets) and subnormals, and
        // every `keep` from 0 (all) past the non-zero count must agree exactly.
        let mut rng = Pcg64::seed_from_u64(7);
        let mut sel = Selection::default();
        for trial in 0..400 {
            let n = 1 + trial % 97;
            let row: Vec<f64> = (0..n)
                .map(|_| match rng.random_range(0..6) {
                    0 => 0.0,
                    1 => f64::from(rng.random_range(-3i32..=3)) * 0.25,
                    // Magnitudes over many exponent buckets, subnormals among them.
                    2 => rng.random_range(-1.0..1.0) * 2f64.powi(rng.random_range(-1070..40)),
                    3 => rng.random_range(-1.0..1.0) * f64::MIN_POSITIVE,
                    _ => rng.random_range(-1.0..1.0),
                })
                .collect();
            for keep in [0, 1, 2, 5, n / 2, n, n + 3] {
                let (want_idx, want_val, _) =
                    haar::keep_largest(&row, if keep == 0 { n } else { keep }, None);
                let mut idx = vec![0; n];
                let mut val = vec![TransportValue::ZERO; n];
                let k = truncate_global(&row, &mut sel, keep, &mut idx, &mut val);
                assert_eq!(k, want_idx.len(), "trial {trial} keep {keep}");
                for j in 0..k {
                    assert_eq!(u32::from(idx[j]), want_idx[j], "trial {trial} keep {keep}");
                    assert_eq!(val[j], TransportValue::from_f64(want_val[j]));
                }
            }
        }
    }
}
