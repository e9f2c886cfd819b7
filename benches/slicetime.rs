//! CPU time per on-demand BRDF slice of the 32² local map for each lobe of the Minerva
//! model (20,000 random outgoing directions above 0.1 of the horizon; CPU seconds, which a
//! shared machine's load changes far less than wall time), with a checksum of every slice
//! value so that two builds can be shown to compute the same slices:
//! `cargo bench --bench slicetime` writes `bench-results/slicetime.md`.

use rand::SeedableRng;
use rand_pcg::Pcg64;
use relight_cpc::stages::Stopwatch;
use relight_cpc::transport::brdf::{parse_list, SliceGrid};
use relight_cpc::Vec3;
use std::fmt::Write;

#[path = "../tests/support/random.rs"]
mod random;
use random::random_unit;
#[path = "support/today.rs"]
mod today;
use today::today;

fn main() {
    let grid = SliceGrid::new(32).expect("grid");
    let mut rng = Pcg64::seed_from_u64(1);
    let wos: Vec<Vec3> = (0..20_000)
        .map(|_| loop {
            let d = random_unit(&mut rng);
            if d.z > 0.1 {
                break d;
            }
        })
        .collect();
    let basis =
        parse_list("lambert,ggx:0.1,ggx:0.2,ggx:0.35,ggx:0.6,phong:50,phong:500").expect("basis");
    let mut out = vec![0.0; 1024];
    let mut check = 0.0;
    let date = today();
    let mut md = format!("# On-demand slices, 32² local map\n\nMeasured {date} with `cargo bench --bench slicetime`; 20,000 outgoing directions per lobe, CPU µs per slice (user + system, 1/100 s ticks).\n\n| lobe | µs / slice |\n|---|---:|\n");
    for b in basis {
        let watch = Stopwatch::start();
        for wo in &wos {
            b.slice_with(&grid, wo, &mut out);
            check += out.iter().sum::<f64>();
        }
        let us = watch.elapsed().1 * 1e6 / wos.len() as f64;
        println!("{:10} {us:.2} us/slice", b.label());
        let _ = writeln!(md, "| {} | {us:.2} |", b.label());
    }
    println!("checksum {check:.17e}");
    let _ = writeln!(md, "\nChecksum of every slice value: `{check:.17e}`.");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("bench-results/slicetime.md");
    if let Err(e) = std::fs::write(&path, md) {
        eprintln!("{}: {e}", path.display());
    }
}
