use super::*;
use rand::{Rng, SeedableRng};

#[test]
fn entry_chunks_cover_the_rows_in_order_and_balance_the_entries() {
    // 1,000 rows of 0–99 entries.
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut offsets = vec![0];
    for _ in 0..1000 {
        let len = rng.random_range(0..100);
        offsets.push(offsets.last().unwrap() + len);
    }
    let chunks = entry_chunks(&offsets, 4);
    assert_eq!(chunks.len(), 4);
    assert_eq!(chunks[0].start, 0);
    assert_eq!(chunks.last().unwrap().end, 1000);
    for w in chunks.windows(2) {
        assert_eq!(w[0].end, w[1].start);
    }
    let total = *offsets.last().unwrap();
    for c in &chunks {
        let e = offsets[c.end] - offsets[c.start];
        // A cut lands on a row boundary, so a part is off its quarter by less than one
        // row (< 100 entries).
        assert!((e as i64 - total as i64 / 4).abs() < 100, "{e} of {total}");
    }
    // Fewer rows than parts, and no rows: no empty part.
    assert_eq!(entry_chunks(&[0, 5, 9], 4), vec![0..1, 1..2]);
    assert!(entry_chunks(&[0], 4).is_empty());
}

/// Rows of random lengths (0–`max_len` entries, ascending indices over `n²`) and values.
fn random_rows(
    rng: &mut rand::rngs::StdRng,
    n: usize,
    rows: usize,
    max_len: usize,
) -> (Vec<usize>, Vec<HaarIndex>, Vec<[f32; 3]>) {
    let mut offsets = vec![0];
    let (mut index, mut value) = (Vec::new(), Vec::new());
    for _ in 0..rows {
        let len = rng.random_range(0..=max_len);
        let mut idx: Vec<HaarIndex> = rand::seq::index::sample(rng, n * n, len)
            .into_iter()
            .map(|m| m as HaarIndex)
            .collect();
        idx.sort_unstable();
        for _ in &idx {
            value.push([0, 1, 2].map(|_| rng.random_range(-1.0_f32..1.0)));
        }
        index.extend(idx);
        offsets.push(index.len());
    }
    (offsets, index, value)
}

#[test]
fn paired_row_dots_equal_single_row_dots_bit_for_bit() {
    // Each row's sum runs over its own entries in its own order, so the pair must
    // reproduce `row_dot` exactly (no tolerance), whichever row is longer.
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let n = 16;
    let (offsets, index, value) = random_rows(&mut rng, n, 200, 120);
    let h = random_light(&mut rng, n * n);
    let row = |q: usize| {
        (
            &index[offsets[q]..offsets[q + 1]],
            &value[offsets[q]..offsets[q + 1]],
        )
    };
    for q in 0..199 {
        let (a, b) = (row(q), row(q + 1));
        let [x, y] = row_dot_pair(a, b, &h);
        assert_eq!(x, row_dot(a.0, a.1, &h), "row {q}");
        assert_eq!(y, row_dot(b.0, b.1, &h), "row {}", q + 1);
    }
}

#[test]
fn the_avx2_product_is_the_scalar_product_bit_for_bit() {
    // The same rows with the padding entry (the AVX2 path, where the CPU has it) and
    // without (the scalar path): each lane does the scalar code's operations in its
    // order, so the products must agree exactly, over four parts, with zero-weight
    // rows and rows of every length down to empty.
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    let n = 32;
    let rows = 257;
    let (offsets, index, value) = random_rows(&mut rng, n, rows, 300);
    let dw = random_weights(&mut rng, rows, 5);
    let scalar = PhotoSystem {
        range: 0..rows,
        n,
        dw,
        chunks: entry_chunks(&offsets, PRODUCT_CHUNKS),
        offsets,
        index,
        value,
    };
    let mut padded_value = scalar.value.clone();
    padded_value.push([0.0; 3]);
    let padded = PhotoSystem {
        range: scalar.range.clone(),
        n,
        dw: scalar.dw.clone(),
        offsets: scalar.offsets.clone(),
        index: scalar.index.clone(),
        value: padded_value,
        chunks: scalar.chunks.clone(),
    };
    let h = random_light(&mut rng, n * n);
    let (mut a, mut b) = (vec![[0.5; 3]; n * n], vec![[0.5; 3]; n * n]);
    scalar.normal_rows(&h, &mut a);
    padded.normal_rows(&h, &mut b);
    assert!(a.iter().flatten().any(|v| (v - 0.5).abs() > 1.0));
    assert_eq!(a, b);
}

