//! Binary glTF 2.0 (`.glb`) of a finished run: the mesh with per-vertex base colour and a
//! metallic-roughness material approximating the fitted BRDF mixture, for Blender and
//! three.js viewers.
//!
//! The fitted reflectance at vertex `x` is `ρ(x) = Σ_b β_b(x) ρ_b` (paper Eq. 11; every
//! `ρ_b` includes `cos θi`). glTF's core material is the metallic-roughness model, so the
//! mixture is approximated as follows:
//!
//! - **base colour** (`COLOR_0`, linear RGB) = the Lambertian weight `β_lambert(x)`, the
//!   diffuse albedo, divided by its largest channel value over the mesh (the scale of Eq. 9
//!   is not observable, the same convention as `mesh.ply`);
//! - **roughness**: each glossy lobe has a GGX width `α_b` (GGX lobes their own; a Phong
//!   lobe of exponent `N` the width of equal Beckmann/GGX sharpness,
//!   `α ≈ sqrt(2 / (N + 2))`, Walter et al. 2007, Eq. 33 solved for `α`). The vertex's `α` is
//!   the average of its glossy lobes' `α_b` weighted by their mean-channel weights
//!   `β̄_b(x)`, and glTF's roughness is `r = sqrt(α)` (glTF squares roughness into `α`). A
//!   vertex without glossy weight gets `r = 1`. Per-vertex `r` is written as the
//!   application attribute `_ROUGHNESS`; since core glTF has no per-vertex roughness, faces
//!   are grouped by their vertices' mean `r` into [`ROUGHNESS_LEVELS`] levels, one primitive
//!   and one material (`roughnessFactor` = the level's centre) per level used;
//! - **metallic** = 0: the basis lobes are dielectric-like (white highlights, colour in
//!   the diffuse term). glTF's fixed specular reflectance (F0 = 0.04) does not carry the
//!   fitted glossy strength `Σ_glossy β̄_b`; that is left to the per-vertex data.
//!
//! Frame: positions and normals are expressed in the run's environment frame
//! (`materials.json` → `env_frame`, `e_z` up), centred on the mesh's bounding box, then
//! mapped to glTF's Y-up axes as `(x, y, z)_gltf = (e_x, e_z, −e_y)`. Blender's importer maps
//! glTF back to Z-up as `(x, −z, y)`, so in Blender the object sits in the environment frame
//! itself, and an environment map exported in Blender's convention
//! ([`crate::export::envmap`]) lights it as the run's maps did.

use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result, Vec3};
use gltf::json;
use json::validation::{Checked, USize64};
use nalgebra::Matrix3;
use std::borrow::Cow;
use std::collections::BTreeMap;

/// Roughness levels the faces are grouped into (one material each).
pub const ROUGHNESS_LEVELS: usize = 8;

/// GGX width `α` of a basis lobe; `None` for the Lambertian lobe. Phong exponent `N` maps to
/// `α = sqrt(2 / (N + 2))` (see the module docs).
pub fn lobe_alpha(b: &BasisBrdf) -> Option<f64> {
    match b {
        BasisBrdf::Lambert => None,
        BasisBrdf::Phong { exponent } => Some((2.0 / (exponent + 2.0)).sqrt()),
        BasisBrdf::Ggx { alpha } => Some(*alpha),
    }
}

