//! The wavelet renderer with the light rotated once per precomputed frame and blended per
//! vertex ([`WaveletRenderer::with_frames`], used by `render_wavelet` for held-out
//! evaluation and renders) against the per-vertex rotation it replaces: same Eq. 6 sum, so
//! equal up to rounding, on a light with a one-texel sun (the sharpest case) and random
//! normals, views and visibility, for both rotation storage forms.

use crate::random::random_vertices;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use relight_cpc::render::wavelet::{RadianceScratch, WaveletRenderer};
use relight_cpc::sphere::envmap::OctEnv;
use relight_cpc::sphere::rotation::{Rotation, RotationForm};
use relight_cpc::transport::brdf::BasisBrdf;
use relight_cpc::transport::visibility::Visibility;
use relight_cpc::Vec3;

const NG: usize = 32;
const NL: usize = 16;
const NV: usize = 200;

#[test]
fn frame_blend_equals_per_vertex_rotation() {
    let mut rng = Pcg64::seed_from_u64(9);
    let (normals, dirs, vis) = random_vertices(&mut rng, NV, NL, 1, 0);
    let basis = [
        BasisBrdf::Lambert,
        BasisBrdf::Phong { exponent: 40.0 },
        BasisBrdf::Phong { exponent: 500.0 },
    ];
    let beta = [[0.5, 0.2, 0.1], [0.1, 0.3, 0.6], [0.2, 0.0, 0.4]];
    // A dim coloured sky plus a one-texel sun 1000× brighter.
    let mut rgb: Vec<[f32; 3]> = (0..NG * NG)
        .map(|t| [(t % 7) as f32 * 0.1, (t % 5) as f32 * 0.03, 0.1])
        .collect();
    rgb[NG * NG / 3 + 5] = [1000.0, 900.0, 800.0];
    let env = OctEnv { n: NG, rgb };
    for form in [
        RotationForm::Factored,
        RotationForm::Sparse { threshold: 0.0 },
    ] {
        let rot = Rotation::new(NG, NL, 8, form);
        let per_vertex = WaveletRenderer::new(&rot, &basis, &env).unwrap();
        let framed = WaveletRenderer::new(&rot, &basis, &env)
            .unwrap()
            .with_frames();
        assert!(framed.has_frames() && !per_vertex.has_frames());
        let mut max_abs = 0.0f64;
        let mut max_err = 0.0f64;
        let mut nonzero = 0;
        for p in 0..NV {
            let a = per_vertex.vertex_radiance(&normals[p], vis.vertex(p), &dirs[p], &beta);
            let b = framed.vertex_radiance(&normals[p], vis.vertex(p), &dirs[p], &beta);
            for c in 0..3 {
                assert!(b[c].is_finite());
                if form == RotationForm::Factored {
                    // Factored: the frame table holds exactly the per-frame resampled sums
                    // and the blend adds them in the same order as the per-vertex
                    // resampling, so the results are bitwise equal.
                    assert_eq!(a[c].to_bits(), b[c].to_bits(), "vertex {p} channel {c}");
                }
                max_abs = max_abs.max(a[c].abs());
                max_err = max_err.max((a[c] - b[c]).abs());
                nonzero += usize::from(a[c] > 0.0);
            }
        }
        // Sparse: the per-vertex path blends Haar coefficients and inverts once, the frame
        // path inverts per frame and blends texels: the same linear map in another order.
        // Rounding of a 16² Haar inverse (8 levels, values up to the sun's 1000) stays far
        // below 1e-9 of the largest radiance.
        assert!(
            max_err <= 1e-9 * max_abs,
            "{form:?}: max |Δ| {max_err:e} vs max radiance {max_abs:e}"
        );
        assert!(nonzero > NV, "{form:?}: only {nonzero} lit channels");
    }
}

