//! PLY meshes: truncated, wrong counts, bad indices, strips and polygons, NaN, not a PLY.

use super::*;
use relight_cpc::import::mesh::Mesh;

#[test]
fn ply_truncated_binary_mesh() {
    // The example's real mesh (binary), cut in the middle of its face list.
    let bytes = std::fs::read(repo("examples/spot/dense/meshed-poisson.ply")).unwrap();
    let (_d, p) = file("ply-trunc-bin", "mesh.ply", &bytes[..bytes.len() * 3 / 4]);
    expect(
        Mesh::read_ply(&p),
        &p,
        &["`face` element", "ends early", "expected"],
    );
}

#[test]
fn ply_truncated_ascii_mesh() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n");
    let (_d, p) = file("ply-trunc-ascii", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["`vertex` element", "expected 3", "found 2"],
    );
}

#[test]
fn ply_more_vertices_announced_than_written() {
    // Header says 5 vertices; the face line is read as vertex 3, then the file ends.
    let text = ASCII_HEAD.replace("vertex 3", "vertex 5") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let (_d, p) = file("ply-count-more", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["expected 5", "found 4"]);
}

#[test]
fn ply_fewer_vertices_announced_than_used() {
    // Header says 2 vertices: the face `3 0 1 2` then uses index 2 of 2 vertices.
    let text = ASCII_HEAD.replace("vertex 3", "vertex 2") + "0 0 0\n1 0 0\n3 0 1 2\n";
    let (_d, p) = file("ply-count-fewer", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["face 0", "expected vertex indices 0 to 1"],
    );
}

#[test]
fn ply_face_index_out_of_range() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n");
    let (_d, p) = file("ply-index", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["face 0", "0 to 2", "found 9"]);
}

#[test]
fn ply_negative_face_index() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 -4 1\n");
    let (_d, p) = file("ply-negative", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["face 0", "found -4"]);
}

#[test]
fn ply_triangle_strips_are_refused_in_words() {
    let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n";
    let (_d, p) = file("ply-strips", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["header", "triangle strips", "`face`"],
    );
}

#[test]
fn ply_polygons_are_accepted_as_triangle_fans() {
    // A quad and a pentagon: fans of 2 and 3 triangles (5 in all), nothing refused.
    let text = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n\
property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0.5 0\n1.5 -1 0\n4 0 1 2 3\n5 1 5 4 2 0\n";
    let (_d, p) = file("ply-polygons", "mesh.ply", text.as_bytes());
    let (mesh, cleanup) = Mesh::read_ply(&p).unwrap();
    assert_eq!(cleanup.polygons_triangulated, 2);
    assert_eq!(mesh.faces.len() + cleanup.degenerate_faces, 5);
}

#[test]
fn ply_nan_coordinate_binary() {
    let mut bytes = ASCII_HEAD
        .replace("ascii", "binary_little_endian")
        .into_bytes();
    for v in [[0.0f32, 0.0, 0.0], [1.0, f32::NAN, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            bytes.extend(c.to_le_bytes());
        }
    }
    bytes.push(3);
    for k in [0i32, 1, 2] {
        bytes.extend(k.to_le_bytes());
    }
    let (_d, p) = file("ply-nan-bin", "mesh.ply", &bytes);
    expect(Mesh::read_ply(&p), &p, &["vertex 1", "finite", "NaN"]);
}

#[test]
fn ply_nan_coordinate_ascii() {
    let text = format!("{ASCII_HEAD}0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
    let (_d, p) = file("ply-nan-ascii", "mesh.ply", text.as_bytes());
    expect(
        Mesh::read_ply(&p),
        &p,
        &["line 11", "`vertex` record 1", "nan 0 0"],
    );
}

#[test]
fn ply_word_where_a_number_belongs() {
    let text = format!("{ASCII_HEAD}0 0 0\n1 0 0\n0 one 0\n3 0 1 2\n");
    let (_d, p) = file("ply-word", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["line 12", "x y z", "0 one 0"]);
}

#[test]
fn ply_that_is_a_png() {
    let (_d, p) = file("ply-png", "mesh.ply", b"\x89PNG\r\n\x1a\n....");
    expect(Mesh::read_ply(&p), &p, &["line 1", "not a PLY file"]);
}

#[test]
fn ply_empty_file() {
    let (_d, p) = file("ply-empty", "mesh.ply", b"");
    expect(Mesh::read_ply(&p), &p, &["not a PLY file"]);
}

#[test]
fn ply_unknown_format_line() {
    let text = ASCII_HEAD.replace("format ascii 1.0", "format utf16 1.0");
    let (_d, p) = file("ply-format", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["line 2", "format utf16 1.0"]);
}

#[test]
fn ply_header_without_end() {
    let (_d, p) = file(
        "ply-noend",
        "mesh.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\n",
    );
    expect(Mesh::read_ply(&p), &p, &["header", "end_header"]);
}

#[test]
fn ply_without_z() {
    let text = ASCII_HEAD.replace("property float z\n", "");
    let (_d, p) = file("ply-noz", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["header", "x, y, z"]);
}

#[test]
fn ply_huge_vertex_count_in_a_small_file() {
    // 4 294 967 295 vertices announced, 3 given: an error, not an allocation abort.
    let text =
        ASCII_HEAD.replace("vertex 3", "vertex 4294967295") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let (_d, p) = file("ply-huge", "mesh.ply", text.as_bytes());
    expect(Mesh::read_ply(&p), &p, &["expected 4294967295", "found 4"]);
}
