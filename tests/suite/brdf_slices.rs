//! Basis BRDF slices against closed forms and brute-force quadrature (issue 4).
//!
//! A slice holds texel averages, so `Σ_t slice_t Δω_t` is the lobe's directional albedo
//! `∫ ρ(ω, ω_o) dω`; the references below integrate `eval` independently in spherical
//! coordinates (no hemi-octahedral map involved).

use relight_cpc::transport::brdf::{default_basis, BasisBrdf, SliceGrid, SliceTable};
use relight_cpc::Vec3;
use std::f64::consts::PI;

/// `∫ ρ(ω, ω_o) dω` by the midpoint rule in `(cos θ, φ)` (area element `d cosθ dφ`).
fn albedo_reference(b: &BasisBrdf, wo: &Vec3, n_theta: usize, n_phi: usize) -> f64 {
    let mut s = 0.0;
    let dc = 1.0 / n_theta as f64;
    let dp = 2.0 * PI / n_phi as f64;
    for i in 0..n_theta {
        let c = (i as f64 + 0.5) * dc;
        let st = (1.0 - c * c).sqrt();
        for j in 0..n_phi {
            let p = (j as f64 + 0.5) * dp;
            let wi = Vec3::new(st * p.cos(), st * p.sin(), c);
            s += b.eval(&wi, wo);
        }
    }
    s * dc * dp
}

fn slice_albedo(grid: &SliceGrid, b: &BasisBrdf, wo: &Vec3) -> f64 {
    let mut out = vec![0.0; grid.centre.len()];
    b.slice_with(grid, wo, &mut out);
    out.iter().zip(&grid.solid_angle).map(|(v, w)| v * w).sum()
}

fn dir(theta_deg: f64, phi_deg: f64) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

#[test]
fn lambert_slice_integrates_to_its_albedo() {
    // ∫ cos θ / π dω = 1. The slice's midpoint quadrature over 4×4 exact-area sub-texels of
    // a smooth integrand has O(h²) error, h ≈ 0.02 rad: well under 1e-4.
    // On the 8² grid sub-texels are ~0.1 rad wide: allow 1e-3 there.
    for (n, tol) in [(8, 1e-3), (32, 1e-4)] {
        let grid = SliceGrid::new(n).unwrap();
        let a = slice_albedo(&grid, &BasisBrdf::Lambert, &dir(30.0, 10.0));
        assert!((a - 1.0).abs() < tol, "n {n}: {a}");
    }
}

#[test]
fn phong_slice_albedo_is_one_at_normal_incidence_even_when_sharper_than_a_texel() {
    // The normalised lobe integrates to exactly 1 at ω_o = n. Exponent 500 has σ ≈ 2.6°,
    // narrower than a 32² texel (~4.5°): point sampling would be off by tens of percent;
    // the adaptive sub-texels must get within 0.5%.
    let grid = SliceGrid::new(32).unwrap();
    for exponent in [50.0, 500.0] {
        let a = slice_albedo(&grid, &BasisBrdf::Phong { exponent }, &Vec3::z());
        assert!((a - 1.0).abs() < 5e-3, "N {exponent}: {a}");
    }
    // Even on a coarse 8² grid (texels ~18° wide).
    let grid = SliceGrid::new(8).unwrap();
    let a = slice_albedo(&grid, &BasisBrdf::Phong { exponent: 500.0 }, &Vec3::z());
    assert!((a - 1.0).abs() < 2e-2, "coarse grid: {a}");
}

#[test]
fn slice_albedos_match_spherical_quadrature_and_stay_within_bounds() {
    // Reference: 1500 × 1500 midpoint cells in (cos θ, φ), cells ≤ 0.004 rad, far finer
    // than the sharpest lobe here (σ = 0.045 rad), so its error is < 1e-4. The slice may
    // differ by its own quadrature error, allowed 1% relative (plus 1e-3 absolute for lobes
    // that the horizon cuts away).
    let grid = SliceGrid::new(32).unwrap();
    let cases = [(0.0, 0.0), (35.0, 20.0), (60.0, 200.0), (80.0, 75.0)];
    for b in default_basis() {
        for &(t, p) in &cases {
            let wo = dir(t, p);
            let reference = albedo_reference(&b, &wo, 1500, 1500);
            let a = slice_albedo(&grid, &b, &wo);
            assert!(
                (a - reference).abs() < 1e-2 * reference + 1e-3,
                "{} at θo {t}: slice {a} reference {reference}",
                b.label()
            );
            // Energy: no lobe reflects more than it receives.
            assert!(reference <= 1.0 + 1e-3, "{} θo {t}: {reference}", b.label());
            // GGX at normal incidence, closed-form bounds from the GGX slope distribution
            // (P(tan²θ_h ≤ x) = x / (α² + x), weighted by n·h) and G1 ≤ 1: half-vectors
            // beyond 45° send ω_i below the horizon, so albedo ≤ P(θ_h < 45°) = 1/(1+α²);
            // those within 30° keep ω_i within 60°, where G1 ≥ G1(cos 60°), so
            // albedo ≥ P(θ_h < 30°) · G1(½).
            if let (BasisBrdf::Ggx { alpha }, 0.0) = (b, t) {
                let a2 = alpha * alpha;
                let upper = 1.0 / (1.0 + a2);
                let t30 = 1.0 / 3.0;
                let g1 = 1.0 / (0.5 + (a2 + (1.0 - a2) * 0.25).sqrt());
                let lower = t30 / (a2 + t30) * g1;
                assert!(
                    reference <= upper + 1e-3 && reference >= lower - 1e-3,
                    "{}: {lower} <= {reference} <= {upper}",
                    b.label()
                );
            }
        }
    }
}

