//! PLY reading: every encoding and property variant the issue lists, written byte by byte
//! here (not by this crate's writer), the writer checked with ply-rs' generic reader, and
//! bad files: each a clear error naming the file and the element, none a panic.

use std::io::Write;
use std::path::Path;

use relight_cpc::import::mesh::Mesh;
use relight_cpc::{Error, Vec3};

/// `name` in a scratch folder of its own, removed when the returned value is dropped.
fn scratch(name: &str) -> crate::scratch::ScratchFile {
    crate::scratch::scratch_file("mesh", name)
}

/// A square pyramid: 5 vertices, 4 triangles and one quad base (6 triangles after the fan).
const P: [[f64; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.5, 0.5, 0.75],
];
const FACES: [&[i32]; 5] = [
    &[0, 1, 4],
    &[1, 2, 4],
    &[2, 3, 4],
    &[3, 0, 4],
    &[0, 3, 2, 1],
];
const RGB: [[u8; 3]; 5] = [
    [255, 0, 0],
    [0, 255, 0],
    [0, 0, 255],
    [10, 20, 30],
    [128, 128, 128],
];

#[derive(Clone, Copy)]
enum Enc {
    Ascii,
    Le,
    Be,
}

struct Variant {
    enc: Enc,
    double: bool,
    index_name: &'static str,
    normals: bool,
    colors: bool,
}

fn write_variant(path: &Path, v: &Variant) {
    let mut h = String::from("ply\n");
    h += match v.enc {
        Enc::Ascii => "format ascii 1.0\n",
        Enc::Le => "format binary_little_endian 1.0\n",
        Enc::Be => "format binary_big_endian 1.0\n",
    };
    h += "comment test\nelement vertex 5\n";
    let ty = if v.double { "double" } else { "float" };
    for p in ["x", "y", "z"] {
        h += &format!("property {ty} {p}\n");
    }
    if v.normals {
        for p in ["nx", "ny", "nz"] {
            h += &format!("property float {p}\n");
        }
    }
    if v.colors {
        for p in ["red", "green", "blue"] {
            h += &format!("property uchar {p}\n");
        }
    }
    h += &format!(
        "element face 5\nproperty list uchar int {}\nend_header\n",
        v.index_name
    );
    let mut out = h.into_bytes();
    let num = |out: &mut Vec<u8>, x: f64, double: bool| match v.enc {
        Enc::Ascii => out.extend(format!("{x} ").as_bytes()),
        Enc::Le if double => out.extend(x.to_le_bytes()),
        Enc::Le => out.extend((x as f32).to_le_bytes()),
        Enc::Be if double => out.extend(x.to_be_bytes()),
        Enc::Be => out.extend((x as f32).to_be_bytes()),
    };
    for i in 0..5 {
        for c in P[i] {
            num(&mut out, c, v.double);
        }
        if v.normals {
            // Deliberately not the geometric normal: read normals must be kept.
            for c in [0.0, 0.0, 2.0] {
                num(&mut out, c, false);
            }
        }
        if v.colors {
            for c in RGB[i] {
                match v.enc {
                    Enc::Ascii => out.extend(format!("{c} ").as_bytes()),
                    _ => out.push(c),
                }
            }
        }
        if let Enc::Ascii = v.enc {
            out.push(b'\n');
        }
    }
    for f in FACES {
        match v.enc {
            Enc::Ascii => {
                out.extend(format!("{}", f.len()).as_bytes());
                for k in f {
                    out.extend(format!(" {k}").as_bytes());
                }
                out.push(b'\n');
            }
            Enc::Le => {
                out.push(f.len() as u8);
                for k in f.iter() {
                    out.extend(k.to_le_bytes());
                }
            }
            Enc::Be => {
                out.push(f.len() as u8);
                for k in f.iter() {
                    out.extend(k.to_be_bytes());
                }
            }
        }
    }
    std::fs::write(path, out).unwrap();
}

