//! Real-photo effects (issue 28) planted into the built-in example, a known-truth
//! synthetic workspace (`examples/spot`, 6 training and 2 held-out photos of 192², each
//! under its own real map): every figure is the held-out photos' RMSE under their TRUE
//! light (protocol `truth`, after the best scale), so the planted effect is the only thing
//! that differs between the runs compared.
//!
//! - transient occluders: discs of a foreign colour pasted over the object in two training
//!   photos (known pixel masks); the masks written to `outliers/` are scored against them;
//! - a small pose error: the training cameras turned by 0.6° (about 2.8 px at the image
//!   centre), so silhouette pixels mix the black background into the object;
//! - per-photo exposure and white balance: the training photos scaled by planted gains;
//! - partial coverage: one training photo cropped to a small part of the object.

use std::path::{Path, PathBuf};

use relight_cpc::run::{builtin_example, run, MaterialCount, RunOptions};

/// Small settings, as `run_example`'s, so each run stays within seconds.
fn options(ws: &Path, out: PathBuf) -> RunOptions {
    let mut o = RunOptions::new(ws.to_path_buf(), out);
    o.global_resolution = 32;
    o.keep = 64;
    o.max_iterations = 3;
    o.materials = MaterialCount::Fixed(2);
    o.progress = false;
    o.render_training = false;
    o
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

/// A copy of the built-in example in `dir/ws`.
fn workspace(dir: &Path) -> PathBuf {
    let ws = dir.join("ws");
    copy_dir(&builtin_example().unwrap(), &ws);
    ws
}

/// Mean over the held-out photos of protocol `truth`'s RMSE after scale.
fn truth_rmse(r: &relight_cpc::report::RunReport) -> f64 {
    let v: Vec<f64> = r
        .holdout
        .iter()
        .filter(|h| h.protocol == "truth")
        .map(|h| h.rmse_scaled)
        .collect();
    assert_eq!(v.len(), 2, "two held-out photos under their true light");
    v.iter().sum::<f64>() / v.len() as f64
}

fn read_grey(path: &Path) -> image::GrayImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_luma8()
}

/// Training photos that get an occluder: two that see the object from different sides, so
/// that each occluded part of the surface is clean in most of the other photos that see
/// it. That is what makes an occluder transient, and what the mask relies on: an
/// observation is masked where it disagrees with the other photos of the same vertex
/// (`crate::observe::outliers`), so a thing in front of the same part of the surface in
/// most photos is, for the method, part of that surface.
const OCCLUDED: [&str; 2] = ["photo_000", "photo_005"];

/// Pastes a disc of a foreign colour (sRGB 200, 40, 30: a red coat in front of a blue-grey
/// statue) of radius 20 px (about a fifth of the object's pixels) at the object's centroid into `stem`'s photo; returns the
/// planted mask restricted to the object (truth/masks).
fn paste_occluder(ws: &Path, stem: &str) -> Vec<bool> {
    let path = ws.join("images").join(format!("{stem}.png"));
    let mut img = image::open(&path).unwrap().to_rgb8();
    let object = read_grey(&ws.join("truth/masks").join(format!("{stem}.png")));
    let (w, h) = img.dimensions();
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for (x, y, p) in object.enumerate_pixels() {
        if p[0] > 127 {
            sx += x as f64;
            sy += y as f64;
            n += 1.0;
        }
    }
    let (cx, cy) = (sx / n, sy / n);
    let mut planted = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
            if dx * dx + dy * dy <= 20.0 * 20.0 {
                img.put_pixel(x, y, image::Rgb([200, 40, 30]));
                planted[(y * w + x) as usize] = object.get_pixel(x, y)[0] > 127;
            }
        }
    }
    img.save(&path).unwrap();
    planted
}

