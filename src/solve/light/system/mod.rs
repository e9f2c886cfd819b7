//! One photo's lighting system in the Haar basis (Eq. 10): the observations' transport rows
//! blended with `β` into one sparse row per observation, and the products `A h`, `Aᵀ u`
//! and `Aᵀ D A h` the matrix-free QP needs; plus the texel-basis diagonal of `Wᵀ Aᵀ D A W`
//! that scales the QP and sets the smoothness weight `μ`.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::solve::problem::Problem;
use crate::sphere::haar;
use crate::transport::HaarIndex;

/// One photo's data for the lighting step.
///
/// With `β` fixed for the whole lighting step, an observation's `B` transport rows enter
/// every product only through their per-channel blend `e_{p,c} = Σ_b β_{x,b,c} g_{p,b}`.
/// [`PhotoSystem::new`] merges them once into one sparse row per observation (the union of
/// the bases' kept indices, ascending, values `[f32; 3]`, one per channel), so a product
/// costs one gather or scatter per merged entry instead of `B` per kept entry. The blend
/// is summed in `f64` in basis order and rounded once to `f32` (relative error ≤ 2⁻²⁴, the
/// precision the transport values are stored in); forward and adjoint products read the
/// same stored values, so the Hessian stays exactly symmetric.
///
/// With a tolerance `ε` > 0 ([`crate::solve::EstimateOptions::blend_tolerance`]) each
/// merged row then drops its smallest entries (by `Σ_c e_{p,c}²`) for as long as their
/// summed energy stays within `ε` of the row's ([`cut_to_energy`]): the cut row is within
/// `√ε` of the exact one in `ℓ²`, relative to its norm (3.2% at the default 10⁻³), and of
/// all cuts that drop that many entries this one drops the least. The bases' kept sets
/// overlap only in part (at 7 lobes × 128 kept, the union holds ~290 entries) while the
/// blend's energy sits in its largest entries: at 100K vertices protocol (b)'s light fits,
/// whose every step is a product over these rows, took 27% less CPU
/// (`bench-results/blend-tolerance.md`).
pub(crate) struct PhotoSystem {
    /// `0..rows`: the system's rows (the photo's observations, or its lighting sample).
    pub(crate) range: std::ops::Range<usize>,
    pub(crate) n: usize,
    /// `α_p ω_{p,c}` for the range's observations.
    pub(crate) dw: Vec<[f64; 3]>,
    /// Merged row `q` (range order) spans `index[offsets[q]..offsets[q + 1]]`.
    pub(crate) offsets: Vec<usize>,
    /// Haar coefficient indices of the merged rows, ascending within a row (2 bytes, the
    /// transport's own index type: 14 bytes an entry with the values, was 16).
    pub(crate) index: Vec<HaarIndex>,
    /// `e_{p,c}` at those indices.
    pub(crate) value: Vec<[f32; 3]>,
    /// The merged rows cut into [`PRODUCT_CHUNKS`] contiguous ranges of about equal
    /// entries: the parallel parts of [`Self::normal_rows`].
    pub(crate) chunks: Vec<std::ops::Range<usize>>,
}

/// Parts of one lighting-step product ([`PhotoSystem::normal_rows`]): each part's rows are
/// scattered into a buffer of its own, in parallel, and the buffers summed in part order.
/// A fixed number, not the thread count, so the sum (and every result) does not depend on
/// the machine. Lone QPs (protocol (b)'s light fits, the last photos of a lighting step)
/// then use every core; inside the estimate's parallel photos the parts only add a
/// `PRODUCT_CHUNKS × n²` buffer sum to a product that reads every merged row.
pub(crate) const PRODUCT_CHUNKS: usize = 4;

/// Merged entries from which [`PhotoSystem::normal_rows`] runs its parts in parallel;
/// smaller products run them one after another on the calling thread (the same parts
/// summed in the same order, so the same result): there a task per part costs more than
/// it saves, and the estimate already runs its photos in parallel.
pub(crate) const PARALLEL_PRODUCT_ENTRIES: usize = 1 << 17;

