//! Triangle meshes: reading and writing PLY, cleaning, vertex normals and one-rings.
//!
//! The surface the paper's observations live on (Sec. 3: "a triangle mesh ... each vertex is
//! a surface point x"). A mesh is read from PLY with `ply-rs` (ascii, binary little- and
//! big-endian; `float`/`double` coordinates; `vertex_indices` or `vertex_index` face lists;
//! optional `nx ny nz` normals and `red green blue` colours), then cleaned:
//!
//! - a face is *degenerate* and dropped when it repeats a vertex index, touches a
//!   non-finite position, or has zero area: `|(p1 − p0) × (p2 − p0)| ≤ 1e-12 · d²` with `d` the
//!   bounding-box diagonal (a scale-free "zero": a 100K-vertex mesh of diagonal 1 has face
//!   cross products around 1e-5);
//! - polygons with more than three corners are split into a triangle fan;
//! - vertices no kept face references are dropped and the faces re-indexed;
//! - when the file carries no (usable) normals, each vertex gets the area-weighted normal
//!   `n_v = normalize(Σ_{f ∋ v} (p1 − p0) × (p2 − p0))` (the cross product is twice the face
//!   area times the unit face normal, so the sum is area-weighted).
//!
//! A face index out of range or a NaN/infinite coordinate in a file is an error naming the
//! file and the element index: silently dropping it would hide a broken export.
//!
//! Writing ([`Mesh::write_ply`]) is binary little-endian with float positions and normals,
//! uchar colours and any extra per-vertex float properties (e.g. material weights).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use byteorder::{LittleEndian, WriteBytesExt};
use ply_rs::parser::Parser;
use ply_rs::ply::{ElementDef, Property, PropertyAccess, PropertyType};

use crate::{Error, Result, Vec3};

/// An indexed triangle mesh.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Vertex positions (world coordinates of the COLMAP model).
    pub positions: Vec<Vec3>,
    /// Unit vertex normals; area-weighted face normals when the file had none.
    pub normals: Vec<Vec3>,
    /// Counter-clockwise triangles (indices into `positions`).
    pub faces: Vec<[u32; 3]>,
    /// Per-vertex colours as stored in the file, scaled to `[0, 1]` (uchar / 255,
    /// ushort / 65535, floats as they are).
    pub colors: Option<Vec<[f32; 3]>>,
}

/// What cleaning changed, for the summary printed by `inspect`.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct MeshCleanup {
    /// Vertices in the input.
    pub input_vertices: usize,
    /// Faces (polygons) in the input.
    pub input_faces: usize,
    /// Faces dropped for a repeated index, a non-finite corner or zero area.
    pub degenerate_faces: usize,
    /// Faces dropped by [`Mesh::from_parts`] for an index out of range (files error instead).
    pub invalid_faces: usize,
    /// Polygons with more than three corners that were split into triangle fans.
    pub polygons_triangulated: usize,
    /// Vertices dropped because no kept face uses them.
    pub unreferenced_vertices: usize,
    /// True when the normals were computed (area-weighted) rather than read.
    pub normals_computed: bool,
}

