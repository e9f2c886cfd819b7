//! Seeded random directions for the transport and render tests and benches.

#![allow(dead_code)]

use rand::Rng;
use rand_pcg::Pcg64;
use relight_cpc::Vec3;

/// A uniformly distributed unit vector (rejection from the unit ball, skipping the
/// innermost shell so that normalising never amplifies rounding).
pub fn random_unit(rng: &mut Pcg64) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.norm() > 0.2 && v.norm() <= 1.0 {
            return v.normalize();
        }
    }
}

/// `n` seeded random vertices for renderer tests and benches: unit normals, unit view
/// directions within about 0.7 of each normal, and a visibility at side `n_local` whose
/// fractions are uniform in `lo..=255` (drawn in that order from `rng`).
pub fn random_vertices(
    rng: &mut Pcg64,
    n: usize,
    n_local: usize,
    rays_per_texel: usize,
    lo: u8,
) -> (
    Vec<Vec3>,
    Vec<Vec3>,
    relight_cpc::transport::visibility::Visibility,
) {
    let normals: Vec<Vec3> = (0..n).map(|_| random_unit(rng)).collect();
    let dirs: Vec<Vec3> = normals
        .iter()
        .map(|nv| (nv + random_unit(rng) * 0.7).normalize())
        .collect();
    let vis = relight_cpc::transport::visibility::Visibility {
        n_local,
        rays_per_texel,
        frac: (0..n * n_local * n_local)
            .map(|_| rng.random_range(lo..=255u8))
            .collect(),
        open: vec![false; n],
        degenerate: 0,
        rays_traced: 0,
        rays_known_open: 0,
    };
    (normals, dirs, vis)
}
