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

mod ply;

pub use ply::{read_ply_data, PlyData};

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
    let input_faces = faces.len();
    let kept = non_degenerate_faces(&positions, faces);
    let new_index = referenced_index(positions.len(), &kept);
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
    let read = normals.map(|read| {
        (0..positions.len())
            .filter(|&i| keep(i))
            .map(|i| read[i])
            .collect::<Vec<_>>()
    });
    let (new_normals, normals_computed) = merge_normals(read, computed);
    let cleanup = MeshCleanup {
        input_vertices: positions.len(),
        input_faces,
        degenerate_faces: input_faces - kept.len(),
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

/// The faces with three distinct, finite corners and an area above `10⁻¹²` of the
/// squared diagonal of the finite vertices' bounding box.
fn non_degenerate_faces(positions: &[Vec3], faces: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
    let finite: Vec<Vec3> = positions
        .iter()
        .copied()
        .filter(|p| p.iter().all(|c| c.is_finite()))
        .collect();
    let (lo, hi) = bounding_box(&finite);
    let zero_area = 1e-12 * (hi - lo).norm_squared();
    faces
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
        .collect()
}

/// Each vertex's new index when the vertices `faces` reference keep their order
/// (`u32::MAX` for the unreferenced).
fn referenced_index(n_vertices: usize, faces: &[[u32; 3]]) -> Vec<u32> {
    let mut new_index = vec![u32::MAX; n_vertices];
    for f in faces {
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
    new_index
}

/// Read normals where usable (finite, non-zero, normalised), computed ones elsewhere;
/// whether any computed one was used.
fn merge_normals(read: Option<Vec<Vec3>>, computed: Vec<Vec3>) -> (Vec<Vec3>, bool) {
    let Some(read) = read else {
        return (computed, true);
    };
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

#[cfg(test)]
mod tests;
