//! Shared by `tests/suite/estimate_synth.rs` and `benches/estimator.rs`: a known-truth scene made
//! by `synth` (photos rendered by the independent reference renderer), taken through the
//! real pipeline stages (workspace import, observations, visibility, rotation, transport)
//! into an estimation [`Problem`], together with the truth it was rendered from: the
//! materials `λ` (`truth/materials.json`), the blending weights (`truth/weights.ply`) and
//! every photo's light (`truth/env/*.exr` resampled on the octahedral grid, times the
//! photo's exposure and white balance, [`Truth::light`]).
//!
//! The environment frame is the truth's own (`manifest.json`), so the true maps need no
//! re-projection; the estimator never sees the truth unless a test hands it over
//! (`fixed_materials`).

#![allow(dead_code, clippy::needless_range_loop)]

use std::path::{Path, PathBuf};

use nalgebra::Matrix3;
use relight_cpc::import::scene;
use relight_cpc::import::workspace::Workspace;
use relight_cpc::observe::trace::SceneBvh;
use relight_cpc::observe::{self, Observations, ObserveOptions};
use relight_cpc::run::Truth;
use relight_cpc::solve::light::shared::LightGroups;
use relight_cpc::solve::light::sky::clock::ClockSuns;
use relight_cpc::solve::{
    beta_per_vertex, estimate, Estimate, EstimateOptions, Materials0, Problem,
};
use relight_cpc::sphere::rotation::{LocalRotation, Rotation, RotationForm, SplatRotation};
use relight_cpc::synth::{self, SynthOptions};
use relight_cpc::transport::brdf::BasisBrdf;
use relight_cpc::transport::reference::{Lobe, Samples};
use relight_cpc::transport::visibility::Visibility;
use relight_cpc::transport::{self, Transport, TransportOptions};
use relight_cpc::{sphere::haar, transport::visibility, Vec3};

/// A scratch folder removed on drop.
pub struct Scratch(pub PathBuf);
impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub fn scratch(tag: &str) -> Scratch {
    let p = std::env::temp_dir().join(format!("relight-estsynth-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&p);
    std::fs::create_dir_all(&p).unwrap();
    Scratch(p)
}

/// Sizes of a case.
#[derive(Debug, Clone, Copy)]
pub struct Sizes {
    pub width: u32,
    pub photos: Option<usize>,
    pub vertices: usize,
    pub spp: u32,
    pub light_samples: u32,
    pub global: usize,
    pub local: usize,
    pub normal_grid: usize,
    /// Kept Haar coefficients per transport row (0 = all).
    pub keep: usize,
    pub rays_per_texel: usize,
}

impl Sizes {
    /// The small Spot case of the estimator's synthetic tests: 64 px photos, 1,000 of the
    /// mesh's 2,930 vertices, 16² maps, 8² local maps, every coefficient kept.
    pub fn spot_small() -> Self {
        Sizes {
            width: 64,
            photos: None,
            vertices: 1_000,
            spp: 4,
            light_samples: 64,
            global: 16,
            local: 8,
            normal_grid: 16,
            keep: 0,
            rays_per_texel: 2,
        }
    }
}

/// One split's observations and transport.
pub struct Split {
    pub obs: Observations,
    pub transport: Transport,
    /// Per photo of the split (in its order), the true light's texels per channel.
    pub lights: Vec<[Vec<f64>; 3]>,
    /// The split's cameras, in its order (the photo halves `run --light auto` scores on).
    pub views: Vec<scene::View>,
    /// Per photo of the split, the texels its background pixels observe on the
    /// `global²` map ([`observe::background`]); empty unless the photos were rendered with
    /// `SYNTH_SKY_BACKGROUND=1`.
    pub background: observe::background::BackgroundLight,
}

impl Split {
    /// The split's photo names, in its order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.views.iter().map(|v| v.image.name.as_str())
    }

    pub fn problem(&self, nv: usize) -> Problem<'_> {
        Problem {
            obs: &self.obs,
            transport: &self.transport,
            n_vertices: nv,
            n_photos: self.obs.photo_ranges.len(),
        }
    }
}

