//! Reading PLY meshes (ASCII and binary, via ply-rs): the header checks, the record reader, and the properties a mesh needs (positions, normals, colours, faces), each error naming the file, the element and record.

use super::*;

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
pub(crate) struct PlyRecord {
    pub(crate) xyz: [f64; 3],
    pub(crate) normal: [f64; 3],
    pub(crate) color: [f32; 3],
    pub(crate) indices: Vec<i64>,
}

pub(crate) fn scalar_f64(p: &Property) -> Option<f64> {
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
pub(crate) fn color_channel(p: &Property) -> f32 {
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

pub(crate) fn list_i64(p: Property) -> Vec<i64> {
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

pub(crate) fn float_index(x: f32) -> i64 {
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

pub(crate) fn has_props(e: &ElementDef, names: &[&str]) -> bool {
    names.iter().all(|n| e.properties.contains_key(*n))
}

pub(crate) fn color_names(e: &ElementDef) -> Option<[&'static str; 3]> {
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
    let parser = Parser::<PlyRecord>::new();
    let PlyFile {
        header,
        mut records,
    } = read_header(path, &bytes, &parser)?;
    check_header(path, &header)?;
    let vdef = &header.elements["vertex"];
    let has_normals = has_props(vdef, &["nx", "ny", "nz"]);
    let has_colors = color_names(vdef).is_some();
    let face_list = face_list_property(&header);
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
    let positions = finite_positions(path, &vertices)?;
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

/// A PLY file's header, and a record reader placed at its payload.
struct PlyFile<'a> {
    header: ply_rs::ply::Header,
    records: RecordReader<'a>,
}

/// The header of the PLY file `bytes` (from `path`), the reader counting lines from its end.
fn read_header<'a>(
    path: &'a Path,
    bytes: &'a [u8],
    parser: &'a Parser<PlyRecord>,
) -> Result<PlyFile<'a>> {
    if !bytes.starts_with(b"ply") {
        return Err(Error::format(
            path,
            "line 1",
            "the file does not start with `ply`: not a PLY file",
        ));
    }
    let mut reader = std::io::Cursor::new(bytes);
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
    .map_err(|e| header_error(path, bytes, &e))?;
    let header_lines = bytes[..reader.position() as usize]
        .iter()
        .filter(|&&b| b == b'\n')
        .count();
    let records = RecordReader {
        path,
        parser,
        encoding: header.encoding,
        reader,
        line: header_lines,
    };
    Ok(PlyFile { header, records })
}

/// The name of the face element's vertex-index list (`vertex_indices` or
/// `vertex_index`), when it has one.
fn face_list_property(header: &ply_rs::ply::Header) -> Option<&'static str> {
    header.elements.get("face").and_then(|f| {
        ["vertex_indices", "vertex_index"].into_iter().find(|n| {
            matches!(f.properties.get(*n), Some(p) if matches!(p.data_type, PropertyType::List(..)))
        })
    })
}

/// The vertices' positions, each checked finite (the error names the vertex).
fn finite_positions(path: &Path, vertices: &[PlyRecord]) -> Result<Vec<Vec3>> {
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
    Ok(positions)
}

/// The header's `vertex` element must exist with scalar `x y z`.
pub(crate) fn check_header(path: &Path, header: &ply_rs::ply::Header) -> Result<()> {
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
pub(crate) fn header_error(path: &Path, bytes: &[u8], e: &std::io::Error) -> Error {
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
pub(crate) fn excerpt(line: &str) -> String {
    let t = line.trim_end_matches(['\r', '\n']);
    if t.chars().count() > 60 {
        format!("{}…", t.chars().take(60).collect::<String>())
    } else {
        t.to_string()
    }
}

/// Reads a PLY payload one record at a time, keeping the line count (ASCII).
pub(crate) struct RecordReader<'a> {
    pub(crate) path: &'a Path,
    pub(crate) parser: &'a Parser<PlyRecord>,
    pub(crate) encoding: ply_rs::ply::Encoding,
    pub(crate) reader: std::io::Cursor<&'a [u8]>,
    /// Lines consumed so far (ASCII).
    pub(crate) line: usize,
}

impl RecordReader<'_> {
    /// Reads every record of `def`, pushing them to `keep` when given.
    pub(crate) fn element(
        &mut self,
        def: &ElementDef,
        mut keep: Option<&mut Vec<PlyRecord>>,
    ) -> Result<()> {
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

    pub(crate) fn ended(&self, def: &ElementDef, k: usize) -> Error {
        Error::format(
            self.path,
            format!("`{}` element", def.name),
            format!(
                "expected {} records as the header announces, found {k}: the file ends early (truncated?)",
                def.count
            ),
        )
    }

    pub(crate) fn bad_line(&self, def: &ElementDef, k: usize, line: &str) -> Error {
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

    pub(crate) fn bad_record(
        &self,
        def: &ElementDef,
        k: usize,
        at: u64,
        e: &std::io::Error,
    ) -> Error {
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
pub(crate) fn property_list(def: &ElementDef) -> String {
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