impl Mesh {
    /// Reads a PLY mesh and cleans it (see the module docs).
    ///
    /// Errors: [`Error::Io`] when the file cannot be read, [`Error::Format`] (naming the file
    /// and the element) for a malformed file, a missing `vertex`/`face` element or `x y z`
    /// property, a non-finite coordinate, or a face index out of range.
    pub fn read_ply(path: &Path) -> Result<(Mesh, MeshCleanup)> {
        let data = read_ply_data(path)?;
        if !data.has_faces {
            let found = if data.elements.iter().any(|e| e == "tristrips") {
                "found triangle strips (`tristrips`), which are not read: export the mesh \
                 with a `face` element"
                    .to_string()
            } else {
                format!("found only: {}", data.elements.join(", "))
            };
            return Err(Error::format(
                path,
                "header",
                format!(
                    "expected a `face` element with a `vertex_indices` (or `vertex_index`) \
                     list; {found}"
                ),
            ));
        }
        let n = data.positions.len();
        // Validate indices and triangulate polygons.
        let mut tris: Vec<[u32; 3]> = Vec::with_capacity(data.faces.len());
        let mut polygons = 0usize;
        let mut short_faces = 0usize;
        for (fi, face) in data.faces.iter().enumerate() {
            for &k in face {
                if k < 0 || k as usize >= n {
                    return Err(Error::format(
                        path,
                        format!("face {fi}"),
                        format!("expected vertex indices 0 to {}, found {k}", n as i64 - 1),
                    ));
                }
            }
            if face.len() < 3 {
                short_faces += 1;
                continue;
            }
            if face.len() > 3 {
                polygons += 1;
            }
            for j in 1..face.len() - 1 {
                tris.push([face[0] as u32, face[j] as u32, face[j + 1] as u32]);
            }
        }
        let (mesh, mut cleanup) = clean(data.positions, data.normals, data.colors, tris);
        cleanup.input_faces = data.faces.len();
        cleanup.degenerate_faces += short_faces;
        cleanup.polygons_triangulated = polygons;
        Ok((mesh, cleanup))
    }

    /// Builds a cleaned mesh from positions and triangles, computing area-weighted normals.
    /// Faces with an index out of range are dropped and counted in `invalid_faces`.
    pub fn from_parts(positions: Vec<Vec3>, faces: Vec<[u32; 3]>) -> (Mesh, MeshCleanup) {
        let n = positions.len();
        let input_faces = faces.len();
        let valid: Vec<[u32; 3]> = faces
            .into_iter()
            .filter(|f| f.iter().all(|&k| (k as usize) < n))
            .collect();
        let invalid = input_faces - valid.len();
        let (mesh, mut cleanup) = clean(positions, None, None, valid);
        cleanup.input_faces = input_faces;
        cleanup.invalid_faces = invalid;
        (mesh, cleanup)
    }

    /// Writes the mesh as binary little-endian PLY: `x y z nx ny nz` floats, `red green blue`
    /// uchar when there are colours, then one float property per entry of `extra`
    /// (`(name, values)`, one value per vertex), and `vertex_indices` faces.
    pub fn write_ply(&self, path: &Path, extra: &[(&str, &[f32])]) -> Result<()> {
        let n = self.positions.len();
        for (name, values) in extra {
            if values.len() != n {
                return Err(Error::Internal(format!(
                    "extra PLY property `{name}` has {} values for {n} vertices",
                    values.len()
                )));
            }
            if name.is_empty() || name.chars().any(char::is_whitespace) {
                return Err(Error::Internal(format!(
                    "extra PLY property name `{name}` must be one word"
                )));
            }
        }
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let mut w = BufWriter::new(file);
        let io = |e: std::io::Error| Error::io(path, e);
        let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
        header.push_str("comment written by relight-cpc\n");
        header.push_str(&format!("element vertex {n}\n"));
        for p in ["x", "y", "z", "nx", "ny", "nz"] {
            header.push_str(&format!("property float {p}\n"));
        }
        if self.colors.is_some() {
            for p in ["red", "green", "blue"] {
                header.push_str(&format!("property uchar {p}\n"));
            }
        }
        for (name, _) in extra {
            header.push_str(&format!("property float {name}\n"));
        }
        header.push_str(&format!("element face {}\n", self.faces.len()));
        header.push_str("property list uchar int vertex_indices\nend_header\n");
        w.write_all(header.as_bytes()).map_err(io)?;
        for i in 0..n {
            let p = self.positions[i];
            let nrm = self.normals.get(i).copied().unwrap_or_else(Vec3::zeros);
            for v in [p.x, p.y, p.z, nrm.x, nrm.y, nrm.z] {
                w.write_f32::<LittleEndian>(v as f32).map_err(io)?;
            }
            if let Some(colors) = &self.colors {
                for c in colors[i] {
                    w.write_u8((c.clamp(0.0, 1.0) * 255.0).round() as u8)
                        .map_err(io)?;
                }
            }
            for (_, values) in extra {
                w.write_f32::<LittleEndian>(values[i]).map_err(io)?;
            }
        }
        for f in &self.faces {
            w.write_u8(3).map_err(io)?;
            for &k in f {
                w.write_i32::<LittleEndian>(k as i32).map_err(io)?;
            }
        }
        w.flush().map_err(io)?;
        Ok(())
    }