/// A prepared known-truth case.
pub struct Case {
    pub scene: String,
    pub scratch: Scratch,
    pub basis: Vec<BasisBrdf>,
    pub nv: usize,
    /// Vertex positions, world frame (the cleaned mesh's).
    pub positions: Vec<Vec3>,
    pub train: Split,
    pub held: Split,
    /// `lambda[k][b][c]`, the truth.
    pub lambda: Vec<Vec<[f64; 3]>>,
    /// Row-major `V × K`, the truth.
    pub weights: Vec<f64>,
    pub sizes: Sizes,
    pub seconds_synth: f64,
    pub seconds_prepare: f64,
    /// Env-frame vertex normals, the world → environment rotation and the visibility at
    /// `sizes.local`: what `run` hands the adaptive pilot.
    pub normals_env: Vec<Vec3>,
    pub env_from_world: nalgebra::Matrix3<f64>,
    pub vis: Visibility,
    /// `truth/manifest.json`: each photo's map, rotation, exposure and white balance.
    pub truth: Truth,
    /// The training photos' suns read from their PNGs' geotags as `run` reads them
    /// (`None` unless the scene was rendered with `synth --geotag`).
    pub geotag_suns: Option<ClockSuns>,
}

impl Case {
    /// The training photos' groups under one true sky (`--light shared` as a user's groups
    /// file would give them): photos whose truth names the same map and rotation share a
    /// group. Their source reads "the true sky of each training photo".
    pub fn true_light_groups(&self) -> LightGroups {
        let labels: Vec<String> = self
            .train
            .names()
            .map(|name| {
                let p = self
                    .truth
                    .photos
                    .get(name)
                    .unwrap_or_else(|| panic!("{name} is not in the truth manifest"));
                format!("{} {}", p.map, p.rotation_texels)
            })
            .collect();
        LightGroups::from_labels(&labels, "the true sky of each training photo".into())
    }

    /// The true materials, as the estimator's start.
    pub fn true_materials(&self) -> Materials0 {
        Materials0 {
            lambda: self.lambda.clone(),
            weights: self.weights.clone(),
        }
    }

    /// The model's prediction for the held-out observations under their TRUE lights with
    /// reflectance `(lambda, weights)`.
    pub fn predict_held(&self, lambda: &[Vec<[f64; 3]>], weights: &[f64]) -> Vec<[f64; 3]> {
        predict_with(&self.held, self.nv, lambda, weights, &self.held.lights)
    }

    /// The training split's problem over other observations of the same photos and
    /// vertices (`obs`: a corrupted or noise-free copy of `train.obs`).
    pub fn train_problem_with<'a>(&'a self, obs: &'a Observations) -> Problem<'a> {
        Problem {
            obs,
            transport: &self.train.transport,
            n_vertices: self.nv,
            n_photos: obs.photo_ranges.len(),
        }
    }
}

fn basis_of(l: &Lobe) -> BasisBrdf {
    match *l {
        Lobe::Lambert => BasisBrdf::Lambert,
        Lobe::Phong { exponent } => BasisBrdf::Phong { exponent },
        Lobe::Ggx { alpha } => BasisBrdf::Ggx { alpha },
    }
}

/// Per-vertex `w0 … w{K-1}` of `truth/weights.ply`, row-major `V × K`.
fn read_weights(path: &Path, k: usize) -> Vec<f64> {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let mut f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let ply = Parser::<DefaultElement>::new().read_ply(&mut f).unwrap();
    let verts = &ply.payload["vertex"];
    let mut out = Vec::with_capacity(verts.len() * k);
    for v in verts {
        for j in 0..k {
            let val = match &v[&format!("w{j}")] {
                Property::Float(x) => *x as f64,
                Property::Double(x) => *x,
                other => panic!("{}: w{j} has type {other:?}", path.display()),
            };
            out.push(val);
        }
    }
    out
}

/// Whether the scenes are rendered with sky backgrounds (`SYNTH_SKY_BACKGROUND=1`,
/// `synth --sky-background`), and so their backgrounds read.
pub fn sky_backgrounds() -> bool {
    std::env::var("SYNTH_SKY_BACKGROUND").is_ok_and(|v| v == "1")
}

/// Build `scene` with `synth`, then observations and transport of the training and
/// held-out photos (the manifest's split).
pub fn prepare(scene_name: &str, sizes: Sizes, seed: u64, tag: &str) -> Case {
    let scratch = scratch(tag);
    let seconds_synth = synthesize(scene_name, &scratch.0.join("ws"), sizes, seed);
    prepare_in(scene_name, scratch, seconds_synth, sizes, seed)
}

