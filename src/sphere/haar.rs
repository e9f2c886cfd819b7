//! The 2D non-standard Haar wavelet transform on `n × n` texel maps (`n` a power of two),
//! the basis in which the paper (Sec. 4.1, Eq. 2–5) expresses lighting, visibility and
//! BRDF slices.
//!
//! Orthonormal as a matrix `W` on the texel vector (`x ↦ W x`, `Wᵀ W = I`), so Parseval
//! holds: `Σ_t x_t² = Σ_k (W x)_k²`, and `Σ_t f_t g_t = Σ_k (W f)_k (W g)_k`.
//!
//! One level on an `s × s` block replaces each 2×2 group `p00 p01 / p10 p11` (row, column)
//! by its scaling coefficient and three details:
//!
//! ```text
//! a = (p00 + p01 + p10 + p11) / 2      h = (p00 − p01 + p10 − p11) / 2   (+ on the left column)
//! v = (p00 + p01 − p10 − p11) / 2      d = (p00 − p01 − p10 + p11) / 2   (+ on the top row)
//! ```
//!
//! Layout (index `k = row · n + col`, as the texels): with `m = s/2` nodes per side at that
//! level, node `(r, c)` (`r, c < m`) puts `a` at `(r, c)`, `h` at `(r, c + m)`, `v` at
//! `(r + m, c)`, `d` at `(r + m, c + m)`; the next level recurses on the `m × m` top-left
//! block of `a`s. After all levels, `k = 0` is the scaling coefficient (`Σ_t x_t / n`), and
//! every other `k` is a wavelet: with `m` the power of two such that `m ≤ max(row, col) < 2m`
//! ([`coefficient`]), it lives at level `m` (nodes per side), node `(row mod m, col mod m)`,
//! type `h` (row < m), `v` (col < m) or `d`; its support is the `n/m × n/m` texel square of
//! that node and its value there is `±m/n`.

/// Which basis function a Haar coefficient index names (layout in the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coefficient {
    /// `k = 0`: the constant `1/n`.
    Scaling,
    /// A wavelet at level `m` (nodes per side: 1, 2, …, n/2), node `(r, c)`, of type `ty`.
    Wavelet {
        /// Nodes per side at this level; the support is `n/m` texels wide.
        m: usize,
        /// Node row (`< m`).
        r: usize,
        /// Node column (`< m`).
        c: usize,
        /// Detail type.
        ty: WaveletType,
    },
}

/// The three Haar detail types of one node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaveletType {
    /// Sign `+` on the left half of the support, `−` on the right.
    H,
    /// Sign `+` on the top half, `−` on the bottom.
    V,
    /// Product `H · V`.
    D,
}

impl WaveletType {
    /// Sign of this wavelet on quadrant `(dr, dc)` (0 = top/left, 1 = bottom/right).
    pub fn sign(self, dr: usize, dc: usize) -> f64 {
        let sh = if dc == 0 { 1.0 } else { -1.0 };
        let sv = if dr == 0 { 1.0 } else { -1.0 };
        match self {
            WaveletType::H => sh,
            WaveletType::V => sv,
            WaveletType::D => sh * sv,
        }
    }
}

/// The basis function of coefficient `k` on an `n × n` map.
pub fn coefficient(n: usize, k: usize) -> Coefficient {
    let (row, col) = (k / n, k % n);
    if k == 0 {
        return Coefficient::Scaling;
    }
    let hi = row.max(col);
    let m = 1usize << (usize::BITS - 1 - hi.leading_zeros());
    let (r, c, ty) = if row < m {
        (row, col - m, WaveletType::H)
    } else if col < m {
        (row - m, col, WaveletType::V)
    } else {
        (row - m, col - m, WaveletType::D)
    };
    Coefficient::Wavelet { m, r, c, ty }
}

/// Coefficient index of the wavelet of type `ty` at level `m`, node `(r, c)`.
pub fn wavelet_index(n: usize, m: usize, r: usize, c: usize, ty: WaveletType) -> usize {
    match ty {
        WaveletType::H => r * n + c + m,
        WaveletType::V => (r + m) * n + c,
        WaveletType::D => (r + m) * n + c + m,
    }
}

/// Value of basis function `k` at texel `t` (the row `k` of `W`, column `t`).
pub fn basis_value(n: usize, k: usize, t: usize) -> f64 {
    match coefficient(n, k) {
        Coefficient::Scaling => 1.0 / n as f64,
        Coefficient::Wavelet { m, r, c, ty } => {
            let s = n / m;
            let (ti, tj) = (t % n, t / n);
            if tj / s != r || ti / s != c {
                return 0.0;
            }
            let dr = usize::from((tj % s) >= s / 2);
            let dc = usize::from((ti % s) >= s / 2);
            ty.sign(dr, dc) * m as f64 / n as f64
        }
    }
}