/// glTF roughness `r = sqrt(α)` of one vertex from its per-basis RGB weights `beta`
/// (one entry per lobe of `basis`): `α` is the glossy lobes' `α_b` averaged with weights
/// `mean_c β_{b,c}` (negative weights count as 0); 1 when no glossy lobe has weight.
pub fn vertex_roughness(basis: &[BasisBrdf], beta: &[[f64; 3]]) -> f32 {
    let (mut num, mut den) = (0.0, 0.0);
    for (b, w) in basis.iter().zip(beta) {
        if let Some(alpha) = lobe_alpha(b) {
            let wb = ((w[0] + w[1] + w[2]) / 3.0).max(0.0);
            if wb.is_finite() {
                num += wb * alpha;
                den += wb;
            }
        }
    }
    if den > 0.0 {
        ((num / den).sqrt() as f32).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// The roughness level `0..ROUGHNESS_LEVELS` of a roughness in `[0, 1]`.
pub fn roughness_level(r: f32) -> usize {
    ((r.clamp(0.0, 1.0) * ROUGHNESS_LEVELS as f32) as usize).min(ROUGHNESS_LEVELS - 1)
}

/// The roughness factor of level `l`: the level's centre.
pub fn level_roughness(l: usize) -> f32 {
    (l as f32 + 0.5) / ROUGHNESS_LEVELS as f32
}

/// What goes into the `.glb`, in glTF's frame (module docs).
#[derive(Debug, Clone)]
pub struct GltfMesh {
    /// Positions, glTF axes.
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, glTF axes.
    pub normals: Vec<[f32; 3]>,
    /// Linear base colour in `[0, 1]`.
    pub colors: Vec<[f32; 3]>,
    /// Per-vertex glTF roughness in `[0, 1]`.
    pub roughness: Vec<f32>,
    /// Counter-clockwise triangles.
    pub faces: Vec<[u32; 3]>,
}

/// What [`glb_bytes`] wrote.
#[derive(Debug, Clone)]
pub struct GltfSummary {
    /// Vertices in the file.
    pub vertices: usize,
    /// Triangles in the file.
    pub triangles: usize,
    /// `(roughness factor, triangles)` per material, in level order.
    pub materials: Vec<(f32, usize)>,
    /// Bytes written.
    pub bytes: usize,
}

/// `(x, y, z)_gltf = (e_x, e_z, −e_y)` for a vector in environment coordinates.
fn gltf_from_env(v: &Vec3) -> [f32; 3] {
    [v.x as f32, v.z as f32, -v.y as f32]
}

/// Build the glTF mesh of a result: world positions and environment-frame normals, faces,
/// the basis and `β` (`basis.len()` RGB weights per vertex, vertex-major).
pub fn gltf_mesh(
    positions_world: &[Vec3],
    normals_env: &[Vec3],
    faces: &[[u32; 3]],
    env_from_world: &Matrix3<f64>,
    basis: &[BasisBrdf],
    beta: &[[f64; 3]],
) -> Result<GltfMesh> {
    let nv = positions_world.len();
    let nb = basis.len();
    if normals_env.len() != nv || beta.len() != nv * nb || nv == 0 {
        return Err(Error::Config(format!(
            "export: {nv} vertices, {} normals and {} β entries ({nb} per vertex expected)",
            normals_env.len(),
            beta.len()
        )));
    }
    let env: Vec<Vec3> = positions_world.iter().map(|p| env_from_world * p).collect();
    let (mut lo, mut hi) = (env[0], env[0]);
    for p in &env {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let centre = (lo + hi) / 2.0;
    let positions = env.iter().map(|p| gltf_from_env(&(p - centre))).collect();
    let normals = normals_env
        .iter()
        .map(|n| {
            let m = n.norm();
            if m.is_finite() && m > 0.0 {
                gltf_from_env(&(n / m))
            } else {
                [0.0, 1.0, 0.0]
            }
        })
        .collect();
    let lambert = basis.iter().position(|b| matches!(b, BasisBrdf::Lambert));
    let albedo: Vec<[f64; 3]> = (0..nv)
        .map(|x| lambert.map_or([1.0; 3], |l| beta[x * nb + l]))
        .collect();
    let max = albedo
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let scale = if max > 0.0 { 1.0 / max } else { 1.0 };
    let colors = albedo
        .iter()
        .map(|a| {
            a.map(|v| {
                if v.is_finite() {
                    (v * scale).clamp(0.0, 1.0) as f32
                } else {
                    0.0
                }
            })
        })
        .collect();
    let roughness = (0..nv)
        .map(|x| vertex_roughness(basis, &beta[x * nb..(x + 1) * nb]))
        .collect();
    Ok(GltfMesh {
        positions,
        normals,
        colors,
        roughness,
        faces: faces.to_vec(),
    })
}

/// Append `data` to `bin` as a new buffer view (4-byte aligned), returning its index.
fn push_view(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    data: &[u8],
    target: json::buffer::Target,
) -> json::Index<json::buffer::View> {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend_from_slice(data);
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(data.len()),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: Some(Checked::Valid(target)),
        extensions: None,
        extras: Default::default(),
    })
}

/// One accessor over a whole view.
fn push_accessor(
    root: &mut json::Root,
    view: json::Index<json::buffer::View>,
    count: usize,
    component: json::accessor::ComponentType,
    type_: json::accessor::Type,
    min_max: Option<(serde_json::Value, serde_json::Value)>,
) -> json::Index<json::Accessor> {
    let (min, max) = match min_max {
        Some((a, b)) => (Some(a), Some(b)),
        None => (None, None),
    };
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
        extensions: None,
        extras: Default::default(),
        type_: Checked::Valid(type_),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    })
}

