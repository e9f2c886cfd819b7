//! Procedural meshes for the synthetic scenes: icospheres, ground planes, a merge of parts
//! into one triangle list, and a procedural blend pattern for textured materials.
//!
//! The icosphere is the regular icosahedron with every edge split at its midpoint `s`
//! times and the new vertices pushed to the unit sphere: `10·4^s + 2` vertices,
//! `20·4^s` faces, counter-clockwise seen from outside.

use crate::Vec3;
use std::collections::HashMap;

/// Unit icosphere after `subdivisions` midpoint splits.
pub fn icosphere(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5.0_f64.sqrt()) / 2.0;
    let mut pos: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        let mut midpoint = |a: u32, b: u32, pos: &mut Vec<Vec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                pos.push(((pos[a as usize] + pos[b as usize]) * 0.5).normalize());
                (pos.len() - 1) as u32
            })
        };
        for f in &faces {
            let ab = midpoint(f[0], f[1], &mut pos);
            let bc = midpoint(f[1], f[2], &mut pos);
            let ca = midpoint(f[2], f[0], &mut pos);
            next.push([f[0], ab, ca]);
            next.push([f[1], bc, ab]);
            next.push([f[2], ca, bc]);
            next.push([ab, bc, ca]);
        }
        faces = next;
    }
    (pos, faces)
}

/// A square grid in the plane through `center` with unit normal `normal`, side length
/// `size`, `cells × cells` quads split into two triangles each, counter-clockwise seen
/// from the side `normal` points to.
pub fn plane(center: &Vec3, normal: &Vec3, size: f64, cells: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let n = normal.normalize();
    let seed = if n.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let a = (seed - n * n.dot(&seed)).normalize();
    let b = n.cross(&a);
    let m = cells.max(1);
    let mut pos = Vec::with_capacity(((m + 1) * (m + 1)) as usize);
    for j in 0..=m {
        for i in 0..=m {
            let s = (i as f64 / m as f64 - 0.5) * size;
            let t = (j as f64 / m as f64 - 0.5) * size;
            pos.push(center + a * s + b * t);
        }
    }
    let mut faces = Vec::with_capacity((2 * m * m) as usize);
    for j in 0..m {
        for i in 0..m {
            let v00 = j * (m + 1) + i;
            let v10 = v00 + 1;
            let v01 = v00 + m + 1;
            let v11 = v01 + 1;
            // a × b = n, so (v00, v10, v11) is counter-clockwise about n.
            faces.push([v00, v10, v11]);
            faces.push([v00, v11, v01]);
        }
    }
    (pos, faces)
}

/// Appends part `(positions, faces)` to `(all_pos, all_faces)`, re-indexing its faces.
pub fn append(
    all_pos: &mut Vec<Vec3>,
    all_faces: &mut Vec<[u32; 3]>,
    pos: &[Vec3],
    faces: &[[u32; 3]],
) {
    let base = all_pos.len() as u32;
    all_pos.extend_from_slice(pos);
    all_faces.extend(
        faces
            .iter()
            .map(|f| [f[0] + base, f[1] + base, f[2] + base]),
    );
}

/// One step of flat midpoint subdivision (each triangle into four, shared edge midpoints;
/// the surface does not change).
pub fn subdivide(positions: &[Vec3], faces: &[[u32; 3]]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut pos = positions.to_vec();
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    let mut out = Vec::with_capacity(faces.len() * 4);
    let mut midpoint = |a: u32, b: u32, pos: &mut Vec<Vec3>| -> u32 {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            pos.push((pos[a as usize] + pos[b as usize]) * 0.5);
            (pos.len() - 1) as u32
        })
    };
    for f in faces {
        let ab = midpoint(f[0], f[1], &mut pos);
        let bc = midpoint(f[1], f[2], &mut pos);
        let ca = midpoint(f[2], f[0], &mut pos);
        out.push([f[0], ab, ca]);
        out.push([f[1], bc, ab]);
        out.push([f[2], ca, bc]);
        out.push([ab, bc, ca]);
    }
    (pos, out)
}

