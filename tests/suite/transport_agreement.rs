//! The two renderers agree (issue 4): the wavelet renderer
//! (`render::wavelet::WaveletRenderer::vertex_radiance`, Eq. 5–8: light rotated into the local
//! frame by `rotation::SplatRotation`, triple product with visibility and BRDF slice,
//! untruncated; what `render_wavelet` draws for `run` and `render`) against the independent reference (`reference::quadrature_point`, Eq. 1 by
//! stratified quadrature over the lat-long texels with shadow rays), at the vertices of a
//! sphere above a ground plane (cast shadows) under real maps. A reduced version of
//! `cargo bench --bench agreement` (see `bench-results/agreement.md` for the full figures).

use crate::agreement_support::*;
use relight_cpc::sphere::rotation::SplatRotation;
use relight_cpc::transport::visibility;

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
    // The run's render defaults: 64² global, 64² render local map with visibility traced
    // at 64² × 1 ray, SplatRotation with 4 × 4 sub-texels per global texel.
    let vis = visibility::compute(&setup.mesh, &setup.bvh, &setup.env_from_world, 64, 1, 1);
    let rot = SplatRotation::with_default_supersample(64, 64);
    assert_eq!(rot.supersample(), 4);
    let wavelet = renderer(&setup, &maps, &vis, &rot);
    // Shadows ignored (every visibility texel open): the same renderer must then disagree,
    // or the comparison could not see a shadow error.
    let mut open = vis.clone();
    open.frac.iter_mut().for_each(|f| *f = 255);
    let unshadowed = renderer(&setup, &maps, &open, &rot);

    // Tolerances: relative RMSE over observations and channels (see agreement_support).
    // Diffuse: the threshold, 2%, for every map. Measured here (this exact set-up,
    // deterministic seeds): sunset 0.43% / 0.77% / 0.49% (diffuse / Phong 50 / GGX 0.3),
    // forest 0.34 / 0.87 / 0.39, studio 1.47 / 6.98 / 1.70; bench-results/agreement.md
    // measures the same renderer on a larger scene (931 vertices, full-size maps, all 8
    // maps: diffuse ≤ 1.5%). The glossy bounds are about 1.7× the measured values.
    // Studio (small bright lights, low: the sphere's shadow edges cut them) and the Phong
    // 50 lobe (≈ 8° wide on 64² local texels of ≈ 2.3°) are resolution limits of the
    // 64² grids (the error falls with resolution in the bench), not bugs. Any broken
    // rotation, slice or visibility is caught: ignoring shadows alone gives 13.7–16.8%
    // diffuse error here (checked below), the estimator's blended 32² rotation up to 2.7%
    // in the bench.
    let maps_tol: [(&str, [f64; 3]); 3] = [
        ("sunset", [0.02, 0.013, 0.009]),
        ("forest", [0.02, 0.015, 0.007]),
        ("studio", [0.02, 0.12, 0.03]),
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
