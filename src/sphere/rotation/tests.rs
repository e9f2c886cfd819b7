use super::*;
use crate::sphere::{from_local, local_frame, SphereGrid};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

fn random(len: usize, seed: u64) -> Vec<f64> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..len).map(|_| rng.random_range(-1.0..1.0)).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[test]
fn transpose_is_the_adjoint_and_forms_agree() {
    // ⟨R x, y⟩ = ⟨x, Rᵀ y⟩: both sides use the same f32 entries in f64 arithmetic, so
    // only summation order differs: 1e-12 relative.
    let fac = Rotation::new(8, 4, 4, RotationForm::Factored);
    let sp = Rotation::new(8, 4, 4, RotationForm::Sparse { threshold: 0.0 });
    let x = random(64, 1);
    let y = random(16, 2);
    let normal = Vec3::new(0.3, -0.5, 0.8).normalize();
    for rot in [&fac, &sp] {
        for nu in [0, 5, 15] {
            let mut rx = vec![0.0; 16];
            rot.apply(nu, &x, &mut rx);
            let mut rty = vec![0.0; 64];
            rot.apply_transpose_add(nu, &y, &mut rty);
            let (a, b) = (dot(&rx, &y), dot(&x, &rty));
            assert!((a - b).abs() < 1e-12 * a.abs().max(1.0), "nu {nu}: {a} {b}");
        }
        let mut rx = vec![0.0; 16];
        rot.apply_blend(&normal, &x, &mut rx);
        let mut rty = vec![0.0; 64];
        rot.apply_blend_transpose_add(&normal, &y, &mut rty);
        assert!((dot(&rx, &y) - dot(&x, &rty)).abs() < 1e-12);
    }
    // Factored and unthresholded sparse are the same matrix (the sparse one rounds the
    // entries of W_l S W_gᵀ to f32: 1e-6 relative on O(1) results).
    let all_f = fac.rotate_all(&x);
    let all_s = sp.rotate_all(&x);
    for (a, b) in all_f.iter().zip(&all_s) {
        assert!((a - b).abs() < 1e-5, "{a} {b}");
    }
    // The memory estimate is within 25% of the real figure (nnz per row varies).
    let real = Rotation::new(16, 8, 4, RotationForm::Factored).memory_bytes() as f64;
    let est = Rotation::estimate_memory_bytes(8, 4) as f64;
    assert!(
        (est / real - 1.0).abs() < 0.25,
        "estimate {est} real {real}"
    );
    // rotate_all is apply for each normal.
    let mut one = vec![0.0; 16];
    fac.apply(7, &x, &mut one);
    for (a, b) in one.iter().zip(&all_f[7 * 16..8 * 16]) {
        assert!((a - b).abs() < 1e-12);
    }
}

/// A global map of texel averages: smooth sky `1 + 0.5 z + 0.3 x` plus one sun texel.
#[test]
fn batched_texel_transpose_equals_one_vector_at_a_time_bit_for_bit() {
    // The batched form reads each resampling row once for all vectors but adds the same
    // terms in the same order per output, so its results must be identical (no tolerance),
    // for every batch size up to and past the group of 8, with exact zeros (occluded
    // texels, a narrow lobe's far side) mixed in.
    let rot = Rotation::new(16, 8, 4, RotationForm::Factored);
    let (nl2, ng2) = (64, 256);
    let normal = Vec3::new(-0.2, 0.7, 0.4).normalize();
    for k in [1, 3, 6, 8, 11] {
        let mut locals = random(k * nl2, 10 + k as u64);
        for (t, x) in locals.iter_mut().enumerate() {
            if t % 5 == 0 || (t / nl2 == 1 && t % nl2 > 20) {
                *x = 0.0;
            }
        }
        let mut one_by_one = vec![0.0; k * ng2];
        for (l, g) in locals
            .clone()
            .chunks_mut(nl2)
            .zip(one_by_one.chunks_mut(ng2))
        {
            rot.texel_transpose(&normal, l, g);
        }
        let mut batched = vec![f64::NAN; k * ng2];
        let mut scratch = Vec::new();
        rot.texel_transpose_many(&normal, &mut locals, &mut batched, &mut scratch);
        assert_eq!(batched, one_by_one, "k = {k}");
    }
}

