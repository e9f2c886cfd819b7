//! `synth` output read back by the project's readers (COLMAP text model, PLY, EXR, PNG):
//! every 3D point projects onto its recorded 2D observations, the photos' silhouettes match
//! a rasterisation of the mesh written to `dense/`, the exposure clips ~1% of the object,
//! the truth files are complete, and the same seed gives the same bytes.

use relight_cpc::import::colmap::Reconstruction;
use relight_cpc::import::mesh::Mesh;
use relight_cpc::sphere::envmap::LatLong;
use relight_cpc::synth::{build, scene_names, SynthOptions};
use relight_cpc::transport::reference::Samples;
use std::path::{Path, PathBuf};

fn tmp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("relight-synth-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn small(photos: usize, seed: u64) -> SynthOptions {
    SynthOptions {
        width: 64,
        height: 48,
        photos: Some(photos),
        seed,
        vertices: Some(600),
        exact_vertices: false,
        noise: 0.0,
        white_balance: true,
        exposure_peak: 1.0,
        shared_skies: false,
        geotag: false,
        sky_background: false,
        samples: Samples {
            per_pixel: 1,
            light: 4,
            seed,
        },
        points: 400,
    }
}

#[test]
fn scene_list_is_complete() {
    let names = scene_names();
    for n in [
        "sphere-diffuse",
        "sphere-glossy",
        "sphere-specular",
        "sphere-plane",
        "spot-varying",
        "spot-one",
        "spot-static",
        "spot-textured",
    ] {
        assert!(names.contains(&n), "{n} missing from {names:?}");
    }
    assert!(build("no-such-scene", &tmp("none"), &small(2, 1)).is_err());
}

