use super::*;

fn tmp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("relight-envmap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn latlong_layout_and_solid_angles() {
    let ll = LatLong::black(16);
    // Top row looks up, φ grows from e_x toward e_y.
    assert!(ll.dir(0, 0).z > 0.99);
    assert!(ll.dir(0, 15).z < -0.99);
    let d = ll.dir(8, 8); // φ ≈ π/2 + half a pixel, θ ≈ π/2 + half a pixel
    assert!(d.y > 0.99);
    // Pixel solid angles sum to 4π (exact formula: rounding only).
    let total: f64 = (0..16).map(|v| ll.solid_angle(v) * 32.0).sum();
    assert!((total - 4.0 * PI).abs() < 1e-12);
    for v in 0..16 {
        for u in 0..32 {
            assert_eq!(ll.pixel_of(&ll.dir(u, v)), (u, v));
        }
    }
}

#[test]
fn exr_round_trip_is_lossless_in_f32() {
    let mut ll = LatLong::black(8);
    for (i, p) in ll.rgb.iter_mut().enumerate() {
        *p = [i as f32 * 0.5, 1e4, -0.25];
    }
    let path = tmp("rt.exr");
    ll.write_exr(&path).unwrap();
    let (back, stats) = LatLong::read_exr(&path).unwrap();
    assert_eq!(stats.negative_clamped, ll.rgb.len());
    for (a, b) in ll.rgb.iter().zip(&back.rgb) {
        assert_eq!([a[0], a[1], 0.0], *b);
    }
    let oct = OctEnv::from_latlong(&back, 8);
    let p2 = tmp("oct.exr");
    oct.write_exr(&p2).unwrap();
    assert_eq!(OctEnv::read_exr(&p2).unwrap(), oct);
    // A lat-long file is not an octahedral map.
    assert!(matches!(OctEnv::read_exr(&path), Err(Error::Image { .. })));
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
}

/// Every sub-pixel's direction by `dir_at` (two `sincos` per sample), as
/// [`OctEnv::from_latlong`] computed it before its trigonometric tables.
fn from_latlong_per_sample(ll: &LatLong, n: usize, s: usize) -> Vec<[f64; 3]> {
    let grid = SphereGrid::full(n);
    let mut energy = vec![[0.0f64; 3]; n * n];
    let sf = s as f64;
    for v in 0..ll.height {
        for b in 0..s {
            let y0 = v as f64 + b as f64 / sf;
            let y1 = y0 + 1.0 / sf;
            let sub_sa = 2.0 * PI / (ll.width as f64 * sf)
                * (ll.theta_edge(y0).cos() - ll.theta_edge(y1).cos());
            let yc = 0.5 * (y0 + y1);
            for u in 0..ll.width {
                let p = ll.rgb[v * ll.width + u];
                for a in 0..s {
                    let x = u as f64 + (a as f64 + 0.5) / sf;
                    let t = grid.texel_of(&ll.dir_at(x, yc));
                    for c in 0..3 {
                        energy[t][c] += p[c] as f64 * sub_sa;
                    }
                }
            }
        }
    }
    energy
}

#[test]
fn from_latlong_tables_give_the_per_sample_directions_bit_for_bit() {
    // 16 × 8 pixels onto 16²: s = ⌈√(1024 · 256 / 128)⌉ = 46 sub-pixels per side.
    let mut ll = LatLong::black(8);
    for (i, p) in ll.rgb.iter_mut().enumerate() {
        *p = [
            1.0 + i as f32,
            (i % 7) as f32 * 0.3,
            if i % 5 == 0 { 0.0 } else { 2.0 },
        ];
    }
    let oct = OctEnv::from_latlong(&ll, 16);
    let energy = from_latlong_per_sample(&ll, 16, 46);
    let omega = SphereGrid::full(16).solid_angles();
    for ((t, e), o) in oct.rgb.iter().zip(&energy).zip(&omega) {
        assert_eq!(*t, [0, 1, 2].map(|c| (e[c] / o) as f32));
    }
}