#[test]
fn every_encoding_and_property_variant_reads_the_same_mesh() {
    let mut k = 0;
    for enc in [Enc::Ascii, Enc::Le, Enc::Be] {
        for double in [false, true] {
            for index_name in ["vertex_indices", "vertex_index"] {
                for (normals, colors) in [(false, false), (true, true)] {
                    let v = Variant {
                        enc,
                        double,
                        index_name,
                        normals,
                        colors,
                    };
                    k += 1;
                    let path = scratch(&format!("variant{k}.ply"));
                    write_variant(&path, &v);
                    let (mesh, c) = Mesh::read_ply(&path).unwrap();
                    let what = format!("variant {k} ({index_name}, double {double})");
                    // Coordinates are multiples of 1/4: exact in f32 and ascii.
                    assert_eq!(mesh.positions.len(), 5, "{what}");
                    for (p, expect) in mesh.positions.iter().zip(P) {
                        assert_eq!(*p, Vec3::from(expect), "{what}");
                    }
                    // 4 triangles + the quad as a 2-triangle fan from its first corner.
                    assert_eq!(mesh.faces.len(), 6, "{what}");
                    assert_eq!(mesh.faces[4], [0, 3, 2]);
                    assert_eq!(mesh.faces[5], [0, 2, 1]);
                    assert_eq!(c.polygons_triangulated, 1);
                    assert_eq!(c.degenerate_faces + c.unreferenced_vertices, 0);
                    assert_eq!(c.normals_computed, !normals);
                    if normals {
                        assert!(mesh.normals.iter().all(|n| *n == Vec3::z()), "{what}");
                    } else {
                        // Apex: the four sides' cross products sum to (0, 0, 4·0.5) → +z.
                        assert!((mesh.normals[4] - Vec3::z()).norm() < 1e-12, "{what}");
                    }
                    match (&mesh.colors, colors) {
                        (Some(cs), true) => {
                            for i in 0..5 {
                                let expect = RGB[i].map(|c| c as f32 / 255.0);
                                assert_eq!(cs[i], expect, "{what}");
                            }
                        }
                        (None, false) => {}
                        (got, _) => panic!("{what}: colours {got:?}"),
                    }
                }
            }
        }
    }
}

#[test]
fn writer_output_reads_back_with_a_generic_ply_reader() {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let path = scratch("written.ply");
    let (mut mesh, _) = Mesh::from_parts(
        P.iter().map(|p| Vec3::from(*p)).collect(),
        vec![
            [0, 1, 4],
            [1, 2, 4],
            [2, 3, 4],
            [3, 0, 4],
            [0, 3, 2],
            [0, 2, 1],
        ],
    );
    mesh.colors = Some(RGB.iter().map(|c| c.map(|x| x as f32 / 255.0)).collect());
    let weights = [0.5f32, 0.25, 1.0, 0.0, -2.0];
    mesh.write_ply(&path, &[("w0", &weights)]).unwrap();
    let mut f = std::fs::File::open(&path).unwrap();
    let ply = Parser::<DefaultElement>::new().read_ply(&mut f).unwrap();
    let verts = &ply.payload["vertex"];
    assert_eq!(verts.len(), 5);
    for (i, v) in verts.iter().enumerate() {
        assert_eq!(v["x"], Property::Float(P[i][0] as f32));
        assert_eq!(v["z"], Property::Float(P[i][2] as f32));
        assert_eq!(v["red"], Property::UChar(RGB[i][0]));
        assert_eq!(v["w0"], Property::Float(weights[i]));
    }
    assert_eq!(ply.payload["face"].len(), 6);
    // And this crate reads it back to the same mesh (f32 positions: exact here).
    let (back, c) = Mesh::read_ply(&path).unwrap();
    assert_eq!(back.positions, mesh.positions);
    assert_eq!(back.faces, mesh.faces);
    assert!(!c.normals_computed);
    // A wrong-length extra property is refused.
    assert!(mesh.write_ply(&path, &[("w0", &weights[..2])]).is_err());
}