/// `parts` contiguous ranges of `0..offsets.len() − 1` (rows), cut where the running entry
/// count `offsets[q]` crosses `k/parts` of the total; empty ranges are dropped.
pub(crate) fn entry_chunks(offsets: &[usize], parts: usize) -> Vec<std::ops::Range<usize>> {
    let rows = offsets.len().saturating_sub(1);
    let total = offsets.last().copied().unwrap_or(0);
    let mut cuts = vec![0];
    for k in 1..parts {
        let target = total * k / parts;
        let q = offsets.partition_point(|&o| o < target).min(rows);
        cuts.push(q.max(*cuts.last().unwrap_or(&0)));
    }
    cuts.push(rows);
    cuts.windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| w[0]..w[1])
        .collect()
}

/// `⟨e_c, h_c⟩` per channel for one merged transport row (`idx`, `val`) and a light `h`
/// (interleaved Haar): the forward half of the lighting step's products.
#[inline]
pub(crate) fn row_dot(idx: &[HaarIndex], val: &[[f32; 3]], h: &[[f64; 3]]) -> [f64; 3] {
    let mut acc = [0.0_f64; 3];
    row_dot_add(&mut acc, idx, val, h);
    acc
}

/// `acc_c += ⟨e_c, h_c⟩`, entry by entry in row order.
#[inline]
fn row_dot_add(acc: &mut [f64; 3], idx: &[HaarIndex], val: &[[f32; 3]], h: &[[f64; 3]]) {
    for (&m, e) in idx.iter().zip(val) {
        let hm = &h[m as usize];
        acc[0] += e[0] as f64 * hm[0];
        acc[1] += e[1] as f64 * hm[1];
        acc[2] += e[2] as f64 * hm[2];
    }
}

/// [`row_dot`] of two rows at once, bit for bit: each row's sums run over its own entries
/// in its own order, the two rows' entries interleaved so that their six dependency chains
/// overlap (one row's three chains wait on the add latency, ~4 cycles an entry).
#[inline]
pub(crate) fn row_dot_pair(
    a: (&[HaarIndex], &[[f32; 3]]),
    b: (&[HaarIndex], &[[f32; 3]]),
    h: &[[f64; 3]],
) -> [[f64; 3]; 2] {
    let (mut x, mut y) = ([0.0_f64; 3], [0.0_f64; 3]);
    let k = a.0.len().min(b.0.len());
    let ea = a.0[..k].iter().zip(&a.1[..k]);
    let eb = b.0[..k].iter().zip(&b.1[..k]);
    for ((&ma, va), (&mb, vb)) in ea.zip(eb) {
        let (ha, hb) = (&h[ma as usize], &h[mb as usize]);
        x[0] += va[0] as f64 * ha[0];
        y[0] += vb[0] as f64 * hb[0];
        x[1] += va[1] as f64 * ha[1];
        y[1] += vb[1] as f64 * hb[1];
        x[2] += va[2] as f64 * ha[2];
        y[2] += vb[2] as f64 * hb[2];
    }
    row_dot_add(&mut x, &a.0[k..], &a.1[k..], h);
    row_dot_add(&mut y, &b.0[k..], &b.1[k..], h);
    [x, y]
}

/// `out_c += e_c u_c` for one merged transport row: the adjoint half.
#[inline]
pub(crate) fn row_scatter(idx: &[HaarIndex], val: &[[f32; 3]], u: [f64; 3], out: &mut [[f64; 3]]) {
    for (&m, e) in idx.iter().zip(val) {
        let o = &mut out[m as usize];
        o[0] += e[0] as f64 * u[0];
        o[1] += e[1] as f64 * u[1];
        o[2] += e[2] as f64 * u[2];
    }
}

