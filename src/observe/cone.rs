//! Empty-cone queries: whether any triangle of the mesh lies in a cone of directions from a
//! point, so that every ray from that point in those directions is known to escape without
//! being traced.
//!
//! A cone is a cap of directions `{ω : ∠(ω, c) ≤ θ}` (unit axis `c`, half-angle `θ < π/2`)
//! from an apex `a`. Ray `a + t ω`, `t > 0`, can only hit triangle `T` if `ω` is in the set
//! of directions from `a` to the points of `T`: the spherical triangle spanned by
//! `d_k = (p_k − a) / |p_k − a|` (the positive combinations of the `d_k`, since the points
//! of `T` are convex combinations of its corners). That set meets the cap exactly when
//! ([`triangle_meets_cap`])
//! 1. a corner is in the cap, `d_k · c ≥ cos θ`; or
//! 2. the axis is in the spherical triangle, `c = Σ λ_k d_k` with every `λ_k ≥ 0`
//!    (Cramer's rule, `λ_0 = det(c, d_1, d_2) / det(d_0, d_1, d_2)`, …); or
//! 3. an edge's great-circle arc passes within `θ` of `c`: the arc's circle, normal
//!    `m = d_i × d_j / |d_i × d_j|`, comes within `asin |c · m|` of `c`, at the
//!    direction of `c − (c · m) m`, which must lie between `d_i` and `d_j`.
//!
//! When the apex is (nearly) in the triangle's plane, `det(d_0, d_1, d_2) ≈ 0`, the test
//! answers "meets": every answer of "misses" is exact, and doubt counts as a hit.
//!
//! The triangles are held in a binary tree of bounding spheres (median splits on the
//! longest axis of the centroids, at most [`LEAF`] triangles a leaf). A sphere of centre
//! `s` and radius `r` seen from `a` at distance `L = |s − a| > r` spans the cap of
//! half-angle `α = asin(r / L)` around `s − a`, so it misses the query's cap when the angle
//! `φ` between `s − a` and `c` exceeds `θ + α`: `cos φ < cos θ cos α − sin θ sin α`. A
//! sphere that contains the apex is always opened. Up to 64 caps from one apex are answered
//! in one traversal ([`ConeTree::empty_caps`]): a node carries the bit mask of the caps it
//! may meet that no triangle has met yet, so the nodes near the apex, which every cap must
//! open, are opened once (the 30K workspace's visibility on one thread: 15.7 CPU s, against
//! 17.1–17.4 with a traversal per cap and 18.5–18.6 without cones).
//!
//! The visibility uses this to skip the rays of whole blocks of texels whose cone holds no
//! triangle ([`crate::transport::visibility`]): such rays escape, whatever their jitter.

use crate::import::mesh::Mesh;
use crate::Vec3;

/// Triangles per leaf at most.
pub const LEAF: usize = 4;

/// A cap of directions: unit `axis`, half-angle `θ` given by its cosine and sine
/// (`0 ≤ θ < π/2`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cap {
    /// Unit axis `c`.
    pub axis: Vec3,
    /// `cos θ`.
    pub cos: f64,
    /// `sin θ`.
    pub sin: f64,
}

impl Cap {
    /// The cap around unit `axis` with half-angle `theta` (radians, clamped to `[0, π/2)`).
    pub fn new(axis: Vec3, theta: f64) -> Cap {
        let t = theta.clamp(0.0, std::f64::consts::FRAC_PI_2 - 1e-9);
        Cap {
            axis,
            cos: t.cos(),
            sin: t.sin(),
        }
    }
}

/// Whether triangle `q` (its corners minus the apex, `p_k − a`) has a point whose direction
/// from the apex lies in `cap` (module docs); `true` when in doubt (the apex on a corner or
/// nearly in the triangle's plane).
pub fn triangle_meets_cap(q: &[Vec3; 3], cap: &Cap) -> bool {
    TriangleDirections::new(q).meets(cap)
}

