//! The reference renderer against closed forms: white furnace, a Lambert sphere under
//! `L(ω) = max(0, ω·up)`, a cast shadow of a sphere on a plane point, and a glossy lobe
//! under a stiff (sun) map against fine quadrature. Tolerances come from the estimator's own
//! standard error (5σ: a false failure once in ~1.7 million checks) plus a stated bound on
//! the discretisation.

use relight_cpc::import::mesh::area_weighted_normals;
use relight_cpc::sphere::env_frame;
use relight_cpc::synth::geometry::{icosphere, plane};
use relight_cpc::transport::reference::{
    texel_solid_angle, BruteForce, Environment, Lobe, PinholeCamera, ReferenceScene, Reflectance,
    Samples, Unoccluded,
};
use relight_cpc::Vec3;
use std::f64::consts::PI;

fn lambert(albedo: [f64; 3], n_vertices: usize) -> Reflectance {
    Reflectance {
        lobes: vec![Lobe::Lambert],
        lambda: vec![vec![albedo]],
        weights: vec![1.0; n_vertices],
    }
}

/// A camera at `eye` looking at the origin, world +y roughly up in the image (−y_cam).
fn look_at(eye: Vec3, size: u32, fov_deg: f64) -> PinholeCamera {
    let z = (-eye).normalize();
    let x = z.cross(&Vec3::y()).normalize() * -1.0;
    let x = if x.dot(&z.cross(&Vec3::y())) < 0.0 {
        x
    } else {
        -x
    };
    let y = z.cross(&x);
    let r = nalgebra::Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let f = size as f64 / 2.0 / (fov_deg.to_radians() / 2.0).tan();
    PinholeCamera {
        width: size,
        height: size,
        fx: f,
        fy: f,
        cx: size as f64 / 2.0,
        cy: size as f64 / 2.0,
        rotation: r,
        translation: -(r * eye),
    }
}

#[test]
fn white_furnace_lambert_sphere_renders_albedo_times_radiance() {
    // Constant L, convex unoccluded object, Lambert albedo a: every pixel fully on the
    // object has expectation a·L exactly (E = πL, ρ = a/π). A pixel's MC noise is not
    // returned by `render`, so the tolerance uses the scatter across pixels: the mean over
    // N pixels within 5σ/√N, each pixel within 6σ. A thin sliver of directions between
    // the interpolated and the geometric normal is self-shadowed (icosphere level 3,
    // angle ≤ 0.04 rad: cosine-weighted measure < 2e-3), so 2e-3 relative is added.
    let (p, f) = icosphere(3);
    let normals = area_weighted_normals(&p, &f);
    let a = [0.2, 0.5, 0.8];
    let l = [1.0f32, 2.0, 0.5];
    let refl = lambert(a, p.len());
    let frame = env_frame(&Vec3::y()).unwrap();
    let env = Environment::constant(l, frame).unwrap();
    let caster = BruteForce {
        positions: &p,
        faces: &f,
    };
    let scene = ReferenceScene {
        positions: &p,
        normals: &normals,
        faces: &f,
        reflectance: &refl,
        env: &env,
        caster: &caster,
        offset: 1e-6,
    };
    scene.validate().unwrap();
    let cam = look_at(Vec3::new(0.5, 1.0, 3.5), 24, 40.0);
    let img = scene.render(
        &cam,
        &Samples {
            per_pixel: 1,
            light: 16,
            seed: 5,
        },
    );
    for c in 0..3 {
        let expect = a[c] * l[c] as f64;
        let vals: Vec<f64> = img
            .rgb
            .iter()
            .zip(&img.coverage)
            .filter(|(_, &cov)| cov == 1.0)
            .map(|(px, _)| px[c] as f64)
            .collect();
        assert!(vals.len() > 100, "only {} object pixels", vals.len());
        let n = vals.len() as f64;
        let mean = vals.iter().sum::<f64>() / n;
        let sd = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let tol = 5.0 * sd / n.sqrt() + 2e-3 * expect;
        assert!(
            (mean - expect).abs() < tol,
            "channel {c}: {mean} vs {expect} ± {tol}"
        );
        for v in &vals {
            assert!(
                (v - expect).abs() < 6.0 * sd + 2e-3 * expect,
                "pixel {v} vs {expect}"
            );
        }
    }
    // Background pixels stay black.
    assert!(img
        .rgb
        .iter()
        .zip(&img.coverage)
        .filter(|(_, &cov)| cov == 0.0)
        .all(|(px, _)| px == &[0.0; 3]));
}

