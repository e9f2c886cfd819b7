//! End to end: `run` on the built-in example (a known-truth workspace made by `synth` from
//! real data, `examples/spot`), checked against the truth it carries.

use relight_cpc::run::{
    builtin_example, run, MaterialCount, RunOptions, StartBrightness, WeightsSmoothness, WeightsSum,
};

fn options(out: &std::path::Path) -> RunOptions {
    let mut o = RunOptions::new(builtin_example().unwrap(), out.to_path_buf());
    // Small settings so the whole pipeline stays well under a minute in the test profile.
    o.global_resolution = 32;
    o.keep = 64;
    o.max_iterations = 3;
    o.materials = MaterialCount::Fixed(2);
    o.progress = false;
    o.render_training = false;
    o
}

#[test]
fn example_run_recovers_held_out_photos_under_their_true_light() {
    let dir = std::env::temp_dir().join(format!("relight-run-example-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.join("spot");
    let summary = run(&options(&out)).expect("run on the built-in example");
    let r = &summary.report;

    // Everything a user opens is there, and nothing half-written is left beside it.
    for f in [
        "report.json",
        "report.md",
        "materials.json",
        "mesh.ply",
        "plots/error_vs_time.png",
        "plots/envmaps.png",
        "plots/stages.png",
        "plots/per_photo_rmse.png",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    let beside: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(
        beside.len(),
        1,
        "only the result, no staging folder, is left"
    );
    assert!(out.join(relight_cpc::out_dir::STAMP).is_file());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    for key in [
        "holdout",
        "train_rmse",
        "timeline",
        "stages",
        "peak_memory_bytes",
        "model",
    ] {
        assert!(json.get(key).is_some(), "report.json lacks {key}");
    }

    // The truth manifest holds out two photos; each is scored under its true light.
    let truth: Vec<_> = r.holdout.iter().filter(|h| h.protocol == "truth").collect();
    assert_eq!(truth.len(), 2, "{:?}", r.holdout);
    for h in &r.holdout {
        eprintln!(
            "{} {}: RMSE {:.4} raw, {:.4} scaled (scale {:.3}, {} px)",
            h.image, h.protocol, h.rmse, h.rmse_scaled, h.scale, h.pixels
        );
    }
    eprintln!("train RMSE {:.4}", r.train_rmse);
    for h in &truth {
        assert!(h.rmse_scaled.is_finite() && h.pixels > 1000, "{h:?}");
        // The error of predicting nothing is the photo's own RMS over the same pixels
        // (about 0.25–0.35 on these photos). The fitted model under the true light must
        // explain most of it: measured 0.06–0.11 (MC noise of the reference photos, the
        // 8-bit quantisation and the 32² map resolution of this quick run included), so
        // 0.15 leaves room for platform rounding without admitting a broken fit.
        assert!(h.rmse_scaled < 0.15, "{h:?}");
    }
    // Training fit: the model reproduces the photos it was fitted to far better than the
    // held-out ones (measured about 0.03).
    assert!(r.train_rmse < 0.05, "train RMSE {}", r.train_rmse);
    // The objective never increases over outer iterations (each block step is an exact
    // minimisation; IRLS restarts make it non-strict, so allow rounding).
    for w in r.timeline.windows(2) {
        assert!(
            w[1].objective <= w[0].objective * (1.0 + 1e-6),
            "{:?}",
            r.timeline
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn run_rejects_a_missing_workspace_and_bad_options_with_clear_errors() {
    let dir = std::env::temp_dir().join(format!("relight-run-bad-{}", std::process::id()));
    let mut o = RunOptions::new(dir.join("no-such-workspace"), dir.join("out"));
    o.progress = false;
    let err = run(&o).unwrap_err().to_string();
    assert!(err.contains("no-such-workspace"), "{err}");
    assert!(!dir.join("out").exists());

    let mut o = options(&dir.join("out"));
    o.global_resolution = 48;
    let err = run(&o).unwrap_err().to_string();
    assert!(err.contains("--global-resolution 48"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The CLI's default (`--adaptive on`) on the same example: the truth has two materials and
/// lobes Lambert, Phong 50 and GGX 0.3 (no Phong 500). The adaptive model must keep the
/// Lambertian and Phong 50 lobes the truth uses, fit the truth's two materials, map no
/// finer than requested, and meet the same held-out and training bounds as the full model
/// above (the same reasoning for 0.15 and 0.05 applies). The count is exact here: this
/// run's pilot scores two materials 3.9% above its best count (5), inside the 6% margin,
/// and one material 17% above; the 3% margin took 3 (`adaptive::MATERIAL_TOL`,
/// `bench-results/adaptive-material-margin.md`).
#[test]
fn example_run_with_the_adaptive_model_meets_the_same_bounds() {
    let dir = std::env::temp_dir().join(format!("relight-run-adaptive-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let r = adaptive_example(&dir, "spot", |_| {});
    let m = &r.model;
    assert!(m.adaptive.as_ref().is_some_and(|d| !d.is_empty()));
    assert!(
        m.basis.iter().any(|b| b == "lambert") && m.basis.iter().any(|b| b == "phong:50"),
        "{:#?}",
        m.adaptive
    );
    assert_eq!(m.materials, 2, "{:#?}", m.adaptive);
    assert!(m.global_resolution <= 32);
    let truth: Vec<_> = r.holdout.iter().filter(|h| h.protocol == "truth").collect();
    assert_eq!(truth.len(), 2, "{:?}", r.holdout);
    for h in &truth {
        eprintln!("{} truth: RMSE {:.4} scaled", h.image, h.rmse_scaled);
        assert!(h.rmse_scaled < 0.15, "{h:?}");
    }
    assert!(r.train_rmse < 0.05, "train RMSE {}", r.train_rmse);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The adaptive run of the built-in example into `dir/tag` (the small settings of
/// [`options`], the material count chosen), after `edit` on its options.
fn adaptive_example(
    dir: &std::path::Path,
    tag: &str,
    edit: impl FnOnce(&mut RunOptions),
) -> relight_cpc::report::RunReport {
    let mut o = options(&dir.join(tag));
    o.adaptive = true;
    o.materials = MaterialCount::Auto;
    // The robust loss in every run: these tests compare one choice of the pilot against
    // the same run with it given, and `--loss auto` chooses per run (without the neighbour
    // prior it keeps plain least squares here, with it the robust loss), which would
    // compare two choices at once.
    o.loss = relight_cpc::solve::loss_choice::LossChoice::Robust;
    edit(&mut o);
    run(&o)
        .expect("adaptive run on the built-in example")
        .report
}

/// The pilot's decision `what` in `r` (a panic naming the decisions when there is none).
fn decision<'a>(
    r: &'a relight_cpc::report::RunReport,
    what: &str,
) -> &'a relight_cpc::solve::adapt::Decision {
    let decisions = r.model.adaptive.as_ref().expect("adaptive decisions");
    decisions
        .iter()
        .find(|d| d.what == what)
        .unwrap_or_else(|| panic!("no {what} decision: {decisions:#?}"))
}

/// Whether `r` has adaptive decisions and none of them is `what`.
fn no_decision(r: &relight_cpc::report::RunReport, what: &str) -> bool {
    r.model
        .adaptive
        .as_ref()
        .is_some_and(|d| d.iter().all(|d| d.what != what))
}

/// The pilot's choice `what` against a run given its value (`given`, labelled
/// `given_label`): the given value is not the pilot's to decide, and the run with the
/// pilot's choice (`chosen_label`) predicts the held-out photos under their true light
/// strictly better (the mean of `truth_holdout`).
fn assert_the_choice_beats_the_given(
    auto: &relight_cpc::report::RunReport,
    given: &relight_cpc::report::RunReport,
    what: &str,
    chosen_label: &str,
    given_label: &str,
) {
    assert!(
        no_decision(given, what),
        "a given {what} is not the pilot's to choose"
    );
    let mean_truth = |r: &relight_cpc::report::RunReport| crate::run_fixtures::truth_holdout(r).0;
    let (with, without) = (mean_truth(auto), mean_truth(given));
    eprintln!("truth RMSE: {chosen_label} {with:.4}, {given_label} {without:.4}");
    assert!(
        with < without,
        "{chosen_label} {with:.4} against {given_label} {without:.4}"
    );
}

/// The light model by mesh size (`run` without `--light`, [`RunOptions::light_by_scene`]):
/// the built-in example's 2.9K vertices are below the threshold and its pilot keeps shiny
/// lobes, so the run chooses by validation (`--light auto`). Judged by the truth the choice never sees, the model kept
/// must predict the held-out photos under their true light strictly better than the
/// paper's free map (`--light paper`), and its headline (protocol `half` over the naive
/// baseline) must be no worse: the example's regression when GGX 0.3 joined the basis was
/// the paper's map in protocol `half`. Means over seeds 1–6: under the true light 0.0415 →
/// 0.0380, headline 0.3853 → 0.3178 (`bench-results/light-default.md`); at this test's
/// settings (the run's, seed 1; seeded, so the same on every run) 0.0404 → 0.0385 and
/// 0.3919 → 0.3176, `prior` kept.
#[test]
fn the_light_model_chosen_by_size_beats_the_papers_map_on_the_example() {
    use relight_cpc::solve::light::choose::LightChoice;
    let dir = std::env::temp_dir().join(format!("relight-run-light-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    // The run's own caps (8 rounds, 128 coefficients): at 3 rounds and 64 the fits stop
    // before the light models part (the prior's truth 0.0543 against the paper's 0.0510).
    let full = RunOptions::new(builtin_example().unwrap(), dir.clone());
    let caps = |o: &mut RunOptions| {
        o.max_iterations = full.max_iterations;
        o.keep = full.keep;
    };
    let sized = adaptive_example(&dir, "sized", |o| {
        caps(o);
        o.light_by_scene = true
    });
    let light = sized.model.light.as_ref().expect("a light decision");
    assert!(light.why.starts_with("--light auto"), "{}", light.why);
    assert!(
        light.scores.len() >= 3,
        "paper, prior and sky fitted: {:?}",
        light.scores
    );
    let paper = adaptive_example(&dir, "paper", |o| {
        caps(o);
        o.light = LightChoice::Paper
    });
    let paper_light = paper.model.light.as_ref().expect("a light decision");
    assert_eq!(paper_light.model, "paper");
    let mean_truth = |r: &relight_cpc::report::RunReport| crate::run_fixtures::truth_holdout(r).0;
    let (chosen, given) = (mean_truth(&sized), mean_truth(&paper));
    let headline = |r: &relight_cpc::report::RunReport| r.headline.expect("a headline");
    eprintln!(
        "{}: truth {chosen:.4} headline {:.4}; paper: truth {given:.4} headline {:.4}",
        light.model,
        headline(&sized),
        headline(&paper)
    );
    assert!(
        chosen < given,
        "{} {chosen:.4} against paper {given:.4}",
        light.model
    );
    assert!(
        headline(&sized) <= headline(&paper),
        "headline {} {:.4} against paper {:.4}",
        light.model,
        headline(&sized),
        headline(&paper)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The pilot's choice of the blending weights' sum-to-one prior (`--weights-sum auto`, the
/// CLI's default with the adaptive model), judged by the truth the pilot never sees: on
/// the built-in example the pilot must take the prior, and the fit with it must predict
/// the held-out photos under their true light better than the same run with the paper's
/// free weights (`--weights-sum 0`). At full settings that is 0.0623 against 0.0752
/// (`bench-results/adaptive-weights-sum.md`); strictly lower is the test, since the choice
/// is only worth making when it helps.
#[test]
fn the_pilot_takes_the_weights_prior_where_it_predicts_the_truth_better() {
    let dir = std::env::temp_dir().join(format!("relight-run-wsum-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let fit = |tag: &str, ws: WeightsSum| adaptive_example(&dir, tag, |o| o.weights_sum = ws);
    let auto = fit("auto", WeightsSum::Auto);
    let d = decision(&auto, "weights_sum");
    assert_eq!(d.chosen, "1", "{}", d.reason);
    assert!(
        d.reason.contains("free weights") && d.reason.contains("%"),
        "{}",
        d.reason
    );
    let free = fit("free", WeightsSum::Fixed(0.0));
    for r in [&auto, &free] {
        let photos = crate::run_fixtures::truth_holdout(r).1;
        assert_eq!(photos, 2, "{:?}", r.holdout);
    }
    assert_the_choice_beats_the_given(&auto, &free, "weights_sum", "prior", "free weights");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The pilot's stand-ins (step 4 of `relight_cpc::solve::adapt`): on the built-in example
/// the held-out ablation keeps Phong 50, so GGX 0.3, broader, stays untested beside it;
/// judged by the truth the pilot never sees, the fit with both must render the training
/// photos under their TRUE light (the truth check) better than the same run offered the
/// basis without GGX 0.3, which keeps Phong 50 alone. At full settings that is 0.1552
/// against 0.1697 at seed 1 and lower on seeds 2–3 too
/// (`bench-results/basis-stand-ins.md`); at this test's settings 0.1844 against 0.2090
/// (seeded, so the same on every run); strictly lower is the test.
#[test]
fn a_lobe_broader_than_the_kept_one_stays_and_predicts_the_truth_better() {
    use relight_cpc::transport::brdf::BasisBrdf;
    let dir = std::env::temp_dir().join(format!("relight-run-stand-in-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let both = adaptive_example(&dir, "both", |_| {});
    let d = decision(&both, "basis");
    assert_eq!(d.chosen, "lambert,phong:50,ggx:0.3", "{}", d.reason);
    assert!(d.reason.contains("ggx:0.3 kept untested"), "{}", d.reason);
    let alone = adaptive_example(&dir, "alone", |o| {
        o.basis = vec![
            BasisBrdf::Lambert,
            BasisBrdf::Phong { exponent: 50.0 },
            BasisBrdf::Phong { exponent: 500.0 },
        ]
    });
    assert_eq!(decision(&alone, "basis").chosen, "lambert,phong:50");
    let check = crate::run_fixtures::truth_check_mean;
    let (with, without) = (check(&both), check(&alone));
    eprintln!("truth check: with GGX 0.3 {with:.4}, Phong 50 alone {without:.4}");
    assert!(
        with < without,
        "with GGX 0.3 {with:.4}, Phong 50 alone {without:.4}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The neighbour prior on the blending weights (`--weights-smoothness auto`, the CLI's
/// default with the adaptive model), judged by the truth the pilot never sees: the
/// built-in example's pilot keeps the Phong 50 lobe, so the prior goes in, and the fit
/// with it must predict the held-out photos under their true light better than the same
/// run with independent weights (`--weights-smoothness 0`). At full settings that is
/// 0.0443 against 0.0449 at seed 1, 0.0450 against 0.0500 at seed 3
/// (`bench-results/weights-smoothness-shiny.md`); at this test's settings 0.0510 against
/// 0.0579 (seeded, so the same on every run); strictly lower is the test.
#[test]
fn the_neighbour_prior_goes_in_with_a_shiny_lobe_and_predicts_the_truth_better() {
    let dir = std::env::temp_dir().join(format!("relight-run-pull-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let fit = |tag: &str, ws: WeightsSmoothness| {
        adaptive_example(&dir, tag, |o| o.weights_smoothness = ws)
    };
    let auto = fit("auto", WeightsSmoothness::Auto);
    assert_eq!(decision(&auto, "basis").chosen, "lambert,phong:50,ggx:0.3");
    let d = decision(&auto, "weights_smoothness");
    assert_eq!(d.chosen, "0.1", "{}", d.reason);
    assert!(d.reason.contains("phong:50"), "{}", d.reason);
    let off = fit("off", WeightsSmoothness::Fixed(0.0));
    assert_the_choice_beats_the_given(
        &auto,
        &off,
        "weights_smoothness",
        "neighbour prior",
        "independent weights",
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The pilot's choice of the start's brightness (`--start-brightness auto`, the CLI's
/// default with the adaptive model), judged by the truth the pilot never sees: on the
/// built-in example, whose two materials lie on surfaces facing different ways, the pilot
/// must take the brightness matched by normal, and the fit from it must predict the
/// held-out photos under their true light better than the same run from the clustered
/// colours (`--start-brightness clustered`). At full settings that is 0.0450 against
/// 0.0620 at seed 1 (`bench-results/matched-start.md`); strictly lower is the test.
#[test]
fn the_pilot_takes_the_matched_start_where_it_predicts_the_truth_better() {
    let dir = std::env::temp_dir().join(format!("relight-run-matched-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let fit = |tag: &str, start: StartBrightness| {
        adaptive_example(&dir, tag, |o| o.start_brightness = start)
    };
    let auto = fit("auto", StartBrightness::Auto);
    let d = decision(&auto, "start_brightness");
    assert_eq!(d.chosen, "matched", "{}", d.reason);
    assert!(
        d.reason.contains("clustered") && d.reason.contains("%"),
        "{}",
        d.reason
    );
    assert!(
        auto.model
            .reasons
            .iter()
            .any(|r| r.starts_with("start brightness matched by normal")),
        "{:?}",
        auto.model.reasons
    );
    let clustered = fit("clustered", StartBrightness::Clustered);
    assert_the_choice_beats_the_given(
        &auto,
        &clustered,
        "start_brightness",
        "matched",
        "clustered",
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn several_starts_keep_the_lowest_validation_score() {
    // Two starts (`--starts 2`) on the built-in example: the report names both, keeps the
    // one with the lower validation score, and its timeline carries both starts' iterations
    // in order on one clock.
    let dir = std::env::temp_dir().join(format!("relight-run-starts-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut o = options(&dir.join("spot"));
    o.max_iterations = 2;
    o.starts = 2;
    let summary = run(&o).expect("run with two starts");
    let r = &summary.report;
    let m = r.starts.as_ref().expect("a multi-start record");
    assert_eq!(m.starts.len(), 2);
    let best = if m.starts[1].score < m.starts[0].score {
        1
    } else {
        0
    };
    assert_eq!(m.chosen, best, "{m:?}");
    assert!(m
        .starts
        .iter()
        .all(|s| s.score.is_finite() && s.iterations >= 1));
    let per_start: Vec<usize> = (0..2)
        .map(|i| r.timeline.iter().filter(|t| t.start == i).count())
        .collect();
    assert_eq!(
        per_start,
        vec![m.starts[0].iterations, m.starts[1].iterations]
    );
    assert!(r
        .timeline
        .windows(2)
        .all(|w| w[0].start <= w[1].start && w[0].seconds < w[1].seconds));
    assert!(
        r.notes.iter().any(|n| n.contains("2 starts tried")),
        "{:?}",
        r.notes
    );
    let truth: Vec<_> = r.holdout.iter().filter(|h| h.protocol == "truth").collect();
    assert!(truth.len() == 2 && truth.iter().all(|h| h.rmse_scaled.is_finite()));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--light shared` with a groups file on the built-in example: the run fits one map per
/// group (photos 0–2 share one, the rest keep their own), the report says which model and
/// where the groups came from, and every photo of a group gets the same map up to its
/// per-channel gains. A groups file naming an unknown photo is refused with the file and
/// line, before anything is written.
#[test]
fn shared_light_follows_a_groups_file() {
    use relight_cpc::solve::light::choose::LightChoice;
    let dir = std::env::temp_dir().join(format!("relight-run-shared-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let groups = dir.join("groups.txt");
    std::fs::write(
        &groups,
        "# one sky for the first three photos\nphoto_000.png a\nphoto_001.png a\nphoto_002.png a\n",
    )
    .unwrap();
    let mut o = options(&dir.join("spot"));
    o.max_iterations = 2;
    o.light = LightChoice::Shared;
    o.light_groups = Some(groups.clone());
    let r = run(&o).expect("run with --light shared").report;
    let light = r.model.light.as_ref().unwrap();
    assert_eq!(light.model, "shared", "{light:?}");
    assert!(
        r.model
            .reasons
            .iter()
            .any(|s| s.contains("groups of the 6 training photos from")),
        "{:?}",
        r.model.reasons
    );
    // The three photos' fitted maps: one map times per-channel gains, so the texel-wise
    // ratio of two of them is one number per channel (to the f32 precision of the EXR
    // files, 1e-5 relative, on texels brighter than 1e-3 of the map's peak).
    let read = |n: &str| {
        relight_cpc::sphere::envmap::LatLong::read_exr(
            &dir.join("spot/envmaps").join(format!("{n}.latlong.exr")),
        )
        .unwrap()
        .0
    };
    let (a, b) = (read("photo_000"), read("photo_002"));
    for c in 0..3 {
        let peak = a.rgb.iter().map(|p| p[c]).fold(0.0f32, f32::max);
        let ratios: Vec<f64> = a
            .rgb
            .iter()
            .zip(&b.rgb)
            .filter(|(p, q)| p[c] > 1e-3 * peak && q[c] > 0.0)
            .map(|(p, q)| q[c] as f64 / p[c] as f64)
            .collect();
        assert!(ratios.len() > 100, "channel {c}: {} texels", ratios.len());
        let (lo, hi) = ratios
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
        assert!(hi / lo - 1.0 < 1e-4, "channel {c}: ratios {lo}..{hi}");
    }

    std::fs::write(&groups, "photo_000.png a\nno_such_photo.png b\n").unwrap();
    let mut o = options(&dir.join("refused"));
    o.light = LightChoice::Shared;
    o.light_groups = Some(groups);
    let e = run(&o).unwrap_err().to_string();
    assert!(
        e.contains("groups.txt") && e.contains("line 2") && e.contains("no_such_photo.png"),
        "{e}"
    );
    assert!(
        !dir.join("refused").exists(),
        "nothing written for a refused run"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The README's promise: a run is deterministic for a seed whatever the thread count, down
/// to the bytes of every file but those that carry timings (the report, its stage and
/// timeline plots, the result stamp). Before the EXR writer wrote its tiles in a fixed
/// order, the maps and renders differed from run to run.
#[test]
fn one_and_two_threads_write_the_same_files() {
    let dir = crate::scratch::scratch("run-threads", "spot");
    let [one, two] = [1, 2].map(|threads| {
        let out = dir.join(format!("spot-{threads}"));
        let mut o = options(&out);
        o.render_training = true;
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&o))
            .expect("run on the built-in example");
        // Paths relative to the result, the timed files left out.
        crate::scratch::snapshot(&out)
            .into_iter()
            .map(|(p, bytes)| {
                let rel = p.strip_prefix(&out).unwrap().to_string_lossy();
                (rel.replace('\\', "/"), bytes)
            })
            .filter(|(rel, _)| !TIMED.contains(&rel.as_str()) && rel != relight_cpc::out_dir::STAMP)
            .collect::<Vec<_>>()
    });
    assert!(
        one.iter().any(|(f, _)| f.ends_with(".exr")),
        "no EXR written"
    );
    assert!(one.len() > 10, "only {} files compared", one.len());
    let names = |v: &[(String, Vec<u8>)]| v.iter().map(|(f, _)| f.clone()).collect::<Vec<_>>();
    assert_eq!(
        names(&one),
        names(&two),
        "the two runs wrote different files"
    );
    for ((f, a), (_, b)) in one.iter().zip(&two) {
        assert!(a == b, "{f} differs between 1 and 2 threads");
    }
}

/// The files of a result that carry wall or CPU times (besides the result stamp,
/// [`relight_cpc::out_dir::STAMP`]).
const TIMED: [&str; 5] = [
    "report.json",
    "report.md",
    "report.html",
    "plots/stages.png",
    "plots/error_vs_time.png",
];
