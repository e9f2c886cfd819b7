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
    /// Per slot (a basis BRDF), the magnitude bits of the smallest coefficient the last row
    /// of that slot kept, 0 before the first: the next row's guess of its threshold.
    hint: Vec<u64>,
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
/// A threshold `t` such that at least `k` coefficients have a magnitude `≥ t` makes every
/// one of the `k` largest a candidate; the candidates are gathered in one pass, and a
/// selection and a sort of them in the order above leave the `k` kept. The threshold:
///
/// - first, half the smallest magnitude kept by the last row of the same `slot` (the rows
///   of one basis BRDF at neighbouring vertices and views have similar spectra), checked by
///   counting the magnitudes at or above it, a comparison per coefficient that the compiler
///   runs four at a time; it is used when the count is between `k` and [`HINT_SPREAD`]` · k`;
/// - otherwise a histogram of the magnitudes' exponent fields gives the highest exponent
///   `e` such that at least `k` coefficients have an exponent `≥ e` (rarely more than
///   twice as many candidates), at the cost of a counter increment per coefficient.
///
/// Either way the candidates include the `k` largest, so the result is the same.
pub(super) fn truncate_global(
    global: &[f64],
    sel: &mut Selection,
    slot: usize,
    keep: usize,
    idx: &mut [HaarIndex],
    val: &mut [TransportValue],
) -> usize {
    if sel.hint.len() <= slot {
        sel.hint.resize(slot + 1, 0);
    }
    // `want > 0` needs `keep > 0`: keeping every coefficient (`keep == 0`) has no hint.
    let (want, hint) = (keep.min(idx.len()), sel.hint[slot]);
    let hinted = (want > 0 && hint != 0)
        .then(|| hinted_threshold(global, hint, want))
        .flatten();
    let Some((k, lowest)) = hinted
        .map(|t| (want, t))
        .or_else(|| histogram_threshold(global, sel, keep, idx.len()))
    else {
        return 0;
    };
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
    sel.hint[slot] = sel.kept[k - 1].0;
    for ((i, v), &(_, m)) in idx.iter_mut().zip(val.iter_mut()).zip(sel.kept.iter()) {
        // m < n_global² ≤ 65,536 (checked in `check_inputs`).
        *i = m as HaarIndex;
        *v = TransportValue::from_f64(global[m as usize]);
    }
    k
}

/// Largest ratio of candidates to kept coefficients accepted from a hinted threshold
/// ([`truncate_global`]); beyond it the histogram's tighter threshold is cheaper than
/// selecting among the extra candidates.
const HINT_SPREAD: usize = 4;

/// The threshold from the last row's smallest kept magnitude bits `h` (halved: the exponent
/// field one lower, or the smallest positive magnitude), if at least `k` and at most
/// [`HINT_SPREAD`]` · k` coefficients reach it.
fn hinted_threshold(global: &[f64], h: u64, k: usize) -> Option<u64> {
    let t = if h >> 52 >= 1 { h - (1 << 52) } else { 1 };
    // The count compares `f64` magnitudes: non-negative floats order as their bits, and
    // a NaN (which the bits would rank above infinity) is not counted, so the count never
    // exceeds the number of candidates that the bit-wise gather collects.
    let tf = f64::from_bits(t);
    let count = count_at_least(global, tf);
    (count >= k && count <= HINT_SPREAD * k).then_some(t)
}

/// How many `|c| ≥ t` in `global`, compiled for AVX2 where the CPU has it.
fn count_at_least(global: &[f64], t: f64) -> usize {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports the feature the function is compiled for.
        return unsafe { count_at_least_avx2(global, t) };
    }
    count_at_least_impl(global, t)
}

/// [`count_at_least_impl`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn count_at_least_avx2(global: &[f64], t: f64) -> usize {
    count_at_least_impl(global, t)
}

/// The loop behind [`count_at_least`].
#[inline(always)]
fn count_at_least_impl(global: &[f64], t: f64) -> usize {
    global.iter().map(|c| u64::from(c.abs() >= t)).sum::<u64>() as usize
}