#[test]
fn several_lights_equal_separate_renders_bit_for_bit() {
    // `new_many` + `vertex_radiance_all` computes each vertex's slices once for all lights
    // (what the evaluation's truth / half / mean renders share); each light's sums run in
    // the order of a renderer of that light alone, so the results must be bitwise equal.
    // Checked for the renderer's SplatRotation and the blended rotation with and without
    // frames, with a zero basis weight (skipped) and a degenerate normal (zero radiance).
    use relight_cpc::sphere::rotation::LocalRotation;
    use relight_cpc::sphere::rotation::SplatRotation;
    let mut rng = Pcg64::seed_from_u64(21);
    let (mut normals, dirs, vis) = random_vertices(&mut rng, NV, NL, 1, 0);
    normals[3] = Vec3::zeros();
    let basis = [
        BasisBrdf::Lambert,
        BasisBrdf::Ggx { alpha: 0.2 },
        BasisBrdf::Phong { exponent: 500.0 },
    ];
    let beta = [[0.5, 0.2, 0.1], [0.0, 0.0, 0.0], [0.2, 0.0, 0.4]];
    let envs: Vec<OctEnv> = (0..3)
        .map(|k| {
            let mut rgb: Vec<[f32; 3]> = (0..NG * NG)
                .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..1.0f32)))
                .collect();
            rgb[(NG * NG / 3 + 5 + 97 * k) % (NG * NG)] = [1000.0, 900.0, 800.0];
            OctEnv { n: NG, rgb }
        })
        .collect();
    let refs: Vec<&OctEnv> = envs.iter().collect();

    #[allow(clippy::too_many_arguments)]
    fn check<'a, R: LocalRotation>(
        rot: &'a R,
        frames: bool,
        basis: &'a [BasisBrdf],
        beta: &[[f64; 3]],
        envs: &[&OctEnv],
        normals: &[Vec3],
        dirs: &[Vec3],
        vis: &Visibility,
    ) {
        let frame = |r: WaveletRenderer<'a, R>| if frames { r.with_frames() } else { r };
        let many = frame(WaveletRenderer::new_many(rot, basis, envs).unwrap());
        assert_eq!(many.n_lights(), envs.len());
        let alone: Vec<_> = envs
            .iter()
            .map(|e| frame(WaveletRenderer::new(rot, basis, e).unwrap()))
            .collect();
        let mut out = vec![[0.0; 3]; envs.len()];
        // One scratch for every vertex, as a render thread reuses it.
        let mut scratch = RadianceScratch::default();
        let mut lit = 0;
        for p in 0..normals.len() {
            many.vertex_radiance_all(
                &mut scratch,
                &normals[p],
                vis.vertex(p),
                &dirs[p],
                beta,
                &mut out,
            );
            for (l, r) in alone.iter().enumerate() {
                let want = r.vertex_radiance(&normals[p], vis.vertex(p), &dirs[p], beta);
                for c in 0..3 {
                    assert_eq!(
                        out[l][c].to_bits(),
                        want[c].to_bits(),
                        "vertex {p} light {l} channel {c} (frames {frames})"
                    );
                    lit += usize::from(want[c] > 0.0);
                }
            }
            if p == 3 {
                assert_eq!(out, vec![[0.0; 3]; envs.len()], "degenerate normal");
            }
        }
        assert!(lit > normals.len(), "only {lit} lit channels");
    }
    let splat = SplatRotation::new(NG, NL, 4);
    check(&splat, false, &basis, &beta, &refs, &normals, &dirs, &vis);
    let blended = Rotation::new(NG, NL, 8, RotationForm::Factored);
    check(&blended, false, &basis, &beta, &refs, &normals, &dirs, &vis);
    check(&blended, true, &basis, &beta, &refs, &normals, &dirs, &vis);
    // No light is an error, not an empty render.
    assert!(WaveletRenderer::new_many(&splat, &basis, &[]).is_err());
}

