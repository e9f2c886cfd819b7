//! Property tests of the parsers (issue 8): arbitrary bytes, grammar-aware random lines and
//! multi-point mutations (overwrites, insertions, deletions, splices) of valid files go into
//! the COLMAP text and binary readers and the PLY reader. Each must return a value or an
//! error whose message names the file — never panic, hang or allocate from a count.
//!
//! tests/suite/colmap_errors.rs already covers every prefix and every single-byte change of a
//! small COLMAP model, and tests/suite/mesh_ply.rs the byte flips of a binary PLY; this file adds
//! random inputs, several edits at once, structural (insert/delete) edits, text grammars,
//! ASCII PLY bodies and PLY headers. Case counts are chosen so the file runs in a few
//! seconds in the debug profile; `scripts/fuzz.sh` runs the longer, unbounded search.

use std::path::{Path, PathBuf};

use crate::colmap_model::model;
use proptest::prelude::*;
use relight_cpc::import::colmap::{binary, text};
use relight_cpc::import::mesh::Mesh;
use relight_cpc::Error;

/// The three files of `model()` in one format, as bytes.
fn files(bin: bool) -> [Vec<u8>; 3] {
    let rec = model();
    let (mut c, mut i, mut p) = (Vec::new(), Vec::new(), Vec::new());
    if bin {
        binary::write_cameras(&mut c, &rec.cameras).expect("write");
        binary::write_images(&mut i, &rec.images).expect("write");
        binary::write_points3d(&mut p, &rec.points3d).expect("write");
    } else {
        text::write_cameras(&mut c, &rec.cameras).expect("write");
        text::write_images(&mut i, &rec.images).expect("write");
        text::write_points3d(&mut p, &rec.points3d).expect("write");
    }
    [c, i, p]
}

const NAMES_TXT: [&str; 3] = ["cameras.txt", "images.txt", "points3D.txt"];
const NAMES_BIN: [&str; 3] = ["cameras.bin", "images.bin", "points3D.bin"];

/// Reads `bytes` as file `which` (0 cameras, 1 images, 2 points) of one format; on error,
/// checks that the message names the file. Returns whether it parsed.
fn parse(bin: bool, which: usize, bytes: &[u8]) -> Result<bool, TestCaseError> {
    let name = if bin {
        NAMES_BIN[which]
    } else {
        NAMES_TXT[which]
    };
    let path = PathBuf::from("/fuzz/model").join(name);
    let r = match (bin, which) {
        (true, 0) => binary::read_cameras(bytes, &path).map(|_| ()),
        (true, 1) => binary::read_images(bytes, &path).map(|_| ()),
        (true, _) => binary::read_points3d(bytes, &path).map(|_| ()),
        (false, 0) => text::read_cameras(bytes, &path).map(|_| ()),
        (false, 1) => text::read_images(bytes, &path).map(|_| ()),
        (false, _) => text::read_points3d(bytes, &path).map(|_| ()),
    };
    match r {
        Ok(()) => Ok(true),
        Err(e) => {
            names_file(&e, &path)?;
            Ok(false)
        }
    }
}

fn names_file(e: &Error, path: &Path) -> Result<(), TestCaseError> {
    let msg = e.to_string();
    prop_assert!(
        msg.contains(&*path.to_string_lossy()),
        "error does not name {}: {msg}",
        path.display()
    );
    prop_assert!(
        matches!(e, Error::Format { .. } | Error::Io { .. }),
        "unexpected error kind: {e:?}"
    );
    Ok(())
}

/// One edit of a byte string.
#[derive(Debug, Clone)]
enum Edit {
    Set(usize, u8),
    Insert(usize, Vec<u8>),
    Delete(usize, usize),
    /// Copy `len` bytes from `from` over position `to` (duplicates records and counts).
    Splice {
        from: usize,
        to: usize,
        len: usize,
    },
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::Set(i, b)),
        (
            any::<usize>(),
            prop_oneof![
                proptest::collection::vec(any::<u8>(), 1..9),
                // Bytes that look like large little-endian counts.
                Just(vec![0xff; 8]),
                Just(vec![0xff, 0xff, 0xff, 0x7f]),
                Just(b" 1e308 ".to_vec()),
                Just(b" -1 ".to_vec()),
                Just(b" nan ".to_vec()),
                Just(b"\n".to_vec()),
            ]
        )
            .prop_map(|(i, b)| Edit::Insert(i, b)),
        (any::<usize>(), 1usize..16).prop_map(|(i, n)| Edit::Delete(i, n)),
        (any::<usize>(), any::<usize>(), 1usize..24).prop_map(|(f, t, l)| Edit::Splice {
            from: f,
            to: t,
            len: l
        }),
    ]
}

