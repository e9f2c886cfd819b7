use super::*;

/// Unit cube, 8 vertices, 12 outward-facing triangles.
fn cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let p: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect();
    let f = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (p, f)
}

#[test]
fn cube_normals_are_unit_and_point_outward() {
    // Each corner's normal is a positive mix of its three outward face normals (the
    // weights depend on the triangulation), so every component has the sign of the
    // corner's offset from the centre.
    let (p, f) = cube();
    let (mesh, cleanup) = Mesh::from_parts(p, f);
    assert_eq!(cleanup.degenerate_faces, 0);
    assert_eq!(cleanup.unreferenced_vertices, 0);
    assert!(cleanup.normals_computed);
    let centre = Vec3::new(0.5, 0.5, 0.5);
    for (x, n) in mesh.positions.iter().zip(&mesh.normals) {
        assert!((n.norm() - 1.0).abs() < 1e-12);
        let out = x - centre;
        for k in 0..3 {
            assert!(n[k] * out[k] > 0.0, "normal {n:?} at {x:?}");
        }
    }
}

#[test]
fn area_weighted_normal_of_a_flat_fan_is_the_plane_normal() {
    // Any fan of triangles in the plane z = 0 (ccw seen from +z) has normal +z exactly.
    let p = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.3, 2.0, 0.0),
        Vec3::new(-1.0, 0.5, 0.0),
    ];
    let f = vec![[0, 1, 2], [0, 2, 3]];
    let n = area_weighted_normals(&p, &f);
    for v in n {
        assert!((v - Vec3::z()).norm() < 1e-12);
    }
}

#[test]
fn area_weighting_matches_hand_computation() {
    // Two triangles meet at vertex 0. Face 0: (2,0,0)×(0,2,0) = (0,0,4) (area 2, +z);
    // face 1: (0,1,0)×(0,0,1) = (1,0,0) (area 0.5, +x). Area-weighted: (1,0,4)/√17,
    // unlike the unweighted mean (1,0,1)/√2.
    let p = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    ];
    let f = vec![[0, 1, 2], [0, 3, 4]];
    let n = area_weighted_normals(&p, &f);
    let expect = Vec3::new(1.0, 0.0, 4.0).normalize();
    assert!((n[0] - expect).norm() < 1e-12, "{:?}", n[0]);
}

#[test]
fn cleaning_drops_degenerate_faces_and_orphans() {
    let (mut p, mut f) = cube();
    p.push(Vec3::new(5.0, 5.0, 5.0)); // 8: unreferenced
    p.push(Vec3::new(0.5, 0.0, 0.0)); // 9: collinear with 0 and 1
    p.push(Vec3::new(f64::NAN, 0.0, 0.0)); // 10: NaN, only in a dropped face
    f.push([0, 0, 1]); // repeated index
    f.push([0, 9, 1]); // zero area
    f.push([0, 10, 1]); // non-finite corner
    f.push([0, 1, 99]); // out of range
    let (mesh, c) = Mesh::from_parts(p, f);
    assert_eq!(c.degenerate_faces, 3);
    assert_eq!(c.invalid_faces, 1);
    assert_eq!(c.unreferenced_vertices, 3);
    assert_eq!(mesh.positions.len(), 8);
    assert_eq!(mesh.faces.len(), 12);
    assert!(mesh.faces.iter().flatten().all(|&k| k < 8));
}

#[test]
fn one_ring_of_a_cube_corner() {
    let (p, f) = cube();
    let (mesh, _) = Mesh::from_parts(p, f);
    let ring = mesh.vertex_neighbors();
    // Vertex 0's triangles: [0,2,1], [0,1,4], [0,4,2] → neighbours {1, 2, 4}.
    assert_eq!(ring[0], vec![1, 2, 4]);
    // Areas: 12 triangles of area 1/2 → total 6, each vertex a share.
    let total: f64 = mesh.vertex_areas().iter().sum();
    assert!((total - 6.0).abs() < 1e-12);
    assert!((mesh.diagonal() - 3f64.sqrt()).abs() < 1e-12);
}