/// Flat midpoint refinement to exactly `target` vertices (or the input, if it already has
/// as many): whole [`subdivide`] steps while a step stays within `target`, then a partial
/// step that splits `target − V` edges at their midpoints, and re-triangulates every face
/// conformingly by how many of its edges were split (red–green refinement: 3 → four
/// children, 2 → three, 1 → two; no T-junctions). Edges are taken face by face in a fixed
/// pseudo-random face order, so the extra density is spread over the whole mesh. The
/// surface, its orientation and every edge's two-face adjacency are unchanged; every new
/// vertex adds one vertex, so the count is exact.
pub fn refine_to(
    positions: &[Vec3],
    faces: &[[u32; 3]],
    target: usize,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut pos, mut tri) = (positions.to_vec(), faces.to_vec());
    loop {
        if pos.len() >= target || tri.is_empty() {
            return (pos, tri);
        }
        let edges: std::collections::HashSet<(u32, u32)> = tri
            .iter()
            .flat_map(|f| (0..3).map(move |i| edge_key(f[i], f[(i + 1) % 3])))
            .collect();
        if pos.len() + edges.len() <= target {
            (pos, tri) = subdivide(&pos, &tri);
            continue;
        }
        let need = target - pos.len();
        // A fixed face order (a seeded shuffle), so the result is deterministic.
        let mut order: Vec<usize> = (0..tri.len()).collect();
        {
            use rand::seq::SliceRandom;
            use rand::SeedableRng;
            order.shuffle(&mut rand_pcg::Pcg32::seed_from_u64(0x5eed));
        }
        let mut mid: HashMap<(u32, u32), u32> = HashMap::with_capacity(need);
        'mark: for &fi in &order {
            let f = tri[fi];
            for i in 0..3 {
                if mid.len() == need {
                    break 'mark;
                }
                let key = edge_key(f[i], f[(i + 1) % 3]);
                if let std::collections::hash_map::Entry::Vacant(e) = mid.entry(key) {
                    pos.push((pos[key.0 as usize] + pos[key.1 as usize]) * 0.5);
                    e.insert((pos.len() - 1) as u32);
                }
            }
        }
        let mut out = Vec::with_capacity(tri.len() + 3 * need);
        for f in &tri {
            let m = [0, 1, 2].map(|i| mid.get(&edge_key(f[i], f[(i + 1) % 3])).copied());
            match m.iter().filter(|x| x.is_some()).count() {
                0 => out.push(*f),
                3 => {
                    let [ab, bc, ca] = m.map(|x| x.unwrap_or(0));
                    out.push([f[0], ab, ca]);
                    out.push([f[1], bc, ab]);
                    out.push([f[2], ca, bc]);
                    out.push([ab, bc, ca]);
                }
                1 => {
                    // Split edge (a, b) at m; c opposite: (a, m, c), (m, b, c).
                    let i = (0..3).find(|&i| m[i].is_some()).unwrap_or(0);
                    let (a, b, c) = (f[i], f[(i + 1) % 3], f[(i + 2) % 3]);
                    let mm = m[i].unwrap_or(0);
                    out.push([a, mm, c]);
                    out.push([mm, b, c]);
                }
                _ => {
                    // Edges (a, b) at m1 and (b, c) at m2 split, (c, a) not:
                    // the corner (m1, b, m2) and the quad (a, m1, m2, c) as two triangles.
                    let i = (0..3)
                        .find(|&i| m[i].is_some() && m[(i + 1) % 3].is_some())
                        .unwrap_or(0);
                    let (a, b, c) = (f[i], f[(i + 1) % 3], f[(i + 2) % 3]);
                    let (m1, m2) = (m[i].unwrap_or(0), m[(i + 1) % 3].unwrap_or(0));
                    out.push([m1, b, m2]);
                    out.push([a, m1, m2]);
                    out.push([a, m2, c]);
                }
            }
        }
        return (pos, out);
    }
}

