//! Procedural meshes for the synthetic scenes: icospheres, ground planes, smooth vertex
//! normals, and a merge of parts into one triangle list.
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
}
