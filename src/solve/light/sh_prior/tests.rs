use super::*;
use std::f64::consts::PI;

/// Texel averages of `f` on the full grid by `s × s` sub-texels.
fn texel_averages(n: usize, s: usize, f: impl Fn(&Vec3) -> f64) -> Vec<f64> {
    let g = SphereGrid::full(n);
    (0..g.len())
        .map(|t| {
            let (mut a, mut w) = (0.0, 0.0);
            for (d, o) in g.sample_points(t, s) {
                a += o * f(&d);
                w += o;
            }
            a / w
        })
        .collect()
}

#[test]
fn the_basis_is_orthonormal_by_quadrature() {
    // 128² texels × 4² sub-texels of exact solid angle: a midpoint rule on smooth
    // quadratics, error O(h²) with h ≈ 0.3° → well under 1e-4.
    let p = ShProjection::new(128, 4);
    let g = SphereGrid::full(128);
    for j in 0..N_SH {
        let x: Vec<f64> = (0..g.len()).map(|t| sh9(&g.texel_dir(t))[j]).collect();
        let c = p.project(&x);
        for i in 0..N_SH {
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((c[i] - want).abs() < 1e-3, "⟨Y{i}, Y{j}⟩ = {}", c[i]);
        }
    }
}

#[test]
fn projection_of_the_clamped_cosine_matches_its_analytic_coefficients() {
    // max(0, z): zonal, c_00 = √π/2, c_10 = √(π/3), c_20 = √(5π)/8, all others 0
    // (Ramamoorthi & Hanrahan 2001). Texel averages by 8² sub-texels; the kink at the
    // equator runs along texel edges of the full map (the inner diamond). `P x` treats the
    // map as constant over each texel, an O(h²) error in the texel size: 3.8e-3 on c_10
    // at 32² (measured), so at 64² about a quarter of that, below 2e-3.
    let n = 64;
    let x = texel_averages(n, 8, |d| d.z.max(0.0));
    let c = ShProjection::new(n, 4).project(&x);
    let want = [
        PI.sqrt() / 2.0,
        0.0,
        (PI / 3.0).sqrt(),
        0.0,
        0.0,
        0.0,
        (5.0 * PI).sqrt() / 8.0,
        0.0,
        0.0,
    ];
    for i in 0..N_SH {
        assert!(
            (c[i] - want[i]).abs() < 2e-3,
            "c{i} = {} want {}",
            c[i],
            want[i]
        );
    }
    // A constant map of 1: c_00 = 4π Y_00 = 2√π exactly (solid angles sum to 4π).
    let c1 = ShProjection::new(8, 1).project(&[1.0; 64]);
    assert!((c1[0] - 2.0 * PI.sqrt()).abs() < 1e-12);
}

#[test]
fn latlong_coefficients_turn_with_the_map() {
    // A map bright at azimuth 0 on the horizon: rotating by φ moves Y_11 (∝ x) into
    // Y_1−1 (∝ y): (c_1−1, c_11) → (sin φ, cos φ) c_11. Tolerance 1e-9: the same
    // pixel sum with rotated directions, rounding only.
    let mut ll = LatLong::black(16);
    ll.rgb[8 * ll.width] = [1.0; 3];
    let c0 = latlong_sh(&ll, 0.0);
    let phi = 0.7;
    let c1 = latlong_sh(&ll, phi);
    let (s, c) = phi.sin_cos();
    let want_y = s * c0[0][3] + c * c0[0][1];
    assert!((c1[0][1] - want_y).abs() < 1e-9);
    assert!((c1[0][0] - c0[0][0]).abs() < 1e-12);
}

fn toy_prior() -> LightPrior {
    // A made-up SPD precision (diagonally dominant) and mean: the gradient checks do not
    // depend on real statistics.
    let mut prec = vec![0.0; N_SHAPE * N_SHAPE];
    for i in 0..N_SHAPE {
        for j in 0..N_SHAPE {
            prec[i * N_SHAPE + j] = if i == j {
                3.0 + i as f64 * 0.1
            } else {
                0.05 * ((i + 2 * j) % 5) as f64 / 5.0
            };
        }
    }
    // Symmetrise.
    for i in 0..N_SHAPE {
        for j in 0..i {
            let v = 0.5 * (prec[i * N_SHAPE + j] + prec[j * N_SHAPE + i]);
            prec[i * N_SHAPE + j] = v;
            prec[j * N_SHAPE + i] = v;
        }
    }
    LightPrior {
        maps: vec![],
        rotations: 1,
        shape_mean: (0..N_SHAPE)
            .map(|i| 0.1 * (i as f64 - 12.0) / 12.0)
            .collect(),
        shape_precision: prec,
        shrinkage: 0.0,
        haar_scale: vec![],
    }
}

