use super::*;
use rand::SeedableRng;

fn dir(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// ∫ρ dω_i by a fine midpoint quadrature in (cos θ, φ) over the hemisphere around z.
fn albedo_quadrature(l: &Lobe, wo: &Vec3, m: usize) -> f64 {
    let n = Vec3::z();
    let mut s = 0.0;
    for i in 0..m {
        let ct = (i as f64 + 0.5) / m as f64;
        for j in 0..2 * m {
            let phi = 2.0 * PI * (j as f64 + 0.5) / (2 * m) as f64;
            let st = (1.0 - ct * ct).sqrt();
            let wi = Vec3::new(st * phi.cos(), st * phi.sin(), ct);
            s += l.eval(&n, &wi, wo);
        }
    }
    s * 2.0 * PI / (m * 2 * m) as f64
}

#[test]
fn lambert_and_phong_albedo_at_normal_incidence_is_one() {
    // Normalised lobes: ∫ρ dω = 1 exactly at normal incidence. Midpoint rule with
    // 400×800 cells: error O(1/m²) ≈ 1e-5 for these smooth integrands; Phong 50 is
    // sharp, so allow 1e-3.
    let wo = Vec3::z();
    for l in [
        Lobe::Lambert,
        Lobe::Phong { exponent: 1.0 },
        Lobe::Phong { exponent: 50.0 },
    ] {
        let a = albedo_quadrature(&l, &wo, 400);
        assert!((a - 1.0).abs() < 1e-3, "{l:?}: {a}");
    }
}

#[test]
fn sampling_densities_integrate_to_one_and_match_samples() {
    // The density of each sampler integrates to 1 over the sphere (quadrature), and the
    // MC estimate E[ρ/pdf] of the albedo agrees with the quadrature albedo.
    // Tolerances: quadrature 2e-3 (sharp lobes on a 600×1200 grid); MC: 5 standard errors.
    let wo = dir(0.6, 0.3);
    let n = Vec3::z();
    for l in [
        Lobe::Lambert,
        Lobe::Phong { exponent: 20.0 },
        Lobe::Ggx { alpha: 0.3 },
        Lobe::Ggx { alpha: 0.8 },
    ] {
        let m = 600;
        let mut total = 0.0;
        for i in 0..m {
            let ct = -1.0 + 2.0 * (i as f64 + 0.5) / m as f64;
            for j in 0..2 * m {
                let phi = 2.0 * PI * (j as f64 + 0.5) / (2 * m) as f64;
                let st = (1.0 - ct * ct).sqrt();
                total += l.pdf(&n, &Vec3::new(st * phi.cos(), st * phi.sin(), ct), &wo);
            }
        }
        total *= 4.0 * PI / (m * 2 * m) as f64;

        let reference = albedo_quadrature(&l, &wo, 600);
        let mut rng = Pcg32::seed_from_u64(7);
        let k = 200_000;
        let (mut s, mut s2, mut accepted) = (0.0, 0.0, 0usize);
        for _ in 0..k {
            if let Some(wi) = l.sample(&n, &wo, rng.random(), rng.random()) {
                accepted += 1;
                let p = l.pdf(&n, &wi, &wo);
                if p > 0.0 {
                    let v = l.eval(&n, &wi, &wo) / p;
                    s += v;
                    s2 += v * v;
                }
            }
        }
        let mean = s / k as f64;
        let se = ((s2 / k as f64 - mean * mean) / k as f64).sqrt();
        // GGX rejects half vectors facing away from ω_o, so its density integrates to
        // the acceptance rate (binomial standard error ≤ 0.5/√k ≈ 1.1e-3, plus 2e-3 for
        // the quadrature); the other samplers never reject.
        let accept = accepted as f64 / k as f64;
        assert!(
            (total - accept).abs() < 5e-3,
            "{l:?}: pdf integrates to {total}, accepted {accept}"
        );
        assert!(
            (mean - reference).abs() < 5.0 * se + 1e-3,
            "{l:?}: MC {mean} ± {se} vs quadrature {reference}"
        );
    }
}

#[test]
fn ggx_is_reciprocal_and_within_energy() {
    // Helmholtz: ρ(ω_i, ω_o)/cos θ_i = ρ(ω_o, ω_i)/cos θ_o (ρ includes the cosine).
    // Albedo ≤ 1 (GGX with Smith G loses energy, never gains). Tolerance 1e-12 for the
    // identity (a few flops), 2e-3 for the quadrature.
    let n = Vec3::z();
    for alpha in [0.05, 0.3, 1.0] {
        let l = Lobe::Ggx { alpha };
        for (a, b) in [
            (dir(0.3, 0.1), dir(1.0, 2.0)),
            (dir(1.2, -0.4), dir(0.2, 0.9)),
        ] {
            let x = l.eval(&n, &a, &b) / a.z;
            let y = l.eval(&n, &b, &a) / b.z;
            assert!((x - y).abs() <= 1e-12 * x.abs().max(1.0), "{x} {y}");
        }
        if alpha >= 0.3 {
            let al = albedo_quadrature(&l, &dir(0.5, 0.0), 600);
            // Loose lower bound: separable Smith GGX keeps most energy when smooth
            // (≈0.9 at α = 0.3), much less when rough (≈0.33 at α = 1, Kulla & Conty 2017).
            let floor = if alpha < 0.5 { 0.8 } else { 0.2 };
            assert!(al <= 1.0 + 2e-3 && al > floor, "alpha {alpha}: albedo {al}");
        }
    }
}

#[test]
fn environment_pdf_integrates_to_one_and_matches_sampler() {
    // ∫ pdf dω = Σ_texels P_texel = 1 (up to round-off), and every sampled direction
    // reports the pdf that `pdf()` computes for it (same texel): 1e-9 relative.
    let frame = [Vec3::x(), Vec3::y(), Vec3::z()];
    let (w, h) = (16, 8);
    let mut rng = Pcg32::seed_from_u64(3);
    let rgb: Vec<[f32; 3]> = (0..w * h)
        .map(|_| [rng.random::<f32>(), rng.random::<f32>() * 3.0, 0.0])
        .collect();
    let env = Environment::new(w, h, &rgb, frame).unwrap();
    let mut total = 0.0;
    for v in 0..h {
        for u in 0..w {
            let th = PI * (v as f64 + 0.5) / h as f64;
            let ph = 2.0 * PI * (u as f64 + 0.5) / w as f64;
            total += env.pdf(&dir(th, ph)) * texel_solid_angle(w, h, v);
        }
    }
    assert!((total - 1.0).abs() < 1e-9, "{total}");
    for _ in 0..1000 {
        let (d, p) = env
            .sample(rng.random(), rng.random(), rng.random(), rng.random())
            .unwrap();
        assert!((d.norm() - 1.0).abs() < 1e-12);
        assert!((env.pdf(&d) - p).abs() <= 1e-9 * p);
    }
}