#[test]
fn a_mesh_from_another_tool_reads_with_its_documented_counts() {
    // Spot (Keenan Crane), converted by the synth fixture's script: 2,930 vertices, 5,856
    // faces per tests/fixtures/synth/SOURCE.md, closed (so nothing is dropped).
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/synth/spot.ply");
    let (mesh, c) = Mesh::read_ply(&path).unwrap();
    assert_eq!(mesh.positions.len(), 2930);
    assert_eq!(mesh.faces.len(), 5856);
    assert_eq!(c.degenerate_faces + c.unreferenced_vertices, 0);
    // Closed, consistently oriented surface: Σ_f (p1−p0)×(p2−p0) = 0 (1e-9 · area scale)
    // and the enclosed volume (divergence theorem) is positive when faces point outward.
    let mut s = Vec3::zeros();
    let mut vol = 0.0;
    for f in &mesh.faces {
        let [a, b, d] = f.map(|k| mesh.positions[k as usize]);
        s += (b - a).cross(&(d - a));
        vol += a.dot(&b.cross(&d)) / 6.0;
    }
    assert!(s.norm() < 1e-6, "{s:?}");
    assert!(vol > 0.0);
}

fn expect_format(err: Error, path: &Path, location: &str) -> String {
    match err {
        Error::Format {
            path: p,
            location: l,
            message,
        } => {
            assert_eq!(p, *path);
            assert!(
                l.contains(location),
                "location {l:?}, expected {location:?}"
            );
            message
        }
        other => panic!("expected a format error, got {other}"),
    }
}

#[test]
fn bad_files_give_clear_errors() {
    let ascii = |body: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
             end_header\n{body}"
        )
    };
    // Face index out of range: names the face and the index.
    let p = scratch("bad_index.ply");
    std::fs::write(&p, ascii("0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")).unwrap();
    let msg = expect_format(Mesh::read_ply(&p).unwrap_err(), &p, "face 0");
    assert!(msg.contains("found 7") && msg.contains("0 to 2"), "{msg}");
    // Negative index too.
    std::fs::write(&p, ascii("0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n")).unwrap();
    expect_format(Mesh::read_ply(&p).unwrap_err(), &p, "face 0");
    // NaN and infinite coordinates (binary, where they are representable): names the vertex.
    let p = scratch("nan.ply");
    for (bad, value) in [(1usize, f32::NAN), (2, f32::INFINITY)] {
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
property float x\nproperty float y\nproperty float z\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n"
            .to_vec();
        for i in 0..3 {
            for c in 0..3 {
                let x = if i == bad && c == 1 {
                    value
                } else {
                    (i + c) as f32
                };
                bytes.extend(x.to_le_bytes());
            }
        }
        bytes.push(3);
        for k in [0i32, 1, 2] {
            bytes.extend(k.to_le_bytes());
        }
        std::fs::write(&p, &bytes).unwrap();
        let msg = expect_format(
            Mesh::read_ply(&p).unwrap_err(),
            &p,
            &format!("vertex {bad}"),
        );
        assert!(
            msg.contains("finite") && msg.contains(if bad == 1 { "NaN" } else { "inf" }),
            "{msg}"
        );
    }
    // In ascii, ply-rs' grammar refuses `nan` outright: still a format error with the line
    // (header 9 lines, then vertex 0 on line 10, vertex 1 on line 11).
    std::fs::write(&p, ascii("0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n")).unwrap();
    let msg = expect_format(
        Mesh::read_ply(&p).unwrap_err(),
        &p,
        "line 11 (`vertex` record 1)",
    );
    assert!(msg.contains("x y z") && msg.contains("1 nan 0"), "{msg}");
    // Truncated binary payload.
    let p = scratch("truncated.ply");
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    bytes.extend([0u8; 20]); // 36 bytes of vertices needed
    std::fs::write(&p, &bytes).unwrap();
    let msg = expect_format(Mesh::read_ply(&p).unwrap_err(), &p, "`vertex` element");
    assert!(
        msg.contains("expected 3") && msg.contains("found 1"),
        "{msg}"
    );
    // Unparseable text and a non-PLY file.
    let p = scratch("garbage.ply");
    std::fs::write(&p, ascii("0 0 zero\n1 0 0\n0 1 0\n3 0 1 2\n")).unwrap();
    expect_format(Mesh::read_ply(&p).unwrap_err(), &p, "`vertex` record 0");
    std::fs::File::create(&p)
        .unwrap()
        .write_all(b"\x89PNG\r\n\x1a\n not a ply")
        .unwrap();
    expect_format(Mesh::read_ply(&p).unwrap_err(), &p, "line 1");
    // A point cloud is not a mesh; a missing file is an I/O error naming it.
    let p = scratch("cloud.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         property float z\nend_header\n0 0 0\n",
    )
    .unwrap();
    let msg = expect_format(Mesh::read_ply(&p).unwrap_err(), &p, "header");
    assert!(msg.contains("face"), "{msg}");
    let missing = scratch("missing.ply");
    match Mesh::read_ply(&missing).unwrap_err() {
        Error::Io { path, .. } => assert_eq!(path, *missing),
        other => panic!("{other}"),
    }
}

