//! A bounding-box tree over the mesh's vertex positions for the half-space emptiness query
//! of provably open vertices (module docs of [`super`]).

use crate::Vec3;

/// A bounding-box tree over points for half-space emptiness queries.
pub(super) struct PointTree {
    points: Vec<Vec3>,
    /// Nodes: box and either children or a leaf range.
    nodes: Vec<Node>,
}

struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: `points[start..end]`; inner: `left`, `right` node indices.
    kind: NodeKind,
}

enum NodeKind {
    Leaf(usize, usize),
    Inner(usize, usize),
}

const LEAF: usize = 16;

impl PointTree {
    pub(super) fn new(points: &[Vec3]) -> Self {
        let mut pts: Vec<Vec3> = points
            .iter()
            .filter(|p| p.iter().all(|c| c.is_finite()))
            .copied()
            .collect();
        let mut nodes = Vec::new();
        if !pts.is_empty() {
            let len = pts.len();
            build(&mut pts, 0, len, &mut nodes);
        }
        PointTree { points: pts, nodes }
    }

    /// Whether some point `p` has `n·(p − x) > eps`.
    pub(super) fn any_above(&self, x: &Vec3, n: &Vec3, eps: f64) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let level = n.dot(x) + eps;
        let mut stack = vec![0usize];
        while let Some(k) = stack.pop() {
            let node = &self.nodes[k];
            // Support of the box in direction n.
            let sup: f64 = (0..3)
                .map(|i| (n[i] * node.lo[i]).max(n[i] * node.hi[i]))
                .sum();
            if sup <= level {
                continue;
            }
            match node.kind {
                NodeKind::Leaf(a, b) => {
                    if self.points[a..b].iter().any(|p| n.dot(p) > level) {
                        return true;
                    }
                }
                NodeKind::Inner(l, r) => {
                    stack.push(l);
                    stack.push(r);
                }
            }
        }
        false
    }
}

fn build(pts: &mut [Vec3], start: usize, end: usize, nodes: &mut Vec<Node>) -> usize {
    let slice = &mut pts[start..end];
    let mut lo = slice[0];
    let mut hi = slice[0];
    for p in slice.iter() {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let id = nodes.len();
    nodes.push(Node {
        lo,
        hi,
        kind: NodeKind::Leaf(start, end),
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
        let mid = (end - start) / 2;
        slice.select_nth_unstable_by(mid, |a, b| a[axis].total_cmp(&b[axis]));
        let l = build(pts, start, start + mid, nodes);
        let r = build(pts, start + mid, end, nodes);
        nodes[id].kind = NodeKind::Inner(l, r);
    }
    id
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn point_tree_matches_brute_force() {
        // The half-space query is exact: compare with a linear scan on random clouds.
        let mut rng = Pcg64::seed_from_u64(3);
        let pts: Vec<Vec3> = (0..500)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let tree = PointTree::new(&pts);
        for _ in 0..300 {
            let x = Vec3::new(rng.random(), rng.random(), rng.random());
            let n = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let brute = pts.iter().any(|p| n.dot(&(p - x)) > 1e-9);
            assert_eq!(tree.any_above(&x, &n, 1e-9), brute);
        }
    }
}