#[test]
fn the_sh_term_gradient_matches_finite_differences() {
    // Central differences of a quadratic are exact up to rounding: relative 1e-6.
    let n = 8;
    let p = ShProjection::new(n, 2);
    let term = ShPriorTerm::new(&p, &toy_prior(), [2.0, 1.5, 0.7], 0.3);
    let x: Vec<f64> = (0..3 * n * n)
        .map(|i| 1.0 + ((i * 37) % 11) as f64 / 7.0)
        .collect();
    let mut g = vec![0.0; x.len()];
    term.add_hessian(&x, &mut g);
    let gmax = g.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    assert!(gmax > 0.0);
    for &t in &[0, 5, 63, 64, 100, 191] {
        let h = 1e-4;
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[t] += h;
        xm[t] -= h;
        let fd = (term.energy(&xp) - term.energy(&xm)) / (2.0 * h);
        assert!(
            (fd - g[t]).abs() <= 1e-6 * gmax,
            "texel {t}: fd {fd} grad {}",
            g[t]
        );
    }
    // The diagonal: e_tᵀ H e_t by products.
    let d = term.diagonal();
    for &t in &[3, 70, 150] {
        let mut e = vec![0.0; x.len()];
        e[t] = 1.0;
        let mut he = vec![0.0; x.len()];
        term.add_hessian(&e, &mut he);
        assert!((he[t] - d[t]).abs() <= 1e-12 * d[t].abs().max(1.0));
    }
}

#[test]
fn the_sh_term_vanishes_on_the_mean_shape_and_ignores_scale() {
    // A map whose shape is the prior mean has r = 0 (to the projection's rounding);
    // scaling a map and its s_c together leaves the energy unchanged.
    let n = 16;
    let p = ShProjection::new(n, 2);
    let prior = toy_prior();
    let g = SphereGrid::full(n);
    // Texel values Σ_i a_i Y_i with a_0 = 1 and a_i = m_i (shape = m exactly when the
    // projection reproduces the coefficients, which it does to ~1e-3).
    let x: Vec<f64> = (0..3)
        .flat_map(|c| {
            let prior = &prior;
            (0..g.len()).map(move |t| {
                let y = sh9(&g.texel_dir(t));
                y[0] + (1..N_SH)
                    .map(|i| prior.shape_mean[c * 8 + i - 1] * y[i])
                    .sum::<f64>()
            })
        })
        .collect();
    let c0 = p.project(&x[..n * n])[0];
    let term = ShPriorTerm::new(&p, &prior, [c0; 3], 1.0);
    let e_mean = term.energy(&x);
    let flat = vec![1.0; 3 * n * n];
    let e_flat = ShPriorTerm::new(&p, &prior, [p.project(&flat[..n * n])[0]; 3], 1.0).energy(&flat);
    // The flat map's shape is 0, distance mᵀΛm ≫ the residual of the mean map.
    assert!(e_mean < 1e-3 * e_flat, "mean {e_mean} flat {e_flat}");
    let x3: Vec<f64> = flat.iter().map(|v| 3.0 * v).collect();
    let e3 = ShPriorTerm::new(&p, &prior, [3.0 * p.project(&flat[..n * n])[0]; 3], 1.0).energy(&x3);
    assert!((e3 - e_flat).abs() < 1e-9 * e_flat);
}

#[test]
fn haar_weights_give_the_l1_gradient_at_the_iterate() {
    // At h = h̄ the majoriser ½ d h² has gradient d h̄ = 2σ² sign(h̄) |h̄| / (h_0 b (|h̄| + ε)),
    // i.e. the L1 gradient 2σ² sign(h̄)/(h_0 b) up to the factor |h̄|/(|h̄|+ε) (exactly that
    // factor; tolerance 1e-12 relative, rounding).
    let n = 8;
    let h: Vec<f64> = (0..n * n)
        .map(|k| {
            if k == 0 {
                4.0
            } else {
                ((k * 13) % 7) as f64 - 3.0
            }
        })
        .collect();
    let scales = vec![0.5, 0.25, 0.125];
    let d = haar_l1_weights(&h, n, &scales, 0.2);
    assert_eq!(d[0], 0.0);
    for k in 1..n * n {
        let m = match haar::coefficient(n, k) {
            haar::Coefficient::Wavelet { m, .. } => m,
            _ => unreachable!(),
        };
        let b = scales[m.trailing_zeros() as usize];
        let eps = EPS_REL * 4.0 * m as f64 / n as f64;
        let want = 2.0 * 0.2 / (4.0 * b) * h[k].signum() * h[k].abs() / (h[k].abs() + eps);
        let got = d[k] * h[k];
        assert!((got - want).abs() <= 1e-12 * want.abs().max(1e-300));
    }
    // The texel-basis diagonal against Wᵀ diag(d) W applied to unit vectors.
    let dt = haar_diag_in_texels(&d, n);
    for &t in &[0, 9, 27, 63] {
        let mut e = vec![0.0; n * n];
        e[t] = 1.0;
        haar::forward(&mut e, n);
        e.iter_mut().zip(&d).for_each(|(v, w)| *v *= w);
        haar::inverse(&mut e, n);
        assert!((e[t] - dt[t]).abs() < 1e-9 * dt[t]);
    }
}

#[test]
fn the_builtin_statistics_load_and_cover_the_estimator_resolutions() {
    let p = LightPrior::builtin().unwrap();
    assert_eq!(p.shape_mean.len(), N_SHAPE);
    assert_eq!(p.shape_precision.len(), N_SHAPE * N_SHAPE);
    for n in [8, 16, 32, 64] {
        let s = p.haar_scales(n).unwrap();
        assert_eq!(s.len(), n.trailing_zeros() as usize);
        assert!(s.iter().all(|v| *v > 0.0 && v.is_finite()));
    }
}
