//! Regenerates `src/solve/light/light_prior.json`, the statistics of the light prior
//! ([`relight_cpc::solve::light::sh_prior`]): the eight CC0 maps that `relight-cpc synth` embeds
//! (`tests/fixtures/synth/hdri/`, source and licence in `tests/fixtures/synth/SOURCE.md`),
//! each turned about the up axis 24 times.
//!
//! `cargo run --release --example light_prior_stats [OUT.json]`

use relight_cpc::solve::light::sh_prior::{map_sample, LightPrior, HAAR_SIDES};
use relight_cpc::sphere::envmap::LatLong;
use std::path::Path;

use relight_cpc::synth::data::MAP_NAMES as MAPS;
const ROTATIONS: usize = 24;
const SHRINKAGE: f64 = 0.1;

fn main() {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "src/solve/light/light_prior.json".into());
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/synth/hdri");
    let mut samples = Vec::new();
    for name in MAPS {
        let path = dir.join(format!("{name}.exr"));
        let (ll, _) = match LatLong::read_exr(&path) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(1);
            }
        };
        samples.push(map_sample(&ll, ROTATIONS, &HAAR_SIDES));
        eprintln!("{name}: done");
    }
    let names = MAPS.iter().map(|s| s.to_string()).collect();
    let prior = match LightPrior::fit(names, ROTATIONS, &samples, SHRINKAGE) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    let text = serde_json::to_string_pretty(&prior).expect("plain numbers serialise");
    if let Err(e) = std::fs::write(&out, text + "\n") {
        eprintln!("error: cannot write {out}: {e}");
        std::process::exit(1);
    }
    eprintln!("wrote {out}");
}
