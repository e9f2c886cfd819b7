//! Order statistics the stages share.
//!
//! The median of `n` values sorted as `v₍₁₎ ≤ … ≤ v₍ₙ₎` is `v₍(n+1)/2₎` for odd `n` and
//! `½ (v₍n/2₎ + v₍n/2+1₎)` for even `n`: the value with at least half the values on
//! either side, and for even `n` the midpoint of the two that are.

/// The floating-point types the stages take medians of (`f64`, and the photos' `f32`),
/// with the arithmetic of the median in the type itself.
pub trait Float: Copy + std::ops::Add<Output = Self> + std::ops::Mul<Output = Self> {
    /// One half.
    const HALF: Self;
    /// IEEE 754 total order ([`f64::total_cmp`]).
    fn total_order(&self, other: &Self) -> std::cmp::Ordering;
}

impl Float for f64 {
    const HALF: f64 = 0.5;
    fn total_order(&self, other: &Self) -> std::cmp::Ordering {
        self.total_cmp(other)
    }
}

impl Float for f32 {
    const HALF: f32 = 0.5;
    fn total_order(&self, other: &Self) -> std::cmp::Ordering {
        self.total_cmp(other)
    }
}

/// The median of `v` (module docs), computed in `T`; `None` when `v` is empty. Sorts `v`
/// in the total order, so a NaN sorts last (or first, when negative) instead of
/// panicking.
pub fn median<T: Float>(v: &mut [T]) -> Option<T> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(T::total_order);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        T::HALF * (v[n / 2 - 1] + v[n / 2])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the definition itself, brute force: for odd `n` the value with at least
    /// `(n+1)/2` values `≤` it and `≥` it; for even `n` the mean of the smallest value with
    /// `n/2` values `≤` it and the largest with `n/2` values `≥` it. The small
    /// integers make every comparison and midpoint exact, so equality is exact.
    #[test]
    fn the_median_matches_its_definition_by_counting() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % 7) as f64
        };
        for n in 1usize..=12 {
            for _ in 0..50 {
                let v: Vec<f64> = (0..n).map(|_| next()).collect();
                let le = |m: f64| v.iter().filter(|&&x| x <= m).count();
                let ge = |m: f64| v.iter().filter(|&&x| x >= m).count();
                let want = if n % 2 == 1 {
                    let half = n.div_ceil(2);
                    *v.iter().find(|&&m| le(m) >= half && ge(m) >= half).unwrap()
                } else {
                    let lo = v
                        .iter()
                        .copied()
                        .filter(|&m| le(m) >= n / 2)
                        .fold(f64::MAX, f64::min);
                    let hi = v
                        .iter()
                        .copied()
                        .filter(|&m| ge(m) >= n / 2)
                        .fold(f64::MIN, f64::max);
                    0.5 * (lo + hi)
                };
                let mut w = v.clone();
                assert_eq!(median(&mut w), Some(want), "{v:?}");
            }
        }
        assert_eq!(median::<f64>(&mut []), None);
        // In `f32` the midpoint is the `f32` one, as the photos' values are.
        let (a, b) = (0.1f32, 0.7f32);
        assert_eq!(median(&mut [b, a]), Some(0.5f32 * (a + b)));
    }
}
