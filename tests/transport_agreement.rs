//! The two renderers agree (issue 4): the wavelet renderer
//! (`transport::WaveletRenderer::vertex_radiance`, Eq. 5–8: light rotated into the local
//! frame, triple product with visibility and BRDF slice, untruncated; what `render_wavelet`
//! draws) against the independent reference (`reference::quadrature_point`, Eq. 1 by
//! stratified quadrature over the lat-long texels with shadow rays), at the vertices of a
//! sphere above a ground plane (cast shadows) under real maps. A reduced version of
//! `cargo bench --bench agreement` (see `bench-results/agreement.md` for the full figures).

#[path = "agreement_support/mod.rs"]
mod support;

use relight_cpc::rotation::{Rotation, RotationForm};
use relight_cpc::visibility;
use support::*;

#[test]
fn wavelet_renderer_agrees_with_the_quadrature_reference_for_diffuse_and_glossy() {
    // Small scene: 162 sphere + 13² plane vertices, 4 cameras; maps area-downsampled to
    // 128 × 64 (both renderers see the same map, so this changes the test, not its truth).
    let setup = sphere_plane(2, 12, 4);
    let maps: Vec<_> = ["sunset", "forest", "studio"]
        .iter()
        .map(|m| load_map(m, 2))
        .collect();
    let reference = reference(&setup, &maps, 2, 7);
    // Default resolutions: 64² global, 32² local, 2 visibility rays per texel.
    let vis = visibility::compute(&setup.mesh, &setup.bvh, &setup.env_from_world, 32, 2, 1);
    let rot = Rotation::new(64, 32, 32, RotationForm::Factored);
    let wavelet = renderer(&setup, &maps, &vis, &rot);
    // Shadows ignored (every visibility texel open): the same renderer must then disagree,
    // or the comparison could not see a shadow error.
    let mut open = vis.clone();
    open.frac.iter_mut().for_each(|f| *f = 255);
    let unshadowed = renderer(&setup, &maps, &open, &rot);

    // Tolerances: relative RMSE over observations and channels (see agreement_support).
    // bench-results/agreement.md measures the same renderer at the same resolutions on a
    // larger scene (931 vertices) with the full-size maps; its reference's own error is
    // ≤ 0.04% (sunset, forest) and ≤ 0.2% (studio), negligible here. Measured here
    // (release, this exact set-up): sunset 0.44% / 1.35% / 0.58% (diffuse / Phong 50 / GGX
    // 0.3), forest 0.65% / 3.07% / 0.80%, studio 3.19% / 16.6% / 3.83%; the bench: sunset
    // 0.53 / 1.66 / 0.68, forest 0.65 / 3.97 / 0.87, studio 2.73 / 16.0 / 4.01. Allowed:
    // about 1.3–2× the larger of the two.
    // Studio (small bright lights, low: the sphere's shadow edges cut them) and the Phong
    // 50 lobe (≈ 8° wide on 32² local texels of ≈ 4.5°) are resolution limits of the 64² /
    // 32² grids (the error falls with resolution in the bench), not bugs: their bounds are
    // loose but still catch a broken rotation, slice or visibility (ignoring shadows alone
    // gives 13–18% diffuse error, checked below).
    let maps_tol: [(&str, [f64; 3]); 3] = [
        ("sunset", [0.012, 0.03, 0.012]),
        ("forest", [0.012, 0.05, 0.015]),
        ("studio", [0.05, 0.22, 0.065]),
    ];
    for (i, (name, tol)) in maps_tol.iter().enumerate() {
        for (m, (mname, beta)) in MATERIALS.iter().enumerate() {
            let e = rel_rmse(&blend(&wavelet[i], beta), &blend(&reference[i], beta));
            assert!(
                e < tol[m],
                "{name}, {mname}: relative RMSE {e:.4} ≥ {}",
                tol[m]
            );
        }
        let beta = MATERIALS[0].1;
        let e_open = rel_rmse(&blend(&unshadowed[i], &beta), &blend(&reference[i], &beta));
        assert!(
            e_open > 2.0 * tol[0],
            "{name}: ignoring shadows gives only {e_open:.4}"
        );
    }
}