#[test]
fn transient_occluders_are_masked_and_the_fit_improves() {
    let dir = crate::scratch::scratch("realphoto", "transients");
    let clean_ws = workspace(&dir.join("clean"));
    let clean = run(&options(&clean_ws, dir.join("out-clean")))
        .expect("clean run")
        .report;
    let ws = workspace(&dir);
    let planted: Vec<Vec<bool>> = OCCLUDED.iter().map(|s| paste_occluder(&ws, s)).collect();
    let out = dir.join("out-on");
    let mut o = options(&ws, out.clone());
    o.transients = true;
    let on = run(&o).expect("run with occluders").report;
    let off = run(&options(&ws, dir.join("out-off")))
        .expect("run without the transient mask")
        .report;

    // Mask against the planted discs, over the object's pixels of the occluded photos.
    let (mut tp, mut fp, mut fneg) = (0usize, 0usize, 0usize);
    for (stem, truth) in OCCLUDED.iter().zip(&planted) {
        let m = read_grey(&out.join("outliers").join(format!("{stem}.png")));
        for (i, p) in m.pixels().enumerate() {
            match (p[0] > 127, truth[i]) {
                (true, true) => tp += 1,
                (true, false) => fp += 1,
                (false, true) => fneg += 1,
                _ => {}
            }
        }
    }
    let precision = tp as f64 / (tp + fp).max(1) as f64;
    let recall = tp as f64 / (tp + fneg).max(1) as f64;
    // And on the four clean training photos: object pixels masked for nothing.
    let (mut false_masked, mut object_pixels) = (0usize, 0usize);
    for stem in ["photo_001", "photo_002", "photo_004", "photo_006"] {
        let m = read_grey(&out.join("outliers").join(format!("{stem}.png")));
        let obj = read_grey(&ws.join("truth/masks").join(format!("{stem}.png")));
        for (p, q) in m.pixels().zip(obj.pixels()) {
            object_pixels += usize::from(q[0] > 127);
            false_masked += usize::from(p[0] > 127 && q[0] > 127);
        }
    }
    let clean_false = false_masked as f64 / object_pixels as f64;
    let (e_clean, e_on, e_off) = (truth_rmse(&clean), truth_rmse(&on), truth_rmse(&off));
    eprintln!(
        "occluders: precision {precision:.3} recall {recall:.3} ({tp} / {fp} / {fneg}), \
         clean photos masked {clean_false:.4}; held-out truth RMSE clean {e_clean:.5} \
         masked {e_on:.5} unmasked {e_off:.5}"
    );
    // Measured (2026-11-25): precision 0.914, recall 0.489, 4.1% of the clean photos'
    // object pixels masked, held-out RMSE 0.1100 masked against 0.1125 unmasked and
    // 0.0816 clean (bench-results/realphoto.md). The bounds leave room for rounding and
    // say what the mask is for: what it masks is nearly all occluder (a mask that also
    // ate clean pixels would cost observations for nothing), it finds a sizeable part of
    // each occluder, and it leaves the clean photos nearly whole. The recall is the weak
    // side: the pilot's reflectance at the occluded vertices is pulled toward the
    // occluder, which shrinks their residuals.
    assert!(
        precision >= 0.8 && recall >= 0.4,
        "precision {precision}, recall {recall}"
    );
    assert!(clean_false <= 0.06, "{clean_false}");
    // Within 1.45× the clean fit's held-out error (1.35× measured), below the unmasked fit.
    assert!(e_on <= 1.45 * e_clean, "{e_on} vs clean {e_clean}");
    assert!(e_on < e_off, "{e_on} vs unmasked {e_off}");
}

/// Turns every training camera of `ws` by `radians` about its own y axis, about its centre
/// (`R' = R_δ R`, `t' = R_δ t`): the photos stay, their poses are off by a known amount.
fn turn_training_cameras(ws: &Path, radians: f64) {
    use nalgebra::{Quaternion, UnitQuaternion, Vector3};
    let path = ws.join("sparse/images.txt");
    let text = std::fs::read_to_string(&path).unwrap();
    let turn = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), radians);
    let mut out = String::new();
    // After the comments, image lines and their points lines alternate.
    let mut data_line = 0usize;
    for line in text.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        let image_line = !line.starts_with('#') && data_line.is_multiple_of(2);
        if !line.starts_with('#') {
            data_line += 1;
        }
        if !image_line {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        assert_eq!(t.len(), 10, "an image line: {line}");
        let v: Vec<f64> = t[1..8].iter().map(|s| s.parse().unwrap()).collect();
        let name = t[9];
        let held = name == "photo_003.png" || name == "photo_007.png";
        let (q, tv) = if held {
            (
                UnitQuaternion::from_quaternion(Quaternion::new(v[0], v[1], v[2], v[3])),
                Vector3::new(v[4], v[5], v[6]),
            )
        } else {
            let q = UnitQuaternion::from_quaternion(Quaternion::new(v[0], v[1], v[2], v[3]));
            (turn * q, turn * Vector3::new(v[4], v[5], v[6]))
        };
        out.push_str(&format!(
            "{} {} {} {} {} {} {} {} {} {}\n",
            t[0], q.w, q.i, q.j, q.k, tv.x, tv.y, tv.z, t[8], name
        ));
    }
    std::fs::write(&path, out).unwrap();
}

#[test]
fn edge_margins_lower_the_error_of_a_small_pose_error() {
    // 0.6° at f = 264 px is 2.8 px at the image centre: the silhouette pixels of the
    // training photos mix the black background into the object, as a misregistered real
    // photo mixes in whatever is behind. The held-out photos keep their exact poses.
    let dir = crate::scratch::scratch("realphoto", "margins");
    let ws = workspace(&dir);
    turn_training_cameras(&ws, 0.6f64.to_radians());
    let mut on = options(&ws, dir.join("out-on"));
    on.transients = false;
    let mut off = on.clone();
    off.out = dir.join("out-off");
    off.edge_margin = false;
    let e_on = truth_rmse(&run(&on).expect("run with margins").report);
    let e_off = truth_rmse(&run(&off).expect("run without margins").report);
    eprintln!("pose error 0.6°: held-out truth RMSE with margins {e_on:.5}, without {e_off:.5}");
    // Strictly lower: the margin only removes observations whose colour is contaminated.
    assert!(e_on < e_off, "with margins {e_on}, without {e_off}");
}
