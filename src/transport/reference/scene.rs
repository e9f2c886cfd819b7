//! A whole reference scene (mesh, reflectance, environment, caster) rendered per vertex or per pixel through a pinhole camera.

use super::*;

/// A mesh with reflectance under one environment, ready for the reference renderer.
pub struct ReferenceScene<'a, C: RayCaster + ?Sized> {
    /// Vertex positions (world).
    pub positions: &'a [Vec3],
    /// Unit vertex normals (shading normals, interpolated across triangles).
    pub normals: &'a [Vec3],
    /// Triangles, counter-clockwise seen from outside.
    pub faces: &'a [[u32; 3]],
    /// Materials and per-vertex weights.
    pub reflectance: &'a Reflectance,
    /// The environment.
    pub env: &'a Environment,
    /// Ray caster over the same triangles.
    pub caster: &'a C,
    /// Shadow-ray origin offset (world units), e.g. 1e-4 × the bounding-box diagonal.
    pub offset: f64,
}

/// Seeded per-item random stream: PCG32 with the item index as its stream id.
pub(crate) fn stream(seed: u64, item: u64) -> Pcg32 {
    Pcg32::new(seed ^ 0x853c_49e6_748f_ea9b, item)
}

impl<C: RayCaster + ?Sized> ReferenceScene<'_, C> {
    /// Checks array shapes and the reflectance against the mesh.
    pub fn validate(&self) -> Result<()> {
        if self.normals.len() != self.positions.len() {
            return Err(Error::Internal(format!(
                "{} normals for {} vertices",
                self.normals.len(),
                self.positions.len()
            )));
        }
        let nv = self.positions.len();
        if let Some((i, f)) = self
            .faces
            .iter()
            .enumerate()
            .find(|(_, f)| f.iter().any(|&v| v as usize >= nv))
        {
            return Err(Error::Internal(format!(
                "face {i} {f:?} indexes past {nv} vertices"
            )));
        }
        self.reflectance.validate(nv)
    }

    /// Radiance of vertex `v` toward world direction `wo` (unit), shading normal = the
    /// vertex normal, with `n_pairs` MIS sample pairs from stream `(seed, v)`.
    pub fn vertex_radiance(
        &self,
        v: usize,
        wo: &Vec3,
        n_pairs: u32,
        seed: u64,
    ) -> RadianceEstimate {
        let n = self.normals[v];
        let beta = self.reflectance.beta(self.reflectance.vertex_weights(v));
        let mut rng = stream(seed, v as u64);
        shade_point(
            &self.positions[v],
            &n,
            &n,
            wo,
            &self.reflectance.lobes,
            &beta,
            self.env,
            self.caster,
            self.offset,
            n_pairs,
            &mut rng,
        )
    }

    /// Radiance along a camera ray (origin `o`, unit direction `d`): `None` on a miss.
    pub(crate) fn trace(
        &self,
        o: &Vec3,
        d: &Vec3,
        n_pairs: u32,
        rng: &mut Pcg32,
    ) -> Option<[f64; 3]> {
        let hit = self.caster.intersect(o, d, 0.0, f64::INFINITY)?;
        let f = self.faces[hit.face];
        let (i0, i1, i2) = (f[0] as usize, f[1] as usize, f[2] as usize);
        let w0 = 1.0 - hit.u - hit.v;
        let x = o + d * hit.t;
        let mut ng = (self.positions[i1] - self.positions[i0])
            .cross(&(self.positions[i2] - self.positions[i0]));
        let ng_len = ng.norm();
        let mut n = self.normals[i0] * w0 + self.normals[i1] * hit.u + self.normals[i2] * hit.v;
        let n_len = n.norm();
        if ng_len == 0.0 || n_len == 0.0 {
            return Some([0.0; 3]);
        }
        ng /= ng_len;
        n /= n_len;
        let wo = -d;
        // Face the geometric normal toward the shading normal's side.
        if ng.dot(&n) < 0.0 {
            ng = -ng;
        }
        let k = self.reflectance.n_materials();
        let wv = self.reflectance.weights.as_slice();
        let w: Vec<f64> = (0..k)
            .map(|j| w0 * wv[i0 * k + j] + hit.u * wv[i1 * k + j] + hit.v * wv[i2 * k + j])
            .collect();
        let beta = self.reflectance.beta(&w);
        let e = shade_point(
            &x,
            &n,
            &ng,
            &wo,
            &self.reflectance.lobes,
            &beta,
            self.env,
            self.caster,
            self.offset,
            n_pairs,
            rng,
        );
        Some(e.mean)
    }

    /// Renders a pinhole view: per pixel `samples.per_pixel` stratified jittered primary
    /// rays, each shaded with `samples.light` MIS pairs; rows in parallel (rayon), one
    /// random stream per pixel, so the output does not depend on the thread count.
    pub fn render(&self, cam: &PinholeCamera, samples: &Samples) -> ReferenceImage {
        let (w, h) = (cam.width as usize, cam.height as usize);
        let side = (samples.per_pixel.max(1) as f64).sqrt().floor().max(1.0) as usize;
        let n_prim = (side * side) as f64;
        let center = cam.center();
        let mut rgb = vec![[0.0f32; 3]; w * h];
        let mut coverage = vec![0.0f32; w * h];
        rgb.par_chunks_mut(w.max(1))
            .zip(coverage.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(y, (row_rgb, row_cov))| {
                for x in 0..w {
                    let idx = (y * w + x) as u64;
                    let mut rng = stream(samples.seed, idx);
                    let mut acc = [0.0; 3];
                    let mut hits = 0usize;
                    for sy in 0..side {
                        for sx in 0..side {
                            let px = x as f64 + (sx as f64 + rng.random::<f64>()) / side as f64;
                            let py = y as f64 + (sy as f64 + rng.random::<f64>()) / side as f64;
                            let d = cam.ray_dir(px, py);
                            if let Some(l) = self.trace(&center, &d, samples.light, &mut rng) {
                                hits += 1;
                                for c in 0..3 {
                                    acc[c] += l[c];
                                }
                            }
                        }
                    }
                    for c in 0..3 {
                        row_rgb[x][c] = (acc[c] / n_prim) as f32;
                    }
                    row_cov[x] = (hits as f64 / n_prim) as f32;
                }
            });
        ReferenceImage {
            width: w,
            height: h,
            rgb,
            coverage,
        }
    }
}