/// Render `scene` into the workspace `ws` (photo sizes and samples from `sizes`); seconds.
pub fn synthesize(scene_name: &str, ws: &Path, sizes: Sizes, seed: u64) -> f64 {
    let t0 = std::time::Instant::now();
    synth::build(
        scene_name,
        ws,
        &SynthOptions {
            width: sizes.width,
            height: sizes.width,
            photos: sizes.photos,
            vertices: Some(sizes.vertices),
            exact_vertices: false,
            seed,
            samples: Samples {
                per_pixel: sizes.spp,
                light: sizes.light_samples,
                seed,
            },
            points: 400,
            // `SYNTH_WHITE_BALANCE=1`: random per-photo white balance too (the shared-light
            // model's gains must absorb it).
            white_balance: std::env::var("SYNTH_WHITE_BALANCE").is_ok_and(|v| v == "1"),
            // `SYNTH_SHARED_SKIES=1`: photos under the same map share its rotation, so
            // they share a sky (the shared-light model's groups).
            shared_skies: std::env::var("SYNTH_SHARED_SKIES").is_ok_and(|v| v == "1"),
            // `SYNTH_GEOTAG=1`: a sun-and-sky scene's suns from a day's clock, each photo
            // geotagged (`synth --geotag`; the cases' `geotag_suns`).
            geotag: std::env::var("SYNTH_GEOTAG").is_ok_and(|v| v == "1"),
            // `SYNTH_SKY_BACKGROUND=1`: the photos' backgrounds show their maps
            // (`synth --sky-background`).
            sky_background: sky_backgrounds(),
            // `SYNTH_EXPOSURE_PEAK=P`: the 99th percentile exposed to P (`synth
            // --exposure-peak`; 0.6 clips nearly nothing).
            exposure_peak: std::env::var("SYNTH_EXPOSURE_PEAK")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(1.0),
            ..SynthOptions::default()
        },
    )
    .unwrap();
    t0.elapsed().as_secs_f64()
}

/// The rest of [`prepare`] on the workspace `scratch/ws` made by [`synthesize`]: the
/// transport's sizes (`global`, `local`, `normal_grid`, `keep`, `rays_per_texel`) may
/// differ from the render's.
pub fn prepare_in(
    scene_name: &str,
    scratch: Scratch,
    seconds_synth: f64,
    sizes: Sizes,
    seed: u64,
) -> Case {
    let ws = scratch.0.join("ws");
    let t1 = std::time::Instant::now();
    let truth = Truth::read(&ws.join("truth")).unwrap();
    let mats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ws.join("truth/materials.json")).unwrap())
            .unwrap();
    let lobes: Vec<Lobe> = serde_json::from_value(mats["lobes"].clone()).unwrap();
    let basis: Vec<BasisBrdf> = lobes.iter().map(basis_of).collect();
    let lambda: Vec<Vec<[f64; 3]>> = mats["materials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| serde_json::from_value(m["lambda"].clone()).unwrap())
        .collect();
    let k = lambda.len();

    let wsp = Workspace::discover(&ws, None).unwrap();
    let sc = scene::load_scene(wsp).unwrap();
    let photos = scene::load_photos(&sc, relight_cpc::import::photo::DEFAULT_CLIP).unwrap();
    let nv = sc.mesh.positions.len();
    let weights = read_weights(&ws.join("truth/weights.ply"), k);
    assert_eq!(
        weights.len(),
        nv * k,
        "the cleaned mesh must keep synth's vertices"
    );
    // The views held out (`true`) or trained on, in the workspace's order.
    let view_indices = |held: bool| -> Vec<usize> {
        (0..sc.views.len())
            .filter(|&i| truth.held_out.contains(&sc.views[i].image.name) == held)
            .collect()
    };
    let geotag_suns = relight_cpc::run::geotag_suns::suns_of(&sc.photo_paths(&view_indices(false)));
    let env_from_world = truth.env_from_world;
    let normals_env: Vec<Vec3> = sc.mesh.normals.iter().map(|n| env_from_world * n).collect();
    let bvh = SceneBvh::new(&sc.mesh);
    let vis = visibility::compute(
        &sc.mesh,
        &bvh,
        &env_from_world,
        sizes.local,
        sizes.rays_per_texel,
        seed,
    );
    let rot = Rotation::new(
        sizes.global,
        sizes.local,
        sizes.normal_grid,
        RotationForm::Factored,
    );
    // `SYNTH_SPLAT_ROTATION=1`: the light rotated into each vertex's frame at its exact
    // normal (the renderer's splat) instead of the estimator's blend over the normal grid.
    let splat = std::env::var("SYNTH_SPLAT_ROTATION")
        .is_ok_and(|v| v == "1")
        .then(|| SplatRotation::with_default_supersample(sizes.global, sizes.local));
    let topts = TransportOptions {
        n_global: sizes.global,
        n_local: sizes.local,
        keep: sizes.keep,
    };
    let split = |held: bool| -> Split {
        let idx = view_indices(held);
        let views: Vec<_> = idx.iter().map(|&i| sc.views[i].clone()).collect();
        let ph: Vec<_> = idx.iter().map(|&i| photos[i].clone()).collect();
        // The paper's observation rule: the estimator's tests measure the estimator, and
        // the edge margin (a real-photo guard, tested in realphoto_effects) is off.
        let opts = ObserveOptions {
            edge_margin: None,
            ..ObserveOptions::default()
        };
        let obs = observe::extract(&sc.mesh, &bvh, &views, &ph, &opts);
        let inputs = TransportInputs {
            normals_env: &normals_env,
            obs: &obs,
            env_from_world: &env_from_world,
            vis: &vis,
            basis: &basis,
            opts: &topts,
        };
        let transport = match &splat {
            Some(s) => inputs.build(s),
            None => inputs.build(&rot),
        };
        let lights = views
            .iter()
            .map(|v| {
                let env = truth
                    .light(&v.image.name, sizes.global, &env_from_world)
                    .unwrap()
                    .unwrap();
                [0, 1, 2].map(|c| env.channel(c))
            })
            .collect();
        let background = if sky_backgrounds() {
            observe::background::extract(
                &sc.mesh,
                &views,
                &ph,
                &env_from_world,
                &observe::background::BackgroundOptions::new(sizes.global),
            )
        } else {
            Vec::new()
        };
        Split {
            obs,
            transport,
            lights,
            views,
            background,
        }
    };
    let train = split(false);
    let held = split(true);
    Case {
        scene: scene_name.to_string(),
        scratch,
        basis,
        nv,
        positions: sc.mesh.positions.clone(),
        train,
        held,
        lambda,
        weights,
        sizes,
        seconds_synth,
        seconds_prepare: t1.elapsed().as_secs_f64(),
        normals_env,
        env_from_world,
        vis,
        truth,
        geotag_suns,
    }
}