impl PhotoSystem {
    /// Merge the range's transport rows with `β`, each cut within the energy tolerance
    /// `eps` (0: the exact blend; struct docs).
    pub(crate) fn new(
        problem: &Problem,
        beta: &[[f64; 3]],
        rows: impl IntoIterator<Item = usize>,
        n: usize,
        dw: Vec<[f64; 3]>,
        eps: f64,
    ) -> Self {
        let t = problem.transport;
        let nb = t.n_basis;
        let n2 = n * n;
        let mut dense = vec![[0.0_f64; 3]; n2];
        // The row's indices as a bitmap over `n²`: read word by word, lowest bit first, it
        // gives them in ascending order without a sort.
        let mut seen = vec![0_u64; n2.div_ceil(64)];
        let mut offsets = Vec::with_capacity(dw.len() + 1);
        offsets.push(0);
        let mut index = Vec::new();
        let mut value = Vec::new();
        let mut sorted = Vec::new();
        for p in rows {
            let start = index.len();
            let x = problem.obs.vertex[p] as usize;
            for b in 0..nb {
                let be = beta[x * nb + b];
                if be == [0.0; 3] {
                    continue;
                }
                let (idx, val) = t.row(p, b);
                for (&m, &g) in idx.iter().zip(val) {
                    let mu = m as usize;
                    seen[mu / 64] |= 1 << (mu % 64);
                    let g = f64::from(g);
                    let d = &mut dense[mu];
                    d[0] += be[0] * g;
                    d[1] += be[1] * g;
                    d[2] += be[2] * g;
                }
            }
            for (w, word) in seen.iter_mut().enumerate() {
                let mut bits = std::mem::take(word);
                while bits != 0 {
                    let mu = w * 64 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let d = std::mem::take(&mut dense[mu]);
                    if d != [0.0; 3] {
                        // `mu < n²`, a Haar index of the transport: it fits `HaarIndex`.
                        index.push(mu as HaarIndex);
                        value.push(d.map(|v| v as f32));
                    }
                }
            }
            if eps > 0.0 {
                cut_to_energy(&mut index, &mut value, start, eps, &mut sorted);
            }
            offsets.push(index.len());
        }
        // One entry past the last row: the AVX2 product loads each entry's three `f32`
        // as four (the fourth ignored), and the last entry's fourth comes from here.
        value.push([0.0; 3]);
        let chunks = entry_chunks(&offsets, PRODUCT_CHUNKS);
        PhotoSystem {
            range: 0..offsets.len() - 1,
            n,
            dw,
            offsets,
            index,
            value,
            chunks,
        }
    }

    /// Merged row `q` (range order): indices and per-channel values.
    pub(crate) fn merged(&self, q: usize) -> (&[HaarIndex], &[[f32; 3]]) {
        let (lo, hi) = (self.offsets[q], self.offsets[q + 1]);
        (&self.index[lo..hi], &self.value[lo..hi])
    }

    /// `s_{p,c} = Σ_b β_{x,b,c} ⟨g_{p,b}, h_c⟩ = ⟨e_{p,c}, h_c⟩` for the range (`h`
    /// interleaved Haar).
    pub(crate) fn forward_rows(&self, h: &[[f64; 3]], out: &mut [[f64; 3]]) {
        debug_assert_eq!(out.len(), self.range.len());
        for (q, o) in out.iter_mut().enumerate() {
            let (idx, val) = self.merged(q);
            *o = row_dot(idx, val, h);
        }
    }

    /// `out += Aᵀ u` in the Haar basis (`u` per observation of the range and channel).
    pub(crate) fn adjoint_rows(&self, u: &[[f64; 3]], out: &mut [[f64; 3]]) {
        for (q, uq) in u.iter().enumerate() {
            if *uq == [0.0; 3] {
                continue;
            }
            let (idx, val) = self.merged(q);
            row_scatter(idx, val, *uq, out);
        }
    }