/// `(k, threshold bits)` from the exponent histogram (module docs of [`truncate_global`]),
/// or `None` when nothing is kept.
fn histogram_threshold(
    global: &[f64],
    sel: &mut Selection,
    keep: usize,
    room: usize,
) -> Option<(usize, u64)> {
    sel.hist.clear();
    sel.hist.resize(BUCKETS, 0);
    let mut zeros = 0usize;
    for &c in global {
        let b = magnitude(c);
        sel.hist[(b >> 52) as usize] += 1;
        zeros += usize::from(b == 0);
    }
    let nz = global.len() - zeros;
    let k = if keep == 0 { nz } else { keep }.min(nz).min(room);
    if k == 0 {
        return None;
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
    Some((k, lowest.max(1)))
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
        // every `keep` from 0 (all) past the non-zero count must agree exactly. One
        // `Selection` over all rows, so that later rows start from earlier rows' hints
        // (three slots, some hints far off): either threshold must give the same result.
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
                let k = truncate_global(&row, &mut sel, trial % 3, keep, &mut idx, &mut val);
                assert_eq!(k, want_idx.len(), "trial {trial} keep {keep}");
                for j in 0..k {
                    assert_eq!(u32::from(idx[j]), want_idx[j], "trial {trial} keep {keep}");
                    assert_eq!(val[j], TransportValue::from_f64(want_val[j]));
                }
            }
        }
    }

    #[test]
    fn a_hinted_threshold_keeps_what_a_full_sort_keeps() {
        // Rows like a transport's: 4,096 coefficients whose magnitudes fall over many
        // octaves, each row a rescaled, perturbed copy of the one before (the next view of
        // the same lobe), some with ties and zeros. Most rows must take the hinted threshold
        // (the count check accepts it), and every row must keep exactly the entries of
        // haar::keep_largest in its order; a hint far too high or too low must fall back.
        let mut rng = Pcg64::seed_from_u64(11);
        let base: Vec<f64> = (0..4096)
            .map(|m| rng.random_range(-1.0..1.0) * (-(m as f64) / 300.0).exp())
            .collect();
        let mut sel = Selection::default();
        let (mut hinted, keep) = (0, 128);
        for trial in 0..60 {
            let scale = 2f64.powf(rng.random_range(-0.5..0.5));
            let mut row: Vec<f64> = base
                .iter()
                .map(|&c| c * scale * (1.0 + 0.2 * rng.random_range(-1.0..1.0)))
                .collect();
            row[trial] = 0.0;
            row[100 + trial] = row[101 + trial];
            if sel.hint.first().is_some_and(|&h| h != 0) {
                hinted += usize::from(hinted_threshold(&row, sel.hint[0], keep).is_some());
            }
            let (want_idx, want_val, _) = haar::keep_largest(&row, keep, None);
            let mut idx = vec![0; keep];
            let mut val = vec![TransportValue::ZERO; keep];
            let k = truncate_global(&row, &mut sel, 0, keep, &mut idx, &mut val);
            assert_eq!(k, keep);
            for j in 0..k {
                assert_eq!(u32::from(idx[j]), want_idx[j], "trial {trial}");
                assert_eq!(val[j], TransportValue::from_f64(want_val[j]));
            }
        }
        assert!(hinted >= 50, "the hint was taken for {hinted} of 59 rows");
        let row = &base;
        let kth = {
            let mut m: Vec<u64> = row.iter().map(|&c| magnitude(c)).collect();
            m.sort_unstable_by(|a, b| b.cmp(a));
            m[keep - 1]
        };
        assert!(hinted_threshold(row, kth, keep).is_some());
        assert!(
            hinted_threshold(row, magnitude(1e300), keep).is_none(),
            "too high"
        );
        assert!(hinted_threshold(row, 1 << 52, keep).is_none(), "too low");
    }
}
