//! The files a run leaves behind (besides the report):
//! - `envmaps/NAME.latlong.exr` (lat-long, docs/conventions.md: sky up, width 2H) and
//!   `envmaps/NAME.oct.exr` (the solver's own octahedral texels) per training photo;
//! - `materials.json`: the basis BRDFs with their formulas, `λ[k][b][c]`, the scale
//!   normalisation, the environment frame;
//! - `mesh.ply`: the mesh with per-vertex diffuse albedo as colour (sRGB 8-bit, the
//!   Lambertian `β`), the linear albedo and the blending weights `w0 … w{K-1}` as floats;
//! - `renders/NAME.png` for training views: photo | render | difference (×4), the render
//!   under the photo's fitted light.

use super::shading::{fitted_env, render_training_view, write_triptych};
use super::Fitted;
use crate::render::relight::{write_render_state, RenderState};
use crate::sphere::envmap::LatLong;
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result};
use std::path::Path;

fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| Error::Internal(e.to_string()))?;
    std::fs::write(path, text).map_err(|e| Error::io(path, e))
}

/// The formula of a basis lobe, in words (the same as `brdf`'s module docs).
fn formula(b: &BasisBrdf) -> String {
    match b {
        BasisBrdf::Lambert => "cos θi / π".into(),
        BasisBrdf::Phong { exponent } => {
            format!("({exponent}+2)/(2π) · max(0, r·ωi)^{exponent} · cos θi, r = 2(n·ωo)n − ωo")
        }
        BasisBrdf::Ggx { alpha } => format!(
            "D(h) G1(ωi) G1(ωo) / (4 cos θo), GGX α = {alpha}, separable Smith G1, Fresnel 1"
        ),
    }
}

/// Lat-long versions of the fitted maps for the report's gallery (training photos).
pub(crate) fn gallery_maps(f: &Fitted) -> Vec<(String, LatLong)> {
    f.train
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            (
                f.scene.views[v].image.name.clone(),
                fitted_env(f, k).to_latlong(64),
            )
        })
        .collect()
}

/// Write environment maps, materials, the coloured mesh, the relighting state and the
/// training renders.
pub(crate) fn write_results(f: &Fitted, dir: &Path, progress: &super::Progress) -> Result<()> {
    write_envmaps(f, dir)?;
    write_materials(f, dir)?;
    write_mesh(f, dir)?;
    let state = RenderState {
        views: &f.scene.views,
        mesh: &f.scene.mesh,
        basis: &f.basis,
        beta: &f.beta,
        normals_env: &f.normals_env,
        env_from_world: f.env_from_world,
        render_vis: &f.render_vis,
        global_resolution: f.opts.global_resolution,
        local_resolution: f.opts.local_resolution,
        normal_grid: f.opts.normal_grid,
        seed: f.opts.seed,
    };
    write_render_state(&state, dir)?;
    if f.opts.render_training {
        write_training_renders(f, dir, progress)?;
    }
    Ok(())
}

/// `envmaps/STEM.oct.exr` (the solver's octahedral texels) and `envmaps/STEM.latlong.exr`
/// per training photo.
fn write_envmaps(f: &Fitted, dir: &Path) -> Result<()> {
    let env_dir = dir.join("envmaps");
    std::fs::create_dir_all(&env_dir).map_err(|e| Error::io(&env_dir, e))?;
    let height = (2 * f.opts.global_resolution).clamp(32, 512);
    for (k, &v) in f.train.iter().enumerate() {
        let stem = crate::render::views::file_stem(&f.scene.views[v].image.name);
        let env = fitted_env(f, k);
        env.write_exr(&env_dir.join(format!("{stem}.oct.exr")))?;
        env.to_latlong(height)
            .write_exr(&env_dir.join(format!("{stem}.latlong.exr")))?;
    }
    Ok(())
}

