//! Triple products in the 2D Haar basis (paper Eq. 5 and 7; Ng, Ramamoorthi & Hanrahan,
//! "Triple product wavelet integrals for all-frequency relighting", SIGGRAPH 2004).
//!
//! For texel vectors `F, G, H` (`n × n`, [`crate::sphere::haar`] coefficients `f = W F` etc.),
//! `Σ_t F_t G_t H_t = Σ_klm C_klm f_k g_l h_m` with the tripling coefficients
//! `C_klm = Σ_t ψ_k(t) ψ_l(t) ψ_m(t)`. (The quadrature weight `Δω` is not in `C`: it lives
//! in exactly one factor, docs/conventions.md.) For the orthonormal non-standard Haar basis, `C_klm`
//! is non-zero only in three cases (Ng et al. 2004, Sec. 4):
//!
//! 1. all three are the scaling function: `C = 1/n`;
//! 2. three wavelets of one node with the three distinct types `h, v, d`: `C = m/n`
//!    (the wavelets' amplitude, `m` nodes per side at that level);
//! 3. two identical basis functions `k = l` and a third `m` that is the scaling function or
//!    a strictly coarser wavelet whose support contains theirs: `C = ψ_m` on that support.
//!
//! So the triple product is a single walk down the wavelet tree carrying, per node, the
//! value of each function's coarser part on the node's support (the "parent sums"):
//! `O(n²)`, linear in the coefficients ([`triple_product`]). [`double_product`] applies
//! `T_m = Σ_kl C_klm f_k g_l` (Eq. 7: visibility folded into the transport) in `O(n²)` with
//! one more bottom-up pass for case 3 where `m` is the coarse one.

use crate::sphere::haar::{coefficient, Coefficient, WaveletType};
use std::cell::RefCell;

const TYPES: [WaveletType; 3] = [WaveletType::H, WaveletType::V, WaveletType::D];

/// Offsets of the `h, v, d` coefficients of node `(r, c)` at level `m` in an `n × n` layout.
#[inline(always)]
fn node_idx(n: usize, m: usize, r: usize, c: usize) -> [usize; 3] {
    let ih = r * n + c + m;
    let iv = (r + m) * n + c;
    [ih, iv, iv + m]
}

/// The tripling coefficient `C_klm = Σ_t ψ_k(t) ψ_l(t) ψ_m(t)` on an `n × n` map, from the
/// three cases in the module docs (`O(1)`).
pub fn tripling_coefficient(n: usize, k: usize, l: usize, m: usize) -> f64 {
    let nf = n as f64;
    let idx = [k, l, m];
    let co = idx.map(|i| coefficient(n, i));
    // Case 3 (and the scaling-only cases 1 and "two scalings"): a repeated pair.
    for (a, b, c) in [(0, 1, 2), (0, 2, 1), (1, 2, 0)] {
        if idx[a] != idx[b] {
            continue;
        }
        return match (co[a], co[c]) {
            (Coefficient::Scaling, Coefficient::Scaling) => 1.0 / nf,
            (Coefficient::Scaling, Coefficient::Wavelet { .. }) => 0.0,
            (Coefficient::Wavelet { .. }, Coefficient::Scaling) => 1.0 / nf,
            (
                Coefficient::Wavelet {
                    m: ma,
                    r: ra,
                    c: ca,
                    ..
                },
                Coefficient::Wavelet {
                    m: mc,
                    r: rc,
                    c: cc,
                    ty,
                },
            ) => {
                if mc >= ma {
                    return 0.0; // same level: Σ ψ_a² ψ_c = 0 or disjoint; finer: Σ ψ_c = 0
                }
                // Position of node a at level 2 mc: which quadrant of c's node it is in.
                let scale = ma / (2 * mc);
                let (qr, qc) = (ra / scale, ca / scale);
                if qr / 2 != rc || qc / 2 != cc {
                    return 0.0;
                }
                ty.sign(qr % 2, qc % 2) * mc as f64 / nf
            }
        };
    }
    // All distinct: case 2 only.
    match co {
        [Coefficient::Wavelet {
            m: m1,
            r: r1,
            c: c1,
            ty: t1,
        }, Coefficient::Wavelet {
            m: m2,
            r: r2,
            c: c2,
            ty: t2,
        }, Coefficient::Wavelet {
            m: m3,
            r: r3,
            c: c3,
            ty: t3,
        }] if (m1, r1, c1) == (m2, r2, c2)
            && (m1, r1, c1) == (m3, r3, c3)
            && t1 != t2
            && t2 != t3
            && t1 != t3 =>
        {
            m1 as f64 / nf
        }
        _ => 0.0,
    }
}