/// `(relative RMSE, RMSE)` of predictions against the observations with `α > 0`, over all
/// channels: `sqrt(Σ (y − ŷ)²) / sqrt(Σ y²)`. With `best_scale` the prediction is first
/// multiplied by the least-squares global factor.
pub fn rel_rmse(obs: &Observations, pred: &[[f64; 3]], best_scale: bool) -> (f64, f64) {
    let (mut yy, mut yp, mut pp, mut n) = (0.0, 0.0, 0.0, 0usize);
    for p in 0..obs.len() {
        if obs.weight[p] <= 0.0 {
            continue;
        }
        for c in 0..3 {
            let y = obs.rgb[p][c] as f64;
            yy += y * y;
            yp += y * pred[p][c];
            pp += pred[p][c] * pred[p][c];
        }
        n += 3;
    }
    let s = if best_scale && pp > 0.0 { yp / pp } else { 1.0 };
    let se = (yy - 2.0 * s * yp + s * s * pp).max(0.0);
    ((se / yy).sqrt(), (se / n.max(1) as f64).sqrt())
}

/// Model prediction for `split`'s observations with reflectance `(lambda, weights)` under
/// `lights` (texels, one per photo of the split).
pub fn predict_with(
    split: &Split,
    nv: usize,
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    lights: &[[Vec<f64>; 3]],
) -> Vec<[f64; 3]> {
    let problem = split.problem(nv);
    let est = Estimate::from_parts(lights.to_vec(), lambda.to_vec(), weights.to_vec());
    relight_cpc::solve::predict(&problem, &est)
}

/// The TRUE model's prediction for `split`'s observations: the case's true reflectance
/// under the split's true lights, through the case's own transport.
pub fn true_prediction(case: &Case, split: &Split) -> Vec<[f64; 3]> {
    predict_with(split, case.nv, &case.lambda, &case.weights, &split.lights)
}

/// Relative and absolute RMSE (as [`rel_rmse`], no scale fitted) of the training photos
/// under `lights` with the case's TRUE reflectance: the known-reflectance re-render error
/// (paper Sec. 6.1), or its floor with the true lights.
pub fn known_rel_rmse(case: &Case, lights: &[[Vec<f64>; 3]]) -> (f64, f64) {
    let pred = predict_with(&case.train, case.nv, &case.lambda, &case.weights, lights);
    rel_rmse(&case.train.obs, &pred, false)
}

