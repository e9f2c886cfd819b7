//! What a user opens after `run` on the built-in example: report.html in a real headless
//! browser (Debian's chromium, through scripts/check_report_html.sh), the glTF export
//! through the Khronos validator (npm gltf-validator, scripts/validate_gltf.sh), and
//! `render` under a Radiance .hdr map turned by 90°. The external checks run when their
//! tools are present, and are required when CI=true (.ci/run installs them).

use relight_cpc::export::{export_result, ExportOptions};
use relight_cpc::render::relight::{render_result, CameraSelection, RenderOptions};
use relight_cpc::run::{builtin_example, run, MaterialCount, RunOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

fn tool_present(name: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {name}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Whether an external check must run: its tool is present, or CI says it must be.
fn must_run(tools: &[&str], what: &str) -> bool {
    let present = tools.iter().all(|t| tool_present(t));
    if !present {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI=true but {tools:?} missing: .ci/run must install them for the {what} check"
        );
        eprintln!("{what}: {tools:?} not installed, check skipped");
    }
    present
}

fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scripts")
        .join(name)
}

#[test]
fn report_html_export_and_render_of_the_example() {
    let t = crate::scratch::scratch("result_use", "example");
    let dir = t.0.clone();
    let out = dir.join("spot");
    let mut o = RunOptions::new(builtin_example().unwrap(), out.clone());
    // Small settings: this test is about the files, not the fit's quality.
    o.global_resolution = 16;
    o.keep = 32;
    o.max_iterations = 2;
    o.materials = MaterialCount::Fixed(2);
    o.progress = false;
    run(&o).expect("run on the built-in example");

    // report.html: at least 6 images, each a file of the result folder that decodes.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let srcs = relight_cpc::report::html::image_sources(&html);
    assert!(srcs.len() >= 6, "{} images: {srcs:?}", srcs.len());
    for s in &srcs {
        let p = out.join(s.replace("%20", " "));
        let img = image::open(&p).unwrap_or_else(|e| panic!("{s}: {e}"));
        assert!(img.width() > 0 && img.height() > 0, "{s}");
    }
    assert!(html.contains("Held-out photos") && html.contains("colour scale"));
    // Truth against recovered (synthetic workspace): every training photo's recovered map
    // beside its true map, and the albedo table, whose figures an independent computation
    // from the truth files and the result's own files must reproduce.
    let recovered = srcs.iter().filter(|s| s.ends_with(".map.png")).count();
    let true_maps = srcs.iter().filter(|s| s.ends_with(".true_map.png")).count();
    assert!(recovered >= 2 && true_maps == recovered, "{srcs:?}");
    assert!(html.contains("id=\"albedo-truth\"") && html.contains("scale anchor"));
    check_albedo_truth(&out);
    check_truth_check_table(&out, &html);
    if must_run(&["chromium"], "report.html in headless chromium") {
        let o = Command::new("bash")
            .arg(script("check_report_html.sh"))
            .arg(&out)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout);
        eprintln!("{text}{}", String::from_utf8_lossy(&o.stderr));
        assert!(
            o.status.success(),
            "chromium: not every image loaded: {text}"
        );
        assert!(
            text.contains(&format!("images: {0}/{0}", srcs.len())),
            "{text}"
        );
    }

    // export --gltf: every mesh vertex, colours and materials; the validator accepts it.
    let glb = dir.join("spot.glb");
    let s = export_result(
        &out,
        &ExportOptions {
            gltf: Some(glb.clone()),
            envmaps: Some(dir.join("blender")),
            force: false,
        },
    )
    .unwrap();
    let (mesh, _) = relight_cpc::import::mesh::Mesh::read_ply(&out.join("mesh.ply")).unwrap();
    let g = &s.gltf.as_ref().unwrap().1;
    assert!(g.vertices >= mesh.positions.len() && g.triangles == mesh.faces.len());
    let bytes = std::fs::read(&glb).unwrap();
    let parsed = gltf::Gltf::from_slice(&bytes).expect("the gltf crate reads it back");
    let prim = parsed.meshes().next().unwrap().primitives().next().unwrap();
    assert!(prim.get(&gltf::Semantic::Colors(0)).is_some());
    assert!(prim.material().index().is_some());
    assert_eq!(s.envmaps.len(), 2 * 6, "{:?}", s.envmaps);
    // The .glb sits beside its result: a second export is refused without --force and
    // replaces the first with it; a file of that name the tool did not write never is.
    let gltf_only = |path: &Path, force| ExportOptions {
        gltf: Some(path.to_path_buf()),
        envmaps: None,
        force,
    };
    let e = export_result(&out, &gltf_only(&glb, false)).unwrap_err();
    assert!(e.to_string().contains("--force"), "{e}");
    export_result(&out, &gltf_only(&glb, true)).unwrap();
    assert_eq!(std::fs::read(&glb).unwrap(), bytes, "the same export again");
    let mine = dir.join("mine.glb");
    std::fs::write(&mine, "not a GLB").unwrap();
    let e = export_result(&out, &gltf_only(&mine, true)).unwrap_err();
    assert!(e.to_string().contains("not a relight-cpc result"), "{e}");
    assert_eq!(std::fs::read(&mine).unwrap(), b"not a GLB");
    if must_run(&["node", "npm"], "Khronos glTF validator") {
        let o = Command::new("bash")
            .arg(script("validate_gltf.sh"))
            .arg(&glb)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout);
        eprintln!("{text}{}", String::from_utf8_lossy(&o.stderr));
        assert!(o.status.success(), "validator: {text}");
        assert!(text.contains("0 errors, 0 warnings"), "{text}");
    }

    // render --env MAP.hdr --rotate 90: files named after the map (and the camera).
    let hdr = s
        .envmaps
        .iter()
        .find(|p| p.extension().is_some_and(|e| e == "hdr"))
        .unwrap();
    let map = dir.join("studio.hdr");
    std::fs::copy(hdr, &map).unwrap();
    let r = render_result(
        &out,
        &RenderOptions {
            env: Some(map),
            cameras: CameraSelection::AllRegistered,
            out: dir.join("renders"),
            resolution: Some(48),
            rotate_deg: 90.0,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(r.views.len() >= 2);
    let mut names: Vec<String> = r
        .views
        .iter()
        .map(|v| v.png.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    for n in &names {
        assert!(n.starts_with("studio_rot90__"), "{n}");
    }
    names.sort();
    names.dedup();
    assert_eq!(names.len(), r.views.len(), "two views share a file name");
}

/// `name`'s float properties `props` of every vertex of a PLY file, read by ply-rs.
fn ply_columns(path: &Path, props: &[String]) -> Vec<Vec<f64>> {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    let mut f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let ply = Parser::<DefaultElement>::new().read_ply(&mut f).unwrap();
    props
        .iter()
        .map(|p| {
            ply.payload["vertex"]
                .iter()
                .map(|v| match &v[p] {
                    Property::Float(x) => *x as f64,
                    Property::Double(x) => *x,
                    other => panic!("{p}: {other:?}"),
                })
                .collect()
        })
        .collect()
}

/// `report.json`'s `albedo_truth` recomputed from files alone: the truth's
/// `materials.json` and `weights.ply`, the result's `materials.json` (λ) and `mesh.ply`
/// (per-vertex diffuse albedo `albedo_*` and weights `w*`).
/// The HTML's truth-check table against `report.json`: every checked photo's row with its
/// three relative errors (the fit under the true and the fitted light, the true reflectance
/// under the true light), and their means recomputed here (to the 0.1% the page prints).
fn check_truth_check_table(out: &Path, html: &str) {
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let rows = json["truth_check"].as_array().unwrap();
    assert!(!rows.is_empty());
    assert!(html.contains("id=\"truth-check\""));
    assert!(
        html.contains("true reflectance, true light"),
        "the floor's column: the example's truth is in lobes the renderer knows"
    );
    let pct = |v: f64| format!("{:.1}%", 100.0 * v);
    let (mut t, mut f, mut g) = (0.0, 0.0, 0.0);
    for r in rows {
        let (rt, rf, rg) = (
            r["relative_true_light"].as_f64().unwrap(),
            r["relative_fitted_light"].as_f64().unwrap(),
            r["relative_true_reflectance"].as_f64().unwrap(),
        );
        let row = format!(
            "<td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td>",
            r["image"].as_str().unwrap(),
            pct(rt),
            pct(rf),
            pct(rg)
        );
        assert!(html.contains(&row), "{row}");
        t += rt / rows.len() as f64;
        f += rf / rows.len() as f64;
        g += rg / rows.len() as f64;
    }
    let mean = format!(
        "<td><b>{}</b></td><td><b>{}</b></td><td><b>{}</b></td>",
        pct(t),
        pct(f),
        pct(g)
    );
    assert!(html.contains(&mean), "{mean}");
}

fn check_albedo_truth(out: &Path) {
    let read = |p: PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let truth_dir = builtin_example().unwrap().join("truth");
    let tm = read(truth_dir.join("materials.json"));
    let lt = tm["lobes"]
        .as_array()
        .unwrap()
        .iter()
        .position(|l| l["type"] == "lambert")
        .unwrap();
    let tmat = tm["materials"].as_array().unwrap();
    let tdiff: Vec<[f64; 3]> = tmat
        .iter()
        .map(|m| [0, 1, 2].map(|c| m["lambda"][lt][c].as_f64().unwrap()))
        .collect();
    let jj = tdiff.len();
    let tw = ply_columns(
        &truth_dir.join("weights.ply"),
        &(0..jj).map(|j| format!("w{j}")).collect::<Vec<_>>(),
    );
    let fm = read(out.join("materials.json"));
    let lb = fm["basis"]
        .as_array()
        .unwrap()
        .iter()
        .position(|b| b["label"] == "lambert")
        .unwrap();
    let lambda = fm["lambda"].as_array().unwrap();
    let kk = lambda.len();
    let mut props: Vec<String> = ["albedo_r", "albedo_g", "albedo_b"]
        .map(String::from)
        .to_vec();
    props.extend((0..kk).map(|k| format!("w{k}")));
    let cols = ply_columns(&out.join("mesh.ply"), &props);
    let nv = cols[0].len();
    assert_eq!(tw[0].len(), nv, "the run's mesh is the truth's");
    let argmax = |w: &[f64]| {
        let (i, m) = w
            .iter()
            .enumerate()
            .fold((0, f64::MIN), |a, (i, &v)| if v > a.1 { (i, v) } else { a });
        (m > 0.0).then_some(i)
    };
    let dom_fit: Vec<Option<usize>> = (0..nv)
        .map(|x| argmax(&(0..kk).map(|k| cols[3 + k][x]).collect::<Vec<_>>()))
        .collect();
    let dom_true: Vec<Option<usize>> = (0..nv)
        .map(|x| argmax(&(0..jj).map(|j| tw[j][x]).collect::<Vec<_>>()))
        .collect();
    let (mut num, mut den) = ([0.0; 3], [0.0; 3]);
    for x in 0..nv {
        if dom_fit[x].is_none() || dom_true[x].is_none() {
            continue;
        }
        for c in 0..3 {
            let b: f64 = (0..jj).map(|j| tw[j][x] * tdiff[j][c]).sum();
            num[c] += b * cols[c][x];
            den[c] += cols[c][x] * cols[c][x];
        }
    }
    let scale: Vec<f64> = (0..3).map(|c| num[c] / den[c]).collect();
    let report = read(out.join("report.json"));
    let a = &report["albedo_truth"];
    // mesh.ply stores the albedo and weights as f32 (relative rounding 6e-8 per value):
    // sums over the mesh agree with the run's f64 figures to far better than 1e-5.
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-5 * y.abs().max(1e-3);
    for c in 0..3 {
        let s = a["scale"][c].as_f64().unwrap();
        assert!(
            close(s, scale[c]),
            "scale {c}: report {s}, recomputed {}",
            scale[c]
        );
    }
    let entries = a["materials"].as_array().unwrap();
    assert_eq!(entries.len(), kk);
    let mut medians: Vec<[f64; 3]> = Vec::new();
    for e in entries {
        let k = e["material"].as_u64().unwrap() as usize;
        let mut votes = vec![0usize; jj];
        for x in 0..nv {
            if let (Some(f), Some(t)) = (dom_fit[x], dom_true[x]) {
                if f == k {
                    votes[t] += 1;
                }
            }
        }
        let j = (0..jj).max_by_key(|&j| votes[j]).unwrap();
        assert_eq!(e["true_material"], tmat[j]["name"], "material {k}");
        for c in 0..3 {
            let l = lambda[k][lb][c].as_f64().unwrap();
            let err = scale[c] * l / tdiff[j][c] - 1.0;
            let rep = e["ratio_error"][c].as_f64().unwrap();
            assert!(
                (rep - err).abs() < 1e-5,
                "material {k} channel {c}: report {rep}, recomputed {err}"
            );
        }
        // The pure-vertex error: the mean scaled per-vertex albedo from mesh.ply over the
        // vertices this material dominates whose true weight of `j` is at least 0.95.
        let pure: Vec<usize> = (0..nv)
            .filter(|&x| dom_fit[x] == Some(k) && tw[j][x] >= 0.95)
            .collect();
        assert_eq!(e["pure_vertices"].as_u64().unwrap() as usize, pure.len());
        assert!(
            !pure.is_empty(),
            "the example's materials have pure vertices"
        );
        for c in 0..3 {
            let mean = pure.iter().map(|&x| scale[c] * cols[c][x]).sum::<f64>() / pure.len() as f64;
            let err = mean / tdiff[j][c] - 1.0;
            let rep = e["pure_ratio_error"][c].as_f64().unwrap();
            assert!(
                (rep - err).abs() < 1e-5,
                "material {k} channel {c}: pure-vertex error {rep}, recomputed {err}"
            );
        }
        // The median over the same vertices (the element at n / 2 in ascending order) and
        // the share of them off the truth by more than 10% in some channel.
        let scaled = |x: usize| [0, 1, 2].map(|c| scale[c] * cols[c][x] / tdiff[j][c] - 1.0);
        let mut median = [0.0; 3];
        for (c, m) in median.iter_mut().enumerate() {
            let mut v: Vec<f64> = pure.iter().map(|&x| scaled(x)[c]).collect();
            v.sort_by(f64::total_cmp);
            *m = v[v.len() / 2];
            let rep = e["pure_median_error"][c].as_f64().unwrap();
            assert!(
                (rep - *m).abs() < 1e-5,
                "material {k} channel {c}: median error {rep}, recomputed {m}"
            );
        }
        medians.push(median);
        let off = pure
            .iter()
            .filter(|&&x| scaled(x).iter().any(|e| e.abs() > 0.1))
            .count() as f64
            / pure.len() as f64;
        let rep = e["pure_off_share"].as_f64().unwrap();
        // A vertex within f32 rounding of the 10% line could count on one side only.
        assert!(
            (rep - off).abs() <= 1.5 / pure.len() as f64,
            "{rep} against {off}"
        );
    }
    // The materials' ratios: every ordered pair, every channel, the medians' ratio.
    let mut worst: f64 = 0.0;
    for (a, ma) in medians.iter().enumerate() {
        for (_, mb) in medians.iter().enumerate().filter(|&(b, _)| b != a) {
            for c in 0..3 {
                worst = worst.max(((1.0 + ma[c]) / (1.0 + mb[c]) - 1.0).abs());
            }
        }
    }
    let rep = a["max_median_ratio_error"].as_f64().unwrap();
    assert!((rep - worst).abs() < 1e-5, "{rep} against {worst}");
}
