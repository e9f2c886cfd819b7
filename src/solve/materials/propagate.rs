//! Blending weights of the vertices no training photo sees, from the seen ones (not in the
//! paper, whose material step leaves them at their start): the harmonic extension of
//! Zhu, Ghahramani & Lafferty 2003 ("Semi-supervised learning using Gaussian fields and
//! harmonic functions", ICML, Eq. 3–5) over the symmetrised k-nearest-neighbour graph of
//! the vertex positions.
//!
//! With `A` the graph's 0/1 adjacency, `D` its degrees and `L = D − A`, the seen vertices'
//! weights are the labelled values and every material's weight column `f` of the unseen
//! vertices `u` solves `L_uu f_u = A_us f_s`: each unseen value is the mean of its
//! neighbours' (harmonic). By the maximum principle `f_u = (L_uu)⁻¹ A_us f_s` is a convex
//! combination of seen rows (the absorption probabilities of a random walk stopped at the
//! seen vertices), so the propagated weights are non-negative and each row's sum lies
//! between the smallest and largest sum of a seen row: on the simplex when the seen rows
//! are. `L_uu` is symmetric positive definite on every connected component of the graph
//! that holds a seen vertex, and the system is solved there by conjugate gradients;
//! unseen vertices of a component without a seen vertex keep their weights.
//!
//! Why it matters: a vertex that held-out photos see but no training photo does keeps the
//! k-means start's uniform weights, the mean of the materials; on the ablation's noise-free
//! diffuse scene those 2.7% of the held-out observations are 80–94% of the relit squared
//! error (`bench-results/estimator-ablation-iterations.md`, section 8).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZeroUsize;

use crate::{Error, Result, Vec3};

/// Neighbours per vertex of the k-nearest-neighbour graph (before symmetrising): the
/// one-ring of a regular triangle mesh has 6; 8 keeps the graph connected across small
/// gaps in the sampling.
pub const NEIGHBOURS: usize = 8;

/// What [`propagate_unseen`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Propagation {
    /// Unseen vertices given weights from their seen neighbours.
    pub filled: usize,
    /// Unseen vertices of a component without a seen vertex (weights kept).
    pub isolated: usize,
    /// Conjugate-gradient iterations (the material columns solved side by side).
    pub iterations: usize,
}

/// A vertex graph in compressed rows: vertex `x`'s neighbours are
/// `targets[offsets[x]..offsets[x + 1]]`, ascending.
#[derive(Debug, Clone, Default)]
pub struct VertexGraph {
    pub offsets: Vec<usize>,
    pub targets: Vec<u32>,
}

impl VertexGraph {
    /// The neighbours of `x`.
    pub fn neighbours(&self, x: usize) -> &[u32] {
        &self.targets[self.offsets[x]..self.offsets[x + 1]]
    }

    /// Whether the graph has no edge.
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }
}

/// The symmetrised `k`-nearest-neighbour adjacency of `positions`.
pub fn knn_graph(positions: &[Vec3], k: usize) -> Result<VertexGraph> {
    let n = positions.len();
    let pts: Vec<[f64; 3]> = positions.iter().map(|p| [p.x, p.y, p.z]).collect();
    let tree: ImmutableKdTree<f64, 3> =
        ImmutableKdTree::new_from_slice(&pts).map_err(|e| Error::Numeric {
            stage: "material propagation".into(),
            message: format!("cannot build the k-d tree of the vertices: {e}"),
        })?;
    let qty = NonZeroUsize::new(k + 1).ok_or_else(|| Error::Numeric {
        stage: "material propagation".into(),
        message: "the neighbour count must be positive".into(),
    })?;
    let found = tree
        .query_batch(&pts)
        .nearest_n::<SquaredEuclidean<f64>>(qty)
        .execute();
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(2 * n * k);
    for i in 0..n {
        let Some(list) = found.get(i) else { continue };
        for nb in list.iter().filter(|nb| nb.item as usize != i) {
            edges.push((i as u32, nb.item));
            edges.push((nb.item, i as u32));
        }
    }
    edges.sort_unstable();
    edges.dedup();
    let mut off = vec![0usize; n + 1];
    for &(a, _) in &edges {
        off[a as usize + 1] += 1;
    }
    for i in 0..n {
        off[i + 1] += off[i];
    }
    Ok(VertexGraph {
        offsets: off,
        targets: edges.into_iter().map(|(_, b)| b).collect(),
    })
}