thread_local! {
    static SCRATCH: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// `Σ_klm C_klm f_k g_l h_m = Σ_t F_t G_t H_t` for dense Haar coefficient vectors of an
/// `n × n` map, by one walk down the wavelet tree (`O(n²)`, no allocation after the first
/// call on a thread). Uses AVX2/FMA code when the CPU has it (same sum, rounding may differ
/// in the last bits).
pub fn triple_product(n: usize, f: &[f64], g: &[f64], h: &[f64]) -> f64 {
    assert!(f.len() == n * n && g.len() == n * n && h.len() == n * n);
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports the features `triple_product_avx2` is compiled for.
        return unsafe { triple_product_avx2(n, f, g, h) };
    }
    triple_product_impl(n, f, g, h)
}

/// [`triple_product_impl`] compiled for AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn triple_product_avx2(n: usize, f: &[f64], g: &[f64], h: &[f64]) -> f64 {
    triple_product_impl(n, f, g, h)
}

/// The tree walk behind [`triple_product`].
#[inline(always)]
fn triple_product_impl(n: usize, f: &[f64], g: &[f64], h: &[f64]) -> f64 {
    let nf = n as f64;
    let mut sum = f[0] * g[0] * h[0] / nf;
    if n < 2 {
        return sum;
    }
    SCRATCH.with(|cell| {
        let mut buf = cell.borrow_mut();
        let q = (n / 2) * (n / 2);
        if buf.len() < 6 * q {
            buf.resize(6 * q, 0.0);
        }
        let (par, chi) = buf.split_at_mut(3 * q);
        // Parent values of f, g, h at the current level: par[0..q], par[q..2q], par[2q..3q].
        par[0] = f[0] / nf;
        par[q] = g[0] / nf;
        par[2 * q] = h[0] / nf;
        let (mut par, mut chi) = (par, chi);
        let mut m = 1;
        while m < n {
            let amp = m as f64 / nf;
            let last = 2 * m == n;
            let mut case2 = 0.0;
            let mut case3 = 0.0;
            for r in 0..m {
                let rowh = r * n + m;
                let rowv = (r + m) * n;
                let rowd = rowv + m;
                if 2 * m == n && m % 4 == 0 {
                    // Finest level: no children; four lanes so the reduction vectorises.
                    let (s2, s3) = finest_row(
                        &f[rowh..rowh + m],
                        &f[rowv..rowv + 2 * m],
                        &g[rowh..rowh + m],
                        &g[rowv..rowv + 2 * m],
                        &h[rowh..rowh + m],
                        &h[rowv..rowv + 2 * m],
                        &par[r * m..(r + 1) * m],
                        &par[q + r * m..q + (r + 1) * m],
                        &par[2 * q + r * m..2 * q + (r + 1) * m],
                    );
                    case2 += s2;
                    case3 += s3;
                    continue;
                }
                for c in 0..m {
                    let (fh, fv, fd) = (f[rowh + c], f[rowv + c], f[rowd + c]);
                    let (gh, gv, gd) = (g[rowh + c], g[rowv + c], g[rowd + c]);
                    let (hh, hv, hd) = (h[rowh + c], h[rowv + c], h[rowd + c]);
                    let p = r * m + c;
                    let (pf, pg, ph) = (par[p], par[q + p], par[2 * q + p]);
                    case2 += fh * (gv * hd + gd * hv)
                        + fv * (gh * hd + gd * hh)
                        + fd * (gh * hv + gv * hh);
                    case3 += (fh * gh + fv * gv + fd * gd) * ph
                        + (fh * hh + fv * hv + fd * hd) * pg
                        + (gh * hh + gv * hv + gd * hd) * pf;
                    if !last {
                        // Children (2r + dr, 2c + dc) on the 2m grid:
                        // P + amp·(±h ± v ± d) with h + on the left, v + on the top.
                        let m2 = 2 * m;
                        let c00 = 2 * r * m2 + 2 * c;
                        for (off, x, y, z, pp) in [
                            (0, fh, fv, fd, pf),
                            (q, gh, gv, gd, pg),
                            (2 * q, hh, hv, hd, ph),
                        ] {
                            let a = y + x;
                            let b = y - x;
                            chi[off + c00] = pp + amp * (a + z);
                            chi[off + c00 + 1] = pp + amp * (b - z);
                            chi[off + c00 + m2] = pp - amp * (b + z);
                            chi[off + c00 + m2 + 1] = pp - amp * (a - z);
                        }
                    }
                }
            }
            sum += amp * case2 + case3;
            std::mem::swap(&mut par, &mut chi);
            m *= 2;
        }
    });
    sum
}