#[test]
fn one_part_product_is_the_forward_scale_adjoint_sequence_exactly() {
    // With a single part (and an odd row count, so one row is left unpaired) the fused
    // product adds the same terms in the same order as the forward rows, the scaling
    // and the adjoint rows done one after the other: equal bit for bit.
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let n = 16;
    let rows = 301;
    let (offsets, index, mut value) = random_rows(&mut rng, n, rows, 80);
    // The padding entry of `PhotoSystem::new`: the AVX2 path where the CPU has it.
    value.push([0.0; 3]);
    let dw = random_weights(&mut rng, rows, 7);
    let sys = PhotoSystem {
        range: 0..rows,
        n,
        dw,
        offsets,
        index,
        value,
        chunks: std::iter::once(0..rows).collect(),
    };
    let (fused, seq) = fused_and_sequential(&sys, &mut rng);
    assert_eq!(fused, seq);
}

#[test]
fn the_parallel_product_is_the_forward_scale_adjoint_sequence() {
    // Random merged rows over a 16² map; the fused, chunked `Aᵀ D A h` against the
    // forward rows, the scaling by `D` and the adjoint rows done one after the other.
    // Only the order of the additions differs: 1e-12 relative.
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let n = 16;
    let rows = 500;
    // Rows of 0–102 entries: a fifth of the 16² map on average.
    let (offsets, index, value) = random_rows(&mut rng, n, rows, 2 * n * n / 5);
    let dw: Vec<[f64; 3]> = (0..rows)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..2.0)))
        .collect();
    let chunks = entry_chunks(&offsets, PRODUCT_CHUNKS);
    let sys = PhotoSystem {
        range: 0..rows,
        n,
        dw,
        offsets,
        index,
        value,
        chunks,
    };
    let (fused, seq) = fused_and_sequential(&sys, &mut rng);
    let scale = seq.iter().flatten().fold(0.0_f64, |a, v| a.max(v.abs()));
    assert!(scale > 1.0);
    for (a, b) in fused.iter().zip(&seq) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() <= 1e-12 * scale, "{} vs {}", a[c], b[c]);
        }
    }
}

/// `Aᵀ D A h` for a random light `h`, fused ([`PhotoSystem::normal_rows`]) and as the
/// forward rows, the scaling by `D` and the adjoint rows one after the other.
fn fused_and_sequential(
    sys: &PhotoSystem,
    rng: &mut rand::rngs::StdRng,
) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let n2 = sys.n * sys.n;
    let h = random_light(rng, n2);
    let mut fused = vec![[0.0; 3]; n2];
    sys.normal_rows(&h, &mut fused);
    let mut s = vec![[0.0; 3]; sys.range.len()];
    sys.forward_rows(&h, &mut s);
    let u: Vec<[f64; 3]> = s
        .iter()
        .zip(&sys.dw)
        .map(|(s, d)| [s[0] * d[0], s[1] * d[1], s[2] * d[2]])
        .collect();
    let mut seq = vec![[0.0; 3]; n2];
    sys.adjoint_rows(&u, &mut seq);
    (fused, seq)
}

/// `α ω` per row in `[0, 2)`, every `zero_every`-th row 0 (rows the products skip).
fn random_weights(rng: &mut rand::rngs::StdRng, rows: usize, zero_every: usize) -> Vec<[f64; 3]> {
    (0..rows)
        .map(|q| {
            [0, 1, 2].map(|_| {
                if q % zero_every == 0 {
                    0.0
                } else {
                    rng.random_range(0.0..2.0)
                }
            })
        })
        .collect()
}

/// A random interleaved light of `n2` coefficients in `[-1, 1)`.
fn random_light(rng: &mut rand::rngs::StdRng, n2: usize) -> Vec<[f64; 3]> {
    (0..n2)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
        .collect()
}