/// The unseen vertices reachable from a seen one through the graph.
fn reachable(off: &[usize], adj: &[u32], seen: &[bool]) -> Vec<bool> {
    let mut reach: Vec<bool> = seen.to_vec();
    let mut stack: Vec<usize> = (0..seen.len()).filter(|&x| seen[x]).collect();
    while let Some(x) = stack.pop() {
        for &y in &adj[off[x]..off[x + 1]] {
            if !reach[y as usize] {
                reach[y as usize] = true;
                stack.push(y as usize);
            }
        }
    }
    reach
}

/// Replace the weights (`weights`, row-major `V × K`) of the vertices with `seen[x]` false
/// by the harmonic extension of the seen ones over the `NEIGHBOURS`-nearest-neighbour graph
/// of `positions` (module docs).
pub fn propagate_unseen(
    positions: &[Vec3],
    seen: &[bool],
    weights: &mut [f64],
    kk: usize,
) -> Result<Propagation> {
    propagate_unseen_over(positions, None, seen, weights, kk)
}

/// [`propagate_unseen`] over `graph` when given: the `NEIGHBOURS`-nearest-neighbour graph
/// of `positions` already built ([`knn_graph`], as the neighbour prior builds it), else
/// built here when needed.
pub fn propagate_unseen_over(
    positions: &[Vec3],
    graph: Option<&VertexGraph>,
    seen: &[bool],
    weights: &mut [f64],
    kk: usize,
) -> Result<Propagation> {
    let n = positions.len();
    if seen.len() != n || weights.len() != n * kk {
        return Err(Error::Numeric {
            stage: "material propagation".into(),
            message: format!(
                "{n} positions, {} seen flags and {} weights for {kk} materials do not match",
                seen.len(),
                weights.len()
            ),
        });
    }
    if seen.iter().all(|&s| s) || seen.iter().all(|&s| !s) || kk == 0 {
        return Ok(Propagation {
            isolated: if seen.iter().any(|&s| s) { 0 } else { n },
            ..Propagation::default()
        });
    }
    let built;
    let graph = match graph {
        Some(g) => g,
        None => {
            built = knn_graph(positions, NEIGHBOURS)?;
            &built
        }
    };
    let (off, adj) = (&graph.offsets, &graph.targets);
    let reach = reachable(off, adj, seen);
    // Unknowns: the unseen vertices a seen one reaches.
    let unknown: Vec<usize> = (0..n).filter(|&x| !seen[x] && reach[x]).collect();
    let mut slot = vec![usize::MAX; n];
    for (i, &x) in unknown.iter().enumerate() {
        slot[x] = i;
    }
    let system = Harmonic {
        off,
        adj,
        unknown: &unknown,
        slot: &slot,
    };
    // Right-hand sides `A_us f_s`, row-major `unknowns × K`.
    let mut rhs = vec![0.0; unknown.len() * kk];
    for (i, &x) in unknown.iter().enumerate() {
        for &y in adj[off[x]..off[x + 1]]
            .iter()
            .filter(|&&y| seen[y as usize])
        {
            for k in 0..kk {
                rhs[i * kk + k] += weights[y as usize * kk + k];
            }
        }
    }
    let (f, iterations) = system.solve(&rhs, kk);
    for (i, &x) in unknown.iter().enumerate() {
        for k in 0..kk {
            // The exact solution is ≥ 0 (module docs); CG's round-off can leave −1e-16.
            weights[x * kk + k] = f[i * kk + k].max(0.0);
        }
    }
    Ok(Propagation {
        filled: unknown.len(),
        isolated: (0..n).filter(|&x| !reach[x]).count(),
        iterations,
    })
}

/// `L_uu` of the graph over the unknowns (module docs).
struct Harmonic<'a> {
    off: &'a [usize],
    adj: &'a [u32],
    unknown: &'a [usize],
    /// Per vertex, its index among the unknowns (`usize::MAX`: seen or isolated).
    slot: &'a [usize],
}

