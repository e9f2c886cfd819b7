//! Extreme inputs to single stages (issue 8): k-means on identical colours and clusters
//! that lose every vertex, and the up-front memory check for a mesh of over a million
//! vertices (tested on the sizes alone: nothing that large is allocated).

use relight_cpc::solve::budget::{self, Sizes};
use relight_cpc::solve::cluster::initial_materials;
use relight_cpc::Error;

/// Checks the invariants of an initial clustering: labels in range, albedo finite and
/// non-negative, each weight row non-negative and summing to one (to 1e-9: a sum of at
/// most K numbers in [0, 1]).
fn consistent(m: &relight_cpc::solve::cluster::InitialMaterials, v: usize) -> usize {
    let k = m.albedo.len();
    assert!(k >= 1);
    assert_eq!(m.labels.len(), v);
    assert!(m.labels.iter().all(|&l| l < k));
    assert!(m
        .albedo
        .iter()
        .flatten()
        .all(|a| a.is_finite() && *a >= 0.0));
    assert_eq!(m.weights.len(), v * k);
    for row in m.weights.chunks(k) {
        assert!(row.iter().all(|w| w.is_finite() && *w >= 0.0));
        assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
    k
}

/// k-means asked for 4 clusters of 500 identical colours: one cluster (there is only
/// one distinct point), its albedo that colour.
#[test]
fn kmeans_on_identical_colours() {
    let rgb = vec![[0.4, 0.2, 0.1]; 500];
    let seen = vec![true; 500];
    let m = initial_materials(&rgb, &seen, 4, 7).unwrap();
    let k = consistent(&m, 500);
    assert_eq!(k, 1, "identical colours gave {k} clusters");
    for (a, b) in m.albedo[0].iter().zip(&rgb[0]) {
        assert!((a - b).abs() < 1e-12);
    }
}

/// Two distinct colours, asked for 5 clusters: no empty cluster survives (every cluster
/// that is returned has vertices), and the two colours are separated.
#[test]
fn clusters_without_vertices_are_dropped() {
    let mut rgb = vec![[0.8, 0.1, 0.1]; 200];
    rgb.extend(vec![[0.1, 0.1, 0.8]; 200]);
    // Black and unseen vertices: no hue; they must not create or break a cluster.
    rgb.extend(vec![[0.0, 0.0, 0.0]; 10]);
    let mut seen = vec![true; 400];
    seen.extend(vec![false; 10]);
    let m = initial_materials(&rgb, &seen, 5, 3).unwrap();
    let k = consistent(&m, 410);
    for c in 0..k {
        assert!(m.labels.contains(&c), "cluster {c} has no vertex");
    }
    assert_ne!(m.labels[0], m.labels[399], "red and blue share a cluster");
}

/// No vertex seen, or a NaN colour: a Numeric error that says so.
#[test]
fn kmeans_refuses_unseen_and_nan() {
    let e = initial_materials(&[[0.1; 3]; 3], &[false; 3], 2, 1).unwrap_err();
    assert!(
        matches!(e, Error::Numeric { .. }) && e.to_string().contains("seen"),
        "{e}"
    );
    let e = initial_materials(&[[0.1, f64::NAN, 0.1]], &[true], 1, 1).unwrap_err();
    assert!(e.to_string().contains("non-finite"), "{e}");
}

/// A 1.5 M-vertex mesh seen by 20 photos at the default options does not fit in 16 GiB:
/// the check refuses up front, names the largest item, and the option it suggests does
/// fit (recomputed independently here by applying it).
#[test]
fn million_vertex_mesh_is_refused_up_front() {
    let s = Sizes {
        vertices: 1_500_000,
        photos: 20,
        held_photos: 0,
        photo_pixels: 20 * 3000 * 2000,
        threads: 2,
        observations: Sizes::observations_upper_bound(1_500_000, 20, 20 * 3000 * 2000),
        basis: 3,
        global_resolution: 64,
        local_resolution: 32,
        render_local_resolution: 64,
        normal_grid: 32,
        keep: 128,
    };
    let avail = 16u64 << 30;
    let b = budget::estimate(&s);
    let e = b.check(avail).unwrap_err();
    let msg = e.to_string();
    let Error::Memory {
        needed_bytes,
        available_bytes,
        hint,
        ..
    } = &e
    else {
        panic!("not a memory error: {msg}");
    };
    assert_eq!(*available_bytes, avail);
    assert!(*needed_bytes > avail);
    // Transport: 30 M observations × 3 × 776 B ≈ 65 GiB dominates.
    assert!(msg.contains("transport rows"), "{msg}");
    // Apply the hint and re-check.
    let words: Vec<&str> = hint.split_whitespace().collect();
    let fixed = match words.as_slice() {
        ["--keep", v, ..] => Sizes {
            keep: v.parse().unwrap(),
            ..s
        },
        ["--local-resolution", v, ..] => Sizes {
            local_resolution: v.parse().unwrap(),
            ..s
        },
        ["--render-local-resolution", v, ..] => Sizes {
            render_local_resolution: v.parse().unwrap(),
            ..s
        },
        ["--global-resolution", v, ..] => Sizes {
            global_resolution: v.parse().unwrap(),
            ..s
        },
        ["--normal-grid", v, ..] => Sizes {
            normal_grid: v.parse().unwrap(),
            ..s
        },
        _ => {
            assert!(hint.contains("decimate"), "{hint}");
            let v: u64 = words.iter().rev().find_map(|w| w.parse().ok()).unwrap();
            Sizes {
                vertices: v,
                observations: s.observations / s.vertices * v,
                ..s
            }
        }
    };
    assert!(
        budget::estimate(&fixed).check(avail).is_ok(),
        "hint {hint} does not fit"
    );
}

/// The check against this machine: a small run passes (it is what the tests run).
#[test]
fn small_run_passes_on_this_machine() {
    let s = Sizes {
        vertices: 2500,
        photos: 4,
        held_photos: 1,
        photo_pixels: 5 * 640 * 480,
        threads: 2,
        observations: 10_000,
        basis: 3,
        global_resolution: 64,
        local_resolution: 32,
        render_local_resolution: 64,
        normal_grid: 32,
        keep: 128,
    };
    assert!(budget::check(&s).is_ok());
}

/// Early stopping's held-back fraction (`--validation`) must leave most observations to the
/// fit: outside [0, 0.5) (or NaN) the options are refused with a message naming the flag;
/// 0 (off) and the default pass.
#[test]
fn validation_fraction_outside_its_range_is_refused() {
    use relight_cpc::run::RunOptions;
    let base = RunOptions::new("ws".into(), "out".into());
    assert!(base.check().is_ok());
    for bad in [-0.1, 0.5, 0.7, f64::NAN] {
        let o = RunOptions {
            validation: bad,
            ..base.clone()
        };
        let e = o.check().unwrap_err().to_string();
        assert!(e.contains("--validation"), "{e}");
    }
    let off = RunOptions {
        validation: 0.0,
        ..base.clone()
    };
    assert!(off.check().is_ok());
}

/// `--starts 0` would leave the alternation nothing to start from: refused, naming the flag.
#[test]
fn zero_starts_are_refused() {
    use relight_cpc::run::RunOptions;
    let base = RunOptions::new("ws".into(), "out".into());
    let o = RunOptions {
        starts: 0,
        ..base.clone()
    };
    let e = o.check().unwrap_err().to_string();
    assert!(e.contains("--starts"), "{e}");
    let two = RunOptions { starts: 2, ..base };
    assert!(two.check().is_ok());
}

/// `flag` (set on the defaults by `set`) is refused for every `bad` value, with an error
/// naming it, and accepted for every `good` one.
fn assert_range_checked<T: Copy + std::fmt::Debug>(
    flag: &str,
    set: impl Fn(&mut relight_cpc::run::RunOptions, T),
    bad: &[T],
    good: &[T],
) {
    let base = relight_cpc::run::RunOptions::new("ws".into(), "out".into());
    let with = |v: T| {
        let mut o = base.clone();
        set(&mut o, v);
        o.check()
    };
    for &v in bad {
        let e = with(v).unwrap_err().to_string();
        assert!(e.contains(flag), "{flag} {v:?}: {e}");
    }
    for &v in good {
        assert!(with(v).is_ok(), "{flag} {v:?}");
    }
}

/// `--weights-sum` is a non-negative multiple of the data's charge: negative, NaN or
/// infinite refused, naming the flag; 0 (off) and positive values pass.
#[test]
fn weights_sum_outside_its_range_is_refused() {
    assert_range_checked(
        "--weights-sum",
        |o, v| o.weights_sum = relight_cpc::run::WeightsSum::Fixed(v),
        &[-0.5, f64::NAN, f64::INFINITY],
        &[0.0, 1.0, 10.0],
    );
}

/// `--pilot-vertices` is 0 (every vertex) or at least `PILOT_MIN_VERTICES`: with 1 the
/// pilot's sample held no seen vertex and the run stopped in k-means with a message about
/// the photos; now the flag is refused by name.
#[test]
fn a_pilot_sample_too_small_to_cluster_is_refused() {
    let min = relight_cpc::solve::adapt::PILOT_MIN_VERTICES;
    assert_range_checked(
        "--pilot-vertices",
        |o, v| o.pilot_vertices = v,
        &[1, 5, min - 1],
        &[0, min, 25_000, 1_000_000],
    );
}

/// `--weights-sum-on blends` needs a strength to apply: with `--weights-sum auto` (the
/// pilot chooses where the prior applies) it is refused, naming the flag; with a number it
/// passes.
#[test]
fn weights_sum_on_blends_needs_a_strength() {
    use relight_cpc::run::{RunOptions, WeightsSum};
    use relight_cpc::solve::{SumScope, BLEND_FLOOR};
    let blends = RunOptions {
        weights_sum_scope: SumScope::Blends { floor: BLEND_FLOOR },
        ..RunOptions::new("ws".into(), "out".into())
    };
    assert_eq!(blends.weights_sum, WeightsSum::Auto);
    let e = blends.check().unwrap_err().to_string();
    assert!(e.contains("--weights-sum-on"), "{e}");
    let given = RunOptions {
        weights_sum: WeightsSum::Fixed(1.0),
        ..blends
    };
    assert!(given.check().is_ok());
}

/// `--weights-smoothness` is a non-negative multiple of the data's charge, like
/// `--weights-sum`: negative, NaN or infinite refused, naming the flag.
#[test]
fn weights_smoothness_outside_its_range_is_refused() {
    assert_range_checked(
        "--weights-smoothness",
        |o, v| o.weights_smoothness = relight_cpc::run::WeightsSmoothness::Fixed(v),
        &[-0.1, f64::NAN, f64::INFINITY],
        &[0.0, 0.1, 3.0],
    );
}

/// `--weights-bic` is a non-negative multiple of BIC's penalty: negative, NaN or infinite
/// refused, naming the flag.
#[test]
fn weights_bic_outside_its_range_is_refused() {
    assert_range_checked(
        "--weights-bic",
        |o, v| o.weights_bic = relight_cpc::run::PriorStrength::Fixed(v),
        &[-1.0, f64::NAN, f64::INFINITY],
        &[0.0, 1.0, 2.5],
    );
}

/// `--smoothness` is a weight ≥ 0 (or `auto`): negative, NaN and infinite refused, naming
/// the flag.
#[test]
fn smoothness_outside_its_range_is_refused() {
    assert_range_checked(
        "--smoothness",
        |o, v| o.smoothness = relight_cpc::run::PriorStrength::Fixed(v),
        &[-1e-3, f64::NAN, f64::INFINITY],
        &[0.0, 1e-3, 1.6e-2],
    );
}

/// `--robust-floor` is a fraction of the RMS radiance: outside [0, 1) (or NaN) refused,
/// naming the flag.
#[test]
fn robust_floor_outside_its_range_is_refused() {
    assert_range_checked(
        "--robust-floor",
        |o, v| o.robust_floor = v,
        &[-0.1, 1.0, f64::NAN, f64::INFINITY],
        &[0.1],
    );
}

/// `--blend-tolerance` is a fraction of each lighting row's energy: outside [0, 1) (or NaN)
/// refused, naming the flag; 0 (the exact blend) and the default accepted.
#[test]
fn blend_tolerance_outside_its_range_is_refused() {
    assert_range_checked(
        "--blend-tolerance",
        |o, v| o.blend_tolerance = v,
        &[-1e-3, 1.0, f64::NAN, f64::INFINITY],
        &[0.0, relight_cpc::solve::options::BLEND_TOLERANCE],
    );
}

/// `--ray-lattice` is 1 (every texel's first ray) or 2 (every other texel's): 0 and 3 are
/// refused, naming the flag.
#[test]
fn ray_lattice_outside_its_range_is_refused() {
    assert_range_checked(
        "--ray-lattice",
        |o, v| o.ray_lattice = v,
        &[0, 3, 8],
        &[1, 2],
    );
}
