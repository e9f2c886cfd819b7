//! The estimator on known-truth scenes (issue 5, "What it must show"), at fuller size than
//! the tests: `cargo bench --bench estimator` writes `bench-results/estimator.json` and
//! `.md`. Every scene is made by `relight-cpc synth` (the reference renderer, not the
//! operator being fitted) and taken through the real pipeline stages
//! (`tests/support/synth_case.rs`).
//!
//! 1. Known reflectance, unknown light (Sec. 6.1): diffuse, Phong 50 and Phong 500 spheres
//!    under the courtyard map; re-render error of the training photos next to the floor
//!    (the TRUE map through the same transport: renderer noise plus discretisation), the
//!    maps against the truth per Haar level (correlation) and as block means after one
//!    global scale, held-out photos under the mean fitted map; μ on two scales.
//! 2. Joint recovery on `spot-varying` (two materials, a different real map per photo,
//!    every 4th photo held out): material assignment, diffuse colour ratios (per-vertex β,
//!    invariant to the K×K material remix, and from λ), held-out photos under their true
//!    light against the photos and against the true reflectance's prediction, the
//!    timeline; after 1 and after ≤ 30 outer iterations.
//! 3. Robustness: 5% of the training observations given bright outliers; IRLS (Huber,
//!    Tukey) against plain least squares, all against the clean Huber fit.
//! 4. Determinism: bitwise comparison of two runs, on 1 and 2 threads.
//!
//! `ESTIMATOR_BENCH=known,joint,robust,determinism` picks parts (default: all; `convergence`
//! and `floors` write their own files). Variants without editing the bench:
//! `JOINT_SPECS` / `ROBUST_SPECS` / `CONVERGENCE_SPECS` replace a part's rows by option
//! strings ([`parse_spec`], e.g. `"floor=0.1;floor=0.1,val=0"`); `JOINT_SCENE` (default
//! `spot-varying`) and `JOINT_GLOBAL`, `JOINT_LOCAL`, `JOINT_SPP`, `JOINT_VERTICES`,
//! `JOINT_WIDTH`, `JOINT_PHOTOS` set parts 2, 3 and 5's case; `KNOWN_SCENES`, `KNOWN_FINE=1`
//! and `KNOWN_NOISE_FREE=1` (every observation the true map's prediction through the
//! transport: the estimator's own error) part 1's; `FLOOR_SCENES`, `FLOOR_WIDTH`, `FLOOR_SPP`,
//! `FLOOR_NORMAL_GRID` part 6's; `RESULTS_SUFFIX=S` writes `STEM-S.{md,json}`. Sizes are
//! chosen to keep the whole run near 15 CPU minutes: parts 2–4 use a 16² global and 8²
//! local map (32² / 16² cost ~20× more per outer iteration on Spot).

#![allow(clippy::needless_range_loop)]

#[path = "../tests/support/synth_case.rs"]
mod synth_case;

use relight_cpc::observe::Observations;
use relight_cpc::solve::light::sh_prior::{map_sample, LightPrior, LightPriorOptions, PriorSample};
use relight_cpc::solve::starts::{self, estimate_best, MultiStart};
use relight_cpc::solve::{estimate, Estimate, EstimateOptions, Robust, SmoothnessScale};
use serde_json::{json, Value};
use std::time::Instant;
use synth_case::*;

/// `KNOWN_FINE=1`: 64² photos at 64 spp, 64² global / 32² local maps, where the diffuse
/// sphere's floor falls below 2% (`estimator-floors.md`).
fn sizes_known() -> Sizes {
    if std::env::var("KNOWN_FINE").is_ok_and(|v| v == "1") {
        return Sizes {
            width: 64,
            photos: None,
            vertices: 2_500,
            spp: 64,
            light_samples: 64,
            global: 64,
            local: 32,
            normal_grid: 16,
            keep: 0,
            rays_per_texel: 2,
        };
    }
    Sizes {
        width: 96,
        photos: None,
        vertices: 2_500,
        spp: 16,
        light_samples: 64,
        global: 32,
        local: 16,
        normal_grid: 16,
        keep: 0,
        rays_per_texel: 2,
    }
}