/// Three bases' random rows over a 32² map (random kept sets of 0–200 entries,
/// overlapping), one observation per vertex, and `β` with some bases off (`β = 0`) at some
/// vertices.
fn random_blend_problem(
    rng: &mut rand::rngs::StdRng,
) -> (
    crate::transport::Transport,
    crate::observe::Observations,
    Vec<[f64; 3]>,
) {
    use crate::observe::Observations;
    use crate::transport::{Transport, TransportValue};
    let (n, nb, rows) = (32, 3, 90);
    let mut t = Transport {
        n_global: n,
        n_basis: nb,
        n_obs: rows,
        offsets: vec![0],
        ..Default::default()
    };
    let mut obs = Observations::default();
    for p in 0..rows {
        for _ in 0..nb {
            let len = rng.random_range(0..=200);
            let mut idx: Vec<HaarIndex> = rand::seq::index::sample(rng, n * n, len)
                .into_iter()
                .map(|m| m as HaarIndex)
                .collect();
            idx.sort_unstable();
            t.value.extend(
                idx.iter()
                    .map(|_| TransportValue::from_f32(rng.random_range(-1.0..1.0))),
            );
            t.index.extend(idx);
            t.offsets.push(t.index.len());
        }
        obs.vertex.push(p as u32);
        obs.photo.push(0);
        obs.rgb.push([0.5; 3]);
        obs.weight.push(1.0);
        obs.dir.push([0.0, 0.0, 1.0]);
    }
    obs.photo_ranges = std::iter::once(0..rows).collect();
    let beta: Vec<[f64; 3]> = (0..rows * nb)
        .map(|i| match i % 7 {
            0 => [0.0; 3],
            _ => [0, 1, 2].map(|_| rng.random_range(0.0..2.0)),
        })
        .collect();
    (t, obs, beta)
}

/// [`random_blend_problem`] from `seed`, merged into a [`PhotoSystem`] at tolerance `eps`
/// (unit weights, every observation): the transport, `β` and the system.
pub(crate) fn random_blend_system(
    seed: u64,
    eps: f64,
) -> (crate::transport::Transport, Vec<[f64; 3]>, PhotoSystem) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let (t, obs, beta) = random_blend_problem(&mut rng);
    let rows = obs.vertex.len();
    let problem = Problem {
        obs: &obs,
        transport: &t,
        n_vertices: rows,
        n_photos: 1,
    };
    let sys = PhotoSystem::new(
        &problem,
        &beta,
        0..rows,
        t.n_global,
        vec![[1.0; 3]; rows],
        eps,
    );
    (t, beta, sys)
}

/// Observation `p`'s blend `Σ_b β_{x,b,c} g_{p,b,m}` by a sorted map, summed in basis order
/// and rounded once to `f32`, without the entries whose three sums are zero.
fn union_row(
    t: &crate::transport::Transport,
    beta: &[[f64; 3]],
    p: usize,
) -> std::collections::BTreeMap<HaarIndex, [f32; 3]> {
    let nb = t.n_basis;
    let mut union = std::collections::BTreeMap::new();
    for b in 0..nb {
        let be = beta[p * nb + b];
        if be == [0.0; 3] {
            continue;
        }
        let (idx, val) = t.row(p, b);
        for (&m, &g) in idx.iter().zip(val) {
            let d: &mut [f64; 3] = union.entry(m).or_insert([0.0; 3]);
            for c in 0..3 {
                d[c] += be[c] * f64::from(g);
            }
        }
    }
    union
        .into_iter()
        .filter(|(_, d)| *d != [0.0; 3])
        .map(|(m, d)| (m, d.map(|v| v as f32)))
        .collect()
}

#[test]
fn merged_rows_are_the_sorted_union_of_the_blended_basis_rows() {
    // Each merged row must be the union of the kept indices, ascending, with the blend
    // summed in basis order and rounded once, and no entry whose three sums are zero;
    // compared exactly with a sorted map.
    let (t, beta, sys) = random_blend_system(17, 0.0);
    let rows = t.n_obs;
    for p in 0..rows {
        let union = union_row(&t, &beta, p);
        let (idx, val) = sys.merged(p);
        assert_eq!(idx, union.keys().copied().collect::<Vec<_>>(), "row {p}");
        assert_eq!(val, union.values().copied().collect::<Vec<_>>(), "row {p}");
    }
}