/// Replace every colour of `obs` by `pred` (e.g. [`true_prediction`]: data the model
/// reproduces exactly, so the floor is 0).
pub fn replace_colours(obs: &mut Observations, pred: &[[f64; 3]]) {
    for (y, v) in obs.rgb.iter_mut().zip(pred) {
        *y = v.map(|a| a as f32);
    }
}

/// Block means of an `n × n` texel map down to `r × r` (the Haar scaling coefficients of
/// level `log2 r`, up to a constant): the map as a BRDF of that bandwidth sees it.
pub fn block_mean(map: &[f64], n: usize, r: usize) -> Vec<f64> {
    let f = n / r;
    let mut out = vec![0.0; r * r];
    for j in 0..n {
        for i in 0..n {
            out[(j / f) * r + i / f] += map[j * n + i] / (f * f) as f64;
        }
    }
    out
}

/// Relative error `‖T_r − s E_r‖ / ‖T_r‖` of estimated maps against the true ones at
/// resolution `r` (block means), all photos and channels together, with `s` the one global
/// least-squares scale at full resolution.
pub fn map_error(est: &[[Vec<f64>; 3]], truth: &[[Vec<f64>; 3]], n: usize, r: usize) -> f64 {
    let (mut te, mut ee) = (0.0, 0.0);
    for (e, t) in est.iter().zip(truth) {
        for c in 0..3 {
            te += e[c].iter().zip(&t[c]).map(|(a, b)| a * b).sum::<f64>();
            ee += e[c].iter().map(|a| a * a).sum::<f64>();
        }
    }
    let s = if ee > 0.0 { te / ee } else { 1.0 };
    let (mut num, mut den) = (0.0, 0.0);
    for (e, t) in est.iter().zip(truth) {
        for c in 0..3 {
            let eb = block_mean(&e[c], n, r);
            let tb = block_mean(&t[c], n, r);
            for (a, b) in eb.iter().zip(&tb) {
                num += (b - s * a).powi(2);
                den += b * b;
            }
        }
    }
    (num / den).sqrt()
}

/// Estimate with the true reflectance held fixed (paper Sec. 6.1).
pub fn fit_known_reflectance(case: &Case, opts: &EstimateOptions) -> Estimate {
    let problem = case.train.problem(case.nv);
    let init = case.true_materials();
    let o = EstimateOptions {
        fixed_materials: true,
        ..opts.clone()
    };
    estimate(&problem, init, &o, &mut |_, _| {}).unwrap()
}

/// Per-vertex β of the truth.
pub fn true_beta(case: &Case) -> Vec<[f64; 3]> {
    beta_per_vertex(&case.lambda, &case.weights, case.nv)
}

/// Haar forward of a texel map (helper for callers comparing coefficients).
pub fn haar_of(map: &[f64], n: usize) -> Vec<f64> {
    let mut h = map.to_vec();
    haar::forward(&mut h, n);
    h
}

/// Like [`rel_rmse`], with the best least-squares scale per channel (3 factors): the
/// light-colour / albedo-colour ambiguity of Eq. 9 (`λ_c → s_c λ_c`, `x_c → x_c / s_c`
/// leaves every photo unchanged), which no normalisation can resolve from the data.
pub fn rel_rmse_per_channel(obs: &Observations, pred: &[[f64; 3]]) -> f64 {
    let (mut yy, mut se) = (0.0, 0.0);
    for c in 0..3 {
        let (mut a, mut b, mut d) = (0.0, 0.0, 0.0);
        for p in 0..obs.len() {
            if obs.weight[p] <= 0.0 {
                continue;
            }
            let y = obs.rgb[p][c] as f64;
            a += y * y;
            b += y * pred[p][c];
            d += pred[p][c] * pred[p][c];
        }
        let s = if d > 0.0 { b / d } else { 1.0 };
        yy += a;
        se += (a - 2.0 * s * b + s * s * d).max(0.0);
    }
    (se / yy).sqrt()
}