/// Parts 2, 3 and 5; `JOINT_GLOBAL`, `JOINT_LOCAL`, `JOINT_SPP`, `JOINT_VERTICES`,
/// `JOINT_WIDTH`, `JOINT_PHOTOS` override the defaults (16², 8², 8 spp, 2,000, 96², the
/// scene's 16 photos, every fourth held out).
fn sizes_joint() -> Sizes {
    let env = |k: &str, d: usize| -> usize {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    Sizes {
        width: env("JOINT_WIDTH", 96) as u32,
        photos: std::env::var("JOINT_PHOTOS")
            .ok()
            .and_then(|v| v.parse().ok()),
        vertices: env("JOINT_VERTICES", 2_000),
        spp: env("JOINT_SPP", 8) as u32,
        light_samples: 64,
        global: env("JOINT_GLOBAL", 16),
        local: env("JOINT_LOCAL", 8),
        normal_grid: 16,
        keep: 0,
        rays_per_texel: 2,
    }
}

const RESOLUTIONS: [usize; 5] = [2, 4, 8, 16, 32];

/// One fit variant from a spec string (`JOINT_SPECS`, `ROBUST_SPECS`,
/// `CONVERGENCE_SPECS`: `;`-separated specs): comma-separated `key=value` changes to
/// `base`. Keys: `floor` (`robust_floor`), `irls` (`none`, `huber`, `tukey`), `k` (Huber's
/// k), `smooth` (`smoothness`), `decay` (`smoothness_decay`), `smin` (`smoothness_min`), `patience`, `extrap` (0/1), `its` (`max_outer`), `val`
/// (`validation_fraction`), `passes` (`irls_iters`), `cut` (`weights_reject`, 0 = none),
/// `qp` (`alternation_qp_iters`, 0 = every lighting QP to the KKT tolerance),
/// `truth=1` (start at the true materials; parts 2 and 5), `spec0=f` (parts 2 and 5: the clustered
/// start with every non-Lambertian basis at `f` × the material's mean Lambertian weight, grey,
/// instead of 0), `start=s` (parts 2 and 5: start number `s` of `starts::variants`),
/// `starts=n` (part 2: the best of the first `n` of them, `starts::estimate_best`), `dirty=1` (5% outliers, part 3),
/// `prior=η` / `haar=η` (the light prior's SH and Haar noise levels), `sky=η` (the
/// sun-and-sky light model with residual noise level η); `base` alone
/// = no change. The label is the spec itself.
struct Spec {
    label: String,
    opts: EstimateOptions,
    start: Start,
    dirty: bool,
}

fn parse_spec(spec: &str, base: &EstimateOptions) -> Spec {
    let mut o = base.clone();
    let (mut from_truth, mut dirty, mut spec0) = (false, false, 0.0);
    let (mut variant, mut best) = (None, None);
    for kv in spec
        .split(',')
        .map(str::trim)
        .filter(|v| !v.is_empty() && *v != "base")
    {
        let (k, v) = kv
            .split_once('=')
            .unwrap_or_else(|| panic!("spec `{spec}`: `{kv}` is not key=value"));
        let num = || -> f64 {
            v.parse()
                .unwrap_or_else(|_| panic!("spec `{spec}`: `{v}` is not a number"))
        };
        match k {
            "floor" => o.robust_floor = num(),
            "irls" => {
                o.robust = match v {
                    "none" => Robust::None,
                    "huber" => Robust::Huber { k: 1.345 },
                    "tukey" => Robust::Tukey { c: 4.685 },
                    _ => panic!("spec `{spec}`: irls `{v}`"),
                }
            }
            "k" => o.robust = Robust::Huber { k: num() },
            "smooth" => o.smoothness = num(),
            "decay" => o.smoothness_decay = num(),
            "smin" => o.smoothness_min = num(),
            "patience" => o.patience = num() as usize,
            "extrap" => o.extrapolate = num() > 0.0,
            "its" => o.max_outer = num() as usize,
            "val" => o.validation_fraction = num(),
            "passes" => o.irls_iters = num() as usize,
            "qp" => o.alternation_qp_iters = (num() > 0.0).then(|| num() as usize),
            "cut" => o.weights_reject = (num() > 0.0).then(num),
            "truth" => from_truth = num() > 0.0,
            "dirty" => dirty = num() > 0.0,
            "spec0" => spec0 = num(),
            "start" => variant = Some(num() as usize),
            "starts" => best = Some(num() as usize),
            // Light prior (issue 25): SH shape and Haar L1 noise levels; `loo=0` uses the
            // statistics of all eight maps (including the photo's own: optimistic).
            "prior" => prior_opts(&mut o).sh_noise = num(),
            "haar" => prior_opts(&mut o).haar_noise = num(),
            // The sun-and-sky model (issue 25) with its residual prior at noise level η.
            "sky" => {
                o.light_sky = Some(relight_cpc::solve::light::sky::SkyOptions {
                    residual_noise: num(),
                })
            }
            "loo" => {
                if num() == 0.0 {
                    prior_opts(&mut o).per_photo = None;
                }
            }
            _ => panic!("spec `{spec}`: unknown key `{k}`"),
        }
    }
    Spec {
        label: if spec.trim().is_empty() {
            "base".into()
        } else {
            spec.trim().into()
        },
        opts: o,
        start: match (from_truth, variant, best) {
            (true, _, _) => Start::Truth,
            (_, Some(s), _) => Start::Variant(s),
            (_, _, Some(n)) => Start::Best(n),
            _ => Start::Clustered(spec0),
        },
        dirty,
    }
}

/// The light prior options of `o`, created with every noise level 0 and leave-one-map-out
/// statistics (filled in per case by [`with_case_priors`]).
fn prior_opts(o: &mut EstimateOptions) -> &mut LightPriorOptions {
    o.light_prior.get_or_insert_with(|| LightPriorOptions {
        stats: std::sync::Arc::new(Vec::new()),
        per_photo: Some(Vec::new()),
        sh_noise: 0.0,
        haar_noise: 0.0,
    })
}

// The eight embedded maps' names, in the order of the leave-one-out statistics.
use relight_cpc::synth::data::MAP_NAMES as PRIOR_MAPS;

/// Statistics for `case`'s training photos: `stats[8]` from all eight maps, `stats[i]` from
/// all but map `i`; each photo uses the set without the map it was rendered with (from
/// `truth/manifest.json`), so no photo's own light is in its prior.
fn with_case_priors(case: &Case, o: &EstimateOptions) -> EstimateOptions {
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
    let manifest: Value = serde_json::from_str(
        &std::fs::read_to_string(case.scratch.0.join("ws/truth/manifest.json")).unwrap(),
    )
    .unwrap();
    let map_of = |name: &str| -> usize {
        let m = manifest["photos"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .and_then(|p| p["map"].as_str())
            .unwrap_or("");
        PRIOR_MAPS.iter().position(|x| *x == m).unwrap_or(8)
    };
    let per_photo = lp
        .per_photo
        .as_ref()
        .map(|_| case.train.names.iter().map(|n| map_of(n)).collect());
    EstimateOptions {
        light_prior: Some(LightPriorOptions {
            stats: std::sync::Arc::new(stats),
            per_photo,
            ..lp.clone()
        }),
        ..o.clone()
    }
}

/// The specs in environment variable `var`, if set.
fn specs_from_env(var: &str, base: &EstimateOptions) -> Option<Vec<Spec>> {
    std::env::var(var)
        .ok()
        .map(|v| v.split(';').map(|s| parse_spec(s, base)).collect())
}

/// The joint parts' scene (`JOINT_SCENE`, default `spot-varying`).
fn joint_scene() -> String {
    std::env::var("JOINT_SCENE").unwrap_or_else(|_| "spot-varying".into())
}

fn known(md: &mut String) -> Value {
    md.push_str("## 1. Known reflectance, unknown light (paper Sec. 6.1)\n\n");
    // `KNOWN_NOISE_FREE=1`: every observation replaced by the true map's prediction
    // through the case's own transport ([`noise_free`]; 1 spp, the render is discarded),
    // so the floor is 0 and the fit's error is the estimator's own.
    let clean = std::env::var("KNOWN_NOISE_FREE").is_ok_and(|v| v == "1");
    let mut s = sizes_known();
    if clean {
        s.spp = 1;
        md.push_str(
            "**Noise-free** (`KNOWN_NOISE_FREE=1`): every observation is the TRUE map's prediction through the \
             case's own transport, so the floor is 0 and the fit error is the estimator's own (the Laplacian's \
             bias, the QP's stopping rule); the spp below only made the discarded render.\n\n",
        );
    }
    md.push_str(&format!(
        "Spheres (`synth`, {}² photos, ≥{} vertices, {} spp × {} MIS pairs) under the courtyard map; \
         {}² global map, {}² local, {}² normal grid, all Haar coefficients kept; \
         the true λ and weights fixed, only the training photos' maps estimated (default options).\n\n\
         *Floor* = the TRUE map through the same transport against the same photos: what the renderer's \
         Monte-Carlo noise and the transport's discretisation leave; a fit cannot be judged below it. \
         *Fit* = the recovered maps' re-render error. Level correlation = `Σ ĥ h / sqrt(Σ ĥ² Σ h²)` of the \
         estimated and true maps' Haar detail coefficients at level m (m × m nodes), all photos and channels: \
         1 = that band's detail recovered up to scale.\n\n",
        s.width, s.vertices, s.spp, s.light_samples, s.global, s.local, s.normal_grid
    ));
    md.push_str("| scene | floor rel. RMSE (true map) | fit rel. RMSE | fit / floor | level corr. m=1 | 2 | 4 | 8 | 16 | map rel. error (block means) 2² | 4² | 8² | 32² | held-out rel. (mean map, best scale) | seconds (prepare / estimate) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    let mut rows = Vec::new();
    let mut cmp = String::from("\nThe Laplacian weight `μ = 10⁻³ × scale` for two choices of the system's scale \
        (`EstimateOptions::smoothness_scale`; `TexelMax`, the default, is used above).\n\n\
        | scene | scale | μ (photo 0, R) | fit rel. RMSE | level corr. m=4 | 8 | 16 | lighting matvecs | seconds |\n|---|---|---|---|---|---|---|---|---|\n");
    let only = std::env::var("KNOWN_SCENES").ok();
    for scene in ["sphere-diffuse", "sphere-glossy", "sphere-specular"] {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|v| v == scene))
        {
            continue;
        }
        let mut case = prepare(scene, s, 1, scene);
        if clean {
            noise_free(&mut case);
        }
        eprintln!(
            "{scene}: prepared in {:.1} + {:.1} s, {} vertices, {} observations",
            case.seconds_synth,
            case.seconds_prepare,
            case.nv,
            case.train.obs.len()
        );
        let (floor, _) = known_rel_rmse(&case, &case.train.lights);
        let mut variants = Vec::new();
        for scale in [SmoothnessScale::TexelMax, SmoothnessScale::HaarMax] {
            let opts = EstimateOptions {
                smoothness_scale: scale,
                ..EstimateOptions::default()
            };
            let t0 = Instant::now();
            let est = fit_known_reflectance(&case, &opts);
            let secs = t0.elapsed().as_secs_f64();
            let (train_rel, train_rmse) = known_rel_rmse(&case, &est.lights);
            let errs: Vec<f64> = RESOLUTIONS
                .iter()
                .map(|&r| map_error(&est.lights, &case.train.lights, s.global, r))
                .collect();
            let corr = level_correlation(&est.lights, &case.train.lights, s.global);
            cmp.push_str(&format!(
                "| {scene} | {scale:?} | {:.3e} | {train_rel:.4} | {} | {} | {secs:.1} |\n",
                est.mu[0][0],
                corr[2..]
                    .iter()
                    .take(3) // m = 4, 8, 16, the table's columns (the JSON has every level)
                    .map(|e| format!("{:.3}", e.1))
                    .collect::<Vec<_>>()
                    .join(" | "),
                est.conditioning.lighting_matvecs,
            ));
            eprintln!(
                "{scene} {scale:?}: floor {floor:.4}, fit {train_rel:.4}, level corr {corr:?}, map errors {errs:?}, {secs:.1} s"
            );
            variants.push(json!({
                "smoothness_scale": format!("{scale:?}"),
                "mu": est.mu.first(),
                "train_rel_rmse": train_rel,
                "level_correlation": corr.iter().map(|(m, r)| json!({"level": m, "correlation": r})).collect::<Vec<_>>(),
                "map_rel_error": RESOLUTIONS.iter().zip(&errs).map(|(r, e)| json!({"resolution": r, "error": e})).collect::<Vec<_>>(),
                "lighting_matvecs": est.conditioning.lighting_matvecs,
                "seconds_estimate": secs,
            }));
            if scale != EstimateOptions::default().smoothness_scale {
                continue;
            }
            // Held out: static illumination, so the mean of the fitted maps (the photos'
            // exposure differences are removed by the best global scale).
            let n2 = s.global * s.global;
            let mean: [Vec<f64>; 3] = [0, 1, 2].map(|c| {
                let mut m = vec![0.0; n2];
                for l in &est.lights {
                    for (a, b) in m.iter_mut().zip(&l[c]) {
                        *a += b / est.lights.len() as f64;
                    }
                }
                m
            });
            let held_lights = vec![mean; case.held.names.len()];
            let hp = predict_with(
                &case.held,
                case.nv,
                &case.lambda,
                &case.weights,
                &held_lights,
            );
            let (held_rel, _) = rel_rmse(&case.held.obs, &hp, true);
            md.push_str(&format!(
                "| {scene} | {floor:.4} | {train_rel:.4} | {} | {} | {} | {held_rel:.4} | {:.1} / {secs:.1} |\n",
                // Noise-free, the floor is rounding (the observations are stored in f32).
                if clean { "–".to_string() } else { format!("{:.3}", train_rel / floor) },
                corr.iter()
                    .take(5) // m = 1 … 16, the table's columns (the JSON has every level)
                    .map(|e| format!("{:.3}", e.1))
                    .collect::<Vec<_>>()
                    .join(" | "),
                [0usize, 1, 2, 4]
                    .iter()
                    .map(|&i| format!("{:.3}", errs[i]))
                    .collect::<Vec<_>>()
                    .join(" | "),
                case.seconds_synth + case.seconds_prepare,
            ));
            rows.push(json!({
                "scene": scene,
                "vertices": case.nv,
                "train_photos": case.train.names.len(),
                "train_observations": case.train.obs.len(),
                "floor_rel_rmse_true_map": floor,
                "train_rel_rmse": train_rel,
                "train_rmse": train_rmse,
                "heldout_rel_rmse_mean_map_best_scale": held_rel,
                "level_correlation": corr.iter().map(|(m, r)| json!({"level": m, "correlation": r})).collect::<Vec<_>>(),
                "map_rel_error": RESOLUTIONS.iter().zip(&errs).map(|(r, e)| json!({"resolution": r, "error": e})).collect::<Vec<_>>(),
                "mu": est.mu.first(),
                "qp_unconverged": est.conditioning.qp_unconverged,
                "lighting_matvecs": est.conditioning.lighting_matvecs,
                "seconds_estimate": secs,
                "seconds_synth": case.seconds_synth,
                "seconds_prepare": case.seconds_prepare,
            }));
        }
        rows.push(json!({"scene": scene, "smoothness_scale_comparison": variants}));
    }
    md.push_str(&cmp);
    md.push_str("\nRelative RMSE = `sqrt(Σ(y − ŷ)²) / sqrt(Σ y²)` over the observations with α > 0 and all channels. \
        Map error = `‖T_r − s E_r‖ / ‖T_r‖` over every training photo's map, `T_r`, `E_r` the true and fitted maps as `r × r` block means \
        (what a BRDF of that bandwidth sees), `s` one global least-squares scale fitted at full resolution.\n\n");
    json!(rows)
}

/// The case's materials as text: per material its lobes with non-zero weight.
fn materials_text(case: &Case) -> String {
    case.lambda
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let lobes: Vec<String> = l
                .iter()
                .zip(&case.basis)
                .filter(|(v, _)| v.iter().any(|&x| x > 0.0))
                .map(|(v, b)| format!("{b:?} {:.2}/{:.2}/{:.2}", v[0], v[1], v[2]))
                .collect();
            format!("material {k}: {}", lobes.join(" + "))
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// The case's basis BRDFs as text.
fn basis_text(case: &Case) -> String {
    case.basis
        .iter()
        .map(|b| format!("{b:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Where a joint fit starts.
#[derive(Clone, Copy)]
enum Start {
    /// The clustered start, every non-Lambertian basis at this fraction of the material's
    /// mean Lambertian weight (0: the paper's start).
    Clustered(f64),
    /// The true materials.
    Truth,
    /// Start number `s` of [`starts::variants`] (gloss [`starts::GLOSS_FRACTION`]).
    Variant(usize),
    /// The first `n` of [`starts::variants`], the best kept ([`starts::estimate_best`]).
    Best(usize),
}

/// The paper's start: the clustered materials, Lambertian only.
const PAPER_START: Start = Start::Clustered(0.0);

impl Start {
    /// The starts this stands for, for `case` fitted to `obs`.
    fn starts(self, case: &Case, obs: &Observations) -> Vec<starts::Start> {
        let clustered = || initial(case, obs, case.lambda.len(), 1);
        let family = |n| starts::variants(clustered(), 0, starts::GLOSS_FRACTION, n);
        let one = |label: &str, materials| {
            vec![starts::Start {
                label: label.into(),
                materials,
            }]
        };
        match self {
            Start::Truth => one("the true materials", case.true_materials()),
            Start::Clustered(f) => one(
                &format!("clustered, glossy lobes at {f}"),
                starts::uniform_gloss(&clustered(), 0, f),
            ),
            Start::Variant(s) => {
                let mut v = family(s + 1);
                assert_eq!(v.len(), s + 1, "start {s} of {} variants", v.len());
                vec![v.pop().unwrap()]
            }
            Start::Best(n) => family(n),
        }
    }

    /// The single start this stands for (not [`Start::Best`] of more than one).
    fn materials(self, case: &Case, obs: &Observations) -> relight_cpc::solve::Materials0 {
        let mut v = self.starts(case, obs);
        assert_eq!(v.len(), 1, "this part fits from a single start");
        v.pop().unwrap().materials
    }
}

/// Joint fit of `case` from `start` (the best of several when it names several); the
/// timeline with the held-out error under the true light (per-channel scale) at every outer
/// iteration of every start.
fn joint_fit(
    case: &Case,
    obs: &Observations,
    opts: &EstimateOptions,
    start: Start,
) -> (Estimate, f64, Vec<Value>, MultiStart) {
    let problem = case.train_problem_with(obs);
    let tried = start.starts(case, obs);
    let mut tl = Vec::new();
    let t0 = Instant::now();
    let (est, record) = estimate_best(&problem, tried, opts, &mut |si, it, st| {
        let hp = predict_with(&case.held, case.nv, st.lambda, st.weights, &case.held.lights);
        let h = rel_rmse_per_channel(&case.held.obs, &hp);
        eprintln!(
            "  start {si} iteration {}: {:.1} s, objective {:.5e}, train RMSE {:.5}, validation {:?}, held-out rel {:.4}",
            tl.len() + 1,
            it.seconds,
            it.objective,
            it.train_rmse,
            it.validation_rel,
            h
        );
        tl.push(json!({"start": si, "seconds": it.seconds, "objective": it.objective, "train_rmse": it.train_rmse, "validation_rel": it.validation_rel, "heldout_rel_true_light": h}));
    })
    .unwrap();
    (est, t0.elapsed().as_secs_f64(), tl, record)
}

fn joint_row(md: &mut String, label: &str, f: &JointFigures) {
    md.push_str(&format!(
        "| {label} | {:.4} | {:.4} | {:.3} / {:.3} / {:.3} | {:.3} / {:.3} / {:.3} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} / {:.4} | {} | {:.1} |\n",
        f.assignment,
        f.assignment_pure,
        f.beta_ratio_errors[0],
        f.beta_ratio_errors[1],
        f.beta_ratio_errors[2],
        f.ratio_errors[0],
        f.ratio_errors[1],
        f.ratio_errors[2],
        f.train_rel,
        f.heldout_rel_channel,
        f.heldout_floor,
        f.heldout_rel_model,
        f.train_true_light,
        f.train_true_light_model,
        f.iterations,
        f.seconds
    ));
}

const JOINT_HEADER: &str = "| fit | assigned (all seen) | assigned (pure) | diffuse-ratio error R / G / B, per-vertex β (remix-invariant) | the same from λ (not invariant) | train rel. RMSE | held-out rel. RMSE (true light) | held-out floor (true reflectance) | held-out vs true model | training photos under their TRUE light: vs photos / vs true model | outer its | seconds |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";

fn joint(md: &mut String) -> Value {
    let s = sizes_joint();
    let scene = joint_scene();
    let mut case = prepare(&scene, s, 1, "joint");
    // `JOINT_NOISE_FREE=1`: every observation the true reflectance under the true light
    // through the case's own transport (floor 0: the estimator's own error).
    let clean = std::env::var("JOINT_NOISE_FREE").is_ok_and(|v| v == "1");
    if clean {
        noise_free(&mut case);
        md.push_str("**Noise-free** (`JOINT_NOISE_FREE=1`): every observation is the true model's prediction through the case's own transport.\n\n");
    }
    eprintln!(
        "{scene}: prepared in {:.1} + {:.1} s, {} vertices, {} train / {} held-out observations",
        case.seconds_synth,
        case.seconds_prepare,
        case.nv,
        case.train.obs.len(),
        case.held.obs.len()
    );
    md.push_str(&format!(
        "## 2. Joint recovery: `{scene}`\n\nSpot ({} vertices), two blended materials ({}), \
         {} training and {} held-out photos ({}², {} spp × {} MIS pairs), 8 real maps cycling, each rotated; basis = the true lobes \
         ({}); {}² global map, {}² local, {}² normal grid, all coefficients kept; K = 2 from the k-means start.\n\n\
         Materials are identifiable only up to a K×K non-negative remix (`w → w M⁻¹`, `λ → M λ` leaves every vertex's reflectance \
         `β = Σ_k w_k λ_k` unchanged) and each channel only up to the light colour (`λ_c → s_c λ_c`, maps `/ s_c`). The diffuse-ratio \
         error is therefore measured on what the data determine: per channel, the median estimated Lambertian weight `β̂_{{x,L,c}}` over the \
         vertices that are truly pure material 1 over the same median for material 2, against the truth's `λ_1,L,c / λ_2,L,c` \
         (the λ-based figure, not invariant, is shown beside it). Held-out photos are predicted under their TRUE maps with the \
         best scale per channel; the *floor* is the true reflectance doing the same (renderer noise, transport discretisation), \
         *vs true model* compares the estimated and the true reflectance's predictions through the same transport (the \
         estimator's own error, no renderer noise).\n\n",
        case.nv,
        materials_text(&case),
        case.train.names.len(),
        case.held.names.len(),
        s.width,
        s.spp,
        s.light_samples,
        basis_text(&case),
        s.global,
        s.local,
        s.normal_grid
    ));
    md.push_str(JOINT_HEADER);
    let mut rows = Vec::new();
    // The start, for reference: the k-means materials (Lambertian only) with the lights of
    // one lighting step.
    let start = EstimateOptions {
        max_outer: 1,
        ..EstimateOptions::default()
    };
    let long = EstimateOptions {
        max_outer: 30,
        rel_tol: 1e-5,
        ..EstimateOptions::default()
    };
    let from_specs: Option<Vec<(String, EstimateOptions, Start)>> =
        specs_from_env("JOINT_SPECS", &long).map(|v| {
            v.into_iter()
                .map(|sp| (sp.label, sp.opts, sp.start))
                .collect()
        });
    let variants: Vec<(String, EstimateOptions, Start)> = from_specs.unwrap_or_else(|| vec![
        ("after 1 outer iteration".into(), start, PAPER_START),
        (
            format!(
                "default options (early stopping: 10% validation, patience {}), ≤ 30 outer iterations",
                relight_cpc::solve::PATIENCE
            ),
            long.clone(),
            PAPER_START,
        ),
        (
            "no early stopping, ≤ 30 outer iterations".into(),
            EstimateOptions {
                validation_fraction: 0.0,
                ..long.clone()
            },
            PAPER_START,
        ),
    ]);
    let mut md_notes = Vec::new();
    for (label, o, from) in variants {
        let label = label.as_str();
        eprintln!("joint: {label}");
        let o = with_case_priors(&case, &o);
        let (est, secs, tl, record) = joint_fit(&case, &case.train.obs, &o, from);
        let f = joint_figures(&case, &est, &case.train.obs, secs);
        eprintln!("{f:?}");
        joint_row(md, label, &f);
        if let Some(v) = &est.validation {
            md_notes.push(format!(
                "- {label}: {} validation observations; kept iteration {} of {} (validation rel. RMSE {:.4} there, {:.4} at the last){}.\n",
                v.observations,
                v.best_iteration,
                v.errors.len(),
                v.best_error(),
                v.errors.last().unwrap(),
                if v.stopped_early { ", stopped by patience" } else { "" }
            ));
        }
        if record.starts.len() > 1 {
            md_notes.push(format!(
                "- {label}: kept start {} by {}; {}.\n",
                record.chosen,
                record.criterion,
                record
                    .starts
                    .iter()
                    .enumerate()
                    .map(|(i, r)| {
                        let held = tl
                            .iter()
                            .filter(|t| t["start"] == i)
                            .nth(r.kept_iteration - 1)
                            .map_or(f64::NAN, |t| t["heldout_rel_true_light"].as_f64().unwrap_or(f64::NAN));
                        format!(
                            "start {i} ({}): score {:.4}, iteration {} of {} kept, held-out {held:.4}, {:.1} s",
                            r.label, r.score, r.kept_iteration, r.iterations, r.seconds
                        )
                    })
                    .collect::<Vec<_>>()
                    .join("; ")
            ));
        }
        rows.push(json!({"fit": label, "figures": f, "timeline": tl, "lambda": est.lambda, "normalisation": est.normalisation, "validation": est.validation, "starts": record}));
    }
    let truth_train = predict_with(
        &case.train,
        case.nv,
        &case.lambda,
        &case.weights,
        &case.train.lights,
    );
    let train_floor = rel_rmse(&case.train.obs, &truth_train, false).0;
    if !md_notes.is_empty() {
        md.push_str("\nEarly stopping (the figures above are of the iterate returned, `outer its` counts the iterations run; the JSON timeline has every iteration):\n\n");
        for n in md_notes {
            md.push_str(&n);
        }
    }
    md.push_str(&format!(
        "\nTraining floor (true reflectance, true light, training photos): {train_floor:.4}. \
         The timeline (objective, train RMSE and held-out error per outer iteration) is in `estimator.json`.\n\n"
    ));
    json!({"vertices": case.nv, "train_observations": case.train.obs.len(), "heldout_observations": case.held.obs.len(), "fits": rows, "train_floor_true_model": train_floor})
}

fn robust(md: &mut String) -> Value {
    let s = sizes_joint();
    let scene = joint_scene();
    let case = prepare(&scene, s, 1, "robust");
    md.push_str(&format!("## 3. Robustness: 5% bright outliers\n\nThe `{scene}` case of part 2; 5% of the training observations get `+u · y99` in every channel \
        (`u ~ U(0.5, 2)`, `y99` the 99th percentile of the observed values); ≤ 12 outer iterations each. Errors against the CLEAN data \
        and the truth; ratio = corrupted / clean (Huber IRLS). The *w-step cut* (`EstimateOptions::weights_reject`, default 4.685) \
        leaves observations whose lighting residual exceeds 4.685 σ out of the per-vertex blending-weight step. \
        With `ROBUST_SPECS` the rows are those specs (the first must be the clean reference).\n\n"));
    md.push_str(JOINT_HEADER);
    // Early stopping off: this part measures the robust loss over a fixed 12 iterations.
    let base = EstimateOptions {
        max_outer: 12,
        rel_tol: 1e-5,
        validation_fraction: 0.0,
        ..EstimateOptions::default()
    };
    let mut dirty = case.train.obs.clone();
    let hit = corrupt(&mut dirty, 0.05, 7);
    let mut rows = Vec::new();
    let mut fits = Vec::new();
    let cut = EstimateOptions::default().weights_reject;
    let table: Vec<(String, &Observations, EstimateOptions)> =
        if let Some(specs) = specs_from_env("ROBUST_SPECS", &base) {
            specs
                .into_iter()
                .map(|sp| {
                    let obs = if sp.dirty { &dirty } else { &case.train.obs };
                    (sp.label, obs, sp.opts)
                })
                .collect()
        } else {
            default_robust_rows(&base, &case.train.obs, &dirty, cut)
        };
    for (label, obs, o) in table {
        let label = label.as_str();
        eprintln!("robust: {label}");
        let (est, secs, _, _) = joint_fit(&case, obs, &o, PAPER_START);
        let f = joint_figures(&case, &est, &case.train.obs, secs);
        eprintln!("{f:?}");
        joint_row(md, label, &f);
        fits.push((label.to_string(), f.clone()));
        rows.push(json!({"fit": label, "options": format!("{o:?}"), "figures": f}));
    }
    robust_ratios(md, &fits, hit.len());
    json!({"corrupted": hit.len(), "fits": rows})
}

/// Part 3's default rows: clean and 5% outliers under Huber (with and without the w-step
/// cut), Tukey and plain least squares.
fn default_robust_rows<'a>(
    base: &EstimateOptions,
    clean: &'a Observations,
    dirty: &'a Observations,
    cut: Option<f64>,
) -> Vec<(String, &'a Observations, EstimateOptions)> {
    let mut out = Vec::new();
    for (label, obs, robust, weights_reject) in [
        (
            "clean, Huber IRLS (default)",
            clean,
            Robust::Huber { k: 1.345 },
            cut,
        ),
        (
            "5% outliers, Huber IRLS (default)",
            dirty,
            Robust::Huber { k: 1.345 },
            cut,
        ),
        (
            "5% outliers, Huber IRLS, no w-step cut",
            dirty,
            Robust::Huber { k: 1.345 },
            None,
        ),
        (
            "5% outliers, Tukey IRLS",
            dirty,
            Robust::Tukey { c: 4.685 },
            cut,
        ),
        ("5% outliers, no IRLS", dirty, Robust::None, cut),
        ("clean, no IRLS", clean, Robust::None, cut),
    ] {
        let o = EstimateOptions {
            robust,
            weights_reject,
            ..base.clone()
        };
        out.push((label.to_string(), obs, o));
    }
    out
}

/// Part 3's ratios of every row to the first (the clean reference).
fn robust_ratios(md: &mut String, fits: &[(String, JointFigures)], corrupted: usize) {
    let (c_ch, c_model, c_train) = (
        fits[0].1.heldout_rel_channel,
        fits[0].1.heldout_rel_model,
        fits[0].1.train_rel,
    );
    md.push_str(&format!(
        "\n{corrupted} observations corrupted. Ratios to the first row (held-out vs observations / held-out vs true model / train vs clean observations):\n\n"
    ));
    for (l, f) in &fits[1..] {
        md.push_str(&format!(
            "- {l}: ×{:.2} / ×{:.2} / ×{:.2}\n",
            f.heldout_rel_channel / c_ch,
            f.heldout_rel_model / c_model,
            f.train_rel / c_train
        ));
    }
    md.push('\n');
}

fn determinism(md: &mut String) -> Value {
    let s = Sizes {
        width: 64,
        vertices: 2000,
        spp: 4,
        ..sizes_joint()
    };
    let case = prepare("spot-varying", s, 1, "determinism");
    let o = EstimateOptions {
        max_outer: 4,
        ..EstimateOptions::default()
    };
    let bits = estimate_bits;
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| bits(&joint_fit(&case, &case.train.obs, &o, PAPER_START).0))
    };
    let a = run(2);
    let b = run(2);
    let c = run(1);
    let same_ab = a == b;
    let same_ac = a == c;
    md.push_str(&format!(
        "## 4. Determinism\n\n`spot-varying` at 64², 4 outer iterations, the k-means start included: {} output numbers (maps, λ, w). \
         Two runs on 2 threads bitwise identical: {same_ab}; 2 threads against 1 thread bitwise identical: {same_ac}.\n\n",
        a.len()
    ));
    json!({"values": a.len(), "identical_same_threads": same_ab, "identical_1_vs_2_threads": same_ac})
}

/// A case (the joint `spot-varying` one, or a known-reflectance sphere) with every observation (training and held out) replaced by the
/// TRUE reflectance under the TRUE light through the case's own transport: data the model
/// reproduces exactly, so the floor is 0 and every remaining error is the estimator's
/// (regularisation bias, a stalled block, the alternation's speed).
fn noise_free(case: &mut Case) {
    let t = true_prediction(case, &case.train);
    replace_colours(&mut case.train.obs, &t);
    let h = true_prediction(case, &case.held);
    replace_colours(&mut case.held.obs, &h);
}

/// Part 5: convergence of the alternation on noise-free data (`noise_free`), per outer
/// iteration, for option variants; written to `bench-results/estimator-convergence.*`.
fn convergence(md: &mut String) -> Value {
    let s = Sizes {
        spp: 1,
        ..sizes_joint()
    };
    let iters: usize = std::env::var("CONVERGENCE_ITERS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(30);
    let scene = joint_scene();
    let mut case = prepare(&scene, s, 1, "convergence");
    noise_free(&mut case);
    md.push_str(&format!(
        "## 5. Convergence on noise-free data\n\n`{scene}` ({} vertices, {} training / {} held-out photos, {}², {}² global, {}² local, all coefficients) \
         with every observation replaced by the TRUE reflectance under the TRUE light through the case's own transport: the model \
         reproduces the data exactly, so the floor is 0 and what remains is the estimator's own error. K = 2 from the k-means start \
         unless stated; ≤ {iters} outer iterations, `rel_tol` 0. Held-out = the held-out photos under their true light (best scale per channel).\n\n",
        case.nv,
        case.train.names.len(),
        case.held.names.len(),
        s.width,
        s.global,
        s.local
    ));
    let base = EstimateOptions {
        max_outer: iters,
        rel_tol: 0.0,
        validation_fraction: 0.0,
        ..EstimateOptions::default()
    };
    let none = EstimateOptions {
        robust: Robust::None,
        ..base.clone()
    };
    let variants: Vec<(&str, EstimateOptions, Start)> =
        vec![
        ("default options, no early stopping", base.clone(), PAPER_START),
        (
            "the same, started at the TRUE materials",
            base.clone(),
            Start::Truth,
        ),
        ("no IRLS", none.clone(), PAPER_START),
        ("no IRLS, started at the TRUE materials", none.clone(), Start::Truth),
        (
            "no IRLS, smoothness 1e-5",
            EstimateOptions {
                smoothness: 1e-5,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, no extrapolation",
            EstimateOptions {
                extrapolate: false,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, 3 material sweeps",
            EstimateOptions {
                material_sweeps: 3,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, gauge fixed every iteration",
            EstimateOptions {
                fix_gauge: true,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "Huber IRLS in the lighting step only, material step α with the 4.685σ cut",
            EstimateOptions {
                materials_cut_only: true,
                ..base.clone()
            },
            PAPER_START,
        ),
        (
            "default, early stopping (10% validation, patience 3)",
            EstimateOptions {
                validation_fraction: 0.1,
                patience: 3,
                ..base.clone()
            },
            PAPER_START,
        ),
        (
            "Huber k = 3",
            EstimateOptions {
                robust: Robust::Huber { k: 3.0 },
                ..base.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, early stopping (10% validation, patience 3)",
            EstimateOptions {
                validation_fraction: 0.1,
                patience: 3,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, started at the TRUE materials, early stopping (10% validation, patience 3)",
            EstimateOptions {
                validation_fraction: 0.1,
                patience: 3,
                ..none.clone()
            },
            Start::Truth,
        ),
    ];
    let variants: Vec<(String, EstimateOptions, Start)> =
        match specs_from_env("CONVERGENCE_SPECS", &base) {
            Some(specs) => specs
                .into_iter()
                .map(|sp| (sp.label, sp.opts, sp.start))
                .collect(),
            None => variants
                .into_iter()
                .map(|(l, o, t)| (l.to_string(), o, t))
                .collect(),
        };
    let only = std::env::var("CONVERGENCE_VARIANTS")
        .ok()
        .filter(|_| std::env::var("CONVERGENCE_SPECS").is_err());
    md.push_str("| fit | outer its | train rel. RMSE after 1 / 5 / 10 / 20 / last | held-out rel. RMSE after 1 / 5 / 10 / 20 / last | best held-out (iteration) | returned estimate's held-out | seconds |\n|---|---|---|---|---|---|---|\n");
    let mut rows = Vec::new();
    for (vi, (label, o, start)) in variants.into_iter().enumerate() {
        if let Some(sel) = &only {
            if !sel.split(',').any(|v| v == vi.to_string()) {
                continue;
            }
        }
        eprintln!("convergence: {label}");
        let problem = case.train.problem(case.nv);
        let init = start.materials(&case, &case.train.obs);
        let mut tl: Vec<Value> = Vec::new();
        let (mut tr, mut he) = (Vec::new(), Vec::new());
        let t0 = Instant::now();
        let est = estimate(&problem, init, &o, &mut |it, st| {
            let hp = predict_with(&case.held, case.nv, st.lambda, st.weights, &case.held.lights);
            let h = rel_rmse_per_channel(&case.held.obs, &hp);
            let tp = predict_with(&case.train, case.nv, st.lambda, st.weights, st.lights);
            let t = rel_rmse(&case.train.obs, &tp, false).0;
            let lam_l: Vec<f64> = (0..3)
                .map(|c| st.lambda.iter().map(|l| l[0][c]).sum::<f64>())
                .collect();
            let light_sum: f64 = st.lights.iter().flat_map(|l| l.iter().flatten()).sum();
            eprintln!(
                "  {label} it {}: {:.1} s, objective {:.5e}, train rel {t:.5}, held-out rel {h:.5}, Σλ_L {lam_l:.4?}, Σ light {light_sum:.4e}",
                tl.len() + 1,
                it.seconds,
                it.objective
            );
            tr.push(t);
            he.push(h);
            tl.push(json!({"seconds": it.seconds, "objective": it.objective, "train_rel": t, "heldout_rel_true_light": h, "lambda_lambert_sum": lam_l, "light_sum": light_sum}));
        })
        .unwrap();
        let secs = t0.elapsed().as_secs_f64();
        let pick = |v: &[f64]| {
            [1usize, 5, 10, 20]
                .iter()
                .map(|&i| v.get(i - 1).map_or("–".to_string(), |x| format!("{x:.4}")))
                .chain(std::iter::once(format!("{:.4}", v.last().unwrap())))
                .collect::<Vec<_>>()
                .join(" / ")
        };
        let (bi, bh) =
            he.iter().enumerate().fold(
                (0, f64::INFINITY),
                |a, (i, &h)| if h < a.1 { (i, h) } else { a },
            );
        let ret = rel_rmse_per_channel(
            &case.held.obs,
            &case.predict_held(&est.lambda, &est.weights),
        );
        let ret_it = est
            .validation
            .as_ref()
            .map_or(est.timeline.len(), |v| v.best_iteration);
        md.push_str(&format!(
            "| {label} | {} of ≤ {} | {} | {} | {bh:.4} ({}) | {ret:.4} (iteration {ret_it}) | {secs:.1} |\n",
            est.timeline.len(),
            o.max_outer,
            pick(&tr),
            pick(&he),
            bi + 1
        ));
        rows.push(json!({"fit": label, "options": format!("{o:?}"), "from_truth": matches!(start, Start::Truth), "timeline": tl, "seconds": secs, "iterations": est.timeline.len(), "returned_heldout_rel": ret, "returned_iteration": ret_it}));
    }
    md.push('\n');
    json!({"vertices": case.nv, "train_observations": case.train.obs.len(), "heldout_observations": case.held.obs.len(), "fits": rows})
}

/// Part 6: the floors (the TRUE reflectance under the TRUE light through the transport,
/// against the rendered photos) against samples per pixel and transport resolution, to
/// split the renderer's Monte-Carlo noise from the transport's discretisation; written to
/// `bench-results/estimator-floors.*`.
fn floors(md: &mut String) -> Value {
    // `FLOOR_WIDTH`: photo side (default 64); `FLOOR_SPP`: the sample counts (comma list).
    let width: u32 = std::env::var("FLOOR_WIDTH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64);
    md.push_str(&format!("## 6. Floors: Monte-Carlo noise against discretisation\n\n\
        Floor = relative RMSE of the TRUE reflectance under the TRUE light through the transport against the rendered photos \
        (training and held-out photos apart). Photos {width}², the same render reused for every transport of a row group \
        (only the transport is rebuilt). Noise halves with 4× the samples; discretisation does not move with samples.\n\n\
        | scene | spp × MIS pairs | global² / local² | floor (train) | floor (held out) | seconds synth / prepare |\n|---|---|---|---|---|---|\n"));
    let mut rows = Vec::new();
    // (scene, samples per pixel, (global, local) transports).
    type Group<'a> = (&'a str, Vec<u32>, Vec<(usize, usize)>);
    let groups: Vec<Group> = vec![
        ("sphere-diffuse", vec![16, 64], vec![(32, 16), (64, 32)]),
        ("sphere-glossy", vec![16, 64], vec![(32, 16), (64, 32)]),
        ("sphere-specular", vec![16, 64], vec![(32, 16), (64, 32)]),
        ("spot-varying", vec![8, 32], vec![(16, 8), (32, 16)]),
        ("spot-ggx", vec![8, 32], vec![(16, 8), (32, 16), (64, 32)]),
    ];
    // `FLOOR_NORMAL_GRID`: the rotations' normal grid side (default 16).
    let normal_grid: usize = std::env::var("FLOOR_NORMAL_GRID")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(16);
    let spp_override: Option<Vec<u32>> = std::env::var("FLOOR_SPP")
        .ok()
        .map(|v| v.split(',').map(|x| x.trim().parse().unwrap()).collect());
    let only = std::env::var("FLOOR_SCENES").ok();
    for (scene, spps, trans) in groups {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|v| v == scene))
        {
            continue;
        }
        for spp in spp_override.clone().unwrap_or(spps) {
            let s0 = Sizes {
                width,
                vertices: 2_500,
                spp,
                ..sizes_known()
            };
            let dir = scratch(&format!("floors-{scene}-{spp}-{width}"));
            let secs = synthesize(scene, &dir.0.join("ws"), s0, 1);
            for &(g, l) in &trans {
                let s = Sizes {
                    global: g,
                    local: l,
                    normal_grid,
                    ..s0
                };
                // `prepare_in` takes ownership of a scratch guard; the real guard `dir`
                // outlives it and removes the folder at the end of the spp loop body.
                let case = prepare_in(scene, Scratch(dir.0.clone()), secs, s, 1);
                let t = predict_with(
                    &case.train,
                    case.nv,
                    &case.lambda,
                    &case.weights,
                    &case.train.lights,
                );
                let ft = rel_rmse(&case.train.obs, &t, false).0;
                let h = case.predict_held(&case.lambda, &case.weights);
                let fh = if case.held.obs.is_empty() {
                    f64::NAN
                } else {
                    rel_rmse(&case.held.obs, &h, false).0
                };
                eprintln!("floors {scene} spp {spp} {g}/{l}: train {ft:.4}, held {fh:.4}, {secs:.1} / {:.1} s", case.seconds_prepare);
                md.push_str(&format!(
                    "| {scene} | {spp} × {} | {g}² / {l}² | {ft:.4} | {} | {secs:.1} / {:.1} |\n",
                    s.light_samples,
                    if fh.is_finite() {
                        format!("{fh:.4}")
                    } else {
                        "–".into()
                    },
                    case.seconds_prepare
                ));
                rows.push(json!({"scene": scene, "spp": spp, "light_samples": s.light_samples, "global": g, "local": l, "floor_train": ft, "floor_heldout": if fh.is_finite() { json!(fh) } else { Value::Null }, "observations": case.train.obs.len(), "seconds_synth": secs, "seconds_prepare": case.seconds_prepare}));
                std::mem::forget(case.scratch);
            }
        }
    }
    md.push('\n');
    json!(rows)
}

fn main() {
    let parts = std::env::var("ESTIMATOR_BENCH")
        .unwrap_or_else(|_| "known,joint,robust,determinism".into());
    let mut md = String::from(
        "# Estimator on known-truth scenes\n\nWritten by `cargo bench --bench estimator`.\n\n",
    );
    let mut out = serde_json::Map::new();
    if parts.contains("known") {
        out.insert("known_reflectance".into(), known(&mut md));
    }
    if parts.contains("joint") {
        out.insert("joint".into(), joint(&mut md));
    }
    if parts.contains("robust") {
        out.insert("robustness".into(), robust(&mut md));
    }
    if parts.contains("determinism") {
        out.insert("determinism".into(), determinism(&mut md));
    }
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("bench-results");
    std::fs::create_dir_all(&dir).unwrap();
    if parts.contains("floors") {
        let mut fmd = String::from(
            "# Estimator bench floors\n\nWritten by `ESTIMATOR_BENCH=floors cargo bench --bench estimator`.\n\n",
        );
        let v = floors(&mut fmd);
        write_results(&dir, "estimator-floors", &fmd, &v);
        if parts == "floors" {
            return;
        }
    }
    if parts.contains("convergence") {
        // Its own files: the diagnosis of the alternation, not one of the figures.
        let mut cmd = String::from(
            "# Estimator convergence on noise-free data\n\nWritten by `ESTIMATOR_BENCH=convergence cargo bench --bench estimator`.\n\n",
        );
        let v = convergence(&mut cmd);
        write_results(&dir, "estimator-convergence", &cmd, &v);
        if parts == "convergence" {
            return;
        }
    }
    write_results(&dir, "estimator", &md, &Value::Object(out));
}

/// `dir/STEM.md` and `dir/STEM.json`, and the Markdown on standard output.
/// `RESULTS_SUFFIX=S` writes `STEM-S.*` instead (a run of a few variants, merged into the
/// main files by hand).
fn write_results(dir: &std::path::Path, stem: &str, md: &str, v: &Value) {
    let stem = match std::env::var("RESULTS_SUFFIX") {
        Ok(sfx) if !sfx.is_empty() => format!("{stem}-{sfx}"),
        _ => stem.to_string(),
    };
    std::fs::write(dir.join(format!("{stem}.md")), md).unwrap();
    std::fs::write(
        dir.join(format!("{stem}.json")),
        serde_json::to_string_pretty(v).unwrap(),
    )
    .unwrap();
    println!("{md}");
}