    /// Axis-aligned bounding box `(min, max)`; zeros for an empty mesh.
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        bounding_box(&self.positions)
    }

    /// Length of the bounding-box diagonal (the scene scale).
    pub fn diagonal(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        (hi - lo).norm()
    }

    /// The one-ring of every vertex: the vertices sharing an edge with it, sorted, no repeats.
    pub fn vertex_neighbors(&self) -> Vec<Vec<u32>> {
        let mut ring: Vec<Vec<u32>> = vec![Vec::new(); self.positions.len()];
        for f in &self.faces {
            for j in 0..3 {
                let (a, b) = (f[j], f[(j + 1) % 3]);
                ring[a as usize].push(b);
                ring[b as usize].push(a);
            }
        }
        for r in &mut ring {
            r.sort_unstable();
            r.dedup();
        }
        ring
    }

    /// Unit normal of face `f` (zero for a degenerate face).
    pub fn face_normal(&self, f: usize) -> Vec3 {
        let [a, b, c] = self.faces[f];
        let (p0, p1, p2) = (
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        );
        (p1 - p0)
            .cross(&(p2 - p0))
            .try_normalize(0.0)
            .unwrap_or_else(Vec3::zeros)
    }

    /// Barycentric vertex areas: one third of the area of every incident face.
    pub fn vertex_areas(&self) -> Vec<f64> {
        let mut area = vec![0.0; self.positions.len()];
        for f in &self.faces {
            let (p0, p1, p2) = (
                self.positions[f[0] as usize],
                self.positions[f[1] as usize],
                self.positions[f[2] as usize],
            );
            let a = 0.5 * (p1 - p0).cross(&(p2 - p0)).norm() / 3.0;
            for &k in f {
                area[k as usize] += a;
            }
        }
        area
    }
}

/// Axis-aligned bounding box of `points`; zeros when empty.
pub fn bounding_box(points: &[Vec3]) -> (Vec3, Vec3) {
    if points.is_empty() {
        return (Vec3::zeros(), Vec3::zeros());
    }
    let mut lo = Vec3::repeat(f64::INFINITY);
    let mut hi = Vec3::repeat(f64::NEG_INFINITY);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (lo, hi)
}

/// Area-weighted unit vertex normals of a triangle mesh (module docs). A vertex whose
/// weighted sum cancels (a sheet folded onto itself) takes its first incident face's normal;
/// a vertex with no non-degenerate face gets zero.
pub fn area_weighted_normals(positions: &[Vec3], faces: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sum = vec![Vec3::zeros(); positions.len()];
    let mut first: Vec<Option<Vec3>> = vec![None; positions.len()];
    for f in faces {
        let (p0, p1, p2) = (
            positions[f[0] as usize],
            positions[f[1] as usize],
            positions[f[2] as usize],
        );
        let c = (p1 - p0).cross(&(p2 - p0));
        let unit = c.try_normalize(0.0);
        for &k in f {
            sum[k as usize] += c;
            if first[k as usize].is_none() {
                first[k as usize] = unit;
            }
        }
    }
    sum.iter()
        .zip(&first)
        .map(|(s, f)| s.try_normalize(1e-300).or(*f).unwrap_or_else(Vec3::zeros))
        .collect()
}

