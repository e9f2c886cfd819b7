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
    /// The magnitudes' bit patterns in the bucket that holds the `k`-th largest.
    bucket: Vec<u64>,
    /// `(|g_m| bits, m)` of the kept coefficients.
    kept: Vec<(u64, u32)>,
}

/// Buckets of [`Selection::hist`]: one per value of the 11-bit exponent field.
const BUCKETS: usize = 1 << 11;

/// The bit pattern of `|c|`, which orders as the magnitude (sign bit clear).
fn magnitude(c: f64) -> u64 {
    c.abs().to_bits()
}

/// The magnitude's exponent bucket (`< BUCKETS`: the sign bit is clear).
fn bucket_of(b: u64) -> usize {
    (b >> 52) as usize
}

/// The `k`-th largest magnitude `τ` of `global` (`1 ≤ k ≤ global.len()`) and how many
/// magnitudes exceed it: a radix selection — a histogram of the exponent fields finds the
/// bucket that holds `τ`, and a selection runs over that bucket's members only.
fn kth_largest(global: &[f64], k: usize, sel: &mut Selection) -> (u64, usize) {
    let mut above = 0usize;
    let mut top = 0usize;
    for e in (0..BUCKETS).rev() {
        let here = sel.hist[e] as usize;
        if above + here >= k {
            top = e;
            break;
        }
        above += here;
    }
    sel.bucket.clear();
    sel.bucket.extend(
        global
            .iter()
            .map(|&c| magnitude(c))
            .filter(|&b| bucket_of(b) == top),
    );
    let r = k - above; // τ is the r-th largest of the bucket, 1 ≤ r ≤ its size
    let len = sel.bucket.len();
    let (_, &mut tau, higher) = sel.bucket.select_nth_unstable(len - r);
    let greater = above + higher.iter().filter(|&&b| b > tau).count();
    (tau, greater)
}

/// The `keep` largest-magnitude non-zero coefficients of the dense row `global` (all
/// non-zero ones for `keep == 0`) into `idx`/`val`, largest first, ties by index: the same
/// entries in the same order as [`haar::keep_largest`], without allocating; `sel` holds
/// the buffers. Returns how many were kept (`≤ idx.len()`).
///
/// The `k`-th largest magnitude `τ` is found by a radix selection over the magnitudes' bit
/// patterns ([`kth_largest`]); one pass in index order then keeps every coefficient above
/// `τ` and the first ones equal to it (ties by index), and only the `k` kept are sorted.
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
        sel.hist[bucket_of(b)] += 1;
        zeros += usize::from(b == 0);
    }
    let nz = global.len() - zeros;
    let k = if keep == 0 { nz } else { keep }.min(nz).min(idx.len());
    if k == 0 {
        return 0;
    }
    // k < nz: τ is a non-zero magnitude; k == nz: τ = 0 keeps every non-zero one.
    let (tau, mut ties) = if k < nz {
        let (tau, greater) = kth_largest(global, k, sel);
        (tau, k - greater)
    } else {
        (0, 0)
    };
    sel.kept.clear();
    for (m, &c) in global.iter().enumerate() {
        let b = magnitude(c);
        if b > tau || (b == tau && ties > 0) {
            if b == tau {
                ties -= 1;
            }
            sel.kept.push((b, m as u32));
        }
    }
    sel.kept
        .sort_unstable_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
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