/// The directions from an apex to a triangle, reduced once to what the test of each cap
/// needs ([`triangle_meets_cap`]): the unit corner directions `d_k`, the cross products
/// `d_{k+1} × d_{k+2}` (so `λ_k = c · (d_{k+1} × d_{k+2}) / det`), and per edge `i → j` its
/// circle's unit normal `m` with `m × d_i` and `d_j × m` (the closest point
/// `c − (c · m) m` of the circle lies between `d_i` and `d_j` when `c · (m × d_i) ≥ 0` and
/// `c · (d_j × m) ≥ 0`).
pub struct TriangleDirections {
    d: [Vec3; 3],
    cross: [Vec3; 3],
    det: f64,
    /// Per edge: `m`, `m × d_i`, `d_j × m`; `None` for an edge of zero angle.
    edges: [Option<[Vec3; 3]>; 3],
    /// The apex on a corner or nearly in the triangle's plane: every cap counts as met.
    doubt: bool,
}

impl TriangleDirections {
    /// The directions to the triangle `q` (corners minus the apex).
    pub fn new(q: &[Vec3; 3]) -> TriangleDirections {
        let len = q.map(|v| v.norm());
        let mut dirs = TriangleDirections {
            d: [Vec3::zeros(); 3],
            cross: [Vec3::zeros(); 3],
            det: 0.0,
            edges: [None; 3],
            doubt: true,
        };
        if len.iter().any(|&l| l.is_nan() || l <= 0.0) {
            return dirs;
        }
        let d = [q[0] / len[0], q[1] / len[1], q[2] / len[2]];
        let cross = [d[1].cross(&d[2]), d[2].cross(&d[0]), d[0].cross(&d[1])];
        let det = d[0].dot(&cross[0]);
        let edge = |i: usize, j: usize| {
            let m = d[i].cross(&d[j]);
            let norm = m.norm();
            // The same direction twice: its corner stands for the edge (case 1).
            (norm > 1e-15).then(|| {
                let m = m / norm;
                [m, m.cross(&d[i]), d[j].cross(&m)]
            })
        };
        dirs.edges = [edge(0, 1), edge(1, 2), edge(2, 0)];
        dirs.d = d;
        dirs.cross = cross;
        dirs.det = det;
        dirs.doubt = det.abs() <= 1e-12;
        dirs
    }

    /// Whether the triangle has a point whose direction lies in `cap` (module docs).
    pub fn meets(&self, cap: &Cap) -> bool {
        if self.doubt {
            return true;
        }
        let c = &cap.axis;
        // 1. A corner in the cap.
        if self.d.iter().any(|dk| dk.dot(c) >= cap.cos) {
            return true;
        }
        // 2. The axis among the directions to the triangle's interior.
        if self.cross.iter().all(|x| c.dot(x) / self.det >= -1e-12) {
            return true;
        }
        // 3. An edge's arc within the cap.
        self.edges.iter().flatten().any(|[m, from, to]| {
            c.dot(m).abs() <= cap.sin && c.dot(from) >= 0.0 && c.dot(to) >= 0.0
        })
    }
}

/// A node: bounding sphere, and either two children or a leaf's triangle range.
#[derive(Debug, Clone, Copy)]
struct Node {
    centre: Vec3,
    radius: f64,
    /// Half the box's extent per axis (the box is `centre ± half`).
    half: Vec3,
    /// Inner: `[left, right]` node indices; leaf: `[start, end)` into the triangles,
    /// marked by `leaf`.
    range: [u32; 2],
    leaf: bool,
}

/// The mesh's triangles in a tree of bounding spheres, for [`ConeTree::cone_is_empty`].
#[derive(Debug, Clone, Default)]
pub struct ConeTree {
    nodes: Vec<Node>,
    tris: Vec<[Vec3; 3]>,
}