fn sun_and_sky(n: usize, sun: usize, sun_value: f64) -> Vec<f64> {
    let g = SphereGrid::full(n);
    let mut m: Vec<f64> = (0..g.len())
        .map(|t| {
            let d = g.texel_dir(t);
            1.0 + 0.5 * d.z + 0.3 * d.x
        })
        .collect();
    m[sun] += sun_value;
    m
}

/// A seeded direction, normalised from the cube [−1, 1)³ (not uniform on the sphere;
/// the tests only need varied normals).
fn random_normal(rng: &mut Pcg64) -> Vec3 {
    Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize()
}

#[test]
fn rotation_conserves_energy_and_constants() {
    let (ng, nl) = (32, 16);
    let gg = SphereGrid::full(ng);
    let gl = SphereGrid::hemi(nl);
    let om_g = gg.solid_angles();
    let om_l = gl.solid_angles();
    let mut rng = Pcg64::seed_from_u64(9);
    for _ in 0..6 {
        let normal = random_normal(&mut rng);
        let rows = resampling_rows(&normal, ng, nl, DEFAULT_SUPERSAMPLE);
        let apply = |m: &[f64]| -> Vec<f64> {
            rows.iter()
                .map(|r| r.iter().map(|&(g, w)| w as f64 * m[g as usize]).sum())
                .collect()
        };
        // A one-texel sun 30,000× the sky, 30° above the local horizon or higher: its
        // energy Ω_g L survives exactly (column balancing; f32 weights: 1e-5).
        let frame = local_frame(&normal);
        for t in (0..gg.len())
            .filter(|&t| gg.texel_dir(t).dot(&frame[2]) > 0.5)
            .step_by(37)
        {
            let mut m = vec![0.0; gg.len()];
            m[t] = 3e4;
            let local = apply(&m);
            let e: f64 = local.iter().zip(&om_l).map(|(a, b)| a * b).sum();
            assert!(
                (e - 3e4 * om_g[t]).abs() < 1e-5 * 3e4 * om_g[t],
                "texel {t}: {e} vs {}",
                3e4 * om_g[t]
            );
        }
        // A constant sky stays constant up to the balancing's residual row error: 1%.
        let local = apply(&vec![1.0; gg.len()]);
        for (j, v) in local.iter().enumerate() {
            assert!((v - 1.0).abs() < 1e-2, "local texel {j}: {v}");
        }
    }
}

#[test]
fn blended_rotation_of_sun_and_sky_matches_direct_resampling() {
    // Normal grid 16² (spacing ≈ 0.2 rad): Eq. 6 blends four rotated copies of the map,
    // so the smooth sky (gradient ≤ 0.6 per radian) agrees with direct resampling at
    // the exact normal to ~0.6 × 0.2 / 2 ≈ 0.06 per texel, the sun's energy exactly
    // (each R_ν conserves it), and the sun's local direction to within a grid spacing.
    let (ng, nl, nn) = (32, 16, 16);
    let rot = Rotation::new(ng, nl, nn, RotationForm::Factored);
    let gg = SphereGrid::full(ng);
    let gl = SphereGrid::hemi(nl);
    let om_l = gl.solid_angles();
    let normal = Vec3::new(0.35, -0.2, 0.9).normalize();
    let frame = local_frame(&normal);
    let sun_dir = Vec3::new(0.1, 0.4, 0.9).normalize();
    let sun = gg.texel_of(&sun_dir);
    let sun_value = 3e4;
    let map = sun_and_sky(ng, sun, sun_value);
    let sky = sun_and_sky(ng, sun, 0.0);
    let direct_rows = resampling_rows(&normal, ng, nl, DEFAULT_SUPERSAMPLE);
    let direct = |m: &[f64]| -> Vec<f64> {
        direct_rows
            .iter()
            .map(|r| r.iter().map(|&(g, w)| w as f64 * m[g as usize]).sum())
            .collect()
    };
    let blended = |m: &[f64]| -> Vec<f64> {
        let mut h = m.to_vec();
        haar::forward(&mut h, ng);
        let mut out = vec![0.0; nl * nl];
        rot.apply_blend(&normal, &h, &mut out);
        haar::inverse(&mut out, nl);
        out
    };
    let (sky_b, sky_d) = (blended(&sky), direct(&sky));
    for j in 0..nl * nl {
        assert!(
            (sky_b[j] - sky_d[j]).abs() < 0.06,
            "sky texel {j}: {} vs {}",
            sky_b[j],
            sky_d[j]
        );
    }
    let (all_b, all_d) = (blended(&map), direct(&map));
    let sun_b: Vec<f64> = all_b.iter().zip(&sky_b).map(|(a, b)| a - b).collect();
    let sun_d: Vec<f64> = all_d.iter().zip(&sky_d).map(|(a, b)| a - b).collect();
    let energy = |m: &[f64]| m.iter().zip(&om_l).map(|(a, b)| a * b).sum::<f64>();
    let truth = sun_value * gg.solid_angle(sun);
    // f32 weights and the Haar round trip of a 3e4 spike: 1e-4 relative.
    assert!((energy(&sun_d) - truth).abs() < 1e-4 * truth);
    assert!((energy(&sun_b) - truth).abs() < 1e-4 * truth);
    let centroid = |m: &[f64]| -> Vec3 {
        (0..nl * nl)
            .map(|j| gl.texel_dir(j) * m[j] * om_l[j])
            .sum::<Vec3>()
            .normalize()
    };
    let want = crate::sphere::to_local(&frame, &gg.texel_dir(sun));
    assert!(
        centroid(&sun_d).angle(&want) < 0.05,
        "direct sun at {}",
        centroid(&sun_d).angle(&want)
    );
    assert!(
        centroid(&sun_b).angle(&want) < 0.2,
        "blended sun at {}",
        centroid(&sun_b).angle(&want)
    );
}