#[test]
fn from_latlong_conserves_energy_and_constants() {
    // Constant sky plus a one-pixel sun 10⁴ brighter.
    let mut ll = LatLong::black(64);
    for p in ll.rgb.iter_mut() {
        *p = [1.0, 2.0, 0.5];
    }
    let sun = 20 * ll.width + 37;
    ll.rgb[sun] = [1e4, 1e4, 1e4];
    let oct = OctEnv::from_latlong(&ll, 16);
    let (a, b) = (ll.integral(), oct.integral());
    for c in 0..3 {
        // Energy is conserved by construction: f64 sums of 8192·s² terms rounded to
        // f32 texels at the end, so 1e-6 relative.
        assert!(
            (a[c] - b[c]).abs() < 1e-6 * a[c],
            "channel {c}: {} vs {}",
            a[c],
            b[c]
        );
    }
    // The sun lands in the texel containing its direction (and its neighbours only
    // through sub-pixels straddling a texel border).
    let t = SphereGrid::full(16).texel_of(&ll.dir(37, 20));
    assert!(oct.rgb[t][0] > 10.0);
    // A constant map stays constant up to the sub-pixel sampling error: ≥ 1024 samples
    // per texel on a regular grid miss at most ~a row of ~32 along the border: 5%.
    let mut flat = LatLong::black(64);
    for p in flat.rgb.iter_mut() {
        *p = [1.0; 3];
    }
    let oct = OctEnv::from_latlong(&flat, 16);
    let worst = oct
        .rgb
        .iter()
        .map(|p| (p[0] - 1.0).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 0.05, "worst texel deviation {worst}");
}

#[test]
fn to_latlong_reproduces_smooth_maps() {
    // L = 1 + z + 0.5 x: linear in the direction, so texel averages and bilinear
    // interpolation are both second-order accurate: 2% at 64² octahedral texels.
    let f = |d: &Vec3| 1.0 + d.z + 0.5 * d.x;
    let grid = SphereGrid::full(64);
    let rgb: Vec<[f32; 3]> = (0..grid.len())
        .map(|t| {
            let v = f(&grid.texel_dir(t)) as f32;
            [v, v, v]
        })
        .collect();
    let oct = OctEnv { n: 64, rgb };
    let ll = oct.to_latlong(32);
    for v in 0..32 {
        for u in 0..64 {
            let want = f(&ll.dir(u, v));
            let got = ll.rgb[v * 64 + u][0] as f64;
            assert!((want - got).abs() < 0.02, "({u},{v}) {want} {got}");
        }
    }
}

#[test]
fn rotated_about_up_moves_azimuth() {
    let mut ll = LatLong::black(8);
    ll.rgb[3 * 16 + 2] = [1.0; 3];
    let r = ll.rotated_about_up(2.0 * PI * 3.0 / 16.0);
    assert_eq!(r.rgb[3 * 16 + 5], [1.0; 3]);
    let half = ll.rotated_about_up(2.0 * PI * 0.5 / 16.0);
    assert!((half.rgb[3 * 16 + 2][0] - 0.5).abs() < 1e-6);
    assert!((half.rgb[3 * 16 + 3][0] - 0.5).abs() < 1e-6);
}

#[test]
fn real_maps_read_or_fail_clearly() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hdri");
    let (ll, stats) = LatLong::read_exr(&root.join("city_64x32.exr")).unwrap();
    assert_eq!((ll.width, ll.height), (64, 32));
    assert_eq!(stats.non_finite, 0);
    // The sun survives the downsampling: peak ≫ mean (the full map is ~30,000×).
    let mean = ll.integral()[0] / (4.0 * PI);
    let peak = ll.rgb.iter().map(|p| p[0]).fold(0.0f32, f32::max) as f64;
    assert!(peak > 100.0 * mean, "peak {peak} mean {mean}");
    // The DWAB file as shipped: decoded, lossy undershoot clamped and counted.
    let (ll, stats) = LatLong::read_exr(&root.join("studio_dwab.exr")).unwrap();
    assert_eq!((ll.width, ll.height), (1024, 512));
    assert!(stats.negative_clamped > 0);
    assert!(ll
        .rgb
        .iter()
        .all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0)));
    // A missing file names itself.
    let err = LatLong::read_exr(&root.join("missing.exr")).unwrap_err();
    assert!(err.to_string().contains("missing.exr"));
}