/// A pinhole camera in COLMAP's convention: `X_cam = R X_world + t`, looking down +z,
/// x right, y down, pixel `(i, j)` covering `[i, i+1] × [j, j+1]` (centre at +0.5),
/// projection `u = fx X/Z + cx`, `v = fy Y/Z + cy`.
#[derive(Debug, Clone, PartialEq)]
pub struct PinholeCamera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length in x (pixels).
    pub fx: f64,
    /// Focal length in y (pixels).
    pub fy: f64,
    /// Principal point x.
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
    /// `R` of `X_cam = R X_world + t` (cam_from_world rotation).
    pub rotation: nalgebra::Matrix3<f64>,
    /// `t` of `X_cam = R X_world + t`.
    pub translation: Vec3,
}

impl PinholeCamera {
    /// The camera centre `C = −Rᵀ t`.
    pub fn center(&self) -> Vec3 {
        -(self.rotation.transpose() * self.translation)
    }

    /// Unit world direction of the ray through continuous pixel coordinates `(px, py)`.
    pub fn ray_dir(&self, px: f64, py: f64) -> Vec3 {
        let d_cam = Vec3::new((px - self.cx) / self.fx, (py - self.cy) / self.fy, 1.0);
        (self.rotation.transpose() * d_cam).normalize()
    }

    /// Continuous pixel coordinates of world point `p`, `None` behind the camera.
    pub fn project(&self, p: &Vec3) -> Option<(f64, f64)> {
        let q = self.rotation * p + self.translation;
        if q.z <= 0.0 {
            return None;
        }
        Some((self.fx * q.x / q.z + self.cx, self.fy * q.y / q.z + self.cy))
    }
}

/// A rendered view: linear RGB and per-pixel object coverage (fraction of primary rays that
/// hit), row-major from the top-left pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear radiance per pixel (background = 0).
    pub rgb: Vec<[f32; 3]>,
    /// Fraction of the pixel's primary rays that hit the mesh.
    pub coverage: Vec<f32>,
}