/// `materials.json`: the basis with formulas, `λ`, the scale normalisation, the
/// environment frame, the resolutions and the training photos.
fn write_materials(f: &Fitted, dir: &Path) -> Result<()> {
    let frame = f.env_from_world;
    let materials = serde_json::json!({
        "model": "ρ(x) = Σ_k w_k(x) Σ_b λ[k][b][c] ρ_b (paper Eq. 11); every ρ_b includes cos θi",
        "basis": f.basis.iter().map(|b| serde_json::json!({"label": b.label(), "formula": formula(b)})).collect::<Vec<_>>(),
        "lambda": f.est.lambda,
        "normalisation": f.est.normalisation,
        "env_frame": {
            "description": "rows e_x, e_y, e_z in world coordinates; environment maps are indexed by directions in this frame (docs/conventions.md)",
            "rows": [[frame[(0,0)], frame[(0,1)], frame[(0,2)]], [frame[(1,0)], frame[(1,1)], frame[(1,2)]], [frame[(2,0)], frame[(2,1)], frame[(2,2)]]],
        },
        "resolutions": {"global": f.opts.global_resolution, "local": f.opts.local_resolution, "normal_grid": f.opts.normal_grid, "kept_coefficients": f.opts.keep},
        "photos": f.train.iter().map(|&v| f.scene.views[v].image.name.clone()).collect::<Vec<_>>(),
    });
    write_json(&dir.join("materials.json"), &materials)
}

/// `mesh.ply`: the diffuse albedo (the Lambertian `β`) as sRGB colour and as floats, and
/// the blending weights `w0 … w{K-1}`.
fn write_mesh(f: &Fitted, dir: &Path) -> Result<()> {
    let nv = f.scene.mesh.positions.len();
    let nb = f.basis.len();
    let kk = f.est.lambda.len();
    let lambert = f
        .basis
        .iter()
        .position(|b| matches!(b, BasisBrdf::Lambert))
        .unwrap_or(0);
    let albedo: Vec<[f32; 3]> = (0..nv)
        .map(|x| f.beta[x * nb + lambert].map(|v| v as f32))
        .collect();
    let max_albedo = albedo
        .iter()
        .flat_map(|a| a.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0f32, f32::max)
        .max(1e-12);
    let mut mesh = f.scene.mesh.clone();
    mesh.colors = Some(
        albedo
            .iter()
            .map(|a| a.map(|v| crate::import::photo::linear_to_srgb(v / max_albedo)))
            .collect(),
    );
    let channels: Vec<Vec<f32>> = (0..3)
        .map(|c| albedo.iter().map(|a| a[c]).collect())
        .collect();
    let weights: Vec<Vec<f32>> = (0..kk)
        .map(|k| (0..nv).map(|x| f.est.weights[x * kk + k] as f32).collect())
        .collect();
    let names: Vec<String> = (0..kk).map(|k| format!("w{k}")).collect();
    let mut extra: Vec<(&str, &[f32])> = vec![
        ("albedo_r", &channels[0]),
        ("albedo_g", &channels[1]),
        ("albedo_b", &channels[2]),
    ];
    for (n, w) in names.iter().zip(&weights) {
        extra.push((n.as_str(), w.as_slice()));
    }
    mesh.write_ply(&dir.join("mesh.ply"), &extra)
}

/// `renders/STEM.png` per training photo: photo | render | difference.
fn write_training_renders(f: &Fitted, dir: &Path, progress: &super::Progress) -> Result<()> {
    // Training renders: the model as fitted (the estimator's predictions at the
    // observations, its visibility and rotation elsewhere), each photo under its own fitted
    // map.
    let renders = dir.join("renders");
    std::fs::create_dir_all(&renders).map_err(|e| Error::io(&renders, e))?;
    let bar = progress.bar(f.train.len() as u64, "training renders");
    for (k, &v) in f.train.iter().enumerate() {
        let r = render_training_view(f, k)?;
        let stem = crate::render::views::file_stem(&f.scene.views[v].image.name);
        write_triptych(
            &renders.join(format!("{stem}.png")),
            &f.photos[v],
            &r.raster,
            &r.rgb,
            1.0,
        )?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(())
}
