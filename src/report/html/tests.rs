//! Tests of the parent module.

use super::*;

#[test]
fn heat_ends_and_clamps() {
    assert_eq!(heat(0.0), HEAT[0]);
    assert_eq!(heat(1.0), HEAT[5]);
    assert_eq!(heat(-3.0), HEAT[0]);
    assert_eq!(heat(f64::NAN), HEAT[0]);
    // Halfway between control points 2 and 3 (t = 0.5): their mean, rounded.
    assert_eq!(heat(0.5), [184, 60, 81]);
}

/// Per-pixel error against a hand computation: photo (0.5, 0.5, 0.5), render
/// (0.2, 0.2, 0.2) at scale 2 gives e = 0.1 exactly (f32: 1e-7).
#[test]
fn pixel_error_formula() {
    let e = pixel_errors(
        &[[0.5; 3], [1.0; 3]],
        &[[0.2; 3], [0.0; 3]],
        &[true, false],
        2.0,
    );
    assert!((e[0].unwrap() - 0.1).abs() < 1e-7);
    assert_eq!(e[1], None);
    assert_eq!(quantile([3.0f32, 1.0, 2.0].into_iter(), 0.5), Some(2.0));
}

#[test]
fn href_encodes_spaces_and_keeps_slashes() {
    assert_eq!(href("renders/a b.png"), "renders/a%20b.png");
    let page = format!("{}{}", img("x/y.png", "a", "c"), img("z.png", "<b>", "c"));
    assert_eq!(image_sources(&page), ["x/y.png", "z.png"]);
    assert!(page.contains("&lt;b&gt;"));
}

/// Metrics of any shape render: a list of records becomes a table with a column per
/// key; a missing key says so.
#[test]
fn metrics_render_what_exists() {
    let mut s = String::new();
    metrics_section(
        &mut s,
        &serde_json::json!({"metrics": [{"image": "a.png", "psnr_h": 21.5}, {"image": "b.png", "ssim": 0.9}]}),
    );
    assert!(s.contains("<th>psnr_h</th>") && s.contains("<th>ssim</th>"));
    assert!(s.contains("21.5000") && s.contains("0.9000"));
    let mut t = String::new();
    metrics_section(&mut t, &serde_json::json!({}));
    assert!(t.contains("no literature metrics"));
}

#[test]
fn the_truth_check_table_shows_the_floor_only_when_every_photo_has_one() {
    use crate::report::metrics::TruthCheckEntry;
    let entry = |image: &str, t: f64, f: f64, floor: Option<f64>| TruthCheckEntry {
        image: image.into(),
        rmse_true_light: t,
        relative_true_light: t,
        scale_true_light: [1.0; 3],
        rmse_fitted_light: f,
        relative_fitted_light: f,
        rmse_true_reflectance: floor,
        relative_true_reflectance: floor,
        pixels: 100,
    };
    let mut s = String::new();
    truth_check_table(&mut s, &[]);
    assert!(s.is_empty());
    let rows = [
        entry("a.png", 0.10, 0.08, Some(0.05)),
        entry("b.png", 0.20, 0.12, Some(0.07)),
    ];
    truth_check_table(&mut s, &rows);
    // Rows in percent to 0.1, and the means: (10 + 20) / 2, (8 + 12) / 2, (5 + 7) / 2.
    assert!(s.contains("<td class=\"l\">a.png</td><td>10.0%</td><td>8.0%</td><td>5.0%</td>"));
    assert!(s.contains("<td><b>15.0%</b></td><td><b>10.0%</b></td><td><b>6.0%</b></td>"));
    assert!(s.contains("true reflectance, true light"));
    // The fit over the floor: (10 + 20) / (5 + 7) = 2.50.
    assert!(s.contains("<b>2.50×</b> the floor"), "{s}");
    // One photo without a floor: no floor column at all, and no ratio.
    let mut s = String::new();
    truth_check_table(&mut s, &[rows[0].clone(), entry("c.png", 0.3, 0.2, None)]);
    assert!(!s.contains("true reflectance, true light") && !s.contains("5.0%"));
    assert!(!s.contains("the floor"), "{s}");
    assert!(s.contains("<td><b>20.0%</b></td><td><b>14.0%</b></td><td></td>"));
}

#[test]
fn the_held_out_section_gives_the_headline_and_the_half_fits_prior() {
    // The same figures as report.md's headline: the ratio to 3 places, both RMSEs, and the
    // sentence naming the light prior of protocol half (HTML-escaped, no backticks).
    let r = RunReport {
        headline_detail: Some(crate::report::metrics::Headline {
            ratio: 0.35125,
            method_rmse: 0.053,
            baseline_rmse: 0.1509,
            photos: 2,
        }),
        half_fit_prior: Some(crate::report::HalfFitPriorReport {
            mode: "off".into(),
            prior: "none".into(),
            ..Default::default()
        }),
        ..Default::default()
    };
    let mut s = String::new();
    headline(&mut s, &r);
    assert!(
        s.contains("<b>Headline: held-out error / baseline error = 0.351</b>"),
        "{s}"
    );
    assert!(
        s.contains("RMSE after scale 0.05300 against 0.15090"),
        "{s}"
    );
    assert!(
        s.contains("Protocol half fits the light with the Laplacian prior alone"),
        "{s}"
    );
    assert!(!s.contains('`'), "{s}");
    let mut empty = String::new();
    headline(&mut empty, &RunReport::default());
    assert!(empty.is_empty());
}
