//! The order in which the vertices' shadow rays are traced: along a Morton (Z-order)
//! curve through the mesh's bounding box (Morton 1966), so that the vertices one worker
//! thread takes in a row are neighbours in space and their rays walk the same BVH nodes
//! while those are still in cache.
//!
//! Each coordinate is quantised to `B = 21` bits over the bounding box,
//! `q = ⌊(x − min) / (max − min) · (2^B − 1)⌋`, and the key interleaves the bits of
//! `q_x, q_y, q_z` (bit `i` of `q_x` at bit `3i`, of `q_y` at `3i + 1`, of `q_z` at
//! `3i + 2`). Sorting by the key visits the boxes of an octree depth first.
//!
//! Every vertex's rays are seeded by its own index and use only scratch that is reset per
//! vertex, so the order changes no value: only where in memory the traversal finds its
//! nodes (a test below traces one scene in three orders).

use crate::Vec3;

/// Bits per coordinate of a key (3 × 21 = 63 bits).
const BITS: u32 = 21;

/// Spread the low 21 bits of `v` to every third bit (bit `i` to bit `3i`).
fn spread_bits(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The Morton key of each point within the points' bounding box (module docs); points
/// with a coordinate that is not finite get the key 0.
pub fn morton_keys(points: &[Vec3]) -> Vec<u64> {
    let finite = |p: &&Vec3| p.iter().all(|c| c.is_finite());
    let mut lo = Vec3::repeat(f64::INFINITY);
    let mut hi = Vec3::repeat(f64::NEG_INFINITY);
    for p in points.iter().filter(finite) {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let top = ((1u64 << BITS) - 1) as f64;
    points
        .iter()
        .map(|p| {
            if !finite(&p) {
                return 0;
            }
            (0..3).fold(0, |key, axis| {
                let extent = hi[axis] - lo[axis];
                let t = if extent > 0.0 {
                    (p[axis] - lo[axis]) / extent
                } else {
                    0.0
                };
                let q = (t * top).clamp(0.0, top) as u64;
                key | spread_bits(q) << axis
            })
        })
        .collect()
}

/// The vertex indices sorted by their Morton keys (ties by index, so the order is
/// deterministic).
pub fn spatial_order(points: &[Vec3]) -> Vec<u32> {
    let keys = morton_keys(points);
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    order.sort_unstable_by_key(|&v| (keys[v as usize], v));
    order
}

#[cfg(test)]
mod tests {
    use super::super::{compute_in_order, Sampling, Tracing};
    use super::*;
    use crate::observe::trace::SceneBvh;
    use nalgebra::Matrix3;

    /// Spreading then reading every third bit back gives the number again, for every bit.
    #[test]
    fn spread_bits_moves_bit_i_to_bit_3i() {
        for i in 0..BITS {
            assert_eq!(spread_bits(1 << i), 1 << (3 * i), "bit {i}");
        }
        let v = 0x15_5a5a;
        let back = (0..BITS).fold(0, |acc, i| acc | ((spread_bits(v) >> (3 * i)) & 1) << i);
        assert_eq!(back, v);
    }

    /// On the 8 corners of a cube the keys follow the Z-order: x is the lowest bit, then
    /// y, then z.
    #[test]
    fn the_corners_of_a_box_come_in_z_order() {
        let mut corners = Vec::new();
        for code in [5usize, 2, 7, 0, 3, 6, 1, 4] {
            let c = |b: usize| ((code >> b) & 1) as f64;
            corners.push(Vec3::new(c(0), c(1), c(2)));
        }
        let order = spatial_order(&corners);
        let codes: Vec<usize> = order
            .iter()
            .map(|&v| {
                let p = corners[v as usize];
                p.x as usize | (p.y as usize) << 1 | (p.z as usize) << 2
            })
            .collect();
        assert_eq!(codes, (0..8).collect::<Vec<_>>());
    }

    /// On points scattered at random, consecutive points in the order are far nearer each
    /// other than consecutive points of the input. A grid of 32³ cells holds 4,096 points
    /// at ~1/16 of the box apart, so along the curve most steps are one cell (~1/32 of the
    /// box, far below 1/4): the factor 4 leaves room for the curve's jumps between octants.
    #[test]
    fn consecutive_points_of_the_order_are_neighbours() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let points: Vec<Vec3> = (0..4096)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        let mean_step = |idx: &[u32]| {
            let d: f64 = idx
                .windows(2)
                .map(|w| (points[w[0] as usize] - points[w[1] as usize]).norm())
                .sum();
            d / (idx.len() - 1) as f64
        };
        let input: Vec<u32> = (0..points.len() as u32).collect();
        let order = spatial_order(&points);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, input, "a permutation");
        assert!(
            mean_step(&order) * 4.0 < mean_step(&input),
            "{} against {}",
            mean_step(&order),
            mean_step(&input)
        );
    }

    /// Points that are not finite do not spoil the box of the others.
    #[test]
    fn points_that_are_not_finite_get_key_zero() {
        let p = [
            Vec3::new(f64::NAN, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
        ];
        let k = morton_keys(&p);
        assert_eq!(k[0], 0);
        assert_eq!(k[1], 0);
        assert_eq!(k[2], (1 << 63) - 1);
    }

    /// A 12 × 12 ground grid under a tilted square roof: most vertices have a roof edge
    /// somewhere in their hemisphere, so edge rays, cones and hints all take part.
    fn roofed_grid() -> crate::import::mesh::Mesh {
        let n = 12;
        let mut pts = Vec::new();
        let mut faces = Vec::new();
        for j in 0..n {
            for i in 0..n {
                pts.push(Vec3::new(i as f64 / 11.0 - 0.5, j as f64 / 11.0 - 0.5, 0.0));
            }
        }
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                faces.push([a, a + 1, a + n as u32 + 1]);
                faces.push([a, a + n as u32 + 1, a + n as u32]);
            }
        }
        let r = pts.len() as u32;
        for (x, y, z) in [
            (-0.3, -0.3, 0.3),
            (0.4, -0.3, 0.5),
            (0.4, 0.4, 0.5),
            (-0.3, 0.4, 0.3),
        ] {
            pts.push(Vec3::new(x, y, z));
        }
        faces.push([r, r + 2, r + 1]);
        faces.push([r, r + 3, r + 2]);
        crate::import::mesh::Mesh::from_parts(pts, faces).0
    }

    /// The maps, ray counts and open flags are bit for bit the same whether the vertices
    /// are traced in index order, in the spatial order or in reverse.
    #[test]
    fn the_tracing_order_changes_no_value() {
        let mesh = roofed_grid();
        let bvh = SceneBvh::new(&mesh);
        let m = Matrix3::identity();
        let nv = mesh.positions.len() as u32;
        let sampling = Sampling::Adaptive {
            edge_rays: 3,
            lattice: 2,
        };
        let tracing = Tracing {
            env_from_world: &m,
            n_local: 16,
            sampling,
            seed: 5,
            skip_open: true,
        };
        let run = |order: &[u32]| compute_in_order(&mesh, &bvh, &tracing, order);
        let index: Vec<u32> = (0..nv).collect();
        let reverse: Vec<u32> = (0..nv).rev().collect();
        let a = run(&index);
        assert!(a.rays_traced > 0 && a.frac.iter().any(|&f| f < 255));
        for order in [spatial_order(&mesh.positions), reverse] {
            let b = run(&order);
            assert_eq!(a.frac, b.frac);
            assert_eq!(a.open, b.open);
            assert_eq!(
                (a.rays_traced, a.rays_known_open),
                (b.rays_traced, b.rays_known_open)
            );
        }
    }
}