    /// The data term's right-hand side `Wᵀ Aᵀ D y` in the texel basis, `y` per observation
    /// of the range (`D = dw`, `W` the Haar synthesis, [`unhaar3`]).
    pub(crate) fn texel_rhs(&self, y: &[[f64; 3]]) -> Vec<f64> {
        let u: Vec<[f64; 3]> = y
            .iter()
            .zip(&self.dw)
            .map(|(yq, d)| [0, 1, 2].map(|c| d[c] * yq[c]))
            .collect();
        let mut hb = vec![[0.0; 3]; self.n * self.n];
        self.adjoint_rows(&u, &mut hb);
        unhaar3(&hb, self.n)
    }

    /// `out += Aᵀ D A h` in the Haar basis (`D = dw`), one pass over the merged rows:
    /// each row's response is formed and scattered back at once, so the rows are read
    /// once per product instead of twice. The rows are cut into [`PRODUCT_CHUNKS`] parts
    /// done in parallel, each into its own buffer, then added to `out` in part order.
    /// Rows of zero weight are skipped, the others taken in pairs ([`row_dot_pair`]), with
    /// AVX2 where the CPU has it ([`Self::normal_part_avx2`]); all three forms give the
    /// same result bit for bit (`bench-results/example-speed.md`: −24% CPU on the built-in
    /// example with the pilot's and the replay's levers).
    pub(crate) fn normal_rows(&self, h: &[[f64; 3]], out: &mut [[f64; 3]]) {
        #[cfg(target_arch = "x86_64")]
        if self.value.len() > self.index.len() && std::is_x86_feature_detected!("avx2") {
            let h4: Vec<[f64; 4]> = h.iter().map(|v| [v[0], v[1], v[2], 0.0]).collect();
            let part = |rows: &std::ops::Range<usize>| {
                let mut acc = vec![[0.0_f64; 4]; out.len()];
                // SAFETY: the CPU has AVX2 (the condition above).
                unsafe { self.normal_part_avx2(rows.clone(), &h4, &mut acc) };
                acc
            };
            add_parts(&self.map_parts(part), out);
            return;
        }
        let part = |rows: &std::ops::Range<usize>| {
            let mut acc = vec![[0.0_f64; 3]; out.len()];
            // A row of zero weight `d` adds nothing (`d ⊙ r = 0` for the finite response
            // `r`): skipped before its dot (protocol (b)'s right half, held-out
            // observations). The others in pairs: both dots (they read `h` only), then
            // both scatters in row order, so `acc` sees the same additions in the same
            // order as row by row.
            let mut live = rows.clone().filter(|&q| self.dw[q] != [0.0; 3]);
            while let Some(q) = live.next() {
                let a = self.merged(q);
                match live.next() {
                    Some(q2) => {
                        let b = self.merged(q2);
                        let [ra, rb] = row_dot_pair(a, b, h);
                        self.scatter_weighted(q, a, ra, &mut acc);
                        self.scatter_weighted(q2, b, rb, &mut acc);
                    }
                    None => self.scatter_weighted(q, a, row_dot(a.0, a.1, h), &mut acc),
                }
            }
            acc
        };
        add_parts(&self.map_parts(part), out);
    }

    /// `part` of every one of the product's parts, in part order: in parallel from
    /// [`PARALLEL_PRODUCT_ENTRIES`] merged entries, else one after another on this thread.
    fn map_parts<T: Send>(
        &self,
        part: impl Fn(&std::ops::Range<usize>) -> T + Sync + Send,
    ) -> Vec<T> {
        if self.index.len() >= PARALLEL_PRODUCT_ENTRIES {
            self.chunks.par_iter().map(part).collect()
        } else {
            self.chunks.iter().map(&part).collect()
        }
    }

    /// `acc += e_q (d_q ⊙ r)` for merged row `q` = `row` and its response `r`, skipped when
    /// the weighted response is zero.
    #[inline]
    fn scatter_weighted(
        &self,
        q: usize,
        row: (&[HaarIndex], &[[f32; 3]]),
        r: [f64; 3],
        acc: &mut [[f64; 3]],
    ) {
        let d = self.dw[q];
        let uq = [r[0] * d[0], r[1] * d[1], r[2] * d[2]];
        if uq != [0.0; 3] {
            row_scatter(row.0, row.1, uq, acc);
        }
    }

