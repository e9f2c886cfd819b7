use super::*;

fn stages(v: &[(&str, f64)]) -> Vec<(String, f64)> {
    v.iter().map(|(s, t)| (s.to_string(), *t)).collect()
}

/// Every sweep setting differs from the default knobs (at the top resolution) in at
/// most one knob, each knob takes each of its listed values once, and the reference is
/// the untruncated model with every other knob at its default.
#[test]
fn sweep_varies_one_knob_at_a_time() {
    for quick in [false, true] {
        let (_, _, _, base) = mode_settings(quick);
        let (list, idx) = sweep_knobs(base, quick);
        let top = list.iter().map(|k| k.global_resolution).max().unwrap();
        let at_top = Knobs {
            global_resolution: top,
            ..base
        };
        assert_eq!(list[idx], Knobs { keep: 0, ..at_top });
        for (i, k) in list.iter().enumerate() {
            assert!(!list[..i].contains(k), "{k:?} twice");
            let differ = k.differs_from(&at_top);
            assert!(differ.iter().filter(|&&d| d).count() <= 1, "{k:?}");
            assert!(!differ[5], "{k:?}: the local resolution is not swept");
        }
        // Three values of each knob other than keep (four, with the untruncated 0).
        let values = |f: fn(&Knobs) -> usize| {
            let mut v: Vec<usize> = list.iter().map(f).collect();
            v.sort_unstable();
            v.dedup();
            v.len()
        };
        assert_eq!(values(|k| k.global_resolution), 3);
        assert_eq!(values(|k| k.keep), 4);
        assert_eq!(values(|k| k.iterations), 3);
        assert_eq!(values(|k| k.normal_grid), 3);
        assert_eq!(values(|k| k.lighting_qp), 3);
        assert!(list.contains(&at_top), "the default knobs are a row");
    }
}

/// Power laws t = c·nᵖ give back their exponent and ratio (n₂/n₁)^(p−1) exactly up to
/// floating-point rounding (1e-12 relative is many ulps above it).
#[test]
fn growth_of_power_laws() {
    let series: Vec<(f64, Vec<(String, f64)>)> = [1e4, 1e5, 4e5]
        .iter()
        .map(|&n: &f64| {
            (
                n,
                stages(&[
                    ("linear", 3e-5 * n),
                    ("quadratic", 1e-9 * n * n),
                    ("constant", 0.7),
                ]),
            )
        })
        .collect();
    let g = growth_rates(&series);
    assert_eq!(g.len(), 6);
    for row in &g {
        let p = match row.stage.as_str() {
            "linear" => 1.0,
            "quadratic" => 2.0,
            _ => 0.0,
        };
        let r = row.to / row.from;
        assert!((row.exponent - p).abs() < 1e-12, "{row:?}");
        assert!(
            (row.relative - r.powf(p - 1.0)).abs() < 1e-12 * r.powf(p),
            "{row:?}"
        );
        assert!(
            (row.time_ratio - r.powf(p)).abs() < 1e-12 * r.powf(p),
            "{row:?}"
        );
    }
}

/// Missing stages, zero times and equal sizes give no row rather than NaN or ∞.
#[test]
fn growth_skips_undefined_rows() {
    let series = vec![
        (10.0, stages(&[("a", 1.0), ("b", 0.0), ("c", 1.0)])),
        (10.0, stages(&[("a", 2.0)])),
        (20.0, stages(&[("a", 4.0), ("b", 1.0)])),
    ];
    let g = growth_rates(&series);
    assert_eq!(g.len(), 1);
    assert_eq!(g[0].stage, "a");
    assert!((g[0].exponent - 1.0).abs() < 1e-12);
}

/// The front of a small hand-checked set: (1, 5) (2, 3) (4, 1) are each best in some
/// trade-off; (3, 4) is beaten by (2, 3); (4, 2) by (4, 1); duplicates both stay.
#[test]
fn pareto_by_hand() {
    let pts = [
        (1.0, 5.0),
        (2.0, 3.0),
        (3.0, 4.0),
        (4.0, 1.0),
        (4.0, 2.0),
        (f64::NAN, 0.0),
    ];
    assert_eq!(
        pareto_front(&pts),
        vec![true, true, false, true, false, false]
    );
    assert_eq!(pareto_front(&[(1.0, 1.0), (1.0, 1.0)]), vec![true, true]);
}

/// A sweep run with knobs `k`, `seconds` of wall time and held-out RMSE `rmse`.
fn sweep_run(k: Knobs, seconds: f64, rmse: f64) -> BenchRun {
    BenchRun {
        group: "sweep".into(),
        vertices: 100,
        photos: 3,
        observations: 300,
        width: 8,
        height: 8,
        knobs: k,
        model: Model::default(),
        synth_seconds: 0.0,
        synth_reused: false,
        stages: Vec::new(),
        total_seconds: seconds,
        total_cpu_seconds: 2.0 * seconds,
        peak_memory_bytes: 1 << 20,
        train_rmse: rmse,
        holdout_rmse: rmse,
        outer_iterations: 1,
        steps: Default::default(),
        command: None,
    }
}

/// The files are rewritten after every run: before the sweep reaches its reference (the
/// plot's yardstick) the JSON and Markdown are written and the plot is not; once the
/// reference has run the plot is a PNG. (The plot was once asked for after the second
/// run, drew nothing and failed the whole bench on its missing staged file.)
#[test]
fn a_sweep_writes_its_plot_once_the_reference_has_run() {
    let (_, _, _, base) = mode_settings(true);
    let (list, idx) = sweep_knobs(base, true);
    assert!(idx >= 2, "the reference comes after two settings");
    let dir = std::env::temp_dir().join(format!("relight-bench-plot-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let names = output_names("sweep");
    let files = crate::out_dir::OutFiles::claim(
        &dir,
        &names.each_ref().map(|s| s.as_str()),
        false,
        &[],
        is_bench_report,
    )
    .unwrap();
    let mut report = BenchReport::started(&BenchOptions::quick(dir.clone()), "bench".into());
    report.reference = Some(idx);
    let png = dir.join(&names[2]);
    for (i, k) in list.iter().enumerate().take(idx + 1) {
        report
            .sweep
            .push(sweep_run(*k, 1.0 + i as f64, 0.1 / (1.0 + i as f64)));
        summarise(&mut report);
        write_outputs(&report, &files, "sweep").unwrap();
        assert!(dir.join(&names[0]).is_file() && dir.join(&names[1]).is_file());
        assert_eq!(png.is_file(), i == idx, "after run {i}");
    }
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    std::fs::remove_dir_all(&dir).unwrap();
}