impl Harmonic<'_> {
    /// `out = L_uu v` for `kk` columns at once (`v`, `out` row-major `unknowns × kk`).
    fn apply(&self, v: &[f64], out: &mut [f64], kk: usize) {
        out.par_chunks_mut(kk)
            .zip(self.unknown.par_iter().enumerate())
            .for_each(|(o, (i, &x))| {
                let nb = &self.adj[self.off[x]..self.off[x + 1]];
                let d = nb.len() as f64;
                for k in 0..kk {
                    o[k] = d * v[i * kk + k];
                }
                for &y in nb {
                    let j = self.slot[y as usize];
                    if j != usize::MAX {
                        for k in 0..kk {
                            o[k] -= v[j * kk + k];
                        }
                    }
                }
            });
    }

    /// Conjugate gradients for `L_uu f = rhs`, the `kk` columns side by side (one pass over
    /// the graph per iteration for all of them, each column its own step lengths), from 0,
    /// each column to a residual of 10⁻¹² of its right-hand side's norm:
    /// `(f, iterations)`.
    fn solve(&self, rhs: &[f64], kk: usize) -> (Vec<f64>, usize) {
        let m = rhs.len();
        let col_dot = |a: &[f64], b: &[f64]| -> Vec<f64> {
            let mut d = vec![0.0; kk];
            for (ra, rb) in a.chunks(kk).zip(b.chunks(kk)) {
                for k in 0..kk {
                    d[k] += ra[k] * rb[k];
                }
            }
            d
        };
        let mut f = vec![0.0; m];
        let mut r = rhs.to_vec();
        let mut p = r.clone();
        let mut ap = vec![0.0; m];
        let mut rr = col_dot(&r, &r);
        let stop: Vec<f64> = rr.iter().map(|v| 1e-24 * v).collect();
        let mut it = 0;
        let limit = 10 * m / kk.max(1) + 10;
        while (0..kk).any(|k| rr[k] > stop[k]) && it < limit {
            self.apply(&p, &mut ap, kk);
            let pap = col_dot(&p, &ap);
            // A converged (or zero) column stops moving: step 0, direction kept at 0.
            let alpha: Vec<f64> = (0..kk)
                .map(|k| {
                    if rr[k] > stop[k] && pap[k] > 0.0 {
                        rr[k] / pap[k]
                    } else {
                        0.0
                    }
                })
                .collect();
            for i in 0..m {
                f[i] += alpha[i % kk] * p[i];
                r[i] -= alpha[i % kk] * ap[i];
            }
            let rr_new = col_dot(&r, &r);
            let beta: Vec<f64> = (0..kk)
                .map(|k| {
                    if alpha[k] > 0.0 {
                        rr_new[k] / rr[k]
                    } else {
                        0.0
                    }
                })
                .collect();
            for i in 0..m {
                p[i] = if alpha[i % kk] > 0.0 {
                    r[i] + beta[i % kk] * p[i]
                } else {
                    0.0
                };
            }
            rr = rr_new;
            it += 1;
        }
        (f, it)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn cloud(n: usize, seed: u64) -> Vec<Vec3> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect()
    }

    /// The graph against brute force: `j` is a neighbour of `i` exactly when one of the two
    /// is among the other's `k` nearest (random points: no ties).
    #[test]
    fn knn_graph_matches_brute_force() {
        let pts = cloud(300, 1);
        let k = 5;
        let g = knn_graph(&pts, k).unwrap();
        let nearest = |i: usize| -> Vec<usize> {
            let mut d: Vec<(f64, usize)> = (0..pts.len())
                .filter(|&j| j != i)
                .map(|j| ((pts[i] - pts[j]).norm_squared(), j))
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0));
            d[..k].iter().map(|v| v.1).collect()
        };
        let near: Vec<Vec<usize>> = (0..pts.len()).map(nearest).collect();
        for i in 0..pts.len() {
            let mut want: Vec<u32> = (0..pts.len())
                .filter(|&j| near[i].contains(&j) || near[j].contains(&i))
                .map(|j| j as u32)
                .collect();
            want.sort_unstable();
            assert_eq!(g.neighbours(i), &want[..], "vertex {i}");
        }
    }

    /// The solution is harmonic (every filled row the mean of its graph neighbours', to
    /// 1e-9: CG stops at a residual of 1e-12 of the right-hand side, on a system of
    /// condition far below 1e3 here), on the simplex when the seen rows are (the maximum
    /// principle, to 1e-9), and the seen rows are untouched.
    #[test]
    fn fills_unseen_with_harmonic_simplex_weights() {
        let pts = cloud(400, 2);
        let kk = 3;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let seen: Vec<bool> = (0..pts.len())
            .map(|i| i % 4 != 0 && pts[i].x > 0.3)
            .collect();
        let mut w: Vec<f64> = Vec::new();
        for i in 0..pts.len() {
            let r: [f64; 3] = [rng.random(), rng.random(), rng.random()];
            let s: f64 = r.iter().sum();
            // Unseen rows start far off the simplex: they must be replaced.
            w.extend(r.map(|v| if seen[i] { v / s } else { 7.0 }));
        }
        let before = w.clone();
        let p = propagate_unseen(&pts, &seen, &mut w, kk).unwrap();
        let unseen = seen.iter().filter(|&&s| !s).count();
        assert_eq!((p.filled, p.isolated), (unseen, 0));
        let g = knn_graph(&pts, NEIGHBOURS).unwrap();
        for x in 0..pts.len() {
            let row = &w[x * kk..(x + 1) * kk];
            if seen[x] {
                assert_eq!(row, &before[x * kk..(x + 1) * kk]);
                continue;
            }
            assert!(row.iter().all(|&v| v >= 0.0));
            assert!(
                (row.iter().sum::<f64>() - 1.0).abs() < 1e-9,
                "vertex {x}: {row:?}"
            );
            let nb = g.neighbours(x);
            for k in 0..kk {
                let mean =
                    nb.iter().map(|&y| w[y as usize * kk + k]).sum::<f64>() / nb.len() as f64;
                assert!((row[k] - mean).abs() < 1e-9, "vertex {x}, material {k}");
            }
        }
    }

    /// Known answers: a constant field extends as itself; a symmetric line of points with
    /// opposite pure materials at its ends gives its centre 1/2 : 1/2 (by the mirror
    /// symmetry of the graph, exact up to CG round-off 1e-9); a cluster far from every seen
    /// vertex keeps its weights.
    #[test]
    fn known_answers() {
        let line: Vec<Vec3> = (0..21).map(|i| Vec3::new(i as f64, 0.0, 0.0)).collect();
        let seen: Vec<bool> = (0..21).map(|i| i == 0 || i == 20).collect();
        let mut w = vec![0.0; 42];
        w[..2].copy_from_slice(&[1.0, 0.0]);
        w[40..].copy_from_slice(&[0.0, 1.0]);
        propagate_unseen(&line, &seen, &mut w, 2).unwrap();
        assert!(
            (w[20] - 0.5).abs() < 1e-9 && (w[21] - 0.5).abs() < 1e-9,
            "{:?}",
            &w[20..22]
        );
        // Monotone along the line (the harmonic extension of a step between two ends).
        assert!((0..20).all(|i| w[2 * i] >= w[2 * i + 2] - 1e-12));

        let mut w = vec![0.25; 42];
        for i in 0..21 {
            if seen[i] {
                w[2 * i..2 * i + 2].copy_from_slice(&[0.3, 0.6]);
            }
        }
        propagate_unseen(&line, &seen, &mut w, 2).unwrap();
        assert!(w
            .chunks(2)
            .all(|r| (r[0] - 0.3).abs() < 1e-9 && (r[1] - 0.6).abs() < 1e-9));

        // Two clusters of 12 points 1000 apart: with 8 neighbours each cluster is its own
        // component, and the unseen one has no seen vertex.
        let mut pts = cloud(12, 4);
        pts.extend(cloud(12, 5).iter().map(|p| p + Vec3::new(1000.0, 0.0, 0.0)));
        let seen: Vec<bool> = (0..24).map(|i| i < 12).collect();
        let mut w = vec![0.5; 24];
        w[12..].fill(0.9);
        let p = propagate_unseen(&pts, &seen, &mut w, 1).unwrap();
        assert_eq!((p.filled, p.isolated), (0, 12));
        assert!(w[12..].iter().all(|&v| v == 0.9));
    }

    #[test]
    fn mismatched_sizes_are_an_error() {
        let pts = cloud(5, 6);
        let e = propagate_unseen(&pts, &[true; 4], &mut [0.0; 10], 2).unwrap_err();
        assert!(e.to_string().contains("do not match"), "{e}");
    }
}
