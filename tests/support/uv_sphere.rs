//! Shared by the tests and the import bench that need a closed sphere-like mesh: a UV
//! sphere's vertices and outward-facing triangles.

#![allow(dead_code)]

use relight_cpc::Vec3;

/// A UV sphere with `rings` latitude bands and `segments` longitudes: one vertex per pole
/// and `segments` per inner ring, at `point(θ, φ)` (polar angle from +z, azimuth), and
/// triangles wound counter-clockwise seen from outside when `point` is star-shaped about
/// the origin. `rings ≥ 2`, `segments ≥ 3`.
pub fn uv_sphere(
    rings: usize,
    segments: usize,
    point: impl Fn(f64, f64) -> Vec3,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let pi = std::f64::consts::PI;
    let mut pos = vec![point(0.0, 0.0)];
    for i in 1..rings {
        let th = pi * i as f64 / rings as f64;
        for j in 0..segments {
            pos.push(point(th, 2.0 * pi * j as f64 / segments as f64));
        }
    }
    pos.push(point(pi, 0.0));
    let last = (pos.len() - 1) as u32;
    let ring = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as u32;
    let mut faces = Vec::new();
    for j in 0..segments {
        faces.push([0, ring(1, j), ring(1, j + 1)]);
        faces.push([last, ring(rings - 1, j + 1), ring(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            faces.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
            faces.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
        }
    }
    (pos, faces)
}

/// The unit direction at polar angle `θ` from +z and azimuth `φ`.
pub fn direction(th: f64, ph: f64) -> Vec3 {
    Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())
}