/// Lat-long map of `L(ω) = max(0, ω·e_z)` with exact texel averages over solid angle:
/// `∫ cos θ sin θ dθ / ∫ sin θ dθ = (sin²θ₁ − sin²θ₀) / (2 (cos θ₀ − cos θ₁))` above the
/// horizon (H even, so the horizon is a row boundary), zero below.
fn clamped_cosine_sky(h: usize) -> Vec<[f32; 3]> {
    let w = 2 * h;
    let mut rgb = vec![[0.0f32; 3]; w * h];
    for v in 0..h / 2 {
        let t0 = PI * v as f64 / h as f64;
        let t1 = PI * (v + 1) as f64 / h as f64;
        let avg = (t1.sin().powi(2) - t0.sin().powi(2)) / (2.0 * (t0.cos() - t1.cos()));
        for u in 0..w {
            rgb[v * w + u] = [avg as f32; 3];
        }
    }
    rgb
}

#[test]
fn lambert_sphere_under_clamped_cosine_sky_matches_closed_form() {
    // Irradiance under L(ω) = max(0, ω·up) at a normal making angle γ with up:
    // E(γ) = ∫ max(0, n·ω) max(0, up·ω) dω = (2/3)((π − γ) cos γ + sin γ)
    // (checks: γ = 0 gives 2π/3 = ∫_hemi cos²; γ = π gives 0). Radiance = (a/π) E.
    // Texel quantisation of a smooth L against the smooth clamped cosine: relative error
    // O(Δθ²) ≈ (π/64)²/12 ≈ 2e-4; tolerance 5σ + 1e-3 · max radiance.
    let (p, f) = icosphere(2);
    let normals = area_weighted_normals(&p, &f);
    let a = [0.7, 0.7, 0.7];
    let refl = lambert(a, p.len());
    let up = Vec3::new(0.2, 1.0, -0.1).normalize();
    let h = 64;
    let env = Environment::new(2 * h, h, &clamped_cosine_sky(h), env_frame(&up).unwrap()).unwrap();
    let caster = BruteForce {
        positions: &p,
        faces: &f,
    };
    let scene = ReferenceScene {
        positions: &p,
        normals: &normals,
        faces: &f,
        reflectance: &refl,
        env: &env,
        caster: &caster,
        offset: 1e-7,
    };
    let mut worst: f64 = 0.0;
    for v in (0..p.len()).step_by(7) {
        let n = normals[v];
        let gamma = n.dot(&up).clamp(-1.0, 1.0).acos();
        let e = 2.0 / 3.0 * ((PI - gamma) * gamma.cos() + gamma.sin());
        let expect = a[0] / PI * e;
        let est = scene.vertex_radiance(v, &n, 512, 11);
        let tol = 5.0 * est.std_err[0] + 1e-3 * a[0] * 2.0 / 3.0;
        assert!(
            (est.mean[0] - expect).abs() < tol,
            "vertex {v} (γ = {gamma:.3}): {} vs {expect} ± {tol}",
            est.mean[0]
        );
        worst = worst.max((est.mean[0] - expect).abs());
    }
    assert!(worst.is_finite());
}

#[test]
fn sphere_casts_the_expected_shadow_on_a_plane_point() {
    // Point on a plane (normal up) under a sphere of radius r whose centre is h above it,
    // constant sky L, Lambert albedo a. The sphere hides a cone of half-angle α around the
    // normal, sin α = r/h, whose cosine-weighted measure is π sin²α, so
    // L_out = a L (1 − r²/h²). The occluder is an inscribed icosphere (level 4: its
    // silhouette radius is within 6e-4 r of the sphere's), so the occluded fraction is
    // known to 1.2e-3 relative: tolerance 5σ + 1e-3 · a L.
    let (r, hgt) = (1.0, 2.0);
    let (sp, sf) = icosphere(4);
    let sp: Vec<Vec3> = sp
        .iter()
        .map(|q| q * r + Vec3::new(0.0, hgt, 0.0))
        .collect();
    // A 2×2-cell plane: its centre vertex sits at the origin, the shaded point.
    let (pp, pf) = plane(&Vec3::zeros(), &Vec3::y(), 1.0, 2);
    let centre = pp.iter().position(|q| q.norm() < 1e-12).unwrap();
    let mut pos = pp.clone();
    let mut faces = pf.clone();
    relight_cpc::synth::geometry::append(&mut pos, &mut faces, &sp, &sf);
    let normals = area_weighted_normals(&pos, &faces);
    let a = 0.6;
    let l = 1.5f32;
    let refl = lambert([a; 3], pos.len());
    let env = Environment::constant([l; 3], env_frame(&Vec3::y()).unwrap()).unwrap();
    let caster = BruteForce {
        positions: &pos,
        faces: &faces,
    };
    let scene = ReferenceScene {
        positions: &pos,
        normals: &normals,
        faces: &faces,
        reflectance: &refl,
        env: &env,
        caster: &caster,
        offset: 1e-7,
    };
    let est = scene.vertex_radiance(centre, &Vec3::new(0.3, 1.0, 0.0).normalize(), 2048, 3);
    let expect = a * l as f64 * (1.0 - r * r / (hgt * hgt));
    let tol = 5.0 * est.std_err[0] + 1e-3 * a * l as f64;
    assert!(
        (est.mean[0] - expect).abs() < tol,
        "{} vs {expect} ± {tol}",
        est.mean[0]
    );
    // And without the sphere the point sees the whole sky: a·L.
    let open = ReferenceScene {
        positions: &pos,
        normals: &normals,
        faces: &faces,
        reflectance: &refl,
        env: &env,
        caster: &Unoccluded,
        offset: 1e-7,
    };
    let est = open.vertex_radiance(centre, &Vec3::y(), 2048, 3);
    let expect = a * l as f64;
    assert!((est.mean[0] - expect).abs() < 5.0 * est.std_err[0] + 1e-9);
}