/// Drops degenerate faces and unreferenced vertices, fills in normals (see module docs).
fn clean(
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    colors: Option<Vec<[f32; 3]>>,
    faces: Vec<[u32; 3]>,
) -> (Mesh, MeshCleanup) {
    let finite: Vec<Vec3> = positions
        .iter()
        .copied()
        .filter(|p| p.iter().all(|c| c.is_finite()))
        .collect();
    let (lo, hi) = bounding_box(&finite);
    let d2 = (hi - lo).norm_squared();
    let zero_area = 1e-12 * d2;
    let input_faces = faces.len();
    let kept: Vec<[u32; 3]> = faces
        .into_iter()
        .filter(|&[a, b, c]| {
            if a == b || b == c || a == c {
                return false;
            }
            let (p0, p1, p2) = (
                positions[a as usize],
                positions[b as usize],
                positions[c as usize],
            );
            if !(p0.iter().chain(p1.iter()).chain(p2.iter())).all(|v| v.is_finite()) {
                return false;
            }
            (p1 - p0).cross(&(p2 - p0)).norm() > zero_area
        })
        .collect();
    let degenerate = input_faces - kept.len();

    // Re-index the referenced vertices in their original order.
    let mut new_index = vec![u32::MAX; positions.len()];
    for f in &kept {
        for &k in f {
            new_index[k as usize] = 0;
        }
    }
    let mut next = 0u32;
    for slot in new_index.iter_mut() {
        if *slot == 0 {
            *slot = next;
            next += 1;
        }
    }
    let keep = |i: usize| new_index[i] != u32::MAX;
    let new_positions: Vec<Vec3> = (0..positions.len())
        .filter(|&i| keep(i))
        .map(|i| positions[i])
        .collect();
    let new_faces: Vec<[u32; 3]> = kept
        .iter()
        .map(|f| f.map(|k| new_index[k as usize]))
        .collect();
    let new_colors = colors.map(|c| {
        (0..positions.len())
            .filter(|&i| keep(i))
            .map(|i| c[i])
            .collect::<Vec<_>>()
    });
    let computed = area_weighted_normals(&new_positions, &new_faces);
    // Read normals are used where usable (finite, non-zero); the rest are computed.
    let (new_normals, normals_computed) = match normals {
        Some(read) => {
            let read: Vec<Vec3> = (0..positions.len())
                .filter(|&i| keep(i))
                .map(|i| read[i])
                .collect();
            let mut all_read = true;
            let merged = read
                .iter()
                .zip(&computed)
                .map(|(r, c)| match r.try_normalize(1e-300) {
                    Some(u) if u.iter().all(|v| v.is_finite()) => u,
                    _ => {
                        all_read = false;
                        *c
                    }
                })
                .collect();
            (merged, !all_read)
        }
        None => (computed, true),
    };
    let cleanup = MeshCleanup {
        input_vertices: positions.len(),
        input_faces,
        degenerate_faces: degenerate,
        invalid_faces: 0,
        polygons_triangulated: 0,
        unreferenced_vertices: positions.len() - new_positions.len(),
        normals_computed,
    };
    (
        Mesh {
            positions: new_positions,
            normals: new_normals,
            faces: new_faces,
            colors: new_colors,
        },
        cleanup,
    )
}

/// Vertex and face data read from a PLY file, before cleaning. Shared with
/// [`crate::import::points`] (fused point clouds are PLY vertex lists).
#[derive(Debug, Clone, Default)]
pub struct PlyData {
    /// Vertex positions (validated finite).
    pub positions: Vec<Vec3>,
    /// Vertex normals when the file has `nx ny nz`.
    pub normals: Option<Vec<Vec3>>,
    /// Vertex colours scaled to `[0, 1]` when the file has `red green blue`.
    pub colors: Option<Vec<[f32; 3]>>,
    /// Face index lists as stored (not validated).
    pub faces: Vec<Vec<i64>>,
    /// Whether the file has a face element with an index list.
    pub has_faces: bool,
    /// The header's element names, in file order.
    pub elements: Vec<String>,
}

/// One PLY element as the parser fills it: only the properties this crate uses are kept,
/// so a 100K-vertex file costs no per-property maps.
#[derive(Debug, Default)]
struct PlyRecord {
    xyz: [f64; 3],
    normal: [f64; 3],
    color: [f32; 3],
    indices: Vec<i64>,
}

