//! Stiff and extreme inputs through the whole pipeline (issue 8): each case builds a small
//! known-truth workspace with `synth` (64×64 photos, a few hundred vertices, 2–4 photos),
//! breaks one thing, runs `run::run` for 1–3 outer iterations and asserts either a stable
//! result — every reported number and every output map finite, lighting non-negative,
//! objective non-increasing, training error within a stated bound — or a clear error
//! naming the file or option at fault. Never a panic, NaN or hang.

use std::path::{Path, PathBuf};

use relight_cpc::run::{self, Holdout, MaterialCount, RunOptions, RunSummary};
use relight_cpc::sphere::envmap::OctEnv;
use relight_cpc::Error;

use crate::scratch::Scratch;

fn scratch(tag: &str) -> Scratch {
    crate::scratch::scratch("extreme", tag)
}

/// A 64×64 synth workspace of `scene` with `photos` photos and about `vertices` vertices
/// (1 sample(s) per pixel, 8 light samples).
fn workspace(dir: &Path, scene: &str, photos: usize, vertices: usize) -> PathBuf {
    crate::scratch::workspace(dir, scene, photos, vertices, 1, 8)
}

/// Fast run options: small maps, one material, few iterations.
fn fast(ws: &Path, out: &Path) -> RunOptions {
    let mut o = RunOptions::new(ws.to_path_buf(), out.to_path_buf());
    o.holdout = Holdout::None;
    o.materials = MaterialCount::Fixed(1);
    o.global_resolution = 16;
    o.local_resolution = 8;
    o.normal_grid = 8;
    o.keep = 32;
    o.max_iterations = 2;
    o.irls_iterations = 1;
    o.progress = false;
    o.render_training = false;
    o
}

/// The checks every successful run must pass: finite numbers, non-negative finite maps,
/// and an objective that does not increase by more than rounding (the alternation accepts
/// an extrapolated step only when the objective drops, so it is monotone up to the
/// solvers' tolerances: 1e-6 relative).
fn stable(s: &RunSummary) {
    let r = &s.report;
    assert!(
        r.train_rmse.is_finite() && r.train_rmse >= 0.0,
        "train rmse {}",
        r.train_rmse
    );
    for t in &r.train {
        assert!(t.rmse.is_finite(), "{}: rmse {}", t.image, t.rmse);
    }
    for (k, v) in &r.conditioning {
        assert!(!v.is_nan(), "conditioning {k} is NaN");
    }
    let obj: Vec<f64> = r.timeline.iter().map(|t| t.objective).collect();
    assert!(
        obj.iter().all(|o| o.is_finite() && *o >= 0.0),
        "objective {obj:?}"
    );
    for w in obj.windows(2) {
        assert!(
            w[1] <= w[0] * (1.0 + 1e-6) + 1e-12,
            "objective rose: {obj:?}"
        );
    }
    let env_dir = s.out.join("envmaps");
    let mut maps = 0;
    for e in std::fs::read_dir(&env_dir).unwrap() {
        let p = e.unwrap().path();
        if p.to_string_lossy().ends_with(".oct.exr") {
            let env = OctEnv::read_exr(&p).unwrap();
            assert!(
                env.rgb
                    .iter()
                    .flatten()
                    .all(|v| v.is_finite() && *v >= -1e-6),
                "{}: non-finite or negative light",
                p.display()
            );
            maps += 1;
        }
    }
    assert!(maps > 0, "no environment maps written");
}

/// Very sharp lobes at the default resolutions: Phong 500 and GGX 0.01 under-sample the
/// 32×32 local texels; the fit must stay finite and non-negative.
#[test]
fn sharp_lobes_at_default_resolutions() {
    let d = scratch("sharp");
    let ws = workspace(&d.0, "sphere-specular", 2, 300);
    let mut o = fast(&ws, &d.0.join("out"));
    o.global_resolution = 64;
    o.local_resolution = 32;
    o.normal_grid = 8;
    o.keep = 128;
    o.max_iterations = 1;
    o.basis = vec![
        relight_cpc::transport::brdf::BasisBrdf::Lambert,
        relight_cpc::transport::brdf::BasisBrdf::Phong { exponent: 500.0 },
        relight_cpc::transport::brdf::BasisBrdf::Ggx { alpha: 0.01 },
    ];
    let s = run::run(&o).unwrap();
    stable(&s);
}