    /// The rows `rows` of [`Self::normal_rows`] into `acc` with AVX2: the three channels
    /// in the first three lanes of a 4-lane vector, each lane's multiplications and
    /// additions the scalar code's, in its order (zero-weight rows skipped; each row's dot
    /// over its own entries in its own order, the scatters in row order), so the result is
    /// bit for bit the scalar one. The rows are taken four at a time so that four dots'
    /// dependency chains overlap (one chain waits on the add latency at every entry); the
    /// scalar code's pairs give the same sums, since a row's dot never reads `acc`. An
    /// entry's three `f32` are loaded as four; the fourth (the next entry's first, or the
    /// padding entry past the last row) meets a zero lane of `h4` or of the scattered
    /// response, and lane 3 is never read.
    ///
    /// # Safety
    /// The CPU must have AVX2. (Every memory access is checked or bounded here: `value`'s
    /// padding entry once, each row's span once, each Haar index by a mask.)
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn normal_part_avx2(
        &self,
        rows: std::ops::Range<usize>,
        h4: &[[f64; 4]],
        acc: &mut [[f64; 4]],
    ) {
        use std::arch::x86_64::*;
        // Every merged index is below `n²` (`PhotoSystem::new` keeps only Haar indices of
        // the map; the cut only drops entries), and `n²` is a power of two: masked with
        // `n² − 1` an index is unchanged, and any index, valid or not, stays in bounds of
        // `h4` and `acc` without a check per entry.
        let n2 = self.n * self.n;
        assert!(n2.is_power_of_two() && h4.len() >= n2 && acc.len() >= n2);
        assert!(self.value.len() > self.index.len(), "no padding entry");
        let mask = n2 - 1;
        // Row `q`'s entries, checked to lie in `index` (so `value` holds one more).
        let span = |q: usize| {
            let (a, b) = (self.offsets[q], self.offsets[q + 1]);
            assert!(
                a <= b && b <= self.index.len(),
                "row {q} outside the entries"
            );
            a..b
        };
        let val = self.value.as_ptr() as *const f32;
        let idx = self.index.as_ptr();
        let hp = h4.as_ptr() as *const f64;
        let ap = acc.as_mut_ptr() as *mut f64;
        // SAFETY (these closures and `scatter`): `i` is an entry of a `span`, so `i <
        // index.len() < value.len()`: the 2 bytes of index `i` lie in `index`, the 16 bytes
        // from entry `i` in `value`, and the masked index `< n²` puts the 32 bytes at
        // `slot(i)` in `h4` and in `acc`.
        let slot = |i: usize| 4 * (unsafe { *idx.add(i) } as usize & mask);
        let e4 = |i: usize| unsafe { _mm256_cvtps_pd(_mm_loadu_ps(val.add(3 * i))) };
        let h_at = |i: usize| unsafe { _mm256_loadu_pd(hp.add(slot(i))) };
        let dot_from = |mut x: __m256d, r: std::ops::Range<usize>| {
            for i in r {
                x = _mm256_add_pd(x, _mm256_mul_pd(e4(i), h_at(i)));
            }
            x
        };
        let scatter = |q: usize, x: __m256d| {
            let mut r = [0.0_f64; 4];
            // SAFETY: `r` holds four f64.
            unsafe { _mm256_storeu_pd(r.as_mut_ptr(), x) };
            let d = self.dw[q];
            let uq = [r[0] * d[0], r[1] * d[1], r[2] * d[2]];
            if uq == [0.0; 3] {
                return;
            }
            let u = _mm256_setr_pd(uq[0], uq[1], uq[2], 0.0);
            for i in span(q) {
                // SAFETY: as for `h_at`.
                unsafe {
                    let o = ap.add(slot(i));
                    _mm256_storeu_pd(
                        o,
                        _mm256_add_pd(_mm256_loadu_pd(o), _mm256_mul_pd(e4(i), u)),
                    );
                }
            }
        };
        let mut live = rows.filter(|&q| self.dw[q] != [0.0; 3]);
        loop {
            let mut qs = [0_usize; 4];
            let mut m = 0;
            while m < 4 {
                let Some(q) = live.next() else { break };
                qs[m] = q;
                m += 1;
            }
            if m < 4 {
                for &q in &qs[..m] {
                    scatter(q, dot_from(_mm256_setzero_pd(), span(q)));
                }
                break;
            }
            let spans = qs.map(span);
            let (a, b) = (spans.clone().map(|r| r.start), spans.map(|r| r.end));
            let k = (0..4).map(|j| b[j] - a[j]).min().unwrap_or(0);
            let mut x = [_mm256_setzero_pd(); 4];
            for t in 0..k {
                for j in 0..4 {
                    x[j] = _mm256_add_pd(x[j], _mm256_mul_pd(e4(a[j] + t), h_at(a[j] + t)));
                }
            }
            for j in 0..4 {
                x[j] = dot_from(x[j], a[j] + k..b[j]);
            }
            for j in 0..4 {
                scatter(qs[j], x[j]);
            }
        }
    }

