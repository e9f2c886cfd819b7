//! Texel blocks answered by empty cones before any shadow ray: the blocks' caps in the
//! local frame, and the per-vertex test through [`crate::observe::cone`] (module docs of
//! [`super`]).

use crate::import::mesh::Mesh;
use crate::observe::cone::{Cap, ConeTree};
use crate::sphere::SphereGrid;
use crate::Vec3;

/// Blocks of texels whose cone of directions is tested for emptiness before any ray
/// ([`crate::observe::cone`]): a block whose cone, from the rays' origin and above the
/// vertex's tangent plane, holds no triangle has every ray escape, so its rays are answered
/// without tracing and the map is the same, bit for bit (the jitter is still drawn).
///
/// Blocks are an eighth of the map's side (4 × 4 texels at 32²; none below 16²). Their caps
/// are computed once, in the local frame: a block's directions are the image of its `uv`
/// square under [`SphereGrid::decode`], whose largest angle from any axis (not antipodal to
/// the block) lies on the square's boundary; the boundary is sampled [`CAP_SAMPLES`] times
/// per texel side, the axis is the samples' mean direction, and the half-angle is the
/// largest sample angle plus the largest angle between neighbouring samples (what a
/// boundary point between two samples can add) plus `10⁻⁶`. A vertex's frame is a
/// rotation, so its caps are the local ones with the axis rotated.
///
/// The 64 blocks' cones are tested in one traversal of the triangle tree
/// ([`ConeTree::empty_caps`]). Measured on the 30K workspace's mesh (one thread,
/// `bench-results/speed-levers-3.md`): 42% of the rays answered without tracing, the
/// visibility 18.5 → 15.7 CPU s (−15%; the rays of open sky are the cheap ones); 2 × 2 or
/// 8 × 8 blocks saved less.
pub(super) struct OpenCones {
    tree: ConeTree,
    /// Block side in texels.
    side: usize,
    /// The blocks' local caps, row-major.
    caps: Vec<Cap>,
    n: usize,
}

/// Boundary samples per texel side of a block, for its cap ([`OpenCones`]).
const CAP_SAMPLES: usize = 16;

/// A worker's scratch for [`OpenCones::mark_open`].
#[derive(Default)]
pub(super) struct ConeScratch {
    pub(super) sure: Vec<bool>,
    caps: Vec<Cap>,
    stack: Vec<(u32, u64)>,
}

impl OpenCones {
    /// `None` when the blocks would be smaller than 2 × 2 texels.
    pub(super) fn new(mesh: &Mesh, grid: &SphereGrid) -> Option<OpenCones> {
        let side = grid.n / 8;
        (side >= 2).then(|| OpenCones {
            tree: ConeTree::new(mesh),
            side,
            caps: block_caps(grid, side),
            n: grid.n,
        })
    }

    /// Set `scratch.sure[t]` for the texels of every block whose cone from `origin`, above
    /// the plane of normal `up`, is empty; `to_world` rotates local directions to world.
    pub(super) fn mark_open(
        &self,
        origin: &Vec3,
        up: &Vec3,
        to_world: impl Fn(&Vec3) -> Vec3,
        scratch: &mut ConeScratch,
    ) {
        let (b, per_row) = (self.side, self.n / self.side);
        scratch.caps.clear();
        scratch.caps.extend(self.caps.iter().map(|local| Cap {
            axis: to_world(&local.axis),
            ..*local
        }));
        for (c, caps) in scratch.caps.chunks(64).enumerate() {
            let empty = self.tree.empty_caps(origin, up, caps, &mut scratch.stack);
            for k in (0..caps.len()).filter(|k| empty >> k & 1 == 1) {
                let k = 64 * c + k;
                let (i0, j0) = ((k % per_row) * b, (k / per_row) * b);
                for j in j0..j0 + b {
                    scratch.sure[j * self.n + i0..j * self.n + i0 + b].fill(true);
                }
            }
        }
    }
}

/// The local caps of the `b × b` blocks of `grid`, row-major ([`OpenCones`]).
fn block_caps(grid: &SphereGrid, b: usize) -> Vec<Cap> {
    let n = grid.n;
    let per_row = n / b;
    (0..per_row * per_row)
        .map(|k| {
            let (i0, j0) = ((k % per_row) * b, (k / per_row) * b);
            let steps = b * CAP_SAMPLES;
            let at = |s: usize| -> [f64; 2] {
                // The boundary walked once around: four sides of `steps` samples.
                let (side, r) = (s / steps, (s % steps) as f64 / steps as f64);
                let (u, v) = match side {
                    0 => (r, 0.0),
                    1 => (1.0, r),
                    2 => (1.0 - r, 1.0),
                    _ => (0.0, 1.0 - r),
                };
                let bf = b as f64;
                [
                    (i0 as f64 + u * bf) / n as f64,
                    (j0 as f64 + v * bf) / n as f64,
                ]
            };
            let ring: Vec<Vec3> = (0..4 * steps).map(|s| grid.decode(at(s))).collect();
            let axis = ring.iter().fold(Vec3::zeros(), |a, d| a + d).normalize();
            let angle = |a: &Vec3, b: &Vec3| a.dot(b).clamp(-1.0, 1.0).acos();
            let widest = ring.iter().map(|d| angle(&axis, d)).fold(0.0, f64::max);
            let step = (0..ring.len())
                .map(|s| angle(&ring[s], &ring[(s + 1) % ring.len()]))
                .fold(0.0, f64::max);
            Cap::new(axis, widest + step + 1e-6)
        })
        .collect()
}