fn edge_key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Hash of a lattice point to `[-1, 1]` (integer mixing, fixed: the pattern never changes).
fn lattice(i: i64, j: i64, k: i64) -> f64 {
    let mut h = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
        ^ (k as u64).wrapping_mul(0x1656_67b1_9e37_79f9);
    h ^= h >> 31;
    h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^= h >> 29;
    h = h.wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^= h >> 32;
    (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// Value noise in `[-1, 1]`: lattice values at integer points, blended with the smooth
/// fade `t²(3 − 2t)` per axis (continuous, about one feature per unit).
pub fn value_noise(p: &Vec3) -> f64 {
    let f = p.map(f64::floor);
    let t = (p - f).map(|t| t * t * (3.0 - 2.0 * t));
    let (i, j, k) = (f.x as i64, f.y as i64, f.z as i64);
    let mut acc = 0.0;
    for (di, wx) in [(0, 1.0 - t.x), (1, t.x)] {
        for (dj, wy) in [(0, 1.0 - t.y), (1, t.y)] {
            for (dk, wz) in [(0, 1.0 - t.z), (1, t.z)] {
                acc += wx * wy * wz * lattice(i + di, j + dj, k + dk);
            }
        }
    }
    acc
}

/// A blend weight in `[0, 1]` with blobs of half a unit to a unit across: three octaves of
/// [`value_noise`] (`n = v(p) + v(2p + a)/2 + v(4p + b)/4`) through a steep smoothstep of
/// `(n − 0.05)/0.16 + 1/2`, so most of the surface is 0 or 1 (about 45% at 1) and the
/// transitions are narrow (a high-contrast texture for feature matching that per-vertex
/// weights represent exactly).
pub fn pattern(p: &Vec3) -> f64 {
    let n = value_noise(p)
        + 0.5 * value_noise(&(p * 2.0 + Vec3::new(17.3, 5.1, 9.7)))
        + 0.25 * value_noise(&(p * 4.0 + Vec3::new(-3.7, 11.9, 2.3)));
    let x = ((n - 0.05) / 0.16 + 0.5).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_counts_and_orientation() {
        // 10·4^s + 2 vertices, 20·4^s faces; every face normal points outward
        // (positive dot with its centroid), every vertex on the unit sphere (1e-12).
        for s in 0..4 {
            let (p, f) = icosphere(s);
            assert_eq!(p.len(), 10 * 4usize.pow(s) + 2);
            assert_eq!(f.len(), 20 * 4usize.pow(s));
            for v in &p {
                assert!((v.norm() - 1.0).abs() < 1e-12);
            }
            for t in &f {
                let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
                assert!((b - a).cross(&(c - a)).dot(&(a + b + c)) > 0.0);
            }
        }
    }

    #[test]
    fn pattern_is_a_bounded_mostly_binary_texture() {
        // Weights in [0, 1]; on a 40³ grid over 10 units both materials cover a real share
        // of the volume (each > 20%) and most points are pure (|w − 0.5| > 0.45 on > 50%):
        // a texture, not a constant and not a smooth gradient.
        let (mut ones, mut zeros, mut pure, mut n) = (0, 0, 0, 0);
        for i in 0..40 {
            for j in 0..40 {
                for k in 0..40 {
                    let p = Vec3::new(i as f64, j as f64, k as f64) * 0.25 + Vec3::repeat(0.1);
                    let w = pattern(&p);
                    assert!((0.0..=1.0).contains(&w), "{w}");
                    ones += (w > 0.5) as usize;
                    zeros += (w < 0.5) as usize;
                    pure += ((w - 0.5).abs() > 0.45) as usize;
                    n += 1;
                }
            }
        }
        assert!(ones * 5 > n && zeros * 5 > n, "{ones} {zeros} of {n}");
        assert!(pure * 2 > n, "{pure} of {n}");
    }

    #[test]
    fn plane_faces_follow_normal() {
        let n = Vec3::new(0.0, 1.0, 0.0);
        let (p, f) = plane(&Vec3::zeros(), &n, 2.0, 3);
        assert_eq!(p.len(), 16);
        assert_eq!(f.len(), 18);
        for t in &f {
            let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
            let fnorm = (b - a).cross(&(c - a)).normalize();
            assert!((fnorm - n).norm() < 1e-12);
        }
    }

    #[test]
    fn refine_to_is_exact_conforming_and_keeps_the_surface() {
        // Independent checks on a closed icosphere (162 vertices, 480 edges): the count is
        // exactly the target; the surface is the same (total area and enclosed signed
        // volume to 1e-12 relative: midpoints lie on the flat faces); the mesh stays a
        // closed, consistently oriented 2-manifold (every directed edge appears once and
        // its reverse once: a T-junction or a flipped child would break that); no face is
        // degenerate; every vertex is used. 400: one partial step; 700: a full step
        // (642) then a partial one; 100: below the input, unchanged.
        let (p0, f0) = icosphere(2);
        let measure = |p: &[Vec3], f: &[[u32; 3]]| {
            f.iter().fold((0.0, 0.0), |(a, v), t| {
                let (x, y, z) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
                (
                    a + 0.5 * (y - x).cross(&(z - x)).norm(),
                    v + x.dot(&y.cross(&z)) / 6.0,
                )
            })
        };
        let (area0, vol0) = measure(&p0, &f0);
        for target in [400, 700, 100] {
            let (p, f) = refine_to(&p0, &f0, target);
            assert_eq!(p.len(), target.max(p0.len()), "target {target}");
            let (area, vol) = measure(&p, &f);
            assert!((area - area0).abs() < 1e-12 * area0, "{area} {area0}");
            assert!((vol - vol0).abs() < 1e-12 * vol0, "{vol} {vol0}");
            let mut directed = std::collections::HashSet::new();
            let mut used = vec![false; p.len()];
            for t in &f {
                let (x, y, z) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
                assert!((y - x).cross(&(z - x)).norm() > 1e-9, "degenerate {t:?}");
                for i in 0..3 {
                    used[t[i] as usize] = true;
                    assert!(directed.insert((t[i], t[(i + 1) % 3])), "edge twice {t:?}");
                }
            }
            for &(a, b) in &directed {
                assert!(directed.contains(&(b, a)), "open edge ({a}, {b})");
            }
            assert!(used.iter().all(|&u| u));
            // Euler characteristic of a sphere: V − E + F = 2.
            assert_eq!(p.len() + f.len(), directed.len() / 2 + 2);
        }
    }
}