/// Either a stable run or a specific error (not an I/O failure) whose message says what
/// is wrong; returns the run when it succeeded.
fn stable_or_clear(r: Result<RunSummary, Error>, expect_in_error: &[&str]) -> Option<RunSummary> {
    match r {
        Ok(s) => {
            stable(&s);
            eprintln!(
                "ran: train rmse {:.4}, conditioning {:?}, notes {:?}",
                s.report.train_rmse, s.report.conditioning, s.report.notes
            );
            Some(s)
        }
        Err(e) => {
            let msg = e.to_string();
            eprintln!("refused: {msg}");
            assert!(!matches!(e, Error::Io { .. }), "I/O error: {msg}");
            assert!(
                expect_in_error.iter().any(|w| msg.contains(w)),
                "unclear error (wanted one of {expect_in_error:?}): {msg}"
            );
            None
        }
    }
}

/// Rewrite every photo of the workspace through `f` (8-bit RGB pixels).
fn edit_photos(ws: &Path, f: impl Fn(&mut image::RgbImage)) {
    for e in std::fs::read_dir(ws.join("images")).unwrap() {
        let p = e.unwrap().path();
        let mut im = image::open(&p).unwrap().to_rgb8();
        f(&mut im);
        im.save(&p).unwrap();
    }
}

/// A sun 10⁴× the sky: the city map (peak ~34,000, mean ~1) rotated per photo, with a
/// glossy sphere shadowing a plane.
#[test]
fn hdr_sun_city() {
    let d = scratch("city");
    let ws = workspace(&d.0, "sphere-plane", 3, 400);
    let s = run::run(&fast(&ws, &d.0.join("out"))).unwrap();
    stable(&s);
    // A fit, not garbage: the training error is below the photos' own spread (RMSE of
    // predicting every pixel by 0 would be the mean intensity, ~0.3 on these exposures).
    assert!(
        s.report.train_rmse < 0.3,
        "train rmse {}",
        s.report.train_rmse
    );
}