#[test]
fn an_energy_cut_drops_the_most_entries_whose_energy_fits_the_tolerance() {
    // At ε = 10⁻² every merged row must (1) be a subset of the exact union, with its values;
    // (2) have dropped at most ε of the union's energy `Σ_m Σ_c e_{m,c}²`; (3) have dropped
    // no entry of more energy than one it kept; and (4) not fit one more drop: the dropped
    // energy plus the smallest kept entry's exceeds ε. (3) and (4) make the cut the
    // largest one within the tolerance; checked against the union built by a sorted map.
    let eps = 1e-2;
    let (t, beta, sys) = random_blend_system(23, eps);
    let rows = t.n_obs;
    let energy = super::entry_energy;
    let mut cut_rows = 0;
    for p in 0..rows {
        let union = union_row(&t, &beta, p);
        let (idx, val) = sys.merged(p);
        for (m, v) in idx.iter().zip(val) {
            assert_eq!(union.get(m), Some(v), "row {p}: entry {m} not the union's");
        }
        let total: f64 = union.values().map(energy).sum();
        let kept: Vec<f64> = val.iter().map(energy).collect();
        let dropped = total - kept.iter().sum::<f64>();
        let min_kept = kept.iter().copied().fold(f64::INFINITY, f64::min);
        let max_dropped = union
            .iter()
            .filter(|(m, _)| idx.binary_search(m).is_err())
            .map(|(_, v)| energy(v))
            .fold(0.0, f64::max);
        // 1e-12 relative: the two energy sums differ by their order of addition only.
        assert!(
            dropped <= eps * total * (1.0 + 1e-12),
            "row {p}: dropped {dropped} of {total}"
        );
        assert!(max_dropped <= min_kept || union.is_empty(), "row {p}");
        if !union.is_empty() {
            assert!(
                dropped + min_kept > eps * total * (1.0 - 1e-12),
                "row {p}: one more fits"
            );
        }
        cut_rows += usize::from(idx.len() < union.len());
    }
    assert!(cut_rows > rows / 2, "{cut_rows} of {rows} rows cut");
}

#[test]
fn parallel_and_sequential_parts_give_the_same_product_bit_for_bit() {
    // A system above `PARALLEL_PRODUCT_ENTRIES` (its parts run in parallel) against the
    // same parts each run as a one-part system (sequential, on this thread) and added in
    // part order: the same additions in the same order, so equal bit for bit.
    let mut rng = rand::rngs::StdRng::seed_from_u64(13);
    let n = 32;
    let rows = 1200;
    let (offsets, index, mut value) = random_rows(&mut rng, n, rows, 300);
    value.push([0.0; 3]);
    assert!(
        index.len() >= PARALLEL_PRODUCT_ENTRIES,
        "{} entries",
        index.len()
    );
    let dw = random_weights(&mut rng, rows, 5);
    let sys = PhotoSystem {
        range: 0..rows,
        n,
        dw,
        chunks: entry_chunks(&offsets, PRODUCT_CHUNKS),
        offsets,
        index,
        value,
    };
    let h = random_light(&mut rng, n * n);
    let mut parallel = vec![[0.25; 3]; n * n];
    sys.normal_rows(&h, &mut parallel);
    let mut by_part = vec![[0.25; 3]; n * n];
    assert_eq!(sys.chunks.len(), PRODUCT_CHUNKS);
    for rows in &sys.chunks {
        let one = PhotoSystem {
            range: sys.range.clone(),
            n,
            dw: sys.dw.clone(),
            offsets: sys.offsets.clone(),
            index: sys.index.clone(),
            value: sys.value.clone(),
            chunks: vec![rows.clone()],
        };
        let mut part = vec![[0.0; 3]; n * n];
        one.normal_rows(&h, &mut part);
        for (o, p) in by_part.iter_mut().zip(&part) {
            for c in 0..3 {
                o[c] += p[c];
            }
        }
    }
    assert!(parallel.iter().flatten().any(|v| (v - 0.25).abs() > 1.0));
    assert_eq!(parallel, by_part);
}