fn apply(bytes: &mut Vec<u8>, edits: &[Edit]) {
    for e in edits {
        let n = bytes.len();
        match e {
            Edit::Set(i, b) if n > 0 => bytes[i % n] = *b,
            Edit::Insert(i, b) => {
                let at = i % (n + 1);
                bytes.splice(at..at, b.iter().copied());
            }
            Edit::Delete(i, k) if n > 0 => {
                let at = i % n;
                bytes.drain(at..(at + k).min(n));
            }
            Edit::Splice { from, to, len } if n > 0 => {
                let f = from % n;
                let l = (*len).min(n - f);
                let chunk = bytes[f..f + l].to_vec();
                let t = to % n;
                for (k, b) in chunk.into_iter().enumerate() {
                    if t + k < n {
                        bytes[t + k] = b;
                    }
                }
            }
            _ => {}
        }
    }
}

/// Tokens a COLMAP text line is made of, including edge cases.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        (0u64..12).prop_map(|v| v.to_string()),
        any::<i64>().prop_map(|v| v.to_string()),
        any::<u64>().prop_map(|v| v.to_string()),
        any::<f64>().prop_map(|v| v.to_string()),
        (-10.0f64..10.0).prop_map(|v| format!("{v}")),
        prop_oneof![
            Just("SIMPLE_PINHOLE"),
            Just("PINHOLE"),
            Just("SIMPLE_RADIAL"),
            Just("RADIAL"),
            Just("OPENCV"),
            Just("FULL_OPENCV"),
            Just("nan"),
            Just("inf"),
            Just("-inf"),
            Just("1e999"),
            Just("-0"),
            Just("18446744073709551616"),
            Just("im2.png"),
            Just("#"),
            Just(""),
            Just("\u{feff}"),
        ]
        .prop_map(String::from),
    ]
}

fn text_file() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(proptest::collection::vec(token(), 0..14), 0..8).prop_map(|lines| {
        lines
            .iter()
            .map(|l| l.join(" "))
            .collect::<Vec<_>>()
            .join("\n")
            .into_bytes()
    })
}

/// A valid ASCII PLY: a tetrahedron with normals and colours.
fn ply_ascii() -> String {
    "ply\nformat ascii 1.0\ncomment fuzz\nelement vertex 4\nproperty float x\nproperty float y\n\
     property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
     property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 4\n\
     property list uchar int vertex_indices\nend_header\n\
     0 0 0 0 0 -1 255 0 0\n1 0 0 0 0 -1 0 255 0\n0 1 0 0 0 -1 0 0 255\n0 0 1 1 1 1 9 9 9\n\
     3 0 2 1\n3 0 1 3\n3 1 2 3\n3 0 3 2\n"
        .to_string()
}

/// Header lines for random PLY headers.
fn ply_header_line() -> impl Strategy<Value = String> {
    let ty = prop_oneof![
        Just("char"),
        Just("uchar"),
        Just("short"),
        Just("int"),
        Just("uint"),
        Just("float"),
        Just("double"),
        Just("int8"),
        Just("float32"),
        Just("bogus"),
    ];
    let count = prop_oneof![
        (0u64..6).prop_map(|v| v.to_string()),
        Just("4294967296".to_string()),
        Just("18446744073709551615".to_string()),
        Just("-1".to_string()),
        // 2^64 panics inside ply-rs: see `ply_element_count_above_u64_max`.
    ];
    let elem = prop_oneof![Just("vertex"), Just("face"), Just("edge")];
    let prop = prop_oneof![
        Just("x"),
        Just("y"),
        Just("z"),
        Just("nx"),
        Just("red"),
        Just("vertex_indices"),
        Just("vertex_index"),
    ];
    prop_oneof![
        (elem, count).prop_map(|(e, c)| format!("element {e} {c}")),
        (ty.clone(), prop.clone()).prop_map(|(t, p)| format!("property {t} {p}")),
        (ty.clone(), ty, prop).prop_map(|(a, b, p)| format!("property list {a} {b} {p}")),
        prop_oneof![
            Just("format ascii 1.0"),
            Just("format binary_little_endian 1.0"),
            Just("format binary_big_endian 1.0"),
            Just("format ascii 2.0"),
            Just("comment x"),
            Just("obj_info y"),
            Just("ply"),
        ]
        .prop_map(String::from),
    ]
}

