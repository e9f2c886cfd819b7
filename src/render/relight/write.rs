//! Writing the render state of a run (`model/`, `relight.json`, `relight.bin`; format in
//! the module docs of [`crate::render::relight`]), called by `run`.

use super::*;

fn put_f64s(w: &mut impl Write, v: impl Iterator<Item = f64>) -> std::io::Result<()> {
    for x in v {
        w.write_all(&x.to_le_bytes())?;
    }
    Ok(())
}

/// What `run` hands [`write_render_state`]: the fitted model's parts a render needs.
pub struct RenderState<'a> {
    /// The registered views the run used (cameras and poses are written, 2D points not).
    pub views: &'a [View],
    /// The cleaned mesh.
    pub mesh: &'a Mesh,
    /// The basis BRDFs.
    pub basis: &'a [BasisBrdf],
    /// `β`: `B` RGB weights per vertex, vertex-major.
    pub beta: &'a [[f64; 3]],
    /// Unit vertex normals in the environment frame.
    pub normals_env: &'a [Vec3],
    /// Rows `e_x, e_y, e_z` in world coordinates.
    pub env_from_world: Matrix3<f64>,
    /// Visibility at the render local resolution.
    pub render_vis: &'a Visibility,
    /// Global (light) octahedral side.
    pub global_resolution: usize,
    /// The estimator's local (hemisphere) side.
    pub local_resolution: usize,
    /// Normal grid side of the rotation.
    pub normal_grid: usize,
    /// The run's seed.
    pub seed: u64,
}

/// Write `model/`, `relight.json` and `relight.bin` for the fitted run (see module docs).
pub fn write_render_state(f: &RenderState, dir: &Path) -> Result<()> {
    let model = dir.join("model");
    std::fs::create_dir_all(&model).map_err(|e| Error::io(&model, e))?;
    let mut cameras = BTreeMap::new();
    let mut images = BTreeMap::new();
    for v in f.views {
        cameras.insert(v.camera.id, v.camera.clone());
        let mut im = v.image.clone();
        im.points2d.clear();
        images.insert(im.id, im);
    }
    write_with(&model.join("cameras.txt"), |w| {
        text::write_cameras(w, &cameras)
    })?;
    write_with(&model.join("images.txt"), |w| {
        text::write_images(w, &images)
    })?;

    let m = f.env_from_world;
    let meta = serde_json::json!({
        "format": "relight.bin: magic RCPCREL1, u64 nv nf nb texels, f64 positions[nv][3], f64 normals_env[nv][3], u32 faces[nf][3], f64 beta[nv][nb][3], u8 vis[nv][texels], u8 open[nv] (little-endian)",
        "basis": f.basis.iter().map(|b| b.label()).collect::<Vec<_>>(),
        "global_resolution": f.global_resolution,
        "local_resolution": f.local_resolution,
        "render_local_resolution": f.render_vis.n_local,
        "normal_grid": f.normal_grid,
        "rays_per_texel": f.render_vis.rays_per_texel,
        "seed": f.seed,
        "env_from_world": [[m[(0,0)], m[(0,1)], m[(0,2)]], [m[(1,0)], m[(1,1)], m[(1,2)]], [m[(2,0)], m[(2,1)], m[(2,2)]]],
    });
    let text = serde_json::to_string_pretty(&meta).map_err(|e| Error::Internal(e.to_string()))?;
    let jp = dir.join("relight.json");
    std::fs::write(&jp, text).map_err(|e| Error::io(&jp, e))?;

    let mesh = f.mesh;
    let nv = mesh.positions.len();
    let vis = f.render_vis;
    let t = vis.texels();
    write_with(&dir.join("relight.bin"), |w| {
        w.write_all(MAGIC)?;
        for n in [nv, mesh.faces.len(), f.basis.len(), t] {
            w.write_all(&(n as u64).to_le_bytes())?;
        }
        put_f64s(w, mesh.positions.iter().flat_map(|p| [p.x, p.y, p.z]))?;
        put_f64s(w, f.normals_env.iter().flat_map(|p| [p.x, p.y, p.z]))?;
        for face in &mesh.faces {
            for i in face {
                w.write_all(&i.to_le_bytes())?;
            }
        }
        put_f64s(w, f.beta.iter().flat_map(|b| *b))?;
        w.write_all(&vis.frac)?;
        let open: Vec<u8> = vis.open.iter().map(|&o| o as u8).collect();
        w.write_all(&open)
    })
}

fn write_with(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = BufWriter::new(file);
    body(&mut w)
        .and_then(|_| w.flush())
        .map_err(|e| Error::io(path, e))
}
