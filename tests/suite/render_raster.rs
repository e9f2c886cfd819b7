//! Rasteriser and image writers against analytic geometry (issue 4).

use nalgebra::Rotation3;
use relight_cpc::import::colmap::{Camera, CameraId, Image, ImageId};
use relight_cpc::import::mesh::Mesh;
use relight_cpc::render::{
    interpolate_scalar, rasterize, shade_vertices, srgb_encode, write_exr, write_png,
};
use relight_cpc::Vec3;

use crate::octahedron::octahedron;

const W: u32 = 80;
const H: u32 = 60;
const F: f64 = 70.0;
const CX: f64 = 40.0;
const CY: f64 = 30.0;

fn camera() -> Camera {
    Camera::pinhole(CameraId(1), W, H, F, F, CX, CY)
}

/// Camera at the world origin looking down +z (X_cam = X_world).
fn image_identity() -> Image {
    Image::from_pose(
        ImageId(1),
        "a.png",
        CameraId(1),
        &Rotation3::identity(),
        &Vec3::zeros(),
    )
}

/// Quad `a b c d` (two triangles) as a mesh.
fn quad(p: [Vec3; 4]) -> Mesh {
    let (m, _) = Mesh::from_parts(p.to_vec(), vec![[0, 1, 2], [0, 2, 3]]);
    m
}

/// The ray through pixel centre `(x + ½, y + ½)` in camera coordinates (z = 1).
fn pixel_ray(x: u32, y: u32) -> Vec3 {
    Vec3::new((x as f64 + 0.5 - CX) / F, (y as f64 + 0.5 - CY) / F, 1.0)
}

#[test]
fn perspective_correct_interpolation_on_a_tilted_quad() {
    // A quad on the tilted plane z = 3 + 0.8 x + 0.3 y, strongly foreshortened. A value
    // linear in 3D position, v(p) = 2 p.x − p.y + 0.5 p.z, interpolated across the
    // triangles must equal v at the ray–plane intersection (screen-space interpolation
    // would be off by several percent here), and the depth must equal the intersection's
    // z. Tolerance: f32 barycentrics and depth, 1e-4 relative.
    let z = |x: f64, y: f64| 3.0 + 0.8 * x + 0.3 * y;
    let c = [(-1.0, -0.8), (1.0, -0.8), (1.0, 0.8), (-1.0, 0.8)];
    let mesh = quad(c.map(|(x, y)| Vec3::new(x, y, z(x, y))));
    let value = |p: &Vec3| 2.0 * p.x - p.y + 0.5 * p.z;
    let vals: Vec<f32> = mesh.positions.iter().map(|p| value(p) as f32).collect();
    let r = rasterize(&mesh, &camera(), &image_identity());
    let interp = interpolate_scalar(&r, &mesh, &vals);
    let mut inside = 0;
    for y in 0..H {
        for x in 0..W {
            let k = (y * W + x) as usize;
            let d = pixel_ray(x, y);
            // Intersect t d with the plane: t = 3 / (1 − 0.8 d.x − 0.3 d.y).
            let t = 3.0 / (1.0 - 0.8 * d.x - 0.3 * d.y);
            let p = d * t;
            let strictly_inside = p.x.abs() < 0.98 && p.y.abs() < 0.78;
            let outside = p.x.abs() > 1.02 || p.y.abs() > 0.82;
            if strictly_inside {
                inside += 1;
                assert_ne!(r.face[k], u32::MAX, "hole at ({x}, {y})");
                let v = value(&p);
                assert!(
                    (interp[k] as f64 - v).abs() < 1e-4 * v.abs().max(1.0),
                    "({x},{y})"
                );
                assert!((r.depth[k] as f64 - p.z).abs() < 1e-4 * p.z);
                let b = r.bary[k];
                assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-5);
            } else if outside {
                assert_eq!(r.face[k], u32::MAX, "spill at ({x}, {y})");
                assert!(interp[k].is_nan());
            }
        }
    }
    assert!(inside > 500);
}