/// Writes `bytes` to a fresh file under the target dir and reads it as a mesh; checks the
/// result (a consistent mesh) or the error (names the file).
fn read_ply_bytes(tag: &str, case: u64, bytes: &[u8]) -> Result<bool, TestCaseError> {
    // A folder of its own per call: tests run on several threads, and a folder shared
    // between them could be removed by one between another's create and write.
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!(
        "relight-proptest-ply-{}-{call}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let path = dir.join(format!("{tag}-{case}.ply"));
    std::fs::write(&path, bytes).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let r = Mesh::read_ply(&path);
    let _ = std::fs::remove_dir_all(&dir);
    match r {
        Ok((mesh, _)) => {
            let n = mesh.positions.len();
            prop_assert!(mesh.faces.iter().flatten().all(|&k| (k as usize) < n));
            prop_assert_eq!(mesh.normals.len(), n);
            prop_assert!(mesh
                .positions
                .iter()
                .all(|p| p.iter().all(|c| c.is_finite())));
            prop_assert!(mesh.normals.iter().all(|p| p.iter().all(|c| c.is_finite())));
            Ok(true)
        }
        Err(e) => {
            names_file(&e, &path)?;
            Ok(false)
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary bytes into every COLMAP reader.
    #[test]
    fn colmap_random_bytes(bin in any::<bool>(), which in 0usize..3,
                           bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        parse(bin, which, &bytes)?;
    }

    /// Several structural edits of a valid binary model.
    #[test]
    fn colmap_binary_mutations(which in 0usize..3,
                               edits in proptest::collection::vec(edit(), 1..6)) {
        let mut b = files(true)[which].clone();
        apply(&mut b, &edits);
        parse(true, which, &b)?;
    }

    /// Several structural edits of a valid text model.
    #[test]
    fn colmap_text_mutations(which in 0usize..3,
                             edits in proptest::collection::vec(edit(), 1..6)) {
        let mut b = files(false)[which].clone();
        apply(&mut b, &edits);
        parse(false, which, &b)?;
    }

    /// Lines of plausible tokens (ids, model names, huge and non-finite numbers).
    #[test]
    fn colmap_text_grammar(which in 0usize..3, body in text_file()) {
        parse(false, which, &body)?;
    }

    /// A valid binary header count followed by random records.
    #[test]
    fn colmap_binary_count_then_noise(which in 0usize..3, count in prop_oneof![0u64..4, Just(u64::MAX), Just(1u64 << 40)],
                                      rest in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut b = count.to_le_bytes().to_vec();
        b.extend(rest);
        parse(true, which, &b)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, failure_persistence: None, ..ProptestConfig::default() })]

    /// Several edits of a valid ASCII PLY (the binary byte flips are in mesh_ply.rs).
    #[test]
    fn ply_ascii_mutations(case in any::<u64>(), edits in proptest::collection::vec(edit(), 1..6)) {
        let mut b = ply_ascii().into_bytes();
        apply(&mut b, &edits);
        read_ply_bytes("ascii", case, &b)?;
    }

    /// Random headers over the valid ASCII body, or over random bytes.
    #[test]
    fn ply_random_headers(case in any::<u64>(),
                          lines in proptest::collection::vec(ply_header_line(), 0..10),
                          noise in proptest::option::of(proptest::collection::vec(any::<u8>(), 0..200))) {
        let body = ply_ascii();
        let body = body.split("end_header\n").nth(1).unwrap_or("").as_bytes().to_vec();
        let mut b = format!("ply\n{}\nend_header\n", lines.join("\n")).into_bytes();
        b.extend(noise.unwrap_or(body));
        read_ply_bytes("header", case, &b)?;
    }

    /// Arbitrary bytes, with and without the magic line.
    #[test]
    fn ply_random_bytes(case in any::<u64>(), magic in any::<bool>(),
                        bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let mut b = if magic { b"ply\nformat binary_little_endian 1.0\n".to_vec() } else { Vec::new() };
        b.extend(bytes);
        read_ply_bytes("bytes", case, &b)?;
    }
}

/// The valid inputs the mutations start from do parse (otherwise the mutation tests would
/// only ever exercise the first error path).
#[test]
fn seeds_are_valid() {
    for bin in [false, true] {
        for (which, f) in files(bin).iter().enumerate() {
            assert!(
                parse(bin, which, f).expect("no error"),
                "seed {which} bin={bin}"
            );
        }
    }
    assert!(read_ply_bytes("seed", 0, ply_ascii().as_bytes()).expect("no error"));
}

/// Found by scripts/fuzz.sh (fuzz/artifacts/ply/crash-1): an element count above u64::MAX
/// panics inside ply-rs 0.1.3 (`ply_grammar.rs:23`, `n.parse().unwrap()` in the header
/// grammar), reached from `mesh::read_ply_data` (src/mesh.rs, `parser.read_header`). The
/// reader should turn it into a Format error naming the file, e.g. by checking element
/// counts before ply-rs or with `std::panic::catch_unwind` around `read_header`.
#[test]
fn ply_element_count_above_u64_max() {
    let body = "ply\nformat ascii 1.0\nelement vertex 18446744073709551616\nproperty float x\n\
                property float y\nproperty float z\nelement face 0\n\
                property list uchar int vertex_indices\nend_header\n";
    let r = std::panic::catch_unwind(|| read_ply_bytes("u64max", 0, body.as_bytes()));
    assert!(r.is_ok(), "read_ply panicked");
    assert!(!r.unwrap().expect("error names the file"));
}