#[test]
fn splat_rotation_conserves_energy_places_the_sun_and_is_adjoint() {
    let (ng, nl) = (32, 32);
    let s = 3;
    assert_eq!(SplatRotation::default_supersample(64, 64), 4);
    assert_eq!(SplatRotation::default_supersample(32, 64), 8);
    let rot = SplatRotation::new(ng, nl, s);
    let gg = SphereGrid::full(ng);
    let gl = SphereGrid::hemi(nl);
    let om_g = gg.solid_angles();
    let om_l = gl.solid_angles();
    let mut rng = Pcg64::seed_from_u64(11);
    for _ in 0..5 {
        let normal = random_normal(&mut rng);
        let frame = local_frame(&normal);
        let mut local = vec![0.0; nl * nl];
        // A one-texel sun wholly above the horizon keeps its energy Ω_g L exactly (every
        // sub-texel lands in one local texel; f64 sums of s² terms: 1e-12), and its
        // footprint matches the exact overlap measured independently below.
        for g in (0..gg.len())
            .filter(|&g| gg.texel_dir(g).dot(&frame[2]) > 0.3)
            .step_by(41)
        {
            let mut m = vec![0.0; gg.len()];
            m[g] = 3e4;
            rot.resample(&normal, &m, &mut local);
            let e: f64 = local.iter().zip(&om_l).map(|(a, b)| a * b).sum();
            assert!(
                (e - 3e4 * om_g[g]).abs() < 1e-12 * 3e4 * om_g[g],
                "texel {g}: {e} vs {}",
                3e4 * om_g[g]
            );
            // Independent footprint: the overlap area of each local texel with global
            // texel g measured from the LOCAL side (16 × 16 sub-texels of every local
            // texel, nearest global texel).
            let overlap: Vec<f64> = (0..nl * nl)
                .map(|j| {
                    gl.sample_points(j, 16)
                        .filter(|(d, _)| gg.texel_of(&from_local(&frame, d)) == g)
                        .map(|(_, w)| w)
                        .sum()
                })
                .collect();
            let splat: Vec<f64> = local.iter().zip(&om_l).map(|(a, b)| a * b / 3e4).collect();
            let centroid = |a: &[f64]| -> Vec3 {
                (0..nl * nl)
                    .map(|j| gl.texel_dir(j) * a[j])
                    .sum::<Vec3>()
                    .normalize()
            };
            // Measured (5 normals × 10 texels, s = 3 at 32²/32²): centroids ≤ 0.012 rad
            // apart (a local texel is ≈ 0.08 rad wide), total-variation distance of the
            // two footprints ≤ 0.41 of Ω_g (the splat puts each of its 9 sub-texels in
            // one local texel). Allowed: 0.02 rad and 0.6.
            let angle = centroid(&splat).angle(&centroid(&overlap));
            let tv: f64 = splat
                .iter()
                .zip(&overlap)
                .map(|(a, b)| (a - b).abs())
                .sum::<f64>()
                / om_g[g];
            assert!(angle < 0.02 && tv < 0.6, "texel {g}: {angle} rad, tv {tv}");
        }
        // A constant sky: the total energy over the hemisphere is 2π up to the global
        // texels cut by the horizon (sub-texels of ≈ 0.04 rad: the horizon band they
        // miscount is ≈ 2π · 0.02 sr of 2π, 2%).
        rot.resample(&normal, &vec![1.0; gg.len()], &mut local);
        let e: f64 = local.iter().zip(&om_l).map(|(a, b)| a * b).sum();
        let two_pi = 2.0 * std::f64::consts::PI;
        assert!((e - two_pi).abs() < 0.02 * two_pi, "sky energy {e}");
        // Per texel the splat's counts are noisy (rms 16–23% here); averaged over 4 × 4
        // local texels (what a smooth lobe sees) within 10% measured: allowed 15%.
        for bj in 0..nl / 4 {
            for bi in 0..nl / 4 {
                let (mut a, mut w) = (0.0, 0.0);
                for jj in 0..4 {
                    for ii in 0..4 {
                        let t = (bj * 4 + jj) * nl + bi * 4 + ii;
                        a += local[t] * om_l[t];
                        w += om_l[t];
                    }
                }
                let centre = (bj * 4 + 2) * nl + bi * 4 + 2;
                if gl.texel_dir(centre).z > 0.3 {
                    assert!((a / w - 1.0).abs() < 0.15, "block ({bi}, {bj}): {}", a / w);
                }
            }
        }
        // ⟨R x, y⟩ = ⟨x, Rᵀ y⟩ (the same splat both ways; summation order only).
        let x = random(ng * ng, 3);
        let y = random(nl * nl, 4);
        let mut rx = vec![0.0; nl * nl];
        LocalRotation::apply(&rot, &normal, &x, &mut rx);
        let mut rty = vec![0.0; ng * ng];
        LocalRotation::apply_transpose_add(&rot, &normal, &y, &mut rty);
        let (a, b) = (dot(&rx, &y), dot(&x, &rty));
        assert!((a - b).abs() < 1e-10 * a.abs().max(1.0), "{a} {b}");
        // The three-channel path is the one-channel path per channel.
        let (g1, g2) = (random(ng * ng, 5), random(ng * ng, 6));
        let mut rgb = [Vec::new(), Vec::new(), Vec::new()];
        rot.resample_rgb(&normal, [&x, &g1, &g2], &mut rgb);
        for (c, g) in [&x, &g1, &g2].iter().enumerate() {
            rot.resample(&normal, g, &mut local);
            assert_eq!(local, rgb[c]);
        }
    }
}