#[test]
fn slice_texels_are_texel_averages() {
    // Per texel, compare with a 48 × 48 sub-texel average (sub-texels of ≈ 0.002 rad),
    // for the texels holding the peak of a sharp lobe. Tolerance 3% of the peak texel
    // value: the adaptive slice uses ≥ 8×8 sub-texels there.
    let n = 32;
    let grid = SliceGrid::new(n).unwrap();
    let b = BasisBrdf::Phong { exponent: 500.0 };
    let wo = dir(40.0, 30.0);
    let mut out = vec![0.0; n * n];
    b.slice_with(&grid, &wo, &mut out);
    let peak = out.iter().cloned().fold(0.0, f64::max);
    assert!(peak > 0.0);
    let mut checked = 0;
    for (t, &o) in out.iter().enumerate() {
        if o < 0.05 * peak {
            continue;
        }
        let (num, den) = grid
            .grid
            .sample_points(t, 48)
            .fold((0.0, 0.0), |(a, c), (d, w)| {
                (a + b.eval(&d, &wo) * w, c + w)
            });
        let truth = num / den;
        assert!(
            (o - truth).abs() < 0.03 * peak,
            "texel {t}: {} vs {truth}",
            o
        );
        checked += 1;
    }
    assert!(checked >= 2);
}

#[test]
fn tabulated_slices_interpolate_smooth_lobes() {
    // A 16² table over ω_o, bilinear: for the broad lobes (Lambert, GGX 0.4) the
    // interpolated albedo stays within 2% of the direct slice's (the albedo varies slowly
    // with ω_o); this is the cheap path measured in benches/transport.rs.
    let grid = SliceGrid::new(16).unwrap();
    for b in [BasisBrdf::Lambert, BasisBrdf::Ggx { alpha: 0.4 }] {
        let table = SliceTable::new(&b, &grid, 16).unwrap();
        let mut out = vec![0.0; grid.centre.len()];
        for wo in [dir(10.0, 0.0), dir(45.0, 100.0), dir(70.0, 250.0)] {
            table.lookup(&wo, &mut out);
            let a: f64 = out.iter().zip(&grid.solid_angle).map(|(v, w)| v * w).sum();
            let d = slice_albedo(&grid, &b, &wo);
            assert!((a - d).abs() < 0.02 * d, "{}: {a} vs {d}", b.label());
        }
    }
}

#[test]
fn view_independent_slices_are_bitwise_the_same_for_every_outgoing_direction() {
    // The renderer and the transport compute a view-independent basis's slice once (at
    // ω_o = z) and reuse it for every vertex and view: that is exact only if the slice does
    // not depend on ω_o at all, bit for bit. A view-dependent lobe must differ.
    for n in [16, 32, 64] {
        let grid = SliceGrid::new(n).unwrap();
        for b in [
            BasisBrdf::Lambert,
            BasisBrdf::Phong { exponent: 50.0 },
            BasisBrdf::Ggx { alpha: 0.35 },
        ] {
            let mut at_z = vec![0.0; grid.centre.len()];
            b.slice_with(&grid, &Vec3::z(), &mut at_z);
            let mut other = vec![0.0; grid.centre.len()];
            let mut differs = false;
            for (t, p) in [(10.0, 0.0), (45.0, 120.0), (80.0, 250.0)] {
                b.slice_with(&grid, &dir(t, p), &mut other);
                let same = at_z
                    .iter()
                    .zip(&other)
                    .all(|(a, o)| a.to_bits() == o.to_bits());
                differs |= !same;
                if !b.view_dependent() {
                    assert!(same, "{b:?} at {n}²: slice changes with ω_o ({t}°, {p}°)");
                }
            }
            assert_eq!(differs, b.view_dependent(), "{b:?} at {n}²");
        }
    }
}