#[test]
fn points_land_on_their_observations_and_silhouettes_match_the_mesh() {
    let out = tmp("readback");
    let summary = build("sphere-plane", &out, &small(4, 3)).unwrap();
    let rec = Reconstruction::read_text(&out.join("sparse")).unwrap();
    assert_eq!(rec.images.len(), 4);
    assert!(rec.points3d.len() > 50, "{} points", rec.points3d.len());
    assert_eq!(rec.points3d.len(), summary.points3d);

    // Every track element: the 3D point projected by the COLMAP reader's camera and pose
    // lands on the recorded keypoint. The writer prints shortest round-trip decimals and
    // the pose goes through a quaternion: 1e-6 px is far above that round-off (~1e-12).
    let mut n_obs = 0;
    for p in rec.points3d.values() {
        assert!(p.track.len() >= 2);
        for te in &p.track {
            let im = &rec.images[&te.image_id];
            let kp = &im.points2d[te.point2d_idx as usize];
            assert_eq!(kp.point3d_id, Some(p.id));
            let xy = rec.project(te.image_id, &p.xyz).unwrap();
            let err = ((xy[0] - kp.xy[0]).powi(2) + (xy[1] - kp.xy[1]).powi(2)).sqrt();
            assert!(
                err < 1e-6,
                "point {} in image {}: {err} px",
                p.id.0,
                im.name
            );
            n_obs += 1;
        }
    }
    assert_eq!(n_obs, summary.observations);

    // Silhouettes: rasterise the PLY mesh with the model's cameras (point-in-triangle at
    // pixel centres, no ray tracing) and compare with the photos' non-black pixels.
    // Pixels whose 3×3 neighbourhood is all inside (or all outside) must agree: outside
    // pixels are exactly black (no noise, black background); inside pixels may be black
    // only where the radiance rounds to 0 in 8 bits (allow 1%).
    let (mesh, _) = Mesh::read_ply(&out.join("dense/meshed-poisson.ply")).unwrap();
    let cam = rec.cameras.values().next().unwrap();
    let (w, h) = (cam.width as usize, cam.height as usize);
    for im in rec.images.values() {
        let proj: Vec<Option<[f64; 2]>> = mesh
            .positions
            .iter()
            .map(|p| cam.project(&im.cam_from_world_point(p)))
            .collect();
        let mut inside = vec![false; w * h];
        for f in &mesh.faces {
            let [Some(a), Some(b), Some(c)] = f.map(|v| proj[v as usize]) else {
                continue;
            };
            let edge = |p: [f64; 2], q: [f64; 2], x: [f64; 2]| {
                (q[0] - p[0]) * (x[1] - p[1]) - (q[1] - p[1]) * (x[0] - p[0])
            };
            let lo_x = a[0].min(b[0]).min(c[0]).floor().max(0.0) as usize;
            let hi_x = (a[0].max(b[0]).max(c[0]).ceil().max(0.0) as usize).min(w);
            let lo_y = a[1].min(b[1]).min(c[1]).floor().max(0.0) as usize;
            let hi_y = (a[1].max(b[1]).max(c[1]).ceil().max(0.0) as usize).min(h);
            for y in lo_y..hi_y {
                for x in lo_x..hi_x {
                    let q = [x as f64 + 0.5, y as f64 + 0.5];
                    let (e0, e1, e2) = (edge(a, b, q), edge(b, c, q), edge(c, a, q));
                    if (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0)
                        || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0)
                    {
                        inside[y * w + x] = true;
                    }
                }
            }
        }
        let photo = image::open(out.join("images").join(&im.name))
            .unwrap()
            .to_rgb8();
        assert_eq!((photo.width() as usize, photo.height() as usize), (w, h));
        let (mut dark_inside, mut n_inside, mut n_outside) = (0, 0, 0);
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let nb = |v: bool| {
                    (0..3).all(|dy| (0..3).all(|dx| inside[(y + dy - 1) * w + x + dx - 1] == v))
                };
                let lit = photo.get_pixel(x as u32, y as u32).0.iter().any(|&c| c > 0);
                if nb(true) {
                    n_inside += 1;
                    dark_inside += usize::from(!lit);
                } else if nb(false) {
                    n_outside += 1;
                    assert!(!lit, "{}: pixel ({x}, {y}) lit outside the mesh", im.name);
                }
            }
        }
        assert!(
            n_inside > 100 && n_outside > 20,
            "{}: {n_inside} / {n_outside}",
            im.name
        );
        assert!(
            dark_inside * 100 <= n_inside,
            "{}: {dark_inside} of {n_inside} dark",
            im.name
        );
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn truth_is_complete_and_exposure_clips_about_one_percent() {
    let out = tmp("truth");
    let mut opts = small(5, 9);
    opts.width = 96;
    opts.height = 96;
    let s = build("spot-varying", &out, &opts).unwrap();
    assert_eq!(s.held_out, vec!["photo_003.png".to_string()]);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("truth/manifest.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["scene"], "spot-varying");
    let photos = manifest["photos"].as_array().unwrap();
    assert_eq!(photos.len(), 5);
    // A different real map per photo; each truth map is the embedded map turned about up by
    // whole texels, so its integral ∫L dω is unchanged (f32 sums: 1e-5 relative).
    let mut maps = std::collections::BTreeSet::new();
    let mut integrals = std::collections::BTreeMap::new();
    for p in photos {
        let name = p["map"].as_str().unwrap().to_string();
        let (env, _) =
            LatLong::read_exr(&out.join("truth").join(p["env"].as_str().unwrap())).unwrap();
        let i = env.integral();
        if let Some(prev) = integrals.get(&name) {
            let prev: &[f64; 3] = prev;
            for c in 0..3 {
                assert!((prev[c] - i[c]).abs() <= 1e-5 * prev[c].abs().max(1e-9));
            }
        }
        integrals.insert(name.clone(), i);
        maps.insert(name);
    }
    assert_eq!(maps.len(), 5);
    // Weights: two materials, non-negative, summing to one at every vertex (1e-6: f32).
    let data = relight_cpc::import::mesh::read_ply_data(&out.join("truth/weights.ply")).unwrap();
    let (mesh, _) = Mesh::read_ply(&out.join("dense/meshed-poisson.ply")).unwrap();
    assert_eq!(data.positions.len(), mesh.positions.len());
    let materials: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("truth/materials.json")).unwrap())
            .unwrap();
    assert_eq!(materials["materials"].as_array().unwrap().len(), 2);
    assert_eq!(materials["photos"].as_array().unwrap().len(), 5);
    // Exposure: the 99th percentile of the brightest channel maps to 1, so about 1% of the
    // object's pixels (coverage > 0 in the truth mask) clip at 255; ties and the ≥ 1
    // boundary allow 0.3%–3%.
    for p in photos {
        let name = p["name"].as_str().unwrap();
        let pixels = object_pixels(&out, name);
        let obj = pixels.len();
        let clipped = pixels.iter().filter(|px| px.contains(&255)).count();
        let frac = clipped as f64 / obj as f64;
        assert!(
            obj > 200 && (0.003..=0.03).contains(&frac),
            "{name}: {clipped}/{obj}"
        );
    }
    std::fs::remove_dir_all(&out).ok();
}