fn scalar_f64(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// A colour channel scaled to `[0, 1]` by its type's range (floats as stored).
fn color_channel(p: &Property) -> f32 {
    match *p {
        Property::UChar(v) => v as f32 / 255.0,
        Property::Char(v) => v as f32 / 127.0,
        Property::UShort(v) => v as f32 / 65535.0,
        Property::Short(v) => v as f32 / 32767.0,
        Property::UInt(v) => (v as f64 / u32::MAX as f64) as f32,
        Property::Int(v) => (v as f64 / i32::MAX as f64) as f32,
        Property::Float(v) => v,
        Property::Double(v) => v as f32,
        _ => f32::NAN,
    }
}

fn list_i64(p: Property) -> Vec<i64> {
    match p {
        Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
        Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
        Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
        // Float index lists are not PLY, but some writers emit them: round-trip exact ints.
        Property::ListFloat(v) => v.into_iter().map(float_index).collect(),
        Property::ListDouble(v) => v.into_iter().map(|x| float_index(x as f32)).collect(),
        _ => Vec::new(),
    }
}

fn float_index(x: f32) -> i64 {
    if x.is_finite() && x.fract() == 0.0 {
        x as i64
    } else {
        -1
    }
}

impl PropertyAccess for PlyRecord {
    fn new() -> Self {
        PlyRecord::default()
    }
    fn set_property(&mut self, name: String, property: Property) {
        let slot = match name.as_str() {
            "x" => Some(&mut self.xyz[0]),
            "y" => Some(&mut self.xyz[1]),
            "z" => Some(&mut self.xyz[2]),
            "nx" => Some(&mut self.normal[0]),
            "ny" => Some(&mut self.normal[1]),
            "nz" => Some(&mut self.normal[2]),
            _ => None,
        };
        if let Some(slot) = slot {
            *slot = scalar_f64(&property).unwrap_or(f64::NAN);
            return;
        }
        match name.as_str() {
            "red" | "r" | "diffuse_red" => self.color[0] = color_channel(&property),
            "green" | "g" | "diffuse_green" => self.color[1] = color_channel(&property),
            "blue" | "b" | "diffuse_blue" => self.color[2] = color_channel(&property),
            "vertex_indices" | "vertex_index" => self.indices = list_i64(property),
            _ => {}
        }
    }
}

fn has_props(e: &ElementDef, names: &[&str]) -> bool {
    names.iter().all(|n| e.properties.contains_key(*n))
}

fn color_names(e: &ElementDef) -> Option<[&'static str; 3]> {
    [
        ["red", "green", "blue"],
        ["r", "g", "b"],
        ["diffuse_red", "diffuse_green", "diffuse_blue"],
    ]
    .into_iter()
    .find(|names| has_props(e, names))
}

/// Reads the `vertex` (and, when present, `face`) elements of a PLY file with `ply-rs`.
/// Positions are checked finite (error naming the vertex); normals and colours are taken
/// when all three components are declared.
///
/// The payload is read one record at a time (ply-rs's per-record readers), so an error
/// names the element, the record and, for ASCII files, the line; ply-rs's own messages
/// (which embed Debug text) never reach the user.
pub fn read_ply_data(path: &Path) -> Result<PlyData> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if !bytes.starts_with(b"ply") {
        return Err(Error::format(
            path,
            "line 1",
            "the file does not start with `ply`: not a PLY file",
        ));
    }
    let mut reader = std::io::Cursor::new(bytes.as_slice());
    let parser = Parser::<PlyRecord>::new();
    // ply-rs 0.1.3 panics on an element count that does not fit in u64 (it unwraps the
    // parse); turn that into an error naming the file instead of a crash.
    let header = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        parser.read_header(&mut reader)
    }))
    .map_err(|_| {
        Error::format(
            path,
            "header",
            "malformed header (an element count or property is out of range)",
        )
    })?
    .map_err(|e| header_error(path, &bytes, &e))?;
    let header_lines = bytes[..reader.position() as usize]
        .iter()
        .filter(|&&b| b == b'\n')
        .count();
    check_header(path, &header)?;
    let vdef = &header.elements["vertex"];
    let has_normals = has_props(vdef, &["nx", "ny", "nz"]);
    let has_colors = color_names(vdef).is_some();
    let face_list = header.elements.get("face").and_then(|f| {
        ["vertex_indices", "vertex_index"]
            .into_iter()
            .find(|n| matches!(f.properties.get(*n), Some(p) if matches!(p.data_type, PropertyType::List(..))))
    });
    let mut records = RecordReader {
        path,
        parser: &parser,
        encoding: header.encoding,
        reader,
        line: header_lines,
    };
    let mut vertices: Vec<PlyRecord> = Vec::new();
    let mut face_records: Vec<PlyRecord> = Vec::new();
    for (name, def) in &header.elements {
        let keep = match name.as_str() {
            "vertex" => Some(&mut vertices),
            "face" => Some(&mut face_records),
            _ => None,
        };
        records.element(def, keep)?;
    }
    let mut positions = Vec::with_capacity(vertices.len());
    for (i, r) in vertices.iter().enumerate() {
        let p = Vec3::new(r.xyz[0], r.xyz[1], r.xyz[2]);
        if !p.iter().all(|c| c.is_finite()) {
            return Err(Error::format(
                path,
                format!("vertex {i}"),
                format!(
                    "expected finite coordinates, found ({}, {}, {})",
                    r.xyz[0], r.xyz[1], r.xyz[2]
                ),
            ));
        }
        positions.push(p);
    }
    let normals = has_normals.then(|| {
        vertices
            .iter()
            .map(|r| Vec3::new(r.normal[0], r.normal[1], r.normal[2]))
            .collect()
    });
    let colors = has_colors.then(|| vertices.iter().map(|r| r.color).collect());
    let faces = match face_list {
        Some(_) => face_records.into_iter().map(|r| r.indices).collect(),
        None => Vec::new(),
    };
    Ok(PlyData {
        positions,
        normals,
        colors,
        faces,
        has_faces: face_list.is_some(),
        elements: header.elements.keys().cloned().collect(),
    })
}