#[test]
fn glossy_lobe_under_a_sun_matches_quadrature_without_fireflies() {
    // A stiff map: sky 1 everywhere plus one texel 30,000× brighter (the city.exr case).
    // Reference: Σ_texels L_texel ∫_texel ρ dω by 16×16 midpoint sub-quadrature in
    // (φ, cos θ) per texel (the map is piecewise constant, so this is the exact integral
    // up to the sub-quadrature of ρ; Phong 50 over a 2.8°×2.8° texel: < 0.5% relative).
    // MC with MIS: within 5σ + 0.5%, and the standard error under 3% of the mean (no
    // firefly dominates).
    let (w, h) = (128, 64);
    let mut rgb = vec![[1.0f32; 3]; w * h];
    let sun = 20 * w + 37;
    rgb[sun] = [30_000.0; 3];
    let frame = env_frame(&Vec3::z()).unwrap();
    let env = Environment::new(w, h, &rgb, frame).unwrap();
    let sun_dir = {
        let th = PI * 20.5 / h as f64;
        let ph = 2.0 * PI * 37.5 / w as f64;
        frame[0] * (th.sin() * ph.cos()) + frame[1] * (th.sin() * ph.sin()) + frame[2] * th.cos()
    };
    let n = Vec3::z();
    // The viewing direction whose mirror direction is the sun: the sharp lobe catches it.
    let wo_sun = n * (2.0 * n.dot(&sun_dir)) - sun_dir;
    for (lobe, wo) in [
        (Lobe::Phong { exponent: 50.0 }, wo_sun),
        (Lobe::Ggx { alpha: 0.2 }, wo_sun),
        (
            Lobe::Phong { exponent: 50.0 },
            Vec3::new(0.3, -0.2, 1.0).normalize(),
        ),
        (Lobe::Lambert, Vec3::new(0.1, 0.4, 1.0).normalize()),
        (
            Lobe::Ggx { alpha: 0.2 },
            Vec3::new(-0.4, 0.2, 1.0).normalize(),
        ),
    ] {
        let m = 16;
        let mut reference = 0.0;
        for v in 0..h {
            let c0 = (PI * v as f64 / h as f64).cos();
            let c1 = (PI * (v + 1) as f64 / h as f64).cos();
            if c0 <= 0.0 && c1 <= 0.0 {
                continue;
            }
            let om = texel_solid_angle(w, h, v);
            for u in 0..w {
                let mut s = 0.0;
                for i in 0..m {
                    let ct = c0 + (c1 - c0) * (i as f64 + 0.5) / m as f64;
                    let st = (1.0 - ct * ct).max(0.0).sqrt();
                    for j in 0..m {
                        let ph = 2.0 * PI * (u as f64 + (j as f64 + 0.5) / m as f64) / w as f64;
                        let wi =
                            frame[0] * (st * ph.cos()) + frame[1] * (st * ph.sin()) + frame[2] * ct;
                        s += lobe.eval(&n, &wi, &wo);
                    }
                }
                reference += rgb[v * w + u][0] as f64 * s / (m * m) as f64 * om;
            }
        }
        let est = relight_cpc::transport::reference::shade_point(
            &Vec3::zeros(),
            &n,
            &n,
            &wo,
            &[lobe],
            &[[1.0; 3]],
            &env,
            &Unoccluded,
            1e-6,
            4096,
            &mut rand_pcg::Pcg32::new(9, 1),
        );
        let tol = 5.0 * est.std_err[0] + 5e-3 * reference;
        assert!(
            (est.mean[0] - reference).abs() < tol,
            "{lobe:?}: MC {} ± {} vs quadrature {reference}",
            est.mean[0],
            est.std_err[0]
        );
        assert!(
            est.std_err[0] < 0.03 * est.mean[0],
            "{lobe:?}: noisy: {} ± {}",
            est.mean[0],
            est.std_err[0]
        );
    }
}