/// Case 2 and case 3 sums over one row of finest-level nodes (`m` a multiple of 4): `*h` the
/// `h` coefficients, `*vd` the `v` then `d` coefficients (`2m` values), `p*` parent values.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn finest_row(
    fh: &[f64],
    fvd: &[f64],
    gh: &[f64],
    gvd: &[f64],
    hh: &[f64],
    hvd: &[f64],
    pf: &[f64],
    pg: &[f64],
    ph: &[f64],
) -> (f64, f64) {
    let m = fh.len();
    let (mut a2, mut a3) = ([0.0f64; 4], [0.0f64; 4]);
    for c0 in (0..m).step_by(4) {
        for l in 0..4 {
            let c = c0 + l;
            let (fh, fv, fd) = (fh[c], fvd[c], fvd[m + c]);
            let (gh, gv, gd) = (gh[c], gvd[c], gvd[m + c]);
            let (hh, hv, hd) = (hh[c], hvd[c], hvd[m + c]);
            a2[l] += fh * (gv * hd + gd * hv) + fv * (gh * hd + gd * hh) + fd * (gh * hv + gv * hh);
            a3[l] += (fh * gh + fv * gv + fd * gd) * ph[c]
                + (fh * hh + fv * hv + fd * hd) * pg[c]
                + (gh * hh + gv * hv + gd * hd) * pf[c];
        }
    }
    (
        (a2[0] + a2[1]) + (a2[2] + a2[3]),
        (a3[0] + a3[1]) + (a3[2] + a3[3]),
    )
}

/// Value of `g`'s part coarser than level `m` on node `(r, c)` (the scaling function plus
/// all ancestors' wavelets), by walking up the tree (`O(log n)`).
fn coarse_value(n: usize, g: &[f64], m: usize, r: usize, c: usize) -> f64 {
    let nf = n as f64;
    let mut v = g[0] / nf;
    let mut ma = 1;
    while ma < m {
        // Ancestor at level ma, and the quadrant of it that contains (r, c).
        let scale = m / (2 * ma);
        let (qr, qc) = (r / scale, c / scale);
        let (ar, ac) = (qr / 2, qc / 2);
        let ids = node_idx(n, ma, ar, ac);
        for (ty, &i) in TYPES.iter().zip(&ids) {
            v += g[i] * ty.sign(qr % 2, qc % 2) * ma as f64 / nf;
        }
        ma *= 2;
    }
    v
}

