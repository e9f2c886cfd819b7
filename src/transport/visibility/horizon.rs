//! The horizon of a vertex: an exact bound above which every shadow ray escapes.
//!
//! A ray `o + t ω` (`t > 0`, unit `ω`) can only hit a triangle `T` if `ω` lies in `T`'s
//! spherical image from `o`, `{(p − o)/|p − o| : p ∈ T}`. So with
//!
//! `h(o, n) = max_T max_{p ∈ T} n·(p − o)/|p − o|`
//!
//! (the sine of the highest elevation, above the plane through `o` with normal `n`, of any
//! point of the mesh), every ray with `n·ω > h` escapes: it needs no traversal. This is the
//! open-hemisphere shortcut of [`super`] made per direction: where that test proves the whole
//! hemisphere open, this one proves a cap around `n` open, and the rays in it are skipped
//! while their directions (and the random numbers behind them) stay the same, so the
//! visibility is unchanged bit for bit.
//!
//! `h` is computed by branch and bound over a bounding-box tree of the triangles. A box `B`
//! bounds the elevation of its points by `sup_B n·(p − o) / dist(o, B)` (1 when `o` lies
//! in `B`; nothing when the support is below the plane); a node is opened only when that
//! bound exceeds the best value found so far. A triangle's own maximum is exact: the
//! spherical image of a triangle not containing `o` is the geodesic triangle on the unit
//! sphere spanned by its corners' directions `u_0, u_1, u_2`, and the maximum of the linear
//! function `n·u` over it is 1 when `n` lies inside (`n·(u_i × u_{i+1})` all of the sign of
//! `u_0·(u_1 × u_2)`), else on its boundary: at a corner, or on an arc `u_a u_b` at the
//! normalised projection `q` of `n` onto the arc's great circle (normal `m = u_a × u_b`,
//! `q = n − (n·m̂) m̂`, value `|q|`) when `q` lies between `u_a` and `u_b`.
//!
//! The ray–triangle test accepts points up to `1e-12` outside a triangle in barycentric
//! terms ([`crate::observe::trace`]); [`HORIZON_MARGIN`] on the sine covers that and the
//! rounding of the bound, many orders of magnitude over.

use std::collections::BinaryHeap;

use crate::Vec3;

/// Margin added to the horizon sine before a ray is skipped (module docs).
pub const HORIZON_MARGIN: f64 = 1e-6;

/// Triangles per leaf of [`TriangleTree`].
const LEAF: usize = 8;

/// A bounding-box tree over triangles for [`TriangleTree::horizon`] queries.
pub struct TriangleTree {
    tris: Vec<[Vec3; 3]>,
    nodes: Vec<BoxNode>,
}

/// A node: its box and either a leaf range of triangles or two children.
struct BoxNode {
    lo: Vec3,
    hi: Vec3,
    kind: BoxKind,
}

enum BoxKind {
    Leaf(usize, usize),
    Inner(usize, usize),
}

/// The sine bound of a box (module docs); `None` when the box lies wholly on or below the
/// plane through `o` with normal `n`.
fn box_bound(lo: &Vec3, hi: &Vec3, o: &Vec3, n: &Vec3) -> Option<f64> {
    let mut up = 0.0;
    let mut d2 = 0.0;
    for i in 0..3 {
        up += (n[i] * (lo[i] - o[i])).max(n[i] * (hi[i] - o[i]));
        let gap = (lo[i] - o[i]).max(o[i] - hi[i]).max(0.0);
        d2 += gap * gap;
    }
    if up <= 0.0 {
        return None;
    }
    if d2 == 0.0 {
        return Some(1.0);
    }
    Some((up / d2.sqrt()).min(1.0))
}