/// Each photo's background, read by `observe::background` from the PNG (8-bit sRGB decoded,
/// the mesh rasterised by the COLMAP cameras), against the truth: with `sky_background`
/// every texel it reads holds the truth map there (synth's EXR resampled onto the same
/// 32² octahedral map, times the photo's exposure and white balance: `Truth::light`): per
/// channel every texel's ratio within 6% of 1, their median and the pixel-weighted sums
/// within 1% (measured: 0.953–1.038, medians and sums 0.999–1.001). The reading is the
/// pixel centres' solid-angle-weighted mean, the truth the texel's integral over 1,024
/// samples: a map varying inside a texel and the 8-bit steps leave a few percent per
/// texel. A wrong frame, flip, exposure or a texel read in part (its bright part clipped
/// or hidden) moves single texels by tens of percent. Without the option every
/// background pixel is black.
#[test]
fn sky_backgrounds_show_the_truth_map() {
    use relight_cpc::import::{scene, workspace::Workspace};
    use relight_cpc::observe::background::{extract, BackgroundOptions};
    let n = 32;
    for sky in [true, false] {
        let out = tmp(&format!("sky-{sky}"));
        let mut opts = small(4, 3);
        (opts.width, opts.height, opts.sky_background) = (128, 128, sky);
        build("spot-varying", &out, &opts).unwrap();
        let sc = scene::load_scene(Workspace::discover(&out, None).unwrap()).unwrap();
        let photos = scene::load_photos(&sc, relight_cpc::import::photo::DEFAULT_CLIP).unwrap();
        let truth = relight_cpc::run::Truth::read(&out.join("truth")).unwrap();
        let env_from_world = truth.env_from_world;
        let bg_opts = BackgroundOptions::new(n);
        let bg = extract(&sc.mesh, &sc.views, &photos, &env_from_world, &bg_opts);
        assert_eq!(bg.len(), 4);
        let mut ratios: [Vec<f64>; 3] = Default::default();
        let mut sums = [(0.0, 0.0); 3];
        for (view, texels) in sc.views.iter().zip(&bg) {
            assert!(!texels.is_empty(), "{}: no texel", view.image.name);
            let env = truth
                .light(&view.image.name, n, &env_from_world)
                .unwrap()
                .unwrap();
            for t in texels {
                let truth_rgb = env.rgb[t.texel as usize];
                for c in 0..3 {
                    if !sky {
                        assert_eq!(t.mean[c], 0.0);
                    } else if truth_rgb[c] > 1e-3 {
                        ratios[c].push(f64::from(t.mean[c] / truth_rgb[c]));
                        let w = f64::from(t.pixels);
                        sums[c].0 += w * f64::from(t.mean[c]);
                        sums[c].1 += w * f64::from(truth_rgb[c]);
                    }
                }
            }
        }
        if sky {
            for (c, r) in ratios.iter_mut().enumerate() {
                r.sort_by(f64::total_cmp);
                let q = |f: f64| r[(f * r.len() as f64) as usize];
                assert!(r.len() >= 8, "channel {c}: {} texels", r.len());
                assert!(
                    (q(0.5) - 1.0).abs() < 0.01,
                    "channel {c}: median {}",
                    q(0.5)
                );
                assert!(
                    r[0] > 0.94 && r[r.len() - 1] < 1.06,
                    "channel {c}: {} – {}",
                    r[0],
                    r[r.len() - 1]
                );
                let total = sums[c].0 / sums[c].1;
                assert!(
                    (total - 1.0).abs() < 0.01,
                    "channel {c}: pixel-weighted {total}"
                );
            }
        }
        std::fs::remove_dir_all(&out).ok();
    }
}