    /// Largest diagonal entry of `Aᵀ D A` per channel, in the Haar basis:
    /// `max_m Σ_p d_{p,c} e_{p,c,m}²`.
    pub(crate) fn max_diag(&self) -> [f64; 3] {
        let mut diag = vec![[0.0; 3]; self.n * self.n];
        for (q, d) in self.dw.iter().enumerate() {
            let (idx, val) = self.merged(q);
            for (&m, e) in idx.iter().zip(val) {
                let o = &mut diag[m as usize];
                for c in 0..3 {
                    let v = e[c] as f64;
                    o[c] += d[c] * v * v;
                }
            }
        }
        let mut mx = [0.0_f64; 3];
        for d in &diag {
            for c in 0..3 {
                mx[c] = mx[c].max(d[c]);
            }
        }
        mx
    }
}

/// Largest and mean diagonal entries per channel of the unweighted-by-IRLS lighting system
/// `Wᵀ Aᵀ D A W` in the texel basis (`D = α`): `Σ_p α_p ((Wᵀ e_{p,c})_t)²`, with
/// `e_{p,c} = Σ_b β_{x,b,c} g_{p,b}` rebuilt densely and inverse-Haar transformed per
/// observation (`O(n²)` each, once per photo).
pub(crate) fn texel_diag(
    problem: &Problem,
    beta: &[[f64; 3]],
    range: impl IntoIterator<Item = usize>,
    alpha: &[f64],
) -> ([f64; 3], [f64; 3]) {
    let diag = texel_diag_vec(problem, beta, range, alpha);
    let n2 = diag.len();
    let (mut mx, mut sum) = ([0.0_f64; 3], [0.0_f64; 3]);
    for d in &diag {
        for c in 0..3 {
            mx[c] = mx[c].max(d[c]);
            sum[c] += d[c];
        }
    }
    (mx, sum.map(|v| v / n2 as f64))
}

/// The diagonal itself, per texel and channel (see [`texel_diag`]).
pub(crate) fn texel_diag_vec(
    problem: &Problem,
    beta: &[[f64; 3]],
    range: impl IntoIterator<Item = usize>,
    alpha: &[f64],
) -> Vec<[f64; 3]> {
    let t = problem.transport;
    let (n, nb) = (t.n_global, t.n_basis);
    let n2 = n * n;
    let mut diag = vec![[0.0_f64; 3]; n2];
    // The three channels interleaved and transformed together (`haar::Rgb`: the same
    // operations per channel as three separate transforms).
    let mut dense = vec![haar::Rgb::default(); n2];
    let mut scratch = Vec::new();
    for (q, p) in range.into_iter().enumerate() {
        let a = alpha[q];
        if a <= 0.0 {
            continue;
        }
        let x = problem.obs.vertex[p] as usize;
        dense.fill(haar::Rgb::default());
        for b in 0..nb {
            let be = beta[x * nb + b];
            let (idx, val) = t.row(p, b);
            for (&m, &g) in idx.iter().zip(val) {
                let d = &mut dense[m as usize].0;
                for c in 0..3 {
                    d[c] += be[c] * f64::from(g);
                }
            }
        }
        haar::inverse_with(&mut dense, n, &mut scratch);
        for (o, v) in diag.iter_mut().zip(&dense) {
            for c in 0..3 {
                o[c] += a * v.0[c] * v.0[c];
            }
        }
    }
    diag
}