/// The exact maximum of `n·(p − o)/|p − o|` over triangle `c` (module docs); 1 when `o`
/// lies on the triangle's corners or edges' lines within rounding.
pub fn triangle_max_sine(c: &[Vec3; 3], o: &Vec3, n: &Vec3) -> f64 {
    let mut u = [Vec3::zeros(); 3];
    for (ui, ci) in u.iter_mut().zip(c) {
        let a = ci - o;
        let len = a.norm();
        if len.is_nan() || len == 0.0 {
            return 1.0;
        }
        *ui = a / len;
    }
    let mut best = u
        .iter()
        .map(|ui| n.dot(ui))
        .fold(f64::NEG_INFINITY, f64::max);
    let orient = u[0].dot(&u[1].cross(&u[2]));
    let mut inside = orient != 0.0;
    for k in 0..3 {
        let (a, b) = (&u[k], &u[(k + 1) % 3]);
        let m = a.cross(b);
        inside &= n.dot(&m) * orient >= 0.0;
        let mn = m.norm();
        if mn < 1e-12 {
            if a.dot(b) < 0.0 {
                // `o` on the segment between the corners: the image is a half circle.
                return 1.0;
            }
            continue;
        }
        let m = m / mn;
        let q = n - m * n.dot(&m);
        if a.cross(&q).dot(&m) >= 0.0 && q.cross(b).dot(&m) >= 0.0 {
            best = best.max(q.norm());
        }
    }
    if inside {
        1.0
    } else {
        best.min(1.0)
    }
}

impl TriangleTree {
    /// The tree over `tris` (triangles with a non-finite corner are left out: no ray
    /// hits them either).
    pub fn new(tris: impl Iterator<Item = [Vec3; 3]>) -> Self {
        let mut tris: Vec<[Vec3; 3]> = tris
            .filter(|t| t.iter().all(|c| c.iter().all(|x| x.is_finite())))
            .collect();
        let mut nodes = Vec::new();
        if !tris.is_empty() {
            let len = tris.len();
            build(&mut tris, 0, len, &mut nodes);
        }
        TriangleTree { tris, nodes }
    }

    /// `h(o, n)` of the module docs, floored at 0 (rays below the plane are traced
    /// anyway), without [`HORIZON_MARGIN`].
    pub fn horizon(&self, o: &Vec3, n: &Vec3, heap: &mut BinaryHeap<(u64, usize)>) -> f64 {
        let mut best = 0.0f64;
        heap.clear();
        if !self.nodes.is_empty() {
            let b = self.bound(0, o, n);
            if b > 0.0 {
                heap.push((b.to_bits(), 0));
            }
        }
        // Best first: nodes leave the queue by decreasing bound, so the search ends at the
        // first node whose bound does not exceed the best maximum found.
        while let Some((bits, k)) = heap.pop() {
            if f64::from_bits(bits) <= best {
                break;
            }
            match self.nodes[k].kind {
                BoxKind::Leaf(a, b) => {
                    for t in &self.tris[a..b] {
                        let (lo, hi) = tri_box(t);
                        if box_bound(&lo, &hi, o, n).is_some_and(|b| b > best) {
                            best = best.max(triangle_max_sine(t, o, n));
                        }
                    }
                    if best >= 1.0 {
                        return 1.0;
                    }
                }
                BoxKind::Inner(l, r) => {
                    for c in [l, r] {
                        let b = self.bound(c, o, n);
                        if b > best {
                            heap.push((b.to_bits(), c));
                        }
                    }
                }
            }
        }
        best
    }

    /// [`box_bound`] of node `k` (`-1` when it lies below the plane).
    fn bound(&self, k: usize, o: &Vec3, n: &Vec3) -> f64 {
        let node = &self.nodes[k];
        box_bound(&node.lo, &node.hi, o, n).unwrap_or(-1.0)
    }
}

fn tri_box(t: &[Vec3; 3]) -> (Vec3, Vec3) {
    (t[0].inf(&t[1]).inf(&t[2]), t[0].sup(&t[1]).sup(&t[2]))
}