/// The 8-bit RGB of the object's pixels (coverage > 0 in the truth mask) of photo `name`
/// in workspace `out`.
fn object_pixels(out: &Path, name: &str) -> Vec<[u8; 3]> {
    let photo = image::open(out.join("images").join(name))
        .unwrap()
        .to_rgb8();
    let mask = image::open(out.join("truth/masks").join(name))
        .unwrap()
        .to_luma8();
    photo
        .pixels()
        .zip(mask.pixels())
        .filter(|(_, m)| m.0[0] > 0)
        .map(|(px, _)| px.0)
        .collect()
}

/// The object's pixels of photo `name` in workspace `out`: each one's brightest channel,
/// decoded to linear (IEC 61966-2-1).
fn object_peaks(out: &Path, name: &str) -> Vec<f64> {
    object_pixels(out, name)
        .iter()
        .map(|px| {
            let top = *px.iter().max().unwrap() as f64 / 255.0;
            if top <= 0.04045 {
                top / 12.92
            } else {
                ((top + 0.055) / 1.055).powf(2.4)
            }
        })
        .collect()
}

#[test]
fn exposure_peak_sets_the_objects_99th_percentile() {
    // The same render exposed to peak 1 and to peak 0.5: the manifest's exposure halves
    // exactly (one f64 product by 0.5), no object pixel reaches 255 at 0.5, and the 99th
    // percentile of the decoded brightest channel lands at 0.5 (±4%: one 8-bit code near
    // 0.5 is 0.5% of it, and the percentile of a few hundred pixels moves by a tie).
    let (one, half) = (tmp("peak-1"), tmp("peak-half"));
    let mut opts = small(2, 4);
    opts.width = 96;
    opts.height = 96;
    build("spot-diffuse", &one, &opts).unwrap();
    opts.exposure_peak = 0.5;
    build("spot-diffuse", &half, &opts).unwrap();
    let manifest = |out: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("truth/manifest.json")).unwrap())
            .unwrap()
    };
    let (m1, mh) = (manifest(&one), manifest(&half));
    for (p1, ph) in m1["photos"]
        .as_array()
        .unwrap()
        .iter()
        .zip(mh["photos"].as_array().unwrap())
    {
        let (e1, eh) = (
            p1["exposure"].as_f64().unwrap(),
            ph["exposure"].as_f64().unwrap(),
        );
        assert_eq!(eh, 0.5 * e1);
        let name = ph["name"].as_str().unwrap();
        let mut peaks = object_peaks(&half, name);
        assert!(peaks.len() > 200, "{name}: {} object pixels", peaks.len());
        assert!(peaks.iter().all(|&v| v < 1.0), "{name}: a pixel clipped");
        peaks.sort_by(f64::total_cmp);
        let p99 = peaks[(peaks.len() as f64 * 0.99) as usize];
        assert!(
            (0.48..=0.52).contains(&p99),
            "{name}: 99th percentile {p99}"
        );
    }
    std::fs::remove_dir_all(&one).ok();
    std::fs::remove_dir_all(&half).ok();
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(files(&p));
        } else {
            out.push(p);
        }
    }
    out.sort();
    out
}

#[test]
fn same_seed_same_bytes() {
    let (a, b) = (tmp("det-a"), tmp("det-b"));
    build("sphere-glossy", &a, &small(3, 5)).unwrap();
    build("sphere-glossy", &b, &small(3, 5)).unwrap();
    let (fa, fb) = (files(&a), files(&b));
    assert_eq!(fa.len(), fb.len());
    assert!(fa.len() >= 3 + 3 + 1 + 3 * 2 + 3);
    for (x, y) in fa.iter().zip(&fb) {
        assert_eq!(x.strip_prefix(&a).unwrap(), y.strip_prefix(&b).unwrap());
        assert!(
            std::fs::read(x).unwrap() == std::fs::read(y).unwrap(),
            "{} differs",
            x.display()
        );
    }
    // A different seed changes the photos.
    let c = tmp("det-c");
    build("sphere-glossy", &c, &small(3, 6)).unwrap();
    assert!(
        std::fs::read(a.join("images/photo_000.png")).unwrap()
            != std::fs::read(c.join("images/photo_000.png")).unwrap()
    );
    for d in [a, b, c] {
        std::fs::remove_dir_all(&d).ok();
    }
}

