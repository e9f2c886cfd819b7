//! Loading a finished run's result folder for rendering (`model/`, `relight.json`, `relight.bin`; format in [`crate::render::relight`]'s module docs).

use super::*;

/// Everything a result folder holds for rendering.
pub struct ResultModel {
    /// The cleaned mesh the run used (positions, world normals, faces).
    pub mesh: Mesh,
    /// Unit vertex normals in the environment frame.
    pub normals_env: Vec<Vec3>,
    /// Per-vertex visibility at the render local resolution (as the run computed it).
    pub vis: Visibility,
    /// The basis BRDFs.
    pub basis: Vec<BasisBrdf>,
    /// `β`: `B` RGB weights per vertex, vertex-major.
    pub beta: Vec<[f64; 3]>,
    /// Rows `e_x, e_y, e_z` in world coordinates.
    pub env_from_world: Matrix3<f64>,
    /// Global (light) octahedral side.
    pub n_global: usize,
    /// The estimator's local (hemisphere) side.
    pub n_local: usize,
    /// The renderer's local side: that of the stored visibility rows.
    pub n_render_local: usize,
    /// Normal grid side of the rotation.
    pub normal_grid: usize,
    /// The registered cameras.
    pub cameras: BTreeMap<CameraId, Camera>,
    /// The registered images.
    pub images: BTreeMap<ImageId, Image>,
}

// ---------------------------------------------------------------------------------------
// Loading.

pub(crate) fn missing(dir: &Path, what: &str) -> Error {
    Error::Workspace {
        path: dir.to_path_buf(),
        message: format!("not a relight-cpc result folder: {what} (written by `relight-cpc run`)"),
    }
}

pub(crate) fn json_usize(path: &Path, v: &serde_json::Value, key: &str) -> Result<usize> {
    v.get(key)
        .and_then(|x| x.as_u64())
        .map(|x| x as usize)
        .ok_or_else(|| Error::format(path, key, "missing or not a non-negative integer"))
}

pub(crate) struct Cursor<'a> {
    pub(crate) path: &'a Path,
    pub(crate) data: &'a [u8],
    pub(crate) at: usize,
}

impl Cursor<'_> {
    pub(crate) fn take(&mut self, n: usize, what: &str) -> Result<&[u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(Error::format(
                self.path,
                what,
                format!(
                    "file ends at byte {} but {n} more bytes were expected",
                    self.data.len()
                ),
            ));
        };
        let s = &self.data[self.at..end];
        self.at = end;
        Ok(s)
    }
    pub(crate) fn u64(&mut self, what: &str) -> Result<u64> {
        let b = self.take(8, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    pub(crate) fn f64s(&mut self, n: usize, what: &str) -> Result<Vec<f64>> {
        let bytes = n
            .checked_mul(8)
            .ok_or_else(|| Error::format(self.path, what, "count overflows"))?;
        let b = self.take(bytes, what)?;
        let v: Vec<f64> = b
            .chunks_exact(8)
            .map(|c| {
                let mut a = [0u8; 8];
                a.copy_from_slice(c);
                f64::from_le_bytes(a)
            })
            .collect();
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::format(
                self.path,
                format!("{what}[{i}]"),
                "not a finite number",
            ));
        }
        Ok(v)
    }
}