/// A convex object: no cast shadows, so the lighting step sees only the cosine-blurred
/// light (badly conditioned). The run must stay finite and report its conditioning.
#[test]
fn convex_sphere_without_shadows() {
    let d = scratch("convex");
    let ws = workspace(&d.0, "sphere-diffuse", 3, 300);
    let s = run::run(&fast(&ws, &d.0.join("out"))).unwrap();
    stable(&s);
    assert!(
        !s.report.conditioning.is_empty(),
        "no conditioning reported"
    );
    // And says how the solver used each figure: the lighting system's prior, the λ ridge,
    // the w systems' minimum-norm fallback.
    let uses = &s.report.conditioning_use;
    for (start, needs) in [
        ("lighting", "Laplacian prior"),
        ("material weights λ", "ridge"),
        ("blending weights w", "minimum-norm"),
    ] {
        let line = uses
            .iter()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no {start} line in {uses:#?}"));
        assert!(line.contains(needs), "{line}");
    }
    assert!(
        s.report.train_rmse < 0.3,
        "train rmse {}",
        s.report.train_rmse
    );
}

/// One photo only: the lighting and materials are fitted from a single view.
#[test]
fn single_photo() {
    let d = scratch("single");
    let ws = workspace(&d.0, "sphere-diffuse", 1, 300);
    stable_or_clear(
        run::run(&fast(&ws, &d.0.join("out"))),
        &["photo", "view", "image"],
    );
}

/// Two photos from almost the same viewpoint: the second image is a copy of the first,
/// its pose translated by 1e-7 of the scene size.
#[test]
fn two_nearly_identical_viewpoints() {
    let d = scratch("twin");
    let ws = workspace(&d.0, "sphere-diffuse", 2, 300);
    let images = ws.join("sparse").join("images.txt");
    let text = std::fs::read_to_string(&images).unwrap();
    // images.txt: comment lines, then per image a pose line and a points line.
    let lines: Vec<&str> = text.lines().collect();
    let data: Vec<usize> = (0..lines.len())
        .filter(|&i| !lines[i].starts_with('#'))
        .collect();
    let first: Vec<&str> = lines[data[0]].split_whitespace().collect();
    let second: Vec<&str> = lines[data[2]].split_whitespace().collect();
    let tx: f64 = first[5].parse().unwrap();
    let mut twin: Vec<String> = first.iter().map(|s| s.to_string()).collect();
    twin[0] = second[0].to_string();
    twin[5] = format!("{}", tx + 1e-7);
    twin[9] = second[9].to_string();
    let mut out: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    out[data[2]] = twin.join(" ");
    out[data[3]] = lines[data[1]].to_string();
    std::fs::write(&images, out.join("\n") + "\n").unwrap();
    std::fs::copy(
        ws.join("images").join(first[9]),
        ws.join("images").join(second[9]),
    )
    .unwrap();
    stable_or_clear(run::run(&fast(&ws, &d.0.join("out"))), &["photo", "view"]);
    // The adaptive model sees a copy from within 1° and skips it with a note, fitting the
    // one photo left.
    let mut o = fast(&ws, &d.0.join("adaptive"));
    o.adaptive = true;
    o.materials = MaterialCount::Auto;
    if let Some(s) = stable_or_clear(run::run(&o), &["photo", "view"]) {
        assert_eq!(s.report.train.len(), 1, "{:?}", s.report.notes);
        assert!(
            s.report
                .notes
                .iter()
                .any(|n| n.contains("skipped, it adds no new observation")),
            "{:?}",
            s.report.notes
        );
    }
}

/// Two materials asked for on grey photos (each pixel's channels set to their mean, as a
/// greyscale collection): every vertex has the same hue, so the start's k-means finds one
/// cluster, one material is fitted, and the report's reasons say why in plain words. With
/// `run`'s light by scene and 21 training photos (from `PRIOR_FROM_PHOTOS` = 20) the light
/// follows the one material fitted, not the two asked for: the paper's map, not the prior.
#[test]
fn more_materials_asked_than_the_colours_hold() {
    let d = scratch("one-hue");
    let photos = relight_cpc::run::PRIOR_FROM_PHOTOS + 1;
    let ws = workspace(&d.0, "sphere-diffuse", photos, 300);
    edit_photos(&ws, |im| {
        im.pixels_mut().for_each(|p| {
            let grey = p.0.iter().map(|&v| v as u32).sum::<u32>() / 3;
            p.0 = [grey as u8; 3];
        })
    });
    let mut o = fast(&ws, &d.0.join("out"));
    o.materials = MaterialCount::Fixed(2);
    o.light_by_scene = true;
    // The scene's one lobe, so that the rule's Lambertian branch applies.
    o.basis = vec![relight_cpc::transport::brdf::BasisBrdf::Lambert];
    let s = run::run(&o).expect("a one-colour sphere fits");
    stable(&s);
    let m = &s.report.model;
    assert_eq!(m.materials, 1, "{:#?}", m.reasons);
    let light = m.light.as_ref().expect("the report names the light model");
    assert_eq!(light.model, "paper", "{}", light.why);
    let why = "2 materials were asked for, but the seen vertices' colours form only \
               1 distinct hue cluster (grey photos have one hue), so 1 material is fitted";
    assert!(m.reasons.iter().any(|r| r == why), "{:#?}", m.reasons);
}

/// The adaptive model on stiff inputs: one photo (the pilot holds out observations of
/// the only photo), a nearly black environment, and a one-colour sphere with
/// `--materials auto` (k-means finds no second distinct cluster): a stable run or a clear
/// error, never a panic or NaN.
#[test]
fn adaptive_model_on_stiff_inputs() {
    let d = scratch("adaptive");
    let ws = workspace(&d.0, "sphere-diffuse", 1, 300);
    let mut o = fast(&ws, &d.0.join("one"));
    o.adaptive = true;
    o.materials = MaterialCount::Auto;
    stable_or_clear(run::run(&o), &["photo", "view", "image"]);

    let ws = workspace(&d.0.join("dim"), "sphere-diffuse", 3, 300);
    edit_photos(&ws, |im| {
        im.pixels_mut().for_each(|p| p.0 = p.0.map(|v| v / 40))
    });
    let mut o = fast(&ws, &d.0.join("dim-out"));
    o.adaptive = true;
    o.materials = MaterialCount::Auto;
    if let Some(s) = stable_or_clear(run::run(&o), &["dark", "black", "light"]) {
        // A one-material scene: the pilot picks 1 whatever the brightness.
        assert_eq!(
            s.report.model.materials, 1,
            "{:#?}",
            s.report.model.adaptive
        );
    }
}

/// Photos scaled to 1/40 of their brightness: a nearly black environment seen at a fixed
/// exposure. The fit must stay finite and non-negative.
#[test]
fn nearly_black_environment() {
    let d = scratch("dim");
    let ws = workspace(&d.0, "sphere-diffuse", 3, 300);
    edit_photos(&ws, |im| {
        im.pixels_mut().for_each(|p| p.0 = p.0.map(|v| v / 40))
    });
    stable_or_clear(
        run::run(&fast(&ws, &d.0.join("out"))),
        &["dark", "observation"],
    );
}

/// Entirely black photos: nothing to fit. A run may return zero light or refuse, but not
/// NaN.
#[test]
fn entirely_dark_photos() {
    let d = scratch("dark");
    let ws = workspace(&d.0, "sphere-diffuse", 2, 300);
    edit_photos(&ws, |im| im.pixels_mut().for_each(|p| p.0 = [0, 0, 0]));
    stable_or_clear(
        run::run(&fast(&ws, &d.0.join("out"))),
        &["dark", "observation", "zero"],
    );
}

/// Entirely overexposed photos: every observation is clipped, so none carries
/// information; the run must say so rather than fit clipped values.
#[test]
fn entirely_overexposed_photos() {
    let d = scratch("white");
    let ws = workspace(&d.0, "sphere-diffuse", 2, 300);
    edit_photos(&ws, |im| {
        im.pixels_mut().for_each(|p| p.0 = [255, 255, 255])
    });
    let r = run::run(&fast(&ws, &d.0.join("out")));
    stable_or_clear(r, &["clip", "overexposed", "observation"]);
}

/// A photo of the wrong size: an error naming that photo and the size mismatch.
#[test]
fn photo_of_the_wrong_size() {
    let d = scratch("size");
    let ws = workspace(&d.0, "sphere-diffuse", 2, 300);
    let p = std::fs::read_dir(ws.join("images"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .min()
        .unwrap();
    let im = image::open(&p).unwrap().to_rgb8();
    image::imageops::resize(&im, 48, 40, image::imageops::FilterType::Triangle)
        .save(&p)
        .unwrap();
    let err = run::run(&fast(&ws, &d.0.join("out"))).unwrap_err();
    let msg = err.to_string();
    let name = p.file_name().unwrap().to_string_lossy().to_string();
    assert!(msg.contains(&name), "error does not name {name}: {msg}");
    assert!(
        msg.contains("48") && msg.contains("64"),
        "error does not give sizes: {msg}"
    );
}

/// Writes an ASCII PLY.
fn write_ply(path: &Path, pos: &[[f64; 3]], faces: &[[usize; 3]]) {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        pos.len(),
        faces.len()
    );
    for p in pos {
        s += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    for f in faces {
        s += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
    }
    std::fs::write(path, s).unwrap();
}

/// The synth mesh with degenerate triangles (repeated index, collinear), duplicated
/// vertices (a copy of a patch, stitched in), isolated vertices, and a triangle far
/// behind every camera that no photo sees.
#[test]
fn damaged_mesh() {
    let d = scratch("mesh");
    let ws = workspace(&d.0, "sphere-diffuse", 3, 300);
    let src = ws.join("dense").join("meshed-poisson.ply");
    let data = relight_cpc::import::mesh::read_ply_data(&src).unwrap();
    let mut pos: Vec<[f64; 3]> = data.positions.iter().map(|p| [p.x, p.y, p.z]).collect();
    let mut faces: Vec<[usize; 3]> = data
        .faces
        .iter()
        .map(|f| [f[0] as usize, f[1] as usize, f[2] as usize])
        .collect();
    let n = pos.len();
    // Degenerate: repeated index and a collinear triple (midpoint of an edge).
    let [a, b, c] = faces[0];
    faces.push([a, a, b]);
    let mid = [0, 1, 2].map(|k| 0.5 * (pos[a][k] + pos[b][k]));
    pos.push(mid);
    faces.push([a, b, n]);
    // Duplicated vertices: copies of a, b, c with a face on them (coincident with face 0).
    pos.extend([pos[a], pos[b], pos[c]]);
    faces.push([n + 1, n + 2, n + 3]);
    // Isolated vertices.
    pos.push([0.0, 0.0, 0.0]);
    pos.push([1e3, 1e3, 1e3]);
    // A triangle far away that no photo sees.
    let m = pos.len();
    pos.extend([[1e4, 0.0, 0.0], [1e4, 1.0, 0.0], [1e4, 0.0, 1.0]]);
    faces.push([m, m + 1, m + 2]);
    let mesh = d.0.join("damaged.ply");
    write_ply(&mesh, &pos, &faces);
    let mut o = fast(&ws, &d.0.join("out"));
    o.mesh = Some(mesh);
    stable_or_clear(run::run(&o), &["mesh", "vertex", "vertices"]);
}

/// A mesh of one triangle through the object's centre, facing the first camera.
#[test]
fn one_triangle_mesh() {
    let d = scratch("tri");
    let ws = workspace(&d.0, "sphere-diffuse", 3, 300);
    let rec = relight_cpc::import::colmap::Reconstruction::read_text(&ws.join("sparse")).unwrap();
    // Facing the first camera (the others see it obliquely or from behind).
    let c = rec.images.values().next().unwrap().center();
    let src =
        relight_cpc::import::mesh::read_ply_data(&ws.join("dense").join("meshed-poisson.ply"))
            .unwrap();
    let o: relight_cpc::Vec3 =
        src.positions.iter().sum::<relight_cpc::Vec3>() / src.positions.len() as f64;
    let r = 0.8
        * src
            .positions
            .iter()
            .map(|p| (p - o).norm())
            .fold(0.0, f64::max);
    let dir = (c - o).normalize();
    let u = dir
        .cross(&relight_cpc::Vec3::new(0.3, 0.5, 0.8))
        .normalize();
    let v = dir.cross(&u);
    let mut tri = [
        o + u * r,
        o + (-0.5 * u + 0.866 * v) * r,
        o + (-0.5 * u - 0.866 * v) * r,
    ];
    if (tri[1] - tri[0]).cross(&(tri[2] - tri[0])).dot(&dir) < 0.0 {
        tri.swap(1, 2);
    }
    let mesh = d.0.join("tri.ply");
    write_ply(&mesh, &tri.map(|p| [p.x, p.y, p.z]), &[[0, 1, 2]]);
    let mut o = fast(&ws, &d.0.join("out"));
    o.mesh = Some(mesh);
    stable_or_clear(
        run::run(&o),
        &["mesh", "vertex", "vertices", "observation", "triangle"],
    );
}

/// More materials than the object has: a one-colour sphere fitted with 3 materials
/// (k-means on identical colours; clusters that end up with no vertices).
#[test]
fn more_materials_than_colours() {
    let d = scratch("mats");
    let ws = workspace(&d.0, "sphere-diffuse", 2, 300);
    let mut o = fast(&ws, &d.0.join("out"));
    o.materials = MaterialCount::Fixed(3);
    stable_or_clear(run::run(&o), &["material", "cluster"]);
}

/// Entirely black photos should be refused with a clear error: with no light reaching
/// the camera the materials are undetermined (the run currently reports λ conditioning
/// `inf` and writes zero light and arbitrary materials without a word).
#[test]
fn entirely_dark_photos_are_refused() {
    let d = scratch("dark2");
    let ws = workspace(&d.0, "sphere-diffuse", 2, 300);
    edit_photos(&ws, |im| im.pixels_mut().for_each(|p| p.0 = [0, 0, 0]));
    let e = run::run(&fast(&ws, &d.0.join("out"))).unwrap_err();
    assert!(
        e.to_string().contains("dark") || e.to_string().contains("black"),
        "{e}"
    );
}
