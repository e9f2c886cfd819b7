//! Cost and noise of the reference renderer (a benchmark, not a test: ignored by default).
//! `cargo test --release --test suite -- --ignored --nocapture reference_cost::`
//! Renders Spot (2,930 vertices) at 256×256 under the sunny city map (the stiff case) at
//! several sample counts, twice with different seeds; the per-pixel noise is estimated from
//! the difference of the two renders (σ_pixel = std(a − b)/√2) and reported relative to the
//! mean object radiance. Figures go to `target/reference_cost.json`.

use relight_cpc::import::mesh::Mesh;
use relight_cpc::observe::trace::SceneBvh;
use relight_cpc::sphere::env_frame;
use relight_cpc::sphere::envmap::LatLong;
use relight_cpc::synth::look_at;
use relight_cpc::transport::reference::{Environment, Lobe, ReferenceScene, Reflectance, Samples};
use relight_cpc::Vec3;
use std::path::Path;

#[test]
#[ignore]
fn reference_cost() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (mesh, _) = Mesh::read_ply(&root.join("tests/fixtures/synth/spot.ply")).unwrap();
    let bvh = SceneBvh::new(&mesh);
    let (map, _) = LatLong::read_exr_bytes(
        &std::fs::read(root.join("tests/fixtures/synth/hdri/city.exr")).unwrap(),
        "city",
    )
    .unwrap();
    let env = Environment::new(
        map.width,
        map.height,
        &map.rgb,
        env_frame(&Vec3::y()).unwrap(),
    )
    .unwrap();
    let refl = Reflectance {
        lobes: vec![Lobe::Lambert, Lobe::Phong { exponent: 50.0 }],
        lambda: vec![vec![[0.6, 0.4, 0.3], [0.3, 0.3, 0.3]]],
        weights: vec![1.0; mesh.positions.len()],
    };
    let scene = ReferenceScene {
        positions: &mesh.positions,
        normals: &mesh.normals,
        faces: &mesh.faces,
        reflectance: &refl,
        env: &env,
        caster: &bvh,
        offset: bvh.ray_offset(),
    };
    let (lo, hi) = mesh.bounding_box();
    let c = (lo + hi) * 0.5;
    let eye = c + Vec3::new(0.8, 0.5, 1.6).normalize() * (hi - lo).norm() * 1.3;
    let cam = look_at(&eye, &c, &Vec3::y(), 256, 256, 40.0);
    let mut rows = Vec::new();
    for (spp, light) in [(1, 16), (4, 16), (4, 64), (16, 64)] {
        let t0 = std::time::Instant::now();
        let a = scene.render(
            &cam,
            &Samples {
                per_pixel: spp,
                light,
                seed: 1,
            },
        );
        let secs = t0.elapsed().as_secs_f64();
        let b = scene.render(
            &cam,
            &Samples {
                per_pixel: spp,
                light,
                seed: 2,
            },
        );
        let (mut n, mut mean, mut var) = (0usize, 0.0, 0.0);
        for i in 0..a.rgb.len() {
            if a.coverage[i] == 1.0 && b.coverage[i] == 1.0 {
                let (x, y) = (a.rgb[i][1] as f64, b.rgb[i][1] as f64);
                n += 1;
                mean += (x + y) / 2.0;
                var += (x - y).powi(2) / 2.0;
            }
        }
        let rel = (var / n as f64).sqrt() / (mean / n as f64);
        println!("spp {spp:2} light {light:3}: {secs:6.2} s, {n} object pixels, relative noise per pixel {rel:.4}");
        rows.push(
            serde_json::json!({"per_pixel": spp, "light_pairs": light, "seconds": secs,
            "object_pixels": n, "relative_noise_per_pixel": rel}),
        );
    }
    let out = root.join("target/reference_cost.json");
    std::fs::write(
        &out,
        serde_json::to_string_pretty(&serde_json::json!({
        "mesh": "spot (2930 vertices)", "image": [256, 256], "map": "city 256x128",
        "threads": rayon::current_num_threads(), "runs": rows}))
        .unwrap(),
    )
    .unwrap();
}
