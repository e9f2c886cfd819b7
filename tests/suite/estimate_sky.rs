//! The sun-and-sky light model (`--light sky`, issue 25) on a known-truth outdoor scene:
//! `spot-sky` is rendered by the reference renderer under a clear sky (Hosek–Wilkie),
//! a sun lobe and a ground term with a different, recorded sun direction per photo
//! (`truth/manifest.json`), every 4th photo held out.

use crate::synth_case::*;
use relight_cpc::observe::Observations;
use relight_cpc::solve::light::sky::clock::{ClockSun, ClockSuns};
use relight_cpc::solve::light::sky::{SkyLight, SkyOptions, SunSky};
use relight_cpc::solve::light::{LightModel, LightingInput, LightingOutput};
use relight_cpc::solve::{
    basis_responses, beta_per_vertex, estimate, predict_from, Conditioning, Estimate,
    EstimateOptions,
};
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
            .names()
            .map(|n| {
                let p = manifest["photos"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .find(|p| p["name"] == n)
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
    sun_step(c, lambda, weights, None).0
}

/// The frame azimuth of north in [`geotag_suns`]: off the 5° grid of the north search.
const TRUE_NORTH: f64 = 1.9;

/// The suns of the training photos as their geotags would give them were north at frame
/// azimuth [`TRUE_NORTH`]: the elevation of the true sun, its compass azimuth `ν − φ`.
fn geotag_suns(c: &SkyCase) -> ClockSuns {
    let per_photo = c
        .suns
        .iter()
        .map(|s| {
            let (phi, elevation) = SunSky {
                sun: *s,
                turbidity: 3.0,
                kappa: 1.0,
            }
            .angles();
            Some(ClockSun {
                elevation,
                compass_azimuth: TRUE_NORTH - phi,
            })
        })
        .collect();
    ClockSuns {
        per_photo,
        source: "the true suns".into(),
    }
}

/// The angle between two frame azimuths, degrees.
fn azimuth_gap(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d).to_degrees()
}

/// [`sun_errors`] with the suns' geotags `clock`, and the north found.
fn sun_step(
    c: &SkyCase,
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    clock: Option<ClockSuns>,
) -> (Vec<f64>, Option<f64>) {
    let case = &c.case;
    let problem = case.train.problem(case.nv);
    let opts = EstimateOptions {
        sun_clock: clock,
        ..EstimateOptions::default()
    };
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
    let err = light
        .thetas()
        .iter()
        .zip(&c.suns)
        .map(|(t, s)| t.sun.dot(s).clamp(-1.0, 1.0).acos().to_degrees())
        .collect();
    (err, light.north())
}

#[test]
fn geotags_fix_every_sun_up_to_one_north() {
    // The true materials fixed and every training photo geotagged (its true sun's
    // elevation and its compass azimuth for a north at TRUE_NORTH): the north search over
    // the summed error must find that north, and with it every sun. North comes out on a
    // 0.5° grid (0.25° from the score's minimum) and the score pools 12 photos whose suns
    // the free search places to a median 3.3° (the test above): bound 2°. A photo's sun
    // is then off by at most the north's error (less at elevation e: × cos e).
    let c = sky_case();
    let (err, north) = sun_step(c, &c.case.lambda, &c.case.weights, Some(geotag_suns(c)));
    let north = north.expect("a north from the geotagged photos");
    let gap = azimuth_gap(north, TRUE_NORTH);
    eprintln!("north off by {gap:.2}°; sun errors (°): {err:.2?}");
    assert!(
        gap <= 2.0,
        "north {:.2}° vs {:.2}°",
        north.to_degrees(),
        TRUE_NORTH.to_degrees()
    );
    assert!(err.iter().all(|e| *e <= gap + 1e-6), "{err:?}");
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
    joint_with(case, light_sky, None)
}

fn joint_with(
    case: &Case,
    light_sky: Option<SkyOptions>,
    sun_clock: Option<ClockSuns>,
) -> (Estimate, f64) {
    let problem = case.train.problem(case.nv);
    let init = initial(case, &case.train.obs, 2, 1);
    let o = EstimateOptions {
        max_outer: 8,
        rel_tol: 1e-5,
        light_sky,
        sun_clock,
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
    // (the test above), it loses its sun (87°) under the fitted ones. A third fit gives
    // every photo a geotag (geotag_suns).
    let c = sky_case();
    let case = &c.case;
    let (paper, tp) = joint(case, None);
    let (sky, ts) = joint(case, Some(SkyOptions::default()));
    let fp = joint_figures(case, &paper, &case.train.obs, tp);
    let fs = joint_figures(case, &sky, &case.train.obs, ts);
    eprintln!("paper: {fp:?}\nsky: {fs:?}");
    let (geo, tg) = joint_with(case, Some(SkyOptions::default()), Some(geotag_suns(c)));
    let fg = joint_figures(case, &geo, &case.train.obs, tg);
    eprintln!("sky with geotags: {fg:?}");
    let (geo_err, north) = sun_step(c, &geo.lambda, &geo.weights, Some(geotag_suns(c)));
    let gap = azimuth_gap(north.unwrap(), TRUE_NORTH);
    eprintln!("geotagged: north off by {gap:.2}°, sun errors {geo_err:.2?}");
    // With geotags every sun holds under the fitted materials too (the bound of
    // geotags_fix_every_sun_up_to_one_north; measured 0.14°), and the held-out photos are
    // predicted at least as well as without them (the same 5% slack; measured 0.202
    // against 0.229).
    assert!(
        gap <= 2.0 && geo_err.iter().all(|e| *e <= gap + 1e-6),
        "{gap} {geo_err:?}"
    );
    assert!(
        fg.heldout_rel_channel <= 1.05 * fs.heldout_rel_channel,
        "held-out: geotagged {:.4} vs sky {:.4}",
        fg.heldout_rel_channel,
        fs.heldout_rel_channel
    );
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

#[test]
fn the_ratio_step_runs_under_the_sky_with_every_sun_held() {
    // The ratio step mixes the probes' lights (`LightModel::combine`); the sun-and-sky
    // model holds each photo's θ and north through the probes (`hold_shape`), so its
    // colour weights and residuals mix and no round is left unsupported: every round
    // asked for tries its move (one direction, two materials) until the patience ends it.
    // Holding θ must not cost the geotags their suns: every sun within the north's error
    // and the north within 2° (the bounds of the joint test above).
    let c = sky_case();
    let case = &c.case;
    let problem = case.train.problem(case.nv);
    let o = EstimateOptions {
        max_outer: 4,
        rel_tol: 1e-5,
        ratio_steps: 4,
        light_sky: Some(SkyOptions::default()),
        sun_clock: Some(geotag_suns(c)),
        ..EstimateOptions::default()
    };
    let est = estimate(
        &problem,
        initial(case, &case.train.obs, 2, 1),
        &o,
        &mut |_, _| {},
    )
    .unwrap();
    let m = &est.ratio_moves;
    eprintln!("{m:?}");
    assert_eq!(m.unsupported, 0, "{m:?}");
    assert_eq!(m.tried, m.stopped_after.unwrap_or(4), "{m:?}");
    let sky = est.sky.as_ref().expect("the sky model's fit");
    let gap = azimuth_gap(sky.north.unwrap(), TRUE_NORTH);
    let err: Vec<f64> = sky
        .photos
        .iter()
        .zip(&c.suns)
        .map(|(p, s)| p.theta.sun.angle(s).to_degrees())
        .collect();
    assert!(
        gap <= 2.0 && err.iter().all(|e| *e <= gap + 1e-6),
        "{gap} {err:?}"
    );
}

/// A small geotagged `spot-sky` workspace (`synth --geotag`: 8 photos of 48², 600
/// vertices, 1 sample per pixel) in `dir/ws`, rendered with `seed`.
fn geotag_workspace(dir: &std::path::Path, seed: u64) -> std::path::PathBuf {
    use relight_cpc::synth::{build, SynthOptions};
    use relight_cpc::transport::reference::Samples;
    let ws = dir.join("ws");
    let opts = SynthOptions {
        width: 48,
        height: 48,
        photos: Some(8),
        vertices: Some(600),
        geotag: true,
        samples: Samples {
            per_pixel: 1,
            light: 8,
            seed,
        },
        points: 400,
        ..SynthOptions::default()
    };
    build("spot-sky", &ws, &opts).unwrap();
    ws
}

/// `run` on [`geotag_workspace`] under `light`, into `out`: 16² maps, 2 rounds, 2
/// materials, no progress bars or training renders.
fn small_sky_run(
    ws: &std::path::Path,
    out: std::path::PathBuf,
    light: relight_cpc::solve::light::choose::LightChoice,
) -> relight_cpc::run::RunOptions {
    use relight_cpc::run::{MaterialCount, RunOptions};
    let mut o = RunOptions::new(ws.to_path_buf(), out);
    o.light = light;
    o.global_resolution = 16;
    o.keep = 64;
    o.max_iterations = 2;
    o.materials = MaterialCount::Fixed(2);
    o.progress = false;
    o.render_training = false;
    o
}

/// Under the sun and sky the lighting step does not reweight (only overexposed
/// observations get bounds), so the robust loss and plain least squares fit the same, and
/// `--loss auto` keeps the robust loss without fitting both
/// ([`relight_cpc::solve::loss_choice::loss_acts`]). Checked on a geotagged workspace:
/// `--loss plain` and `--loss robust` give the same training error, bit for bit (the
/// premise), and `auto` gives `--loss robust`'s fit and headline, bit for bit, and says
/// why it did not choose.
#[test]
fn under_the_sky_either_loss_fits_the_same_and_auto_does_not_choose() {
    use relight_cpc::run::run;
    use relight_cpc::solve::light::choose::LightChoice;
    use relight_cpc::solve::loss_choice::{LossChoice, SKY_WHY};
    let dir = scratch("sky-loss");
    let ws = geotag_workspace(&dir.0, 1);
    let with = |loss: LossChoice| {
        let out = dir.0.join(format!("out-{}", loss.name()));
        let mut o = small_sky_run(&ws, out, LightChoice::Sky);
        o.loss = loss;
        run(&o).expect("run --light sky").report
    };
    let (auto, robust, plain) = (
        with(LossChoice::Auto),
        with(LossChoice::Robust),
        with(LossChoice::Plain),
    );
    assert_eq!(robust.train_rmse, plain.train_rmse, "the premise");
    assert_eq!(auto.train_rmse, robust.train_rmse);
    assert_eq!(auto.headline, robust.headline);
    assert!(
        auto.model.reasons.iter().any(|r| r == SKY_WHY),
        "{:?}",
        auto.model.reasons
    );
}

/// A geotagged outdoor workspace through `run --light sky`: `synth --geotag` writes each
/// photo's place and UTC time into its PNG, and the run reads them back. The suns the
/// geotags give, turned by the north `synth` drew, are the suns it rendered with: the
/// time is written to the second (the sun moves 0.0042° a second) and the place to
/// 1e-4″, so 0.01° bounds the round trip. The run then says the suns came from the
/// geotags, of every training photo.
#[test]
fn a_geotagged_workspace_gives_run_its_suns() {
    use relight_cpc::run::run;
    use relight_cpc::solve::light::choose::LightChoice;
    let dir = scratch("geotag-run");
    let ws = geotag_workspace(&dir.0, 1);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ws.join("truth/manifest.json")).unwrap())
            .unwrap();
    let north = manifest["north_radians"]
        .as_f64()
        .expect("north in the manifest");
    for p in manifest["photos"].as_array().unwrap() {
        let path = ws.join("images").join(p["name"].as_str().unwrap());
        let suns = relight_cpc::run::geotag_suns::suns_of(&[path.as_path()]).unwrap();
        let sun = suns.per_photo[0].unwrap();
        let got = SunSky::from_angles(sun.frame_azimuth(north), sun.elevation, 3.0, 1.0).sun;
        let want: Vec<f64> = p["sun"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let angle = got
            .dot(&Vec3::new(want[0], want[1], want[2]))
            .clamp(-1.0, 1.0)
            .acos();
        assert!(
            angle.to_degrees() < 0.01,
            "{}: {:.4}°",
            p["name"],
            angle.to_degrees()
        );
    }
    let o = small_sky_run(&ws, dir.0.join("out"), LightChoice::Sky);
    let r = run(&o)
        .expect("run --light sky on a geotagged workspace")
        .report;
    assert_eq!(r.model.light.as_ref().unwrap().model, "sky");
    assert!(
        r.model
            .reasons
            .iter()
            .any(|s| s.contains("the sun of 6 of the 6 training photos from their geotags")),
        "{:?}",
        r.model.reasons
    );
    // The report's suns against the rendered ones. A clock sun is placed from the run's
    // horizon (the cameras' up) at the fitted north, so it lies off the rendered sun by
    // the composition of two rotations, the up's tilt and north's error: at most their
    // sum (the angle of a composed rotation is at most the sum of the angles), plus
    // 0.01° for the geotag's rounding (above). North is searched on a 0.5° grid by a fit
    // of 2 rounds at 48² photos, whose 16² map has 11°-wide texels: a texel bounds it.
    // Protocol (b) fits both geotagged held-out photos within the sun and sky.
    assert!(
        r.notes
            .iter()
            .any(|n| n.contains("protocol `half` fits the light of 2 of the 2 held-out photos")),
        "{:?}",
        r.notes
    );
    let sky = r.model.sky.as_ref().expect("the report's sun and sky");
    assert_eq!(sky.photos.len(), 6);
    let up = sky
        .cameras_up_error_degrees
        .expect("the cameras' up against the truth's");
    let north = sky
        .truth_north_error_degrees
        .expect("north against the truth's");
    assert!(north < 11.0, "north {north:.2}° from the truth's");
    for p in &sky.photos {
        assert_eq!(p.sun_from, "geotag", "{}", p.image);
        let e = p.truth_error_degrees.expect("each sun against the truth's");
        assert!(
            e <= up + north + 0.01,
            "{}: {e:.3}° against up {up:.3}° + north {north:.3}°",
            p.image
        );
    }
}

/// `--light auto` scores its candidates on the right halves of 4 training photos held
/// back whole, then fits the model it keeps again with the run's own early stopping: the
/// result is that model's run, to the last bit (the refit has the same options, data and
/// seed as `--light <model>`; the scores are the halves' and not what the kept fit's early
/// stopping saw). The reason says how the candidates were scored. `--light constrained`
/// scores the same candidates but the paper's map to the same bits.
#[test]
fn light_auto_scores_on_photo_halves_and_refits_the_model_kept() {
    use relight_cpc::run::run;
    use relight_cpc::solve::light::choose::LightChoice;
    let dir = scratch("light-auto-halves");
    let ws = geotag_workspace(&dir.0, 2);
    let options = |light: LightChoice, out: &str| small_sky_run(&ws, dir.0.join(out), light);
    let auto = run(&options(LightChoice::Auto, "auto"))
        .expect("run --light auto")
        .report;
    let decision = auto.model.light.as_ref().expect("the light decision");
    assert_eq!(decision.scores.len(), 3, "{decision:?}");
    assert!(
        decision
            .why
            .contains("scored on the right halves of 4 training photos held back whole"),
        "{}",
        decision.why
    );
    let kept = LightChoice::parse(&decision.model).unwrap();
    let direct = run(&options(kept, "direct"))
        .expect("run with the model kept")
        .report;
    assert_eq!(auto.train_rmse.to_bits(), direct.train_rmse.to_bits());
    assert_eq!(auto.holdout.len(), direct.holdout.len());
    for (a, d) in auto.holdout.iter().zip(&direct.holdout) {
        assert_eq!(
            (a.image.as_str(), a.protocol.as_str(), a.rmse.to_bits()),
            (d.image.as_str(), d.protocol.as_str(), d.rmse.to_bits())
        );
    }
    let best = decision
        .scores
        .iter()
        .map(|(_, s)| *s)
        .fold(f64::INFINITY, f64::min);
    let kept_score = decision
        .scores
        .iter()
        .find(|(n, _)| *n == decision.model)
        .map(|(_, s)| *s);
    assert_eq!(kept_score, Some(best), "{decision:?}");
    // `--light constrained`: the same candidates but the paper's map, scored on the same
    // halves with the same options and seed, so each score is auto's to the bit, and the
    // lower of the two is kept.
    let constrained = run(&options(LightChoice::Constrained, "constrained"))
        .expect("run --light constrained")
        .report;
    let c = constrained
        .model
        .light
        .as_ref()
        .expect("the light decision");
    let names: Vec<&str> = c.scores.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["prior", "sky"], "{c:?}");
    for (n, s) in &c.scores {
        let in_auto = decision
            .scores
            .iter()
            .find(|(m, _)| m == n)
            .map(|(_, v)| *v);
        assert_eq!(in_auto.map(f64::to_bits), Some(s.to_bits()), "{n}: {c:?}");
    }
    let lower = if c.scores[0].1 <= c.scores[1].1 {
        "prior"
    } else {
        "sky"
    };
    assert_eq!(c.model, lower, "{c:?}");
    assert!(c.why.starts_with("--light constrained: "), "{}", c.why);
}

/// Held-out protocol (b) under the sun and sky (`fit_held_out`): the light of a photo
/// fitted with the TRUE reflectance frozen on the observations whose normals face one
/// side of its sun's vertical plane, scored on the other side's, which that half never
/// saw. A free map per photo (the paper's frozen lighting step) knows the unseen side's
/// light only through its smoothness prior; the sun and sky with the clock's sun at the
/// collection's north carries it over. Every training photo of the small `spot-sky` case
/// (the photos rendered from the truth, 8-bit), relative RMSE over the held-back
/// observations over all photos. Measured: sky 0.566, free map 1.547 (0.37 of it); the
/// bound, 0.6 of the free map's, leaves a 1.6× margin on that ratio.
#[test]
fn a_held_out_sky_fit_extrapolates_where_the_free_map_cannot() {
    use relight_cpc::solve::light::frozen::{fit_light_scheduled, PassCaps};
    use relight_cpc::solve::light::sky::held_out::fit_held_out;
    use relight_cpc::solve::{predict, Problem};
    let c = sky_case();
    let case = &c.case;
    let mut obs = case.train.obs.clone();
    let mut held = Vec::new();
    for (i, range) in obs.photo_ranges.clone().into_iter().enumerate() {
        let s = c.suns[i];
        let side = Vec3::new(-s.y, s.x, 0.0).normalize();
        for q in range {
            if case.normals_env[obs.vertex[q] as usize].dot(&side) > 0.0 {
                held.push(q);
            }
        }
    }
    for &q in &held {
        obs.weight[q] = 0.0;
    }
    let problem = Problem {
        obs: &obs,
        transport: &case.train.transport,
        n_vertices: case.nv,
        n_photos: obs.photo_ranges.len(),
    };
    let beta = beta_per_vertex(&case.lambda, &case.weights, case.nv);
    let opts = EstimateOptions::default();
    let sky = fit_held_out(
        &problem,
        &beta,
        &opts,
        &SkyOptions::default(),
        geotag_suns(c),
        TRUE_NORTH,
    )
    .unwrap();
    let passes = [PassCaps {
        gpcg: opts.qp_max_iter,
        cg: opts.qp_max_cg,
    }];
    let paper: Vec<[Vec<f64>; 3]> = (0..problem.n_photos)
        .map(|i| {
            fit_light_scheduled(&problem, &beta, i, None, &opts, &passes)
                .unwrap()
                .light
        })
        .collect();
    let held_error = |maps: Vec<[Vec<f64>; 3]>| {
        let est = Estimate::from_parts(maps, case.lambda.clone(), case.weights.clone());
        let pred = predict(&problem, &est);
        let (mut num, mut den) = (0.0, 0.0);
        for &q in &held {
            for (p, y) in pred[q].iter().zip(obs.rgb[q].map(f64::from)) {
                num += (p - y).powi(2);
                den += y * y;
            }
        }
        (num / den).sqrt()
    };
    let (e_sky, e_paper) = (held_error(sky), held_error(paper));
    assert!(
        e_sky < 0.6 * e_paper,
        "sky {e_sky:.4} against the free map's {e_paper:.4}"
    );
}

/// `sky_case`'s training observations with every channel value above the `q`-quantile of
/// all of them clipped to it (a photo's overexposure: the sunlit surfaces), the clipped
/// channels flagged and given their confidence as bounds; and the values before clipping.
fn clipped_training(c: &SkyCase, q: f64) -> (Observations, Vec<[f32; 3]>, f32) {
    let mut obs = c.case.train.obs.clone();
    let original = obs.rgb.clone();
    let mut all: Vec<f32> = obs
        .rgb
        .iter()
        .zip(&obs.weight)
        .filter(|(_, &a)| a > 0.0)
        .flat_map(|(v, _)| *v)
        .collect();
    all.sort_by(f32::total_cmp);
    let level = all[(all.len() as f64 * q) as usize];
    obs.clipped.clear();
    obs.bound_weight.clear();
    for (rgb, &a) in obs.rgb.iter_mut().zip(&obs.weight) {
        let mask = (0..3)
            .filter(|&c| a > 0.0 && rgb[c] > level)
            .fold(0u8, |m, c| m | 1 << c);
        for c in (0..3).filter(|&c| mask & 1 << c != 0) {
            rgb[c] = level;
        }
        obs.clipped.push(mask);
        obs.bound_weight.push(if mask != 0 { a } else { 0.0 });
    }
    (obs, original, level)
}

/// `steps` sky lighting steps (outer iterations 1, 2, …) with the true materials fixed on
/// `obs`; the prediction of every observation under the light reached.
fn sky_steps(c: &SkyCase, obs: &Observations, steps: usize) -> Vec<[f64; 3]> {
    let case = &c.case;
    let problem = relight_cpc::solve::Problem {
        obs,
        transport: &case.train.transport,
        n_vertices: case.nv,
        n_photos: obs.photo_ranges.len(),
    };
    let opts = EstimateOptions::default();
    let mut light = SkyLight::new(&problem, &opts, &SkyOptions::default()).unwrap();
    let beta = beta_per_vertex(&case.lambda, &case.weights, case.nv);
    let mut irls = vec![[0.0_f32; 3]; obs.rgb.len()];
    let mut cond = Conditioning::default();
    for outer_iteration in 1..=steps {
        let input = LightingInput {
            problem: &problem,
            beta: &beta,
            outer_iteration,
        };
        let mut out = LightingOutput {
            irls_weights: &mut irls,
            conditioning: &mut cond,
        };
        light.fit(&input, &mut out).unwrap();
    }
    let s = basis_responses(&problem, &light.maps(light.params()));
    predict_from(&problem, &beta, &s)
}

#[test]
fn clipped_channels_read_as_bounds_give_the_sun_back_its_power() {
    // The true materials fixed; every channel above the 80th percentile of the training
    // values clipped to it (a fifth of the channel values: the sunlit ones). Read as
    // exact values the clipped rows pull the sun down: the clipped channels are predicted
    // far below what the photo held before clipping. Read as lower bounds (the one-sided
    // term, its set re-read as each pass starts) the sun must come back: the relative RMS
    // error of the clipped channels against their unclipped values at most half the
    // exact reading's (measured 0.116 against 0.355), and at most 10% of the clipped
    // channels predicted more than 5% below their bound (measured 3.9%, the exact reading
    // 31%; 8-bit photos on a 16² map: the fit does not reach every row exactly even
    // unclipped).
    let c = sky_case();
    let (obs, original, level) = clipped_training(c, 0.8);
    let exact_reading = Observations {
        clipped: Vec::new(),
        bound_weight: Vec::new(),
        ..obs.clone()
    };
    let clipped_error = |pred: &[[f64; 3]]| {
        let (mut num, mut den, mut short, mut n) = (0.0, 0.0, 0, 0);
        for (p, &mask) in obs.clipped.iter().enumerate() {
            for ch in (0..3).filter(|&ch| mask & 1 << ch != 0) {
                let y0 = f64::from(original[p][ch]);
                num += (pred[p][ch] - y0).powi(2);
                den += y0 * y0;
                n += 1;
                short += usize::from(pred[p][ch] < 0.95 * f64::from(level));
            }
        }
        ((num / den).sqrt(), short as f64 / n as f64, n)
    };
    let (e_exact, short_exact, n) = clipped_error(&sky_steps(c, &exact_reading, 3));
    let (e_bounds, short_bounds, _) = clipped_error(&sky_steps(c, &obs, 3));
    eprintln!(
        "{n} clipped channels: relative RMS error exact reading {e_exact:.4} ({:.1}% short), \
         bounds {e_bounds:.4} ({:.1}% short)",
        100.0 * short_exact,
        100.0 * short_bounds
    );
    assert!(e_bounds <= 0.5 * e_exact, "{e_bounds} vs {e_exact}");
    assert!(short_bounds <= 0.1, "{short_bounds}");
}