/// Floats the transform runs on (`f32` for compact storage, `f64` for exactness).
pub trait Real:
    Copy
    + Default
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
{
    /// One half.
    const HALF: Self;
}
impl Real for f64 {
    const HALF: f64 = 0.5;
}
impl Real for f32 {
    const HALF: f32 = 0.5;
}

/// Three channels transformed as one value: every operation is done channel by channel,
/// so the transform of an interleaved RGB map equals its three channels' transforms bit
/// for bit, in one pass over the map instead of three.
#[derive(Clone, Copy, Default, Debug, PartialEq)]
pub struct Rgb(pub [f64; 3]);

impl std::ops::Add for Rgb {
    type Output = Rgb;
    #[inline(always)]
    fn add(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}
impl std::ops::Sub for Rgb {
    type Output = Rgb;
    #[inline(always)]
    fn sub(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}
impl std::ops::Mul for Rgb {
    type Output = Rgb;
    #[inline(always)]
    fn mul(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] * o.0[0], self.0[1] * o.0[1], self.0[2] * o.0[2]])
    }
}
impl Real for Rgb {
    const HALF: Rgb = Rgb([0.5; 3]);
}

fn check_len(len: usize, n: usize) {
    assert!(
        n.is_power_of_two() && len == n * n,
        "Haar transform of {len} values as a {n}×{n} map: n must be a power of two and len = n²"
    );
}

/// Forward transform in place, generic over [`Real`]; `scratch` is resized as needed.
pub fn forward_with<T: Real>(data: &mut [T], n: usize, scratch: &mut Vec<T>) {
    check_len(data.len(), n);
    scratch.resize(n * n, T::default());
    forward_levels(data, n, n, scratch);
}

/// [`forward_with`] of vector `i` of `k` interleaved ones (`src[m · k + i]`, `m < n²`)
/// into `data`. The finest level reads `src` directly and writes its sums and differences
/// to their places in `data`, so neither a de-interleaved copy nor that level's copy back
/// from `scratch` is made; every value is the same sum as [`forward_with`]'s, so the result
/// is equal bit for bit. `scratch` holds at least `(n/2)²` values.
pub fn forward_interleaved<T: Real>(
    src: &[T],
    k: usize,
    i: usize,
    data: &mut [T],
    n: usize,
    scratch: &mut [T],
) {
    check_len(data.len(), n);
    assert!(
        i < k && src.len() >= n * n * k,
        "interleaved Haar: vector {i} of {k}"
    );
    if n < 2 {
        data[0] = src[i];
        return;
    }
    forward_level(|p| src[p * k + i], n, n, data, n);
    forward_levels(data, n, n / 2, scratch);
}

/// One level of the forward transform: the `s × s` block read through `at` (row stride
/// `n`) into its averages (top left) and horizontal, vertical and diagonal differences,
/// written to `out` with row stride `out_n`.
#[inline(always)]
fn forward_level<T: Real>(
    at: impl Fn(usize) -> T,
    n: usize,
    s: usize,
    out: &mut [T],
    out_n: usize,
) {
    let m = s / 2;
    for r in 0..m {
        let (top, bot) = (2 * r * n, 2 * r * n + n);
        for c in 0..m {
            let (p00, p01) = (at(top + 2 * c), at(top + 2 * c + 1));
            let (p10, p11) = (at(bot + 2 * c), at(bot + 2 * c + 1));
            let (sum0, dif0) = (p00 + p01, p00 - p01);
            let (sum1, dif1) = (p10 + p11, p10 - p11);
            out[r * out_n + c] = T::HALF * (sum0 + sum1);
            out[r * out_n + c + m] = T::HALF * (dif0 + dif1);
            out[(r + m) * out_n + c] = T::HALF * (sum0 - sum1);
            out[(r + m) * out_n + c + m] = T::HALF * (dif0 - dif1);
        }
    }
}

/// The levels of the forward transform from the `s × s` top-left block of `data` (side
/// `n`) down: each level's averages and differences via `scratch` (at least `s²` values),
/// copied back.
fn forward_levels<T: Real>(data: &mut [T], n: usize, mut s: usize, scratch: &mut [T]) {
    assert!(
        scratch.len() >= s * s,
        "Haar scratch of {} for {s}²",
        scratch.len()
    );
    while s >= 2 {
        let m = s / 2;
        forward_level(|p| data[p], n, s, scratch, s);
        for r in 0..s {
            data[r * n..r * n + s].copy_from_slice(&scratch[r * s..r * s + s]);
        }
        s = m;
    }
}

