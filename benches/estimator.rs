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
//! `ESTIMATOR_BENCH=known,joint,robust,determinism` picks parts (default: all; `convergence`,
//! `floors` and `propagate`, the cost of filling unseen vertices' materials on the large
//! Spot meshes, write their own files). Variants without editing the bench:
//! `JOINT_SPECS` / `ROBUST_SPECS` / `CONVERGENCE_SPECS` replace a part's rows by option
//! strings ([`parse_spec`], e.g. `"floor=0.1;floor=0.1,val=0"`); `JOINT_SCENE` (default
//! `spot-varying`) and `JOINT_GLOBAL`, `JOINT_LOCAL`, `JOINT_SPP`, `JOINT_VERTICES`,
//! `JOINT_WIDTH`, `JOINT_PHOTOS` set parts 2, 3 and 5's case (`JOINT_SEED` the joint
//! part's render seed, default 1); `KNOWN_SCENES`, `KNOWN_FINE=1`
//! and `KNOWN_NOISE_FREE=1` (every observation the true map's prediction through the
//! transport: the estimator's own error) part 1's; `FLOOR_SCENES`, `FLOOR_WIDTH`, `FLOOR_SPP`,
//! `FLOOR_NORMAL_GRID` part 6's; `RESULTS_SUFFIX=S` writes `STEM-S.{md,json}`. Sizes are
//! chosen to keep the whole run near 15 CPU minutes: parts 2–4 use a 16² global and 8²
//! local map (32² / 16² cost ~20× more per outer iteration on Spot).
//!
//! This file holds the shared sizes, option strings, the noise-free case and `main`; each
//! part is a module in `benches/estimator/` (`known`, `joint`, `robust`, `determinism`,
//! `convergence`, `floors`, `propagate`).

#![allow(clippy::needless_range_loop)]

#[path = "../tests/support/synth_case.rs"]
mod synth_case;

#[path = "estimator/convergence.rs"]
mod convergence;
#[path = "estimator/determinism.rs"]
mod determinism;
#[path = "estimator/floors.rs"]
mod floors;
#[path = "estimator/joint.rs"]
mod joint;
#[path = "estimator/known.rs"]
mod known;
#[path = "estimator/propagate.rs"]
mod propagate;
#[path = "estimator/robust.rs"]
mod robust;
#[path = "support/run_line.rs"]
mod run_line;
#[path = "support/today.rs"]
mod today;

use relight_cpc::observe::Observations;
use relight_cpc::solve::light::sh_prior::LightPriorOptions;
use relight_cpc::solve::light::shared::LightGroups;
use relight_cpc::solve::light::sky::clock::ClockSuns;
use relight_cpc::solve::starts::{self, estimate_best, MultiStart};
use relight_cpc::solve::{estimate, Estimate, EstimateOptions, Robust, SmoothnessScale};
use serde_json::{json, Value};
use std::time::Instant;
use synth_case::*;
use {convergence::*, determinism::*, floors::*, joint::*, known::*, propagate::*, robust::*};

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
/// `qp` (`alternation_qp_iters`, 0 = every lighting QP to the KKT tolerance), `ws`
/// (`weights_sum`),
/// `shared=1` (one map per group of training photos under the same true map, with
/// per-photo gains), `truth=1` (start at the true materials; parts 2 and 5), `spec0=f` (parts 2 and 5: the clustered
/// start with every non-Lambertian basis at `f` × the material's mean Lambertian weight, grey,
/// instead of 0), `start=s` (parts 2 and 5: start number `s` of `starts::variants`),
/// `starts=n` (part 2: the best of the first `n` of them, `starts::estimate_best`), `dirty=1` (5% outliers, part 3),
/// `prior=η` / `haar=η` (the light prior's SH and Haar noise levels), `sky=η` (the
/// sun-and-sky light model with residual noise level η), `geotag=1` (with `sky`: the suns
/// of the training photos' geotags, a scene rendered with `SYNTH_GEOTAG=1`); `base` alone
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
            // The blending weights' sum-to-one prior (issue 25) at strength τ.
            "ws" => o.weights_sum = num(),
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
            // The sun-and-sky model's suns from the training photos' geotags (a scene
            // rendered with `SYNTH_GEOTAG=1`; [`with_case_groups`] fills them in).
            "geotag" => {
                o.sun_clock = (num() > 0.0).then(|| ClockSuns {
                    per_photo: Vec::new(),
                    source: String::new(),
                })
            }
            // Shared light (issue 25): photos rendered under the same true map (and
            // rotation) share one fitted map with per-photo gains ([`with_case_groups`]).
            "shared" => {
                o.light_groups = (num() > 0.0).then(|| LightGroups {
                    group: Vec::new(),
                    source: String::new(),
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

/// `o` with its light groups (spec `shared=1`) filled in from the case's truth (training
/// photos with the same map and rotation in `truth/manifest.json` share a group), and its
/// geotag suns (spec `geotag=1`) from the case's photos.
fn with_case_groups(case: &Case, o: &EstimateOptions) -> EstimateOptions {
    let mut o = o.clone();
    if o.light_groups.is_some() {
        o.light_groups = Some(case.true_light_groups());
    }
    if o.sun_clock.is_some() {
        o.sun_clock = Some(
            case.geotag_suns
                .clone()
                .expect("spec geotag=1 needs a scene rendered with SYNTH_GEOTAG=1"),
        );
    }
    o
}

/// The specs in environment variable `var`, if set.
fn specs_from_env(var: &str, base: &EstimateOptions) -> Option<Vec<Spec>> {
    std::env::var(var)
        .ok()
        .map(|v| v.split(';').map(|s| parse_spec(s, base)).collect())
}

/// The seed the joint part's scene is rendered with (`JOINT_SEED`, default 1).
fn joint_seed() -> u64 {
    std::env::var("JOINT_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
}

/// The joint parts' scene (`JOINT_SCENE`, default `spot-varying`).
fn joint_scene() -> String {
    std::env::var("JOINT_SCENE").unwrap_or_else(|_| "spot-varying".into())
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

fn main() {
    let parts = std::env::var("ESTIMATOR_BENCH")
        .unwrap_or_else(|_| "known,joint,robust,determinism".into());
    let mut md = String::from(
        "# Estimator on known-truth scenes\n\nWritten by `cargo bench --bench estimator`.\n\n",
    );
    md.push_str(&run_line::environment_line(
        "estimator",
        &[
            "ESTIMATOR_BENCH",
            "JOINT_",
            "KNOWN_",
            "ROBUST_",
            "CONVERGENCE_",
            "SYNTH_",
            "RESULTS_SUFFIX",
        ],
    ));
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
    if parts.contains("propagate") {
        // Its own files: a cost, not one of the estimator's accuracy figures.
        let mut pmd = String::from(
            "# Propagating materials to unseen vertices: cost\n\nWritten by `ESTIMATOR_BENCH=propagate cargo bench --bench estimator`.\n\n",
        );
        let v = propagate(&mut pmd);
        write_results(&dir, "estimator-propagate", &pmd, &v);
        if parts == "propagate" {
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