#[test]
fn several_views_of_a_vertex_equal_each_views_own_renderer_bit_for_bit() {
    // `vertex_radiance_views` rotates the lights of every listed view into the vertex's
    // frame in one call and forms the slices per view; each view's values must be what a
    // renderer of that view's lights alone gives (`vertex_radiance_all`), bit for bit, for
    // the SplatRotation and the blended rotation with and without frames. Views: three
    // outgoing directions, under lights {0}, {1, 2} and {2} of one renderer, plus a view
    // listed with no light; a degenerate normal gives zeros.
    use relight_cpc::render::wavelet::VertexView;
    use relight_cpc::sphere::rotation::{LocalRotation, SplatRotation};
    let mut rng = Pcg64::seed_from_u64(33);
    let (mut normals, dirs, vis) = random_vertices(&mut rng, NV, NL, 3, 0);
    normals[5] = Vec3::zeros();
    let basis = [
        BasisBrdf::Lambert,
        BasisBrdf::Ggx { alpha: 0.1 },
        BasisBrdf::Phong { exponent: 50.0 },
    ];
    let beta = [[0.5, 0.2, 0.1], [0.3, 0.1, 0.0], [0.2, 0.0, 0.4]];
    let envs: Vec<OctEnv> = (0..3)
        .map(|k| {
            let mut rgb: Vec<[f32; 3]> = (0..NG * NG)
                .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..1.0f32)))
                .collect();
            rgb[(NG * NG / 4 + 31 * k) % (NG * NG)] = [500.0, 400.0, 300.0];
            OctEnv { n: NG, rgb }
        })
        .collect();
    let ranges = [0..1, 1..3, 3..3, 2..3];

    fn check<R: LocalRotation>(
        rot: &R,
        frames: bool,
        basis: &[BasisBrdf],
        beta: &[[f64; 3]],
        envs: &[OctEnv],
        ranges: &[std::ops::Range<usize>],
        (normals, dirs, vis): (&[Vec3], &[Vec3], &Visibility),
    ) -> usize {
        let refs: Vec<&OctEnv> = envs.iter().collect();
        let many = WaveletRenderer::new_many(rot, basis, &refs).unwrap();
        let many = if frames { many.with_frames() } else { many };
        let mut scratch = RadianceScratch::default();
        let mut lit = 0;
        for p in 0..normals.len() {
            // Three directions per vertex: its own and two others'.
            let wo = [
                dirs[p],
                dirs[(p + 1) % dirs.len()],
                dirs[(p + 7) % dirs.len()],
            ];
            let views: Vec<VertexView> = ranges
                .iter()
                .enumerate()
                .map(|(i, r)| VertexView {
                    wo_env: wo[i % 3],
                    lights: r.clone(),
                })
                .collect();
            let mut out = vec![[0.0; 3]; 4];
            many.vertex_radiance_views(
                &mut scratch,
                &normals[p],
                vis.vertex(p),
                beta,
                &views,
                &mut out,
            );
            let mut at = 0;
            for v in &views {
                let own: Vec<&OctEnv> = refs[v.lights.clone()].to_vec();
                if own.is_empty() {
                    continue;
                }
                let alone = WaveletRenderer::new_many(rot, basis, &own).unwrap();
                let alone = if frames { alone.with_frames() } else { alone };
                let mut want = vec![[0.0; 3]; own.len()];
                let mut s = RadianceScratch::default();
                alone.vertex_radiance_all(
                    &mut s,
                    &normals[p],
                    vis.vertex(p),
                    &v.wo_env,
                    beta,
                    &mut want,
                );
                for (l, w) in want.iter().enumerate() {
                    for c in 0..3 {
                        assert_eq!(
                            out[at + l][c].to_bits(),
                            w[c].to_bits(),
                            "vertex {p} light {l}"
                        );
                        lit += usize::from(w[c] > 0.0);
                    }
                }
                at += own.len();
            }
            if p == 5 {
                assert_eq!(out, vec![[0.0; 3]; 4], "degenerate normal");
            }
        }
        lit
    }
    let data = (&normals[..], &dirs[..], &vis);
    let splat = SplatRotation::new(NG, NL, 4);
    assert!(check(&splat, false, &basis, &beta, &envs, &ranges, data) > NV * 4);
    let blended = Rotation::new(NG, NL, 8, RotationForm::Factored);
    assert!(check(&blended, false, &basis, &beta, &envs, &ranges, data) > NV * 4);
    assert!(check(&blended, true, &basis, &beta, &envs, &ranges, data) > NV * 4);
}

#[test]
fn interleaved_footprint_walk_equals_the_per_light_walk_bit_for_bit() {
    // The renderer's walk reads all lights interleaved texel-major
    // (`SplatRotation::resample_interleaved`); the reference is the walk over one array per
    // light and channel (`resample_rgb_many`). Every output is the same sum of the same
    // products in the same order, so the comparison is exact, for spans in any order and
    // a subset of the lights, on random normals and lights with a one-texel sun.
    use relight_cpc::sphere::rotation::SplatRotation;
    let mut rng = Pcg64::seed_from_u64(41);
    let (normals, _, _) = random_vertices(&mut rng, 40, NL, 1, 0);
    let rot = SplatRotation::new(NG, NL, 2);
    let lights: Vec<[Vec<f64>; 3]> = (0..3)
        .map(|k| {
            [0, 1, 2].map(|c| {
                let mut ch: Vec<f64> = (0..NG * NG).map(|_| rng.random_range(0.0..1.0)).collect();
                ch[(97 * k + c) % (NG * NG)] = 1000.0;
                ch
            })
        })
        .collect();
    let width = 3 * lights.len();
    let mut global = vec![0.0; NG * NG * width];
    for (l, light) in lights.iter().enumerate() {
        for (c, ch) in light.iter().enumerate() {
            for (g, v) in ch.iter().enumerate() {
                global[g * width + 3 * l + c] = *v;
            }
        }
    }
    let mut buffer = Vec::new();
    let mut checked = 0;
    for n in &normals {
        // Lights 2 then 0 (light 1 not asked for).
        let order = [2, 0];
        let spans: Vec<_> = order.iter().map(|&l| 3 * l..3 * l + 3).collect();
        rot.resample_interleaved(n, &global, width, &spans, &mut buffer);
        let refs: Vec<[&[f64]; 3]> = order
            .iter()
            .map(|&l| [0, 1, 2].map(|c| lights[l][c].as_slice()))
            .collect();
        let mut want = vec![[vec![], vec![], vec![]]; order.len()];
        rot.resample_rgb_many(n, &refs, &mut want);
        let w = 3 * order.len();
        for (i, light) in want.iter().enumerate() {
            for (c, ch) in light.iter().enumerate() {
                for (j, v) in ch.iter().enumerate() {
                    assert_eq!(
                        buffer[j * w + 3 * i + c].to_bits(),
                        v.to_bits(),
                        "texel {j}"
                    );
                    checked += usize::from(*v > 0.0);
                }
            }
        }
    }
    assert!(
        checked > normals.len() * NL * NL,
        "only {checked} lit texels"
    );
}