fn build(tris: &mut [[Vec3; 3]], start: usize, end: usize, nodes: &mut Vec<BoxNode>) -> usize {
    let slice = &mut tris[start..end];
    let (mut lo, mut hi) = tri_box(&slice[0]);
    for t in slice.iter() {
        let (l, h) = tri_box(t);
        lo = lo.inf(&l);
        hi = hi.sup(&h);
    }
    let id = nodes.len();
    nodes.push(BoxNode {
        lo,
        hi,
        kind: BoxKind::Leaf(start, end),
    });
    if end - start > LEAF {
        let ext = hi - lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let centre = |t: &[Vec3; 3]| t[0][axis] + t[1][axis] + t[2][axis];
        let mid = (end - start) / 2;
        slice.select_nth_unstable_by(mid, |a, b| centre(a).total_cmp(&centre(b)));
        let l = build(tris, start, start + mid, nodes);
        let r = build(tris, start + mid, end, nodes);
        nodes[id].kind = BoxKind::Inner(l, r);
    }
    id
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_unit(rng: &mut Pcg64) -> Vec3 {
        loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if v.norm() > 0.1 && v.norm() < 1.0 {
                return v.normalize();
            }
        }
    }

    /// The largest sine over a dense barycentric grid of the triangle (brute force).
    fn sampled_max(c: &[Vec3; 3], o: &Vec3, n: &Vec3, steps: usize) -> f64 {
        let mut best = f64::NEG_INFINITY;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (a, b) = (i as f64 / steps as f64, j as f64 / steps as f64);
                let p = c[0] * (1.0 - a - b) + c[1] * a + c[2] * b;
                let d = p - o;
                best = best.max(n.dot(&d) / d.norm());
            }
        }
        best
    }

    #[test]
    fn triangle_maximum_matches_dense_sampling() {
        // The exact maximum must bound every sampled point (up to rounding, 1e-12) and be
        // reached by the samples to within the grid's resolution: at 400 steps a sample
        // lies within 1/400 of a side of the maximiser, which moves the sine by at most
        // side/(400 · distance); the triangles below are at least 0.2 away with sides up
        // to ~2, so 0.03 covers it.
        let mut rng = Pcg64::seed_from_u64(5);
        let mut interior = 0;
        for _ in 0..300 {
            let o = Vec3::zeros();
            let n = random_unit(&mut rng);
            let centre = random_unit(&mut rng) * rng.random_range(0.5..1.5);
            let c = [0, 1, 2].map(|_| centre + random_unit(&mut rng) * 0.4);
            if c.iter().any(|ci| ci.norm() < 0.2) {
                continue;
            }
            let exact = triangle_max_sine(&c, &o, &n);
            let brute = sampled_max(&c, &o, &n, 400);
            assert!(
                brute <= exact + 1e-12,
                "sample {brute} above the bound {exact}"
            );
            assert!(
                exact - brute < 0.03,
                "bound {exact} far above the samples {brute}"
            );
            interior += usize::from(exact == 1.0);
        }
        assert!(
            interior > 0,
            "some triangles should contain the normal's direction"
        );
    }

    #[test]
    fn tree_horizon_is_the_maximum_over_all_triangles() {
        // Branch and bound against a linear scan of the exact per-triangle maxima.
        let mut rng = Pcg64::seed_from_u64(9);
        let tris: Vec<[Vec3; 3]> = (0..600)
            .map(|_| {
                let c = Vec3::new(rng.random(), rng.random(), rng.random()) * 4.0;
                [0, 1, 2].map(|_| c + random_unit(&mut rng) * 0.2)
            })
            .collect();
        let tree = TriangleTree::new(tris.iter().copied());
        let mut stack = BinaryHeap::new();
        let mut below_one = 0;
        for _ in 0..200 {
            let o = Vec3::new(rng.random(), rng.random(), rng.random()) * 4.0;
            let n = random_unit(&mut rng);
            let want = tris
                .iter()
                .map(|t| triangle_max_sine(t, &o, &n))
                .fold(0.0, f64::max);
            let got = tree.horizon(&o, &n, &mut stack);
            assert_eq!(got, want);
            below_one += usize::from(got < 1.0);
        }
        assert!(
            below_one > 20,
            "the scenes should leave some caps open ({below_one})"
        );
    }
}
