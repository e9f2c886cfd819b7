//! Truncation of a transport row to its `keep` largest-magnitude Haar coefficients (module
//! docs of [`crate::transport`]): keeping the largest minimises the `ℓ²` norm of what is
//! dropped, hence the worst-case response error `‖g_drop‖ ‖L̃‖`.

use super::{HaarIndex, TransportValue};
#[cfg(doc)]
use crate::sphere::haar;

/// Reused buffers of [`truncate_global`].
#[derive(Default)]
pub(super) struct Selection {
    /// `|g_m|` as IEEE bits of every coefficient (ordered as the magnitudes:
    /// non-negative floats compare as their bit patterns, NaN above infinity as in
    /// `f64::total_cmp`).
    keys: Vec<u64>,
    /// `(|g_m| bits, m)` of the kept coefficients.
    kept: Vec<(u64, u32)>,
}

/// The `keep` largest-magnitude non-zero coefficients of the dense row `global` (all
/// non-zero ones for `keep == 0`) into `idx`/`val`, largest first, ties by index: the same
/// entries in the same order as [`haar::keep_largest`], without allocating; `sel` holds
/// the buffers. Returns how many were kept (`≤ idx.len()`).
///
/// The `k`-th largest magnitude `τ` is found by a selection over the magnitudes' bit
/// patterns alone; one pass in index order then keeps every coefficient above `τ` and the
/// first ones equal to it (ties by index), and only the `k` kept are sorted.
pub(super) fn truncate_global(
    global: &[f64],
    sel: &mut Selection,
    keep: usize,
    idx: &mut [HaarIndex],
    val: &mut [TransportValue],
) -> usize {
    let magnitude = |c: f64| c.abs().to_bits();
    // Zeros (key 0, −0.0 included) stay in the selection: they are the smallest keys and
    // are never kept, and skipping them would cost a hard-to-predict branch per entry.
    sel.keys.clear();
    sel.keys.extend(global.iter().map(|&c| magnitude(c)));
    let n = sel.keys.len();
    let nz = sel.keys.iter().filter(|&&b| b != 0).count();
    let k = if keep == 0 { nz } else { keep }.min(nz).min(idx.len());
    if k == 0 {
        return 0;
    }
    // k < nz: τ is a non-zero magnitude; k == nz: τ = 0 keeps every non-zero one.
    let (tau, mut ties) = if k < nz {
        let (_, &mut tau, above) = sel.keys.select_nth_unstable(n - k);
        let greater = above.iter().filter(|&&b| b > tau).count();
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
        // ties by index). Rows with zeros, repeated magnitudes of both signs (ties) and
        // every `keep` from 0 (all) past the non-zero count must agree exactly.
        let mut rng = Pcg64::seed_from_u64(7);
        let mut sel = Selection::default();
        for trial in 0..200 {
            let n = 1 + trial % 97;
            let row: Vec<f64> = (0..n)
                .map(|_| match rng.random_range(0..4) {
                    0 => 0.0,
                    1 => f64::from(rng.random_range(-3i32..=3)) * 0.25,
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
