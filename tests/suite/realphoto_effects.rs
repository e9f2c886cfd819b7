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

/// Mean over the two held-out photos of `protocol`'s RMSE after scale (`truth`: under
/// their true light; `half`: right half, the map fitted on the left half).
fn holdout_rmse(r: &relight_cpc::report::RunReport, protocol: &str) -> f64 {
    let v: Vec<f64> = r
        .holdout
        .iter()
        .filter(|h| h.protocol == protocol)
        .map(|h| h.rmse_scaled)
        .collect();
    assert_eq!(v.len(), 2, "two held-out photos under protocol {protocol}");
    v.iter().sum::<f64>() / v.len() as f64
}

fn truth_rmse(r: &relight_cpc::report::RunReport) -> f64 {
    holdout_rmse(r, "truth")
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

/// `--loss auto` (`relight_cpc::solve::loss_choice`) on the example with occluders pasted
/// into two training photos, a collection where either loss could be the better one: the
/// robust loss plays the discs down, plain least squares also fits the scene's own
/// misfit. Judged by the truth the choice never sees (the held-out photos under their true
/// light), the loss kept must be the one whose fit predicts them better, and its fit must
/// be the forced loss's, bit for bit (the kept loss is fitted again with early stopping's
/// own held-back observations, as `--loss robust|plain` fits it). Measured: halves scores
/// robust 0.4744, plain 0.4396 (7.3% lower, past the 3% margin), so plain is kept; under
/// the true light robust 0.1109, plain 0.1072. Seeded, so the same on every run.
#[test]
fn the_loss_auto_keeps_is_the_one_the_truth_prefers_under_occluders() {
    use relight_cpc::solve::loss_choice::LossChoice;
    let dir = crate::scratch::scratch("realphoto", "loss");
    let ws = workspace(&dir);
    for s in OCCLUDED {
        paste_occluder(&ws, s);
    }
    let with = |loss: LossChoice| {
        let mut o = options(&ws, dir.join(format!("out-{}", loss.name())));
        o.loss = loss;
        run(&o).expect("run with occluders").report
    };
    let auto = with(LossChoice::Auto);
    let reason = auto
        .model
        .reasons
        .iter()
        .find(|r| r.starts_with("loss: "))
        .expect("the loss's reason");
    let kept_plain = reason.starts_with("loss: plain least squares");
    let (robust, plain) = (with(LossChoice::Robust), with(LossChoice::Plain));
    let (e_robust, e_plain) = (truth_rmse(&robust), truth_rmse(&plain));
    eprintln!("{reason}\ntruth: robust {e_robust:.5}, plain {e_plain:.5}");
    let forced = if kept_plain { &plain } else { &robust };
    assert_eq!(truth_rmse(&auto), truth_rmse(forced), "{reason}");
    assert_eq!(auto.headline, forced.headline, "{reason}");
    // The truth's choice, with no margin: the two fits differ by the loss alone.
    assert_eq!(
        kept_plain,
        e_plain < e_robust,
        "{reason}: robust {e_robust}, plain {e_plain}"
    );
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

fn half_rmse(r: &relight_cpc::report::RunReport) -> f64 {
    holdout_rmse(r, "half")
}

/// Multiplies `stem`'s photo by `gain` per channel in linear RGB (decode sRGB, scale,
/// re-encode to 8 bits), as a camera's exposure and white balance would.
fn plant_gain(ws: &Path, stem: &str, gain: [f32; 3]) {
    use relight_cpc::import::photo::{linear_to_srgb, srgb_to_linear};
    let path = ws.join("images").join(format!("{stem}.png"));
    let mut img = image::open(&path).unwrap().to_rgb8();
    for p in img.pixels_mut() {
        for c in 0..3 {
            let lin = srgb_to_linear(p[c] as f32 / 255.0) * gain[c];
            p[c] = (linear_to_srgb(lin) * 255.0).round() as u8;
        }
    }
    img.save(&path).unwrap();
}

/// Planted per-photo exposure and white balance: gains at most 1 (no new clipping),
/// one photo a pure exposure change, the others per-channel casts up to 1.8× between
/// channels. `photo_000` and `photo_005` keep gain 1.
const GAINS: [(&str, [f32; 3]); 4] = [
    ("photo_001", [1.0, 0.8, 0.6]),
    ("photo_002", [0.55, 0.7, 0.9]),
    ("photo_004", [0.7, 0.7, 0.7]),
    ("photo_006", [0.9, 1.0, 0.65]),
];

/// RMS over the object's pixels (truth/masks) and channels of `(1 − g_c)·y_c`, `y` the
/// clean photo's linear colour: what an unabsorbed gain leaves in the residuals.
fn unabsorbed_rms(ws: &Path, stem: &str, g: [f32; 3]) -> f64 {
    use relight_cpc::import::photo::srgb_to_linear;
    let img = image::open(ws.join("images").join(format!("{stem}.png")))
        .unwrap()
        .to_rgb8();
    let object = read_grey(&ws.join("truth/masks").join(format!("{stem}.png")));
    let (mut sum, mut n) = (0.0, 0.0);
    for (x, y, p) in img.enumerate_pixels() {
        if object.get_pixel(x, y)[0] > 127 {
            for c in 0..3 {
                let r = (1.0 - g[c]) * srgb_to_linear(p[c] as f32 / 255.0);
                sum += (r * r) as f64;
                n += 1.0;
            }
        }
    }
    (sum / n).sqrt()
}

/// Relative tolerance of a training photo's RMSE between the clean and the gained run:
/// at 3 outer iterations the fit is not converged and lands on a nearby iterate when any
/// colours change; the two ungained photos' RMSEs move by up to 9.3% (measured:
/// `photo_000` +3.8%, `photo_005` −9.3%).
const TRAIN_TOL: f64 = 0.15;

/// Relative tolerance of the held-out check. The model absorbs a gain exactly, the
/// data do not quite: the photos are re-quantised to 8 bits after the gain (steps up to
/// 1.8× coarser in the darkest channel), and the clustered start and the scale anchor
/// see the scaled colours, so the fit lands on a nearby iterate (measured: `half`
/// +2.1%, `truth` +4.6% with the gains of [`GAINS`]).
const TOL: f64 = 0.05;

#[test]
fn per_photo_exposure_and_white_balance_are_absorbed_by_the_maps() {
    // Each photo's map is free per channel, and the Laplacian weight, the robust scale and
    // the lighting step's system all scale with the photo's own radiance (docs/method.md,
    // "Exposure and white balance"), so a gain g_{I,c} on photo I is absorbed by its map
    // L_{I,c}: the photo is still fitted and the held-out prediction does not move.
    let dir = crate::scratch::scratch("realphoto", "gains");
    let clean_ws = workspace(&dir.join("clean"));
    let gained_ws = workspace(&dir.join("gained"));
    for (stem, g) in GAINS {
        plant_gain(&gained_ws, stem, g);
    }
    let clean = options(&clean_ws, dir.join("out-clean"));
    let gained = options(&gained_ws, dir.join("out-gained"));
    let r_clean = run(&clean).expect("clean run").report;
    let r_gained = run(&gained).expect("run with planted gains").report;

    // Recovered: each gained photo's map takes its gain, so its training residuals stay
    // those of the clean run (times the gain). Were the gain not absorbed, the photo would
    // keep a residual of (1 − g_c)·y on top: its RMSE at least √(e² + u²), `u` the RMS of
    // (1 − g_c)·y over the object's pixels of the clean photo.
    let train = |r: &relight_cpc::report::RunReport, stem: &str| -> f64 {
        let e = r.train.iter().find(|t| t.image.starts_with(stem));
        e.unwrap_or_else(|| panic!("{stem} in report.train")).rmse
    };
    for (stem, g) in GAINS {
        let (e_clean, e_gained) = (train(&r_clean, stem), train(&r_gained, stem));
        let u = unabsorbed_rms(&clean_ws, stem, g);
        eprintln!(
            "{stem}: gains {g:?}, training RMSE clean {e_clean:.5}, with gain {e_gained:.5}, \
             not absorbed ≥ {:.5}",
            e_clean.hypot(u)
        );
        assert!(
            e_gained < e_clean * (1.0 + TRAIN_TOL),
            "{stem}: training RMSE {e_gained} with gains {g:?}, {e_clean} without"
        );
        // The check can fail: not absorbing the gain costs more than the tolerance.
        assert!(
            e_clean.hypot(u) > e_clean * (1.0 + TRAIN_TOL),
            "{stem}: gain too small to test"
        );
    }
    // Absorbed: the held-out photos (no gain) are predicted as well. Protocol `half`
    // refits each held-out photo's map, so it is blind to the per-channel balance the
    // reflectance takes from the (gained) training colours; `truth` is not (true light,
    // one global scale) and is only reported.
    let (h_clean, h_gained) = (half_rmse(&r_clean), half_rmse(&r_gained));
    eprintln!(
        "held-out half RMSE clean {h_clean:.5}, with gains {h_gained:.5}; truth {:.5} / {:.5}",
        truth_rmse(&r_clean),
        truth_rmse(&r_gained)
    );
    assert!(
        (h_gained / h_clean - 1.0).abs() < TOL,
        "half RMSE {h_gained} with gains, {h_clean} without"
    );
}

/// Rewrites `ws/sparse/images.txt` line by line: `edit(name, image line)` returns the
/// image line to keep (`None` drops the image with its points line).
fn edit_images(ws: &Path, edit: impl Fn(&str, &str) -> Option<String>) {
    let path = ws.join("sparse/images.txt");
    let text = std::fs::read_to_string(&path).unwrap();
    let (mut out, mut data_line, mut drop_points) = (String::new(), 0usize, false);
    for line in text.lines() {
        if line.starts_with('#') {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        data_line += 1;
        if data_line % 2 == 0 {
            if !drop_points {
                out.push_str(line);
                out.push('\n');
            }
            continue;
        }
        let name = line
            .split_whitespace()
            .last()
            .unwrap_or_default()
            .to_string();
        match edit(&name, line) {
            Some(l) => {
                out.push_str(&l);
                out.push('\n');
                drop_points = false;
            }
            None => drop_points = true,
        }
    }
    std::fs::write(&path, out).unwrap();
}

/// Crops `stem`'s photo to the upper-left quarter of the object's bounding box (truth
/// masks) and gives it its own PINHOLE camera with the principal point shifted by the
/// crop's corner, so the pose still projects the mesh onto the same pixels.
fn crop_to_a_quarter(ws: &Path, stem: &str) {
    let object = read_grey(&ws.join("truth/masks").join(format!("{stem}.png")));
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (x, y, p) in object.enumerate_pixels() {
        if p[0] > 127 {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
    }
    let (w, h) = ((x1 - x0).div_ceil(2), (y1 - y0).div_ceil(2));
    let path = ws.join("images").join(format!("{stem}.png"));
    let img = image::open(&path).unwrap().to_rgb8();
    image::imageops::crop_imm(&img, x0, y0, w, h)
        .to_image()
        .save(&path)
        .unwrap();
    let cams = ws.join("sparse/cameras.txt");
    let text = std::fs::read_to_string(&cams).unwrap();
    let line = text.lines().find(|l| l.starts_with("1 ")).unwrap();
    let t: Vec<f64> = line
        .split_whitespace()
        .skip(4)
        .map(|s| s.parse().unwrap())
        .collect();
    let (f, cx, cy) = (t[0], t[2] - x0 as f64, t[3] - y0 as f64);
    std::fs::write(
        &cams,
        format!("{text}2 PINHOLE {w} {h} {f} {} {cx} {cy}\n", t[1]),
    )
    .unwrap();
    edit_images(ws, |name, line| {
        if name != format!("{stem}.png") {
            return Some(line.to_string());
        }
        let mut t: Vec<&str> = line.split_whitespace().collect();
        t[8] = "2";
        Some(t.join(" "))
    });
}

/// Removes image `id`'s entries from every track of `ws/sparse/points3D.txt`
/// (`ID X Y Z R G B ERROR (IMAGE_ID POINT2D_IDX)…`).
fn drop_tracks(ws: &Path, id: &str) {
    let path = ws.join("sparse/points3D.txt");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        if line.starts_with('#') || t.len() < 8 {
            out.push_str(line);
        } else {
            let mut kept: Vec<&str> = t[..8].to_vec();
            for pair in t[8..].chunks(2).filter(|p| p[0] != id) {
                kept.extend_from_slice(pair);
            }
            out.push_str(&kept.join(" "));
        }
        out.push('\n');
    }
    std::fs::write(&path, out).unwrap();
}

#[test]
fn a_photo_that_sees_a_corner_of_the_object_does_not_hurt_the_fit() {
    // One training photo cropped to the upper-left quarter of the object's bounding box:
    // its map is fitted from the observations it has, and its observations count in the
    // material step only at the vertices it sees. So the held-out error with the cropped
    // photo is no worse than without the photo (up to TOL): a partial view neither breaks
    // the fit nor drags the vertices it does not see. (With so few observations it does
    // not measurably help either: 0.0936 against 0.0938 under the true light.)
    let dir = crate::scratch::scratch("realphoto", "partial");
    const STEM: &str = "photo_001";
    // Its IMAGE_ID in examples/spot/sparse/images.txt.
    const STEM_ID: &str = "2";
    let full_ws = workspace(&dir.join("full"));
    let crop_ws = workspace(&dir.join("crop"));
    let drop_ws = workspace(&dir.join("drop"));
    crop_to_a_quarter(&crop_ws, STEM);
    edit_images(&drop_ws, |name, line| {
        (name != format!("{STEM}.png")).then(|| line.to_string())
    });
    std::fs::remove_file(drop_ws.join("images").join(format!("{STEM}.png"))).unwrap();
    drop_tracks(&drop_ws, STEM_ID);
    let r_full = run(&options(&full_ws, dir.join("out-full")))
        .expect("full")
        .report;
    let r_crop = run(&options(&crop_ws, dir.join("out-crop")))
        .expect("cropped")
        .report;
    let r_drop = run(&options(&drop_ws, dir.join("out-drop")))
        .expect("dropped")
        .report;
    let seen = |r: &relight_cpc::report::RunReport| {
        r.train
            .iter()
            .find(|t| t.image.starts_with(STEM))
            .map_or(0, |t| t.observations)
    };
    let (n_full, n_crop) = (seen(&r_full), seen(&r_crop));
    let e = [&r_full, &r_crop, &r_drop].map(|r| (truth_rmse(r), half_rmse(r)));
    eprintln!(
        "{STEM}: observations whole {n_full}, cropped {n_crop}; held-out truth / half RMSE \
         whole {:.5} / {:.5}, cropped {:.5} / {:.5}, without {:.5} / {:.5}",
        e[0].0, e[0].1, e[1].0, e[1].1, e[2].0, e[2].1
    );
    assert_eq!(seen(&r_drop), 0, "the dropped photo is gone");
    // The bounding box's corner quarter holds at most a quarter of the object's pixels
    // (measured: 47 of 833 observations).
    assert!(
        n_crop > 0 && n_crop * 4 < n_full,
        "cropped {n_crop}, whole {n_full}"
    );
    // The photo matters: without it the held-out error is higher (measured 0.0938 against
    // 0.0816 under the true light), so the bound below can fail.
    assert!(e[0].0 < e[2].0, "whole {:?}, without {:?}", e[0], e[2]);
    // The partial photo does not hurt: within TOL of the run without it, under both
    // protocols (TOL: the spread of a held-out figure when the fit lands on a nearby
    // iterate, as in the planted-gain test).
    for (p, (c, d)) in [("truth", (e[1].0, e[2].0)), ("half", (e[1].1, e[2].1))] {
        assert!(
            c < d * (1.0 + TOL),
            "{p}: cropped {c}, without the photo {d}"
        );
    }
}
