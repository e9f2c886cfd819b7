//! Tests of the parent module.

use super::*;

#[test]
fn compare_matches_direct_formulas() {
    // Prediction = truth / 2 on the masked pixels: raw RMSE is the RMS of truth/2, the
    // best scale is exactly 2 and the scaled RMSE is 0 (to f64 rounding, 1e-12).
    let truth = vec![[0.2f32, 0.4, 0.6], [0.8, 0.1, 0.3], [5.0, 5.0, 5.0]];
    let pred: Vec<[f32; 3]> = truth
        .iter()
        .map(|p| [p[0] / 2.0, p[1] / 2.0, p[2] / 2.0])
        .collect();
    let mask = vec![true, true, false];
    let (rmse, scaled, scale, n) = compare(&truth, &pred, &mask);
    let direct = ((0.1f64.powi(2)
        + 0.2f64.powi(2)
        + 0.3f64.powi(2)
        + 0.4f64.powi(2)
        + 0.05f64.powi(2)
        + 0.15f64.powi(2))
        / 6.0)
        .sqrt();
    assert_eq!(n, 2);
    assert!((rmse - direct).abs() < 1e-6, "{rmse} vs {direct}");
    assert!((scale - 2.0).abs() < 1e-6);
    assert!(scaled < 1e-6);
    assert!((psnr(0.1) - 20.0).abs() < 1e-12);
}

#[test]
fn report_writes_json_markdown_and_pngs() {
    let dir = std::env::temp_dir().join(format!("relight-report-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut r = RunReport {
        version: "test".into(),
        train_rmse: 0.01,
        ..Default::default()
    };
    r.timeline = (0..4)
        .map(|i| TimelinePoint {
            start: 0,
            seconds: i as f64,
            objective: 1.0 / (1.0 + i as f64),
            train_rmse: 0.1 / (1.0 + i as f64),
            holdout_rmse: Some(f64::NAN),
            steps: crate::solve::StepTimes {
                lighting_seconds: 0.5,
                lighting_cpu_seconds: 1.0,
                material_seconds: 0.25,
                material_cpu_seconds: 0.5,
            },
        })
        .collect();
    r.holdout.push(HoldoutEntry {
        image: "a.png".into(),
        protocol: "mean".into(),
        rmse: 0.1,
        rmse_scaled: 0.05,
        scale: 1.2,
        psnr: 20.0,
        pixels: 10,
    });
    let map = vec![[1.0f32, 0.5, 0.25]; 8 * 4];
    r.write(&dir, &[("map".into(), 8, 4, &map)]).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
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
    assert!(json["timeline"][0]["holdout_rmse"].is_null());
    for f in [
        "error_vs_time.png",
        "per_photo_rmse.png",
        "stages.png",
        "envmaps.png",
    ] {
        let img = image::open(dir.join("plots").join(f)).unwrap();
        assert!(img.width() > 100 && img.height() > 50, "{f}");
    }
    assert!(std::fs::read_to_string(dir.join("report.md"))
        .unwrap()
        .contains("| a.png | mean |"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn half_fit_prior_sentence_names_the_prior_used_and_why() {
    // The replay kept no training prior under `--light prior`: the sentence must name the
    // model's own prior (the one the fit used), not "the Laplacian alone", and give the
    // training priors' scores.
    let replayed = HalfFitPriorReport {
        mode: "auto".into(),
        prior: "light model's".into(),
        eta: 0.0,
        model_prior_scale: 0.2,
        smoothness_mode: "fit".into(),
        smoothness: 1.6e-2,
        candidates: vec!["none".into(), "training maps η 3".into()],
        log_rmse_ratio: vec![0.0, 1.25],
        replayed_photos: 4,
        cpu_seconds: 0.5,
    };
    let s = replayed.sentence();
    assert!(s.contains("the light model's own prior"), "{s}");
    assert!(s.contains("at 0.2× its noise levels"), "{s}");
    assert!(s.contains("no training-map prior chosen"), "{s}");
    assert!(s.contains("training maps η 3: +1.2500"), "{s}");
    assert!(s.contains("at Laplacian weight 1.6e-2"), "{s}");
    let fixed = HalfFitPriorReport {
        mode: "fixed".into(),
        prior: "training maps η 3".into(),
        eta: 3.0,
        smoothness_mode: "fit".into(),
        ..Default::default()
    };
    let s = fixed.sentence();
    assert!(
        s.contains("shape prior at η = 3")
            && s.contains("`--half-prior fixed`")
            && s.contains("`--half-smoothness fit`"),
        "{s}"
    );
    let off = HalfFitPriorReport {
        mode: "off".into(),
        prior: "none".into(),
        ..Default::default()
    };
    assert!(off.sentence().contains("the Laplacian prior alone"));
}