impl ConeTree {
    /// The tree over `mesh`'s faces. Faces with a non-finite corner, which the mesh's own
    /// cleaning drops ([`Mesh::from_parts`]), are left out here too: they would make their
    /// nodes' bounds NaN, and a NaN bound would skip its node.
    pub fn new(mesh: &Mesh) -> ConeTree {
        let mut tris: Vec<[Vec3; 3]> = mesh
            .faces
            .iter()
            .map(|f| f.map(|i| mesh.positions[i as usize]))
            .filter(|t| t.iter().all(|p| p.iter().all(|c| c.is_finite())))
            .collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF + 1);
        if !tris.is_empty() {
            let len = tris.len();
            build(&mut tris, 0, len, &mut nodes);
        }
        ConeTree { nodes, tris }
    }

    /// Whether no triangle has a point whose direction from `apex` lies in `cap` and on the
    /// upper side of the plane through `apex` with unit normal `up` (`ω · up ≥ 0`: the
    /// directions of a hemisphere's texels). `true` is exact (every such ray from `apex`
    /// misses every triangle); `false` may be a doubt. `stack` is scratch.
    ///
    /// A triangle (or node) wholly below that plane is missed by every ray going up or
    /// along it: this is what lets cones that reach the horizon be empty although the
    /// vertex's own triangles (`ε` below the apex) are all around it.
    pub fn cone_is_empty(
        &self,
        apex: &Vec3,
        up: &Vec3,
        cap: &Cap,
        stack: &mut Vec<(u32, u64)>,
    ) -> bool {
        self.empty_caps(apex, up, std::slice::from_ref(cap), stack) == 1
    }

    /// [`ConeTree::cone_is_empty`] for up to 64 caps from one apex in one traversal: bit
    /// `k` of the answer is set when cap `k`'s cone is empty. A node is opened with the
    /// caps it may meet that no triangle has met yet, so the nodes near the apex, which
    /// every cap must open, are opened once.
    pub fn empty_caps(
        &self,
        apex: &Vec3,
        up: &Vec3,
        caps: &[Cap],
        stack: &mut Vec<(u32, u64)>,
    ) -> u64 {
        assert!(caps.len() <= 64, "{} caps in one query", caps.len());
        let all = match caps.len() {
            0 => 0,
            n => u64::MAX >> (64 - n),
        };
        let mut met = 0_u64;
        if self.nodes.is_empty() {
            return all;
        }
        stack.clear();
        stack.push((0, all));
        while let Some((k, mask)) = stack.pop() {
            let node = &self.nodes[k as usize];
            let w = node.centre - apex;
            if w.dot(up) + node.half.dot(&up.abs()) < -below_slack(&w, node.radius) {
                continue;
            }
            let mask = sphere_may_meet(&w, node.radius, caps, mask & !met);
            if mask == 0 {
                continue;
            }
            let [a, b] = node.range;
            if !node.leaf {
                stack.push((b, mask));
                stack.push((a, mask));
                continue;
            }
            for t in &self.tris[a as usize..b as usize] {
                let q = t.map(|p| p - apex);
                if q.iter().all(|v| v.dot(up) < -below_slack(v, 0.0)) {
                    continue;
                }
                let dirs = TriangleDirections::new(&q);
                for bit in bits(mask & !met) {
                    if dirs.meets(&caps[bit]) {
                        met |= 1 << bit;
                    }
                }
            }
        }
        all & !met
    }
}

/// The indices of the set bits of `mask`, lowest first.
fn bits(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let b = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            b
        })
    })
}

/// How far below the plane a point at offset `w` (plus `radius`) from the apex must lie to
/// count as below it: `10⁻¹²` of its distance, more than the rounding of a direction's
/// height over the plane can carry a ray down.
fn below_slack(w: &Vec3, radius: f64) -> f64 {
    1e-12 * (w.x.abs() + w.y.abs() + w.z.abs() + radius)
}