/// Replace a fraction `f` of the observations with `α > 0` by bright outliers: every
/// channel of a chosen observation gets `+ u · y99`, `u ~ U(0.5, 2)`, `y99` the 99th
/// percentile of all observed channel values (a specular flare or a passer-by's white
/// shirt, not in the model). Returns the corrupted observations' indices.
pub fn corrupt(obs: &mut Observations, f: f64, seed: u64) -> Vec<usize> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut vals: Vec<f32> = obs
        .rgb
        .iter()
        .zip(&obs.weight)
        .filter(|(_, &w)| w > 0.0)
        .flat_map(|(c, _)| c.iter().copied())
        .collect();
    vals.sort_by(f32::total_cmp);
    let y99 = vals[(vals.len() * 99 / 100).min(vals.len() - 1)];
    let mut hit = Vec::new();
    for p in 0..obs.len() {
        if obs.weight[p] > 0.0 && rng.random::<f64>() < f {
            let u = rng.random_range(0.5..2.0_f32);
            for v in obs.rgb[p].iter_mut() {
                *v += u * y99;
            }
            hit.push(p);
        }
    }
    hit
}

/// Figures of a joint (materials + lights) recovery against the truth.
#[derive(Debug, Clone, serde::Serialize)]
pub struct JointFigures {
    /// Fraction of seen vertices whose largest estimated weight is the true largest
    /// material (best of the K! material orders).
    pub assignment: f64,
    /// The same over the seen vertices whose true weights are pure (max ≥ 0.95).
    pub assignment_pure: f64,
    /// Per channel `|r̂_c / r_c − 1|`, `r_c = λ_{0,L,c} / λ_{1,L,c}` (Lambertian weights of
    /// the materials themselves). NOT invariant to the K×K non-negative remix
    /// `w → w M⁻¹`, `λ → M λ` that leaves every vertex's reflectance β unchanged.
    pub ratio_errors: [f64; 3],
    /// The remix-invariant version: per channel `r̂_c` = median of the estimated per-vertex
    /// Lambertian weight `β̂_{x,L,c}` over the seen vertices that are truly pure material 0
    /// (true weight ≥ 0.95) over the same median for material 1, against the truth's
    /// `λ_{0,L,c} / λ_{1,L,c}`. Depends only on β̂ (what the data determine) and is
    /// invariant to the per-channel light-colour scale too.
    pub beta_ratio_errors: [f64; 3],
    /// Held-out photos under their true light: the estimated reflectance's prediction
    /// against the TRUE reflectance's prediction through the same transport (per-channel
    /// scale): the estimator's own error, without the renderer noise and the transport's
    /// discretisation that the observations also contain (`heldout_floor`).
    pub heldout_rel_model: f64,
    /// The true reflectance under the true light against the held-out observations.
    pub heldout_floor: f64,
    /// Training observations: relative RMSE of the fit.
    pub train_rel: f64,
    /// Held-out photos under their true light, best global scale.
    pub heldout_rel_global: f64,
    /// Held-out photos under their true light, best scale per channel.
    pub heldout_rel_channel: f64,
    /// The fit's reflectance under the TRUE light of its own training photos (best scale
    /// per channel) against those photos: what the per-photo maps hid (issue 25).
    pub train_true_light: f64,
    /// The same against the true reflectance's prediction (no renderer noise).
    pub train_true_light_model: f64,
    /// Outer iterations run.
    pub iterations: usize,
    /// Estimation seconds.
    pub seconds: f64,
}

/// Initial materials as `run` makes them (per-vertex mean colours, k-means, Sec. 5.2).
pub fn initial(case: &Case, obs: &Observations, k: usize, seed: u64) -> Materials0 {
    let (mean, seen) = relight_cpc::run::mean_colours(obs, case.nv);
    let init = relight_cpc::solve::cluster::initial_materials(&mean, &seen, k, seed).unwrap();
    Materials0::from_initial(&init, case.basis.len(), 0)
}

/// A small case of `scene` ([`Sizes::spot_small`], seed 1) with its training photos
/// replaced by the true model's prediction (noise-free: what is left is the estimator's),
/// whether a training photo sees each vertex, and the paper's k-means start.
pub struct NoiseFree {
    pub case: Case,
    pub seen: Vec<bool>,
    pub init: Materials0,
}

/// [`NoiseFree`] of `scene`, its scratch folder named by `tag`.
pub fn noise_free(scene: &str, tag: &str) -> NoiseFree {
    let mut case = prepare(scene, Sizes::spot_small(), 1, tag);
    let t = true_prediction(&case, &case.train);
    replace_colours(&mut case.train.obs, &t);
    let (_, seen) = relight_cpc::run::mean_colours(&case.train.obs, case.nv);
    let init = initial(&case, &case.train.obs, case.lambda.len(), 1);
    NoiseFree { case, seen, init }
}

