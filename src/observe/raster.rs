//! The mesh as one camera sees it: per pixel the visible face, its barycentrics and depth
//! (a z-buffer), and per-vertex values interpolated across the visible triangles. Used to
//! find the vertices a photo sees near depth edges ([`super::margins`]) and to draw every
//! image ([`crate::render`]).
//!
//! Rasterisation: every vertex is taken to camera coordinates (`X_cam = R X + t`,
//! docs/conventions.md) and projected with [`Camera::project`] (lens distortion applied per vertex, so straight
//! edges stay straight: fine for triangles small in the image). A pixel `(x, y)` is covered
//! when its centre `(x + ½, y + ½)` lies inside the projected triangle (edge functions,
//! inclusive). Barycentrics are perspective-correct: with screen-space weights `l_i` and
//! camera depths `z_i`, `b_i = (l_i / z_i) / Σ_j (l_j / z_j)` and the depth is
//! `1 / Σ_j (l_j / z_j)`; the nearest depth wins (z-buffer). Triangles with a vertex behind
//! the camera (`z ≤ 0`) or that do not project are skipped.

use rayon::prelude::*;

use crate::import::colmap::{Camera, Image};
use crate::import::mesh::Mesh;

/// The visible surface per pixel of one camera.
#[derive(Debug, Clone)]
pub struct Raster {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Face visible at each pixel (row-major), `u32::MAX` for background.
    pub face: Vec<u32>,
    /// Perspective-correct barycentrics of the face's three vertices at each pixel.
    pub bary: Vec<[f32; 3]>,
    /// Camera-space depth `z` at each pixel (`f32::INFINITY` for background).
    pub depth: Vec<f32>,
}

impl Raster {
    /// Object mask: `true` where a face is visible.
    pub fn mask(&self) -> Vec<bool> {
        self.face.iter().map(|&f| f != u32::MAX).collect()
    }

    /// Number of pixels covered by the object.
    pub fn covered(&self) -> usize {
        self.face.iter().filter(|&&f| f != u32::MAX).count()
    }
}

/// A vertex projected into the image: pixel coordinates and camera depth.
type Projected = Option<[f64; 3]>;

/// Rasterise `mesh` into the view of `image` taken with `camera`.
pub fn rasterize(mesh: &Mesh, camera: &Camera, image: &Image) -> Raster {
    let projected: Vec<Projected> = mesh
        .positions
        .par_iter()
        .map(|p| {
            let c = image.cam_from_world_point(p);
            if c.z.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return None;
            }
            camera.project(&c).map(|px| [px[0], px[1], c.z])
        })
        .collect();
    rasterize_projected(camera.width, camera.height, &projected, &mesh.faces)
}

/// Rasterise triangles whose vertices are already projected (`[x, y, depth]` in pixels and
/// camera depth, `None` when behind the camera). The kernel behind [`rasterize`].
pub fn rasterize_projected(
    width: u32,
    height: u32,
    projected: &[Projected],
    faces: &[[u32; 3]],
) -> Raster {
    let (w, h) = (width as usize, height as usize);
    let tris = screen_triangles(w, h, projected, faces);
    let mut face = vec![u32::MAX; w * h];
    let mut bary = vec![[0.0f32; 3]; w * h];
    let mut depth = vec![f32::INFINITY; w * h];
    face.par_chunks_mut(BAND * w.max(1))
        .zip(bary.par_chunks_mut(BAND * w.max(1)))
        .zip(depth.par_chunks_mut(BAND * w.max(1)))
        .enumerate()
        .for_each(|(band, ((face, bary), depth))| {
            let rows = band * BAND..(band * BAND + BAND).min(h);
            let mut out = BandOut { face, bary, depth };
            rasterize_band(&tris, rows, w, &mut out);
        });
    Raster {
        width,
        height,
        face,
        bary,
        depth,
    }
}

/// Image rows per parallel band of the z-buffer.
const BAND: usize = 16;

