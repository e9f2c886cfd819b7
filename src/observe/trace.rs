//! Ray casting against the mesh: an `obvhs` compressed wide BVH (CWBVH, Ylitie et al. 2017,
//! built with PLOC) over the triangles, with the triangle tests done in f64.
//!
//! The paper needs rays twice: visibility `V(x, ω)` (Eq. 1, 7) and, at import, whether a
//! vertex sees a camera. The BVH is built in f32 (obvhs' node format); each triangle's box is
//! padded by a relative `1e-6` of the scene diagonal plus a few f32 ulps so the f32 boxes
//! always contain the f64 triangles, and the ray–triangle test is Möller–Trumbore
//! (1997) in f64:
//!
//! `o + t d = (1 − u − v) p0 + u p1 + v p2`, solved by Cramer's rule with `e1 = p1 − p0`,
//! `e2 = p2 − p0`: `det = e1 · (d × e2)`, `u = (o − p0) · (d × e2) / det`,
//! `v = d · ((o − p0) × e1) / det`, `t = e2 · ((o − p0) × e1) / det`.
//!
//! The test is edge-inclusive (`u, v ≥ −1e-12`, `u + v ≤ 1 + 1e-12`) so a ray through a
//! shared edge or vertex hits at least one of the triangles: occlusion rays do not leak
//! through a closed mesh. Both faces of a triangle are hit (no back-face culling).

use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::{Boundable, BvhBuildParams};

use crate::import::mesh::Mesh;
use crate::Vec3;

/// A ray–mesh intersection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter: the hit point is `origin + t · dir` (in units of `|dir|`).
    pub t: f64,
    /// Index of the face hit (into [`Mesh::faces`]).
    pub face: u32,
    /// Barycentric coordinate of the face's vertex 1.
    pub u: f64,
    /// Barycentric coordinate of the face's vertex 2 (vertex 0 has `1 − u − v`).
    pub v: f64,
}

/// One triangle as the BVH builder sees it: its f64 corners and a padded f32 box.
struct Prim {
    corners: [Vec3; 3],
    pad: f64,
}

impl Boundable for Prim {
    fn aabb(&self) -> Aabb {
        let mut lo = self.corners[0];
        let mut hi = self.corners[0];
        for c in &self.corners[1..] {
            lo = lo.inf(c);
            hi = hi.sup(c);
        }
        let widen = |x: f64, s: f64| {
            let x = x + s * (self.pad + 4.0 * f32::EPSILON as f64 * x.abs());
            x as f32
        };
        Aabb::new(
            [widen(lo.x, -1.0), widen(lo.y, -1.0), widen(lo.z, -1.0)].into(),
            [widen(hi.x, 1.0), widen(hi.y, 1.0), widen(hi.z, 1.0)].into(),
        )
    }
}

/// A BVH over a mesh's triangles. Immutable and `Sync`: share one across threads.
pub struct SceneBvh {
    bvh: Option<CwBvh>,
    /// Triangles in BVH primitive order (`tris[i]` is primitive `i`) as the ray test reads
    /// them: `[p0, e1 = p1 − p0, e2 = p2 − p0]`.
    tris: Vec<[Vec3; 3]>,
    /// Mesh face index of BVH primitive `i`.
    face_of: Vec<u32>,
    offset: f64,
}

/// Möller–Trumbore in f64 (module docs). Returns `(t, u, v)` when `t ∈ [t_min, t_max]`.
pub fn intersect_triangle(
    corners: &[Vec3; 3],
    origin: &Vec3,
    dir: &Vec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64, f64)> {
    let edges = edge_form(corners);
    intersect_edges(&edges, origin, dir, t_min, t_max)
}

/// A triangle's corners as `[p0, e1 = p1 − p0, e2 = p2 − p0]`, the form the BVH stores (the
/// edges are computed once per triangle instead of once per ray test).
fn edge_form(corners: &[Vec3; 3]) -> [Vec3; 3] {
    [corners[0], corners[1] - corners[0], corners[2] - corners[0]]
}