/// The header's `vertex` element must exist with scalar `x y z`.
fn check_header(path: &Path, header: &ply_rs::ply::Header) -> Result<()> {
    let vdef = header.elements.get("vertex").ok_or_else(|| {
        let names: Vec<&str> = header.elements.keys().map(|k| k.as_str()).collect();
        Error::format(
            path,
            "header",
            format!(
                "expected a `vertex` element, found only: {}",
                if names.is_empty() {
                    "no elements".to_string()
                } else {
                    names.join(", ")
                }
            ),
        )
    })?;
    if !has_props(vdef, &["x", "y", "z"]) {
        return Err(Error::format(
            path,
            "header",
            "the `vertex` element lacks one of the properties x, y, z",
        ));
    }
    for p in ["x", "y", "z"] {
        if let Some(def) = vdef.properties.get(p) {
            if matches!(def.data_type, PropertyType::List(..)) {
                return Err(Error::format(
                    path,
                    "header",
                    format!("vertex property `{p}` is a list, expected a number"),
                ));
            }
        }
    }
    Ok(())
}

/// A header ply-rs refused, in plain words: the offending line as the file has it.
fn header_error(path: &Path, bytes: &[u8], e: &std::io::Error) -> Error {
    let msg = e.to_string();
    // ply-rs reports "Line N: ..." with N the file's line number (from 1).
    let line_no = msg
        .strip_prefix("Line ")
        .and_then(|r| r.split(':').next())
        .and_then(|n| n.trim().parse::<usize>().ok());
    let text = |n: usize| {
        bytes
            .split(|&b| b == b'\n')
            .nth(n)
            .map(|l| excerpt(&String::from_utf8_lossy(l)))
            .unwrap_or_default()
    };
    let expected = "expected `format ascii|binary_little_endian|binary_big_endian 1.0`, \
                    `element NAME COUNT`, `property TYPE NAME`, `property list TYPE TYPE NAME`, \
                    `comment ...` or `end_header`";
    match (e.kind(), line_no) {
        (std::io::ErrorKind::UnexpectedEof, _) => {
            Error::format(path, "header", "the file ends before `end_header`")
        }
        (_, Some(n)) => Error::format(
            path,
            format!("line {n}"),
            format!("{expected}; found `{}`", text(n.saturating_sub(1))),
        ),
        _ => Error::format(
            path,
            "header",
            format!("not a valid PLY header: {expected}"),
        ),
    }
}