/// `Σ g_l h_l` over all wavelets whose support lies in the node `(r, c)` of level `m`
/// (that node's own three and all its descendants).
fn subtree_dot(n: usize, g: &[f64], h: &[f64], m: usize, r: usize, c: usize) -> f64 {
    let mut sum = 0.0;
    let (mut lm, mut span) = (m, 1);
    while lm < n {
        for rr in r * span..(r + 1) * span {
            for ty_off in [(0, lm), (lm, 0), (lm, lm)] {
                let row = (rr + ty_off.0) * n + ty_off.1;
                let lo = row + c * span;
                sum += g[lo..lo + span]
                    .iter()
                    .zip(&h[lo..lo + span])
                    .map(|(a, b)| a * b)
                    .sum::<f64>();
            }
        }
        lm *= 2;
        span *= 2;
    }
    sum
}

/// `D_k = Σ_lm C_klm g_l h_m` for one coefficient `k` (cost `O(log n)` plus the size of
/// `k`'s subtree).
pub fn double_product_at(n: usize, k: usize, g: &[f64], h: &[f64]) -> f64 {
    let nf = n as f64;
    match coefficient(n, k) {
        Coefficient::Scaling => g.iter().zip(h).map(|(a, b)| a * b).sum::<f64>() / nf,
        Coefficient::Wavelet { m, r, c, ty } => {
            let amp = m as f64 / nf;
            let ids = node_idx(n, m, r, c);
            let t = TYPES.iter().position(|&x| x == ty).unwrap_or(0);
            let (o1, o2) = (ids[(t + 1) % 3], ids[(t + 2) % 3]);
            // Case 2.
            let mut d = amp * (g[o1] * h[o2] + g[o2] * h[o1]);
            // Case 3, k repeated: the other repeated one's partner is the coarse part.
            d += g[k] * coarse_value(n, h, m, r, c) + h[k] * coarse_value(n, g, m, r, c);
            // Case 3, k the coarse one: finer pairs l = l' in each quadrant.
            if 2 * m < n {
                for dr in 0..2 {
                    for dc in 0..2 {
                        let s = subtree_dot(n, g, h, 2 * m, 2 * r + dr, 2 * c + dc);
                        d += amp * ty.sign(dr, dc) * s;
                    }
                }
            }
            d
        }
    }
}

/// `Σ_klm C_klm f_k g_l h_m` with `f` given sparsely (`(indices, values)`, e.g. from
/// [`crate::sphere::haar::keep_largest`]) and `g`, `h` dense: `Σ_k f_k D_k(g, h)`
/// ([`double_product_at`]). Cheap for few, fine-level kept coefficients; a kept coarse
/// wavelet costs its subtree.
pub fn triple_product_sparse(n: usize, f: (&[u32], &[f64]), g: &[f64], h: &[f64]) -> f64 {
    f.0.iter()
        .zip(f.1)
        .map(|(&k, &fk)| fk * double_product_at(n, k as usize, g, h))
        .sum()
}

