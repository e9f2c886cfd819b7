//! Ray casting for the reference: the [`RayCaster`] trait, the brute-force caster, the scene BVH, and the unoccluded caster.

use super::*;

// ---------------------------------------------------------------------------------------
// Ray casting.

/// A ray-triangle hit: distance, face index and barycentrics (point = (1−u−v)p0 + u p1 + v p2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit) direction.
    pub t: f64,
    /// Face index.
    pub face: usize,
    /// Barycentric weight of the face's second vertex.
    pub u: f64,
    /// Barycentric weight of the face's third vertex.
    pub v: f64,
}

/// What the reference renderer needs from a ray tracer.
pub trait RayCaster: Sync {
    /// Nearest hit with `t` in `(tmin, tmax)`.
    fn intersect(&self, origin: &Vec3, dir: &Vec3, tmin: f64, tmax: f64) -> Option<RayHit>;
    /// Whether anything is hit with `t` in `(tmin, tmax)`.
    fn occluded(&self, origin: &Vec3, dir: &Vec3, tmin: f64, tmax: f64) -> bool {
        self.intersect(origin, dir, tmin, tmax).is_some()
    }
}

/// Möller–Trumbore ray-triangle intersection: `(t, u, v)` when the ray hits.
pub fn ray_triangle(
    o: &Vec3,
    d: &Vec3,
    p0: &Vec3,
    p1: &Vec3,
    p2: &Vec3,
) -> Option<(f64, f64, f64)> {
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let pv = d.cross(&e2);
    let det = e1.dot(&pv);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = o - p0;
    let u = tv.dot(&pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(&e1);
    let v = d.dot(&qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((e2.dot(&qv) * inv, u, v))
}

/// Brute-force caster over every triangle: slow, obviously correct; for tests and tiny meshes.
pub struct BruteForce<'a> {
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Triangles.
    pub faces: &'a [[u32; 3]],
}

impl RayCaster for BruteForce<'_> {
    fn intersect(&self, o: &Vec3, d: &Vec3, tmin: f64, tmax: f64) -> Option<RayHit> {
        let mut best: Option<RayHit> = None;
        for (fi, f) in self.faces.iter().enumerate() {
            let p = |i: usize| &self.positions[f[i] as usize];
            if let Some((t, u, v)) = ray_triangle(o, d, p(0), p(1), p(2)) {
                if t > tmin && t < best.map_or(tmax, |b| b.t) {
                    best = Some(RayHit { t, face: fi, u, v });
                }
            }
        }
        best
    }
}

/// The scene BVH (the one piece of ray tracing shared with the wavelet path).
impl RayCaster for crate::observe::trace::SceneBvh {
    fn intersect(&self, o: &Vec3, d: &Vec3, tmin: f64, tmax: f64) -> Option<RayHit> {
        crate::observe::trace::SceneBvh::intersect(self, o, d, tmin, tmax).map(|h| RayHit {
            t: h.t,
            face: h.face as usize,
            u: h.u,
            v: h.v,
        })
    }
    fn occluded(&self, o: &Vec3, d: &Vec3, tmin: f64, tmax: f64) -> bool {
        crate::observe::trace::SceneBvh::occluded(self, o, d, tmin, tmax)
    }
}

/// A caster that never hits anything (no occluders).
pub struct Unoccluded;

impl RayCaster for Unoccluded {
    fn intersect(&self, _: &Vec3, _: &Vec3, _: f64, _: f64) -> Option<RayHit> {
        None
    }
}