/// An entry's energy `Σ_c e_c²`.
#[inline]
fn entry_energy(e: &[f32; 3]) -> f64 {
    e.iter().map(|&v| f64::from(v) * f64::from(v)).sum()
}

/// Drop from the row `start..` of `index`/`value` its lowest-energy entries, as many as fit
/// in `eps` of the row's energy `Σ_m Σ_c e_{m,c}²` (entries of equal energy dropped in row
/// order); the kept ones stay in ascending index order. `sorted` is a reused buffer.
///
/// Only entries of energy at most the budget `eps Σ` can be dropped, and they are the
/// first ones of the row sorted by energy; so only they are sorted (at `ε = 10⁻³` a few
/// dozen of a row's few hundred). Energies are non-negative, so their bit patterns sort as
/// the numbers do.
fn cut_to_energy(
    index: &mut Vec<HaarIndex>,
    value: &mut Vec<[f32; 3]>,
    start: usize,
    eps: f64,
    sorted: &mut Vec<u64>,
) {
    sorted.clear();
    sorted.extend(value[start..].iter().map(|e| entry_energy(e).to_bits()));
    let budget = eps * sorted.iter().map(|&m| f64::from_bits(m)).sum::<f64>();
    sorted.retain(|&m| f64::from_bits(m) <= budget);
    sorted.sort_unstable();
    let (mut dropped, mut n_drop) = (0.0, 0);
    for &m in sorted.iter() {
        let m = f64::from_bits(m);
        if dropped + m > budget {
            break;
        }
        dropped += m;
        n_drop += 1;
    }
    if n_drop == 0 {
        return;
    }
    // Drop every entry below the last dropped energy, and of those equal to it as many
    // as the count leaves.
    let th = f64::from_bits(sorted[n_drop - 1]);
    let mut ties = n_drop - sorted.partition_point(|&m| f64::from_bits(m) < th);
    let mut w = start;
    for r in start..index.len() {
        let m = entry_energy(&value[r]);
        let drop = m < th || (m == th && ties > 0);
        if m == th && drop {
            ties -= 1;
        }
        if !drop {
            index[w] = index[r];
            value[w] = value[r];
            w += 1;
        }
    }
    index.truncate(w);
    value.truncate(w);
}

/// `out_c += Σ_parts part_c`, part by part in order (the first three lanes of each).
fn add_parts<const L: usize>(parts: &[Vec<[f64; L]>], out: &mut [[f64; 3]]) {
    for p in parts {
        for (o, v) in out.iter_mut().zip(p) {
            o[0] += v[0];
            o[1] += v[1];
            o[2] += v[2];
        }
    }
}

pub(crate) fn split3(x: &[f64], n2: usize) -> [Vec<f64>; 3] {
    [0, 1, 2].map(|c| x[c * n2..(c + 1) * n2].to_vec())
}

/// Channel-major texels `Wᵀ h` of interleaved Haar coefficients.
pub(crate) fn unhaar3(h: &[[f64; 3]], n: usize) -> Vec<f64> {
    let n2 = n * n;
    let mut out = vec![0.0; 3 * n2];
    for c in 0..3 {
        let ch = &mut out[c * n2..(c + 1) * n2];
        for (o, v) in ch.iter_mut().zip(h) {
            *o = v[c];
        }
        haar::inverse(ch, n);
    }
    out
}

#[cfg(test)]
pub(crate) mod tests;
