//! The regular octahedron: convex, so every vertex's neighbours lie 45° below its tangent
//! plane and every vertex is open (nothing of the mesh shadows it).

#![allow(dead_code)]

use relight_cpc::import::mesh::Mesh;
use relight_cpc::Vec3;

/// The octahedron with vertices `centre ± radius·e_i` (order +x, −x, +y, −y, +z, −z),
/// faces wound outward.
pub fn octahedron(centre: Vec3, radius: f64) -> Mesh {
    let pts = [
        Vec3::x(),
        -Vec3::x(),
        Vec3::y(),
        -Vec3::y(),
        Vec3::z(),
        -Vec3::z(),
    ]
    .iter()
    .map(|d| centre + radius * d)
    .collect();
    let faces = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    Mesh::from_parts(pts, faces).0
}