/// The caps of `mask` that the sphere of radius `radius` at offset `w` from the apex may
/// meet: all when it holds the apex, else those its angular extent does not miss (module
/// docs), with `10⁻⁹` of slack against rounding.
fn sphere_may_meet(w: &Vec3, radius: f64, caps: &[Cap], mask: u64) -> u64 {
    let dist = w.norm();
    if mask == 0 || dist <= radius * (1.0 + 1e-9) {
        return mask;
    }
    let sin_a = radius / dist;
    let cos_a = (1.0 - sin_a * sin_a).max(0.0).sqrt();
    let dir = w / dist;
    bits(mask)
        .filter(|&k| {
            let cap = &caps[k];
            dir.dot(&cap.axis) >= cap.cos * cos_a - cap.sin * sin_a - 1e-9
        })
        .fold(0, |m, k| m | 1 << k)
}

/// Build the subtree over `tris[start..end]`; returns its node index.
fn build(tris: &mut [[Vec3; 3]], start: usize, end: usize, nodes: &mut Vec<Node>) -> usize {
    let (lo, hi) = tris[start..end].iter().flatten().fold(
        (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let me = nodes.len();
    let centre = (lo + hi) * 0.5;
    let radius = tris[start..end]
        .iter()
        .flatten()
        .map(|p| (p - centre).norm())
        .fold(0.0, f64::max);
    nodes.push(Node {
        centre,
        radius,
        half: (hi - lo) * 0.5,
        range: [start as u32, end as u32],
        leaf: true,
    });
    if end - start <= LEAF {
        return me;
    }
    let centroid = |t: &[Vec3; 3]| (t[0] + t[1] + t[2]) / 3.0;
    let (clo, chi) = tris[start..end].iter().map(centroid).fold(
        (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), c| (lo.inf(&c), hi.sup(&c)),
    );
    let axis = (chi - clo).imax();
    let mid = start + (end - start) / 2;
    tris[start..end].select_nth_unstable_by(mid - start, |a, b| {
        centroid(a)[axis].total_cmp(&centroid(b)[axis])
    });
    let left = build(tris, start, mid, nodes);
    let right = build(tris, mid, end, nodes);
    nodes[me].range = [left as u32, right as u32];
    nodes[me].leaf = false;
    me
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observe::trace::intersect_triangle;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;
    // A uniformly random unit direction.
    use crate::sphere::random_unit as unit;

    /// A uniform direction in `cap`: uniform `cos` in `[cos θ, 1]`, uniform azimuth.
    fn in_cap(rng: &mut Pcg64, cap: &Cap) -> Vec3 {
        let z = rng.random_range(cap.cos..=1.0);
        let phi = rng.random_range(0.0..std::f64::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let [u, v, _] = crate::sphere::local_frame(&cap.axis);
        u * (r * phi.cos()) + v * (r * phi.sin()) + cap.axis * z
    }

    #[test]
    fn a_missed_cap_is_missed_by_every_ray_and_a_hit_ray_means_a_met_cap() {
        // Random triangles near the apex and random caps of 2°–40°. Whenever the test
        // says "misses", 400 rays with directions in the cap (and the cap's boundary
        // directions) must miss the triangle (Möller–Trumbore, the tracer's own test); and
        // every cap that a ray hits through must be reported as met. Independent of the
        // test: the rays are the definition of the question.
        let mut rng = Pcg64::seed_from_u64(7);
        let (mut missed, mut met) = (0, 0);
        for _ in 0..3000 {
            let centre = unit(&mut rng) * rng.random_range(0.2..3.0);
            let size = rng.random_range(0.05..1.5);
            let tri = [0, 1, 2].map(|_| centre + unit(&mut rng) * size);
            // Half the caps aimed near the triangle, so that both answers are common.
            let axis = if rng.random::<bool>() {
                (centre.normalize() + unit(&mut rng) * 0.5).normalize()
            } else {
                unit(&mut rng)
            };
            let cap = Cap::new(axis, rng.random_range(2.0_f64..40.0).to_radians());
            let meets = triangle_meets_cap(&tri, &cap);
            let hit = (0..400).any(|_| {
                let d = in_cap(&mut rng, &cap);
                intersect_triangle(&tri, &Vec3::zeros(), &d, 0.0, f64::INFINITY).is_some()
            });
            if hit {
                assert!(
                    meets,
                    "a ray in the cap hits the triangle, yet the test says missed"
                );
            }
            if meets {
                met += 1;
            } else {
                missed += 1;
            }
        }
        // Both answers occur often enough for the check to mean something.
        assert!(missed > 500 && met > 500, "missed {missed}, met {met}");
    }

    #[test]
    fn the_axis_inside_a_large_triangle_is_a_meeting() {
        // A triangle straddling the axis with every corner outside a narrow cap (case 2),
        // and one whose edge crosses the cap with both corners outside it (case 3).
        let cap = Cap::new(Vec3::z(), 5f64.to_radians());
        let big = [
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, -1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        assert!(triangle_meets_cap(&big, &cap));
        let crossing = [
            Vec3::new(-1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 5.0, 1.0),
        ];
        assert!(triangle_meets_cap(&crossing, &cap));
        let beside = crossing.map(|p| p + Vec3::new(0.0, 0.5, 0.0));
        assert!(!triangle_meets_cap(&beside, &cap));
        // Behind the apex: never met.
        assert!(!triangle_meets_cap(&big.map(|p| -p), &cap));
    }

    #[test]
    fn the_tree_answers_as_every_triangle_tested_alone() {
        // A soup of 2,000 triangles: the tree's answer equals the brute-force "no triangle
        // meets the cap" for 2,000 random apexes and caps (the spheres only prune).
        let mut rng = Pcg64::seed_from_u64(11);
        let mut mesh = Mesh::default();
        for k in 0..2000u32 {
            let c = unit(&mut rng) * rng.random_range(0.0..2.0);
            for _ in 0..3 {
                mesh.positions.push(c + unit(&mut rng) * 0.08);
            }
            mesh.faces.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        let tree = ConeTree::new(&mesh);
        let mut stack = Vec::new();
        let mut empty = 0;
        for _ in 0..2000 {
            let apex = unit(&mut rng) * rng.random_range(0.0..3.0);
            let cap = Cap::new(unit(&mut rng), rng.random_range(1.0_f64..30.0).to_radians());
            let up = unit(&mut rng);
            let brute = mesh.faces.iter().all(|f| {
                let q = f.map(|i| mesh.positions[i as usize] - apex);
                q.iter().all(|v| v.dot(&up) < 0.0) || !triangle_meets_cap(&q, &cap)
            });
            assert_eq!(tree.cone_is_empty(&apex, &up, &cap, &mut stack), brute);
            empty += usize::from(brute);
        }
        assert!(empty > 100 && empty < 1900, "{empty} of 2000 empty");
        // 64 caps from one apex in one traversal: each bit as the cap tested alone.
        for _ in 0..50 {
            let apex = unit(&mut rng) * rng.random_range(0.0..3.0);
            let up = unit(&mut rng);
            let caps: Vec<Cap> = (0..64)
                .map(|_| Cap::new(unit(&mut rng), rng.random_range(1.0_f64..30.0).to_radians()))
                .collect();
            let alone = caps.iter().enumerate().fold(0_u64, |m, (k, cap)| {
                m | u64::from(tree.cone_is_empty(&apex, &up, cap, &mut stack)) << k
            });
            assert_eq!(tree.empty_caps(&apex, &up, &caps, &mut stack), alone);
            assert_eq!(
                tree.empty_caps(&apex, &up, &caps[..5], &mut stack),
                alone & 31
            );
        }
    }
}
