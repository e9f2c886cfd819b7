//! The sun-and-sky light model (`--light sky`, issue 25) on a known-truth outdoor scene:
//! `spot-sky` is rendered by the reference renderer under a clear sky (Hosek–Wilkie),
//! a sun lobe and a ground term with a different, recorded sun direction per photo
//! (`truth/manifest.json`), every 4th photo held out.

use crate::synth_case::*;
use relight_cpc::solve::light::sky::{SkyLight, SkyOptions};
use relight_cpc::solve::light::{LightModel, LightingInput, LightingOutput};
use relight_cpc::solve::{beta_per_vertex, estimate, Conditioning, Estimate, EstimateOptions};
use relight_cpc::Vec3;

/// The case and the true sun direction of each training photo (from the manifest).
struct SkyCase {
    case: Case,
    suns: Vec<Vec3>,
}

fn sky_case() -> &'static SkyCase {
    static CASE: std::sync::OnceLock<SkyCase> = std::sync::OnceLock::new();
    CASE.get_or_init(|| {
        let case = prepare("spot-sky", Sizes::spot_small(), 1, "spot-sky");
        let manifest: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(case.scratch.0.join("ws/truth/manifest.json")).unwrap(),
        )
        .unwrap();
        let suns = case
            .train
            .names
            .iter()
            .map(|n| {
                let p = manifest["photos"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|p| p["name"] == n.as_str())
                    .unwrap_or_else(|| panic!("{n} not in the manifest"));
                let s: Vec<f64> = p["sun"]
                    .as_array()
                    .unwrap_or_else(|| panic!("{n}: no sun in the manifest"))
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect();
                Vec3::new(s[0], s[1], s[2])
            })
            .collect();
        let _ = std::fs::remove_dir_all(&case.scratch.0);
        SkyCase { case, suns }
    })
}

/// One sky lighting step with the materials `(lambda, weights)` fixed: the recovered sun
/// directions' angles to the truth, degrees.
fn sun_errors(c: &SkyCase, lambda: &[Vec<[f64; 3]>], weights: &[f64]) -> Vec<f64> {
    let case = &c.case;
    let problem = case.train.problem(case.nv);
    let opts = EstimateOptions::default();
    let mut light = SkyLight::new(&problem, &opts, &SkyOptions::default()).unwrap();
    let beta = beta_per_vertex(lambda, weights, case.nv);
    let mut irls = vec![[0.0_f32; 3]; case.train.obs.rgb.len()];
    let mut cond = Conditioning::default();
    light
        .fit(
            &LightingInput {
                problem: &problem,
                beta: &beta,
                outer_iteration: 1,
            },
            &mut LightingOutput {
                irls_weights: &mut irls,
                conditioning: &mut cond,
            },
        )
        .unwrap();
    let maps = light.maps(light.params());
    assert!(maps
        .iter()
        .flatten()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
    light
        .thetas()
        .iter()
        .zip(&c.suns)
        .map(|(t, s)| t.sun.dot(s).clamp(-1.0, 1.0).acos().to_degrees())
        .collect()
}

#[test]
fn known_reflectance_recovers_every_sun_direction() {
    // The true materials fixed: the grid (~18° apart) and the pattern search must find the
    // sun of every training photo. The transport sees the light on a 16² global map
    // (texels ~12.7° across) through 8² local hemispheres (~18°), and the sun lobe (κ =
    // 300, ~3° wide) lies inside one texel, so its centre is located only to about a
    // texel where few normals face it: bound 15° for every photo (measured max 12.5°) and
    // 5° for the median, i.e. well inside a texel (measured 3.3°).
    let c = sky_case();
    let err = sun_errors(c, &c.case.lambda, &c.case.weights);
    eprintln!("sun direction errors, true materials (°): {err:.2?}");
    assert!(err.iter().all(|e| *e <= 15.0), "{err:?}");
    assert!(median(&err) <= 5.0, "{err:?}");
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

fn joint(case: &Case, light_sky: Option<SkyOptions>) -> (Estimate, f64) {
    let problem = case.train.problem(case.nv);
    let init = initial(case, &case.train.obs, 2, 1);
    let o = EstimateOptions {
        max_outer: 8,
        rel_tol: 1e-5,
        light_sky,
        ..EstimateOptions::default()
    };
    let t0 = std::time::Instant::now();
    let est = estimate(&problem, init, &o, &mut |_, _| {}).unwrap();
    (est, t0.elapsed().as_secs_f64())
}

#[test]
fn joint_fit_under_a_sky_predicts_held_out_photos_at_least_as_well_as_the_free_map() {
    // Joint recovery from the k-means start, ≤ 8 outer iterations each, the same options
    // but the light model. The held-out photos under their TRUE light (per-channel scale)
    // measure the materials; the sky model constrains each photo's light to a sun, a sky
    // and a penalised residual, so it must not do worse than the paper's free map (5%
    // slack for the two runs' different stopping points; measured: see the eprintln and
    // bench-results/estimator-sky.md; measured 0.229 against 0.241, floor 0.096). The sun
    // directions recovered with the fitted materials: the median within 8° (measured
    // 5.7°) and all but one photo within 12° (measured max 8.7° over those 11). The one
    // allowed is the least constrained photo: 12.5° off even under the true materials
    // (the test above), it loses its sun (87°) under the fitted ones.
    let c = sky_case();
    let case = &c.case;
    let (paper, tp) = joint(case, None);
    let (sky, ts) = joint(case, Some(SkyOptions::default()));
    let fp = joint_figures(case, &paper, &case.train.obs, tp);
    let fs = joint_figures(case, &sky, &case.train.obs, ts);
    eprintln!("paper: {fp:?}\nsky: {fs:?}");
    assert!(sky
        .lights
        .iter()
        .flatten()
        .flatten()
        .chain(sky.lambda.iter().flatten().flatten())
        .all(|v| v.is_finite() && *v >= 0.0));
    assert!(
        fs.heldout_rel_channel <= 1.05 * fp.heldout_rel_channel,
        "held-out: sky {:.4} vs paper {:.4} (floor {:.4})",
        fs.heldout_rel_channel,
        fp.heldout_rel_channel,
        fs.heldout_floor
    );
    let err = sun_errors(c, &sky.lambda, &sky.weights);
    eprintln!("sun direction errors, fitted materials (°): {err:.2?}");
    assert!(
        err.iter().filter(|e| **e <= 12.0).count() + 1 >= err.len(),
        "{err:?}"
    );
    assert!(median(&err) <= 8.0, "{err:?}");
}