#[test]
fn z_buffer_keeps_the_nearest_surface_and_coverage_matches_the_projection() {
    // Two fronto-parallel squares: the far one (z = 5, half-size 1.2) and a near one
    // (z = 2, half-size 0.31, shifted right). A square at depth z with half-size s covers
    // the pixel centres with |x + ½ − c_x| ≤ F s / z (and likewise in y): count them
    // (sizes chosen so that no pixel centre lies on an edge).
    let sq = |cx: f64, s: f64, z: f64| {
        [
            Vec3::new(cx - s, -s, z),
            Vec3::new(cx + s, -s, z),
            Vec3::new(cx + s, s, z),
            Vec3::new(cx - s, s, z),
        ]
    };
    let far = sq(0.0, 1.2, 5.0);
    let near = sq(0.1, 0.31, 2.0);
    let mut pts = far.to_vec();
    pts.extend_from_slice(&near);
    // Near faces listed first, so a z-buffer is needed to get it right.
    let faces = vec![[4, 5, 6], [4, 6, 7], [0, 1, 2], [0, 2, 3]];
    let (mesh, _) = Mesh::from_parts(pts, faces);
    let r = rasterize(&mesh, &camera(), &image_identity());
    let count = |cx: f64, s: f64, z: f64| {
        let (hx, hy) = (F * s / z, F * s / z);
        let u0 = CX + F * cx / z;
        let nx = (0..W)
            .filter(|&x| (x as f64 + 0.5 - u0).abs() <= hx)
            .count();
        let ny = (0..H)
            .filter(|&y| (y as f64 + 0.5 - CY).abs() <= hy)
            .count();
        nx * ny
    };
    let n_near = r.face.iter().filter(|&&f| f <= 1).count();
    let n_all = r.covered();
    assert_eq!(n_near, count(0.1, 0.31, 2.0));
    assert_eq!(n_all, count(0.0, 1.2, 5.0));
    for (k, &f) in r.face.iter().enumerate() {
        if f != u32::MAX {
            let want = if f <= 1 { 2.0 } else { 5.0 };
            assert!((r.depth[k] - want).abs() < 1e-5);
        }
    }
    // Shading with per-vertex colours: near square red, far square blue.
    let mut rgb = vec![[0.0, 0.0, 1.0f32]; 4];
    rgb.extend(vec![[1.0, 0.0, 0.0f32]; 4]);
    let img = shade_vertices(&r, &mesh, &rgb);
    for (k, &f) in r.face.iter().enumerate() {
        let want = match f {
            u32::MAX => [0.0; 3],
            0 | 1 => [1.0, 0.0, 0.0],
            _ => [0.0, 0.0, 1.0],
        };
        for c in 0..3 {
            assert!((img[k][c] - want[c]).abs() < 1e-5);
        }
    }
}