#[test]
fn spot_textured_weights_form_a_fine_pattern_on_a_fine_mesh() {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let out = tmp("textured");
    let mut o = small(2, 1);
    o.vertices = None; // the scene's default: fine enough for the pattern
    let s = build("spot-textured", &out, &o).unwrap();
    assert!(s.vertices >= 20_000, "{} vertices", s.vertices);
    // The truth weights, read by ply-rs directly.
    let mut file = std::fs::File::open(out.join("truth/weights.ply")).unwrap();
    let ply = Parser::<DefaultElement>::new().read_ply(&mut file).unwrap();
    let get = |e: &DefaultElement, k: &str| match e[k] {
        Property::Float(v) => v as f64,
        ref p => panic!("{k}: {p:?}"),
    };
    let verts = &ply.payload["vertex"];
    let w: Vec<f64> = verts.iter().map(|e| get(e, "w1")).collect();
    for (e, w1) in verts.iter().zip(&w) {
        // A blend of the two materials: non-negative, summing to one (f32 storage).
        let w0 = get(e, "w0");
        assert!(w0 >= 0.0 && *w1 >= 0.0 && (w0 + w1 - 1.0).abs() < 1e-6);
    }
    // Both materials cover a real share of the surface...
    let dark = w.iter().filter(|&&x| x > 0.5).count();
    assert!(
        dark * 5 > w.len() && (w.len() - dark) * 5 > w.len(),
        "{dark} of {}",
        w.len()
    );
    // ...in many small patches, not one split (as in spot-varying): the dominant material
    // changes across more than 2% of the face edges (a single boundary on this mesh would
    // cross well under 1%: of the order of sqrt(faces) ~ 220 of the 144K face edges).
    let faces: Vec<[usize; 3]> = ply.payload["face"]
        .iter()
        .map(|f| match &f["vertex_indices"] {
            Property::ListInt(v) => [v[0] as usize, v[1] as usize, v[2] as usize],
            Property::ListUInt(v) => [v[0] as usize, v[1] as usize, v[2] as usize],
            p => panic!("{p:?}"),
        })
        .collect();
    let (mut cut, mut edges) = (0, 0);
    for f in &faces {
        for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            edges += 1;
            cut += ((w[a] > 0.5) != (w[b] > 0.5)) as usize;
        }
    }
    eprintln!("{cut} of {edges} face edges cross a material boundary");
    assert!(
        cut * 50 > edges,
        "{cut} of {edges} edges cross a material boundary"
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn exact_vertex_counts_reach_the_mesh_written_and_are_refused_where_they_cannot_hold() {
    // A spot scene with `exact_vertices` writes a mesh of exactly that many vertices (read
    // back from dense/ by the project's PLY reader, after its own cleaning: a partial
    // refinement that left a T-junction or an unused vertex would show up as a different
    // count or a welded vertex); a count below the spot mesh's own, or a scene built from
    // parts, is a clear error naming the cause.
    let out = tmp("exact");
    let opts = SynthOptions {
        vertices: Some(3_333),
        exact_vertices: true,
        ..small(2, 5)
    };
    let s = build("spot-static", &out, &opts).unwrap();
    assert_eq!(s.vertices, 3_333);
    let (mesh, _) = Mesh::read_ply(&out.join("dense/meshed-poisson.ply")).unwrap();
    assert_eq!(mesh.positions.len(), 3_333);
    let _ = std::fs::remove_dir_all(&out);

    let low = SynthOptions {
        vertices: Some(100),
        ..opts.clone()
    };
    let e = build("spot-static", &tmp("exact-low"), &low)
        .unwrap_err()
        .to_string();
    assert!(e.contains("below the spot mesh"), "{e}");
    let e = build("sphere-plane", &tmp("exact-parts"), &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("spot scene"), "{e}");
}