#[test]
fn shared_geometry_matches_the_grids_and_the_horizon_rule() {
    // The normal-independent parts against the grids' own methods: every local sub-texel
    // (direction and exact solid angle) as `SphereGrid::sample_points` gives it, and the
    // interior set against the footprint rule evaluated directly from the texel centres
    // (a 3×3 block of centres above the horizon). Exact equality: the same f64 operations.
    let (ng, nl, s) = (16, 8, 3);
    let geo = ResamplingGeometry::new(ng, nl, s);
    let (gg, gl) = (SphereGrid::full(ng), SphereGrid::hemi(nl));
    for j in [0, 7, 27, 63] {
        let direct: Vec<(Vec3, f64)> = gl.sample_points(j, s).collect();
        assert_eq!(geo.subs_of(j), &direct[..], "local texel {j}");
    }
    let mut rng = Pcg64::seed_from_u64(11);
    for _ in 0..5 {
        let n = random_normal(&mut rng);
        let up = |t: usize| gg.texel_dir(t).dot(&n) > 0.0;
        let interior = geo.interior(&n);
        assert_eq!(interior.len(), gg.len());
        let mut count = 0;
        for (t, &inside) in interior.iter().enumerate() {
            let direct = up(t)
                && gg
                    .neighbors(t)
                    .iter()
                    .all(|&nb| up(nb) && gg.neighbors(nb).iter().all(|&nn| up(nn)));
            assert_eq!(inside, direct, "texel {t}");
            count += usize::from(direct);
        }
        // About a hemisphere less a border band: between a quarter and a half of the map.
        assert!(count > gg.len() / 4 && count < gg.len() / 2, "{count}");
    }
}