/// Load what [`render_result`] needs from a result folder `dir` (see the module docs), and
/// build the rotation matrices (`R_ν` for the run's normal grid).
///
/// Errors: [`Error::Workspace`] when `dir` or one of its files is missing, [`Error::Format`]
/// (naming the file and the part) when a file is malformed.
pub fn load_result(dir: &Path) -> Result<ResultModel> {
    check_result_files(dir)?;
    let meta = read_meta(&dir.join("relight.json"))?;
    let arrays = read_arrays(&dir.join("relight.bin"), &meta)?;
    let world_from_env = meta.env_from_world.transpose();
    let normals = arrays
        .normals_env
        .iter()
        .map(|n| world_from_env * n)
        .collect();
    let mesh = Mesh {
        positions: arrays.positions,
        normals,
        faces: arrays.faces,
        colors: None,
    };
    let vis = Visibility {
        n_local: meta.n_render_local,
        rays_per_texel: meta.rays_per_texel,
        frac: arrays.frac,
        open: arrays.open,
        degenerate: 0,
        rays_traced: 0,
        rays_known_open: 0,
    };
    let model = dir.join("model");
    let read = |name: &str| -> Result<BufReader<std::fs::File>> {
        let p = model.join(name);
        std::fs::File::open(&p)
            .map(BufReader::new)
            .map_err(|e| Error::io(&p, e))
    };
    let cameras = text::read_cameras(read("cameras.txt")?, &model.join("cameras.txt"))?;
    let images = text::read_images(read("images.txt")?, &model.join("images.txt"))?;
    Ok(ResultModel {
        mesh,
        normals_env: arrays.normals_env,
        vis,
        basis: meta.basis,
        beta: arrays.beta,
        env_from_world: meta.env_from_world,
        n_global: meta.n_global,
        n_local: meta.n_local,
        n_render_local: meta.n_render_local,
        normal_grid: meta.normal_grid,
        cameras,
        images,
    })
}

/// The result folder and the four files `render` reads exist.
fn check_result_files(dir: &Path) -> Result<()> {
    if !dir.is_dir() {
        return Err(Error::Workspace {
            path: dir.to_path_buf(),
            message: "no such result folder".into(),
        });
    }
    let model = dir.join("model");
    for (p, w) in [
        (&dir.join("relight.json"), "relight.json is missing"),
        (&dir.join("relight.bin"), "relight.bin is missing"),
        (&model.join("cameras.txt"), "model/cameras.txt is missing"),
        (&model.join("images.txt"), "model/images.txt is missing"),
    ] {
        if !p.is_file() {
            return Err(missing(dir, w));
        }
    }
    Ok(())
}

/// What `relight.json` holds: the basis, the resolutions and the environment frame.
struct Meta {
    basis: Vec<BasisBrdf>,
    n_global: usize,
    n_local: usize,
    n_render_local: usize,
    normal_grid: usize,
    rays_per_texel: usize,
    env_from_world: Matrix3<f64>,
}

/// `relight.json` read and checked (each resolution a power of two in [2, 1024], the frame
/// a rotation).
fn read_meta(jp: &Path) -> Result<Meta> {
    let text = std::fs::read_to_string(jp).map_err(|e| Error::io(jp, e))?;
    let meta: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| Error::format(jp, format!("line {}", e.line()), e.to_string()))?;
    let basis = meta
        .get("basis")
        .and_then(|b| b.as_array())
        .ok_or_else(|| Error::format(jp, "basis", "missing or not a list"))?
        .iter()
        .map(|b| {
            b.as_str()
                .ok_or_else(|| Error::format(jp, "basis", "entry is not a string"))
                .and_then(BasisBrdf::parse)
        })
        .collect::<Result<Vec<_>>>()?;
    let n_global = json_usize(jp, &meta, "global_resolution")?;
    let n_local = json_usize(jp, &meta, "local_resolution")?;
    let normal_grid = json_usize(jp, &meta, "normal_grid")?;
    let rays_per_texel = json_usize(jp, &meta, "rays_per_texel")?;
    let n_render_local = match meta.get("render_local_resolution") {
        Some(_) => json_usize(jp, &meta, "render_local_resolution")?,
        None => n_local,
    };
    for (k, n) in [
        ("global_resolution", n_global),
        ("local_resolution", n_local),
        ("render_local_resolution", n_render_local),
        ("normal_grid", normal_grid),
    ] {
        if !(n.is_power_of_two() && (2..=1024).contains(&n)) {
            return Err(Error::format(jp, k, "not a power of two in [2, 1024]"));
        }
    }
    Ok(Meta {
        basis,
        n_global,
        n_local,
        n_render_local,
        normal_grid,
        rays_per_texel,
        env_from_world: read_env_frame(jp, &meta)?,
    })
}

