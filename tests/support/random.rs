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