#[test]
fn png_and_exr_round_trip() {
    let dir = std::env::temp_dir().join(format!("relight-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (w, h) = (5u32, 3u32);
    let rgb: Vec<[f32; 3]> = (0..w * h)
        .map(|k| [k as f32 / 15.0, 0.5, 2.0 * k as f32])
        .collect();
    let mask: Vec<bool> = (0..w * h).map(|k| k % 4 != 0).collect();

    // sRGB curve at known points (IEC 61966-2-1): 0.5 → 0.735357, 0.0031308 → 0.0404500.
    assert!((srgb_encode(0.5) - 0.735_357).abs() < 1e-5);
    assert!((srgb_encode(0.003_130_8) - 0.040_450).abs() < 1e-5);
    assert!((srgb_encode(2.0) - 1.0).abs() < 1e-6);

    let png = dir.join("a.png");
    write_png(&png, w, h, &rgb, Some(&mask), 1.0).unwrap();
    let back = image::open(&png).unwrap().to_rgba8();
    assert_eq!(back.dimensions(), (w, h));
    for (k, px) in back.pixels().enumerate() {
        // 0.5 linear encodes to round(0.735357 · 255) = 188.
        assert_eq!(px[1], 188);
        assert_eq!(px[3], if mask[k] { 255 } else { 0 });
        let want = (srgb_encode(rgb[k][0]) * 255.0).round() as u8;
        assert_eq!(px[0], want);
    }
    // Exposure scales linear values before encoding: 0.5 · 0.5 = 0.25 → 137.
    write_png(&png, w, h, &rgb, None, 0.5).unwrap();
    let back = image::open(&png).unwrap().to_rgb8();
    assert_eq!(back.get_pixel(0, 0)[1], 137);

    let exr_path = dir.join("a.exr");
    write_exr(&exr_path, w, h, &rgb, Some(&mask)).unwrap();
    let img = exr::prelude::read_first_rgba_layer_from_file(
        &exr_path,
        |res, _| vec![[0.0f32; 4]; res.width() * res.height()],
        move |buf, pos, (r, g, b, a): (f32, f32, f32, f32)| {
            buf[pos.y() * 5 + pos.x()] = [r, g, b, a];
        },
    )
    .unwrap();
    let px = &img.layer_data.channel_data.pixels;
    for k in 0..(w * h) as usize {
        assert_eq!(&px[k][..3], &rgb[k][..]);
        assert_eq!(px[k][3], if mask[k] { 1.0 } else { 0.0 });
    }
    // Size mismatches are errors naming the file.
    let e = write_png(&png, w + 1, h, &rgb, None, 1.0).unwrap_err();
    assert!(e.to_string().contains("a.png"));
    std::fs::remove_dir_all(&dir).ok();
}

/// The white furnace: a convex octahedron (every vertex open, 8² visibility), a constant
/// light `L = (2, 1, 0.5)` on a 16² map, Lambert with albedo `a = (0.5, 0.25, 0.8)`; every
/// vertex's radiance is `a·L` (up to the quadrature, well within 1%).
struct Furnace {
    mesh: Mesh,
    vis: relight_cpc::transport::visibility::Visibility,
    rot: relight_cpc::sphere::rotation::Rotation,
    env: relight_cpc::sphere::envmap::OctEnv,
    beta: Vec<[f64; 3]>,
    frame: nalgebra::Matrix3<f64>,
}

const FURNACE_ALBEDO: [f64; 3] = [0.5, 0.25, 0.8];
const FURNACE_LIGHT: [f32; 3] = [2.0, 1.0, 0.5];

impl Furnace {
    fn new() -> Self {
        use relight_cpc::observe::trace::SceneBvh;
        use relight_cpc::sphere::rotation::{Rotation, RotationForm};
        let mesh = octahedron(Vec3::new(0.0, 0.0, 5.0), 1.0);
        let frame = nalgebra::Matrix3::identity();
        let vis = relight_cpc::transport::visibility::compute(
            &mesh,
            &SceneBvh::new(&mesh),
            &frame,
            8,
            1,
            0,
        );
        Furnace {
            vis,
            rot: Rotation::new(16, 8, 8, RotationForm::Factored),
            env: relight_cpc::sphere::envmap::OctEnv {
                n: 16,
                rgb: vec![FURNACE_LIGHT; 256],
            },
            beta: vec![FURNACE_ALBEDO; mesh.positions.len()],
            mesh,
            frame,
        }
    }

    fn model(&self) -> relight_cpc::render::WaveletModel<'_> {
        relight_cpc::render::WaveletModel {
            mesh: &self.mesh,
            normals_env: &self.mesh.normals,
            vis: &self.vis,
            env_from_world: &self.frame,
            basis: &[relight_cpc::transport::brdf::BasisBrdf::Lambert],
            beta: &self.beta,
        }
    }
}

#[test]
fn given_vertex_radiance_is_kept_and_the_other_vertices_rendered() {
    // The furnace of the test below (every vertex's radiance is a·L within 1%), with the
    // radiance of three vertices given (a run's training renders pass the estimator's
    // predictions): the image must be the interpolation of those given values and a·L at the
    // other vertices (1%, the furnace's tolerance). With nothing given the result must be
    // the plain render, bit for bit; a `given` of the wrong length is an error.
    use relight_cpc::render::{shade_wavelet, shade_wavelet_known};
    let f = Furnace::new();
    let (model, env, rot) = (f.model(), &f.env, &f.rot);
    let mesh = &f.mesh;
    let image = image_identity();
    let raster = rasterize(mesh, &camera(), &image);
    assert!(raster.covered() > 200);
    let plain = shade_wavelet(&model, &raster, &image, &[env], rot)
        .unwrap()
        .pop()
        .unwrap();
    let none = shade_wavelet_known(&model, &raster, &image, env, rot, &[None; 6]).unwrap();
    assert!(plain
        .iter()
        .zip(&none)
        .all(|(p, q)| (0..3).all(|c| p[c].to_bits() == q[c].to_bits())));

    let mark = [7.0f32, 8.0, 9.0];
    let given: Vec<Option<[f32; 3]>> = (0..6).map(|x| (x < 3).then_some(mark)).collect();
    let rgb = shade_wavelet_known(&model, &raster, &image, env, rot, &given).unwrap();
    let furnace: [f32; 3] = [0, 1, 2].map(|c| FURNACE_ALBEDO[c] as f32 * FURNACE_LIGHT[c]);
    let per_vertex: Vec<[f32; 3]> = (0..6).map(|x| if x < 3 { mark } else { furnace }).collect();
    let want = shade_vertices(&raster, mesh, &per_vertex);
    let mut marked = 0;
    for (k, &f) in raster.face.iter().enumerate() {
        if f == u32::MAX {
            continue;
        }
        for c in 0..3 {
            assert!(
                (rgb[k][c] - want[k][c]).abs() <= 1e-2 * want[k][c],
                "pixel {k}: {:?} vs {:?}",
                rgb[k],
                want[k]
            );
        }
        marked += usize::from(rgb[k][0] > 2.0);
    }
    assert!(marked > 50, "the given values reach only {marked} pixels");
    assert!(shade_wavelet_known(&model, &raster, &image, env, rot, &[None; 5]).is_err());
}

#[test]
fn wavelet_render_of_a_white_furnace_is_albedo_times_radiance() {
    // Convex octahedron (every vertex open), Lambert with RGB albedo a, constant light L:
    // every object pixel must be a·L (the furnace test). Error sources: the Lambert
    // slice quadrature at 8² (≈ 6e-4) and the balanced rotation's row error for a constant
    // sky (rotation tests); allow 1%.
    use relight_cpc::render::render_wavelet;
    let f = Furnace::new();
    assert_eq!(f.vis.open_count(), 6);
    let model = f.model();
    let (r, rgb) = render_wavelet(&model, &f.env, &f.rot, &camera(), &image_identity()).unwrap();
    assert!(r.covered() > 200);
    let want = [2.0 * 0.5, 0.25, 0.4];
    for (k, &f) in r.face.iter().enumerate() {
        if f != u32::MAX {
            for c in 0..3 {
                assert!(
                    (rgb[k][c] as f64 - want[c]).abs() < 1e-2 * want[c],
                    "{:?}",
                    rgb[k]
                );
            }
        }
    }
}

#[test]
fn shade_views_equals_each_views_own_render_bit_for_bit() {
    // `shade_views` shades every view of a list in one vertex-major pass (a vertex's
    // footprint walked once for the lights of all views that show it, its slices once per
    // view). Each of its images must be what `shade_wavelet` makes for that view alone,
    // bit for bit: with the renderer's per-normal SplatRotation every light's local texels
    // are accumulated in the same order whatever else is walked with them, and the slices
    // and sums per view are the same code. Three views of the octahedron from different
    // poses, under one, two and three non-constant lights, glossy lobes with per-vertex
    // weights (one zero weight, skipped). The furnace view (constant light, Lambert) must
    // also give a·L within the furnace's 1% through `shade_views` (the test above: its
    // blended rotation and camera).
    use relight_cpc::render::{shade_views, shade_wavelet, ViewToShade, WaveletModel};
    use relight_cpc::sphere::envmap::OctEnv;
    use relight_cpc::sphere::rotation::SplatRotation;
    use relight_cpc::transport::brdf::BasisBrdf;
    let f = Furnace::new();
    let rot = SplatRotation::new(16, 8, 2);
    let basis = [
        BasisBrdf::Lambert,
        BasisBrdf::Ggx { alpha: 0.2 },
        BasisBrdf::Phong { exponent: 50.0 },
    ];
    let beta: Vec<[f64; 3]> = (0..f.mesh.positions.len() * 3)
        .map(|i| match i % 3 {
            0 => [0.5, 0.25, 0.8],
            1 if i == 4 => [0.0; 3],
            1 => [0.1 * (i % 5) as f64, 0.2, 0.05],
            _ => [0.02, 0.03 * (i % 4) as f64, 0.01],
        })
        .collect();
    let model = WaveletModel {
        basis: &basis,
        beta: &beta,
        ..f.model()
    };
    let lights: Vec<OctEnv> = (0..3)
        .map(|k| {
            let mut rgb: Vec<[f32; 3]> = (0..256)
                .map(|t| [(t % 7) as f32 * 0.1, (t % (5 + k)) as f32 * 0.03, 0.2])
                .collect();
            rgb[(40 + 67 * k) % 256] = [300.0, 250.0, 200.0];
            OctEnv { n: 16, rgb }
        })
        .collect();
    let pose = |angle: f64| {
        // Turned about y around the octahedron's centre (0, 0, 5): it stays in view.
        let r = Rotation3::from_axis_angle(&Vec3::y_axis(), angle);
        let centre = Vec3::new(0.0, 0.0, 5.0);
        let t = centre - r * centre;
        Image::from_pose(ImageId(1), "v.png", CameraId(1), &r, &t)
    };
    let images = [image_identity(), pose(0.4), pose(-0.7)];
    let rasters: Vec<_> = images
        .iter()
        .map(|i| rasterize(&f.mesh, &camera(), i))
        .collect();
    let envs: [Vec<&OctEnv>; 3] = [
        vec![&lights[0]],
        vec![&lights[1], &lights[2]],
        vec![&lights[2], &lights[0], &lights[1]],
    ];
    let views: Vec<ViewToShade> = (0..3)
        .map(|i| ViewToShade {
            raster: &rasters[i],
            image: &images[i],
            envs: envs[i].clone(),
        })
        .collect();
    let shaded = shade_views(&model, &views, &rot).unwrap();
    let mut lit = 0;
    for i in 0..3 {
        assert!(rasters[i].covered() > 200, "view {i} misses the object");
        let got = shaded.images(i, &rasters[i], &f.mesh);
        let want = shade_wavelet(&model, &rasters[i], &images[i], &envs[i], &rot).unwrap();
        assert_eq!(got.len(), want.len());
        for (l, (g, w)) in got.iter().zip(&want).enumerate() {
            for (k, (a, b)) in g.iter().zip(w).enumerate() {
                for c in 0..3 {
                    assert_eq!(
                        a[c].to_bits(),
                        b[c].to_bits(),
                        "view {i} light {l} pixel {k}"
                    );
                    lit += usize::from(a[c] > 0.0);
                }
            }
        }
    }
    assert!(lit > 1000, "only {lit} lit pixel channels");

    let furnace = f.model();
    let one = [ViewToShade {
        raster: &rasters[0],
        image: &images[0],
        envs: vec![&f.env],
    }];
    let rgb = shade_views(&furnace, &one, &f.rot)
        .unwrap()
        .images(0, &rasters[0], &f.mesh);
    let want = [2.0 * 0.5, 0.25, 0.4];
    for (k, &face) in rasters[0].face.iter().enumerate() {
        if face != u32::MAX {
            for c in 0..3 {
                let v = rgb[0][k][c] as f64;
                assert!((v - want[c]).abs() < 1e-2 * want[c], "{:?}", rgb[0][k]);
            }
        }
    }
}