/// `env_from_world`: 3 rows of 3 finite numbers forming a rotation (to 1e-6).
fn read_env_frame(jp: &Path, meta: &serde_json::Value) -> Result<Matrix3<f64>> {
    let rows = meta
        .get("env_from_world")
        .and_then(|r| r.as_array())
        .filter(|r| r.len() == 3)
        .ok_or_else(|| Error::format(jp, "env_from_world", "expected 3 rows"))?;
    let mut env_from_world = Matrix3::zeros();
    for (i, row) in rows.iter().enumerate() {
        let row = row
            .as_array()
            .filter(|r| r.len() == 3)
            .ok_or_else(|| Error::format(jp, "env_from_world", "expected 3 numbers per row"))?;
        for (j, x) in row.iter().enumerate() {
            env_from_world[(i, j)] = x
                .as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| Error::format(jp, "env_from_world", "not a finite number"))?;
        }
    }
    if (env_from_world * env_from_world.transpose() - Matrix3::identity())
        .abs()
        .max()
        > 1e-6
    {
        return Err(Error::format(jp, "env_from_world", "not a rotation"));
    }
    Ok(env_from_world)
}

/// What `relight.bin` holds: the mesh in the environment frame, `β` and the visibility.
struct Arrays {
    positions: Vec<Vec3>,
    normals_env: Vec<Vec3>,
    faces: Vec<[u32; 3]>,
    beta: Vec<[f64; 3]>,
    frac: Vec<u8>,
    open: Vec<bool>,
}

/// `relight.bin` read (module docs: its layout), its header checked against `meta`.
fn read_arrays(bp: &Path, meta: &Meta) -> Result<Arrays> {
    let data = std::fs::read(bp).map_err(|e| Error::io(bp, e))?;
    let mut c = Cursor {
        path: bp,
        data: &data,
        at: 0,
    };
    if c.take(8, "magic")? != MAGIC {
        return Err(Error::format(bp, "magic", "not a relight.bin file"));
    }
    let nv = c.u64("header")? as usize;
    let nf = c.u64("header")? as usize;
    let nb = c.u64("header")? as usize;
    let t = c.u64("header")? as usize;
    if nb != meta.basis.len() || t != meta.n_render_local * meta.n_render_local {
        return Err(Error::format(
            bp,
            "header",
            format!(
                "{nb} basis BRDFs and {t} texels, but relight.json says {} and {}²",
                meta.basis.len(),
                meta.n_render_local
            ),
        ));
    }
    let to_vec = |v: Vec<f64>| -> Vec<Vec3> {
        v.chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    };
    let positions = to_vec(c.f64s(nv.saturating_mul(3), "positions")?);
    let normals_env = to_vec(c.f64s(nv.saturating_mul(3), "normals")?);
    let faces = read_faces(&mut c, nf, nv)?;
    let beta: Vec<[f64; 3]> = c
        .f64s(nv.saturating_mul(nb).saturating_mul(3), "beta")?
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let frac = c.take(nv.saturating_mul(t), "visibility")?.to_vec();
    let open: Vec<bool> = c.take(nv, "open")?.iter().map(|&o| o != 0).collect();
    if c.at != data.len() {
        return Err(Error::format(bp, "end", "trailing bytes after the data"));
    }
    Ok(Arrays {
        positions,
        normals_env,
        faces,
        beta,
        frac,
        open,
    })
}

/// `nf` faces of three little-endian `u32` vertex indices, each below `nv`.
fn read_faces(c: &mut Cursor, nf: usize, nv: usize) -> Result<Vec<[u32; 3]>> {
    let fb = c.take(nf.saturating_mul(12), "faces")?;
    let mut faces = Vec::with_capacity(nf);
    for (k, ch) in fb.chunks_exact(12).enumerate() {
        let mut f = [0u32; 3];
        for (i, x) in f.iter_mut().enumerate() {
            let mut a = [0u8; 4];
            a.copy_from_slice(&ch[4 * i..4 * i + 4]);
            *x = u32::from_le_bytes(a);
            if *x as usize >= nv {
                return Err(Error::format(
                    c.path,
                    format!("face {k}"),
                    format!("vertex index {x} out of range ({nv} vertices)"),
                ));
            }
        }
        faces.push(f);
    }
    Ok(faces)
}