/// Score an estimate of a two-material case against the truth. `train_obs` are the
/// observations the fit saw (possibly corrupted); `clean` the uncorrupted ones.
pub fn joint_figures(
    case: &Case,
    est: &Estimate,
    clean: &Observations,
    seconds: f64,
) -> JointFigures {
    let k = case.lambda.len();
    let ke = est.lambda.len();
    assert_eq!(k, 2, "joint figures are defined for two materials");
    assert_eq!(ke, 2);
    let (_, seen) = relight_cpc::run::mean_colours(clean, case.nv);
    let argmax = |w: &[f64]| (0..w.len()).max_by(|&a, &b| w[a].total_cmp(&w[b])).unwrap();
    let mut best = (0.0, 0.0, [0usize, 1]);
    for perm in [[0usize, 1], [1, 0]] {
        let (mut ok, mut n, mut okp, mut np) = (0, 0, 0, 0);
        for x in 0..case.nv {
            if !seen[x] {
                continue;
            }
            let tw = &case.weights[x * k..(x + 1) * k];
            let ew = &est.weights[x * ke..(x + 1) * ke];
            let t = argmax(tw);
            let hit = perm[argmax(ew)] == t;
            n += 1;
            ok += usize::from(hit);
            if tw[t] >= 0.95 {
                np += 1;
                okp += usize::from(hit);
            }
        }
        let a = ok as f64 / n.max(1) as f64;
        if a > best.0 {
            best = (a, okp as f64 / np.max(1) as f64, perm);
        }
    }
    let perm = best.2;
    // est material j plays true material perm[j]; inv[t] = est index of true t.
    let inv = if perm == [0, 1] { [0, 1] } else { [1, 0] };
    let ratio_errors = [0, 1, 2].map(|c| {
        let r_true = case.lambda[0][0][c] / case.lambda[1][0][c];
        let r_est = est.lambda[inv[0]][0][c] / est.lambda[inv[1]][0][c];
        (r_est / r_true - 1.0).abs()
    });
    let beta_hat = beta_per_vertex(&est.lambda, &est.weights, case.nv);
    let nb = case.basis.len();
    let median = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let beta_ratio_errors = [0, 1, 2].map(|c| {
        let pure = |t: usize| -> Vec<f64> {
            (0..case.nv)
                .filter(|&x| seen[x] && case.weights[x * k + t] >= 0.95)
                .map(|x| beta_hat[x * nb][c])
                .collect()
        };
        let r_true = case.lambda[0][0][c] / case.lambda[1][0][c];
        let r_est = median(pure(0)) / median(pure(1));
        (r_est / r_true - 1.0).abs()
    });
    let pred = relight_cpc::solve::predict(&case.train.problem(case.nv), est);
    let (train_rel, _) = rel_rmse(clean, &pred, false);
    let hp = case.predict_held(&est.lambda, &est.weights);
    let (heldout_rel_global, _) = rel_rmse(&case.held.obs, &hp, true);
    let heldout_rel_channel = rel_rmse_per_channel(&case.held.obs, &hp);
    let hp_true = true_prediction(case, &case.held);
    let mut model_obs = case.held.obs.clone();
    replace_colours(&mut model_obs, &hp_true);
    let heldout_rel_model = rel_rmse_per_channel(&model_obs, &hp);
    let heldout_floor = rel_rmse(&case.held.obs, &hp_true, false).0;
    let tp = predict_with(
        &case.train,
        case.nv,
        &est.lambda,
        &est.weights,
        &case.train.lights,
    );
    let train_true_light = rel_rmse_per_channel(clean, &tp);
    let mut model_train = clean.clone();
    replace_colours(&mut model_train, &true_prediction(case, &case.train));
    let train_true_light_model = rel_rmse_per_channel(&model_train, &tp);
    JointFigures {
        train_true_light,
        train_true_light_model,
        assignment: best.0,
        assignment_pure: best.1,
        ratio_errors,
        beta_ratio_errors,
        heldout_rel_model,
        heldout_floor,
        train_rel,
        heldout_rel_global,
        heldout_rel_channel,
        iterations: est.timeline.len(),
        seconds,
    }
}