fn f32_bytes(v: impl Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(f32::to_le_bytes).collect()
}

/// Serialise `mesh` as GLB bytes (module docs), `name` naming the mesh and node: the
/// vertex attributes, one primitive per roughness level, the scene, then the GLB chunks.
pub fn glb_bytes(mesh: &GltfMesh, name: &str) -> Result<(Vec<u8>, GltfSummary)> {
    check_mesh(mesh)?;
    let mut root = json::Root {
        asset: json::Asset {
            copyright: None,
            extensions: None,
            extras: Default::default(),
            generator: Some(format!("relight-cpc {}", env!("CARGO_PKG_VERSION"))),
            min_version: None,
            version: "2.0".into(),
        },
        ..Default::default()
    };
    let mut bin = Vec::new();
    let attributes = vertex_attributes(&mut root, &mut bin, mesh);
    let (primitives, materials) = roughness_primitives(&mut root, &mut bin, mesh, &attributes);
    let bytes = glb_of(root, bin, name, primitives)?;
    let summary = GltfSummary {
        vertices: mesh.positions.len(),
        triangles: mesh.faces.len(),
        materials,
        bytes: bytes.len(),
    };
    Ok((bytes, summary))
}

/// Every per-vertex array has one entry per vertex, every face indexes a vertex.
fn check_mesh(mesh: &GltfMesh) -> Result<()> {
    let nv = mesh.positions.len();
    if mesh.normals.len() != nv || mesh.colors.len() != nv || mesh.roughness.len() != nv {
        return Err(Error::Config(
            "export: per-vertex arrays of different lengths".into(),
        ));
    }
    if let Some(f) = mesh
        .faces
        .iter()
        .find(|f| f.iter().any(|&i| i as usize >= nv))
    {
        return Err(Error::Config(format!(
            "export: face {f:?} indexes past the {nv} vertices"
        )));
    }
    Ok(())
}