/// A projected triangle with its bounding box of pixel centres.
struct Tri {
    face: u32,
    p: [[f64; 3]; 3],
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

/// The faces whose three vertices project, with the pixel centres `x + ½` their box holds
/// inside the `w × h` image (faces without any are skipped).
fn screen_triangles(w: usize, h: usize, projected: &[Projected], faces: &[[u32; 3]]) -> Vec<Tri> {
    faces
        .iter()
        .enumerate()
        .filter_map(|(fi, f)| {
            let mut p = [[0.0; 3]; 3];
            for k in 0..3 {
                p[k] = (*projected.get(f[k] as usize)?)?;
            }
            let xmin = p.iter().map(|q| q[0]).fold(f64::INFINITY, f64::min);
            let xmax = p.iter().map(|q| q[0]).fold(f64::NEG_INFINITY, f64::max);
            let ymin = p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min);
            let ymax = p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max);
            // Pixel centres x + 0.5 inside [xmin, xmax].
            let x0 = (xmin - 0.5).ceil().max(0.0);
            let x1 = (xmax - 0.5).floor().min(w as f64 - 1.0);
            let y0 = (ymin - 0.5).ceil().max(0.0);
            let y1 = (ymax - 0.5).floor().min(h as f64 - 1.0);
            if !(x0 <= x1 && y0 <= y1) {
                return None;
            }
            Some(Tri {
                face: fi as u32,
                p,
                x0: x0 as usize,
                x1: x1 as usize,
                y0: y0 as usize,
                y1: y1 as usize,
            })
        })
        .collect()
}

/// One band's slices of the raster's arrays (rows `rows` of a `w`-wide image).
struct BandOut<'a> {
    face: &'a mut [u32],
    bary: &'a mut [[f32; 3]],
    depth: &'a mut [f32],
}

/// The z-buffer over image rows `rows`: every triangle crossing them, each covered pixel
/// centre (edge functions, inclusive with a rounding margin) taking the nearest
/// perspective-correct depth and barycentrics.
fn rasterize_band(tris: &[Tri], rows: std::ops::Range<usize>, w: usize, out: &mut BandOut) {
    const EDGE_EPS: f64 = 1e-9;
    let (by0, by1) = (rows.start, rows.end);
    let mut zbuf = vec![f64::INFINITY; (by1 - by0) * w];
    for t in tris {
        if t.y1 < by0 || t.y0 >= by1 {
            continue;
        }
        let [a, b, c] = t.p;
        // Twice the signed area; edge functions normalised by it.
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area == 0.0 || !area.is_finite() {
            continue;
        }
        let inv = 1.0 / area;
        for y in t.y0.max(by0)..=t.y1.min(by1 - 1) {
            let py = y as f64 + 0.5;
            for x in t.x0..=t.x1 {
                let px = x as f64 + 0.5;
                let l0 = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) * inv;
                let l1 = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) * inv;
                let l2 = 1.0 - l0 - l1;
                // Inclusive, with a rounding margin so that pixel centres on an edge shared
                // by two triangles are never dropped by both.
                if l0 < -EDGE_EPS || l1 < -EDGE_EPS || l2 < -EDGE_EPS {
                    continue;
                }
                // Perspective-correct weights (1/z is affine in screen space).
                let (l0, l1, l2) = (l0.max(0.0), l1.max(0.0), l2.max(0.0));
                let q = [l0 / a[2], l1 / b[2], l2 / c[2]];
                let s = q[0] + q[1] + q[2];
                let z = 1.0 / s;
                let k = (y - by0) * w + x;
                if z < zbuf[k] {
                    zbuf[k] = z;
                    out.face[k] = t.face;
                    out.bary[k] = [(q[0] * z) as f32, (q[1] * z) as f32, (q[2] * z) as f32];
                    out.depth[k] = z as f32;
                }
            }
        }
    }
}

/// Interpolate per-vertex RGB across the visible triangles (linear values; background 0).
pub fn shade_vertices(raster: &Raster, mesh: &Mesh, vertex_rgb: &[[f32; 3]]) -> Vec<[f32; 3]> {
    raster
        .face
        .par_iter()
        .zip(&raster.bary)
        .map(|(&f, b)| {
            let Some(tri) = mesh.faces.get(f as usize) else {
                return [0.0; 3];
            };
            let mut out = [0.0f32; 3];
            for k in 0..3 {
                let v = vertex_rgb.get(tri[k] as usize).copied().unwrap_or([0.0; 3]);
                for c in 0..3 {
                    out[c] += b[k] * v[c];
                }
            }
            out
        })
        .collect()
}

/// Interpolate any per-vertex scalar across the visible triangles (background `NaN`).
pub fn interpolate_scalar(raster: &Raster, mesh: &Mesh, vertex_value: &[f32]) -> Vec<f32> {
    raster
        .face
        .par_iter()
        .zip(&raster.bary)
        .map(|(&f, b)| {
            let Some(tri) = mesh.faces.get(f as usize) else {
                return f32::NAN;
            };
            (0..3)
                .map(|k| {
                    b[k] * vertex_value
                        .get(tri[k] as usize)
                        .copied()
                        .unwrap_or(f32::NAN)
                })
                .sum()
        })
        .collect()
}