/// Per Haar level `m = 1, 2, 4, …, n/2` (nodes per side; the detail coefficients with
/// `m ≤ max(row, col) < 2m`, [`relight_cpc::sphere::haar`]): the correlation
/// `Σ ĥ h / sqrt(Σ ĥ² Σ h²)` of the estimated and true maps' coefficients over all photos
/// and channels. Invariant to one global scale; 1 = that band's detail recovered up to
/// scale, 0 = none. A BRDF of bandwidth `m` can only constrain the levels below `m`.
pub fn level_correlation(
    est: &[[Vec<f64>; 3]],
    truth: &[[Vec<f64>; 3]],
    n: usize,
) -> Vec<(usize, f64)> {
    let mut m = 1;
    let mut acc = Vec::new();
    while m < n {
        acc.push((m, [0.0_f64; 3]));
        m *= 2;
    }
    for (e, t) in est.iter().zip(truth) {
        for c in 0..3 {
            let he = haar_of(&e[c], n);
            let ht = haar_of(&t[c], n);
            for k in 1..n * n {
                let (row, col) = (k / n, k % n);
                let lvl = row.max(col).ilog2() as usize;
                let a = &mut acc[lvl].1;
                a[0] += he[k] * ht[k];
                a[1] += he[k] * he[k];
                a[2] += ht[k] * ht[k];
            }
        }
    }
    acc.into_iter()
        .map(|(m, a)| {
            (
                m,
                if a[1] > 0.0 && a[2] > 0.0 {
                    a[0] / (a[1] * a[2]).sqrt()
                } else {
                    0.0
                },
            )
        })
        .collect()
}

/// Every number an estimate outputs (maps, `λ`, blending weights) as raw bits, for bitwise
/// determinism checks.
pub fn estimate_bits(e: &Estimate) -> Vec<u64> {
    e.lights
        .iter()
        .flat_map(|l| l.iter().flatten())
        .chain(e.lambda.iter().flatten().flatten())
        .chain(&e.weights)
        .map(|v| v.to_bits())
        .collect()
}

use relight_cpc::solve::light::sh_prior::{map_sample, LightPrior, LightPriorOptions, PriorSample};
/// The eight embedded maps' names, in the order of the leave-one-out statistics.
pub use relight_cpc::synth::data::MAP_NAMES as PRIOR_MAPS;

/// Statistics for `case`'s training photos: `stats[8]` from all eight maps, `stats[i]` from
/// all but map `i`; each photo uses the set without the map it was rendered with (from
/// `truth/manifest.json`), so no photo's own light is in its prior.
pub fn with_case_priors(case: &Case, o: &EstimateOptions) -> EstimateOptions {
    let Some(lp) = &o.light_prior else {
        return o.clone();
    };
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/synth/hdri");
    let samples: Vec<PriorSample> = PRIOR_MAPS
        .iter()
        .map(|m| {
            let (ll, _) =
                relight_cpc::sphere::envmap::LatLong::read_exr(&dir.join(format!("{m}.exr")))
                    .unwrap();
            map_sample(&ll, 24, &[case.sizes.global])
        })
        .collect();
    let fit = |skip: Option<usize>| {
        let names: Vec<String> = (0..8)
            .filter(|&i| Some(i) != skip)
            .map(|i| PRIOR_MAPS[i].to_string())
            .collect();
        let sub: Vec<PriorSample> = (0..8)
            .filter(|&i| Some(i) != skip)
            .map(|i| samples[i].clone())
            .collect();
        LightPrior::fit(names, 24, &sub, 0.1).unwrap()
    };
    let stats: Vec<LightPrior> = if lp.per_photo.is_some() {
        (0..8).map(|i| fit(Some(i))).chain([fit(None)]).collect()
    } else {
        vec![fit(None)]
    };
    let map_of = |name: &str| -> usize {
        let m = case.truth.photos.get(name).map_or("", |p| p.map.as_str());
        PRIOR_MAPS.iter().position(|x| *x == m).unwrap_or(8)
    };
    let per_photo = lp
        .per_photo
        .as_ref()
        .map(|_| case.train.names().map(map_of).collect());
    EstimateOptions {
        light_prior: Some(LightPriorOptions {
            stats: std::sync::Arc::new(stats),
            per_photo,
            ..lp.clone()
        }),
        ..o.clone()
    }
}

/// What a split's transport is built from, whichever rotation takes the light into each
/// vertex's frame.
struct TransportInputs<'a> {
    normals_env: &'a [Vec3],
    obs: &'a Observations,
    env_from_world: &'a Matrix3<f64>,
    vis: &'a Visibility,
    basis: &'a [BasisBrdf],
    opts: &'a TransportOptions,
}

impl TransportInputs<'_> {
    fn build<R: LocalRotation>(&self, rot: &R) -> Transport {
        transport::build(
            self.normals_env,
            self.obs,
            self.env_from_world,
            self.vis,
            self.basis,
            rot,
            self.opts,
        )
        .unwrap()
    }
}