/// Inverse transform in place, generic over [`Real`]; `scratch` is resized as needed.
pub fn inverse_with<T: Real>(data: &mut [T], n: usize, scratch: &mut Vec<T>) {
    check_len(data.len(), n);
    scratch.resize(n * n, T::default());
    let mut s = 2;
    while s <= n {
        let m = s / 2;
        for r in 0..m {
            for c in 0..m {
                let a = data[r * n + c];
                let h = data[r * n + c + m];
                let v = data[(r + m) * n + c];
                let d = data[(r + m) * n + c + m];
                let (av, ave) = (a + v, a - v);
                let (hd, hde) = (h + d, h - d);
                scratch[2 * r * s + 2 * c] = T::HALF * (av + hd);
                scratch[2 * r * s + 2 * c + 1] = T::HALF * (av - hd);
                scratch[(2 * r + 1) * s + 2 * c] = T::HALF * (ave + hde);
                scratch[(2 * r + 1) * s + 2 * c + 1] = T::HALF * (ave - hde);
            }
        }
        for r in 0..s {
            data[r * n..r * n + s].copy_from_slice(&scratch[r * s..r * s + s]);
        }
        s *= 2;
    }
}

/// Forward transform `x ← W x` of an `n × n` map (`data.len() == n²`), in place.
/// Panics if `n` is not a power of two or the length does not match (a programming error).
pub fn forward(data: &mut [f64], n: usize) {
    forward_with(data, n, &mut Vec::new());
}

/// Inverse transform `x ← Wᵀ x`, in place.
pub fn inverse(data: &mut [f64], n: usize) {
    inverse_with(data, n, &mut Vec::new());
}

/// [`forward`] in `f32`.
pub fn forward_f32(data: &mut [f32], n: usize) {
    forward_with(data, n, &mut Vec::new());
}

/// [`inverse`] in `f32`.
pub fn inverse_f32(data: &mut [f32], n: usize) {
    inverse_with(data, n, &mut Vec::new());
}

