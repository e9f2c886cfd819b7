//! The embedded synth data: downsampling preserves a map's integral, and (ignored by
//! default) the regeneration of `tests/fixtures/synth/` from `/work/shared/data`:
//! `cargo test --release --test suite -- --ignored synth_data::regenerate_fixtures`.

use relight_cpc::sphere::envmap::LatLong;
use relight_cpc::synth::data::write_half_exr;
use std::path::Path;

#[test]
fn downsampling_preserves_the_integral_and_a_constant() {
    // ∫L dω is a sum of texel × solid angle; the block average weighted by solid angle
    // keeps it exactly (f32 storage: 1e-6 relative). A constant map stays constant.
    let h = 16;
    let mut rgb = vec![[0.0f32; 3]; 2 * h * h];
    let mut s = 12345u64;
    for p in rgb.iter_mut() {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let x = (s >> 33) as f32 / (1u64 << 31) as f32;
        *p = [x, 2.0 * x, x * x * 100.0];
    }
    let map = LatLong {
        width: 2 * h,
        height: h,
        rgb,
    };
    let small = map.downsample(4).unwrap();
    assert_eq!((small.width, small.height), (8, 4));
    let (a, b) = (map.integral(), small.integral());
    for c in 0..3 {
        assert!((a[c] - b[c]).abs() <= 1e-6 * a[c], "{a:?} vs {b:?}");
    }
    let flat = LatLong {
        width: 2 * h,
        height: h,
        rgb: vec![[0.25; 3]; 2 * h * h],
    };
    assert!(flat
        .downsample(2)
        .unwrap()
        .rgb
        .iter()
        .all(|p| p.iter().all(|&x| (x - 0.25).abs() < 1e-6)));
    assert!(map.downsample(3).is_err());
}

#[test]
fn half_exr_round_trip() {
    // Half floats keep 11 significant bits: relative error ≤ 2^-11.
    let dir = std::env::temp_dir().join(format!("relight-synth-data-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("m.exr");
    let map = LatLong {
        width: 8,
        height: 4,
        rgb: (0..32).map(|i| [i as f32, 0.5, 30000.0]).collect(),
    };
    write_half_exr(&map, &path).unwrap();
    let (back, _) = LatLong::read_exr_bytes(&std::fs::read(&path).unwrap(), "m.exr").unwrap();
    assert_eq!((back.width, back.height), (8, 4));
    for (a, b) in map.rgb.iter().zip(&back.rgb) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() <= a[c].abs() / 2048.0);
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
#[ignore]
fn regenerate_fixtures() {
    let src = Path::new("/work/shared/data");
    let dst = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/synth");
    std::fs::create_dir_all(dst.join("hdri")).unwrap();
    for name in relight_cpc::synth::data::MAP_NAMES {
        let (map, _) = LatLong::read_exr(&src.join(format!("hdri/{name}.exr"))).unwrap();
        let small = map.downsample(map.height / 128).unwrap();
        write_half_exr(&small, &dst.join(format!("hdri/{name}.exr"))).unwrap();
    }
    std::fs::copy(src.join("meshes/spot.ply"), dst.join("spot.ply")).unwrap();
}
