//! Overexposed observations as lower bounds (`run --clipped bound`) on a `synth` workspace
//! exposed so that much of the object clips (`--exposure-peak 2`): the observations' clipped
//! channels and bound weights checked against the same extraction with the clip raised above
//! every code (so nothing is overexposed), and the flag through `run`.

use relight_cpc::import::scene::{load_photos, load_scene};
use relight_cpc::import::workspace::Workspace;
use relight_cpc::observe::trace::SceneBvh;
use relight_cpc::observe::{self, ObserveOptions};
use relight_cpc::run::{run, Clipped, MaterialCount};
use relight_cpc::synth::{build, SynthOptions};
use relight_cpc::transport::reference::Samples;
use std::path::{Path, PathBuf};

use crate::scratch::{scratch, small_options};

/// A small Spot in `dir/ws` whose photos expose the object's 99th percentile to 2: a large
/// share clips.
fn clipped_workspace(dir: &Path) -> PathBuf {
    let ws = dir.join("ws");
    let opts = SynthOptions {
        width: 64,
        height: 64,
        photos: Some(6),
        vertices: Some(600),
        exposure_peak: 2.0,
        samples: Samples {
            per_pixel: 1,
            light: 4,
            seed: 3,
        },
        seed: 3,
        ..SynthOptions::default()
    };
    build("spot-diffuse", &ws, &opts).unwrap();
    ws
}

#[test]
fn clipped_channels_and_bound_weights_match_an_extraction_that_clips_nothing() {
    // With the clip above code 255 (threshold 1.01) no pixel is overexposed, so every
    // observation gets its confidence α and the same bilinear sample. At the default clip a
    // flagged observation has weight 0, the same sample, and bound weight equal to that α;
    // an unflagged one keeps that α as its weight (one threshold marks both a pixel
    // overexposed and its channel clipped, so no observation is overexposed unflagged).
    let dir = scratch("clipped", "plumbing");
    let ws = clipped_workspace(&dir);
    let scene = load_scene(Workspace::discover(&ws, None).unwrap()).unwrap();
    let bvh = SceneBvh::new(&scene.mesh);
    let opts = ObserveOptions::default();
    let extract = |clip: f32| {
        let photos = load_photos(&scene, clip).unwrap();
        observe::extract(&scene.mesh, &bvh, &scene.views, &photos, &opts)
    };
    let (clipped, plain) = (
        extract(relight_cpc::import::photo::DEFAULT_CLIP),
        extract(1.01),
    );
    assert_eq!(clipped.len(), plain.len());
    assert_eq!(clipped.clipped.len(), clipped.len());
    assert!(
        plain.clipped.iter().all(|&m| m == 0),
        "nothing clips above 255"
    );
    let bounds = clipped.clipped.iter().filter(|&&m| m != 0).count();
    assert!(
        bounds * 10 > clipped.len(),
        "peak 2 clips a large share: {bounds} of {}",
        clipped.len()
    );
    // `inspect` counts the same observations (its extraction is the default one).
    let report = relight_cpc::observe::inspect::inspect(&ws, None).unwrap();
    assert_eq!(report.clipped_observations, bounds);
    for p in 0..clipped.len() {
        assert_eq!(clipped.rgb[p], plain.rgb[p], "observation {p}: the sample");
        if clipped.clipped[p] != 0 {
            assert_eq!(
                clipped.weight[p], 0.0,
                "observation {p}: a bound is no value"
            );
            assert_eq!(clipped.bound_weight[p], plain.weight[p], "observation {p}");
        } else {
            assert_eq!(clipped.bound_weight[p], 0.0);
            assert_eq!(clipped.weight[p], plain.weight[p], "observation {p}");
        }
    }
}

#[test]
fn run_reads_bounds_when_asked_and_says_so() {
    // The smallest model on the clipped workspace, with and without `--clipped bound`: both
    // finish with a finite headline, the report names the count of observations with a
    // clipped channel and which rule the fit used, and the training RMSE (bounds met count
    // no error) stays within 2× of the run that drops them.
    let dir = scratch("clipped", "run");
    let ws = clipped_workspace(&dir);
    let small = |tag: &str, bounds: bool| {
        let mut o = small_options(ws.clone(), dir.join(tag));
        o.materials = MaterialCount::Fixed(1);
        o.clipped = if bounds {
            Clipped::Bound
        } else {
            Clipped::Drop
        };
        o
    };
    let mut reports = Vec::new();
    for (tag, bounds) in [("drop", false), ("bound", true)] {
        let o = small(tag, bounds);
        run(&o).unwrap();
        let text = std::fs::read_to_string(o.out.join("report.json")).unwrap();
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(json["headline"].as_f64().unwrap().is_finite(), "{tag}");
        let md = std::fs::read_to_string(o.out.join("report.md")).unwrap();
        let rule = if bounds {
            "their clipped channels read as lower bounds"
        } else {
            "; left out"
        };
        assert!(md.contains(rule), "{tag}: the rule");
        reports.push(json["train_rmse"].as_f64().unwrap());
    }
    assert!(reports[1] < 2.0 * reports[0], "train RMSE {reports:?}");
}
