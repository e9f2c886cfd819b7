//! Regenerates the committed test map `tests/fixtures/hdri/city_64x32.exr` from the real
//! map in `../shared/data/hdri/` (run with `cargo test --test suite -- --ignored core_fixture::`),
//! and checks the committed map against its source when the source is present.

use relight_cpc::sphere::envmap::LatLong;
use std::path::{Path, PathBuf};

fn source() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/hdri/city.exr")
}

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hdri/city_64x32.exr")
}

#[test]
#[ignore = "writes the fixture; needs ../shared/data/hdri"]
fn write_city_fixture() {
    let (ll, _) = LatLong::read_exr(&source()).unwrap();
    let small = ll.downsample(ll.height / 32).unwrap();
    small.write_exr(&fixture()).unwrap();
}

#[test]
fn fixture_keeps_the_source_energy() {
    let (small, _) = LatLong::read_exr(&fixture()).unwrap();
    let src = source();
    if !src.exists() {
        return; // Outside the project tree only the committed map is available.
    }
    let (ll, _) = LatLong::read_exr(&src).unwrap();
    // Area-weighted box filtering conserves the integral: f64 sums, f32 storage: 1e-5.
    let (a, b) = (ll.integral(), small.integral());
    for c in 0..3 {
        assert!(
            (a[c] - b[c]).abs() < 1e-5 * a[c],
            "channel {c}: {} vs {}",
            a[c],
            b[c]
        );
    }
}

#[test]
fn dwab_reads_like_zip_or_fails_clearly() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/hdri");
    let (dwab, zip) = (dir.join("dwab/city.exr"), dir.join("city.exr"));
    if !dwab.exists() || !zip.exists() {
        return;
    }
    match LatLong::read_exr(&dwab) {
        Ok((lossy, stats)) => {
            let (exact, _) = LatLong::read_exr(&zip).unwrap();
            // DWAB is lossy (and the ZIP copy is half float): the integrals agree to 1%.
            let (a, b) = (exact.integral(), lossy.integral());
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() < 1e-2 * a[c],
                    "channel {c}: {} vs {}",
                    a[c],
                    b[c]
                );
            }
            eprintln!("dwab read: {stats:?}");
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains("city.exr") && msg.to_lowercase().contains("dwab"),
                "{msg}"
            );
        }
    }
}