/// The vertex attributes' views and accessors (position with its bounds, normal, colour
/// and the `_ROUGHNESS` extra), shared by every primitive.
fn vertex_attributes(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    mesh: &GltfMesh,
) -> BTreeMap<Checked<json::mesh::Semantic>, json::Index<json::Accessor>> {
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;
    let nv = mesh.positions.len();
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &mesh.positions {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let flat3 = |v: &[[f32; 3]]| f32_bytes(v.iter().flatten().copied());
    let v = push_view(root, bin, &flat3(&mesh.positions), Target::ArrayBuffer);
    let position = push_accessor(
        root,
        v,
        nv,
        ComponentType::F32,
        Type::Vec3,
        Some((serde_json::json!(lo), serde_json::json!(hi))),
    );
    let v = push_view(root, bin, &flat3(&mesh.normals), Target::ArrayBuffer);
    let normal = push_accessor(root, v, nv, ComponentType::F32, Type::Vec3, None);
    let v = push_view(root, bin, &flat3(&mesh.colors), Target::ArrayBuffer);
    let color = push_accessor(root, v, nv, ComponentType::F32, Type::Vec3, None);
    let v = push_view(
        root,
        bin,
        &f32_bytes(mesh.roughness.iter().copied()),
        Target::ArrayBuffer,
    );
    let rough = push_accessor(root, v, nv, ComponentType::F32, Type::Scalar, None);
    [
        (json::mesh::Semantic::Positions, position),
        (json::mesh::Semantic::Normals, normal),
        (json::mesh::Semantic::Colors(0), color),
        (json::mesh::Semantic::Extras("ROUGHNESS".into()), rough),
    ]
    .into_iter()
    .map(|(k, v)| (Checked::Valid(k), v))
    .collect()
}

/// Faces grouped by the roughness level of their vertices' mean: one primitive and one
/// material per level that has faces; each material's roughness and triangle count.
fn roughness_primitives(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    mesh: &GltfMesh,
    attributes: &BTreeMap<Checked<json::mesh::Semantic>, json::Index<json::Accessor>>,
) -> (Vec<json::mesh::Primitive>, Vec<(f32, usize)>) {
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;
    let mut levels: Vec<Vec<u32>> = vec![Vec::new(); ROUGHNESS_LEVELS];
    for f in &mesh.faces {
        let r = f.iter().map(|&i| mesh.roughness[i as usize]).sum::<f32>() / 3.0;
        levels[roughness_level(r)].extend_from_slice(f);
    }
    let mut primitives = Vec::new();
    let mut materials = Vec::new();
    for (l, idx) in levels.iter().enumerate().filter(|(_, i)| !i.is_empty()) {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let v = push_view(root, bin, &bytes, Target::ElementArrayBuffer);
        let indices = push_accessor(root, v, idx.len(), ComponentType::U32, Type::Scalar, None);
        let roughness = level_roughness(l);
        let material = root.push(json::Material {
            name: Some(format!("roughness {roughness:.3}")),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([1.0; 4]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(roughness),
                ..Default::default()
            },
            ..Default::default()
        });
        materials.push((roughness, idx.len() / 3));
        primitives.push(json::mesh::Primitive {
            attributes: attributes.clone(),
            extensions: None,
            extras: Default::default(),
            indices: Some(indices),
            material: Some(material),
            mode: Checked::Valid(json::mesh::Mode::Triangles),
            targets: None,
        });
    }
    (primitives, materials)
}

/// The buffer (padded to 4 bytes), the mesh, its node and the scene, then the GLB's JSON
/// and BIN chunks.
fn glb_of(
    mut root: json::Root,
    mut bin: Vec<u8>,
    name: &str,
    primitives: Vec<json::mesh::Primitive>,
) -> Result<Vec<u8>> {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let gmesh = root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some(name.to_string()),
        primitives,
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(gmesh),
        name: Some(name.to_string()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some(name.to_string()),
        nodes: vec![node],
    });
    root.scene = Some(scene);
    let text = root
        .to_vec()
        .map_err(|e| Error::Config(format!("export: glTF JSON: {e}")))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // computed by to_vec
        },
        json: Cow::Owned(text),
        bin: Some(Cow::Owned(bin)),
    };
    glb.to_vec()
        .map_err(|e| Error::Config(format!("export: GLB: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Phong exponent N and GGX α = sqrt(2/(N+2)) are the same lobe width by construction:
    /// the map is checked at N = 0 (α = 1) and N = 198 (α = 0.1), exact to f64 rounding.
    #[test]
    fn phong_alpha_equivalence() {
        assert!((lobe_alpha(&BasisBrdf::Phong { exponent: 0.0 }).unwrap() - 1.0).abs() < 1e-15);
        assert!((lobe_alpha(&BasisBrdf::Phong { exponent: 198.0 }).unwrap() - 0.1).abs() < 1e-15);
        assert_eq!(lobe_alpha(&BasisBrdf::Lambert), None);
    }

    /// Two glossy lobes of equal weight average their α; the Lambertian weight does not
    /// count; no glossy weight gives roughness 1.
    #[test]
    fn roughness_is_sqrt_of_weighted_alpha() {
        let basis = [
            BasisBrdf::Lambert,
            BasisBrdf::Ggx { alpha: 0.04 },
            BasisBrdf::Ggx { alpha: 0.16 },
        ];
        let r = vertex_roughness(&basis, &[[9.0; 3], [1.0; 3], [1.0; 3]]);
        assert!((r - 0.1f32.sqrt()).abs() < 1e-6, "{r}");
        assert_eq!(
            vertex_roughness(&basis, &[[1.0; 3], [0.0; 3], [0.0; 3]]),
            1.0
        );
        assert_eq!(roughness_level(0.0), 0);
        assert_eq!(roughness_level(1.0), ROUGHNESS_LEVELS - 1);
    }

    /// A GLB of one triangle parses back with the gltf crate's own reader: header length,
    /// chunk layout and the JSON's accessor counts agree with what was put in.
    #[test]
    fn glb_round_trips_through_the_gltf_reader() {
        let mesh = GltfMesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            colors: vec![[1.0, 0.5, 0.25]; 3],
            roughness: vec![0.3; 3],
            faces: vec![[0, 1, 2]],
        };
        let (bytes, summary) = glb_bytes(&mesh, "tri").unwrap();
        assert_eq!(summary.bytes, bytes.len());
        let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
        assert_eq!(glb.header.length as usize, bytes.len());
        let root = json::Root::from_slice(&glb.json).unwrap();
        assert_eq!(root.accessors[0].count.0, 3);
        assert_eq!(root.materials.len(), 1);
        let m = &root.materials[0].pbr_metallic_roughness;
        assert_eq!(m.metallic_factor.0, 0.0);
        assert_eq!(m.roughness_factor.0, level_roughness(roughness_level(0.3)));
        let bin = glb.bin.unwrap();
        assert_eq!(root.buffers[0].byte_length.0 as usize, bin.len());
    }
}