/// [`intersect_triangle`] of a triangle in [`edge_form`]: the same operations on the same
/// values, so the same result bit for bit.
#[inline]
fn intersect_edges(
    edges: &[Vec3; 3],
    origin: &Vec3,
    dir: &Vec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64, f64)> {
    const EDGE_TOL: f64 = 1e-12;
    let [p0, e1, e2] = edges;
    let pvec = dir.cross(e2);
    let det = e1.dot(&pvec);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tvec = origin - p0;
    let u = tvec.dot(&pvec) * inv;
    if !(-EDGE_TOL..=1.0 + EDGE_TOL).contains(&u) {
        return None;
    }
    let qvec = tvec.cross(e1);
    let v = dir.dot(&qvec) * inv;
    if v < -EDGE_TOL || u + v > 1.0 + EDGE_TOL {
        return None;
    }
    let t = e2.dot(&qvec) * inv;
    (t >= t_min && t <= t_max).then_some((t, u, v))
}

fn to_ray(origin: &Vec3, dir: &Vec3, t_min: f64, t_max: f64) -> Option<Ray> {
    let o = [origin.x as f32, origin.y as f32, origin.z as f32];
    // `+ 0.0` turns −0.0 into +0.0: obvhs reads a direction's sign in two ways (sign bit
    // and comparison), and a −0.0 component makes them disagree and miss hits.
    let d = [dir.x as f32 + 0.0, dir.y as f32 + 0.0, dir.z as f32 + 0.0];
    let finite = o.iter().chain(d.iter()).all(|v| v.is_finite());
    if !finite || d == [0.0; 3] || t_min.is_nan() || t_max.is_nan() || t_min > t_max {
        return None;
    }
    // Widen the f32 interval so f32 rounding never culls a hit the f64 test accepts.
    let lo = (t_min as f32).next_down();
    let hi = if t_max.is_finite() {
        (t_max as f32).next_up() * (1.0 + 1e-5)
    } else {
        f32::INFINITY
    };
    Some(Ray::new(o.into(), d.into(), lo, hi))
}

/// The segment `origin + t · dir`, `t ∈ [t_min, t_max]`, of an occlusion query.
struct Segment<'a> {
    origin: &'a Vec3,
    dir: &'a Vec3,
    t_min: f64,
    t_max: f64,
}

impl Segment<'_> {
    /// Whether the triangle (edge form) lies on the segment: the f64 test.
    #[inline(always)]
    fn hits(&self, edges: &[Vec3; 3]) -> bool {
        intersect_edges(edges, self.origin, self.dir, self.t_min, self.t_max).is_some()
    }
}

impl SceneBvh {
    /// Builds the BVH (obvhs `fast_build` preset: PLOC + light reinsertion).
    pub fn new(mesh: &Mesh) -> SceneBvh {
        let offset = 1e-5 * mesh.diagonal().max(f64::MIN_POSITIVE);
        let pad = 1e-6 * mesh.diagonal();
        let prims: Vec<Prim> = mesh
            .faces
            .iter()
            .map(|f| Prim {
                corners: f.map(|k| mesh.positions[k as usize]),
                pad,
            })
            .collect();
        if prims.is_empty() {
            return SceneBvh {
                bvh: None,
                tris: Vec::new(),
                face_of: Vec::new(),
                offset,
            };
        }
        let mut build_time = std::time::Duration::default();
        let bvh = build_cwbvh(&prims, BvhBuildParams::fast_build(), &mut build_time);
        let tris = bvh
            .primitive_indices
            .iter()
            .map(|&i| edge_form(&prims[i as usize].corners))
            .collect();
        let face_of = bvh.primitive_indices.clone();
        SceneBvh {
            bvh: Some(bvh),
            tris,
            face_of,
            offset,
        }
    }