/// `out_m = Σ_kl C_klm f_k g_l` for all `m` (Eq. 7 as an operator: with `f` the visibility,
/// `out` is `T_x g`; equals `W (F ⊙ G)` in the texel domain). `O(n²)`: one top-down pass for
/// the coarse parts, one bottom-up pass for the subtree sums.
pub fn double_product(n: usize, f: &[f64], g: &[f64], out: &mut [f64]) {
    assert!(f.len() == n * n && g.len() == n * n && out.len() == n * n);
    let nf = n as f64;
    // Levels m = 1, 2, …, n/2; per level the parent values of f and g per node.
    let mut levels = Vec::new();
    let mut m = 1;
    while m < n {
        levels.push(m);
        m *= 2;
    }
    let mut pf: Vec<Vec<f64>> = Vec::with_capacity(levels.len());
    let mut pg: Vec<Vec<f64>> = Vec::with_capacity(levels.len());
    if !levels.is_empty() {
        pf.push(vec![f[0] / nf]);
        pg.push(vec![g[0] / nf]);
    }
    for (li, &m) in levels.iter().enumerate().skip(1) {
        let pm = levels[li - 1];
        let amp = pm as f64 / nf;
        let mut cf = vec![0.0; m * m];
        let mut cg = vec![0.0; m * m];
        for r in 0..m {
            for c in 0..m {
                let (pr, pc, dr, dc) = (r / 2, c / 2, r % 2, c % 2);
                let ids = node_idx(n, pm, pr, pc);
                let mut vf = pf[li - 1][pr * pm + pc];
                let mut vg = pg[li - 1][pr * pm + pc];
                for (ty, &i) in TYPES.iter().zip(&ids) {
                    let s = ty.sign(dr, dc) * amp;
                    vf += s * f[i];
                    vg += s * g[i];
                }
                cf[r * m + c] = vf;
                cg[r * m + c] = vg;
            }
        }
        pf.push(cf);
        pg.push(cg);
    }
    // Bottom-up subtree sums S(node) = Σ_types f g + Σ_children S(child).
    let mut sub: Vec<Vec<f64>> = levels.iter().map(|&m| vec![0.0; m * m]).collect();
    for li in (0..levels.len()).rev() {
        let m = levels[li];
        for r in 0..m {
            for c in 0..m {
                let ids = node_idx(n, m, r, c);
                let mut s: f64 = ids.iter().map(|&i| f[i] * g[i]).sum();
                if li + 1 < levels.len() {
                    let m2 = 2 * m;
                    for (dr, dc) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        s += sub[li + 1][(2 * r + dr) * m2 + 2 * c + dc];
                    }
                }
                sub[li][r * m + c] = s;
            }
        }
    }
    let total = f[0] * g[0] + sub.first().map_or(0.0, |s| s[0]);
    out[0] = total / nf;
    for (li, &m) in levels.iter().enumerate() {
        let amp = m as f64 / nf;
        for r in 0..m {
            for c in 0..m {
                let ids = node_idx(n, m, r, c);
                let (vf, vg) = (pf[li][r * m + c], pg[li][r * m + c]);
                for t in 0..3 {
                    let (k, o1, o2) = (ids[t], ids[(t + 1) % 3], ids[(t + 2) % 3]);
                    let mut d = amp * (f[o1] * g[o2] + f[o2] * g[o1]) + f[k] * vg + g[k] * vf;
                    if li + 1 < levels.len() {
                        let m2 = 2 * m;
                        for (dr, dc) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                            d += amp
                                * TYPES[t].sign(dr, dc)
                                * sub[li + 1][(2 * r + dr) * m2 + 2 * c + dc];
                        }
                    }
                    out[k] = d;
                }
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // index loops mirror the sums being checked
mod tests {
    use super::*;
    use crate::sphere::haar::tests::random;
    use crate::sphere::haar::{basis_value, forward, inverse, keep_largest};

    #[test]
    fn every_tripling_coefficient_of_an_8x8_basis_matches_texel_sums() {
        // Brute force: C_klm = Σ_t ψ_k(t) ψ_l(t) ψ_m(t) over the 64 texels, with ψ from
        // the basis matrix itself. Values are multiples of 1/8³·… and sums of 64 terms:
        // 1e-14 absolute.
        let n = 8;
        let nn = n * n;
        let psi: Vec<f64> = (0..nn * nn)
            .map(|i| basis_value(n, i / nn, i % nn))
            .collect();
        let mut nonzero = 0;
        for k in 0..nn {
            for l in 0..nn {
                let kl: Vec<f64> = (0..nn).map(|t| psi[k * nn + t] * psi[l * nn + t]).collect();
                for m in 0..nn {
                    let brute: f64 = (0..nn).map(|t| kl[t] * psi[m * nn + t]).sum();
                    let fast = tripling_coefficient(n, k, l, m);
                    assert!(
                        (brute - fast).abs() < 1e-14,
                        "C[{k},{l},{m}] brute {brute} fast {fast}"
                    );
                    nonzero += usize::from(brute.abs() > 1e-14);
                }
            }
        }
        // Sparsity as Ng et al. state: O(N log N) non-zeros, not O(N³).
        assert!(nonzero < 64 * 64, "{nonzero} non-zero coefficients");
    }

    #[test]
    fn fast_triple_product_equals_the_texel_sum() {
        // 1e-12 relative to Σ|F G H| (the bound): both sides are sums of O(n²)
        // products of O(1) values.
        for n in [2, 4, 8, 32, 64] {
            let (tf, tg, th) = (random(n, 1), random(n, 2), random(n, 3));
            let brute: f64 = (0..n * n).map(|t| tf[t] * tg[t] * th[t]).sum();
            let scale: f64 = (0..n * n).map(|t| (tf[t] * tg[t] * th[t]).abs()).sum();
            let (mut f, mut g, mut h) = (tf.clone(), tg.clone(), th.clone());
            forward(&mut f, n);
            forward(&mut g, n);
            forward(&mut h, n);
            let fast = triple_product(n, &f, &g, &h);
            assert!(
                (fast - brute).abs() < 1e-12 * scale,
                "n={n}: {fast} vs {brute}"
            );
            // Sparse with every coefficient kept is the same sum.
            let idx: Vec<u32> = (0..(n * n) as u32).collect();
            let sparse = triple_product_sparse(n, (&idx, &f), &g, &h);
            assert!((sparse - brute).abs() < 1e-12 * scale, "sparse n={n}");
        }
    }

    #[test]
    fn sparse_triple_product_of_a_truncated_function_is_exact_for_it() {
        // Truncating f to k terms and reconstructing gives a texel vector F_k; the sparse
        // product must equal Σ F_k G H exactly (1e-12 relative), whatever was dropped.
        let n = 16;
        let mut f = random(n, 4);
        let (mut g, mut h) = (random(n, 5), random(n, 6));
        forward(&mut f, n);
        let (idx, val, _) = keep_largest(&f, 40, None);
        let mut fk = vec![0.0; n * n];
        for (&i, &v) in idx.iter().zip(&val) {
            fk[i as usize] = v;
        }
        inverse(&mut fk, n);
        let brute: f64 = (0..n * n).map(|t| fk[t] * g[t] * h[t]).sum();
        let scale: f64 = (0..n * n).map(|t| (fk[t] * g[t] * h[t]).abs()).sum();
        forward(&mut g, n);
        forward(&mut h, n);
        let sparse = triple_product_sparse(n, (&idx, &val), &g, &h);
        assert!((sparse - brute).abs() < 1e-12 * scale);
    }

    #[test]
    fn double_product_matches_brute_force() {
        // out = W (F ⊙ G) in the texel domain, and out_m = Σ_kl C_klm f_k g_l by the
        // coefficient formula (n = 8: 64³ terms). 1e-12 absolute on O(1) values.
        for n in [2, 8, 32] {
            let (tf, tg) = (random(n, 7), random(n, 8));
            let mut want: Vec<f64> = tf.iter().zip(&tg).map(|(a, b)| a * b).collect();
            forward(&mut want, n);
            let (mut f, mut g) = (tf.clone(), tg.clone());
            forward(&mut f, n);
            forward(&mut g, n);
            let mut out = vec![0.0; n * n];
            double_product(n, &f, &g, &mut out);
            for m in 0..n * n {
                assert!((out[m] - want[m]).abs() < 1e-12, "n={n} m={m}");
                assert!((double_product_at(n, m, &f, &g) - want[m]).abs() < 1e-12);
            }
            if n == 8 {
                for m in 0..n * n {
                    let mut s = 0.0;
                    for k in 0..n * n {
                        for l in 0..n * n {
                            s += tripling_coefficient(n, k, l, m) * f[k] * g[l];
                        }
                    }
                    assert!((s - out[m]).abs() < 1e-12);
                }
            }
        }
    }
}