/// Non-linear approximation: the `k` coefficients with the largest score `|c_i| · w_i`
/// (`w_i = 1` without weights; e.g. pass solid-angle-derived weights). Returns their indices
/// and values, largest score first (ties by index), and the dropped energy `Σ c_i²` of the
/// rest. Zero coefficients are never kept.
pub fn keep_largest(
    coeffs: &[f64],
    k: usize,
    weights: Option<&[f64]>,
) -> (Vec<u32>, Vec<f64>, f64) {
    let score = |i: usize| coeffs[i].abs() * weights.map_or(1.0, |w| w[i]);
    let mut order: Vec<usize> = (0..coeffs.len()).filter(|&i| coeffs[i] != 0.0).collect();
    let cmp = |a: &usize, b: &usize| score(*b).total_cmp(&score(*a)).then(a.cmp(b));
    let k = k.min(order.len());
    if k < order.len() && k > 0 {
        order.select_nth_unstable_by(k - 1, cmp);
    }
    let dropped: f64 = order[k..].iter().map(|&i| coeffs[i] * coeffs[i]).sum();
    let kept = &mut order[..k];
    kept.sort_unstable_by(cmp);
    let idx: Vec<u32> = kept.iter().map(|&i| i as u32).collect();
    let val: Vec<f64> = kept.iter().map(|&i| coeffs[i]).collect();
    (idx, val, dropped)
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // index loops mirror the sums being checked
pub(crate) mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// `n × n` values uniform in [−1, 1), seeded (also used by the triple-product tests).
    pub(crate) fn random(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = Pcg64::seed_from_u64(seed);
        (0..n * n).map(|_| rng.random_range(-1.0..1.0)).collect()
    }

    #[test]
    fn inverse_forward_is_identity_and_parseval_holds() {
        // Each value passes through log2(n) butterflies of 2 adds and 1 multiply: relative
        // error a few ulp per level, so 1e-13 on O(1) data.
        for n in [1, 2, 4, 8, 32, 64] {
            let x = random(n, n as u64);
            let mut y = x.clone();
            forward(&mut y, n);
            let ex: f64 = x.iter().map(|v| v * v).sum();
            let ey: f64 = y.iter().map(|v| v * v).sum();
            assert!((ex - ey).abs() < 1e-12 * ex.max(1.0), "Parseval n={n}");
            assert!((y[0] - x.iter().sum::<f64>() / n as f64).abs() < 1e-12);
            inverse(&mut y, n);
            for (a, b) in x.iter().zip(&y) {
                assert!((a - b).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn the_interleaved_forward_transform_equals_the_plain_one_bit_for_bit() {
        // Reference: forward_with on each vector alone. Three interleaved vectors at every
        // side from 1 to 32 must give the same bits (the same sums in the same order).
        for n in [1usize, 2, 4, 8, 32] {
            let k = 3;
            let vecs: Vec<Vec<f64>> = (0..k).map(|i| random(n, 40 + i as u64)).collect();
            let mut src = vec![0.0; n * n * k];
            for (i, v) in vecs.iter().enumerate() {
                for (m, &x) in v.iter().enumerate() {
                    src[m * k + i] = x;
                }
            }
            let mut scratch = vec![0.0; (n / 2) * (n / 2)];
            for (i, v) in vecs.iter().enumerate() {
                let mut want = v.clone();
                forward_with(&mut want, n, &mut Vec::new());
                let mut got = vec![f64::NAN; n * n];
                forward_interleaved(&src, k, i, &mut got, n, &mut scratch);
                let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&want), "n = {n}, vector {i}");
            }
        }
    }

    #[test]
    fn rgb_transforms_equal_the_three_channels_transforms_bit_for_bit() {
        // Reference: each channel alone through the f64 transform. `Rgb` does the same
        // operations channel by channel, so both directions must give the same bits.
        for n in [1usize, 2, 4, 8, 32] {
            let ch: Vec<Vec<f64>> = (0..3).map(|c| random(n, 60 + c as u64)).collect();
            let rgb = |i: usize| Rgb([ch[0][i], ch[1][i], ch[2][i]]);
            let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            for inverse_dir in [false, true] {
                let mut got: Vec<Rgb> = (0..n * n).map(rgb).collect();
                let mut scratch = Vec::new();
                if inverse_dir {
                    inverse_with(&mut got, n, &mut scratch);
                } else {
                    forward_with(&mut got, n, &mut scratch);
                }
                for (c, v) in ch.iter().enumerate() {
                    let mut want = v.clone();
                    if inverse_dir {
                        inverse(&mut want, n);
                    } else {
                        forward(&mut want, n);
                    }
                    let col: Vec<f64> = got.iter().map(|x| x.0[c]).collect();
                    assert_eq!(bits(&col), bits(&want), "n = {n}, channel {c}");
                }
            }
        }
    }

    #[test]
    fn forward_matches_the_basis_functions() {
        // (W x)_k = Σ_t ψ_k(t) x_t with ψ_k from the documented layout: checks the layout.
        let n = 8;
        let x = random(n, 7);
        let mut y = x.clone();
        forward(&mut y, n);
        for k in 0..n * n {
            let direct: f64 = (0..n * n).map(|t| basis_value(n, k, t) * x[t]).sum();
            assert!((direct - y[k]).abs() < 1e-13, "coefficient {k}");
            if let Coefficient::Wavelet { m, r, c, ty } = coefficient(n, k) {
                assert_eq!(wavelet_index(n, m, r, c, ty), k);
            }
        }
    }

    #[test]
    fn f32_matches_f64() {
        // f32 rounding: ~6e-8 relative per level, 6 levels, O(1) values: 1e-5.
        let n = 64;
        let x = random(n, 3);
        let mut y64 = x.clone();
        forward(&mut y64, n);
        let mut y32: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        forward_f32(&mut y32, n);
        for (a, b) in y64.iter().zip(&y32) {
            assert!((a - *b as f64).abs() < 1e-5);
        }
        inverse_f32(&mut y32, n);
        for (a, b) in x.iter().zip(&y32) {
            assert!((a - *b as f64).abs() < 1e-5);
        }
    }

    #[test]
    fn keep_largest_keeps_the_largest_and_reports_dropped_energy() {
        let c = [0.5, -3.0, 0.0, 2.0, -0.1, 1.0];
        let (idx, val, dropped) = keep_largest(&c, 3, None);
        assert_eq!(idx, vec![1, 3, 5]);
        assert_eq!(val, vec![-3.0, 2.0, 1.0]);
        assert!((dropped - (0.25 + 0.01)).abs() < 1e-15);
        // Weights change the order: |c|·w.
        let w = [10.0, 1.0, 1.0, 1.0, 100.0, 1.0];
        let (idx, _, _) = keep_largest(&c, 2, Some(&w));
        assert_eq!(idx, vec![4, 0]); // scores 0.1·100 = 10 > 0.5·10 = 5
                                     // k beyond the non-zero count keeps all non-zeros and drops nothing.
        let (idx, _, dropped) = keep_largest(&c, 100, None);
        assert_eq!(idx.len(), 5);
        assert_eq!(dropped, 0.0);
    }
}