    /// The closest hit with `t ∈ [t_min, t_max]` along `origin + t · dir`.
    pub fn intersect(&self, origin: &Vec3, dir: &Vec3, t_min: f64, t_max: f64) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let ray = to_ray(origin, dir, t_min, t_max)?;
        let mut best: Option<Hit> = None;
        let mut hit = RayHit::none();
        bvh.ray_traverse(ray, &mut hit, |_, id| {
            let limit = best.map_or(t_max, |b| b.t);
            match intersect_edges(&self.tris[id], origin, dir, t_min, limit) {
                Some((t, u, v)) => {
                    best = Some(Hit {
                        t,
                        face: self.face_of[id],
                        u,
                        v,
                    });
                    // Round up so the f32 cull never drops a closer f64 hit.
                    (t as f32).next_up()
                }
                None => f32::INFINITY,
            }
        });
        best
    }

    /// Whether anything lies on the segment `t ∈ [t_min, t_max]` (stops at the first hit).
    pub fn occluded(&self, origin: &Vec3, dir: &Vec3, t_min: f64, t_max: f64) -> bool {
        let mut no_hint = u32::MAX;
        self.occluded_hinted(origin, dir, t_min, t_max, &mut no_hint)
    }

    /// [`SceneBvh::occluded`] with a hint: `hint` names a BVH primitive that blocked an
    /// earlier, nearby ray (`u32::MAX` for none). It is tested first with the same f64
    /// test; when it blocks this segment too the traversal is skipped, else the ray is
    /// traversed and `hint` becomes the primitive that blocked it, if any. Either way the
    /// answer is whether a triangle accepted by the f64 test lies on the segment: the
    /// hinted one when it does, else the traversal's. With AVX2 the traversal runs in a
    /// copy compiled for it (`SceneBvh::blocked_avx2`: −7% of the visibility stage at
    /// 30K vertices, the same rays and answers, `bench-results/speed-levers-2.md`).
    pub fn occluded_hinted(
        &self,
        origin: &Vec3,
        dir: &Vec3,
        t_min: f64,
        t_max: f64,
        hint: &mut u32,
    ) -> bool {
        let seg = Segment {
            origin,
            dir,
            t_min,
            t_max,
        };
        if let Some(tri) = self.tris.get(*hint as usize) {
            if seg.hits(tri) {
                return true;
            }
        }
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let Some(ray) = to_ray(origin, dir, t_min, t_max) else {
            return false;
        };
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has the feature `blocked_avx2` is compiled for.
            return unsafe { self.blocked_avx2(bvh, &ray, &seg, hint) };
        }
        self.blocked_obvhs(bvh, ray, &seg, hint)
    }

    /// Whether a triangle accepted by the f64 test blocks `seg`, by obvhs'
    /// `ray_traverse_miss`; `hint` becomes the blocker.
    fn blocked_obvhs(&self, bvh: &CwBvh, ray: Ray, seg: &Segment, hint: &mut u32) -> bool {
        !bvh.ray_traverse_miss(ray, |r, id| {
            if seg.hits(&self.tris[id]) {
                // Any value below the ray's tmax stops the traversal.
                *hint = id as u32;
                r.tmin.min(r.tmax)
            } else {
                f32::INFINITY
            }
        })
    }

    /// [`SceneBvh::blocked_traverse`] compiled for AVX2. obvhs' own `ray_traverse_miss` is
    /// a call the compiler keeps out of line, so its node tests would not get the wider
    /// instructions; written with obvhs' `traverse!` macro (its public way to a custom
    /// traversal), they are `#[inline(always)]` and compile into this function.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn blocked_avx2(&self, bvh: &CwBvh, ray: &Ray, seg: &Segment, hint: &mut u32) -> bool {
        self.blocked_traverse(bvh, ray, seg, hint)
    }

    /// [`SceneBvh::blocked_obvhs`] written with obvhs' `traverse!`: the same node tests in
    /// the same order and the same f64 triangle test, so the same answer and blocker.
    #[inline(always)]
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    fn blocked_traverse(&self, bvh: &CwBvh, ray: &Ray, seg: &Segment, hint: &mut u32) -> bool {
        use glam::UVec2;
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        let mut blocked = false;
        'traversal: {
            obvhs::traverse!(bvh, node, state, node.intersect_ray(ray, state.oct_inv4), {
                let id = state.primitive_id as usize;
                if seg.hits(&self.tris[id]) {
                    *hint = id as u32;
                    blocked = true;
                    break 'traversal;
                }
            });
        }
        blocked
    }

    /// Self-hit epsilon: `1e-5 ×` the mesh's bounding-box diagonal. Offset ray origins by
    /// this along the normal and start rays at `t_min = ray_offset()` (unit directions).
    pub fn ray_offset(&self) -> f64 {
        self.offset
    }

    /// Number of triangles in the BVH.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether the BVH holds no triangles (every ray misses).
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// A random triangle soup over [0, 1]³ plus the same as a mesh.
    fn soup(seed: u64, n: usize) -> Mesh {
        let mut rng = Pcg64::seed_from_u64(seed);
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        for i in 0..n {
            let c = Vec3::new(rng.random(), rng.random(), rng.random());
            for _ in 0..3 {
                let d = Vec3::new(
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                );
                positions.push(c + 0.1 * d);
            }
            let b = 3 * i as u32;
            faces.push([b, b + 1, b + 2]);
        }
        Mesh::from_parts(positions, faces).0
    }

    /// [`soup`]`(seed, n)`, its BVH, and a random stream seeded with `rng_seed`.
    fn soup_bvh(seed: u64, n: usize, rng_seed: u64) -> (Mesh, SceneBvh, Pcg64) {
        let mesh = soup(seed, n);
        let bvh = SceneBvh::new(&mesh);
        (mesh, bvh, Pcg64::seed_from_u64(rng_seed))
    }

    /// A ray from a uniform point of the unit cube in a direction uniform in
    /// `[−0.5, 0.5)³` (not normalised), drawn in that order.
    fn random_ray(rng: &mut Pcg64) -> (Vec3, Vec3) {
        let o = Vec3::new(rng.random(), rng.random(), rng.random());
        let d = Vec3::new(
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
        );
        (o, d)
    }

    #[test]
    fn bvh_closest_hit_matches_brute_force() {
        // The BVH must return exactly the brute-force closest triangle (same f64 test, so
        // t agrees to the last bit unless two faces tie within 1e-12).
        let (mesh, bvh, mut rng) = soup_bvh(7, 400, 11);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(
                rng.random::<f64>() * 2.0 - 0.5,
                rng.random::<f64>() * 2.0 - 0.5,
                rng.random::<f64>() * 2.0 - 0.5,
            );
            let target = Vec3::new(rng.random(), rng.random(), rng.random());
            let d = target - o;
            let brute = mesh
                .faces
                .iter()
                .enumerate()
                .filter_map(|(f, tri)| {
                    let c = tri.map(|k| mesh.positions[k as usize]);
                    intersect_triangle(&c, &o, &d, 0.0, 10.0).map(|(t, _, _)| (t, f))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let got = bvh.intersect(&o, &d, 0.0, 10.0);
            match (brute, got) {
                (None, None) => {}
                (Some((t, f)), Some(h)) => {
                    hits += 1;
                    assert!((t - h.t).abs() <= 1e-12 * t.max(1.0), "{t} vs {}", h.t);
                    // The face returned is the closest (or ties with it to 1e-12).
                    let c = mesh.faces[h.face as usize].map(|k| mesh.positions[k as usize]);
                    let (th, _, _) = intersect_triangle(&c, &o, &d, 0.0, 10.0).unwrap();
                    assert!(h.face == f as u32 || (th - t).abs() <= 1e-12 * t.max(1.0));
                    assert!(bvh.occluded(&o, &d, 0.0, 10.0));
                    // Stopping just before the hit: not occluded by that face.
                    assert!(
                        !bvh.occluded(&o, &d, 0.0, t * (1.0 - 1e-9)),
                        "segment ending before the closest hit is free"
                    );
                }
                (b, g) => panic!("brute {b:?} vs bvh {g:?}"),
            }
        }
        assert!(hits > 200, "test rays should hit often ({hits})");
    }

    #[test]
    fn hinted_occlusion_matches_brute_force() {
        // Against the brute-force answer (some triangle accepted by the f64 test on the
        // segment), for random segments and hints that are stale (the last blocker of an
        // unrelated ray), absent, or out of range; no tolerance: the same f64 test decides.
        let (mesh, bvh, mut rng) = soup_bvh(17, 300, 19);
        let mut hint = u32::MAX;
        let (mut blocked, mut hinted) = (0, 0);
        for k in 0..3000 {
            let (o, d) = random_ray(&mut rng);
            let t_max = if k % 3 == 0 {
                f64::INFINITY
            } else {
                rng.random::<f64>()
            };
            let brute = mesh.faces.iter().any(|tri| {
                let c = tri.map(|i| mesh.positions[i as usize]);
                intersect_triangle(&c, &o, &d, 1e-9, t_max).is_some()
            });
            if k % 97 == 0 {
                hint = if k % 2 == 0 { u32::MAX } else { 1_000_000 };
            }
            let before = hint;
            let got = bvh.occluded_hinted(&o, &d, 1e-9, t_max, &mut hint);
            assert_eq!(got, brute, "ray {k}");
            assert_eq!(got, bvh.occluded(&o, &d, 1e-9, t_max), "ray {k}");
            blocked += usize::from(got);
            hinted += usize::from(got && hint == before && before != u32::MAX);
            if got {
                // The blocker just found blocks the same segment: answered by the hint
                // alone, which stays as it was.
                let mut again = hint;
                assert!(bvh.occluded_hinted(&o, &d, 1e-9, t_max, &mut again));
                assert_eq!(again, hint);
                // A shorter segment that the brute force finds free stays free.
                let short = 0.5
                    * mesh
                        .faces
                        .iter()
                        .filter_map(|tri| {
                            let c = tri.map(|i| mesh.positions[i as usize]);
                            intersect_triangle(&c, &o, &d, 1e-9, t_max).map(|h| h.0)
                        })
                        .fold(f64::INFINITY, f64::min);
                assert!(!bvh.occluded_hinted(&o, &d, 1e-9, short, &mut again));
            }
        }
        assert!(blocked > 100, "{blocked} blocked, {hinted} by a stale hint");
    }

    #[test]
    fn both_traversals_give_the_same_answer_and_blocker() {
        // obvhs' own `ray_traverse_miss` (the path of CPUs without AVX2) and the traversal
        // written with `traverse!` (and its AVX2 copy, on CPUs that have it) must test the
        // same nodes and triangles in the same order: the same answer and the same first
        // blocker (the hint they leave), exactly, on random segments through a triangle
        // soup. The brute-force test above checks the answer of the path this CPU takes.
        let (_mesh, scene, mut rng) = soup_bvh(23, 400, 29);
        let bvh = scene.bvh.as_ref().expect("a non-empty soup has a BVH");
        let mut blocked = 0;
        for k in 0..3000 {
            let (o, d) = random_ray(&mut rng);
            let t_max = if k % 2 == 0 {
                f64::INFINITY
            } else {
                rng.random()
            };
            let seg = Segment {
                origin: &o,
                dir: &d,
                t_min: 1e-9,
                t_max,
            };
            let ray = to_ray(&o, &d, 1e-9, t_max).expect("a finite ray");
            let mut h = [u32::MAX; 3];
            let plain = scene.blocked_obvhs(bvh, ray, &seg, &mut h[0]);
            let written = scene.blocked_traverse(bvh, &ray, &seg, &mut h[1]);
            assert_eq!((plain, h[0]), (written, h[1]), "ray {k}");
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2.
                let wide = unsafe { scene.blocked_avx2(bvh, &ray, &seg, &mut h[2]) };
                assert_eq!((plain, h[0]), (wide, h[2]), "ray {k}");
            }
            blocked += usize::from(plain);
        }
        assert!(blocked > 100, "{blocked} blocked");
    }

    #[test]
    fn barycentrics_reconstruct_the_hit_point() {
        let c = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 3.0, 0.0),
        ];
        let o = Vec3::new(0.5, 0.75, 4.0);
        let d = Vec3::new(0.0, 0.0, -2.0);
        let (t, u, v) = intersect_triangle(&c, &o, &d, 0.0, f64::INFINITY).unwrap();
        // Analytic: hit at z = 0 → t = 2; point (0.5, 0.75) = u·(2,0) + v·(0,3).
        assert!((t - 2.0).abs() < 1e-15);
        assert!((u - 0.25).abs() < 1e-15 && (v - 0.25).abs() < 1e-15);
        // Ray through the shared edge of two triangles hits (edge-inclusive).
        let o = Vec3::new(1.0, 1.5, 1.0); // on the hypotenuse x/2 + y/3 = 1
        assert!(intersect_triangle(&c, &o, &Vec3::new(0.0, 0.0, -1.0), 0.0, 9.0).is_some());
    }

    #[test]
    fn negative_zero_direction_components_still_hit() {
        // A camera centre computed as −Rᵀt often has −0.0 components; rays along an axis
        // then carry −0.0 and must hit exactly as with +0.0.
        let (quad, _) = Mesh::from_parts(
            vec![
                Vec3::new(-0.2, -0.2, 3.0),
                Vec3::new(0.3, -0.2, 3.0),
                Vec3::new(0.3, 0.3, 3.0),
                Vec3::new(-0.2, 0.3, 3.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let bvh = SceneBvh::new(&quad);
        for d in [
            Vec3::new(-0.0, -0.0, 1.0),
            Vec3::new(0.0, -0.0, 1.0),
            Vec3::new(-0.0, 0.1, 1.0),
        ] {
            let o = Vec3::new(0.0, 0.0, 1.0);
            assert!(bvh.occluded(&o, &d, 0.0, 10.0), "{d:?}");
            let h = bvh.intersect(&o, &d, 0.0, 10.0).unwrap();
            assert!((h.t - 2.0).abs() < 1e-12);
        }
    }

    #[test]
    fn empty_and_single_triangle_meshes() {
        let empty = SceneBvh::new(&Mesh::default());
        assert!(empty.is_empty());
        assert!(empty
            .intersect(&Vec3::zeros(), &Vec3::z(), 0.0, 1.0)
            .is_none());
        let (one, _) = Mesh::from_parts(vec![Vec3::zeros(), Vec3::x(), Vec3::y()], vec![[0, 1, 2]]);
        let bvh = SceneBvh::new(&one);
        let h = bvh
            .intersect(
                &Vec3::new(0.2, 0.2, 1.0),
                &Vec3::new(0.0, 0.0, -1.0),
                0.0,
                5.0,
            )
            .unwrap();
        assert_eq!(h.face, 0);
        assert!((h.t - 1.0).abs() < 1e-15);
        // t_max before the plane: no hit; zero direction: no hit, no panic.
        assert!(bvh
            .intersect(
                &Vec3::new(0.2, 0.2, 1.0),
                &Vec3::new(0.0, 0.0, -1.0),
                0.0,
                0.5
            )
            .is_none());
        assert!(!bvh.occluded(&Vec3::zeros(), &Vec3::zeros(), 0.0, 1.0));
    }
}