#[test]
fn degenerate_faces_in_a_file_are_dropped_and_counted() {
    let p = scratch("degenerate.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 6\nproperty double x\nproperty double y\n\
         property double z\nelement face 4\nproperty list uchar uint vertex_index\nend_header\n\
         0 0 0\n1 0 0\n0 1 0\n2 0 0\n9 9 9\n0.5 0 0\n3 0 1 2\n3 0 0 2\n3 0 5 1\n2 0 1\n",
    )
    .unwrap();
    let (mesh, c) = Mesh::read_ply(&p).unwrap();
    // Kept: [0 1 2]. Dropped: repeated index, collinear (zero area), 2-corner face.
    assert_eq!(mesh.faces, vec![[0, 1, 2]]);
    assert_eq!(c.degenerate_faces, 3);
    // Vertices 3, 4, 5 are unreferenced once those faces are gone.
    assert_eq!(c.unreferenced_vertices, 3);
    assert_eq!(mesh.positions.len(), 3);
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    fn valid_binary() -> Vec<u8> {
        let p = scratch("fuzz_src.ply");
        write_variant(
            &p,
            &Variant {
                enc: Enc::Le,
                double: false,
                index_name: "vertex_indices",
                normals: true,
                colors: true,
            },
        );
        std::fs::read(p).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        /// Corrupted or truncated files give Ok or an error, never a panic.
        #[test]
        fn corrupted_files_never_panic(
            cut in 0usize..400,
            flips in proptest::collection::vec((0usize..400, any::<u8>()), 0..6),
            case in 0u32..1_000_000,
        ) {
            let mut bytes = valid_binary();
            for (at, b) in flips {
                let n = bytes.len();
                bytes[at % n] = b;
            }
            bytes.truncate(cut.min(bytes.len()));
            let p = scratch(&format!("fuzz_{case}.ply"));
            std::fs::write(&p, &bytes).unwrap();
            if let Ok((mesh, _)) = Mesh::read_ply(&p) {
                // Whatever reads must be a consistent mesh.
                prop_assert!(mesh.faces.iter().flatten().all(|&k| (k as usize) < mesh.positions.len()));
                prop_assert_eq!(mesh.normals.len(), mesh.positions.len());
            }
            let _ = std::fs::remove_file(&p);
        }

        /// write_ply then read_ply returns the mesh (positions rounded to f32).
        #[test]
        fn write_read_round_trip(
            pts in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3, -1e3f64..1e3), 3..40),
            tris in proptest::collection::vec((0u32..40, 0u32..40, 0u32..40), 1..60),
            case in 0u32..1_000_000,
        ) {
            let positions: Vec<Vec3> = pts.iter().map(|&(x, y, z)| Vec3::new(x, y, z)).collect();
            let n = positions.len() as u32;
            let faces = tris.iter().map(|&(a, b, c)| [a % n, b % n, c % n]).collect();
            let (mesh, _) = Mesh::from_parts(positions, faces);
            let p = scratch(&format!("rt_{case}.ply"));
            mesh.write_ply(&p, &[]).unwrap();
            let (back, c) = Mesh::read_ply(&p).unwrap();
            let _ = std::fs::remove_file(&p);
            prop_assert_eq!(&back.faces.len(), &mesh.faces.len());
            prop_assert_eq!(c.unreferenced_vertices, 0);
            for (a, b) in back.positions.iter().zip(&mesh.positions) {
                // f32 storage: relative 2^-24 of |coordinate| ≤ 1e3.
                prop_assert!((a - b).amax() <= 1e3 * 6e-8);
            }
        }
    }
}