/// At most 60 characters of a line, for an error message.
fn excerpt(line: &str) -> String {
    let t = line.trim_end_matches(['\r', '\n']);
    if t.chars().count() > 60 {
        format!("{}…", t.chars().take(60).collect::<String>())
    } else {
        t.to_string()
    }
}

/// Reads a PLY payload one record at a time, keeping the line count (ASCII).
struct RecordReader<'a> {
    path: &'a Path,
    parser: &'a Parser<PlyRecord>,
    encoding: ply_rs::ply::Encoding,
    reader: std::io::Cursor<&'a [u8]>,
    /// Lines consumed so far (ASCII).
    line: usize,
}

impl RecordReader<'_> {
    /// Reads every record of `def`, pushing them to `keep` when given.
    fn element(&mut self, def: &ElementDef, mut keep: Option<&mut Vec<PlyRecord>>) -> Result<()> {
        use ply_rs::ply::Encoding;
        use std::io::BufRead;
        let remaining = self.reader.get_ref().len() - self.reader.position() as usize;
        if let Some(k) = keep.as_mut() {
            // A record takes at least one byte: never reserve more than the file can hold.
            k.reserve((def.count).min(remaining));
        }
        let mut line = String::new();
        for k in 0..def.count {
            let before = self.reader.position();
            let r = match self.encoding {
                Encoding::Ascii => {
                    line.clear();
                    let n = self.reader.read_line(&mut line).unwrap_or(0);
                    if n == 0 {
                        return Err(self.ended(def, k));
                    }
                    self.line += 1;
                    self.parser
                        .read_ascii_element(&line, def)
                        .map_err(|_| self.bad_line(def, k, &line))?
                }
                Encoding::BinaryLittleEndian => self
                    .parser
                    .read_little_endian_element(&mut self.reader, def)
                    .map_err(|e| self.bad_record(def, k, before, &e))?,
                Encoding::BinaryBigEndian => self
                    .parser
                    .read_big_endian_element(&mut self.reader, def)
                    .map_err(|e| self.bad_record(def, k, before, &e))?,
            };
            if let Some(v) = keep.as_mut() {
                v.push(r);
            }
        }
        Ok(())
    }

    fn ended(&self, def: &ElementDef, k: usize) -> Error {
        Error::format(
            self.path,
            format!("`{}` element", def.name),
            format!(
                "expected {} records as the header announces, found {k}: the file ends early (truncated?)",
                def.count
            ),
        )
    }

    fn bad_line(&self, def: &ElementDef, k: usize, line: &str) -> Error {
        Error::format(
            self.path,
            format!("line {} (`{}` record {k})", self.line, def.name),
            format!(
                "expected the values {}, found `{}`",
                property_list(def),
                excerpt(line)
            ),
        )
    }

    fn bad_record(&self, def: &ElementDef, k: usize, at: u64, e: &std::io::Error) -> Error {
        let eof = e.kind() == std::io::ErrorKind::UnexpectedEof
            || e.to_string().contains("UnexpectedEof");
        if eof {
            return self.ended(def, k);
        }
        Error::format(
            self.path,
            format!("`{}` record {k} (byte {at})", def.name),
            format!(
                "expected the values {}, which cannot be read there",
                property_list(def)
            ),
        )
    }
}

/// `x y z (float)` style description of an element's properties.
fn property_list(def: &ElementDef) -> String {
    let names: Vec<String> = def
        .properties
        .iter()
        .map(|(name, p)| match &p.data_type {
            PropertyType::Scalar(_) => name.clone(),
            PropertyType::List(..) => format!("{name} (a count, then that many numbers)"),
        })
        .collect();
    names.join(" ")
}

#[cfg(test)]
mod tests;
