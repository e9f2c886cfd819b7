//! Per-vertex visibility `V(x, ω)` over the local hemisphere (paper Sec. 3, the `V` of
//! Eq. 1 and the `V_l` of Eq. 7).
//!
//! For vertex `x` with unit normal `n` (world), the local frame is
//! [`crate::sphere::local_frame`] of `n_env = M n`, where `M` = `env_from_world` (rows
//! `e_x, e_y, e_z`), so the local hemisphere is the same one the BRDF slices and the
//! rotation `R_ν` use. Each `n_local × n_local` hemi-octahedral texel `t` gets
//! `r` rays (stratified-jittered in the texel's `uv` square when `r` is a perfect square,
//! uniformly jittered otherwise; seeded per vertex, so results do not depend on the thread
//! count), from `x + ε n` with `t_min = ε` (`ε` = [`SceneBvh::ray_offset`]); the stored value
//! is the visible fraction `V_t ≈ (1/Δω_t) ∫_texel V dω` (the texel average, docs/conventions.md),
//! quantised to `u8` (`255` = fully visible, error ≤ 1/510).
//!
//! Two ways to spread the rays ([`Sampling`]): *uniform*, `r` rays in every texel as above;
//! *adaptive* (the run's default), classic adaptive supersampling (Whitted 1980; Mitchell
//! 1987): one uniformly jittered ray per texel, then `m` more (stratified as above) only in
//! the texels on a visibility edge — those whose first ray disagrees with the first ray of
//! one of their eight neighbours (within the map; the map's border is the horizon, where
//! `cos θ` ≈ 0). An edge texel stores the fraction of its `1 + m` rays that escape (each
//! ray is uniform over the texel or over a stratum, so the mean is unbiased); any other
//! texel stores its one ray's 0 or 1, exact wherever the texel is wholly open or wholly
//! blocked, which is where all its neighbours agree unless an occluder is thinner than a
//! texel. Measured (`cargo bench --bench visibility`, `bench-results/visibility-sampling.md`):
//! with `m = 4`, 71% of the rays of two uniform ones per texel and half their texel RMS
//! error against 64 rays.
//!
//! When `m + 1` is a perfect square (`m` = 3, 8, …) a texel's first ray and its edge rays
//! share one `√(m+1) × √(m+1)` grid of strata: the first ray is uniform in a stratum drawn
//! at random (so still uniform over the texel) and the `m` edge rays take the other
//! strata, one each, so an edge texel's `m + 1` rays are stratified. Measured on the same
//! mesh: `m = 3` gives a texel RMS error of 0.0332 against 0.0328 for `m = 4` (a uniform
//! first ray and 4 stratified ones) at 92% of its rays; `m = 3` without the shared strata
//! (3 uniform rays, the rule before) gave 0.0450.
//!
//! The first rays can themselves be spread adaptively (`lattice = 2`, Whitted's corner
//! sampling one level down): the first ray is traced in every other texel of each row
//! and column (and the last row and column), the *lattice*; a texel between lattice
//! texels is traced only when its two or four lattice corners disagree, and otherwise
//! takes their common value (marked *inferred*). The edge test then runs on that map as
//! above; an inferred texel on an edge stores the fraction of its `m` edge rays alone, as
//! its first value was not a sample of it. What this can miss is an occluder, or a gap,
//! that falls wholly between lattice texels (thinner than two texels, ~9° at 32²).
//! Such thin occluders sit mostly near the horizon (a surface's own bumps and folds), so
//! texels in the [`HORIZON_BAND`] (map coordinate `max(|2u − 1|, |2v − 1|) ≥ 0.85`, within
//! ~10–14° of the horizon) always trace their first ray. Measured on the Buddha fixture's
//! mesh against 64 rays (`bench-results/visibility-horizon-band.md`): the lattice over the
//! whole map traced 62% of the rays of `lattice = 1` at a mean visible solid-angle error
//! of 0.0190 sr against 0.0105; with the band 70% at 0.0138.
//!
//! The worker threads take the vertices along a Morton curve through the mesh's box
//! ([`spatial_order`]), so that consecutive vertices' rays walk the same BVH nodes; a
//! vertex's values do not depend on the order.
//!
//! A vertex's rays run texel by texel, so a blocked ray is most often blocked by the same
//! triangle as the previous blocked one: that triangle is tested first
//! ([`SceneBvh::occluded_hinted`], the same f64 test, so a ray it blocks is blocked) and the
//! BVH is traversed only when it does not block.
//!
//! Rays whose direction lies in a provably empty cone are answered without tracing: the
//! map is cut into blocks of 4 × 4 texels (at 32²), and a block whose cone of directions,
//! from the rays' origin and above the tangent plane, holds no triangle
//! ([`crate::observe::cone`]) has every ray escape (`OpenCones`). The jitter is drawn
//! either way, so the maps are bit for bit those of tracing every ray.
//!
//! Provably open vertices skip the rays: if no mesh vertex lies above the tangent plane,
//! `n·(p − x) ≤ ε` for all `p`, no triangle (a convex combination of vertices) does either,
//! so every ray with `n·ω > 0` escapes. The test is a half-space emptiness query on a
//! bounding-box tree of the vertex positions (a node is skipped when its box's support in
//! direction `n` is below the plane), exact and about logarithmic per vertex on convex
//! parts.

use nalgebra::Matrix3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

use crate::import::mesh::Mesh;
use crate::observe::trace::SceneBvh;
use crate::sphere::{from_local, local_frame, SphereGrid};
use crate::Vec3;

mod cones;
mod order;
mod point_tree;
use cones::{ConeScratch, OpenCones};
pub use order::{morton_keys, spatial_order};
use point_tree::PointTree;

/// Per-vertex texel visibility in the local hemi-octahedral map.
#[derive(Debug, Clone, Default)]
pub struct Visibility {
    /// Local map side (texels per side).
    pub n_local: usize,
    /// Rays per texel used for traced vertices.
    pub rays_per_texel: usize,
    /// Visible fraction per texel, `frac[v * n_local² + t] / 255`.
    pub frac: Vec<u8>,
    /// Vertices proven unoccluded (no rays traced; all texels 255).
    pub open: Vec<bool>,
    /// Vertices whose normal is zero or not finite (all texels 0: they contribute nothing).
    pub degenerate: usize,
    /// Rays traced in total.
    pub rays_traced: u64,
    /// Rays not traced because their texel lies in a cone proven empty (`OpenCones`):
    /// each would have escaped.
    pub rays_known_open: u64,
}

impl Visibility {
    /// Texels per vertex, `n_local²`.
    pub fn texels(&self) -> usize {
        self.n_local * self.n_local
    }

    /// The quantised fractions of vertex `v`.
    pub fn vertex(&self, v: usize) -> &[u8] {
        let k = self.texels();
        &self.frac[v * k..(v + 1) * k]
    }

    /// Mean visible fraction over each vertex's texels (1 for an open hemisphere), `[0, 1]`.
    pub fn open_fractions(&self) -> Vec<f64> {
        let k = self.texels().max(1);
        (0..self.open.len())
            .map(|v| {
                if self.open[v] {
                    1.0
                } else {
                    let s: u32 = self.vertex(v).iter().map(|&f| u32::from(f)).sum();
                    s as f64 / (255.0 * k as f64)
                }
            })
            .collect()
    }

    /// Visible fraction of texel `t` at vertex `v`, in `[0, 1]`.
    pub fn value(&self, v: usize, t: usize) -> f64 {
        self.frac[v * self.texels() + t] as f64 / 255.0
    }

    /// Rays the sampling drew: traced, or answered by an empty cone.
    pub fn rays_sampled(&self) -> u64 {
        self.rays_traced + self.rays_known_open
    }

    /// Number of vertices proven open.
    pub fn open_count(&self) -> usize {
        self.open.iter().filter(|&&o| o).count()
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.frac.len() + self.open.len()
    }
}

/// How a traced vertex's rays are spread over its texels (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampling {
    /// `rays` per texel: stratified-jittered when a perfect square, uniformly jittered
    /// otherwise (clamped to at least 1).
    Uniform {
        /// Rays per texel.
        rays: usize,
    },
    /// One uniformly jittered ray per texel, then `edge_rays` more (stratified when a
    /// perfect square) in every texel on a visibility edge: one of its eight neighbours'
    /// first rays disagrees with its own.
    Adaptive {
        /// Extra rays per edge texel.
        edge_rays: usize,
        /// Spacing of the lattice of texels whose first ray is always traced: 1 traces
        /// every texel's; 2 traces every other texel's in each direction (and the last
        /// row and column), and a texel between lattice texels that all agree takes their
        /// value without a ray (module docs).
        lattice: usize,
    },
}

impl Sampling {
    /// Adaptive with `edge_rays` extra rays and first rays on a lattice of spacing
    /// `lattice` when `edge_rays > 0`, else `rays` uniform rays.
    pub fn new(rays: usize, edge_rays: usize, lattice: usize) -> Sampling {
        if edge_rays > 0 {
            Sampling::Adaptive {
                edge_rays,
                lattice: lattice.clamp(1, 2),
            }
        } else {
            Sampling::Uniform { rays }
        }
    }

    /// Rays every traced texel gets at least (the value stored in
    /// [`Visibility::rays_per_texel`]).
    pub fn min_rays(&self) -> usize {
        match *self {
            Sampling::Uniform { rays } => rays.max(1),
            Sampling::Adaptive { .. } => 1,
        }
    }
}

/// Compute visibility for every vertex of `mesh` (see the module docs) with
/// `rays_per_texel` uniform rays per texel (clamped to at least 1); `n_local` must be a
/// power of two ≥ 2.
pub fn compute(
    mesh: &Mesh,
    bvh: &SceneBvh,
    env_from_world: &Matrix3<f64>,
    n_local: usize,
    rays_per_texel: usize,
    seed: u64,
) -> Visibility {
    compute_with(
        mesh,
        bvh,
        env_from_world,
        n_local,
        rays_per_texel,
        seed,
        true,
    )
}

/// [`compute`] with the open-hemisphere shortcut switchable (`skip_open = false` traces every
/// vertex; tests use it to check the shortcut).
pub fn compute_with(
    mesh: &Mesh,
    bvh: &SceneBvh,
    env_from_world: &Matrix3<f64>,
    n_local: usize,
    rays_per_texel: usize,
    seed: u64,
    skip_open: bool,
) -> Visibility {
    let sampling = Sampling::Uniform {
        rays: rays_per_texel,
    };
    compute_sampled(
        mesh,
        bvh,
        env_from_world,
        n_local,
        sampling,
        seed,
        skip_open,
    )
}

/// Visibility of every vertex of `mesh` with the rays spread by `sampling` (module docs);
/// `skip_open` enables the open-hemisphere shortcut.
pub fn compute_sampled(
    mesh: &Mesh,
    bvh: &SceneBvh,
    env_from_world: &Matrix3<f64>,
    n_local: usize,
    sampling: Sampling,
    seed: u64,
    skip_open: bool,
) -> Visibility {
    let order = spatial_order(&mesh.positions);
    let tracing = Tracing {
        env_from_world,
        n_local,
        sampling,
        seed,
        skip_open,
    };
    compute_in_order(mesh, bvh, &tracing, &order)
}

/// The options of [`compute_sampled`], as [`compute_in_order`] takes them.
struct Tracing<'a> {
    env_from_world: &'a Matrix3<f64>,
    n_local: usize,
    sampling: Sampling,
    seed: u64,
    skip_open: bool,
}

/// [`compute_sampled`] with the vertices handed to the worker threads in `order` (a
/// permutation of the vertex indices; [`order`] module docs): the maps are the same for
/// every order.
fn compute_in_order(mesh: &Mesh, bvh: &SceneBvh, tracing: &Tracing, order: &[u32]) -> Visibility {
    let tracer = VertexTracer::new(mesh, bvh, tracing);
    let (nv, texels) = (mesh.positions.len(), tracer.grid.len());
    let mut frac = vec![0u8; nv * texels];
    let mut open = vec![false; nv];
    let mut slots: Vec<Option<(&mut [u8], &mut bool)>> = frac
        .chunks_mut(texels.max(1))
        .zip(open.iter_mut())
        .map(Some)
        .collect();
    let work: Vec<(usize, (&mut [u8], &mut bool))> = order
        .iter()
        .filter_map(|&v| Some((v as usize, slots.get_mut(v as usize)?.take()?)))
        .collect();
    let counts = work
        .into_par_iter()
        .map_init(
            || {
                let ticks = crate::stages::Ticker::default();
                (ticks, FirstRays::default(), ConeScratch::default())
            },
            |(ticks, first, scratch), (v, (out, is_open))| {
                ticks.tick(1);
                tracer.trace(v, out, is_open, first, scratch)
            },
        )
        .reduce(RayCounts::default, RayCounts::add);
    Visibility {
        n_local: tracing.n_local,
        rays_per_texel: tracing.sampling.min_rays(),
        frac,
        open,
        degenerate: counts.degenerate,
        rays_traced: counts.traced,
        rays_known_open: counts.known_open,
    }
}

/// What tracing a vertex's hemisphere counted.
#[derive(Debug, Clone, Copy, Default)]
struct RayCounts {
    /// Rays traced through the scene.
    traced: u64,
    /// Vertices with no finite position or normal (their maps stay 0).
    degenerate: usize,
    /// Rays answered open by the cones without tracing.
    known_open: u64,
}

impl RayCounts {
    fn add(self, o: Self) -> Self {
        RayCounts {
            traced: self.traced + o.traced,
            degenerate: self.degenerate + o.degenerate,
            known_open: self.known_open + o.known_open,
        }
    }
}

/// Everything the shadow rays of one vertex read, shared by all vertices of a trace: the
/// options, and what is built from the mesh and the options once.
struct VertexTracer<'a> {
    mesh: &'a Mesh,
    bvh: &'a SceneBvh,
    t: &'a Tracing<'a>,
    grid: SphereGrid,
    tree: PointTree,
    cones: Option<OpenCones>,
    world_from_env: Matrix3<f64>,
    eps: f64,
}

impl<'a> VertexTracer<'a> {
    fn new(mesh: &'a Mesh, bvh: &'a SceneBvh, t: &'a Tracing<'a>) -> Self {
        let grid = SphereGrid::hemi(t.n_local);
        let cones = t.skip_open.then(|| OpenCones::new(mesh, &grid)).flatten();
        VertexTracer {
            mesh,
            bvh,
            t,
            tree: PointTree::new(&mesh.positions),
            cones,
            grid,
            world_from_env: t.env_from_world.transpose(),
            eps: bvh.ray_offset(),
        }
    }

    /// Vertex `v`'s visible fraction per texel into `out` (`is_open` when it is proven
    /// unoccluded without a ray), its rays seeded by `(seed, v)`.
    fn trace(
        &self,
        v: usize,
        out: &mut [u8],
        is_open: &mut bool,
        first: &mut FirstRays,
        scratch: &mut ConeScratch,
    ) -> RayCounts {
        let x = self.mesh.positions[v];
        let n = self
            .mesh
            .normals
            .get(v)
            .copied()
            .unwrap_or_else(Vec3::zeros);
        let nn = n.norm();
        if !(nn.is_finite() && nn > 0.0 && x.iter().all(|c| c.is_finite())) {
            return RayCounts {
                degenerate: 1,
                ..RayCounts::default()
            };
        }
        let n = n / nn;
        if self.t.skip_open && !self.tree.any_above(&x, &n, self.eps) {
            *is_open = true;
            out.fill(255);
            return RayCounts::default();
        }
        let frame = local_frame(&(self.t.env_from_world * n));
        let origin = x + n * self.eps;
        let to_world = |l: &Vec3| self.world_from_env * from_local(&frame, l);
        scratch.sure.clear();
        scratch.sure.resize(self.grid.len(), false);
        if let Some(cones) = &self.cones {
            cones.mark_open(&origin, &n, to_world, scratch);
        }
        let rays = VertexRays {
            bvh: self.bvh,
            grid: &self.grid,
            frame,
            world_from_env: self.world_from_env,
            origin,
            eps: self.eps,
            blocker: std::cell::Cell::new(u32::MAX),
            sure_open: &scratch.sure,
            skipped: std::cell::Cell::new(0),
        };
        let mut rng = Pcg64::seed_from_u64(mix(self.t.seed, v as u64));
        let counted = match self.t.sampling {
            Sampling::Uniform { rays: r } => rays.uniform(&mut rng, r.max(1), out),
            Sampling::Adaptive { edge_rays, lattice } => {
                rays.adaptive(&mut rng, edge_rays, lattice, first, out)
            }
        };
        let skipped = rays.skipped.get();
        RayCounts {
            traced: counted - skipped,
            degenerate: 0,
            known_open: skipped,
        }
    }
}

/// The shadow rays of one traced vertex: origin `x + ε n`, local frame, grid.
struct VertexRays<'a> {
    bvh: &'a SceneBvh,
    grid: &'a SphereGrid,
    frame: [Vec3; 3],
    world_from_env: Matrix3<f64>,
    origin: Vec3,
    eps: f64,
    /// The BVH primitive that blocked the vertex's last blocked ray, tested first for the
    /// next one ([`SceneBvh::occluded_hinted`]): neighbouring texels' rays are mostly
    /// blocked by the same triangle.
    blocker: std::cell::Cell<u32>,
    /// Texels in a cone proven empty ([`OpenCones::mark_open`]): their rays escape.
    sure_open: &'a [bool],
    /// Rays answered by `sure_open` instead of traced.
    skipped: std::cell::Cell<u64>,
}

impl VertexRays<'_> {
    /// Whether the ray through point `(a, b) ∈ [0, 1)²` of texel `t` escapes.
    fn escapes(&self, t: usize, a: f64, b: f64) -> bool {
        if self.sure_open[t] {
            self.skipped.set(self.skipped.get() + 1);
            return true;
        }
        let n = self.grid.n;
        let (i, j) = ((t % n) as f64, (t / n) as f64);
        let nf = n as f64;
        let local = self.grid.decode([(i + a) / nf, (j + b) / nf]);
        let dir = self.world_from_env * from_local(&self.frame, &local);
        let mut hint = self.blocker.get();
        let blocked =
            self.bvh
                .occluded_hinted(&self.origin, &dir, self.eps, f64::INFINITY, &mut hint);
        self.blocker.set(hint);
        !blocked
    }

    /// How many of `r` jittered rays through texel `t` escape: stratified on a `√r × √r`
    /// grid of the texel's `uv` square when `r` is a perfect square, uniform otherwise.
    fn count(&self, rng: &mut Pcg64, t: usize, r: usize) -> usize {
        let strata = (r as f64).sqrt().round() as usize;
        let stratified = strata * strata == r;
        (0..r)
            .filter(|&k| {
                let (a, b) = if stratified {
                    stratum_point(rng, k, strata)
                } else {
                    (rng.random::<f64>(), rng.random::<f64>())
                };
                self.escapes(t, a, b)
            })
            .count()
    }

    /// The first ray of texel `t`: uniform over the texel when `strata` is 1, else uniform in
    /// a stratum of the `strata × strata` grid drawn at random (so still uniform over the
    /// texel). Returns whether it escaped and its stratum.
    fn first_ray(&self, rng: &mut Pcg64, t: usize, strata: usize) -> (bool, usize) {
        if strata <= 1 {
            return (self.count(rng, t, 1) == 1, 0);
        }
        let k = rng.random_range(0..strata * strata);
        let (a, b) = stratum_point(rng, k, strata);
        (self.escapes(t, a, b), k)
    }

    /// How many of the rays through the strata of a `strata × strata` grid of texel `t`
    /// other than `skip` escape (one uniform ray in each).
    fn count_other_strata(&self, rng: &mut Pcg64, t: usize, strata: usize, skip: usize) -> usize {
        (0..strata * strata)
            .filter(|&k| k != skip)
            .filter(|&k| {
                let (a, b) = stratum_point(rng, k, strata);
                self.escapes(t, a, b)
            })
            .count()
    }

    /// `r` rays in every texel; returns the rays traced.
    fn uniform(&self, rng: &mut Pcg64, r: usize, out: &mut [u8]) -> u64 {
        for (t, o) in out.iter_mut().enumerate() {
            *o = quantise(self.count(rng, t, r), r);
        }
        (out.len() * r) as u64
    }

    /// One ray per texel (or per lattice texel, and between them where needed), then
    /// `edge_rays` more in the texels with a disagreeing neighbour (8-connected, within
    /// the map); returns the rays traced.
    fn adaptive(
        &self,
        rng: &mut Pcg64,
        edge_rays: usize,
        lattice: usize,
        first: &mut FirstRays,
        out: &mut [u8],
    ) -> u64 {
        let strata = shared_strata(edge_rays);
        let mut traced = if lattice >= 2 {
            self.first_rays_on_lattice(rng, strata, first)
        } else {
            first.reset(out.len());
            for t in 0..out.len() {
                (first.open[t], first.stratum[t]) = self.first_ray(rng, t, strata);
            }
            out.len() as u64
        };
        for (t, o) in out.iter_mut().enumerate() {
            let seen = usize::from(first.open[t]);
            *o = if !on_edge(&first.open, self.grid.n, t) {
                quantise(seen, 1)
            } else if first.inferred[t] {
                // Its first value was a neighbour's, not a sample of this texel: only the
                // edge rays (uniform over the texel, or one per stratum) estimate it.
                let r = if strata > 1 {
                    strata * strata
                } else {
                    edge_rays
                };
                traced += r as u64;
                quantise(self.count(rng, t, r), r)
            } else if strata > 1 {
                traced += edge_rays as u64;
                let more = self.count_other_strata(rng, t, strata, first.stratum[t]);
                quantise(seen + more, edge_rays + 1)
            } else {
                traced += edge_rays as u64;
                quantise(seen + self.count(rng, t, edge_rays), edge_rays + 1)
            };
        }
        traced
    }

    /// The first-ray map of [`Sampling::Adaptive`] with `lattice = 2`: the first rays of the
    /// lattice texels (even row and column, or the last), then each other texel's first
    /// ray only when its two or four lattice corners disagree or it lies in the
    /// [`HORIZON_BAND`]; when they agree it takes
    /// their value and is marked inferred. Returns the rays traced.
    fn first_rays_on_lattice(&self, rng: &mut Pcg64, strata: usize, first: &mut FirstRays) -> u64 {
        let n = self.grid.n;
        first.reset(n * n);
        let on_grid = |t: usize| on_lattice(t % n, n) && on_lattice(t / n, n);
        let mut traced = 0;
        for t in (0..n * n).filter(|&t| on_grid(t)) {
            (first.open[t], first.stratum[t]) = self.first_ray(rng, t, strata);
            traced += 1;
        }
        // The lattice indices around `k`: itself when on the lattice, else `k ± 1`.
        let span = |k: usize| {
            if on_lattice(k, n) {
                (k, k)
            } else {
                (k - 1, k + 1)
            }
        };
        for t in (0..n * n).filter(|&t| !on_grid(t)) {
            let ((i0, i1), (j0, j1)) = (span(t % n), span(t / n));
            let corners = [j0 * n + i0, j0 * n + i1, j1 * n + i0, j1 * n + i1];
            let here = first.open[corners[0]];
            let agree = corners.iter().all(|&c| first.open[c] == here);
            if agree && !near_horizon(t % n, t / n, n) {
                first.open[t] = here;
                first.inferred[t] = true;
            } else {
                (first.open[t], first.stratum[t]) = self.first_ray(rng, t, strata);
                traced += 1;
            }
        }
        traced
    }
}

/// A vertex's first-ray map: per texel whether its first ray escaped, and whether that
/// value was inferred from its lattice neighbours instead of traced (a worker's scratch).
#[derive(Default)]
struct FirstRays {
    open: Vec<bool>,
    inferred: Vec<bool>,
    /// The stratum of each traced first ray ([`VertexRays::first_ray`]).
    stratum: Vec<usize>,
}

impl FirstRays {
    /// `texels` entries, every one blocked, traced (not inferred) and in stratum 0 until
    /// set.
    fn reset(&mut self, texels: usize) {
        for v in [&mut self.open, &mut self.inferred] {
            v.clear();
            v.resize(texels, false);
        }
        self.stratum.clear();
        self.stratum.resize(texels, 0);
    }
}

/// The side of the stratum grid that a texel's first ray and its `edge_rays` share when
/// `edge_rays + 1` is a perfect square of at least 4 (3, 8, …: the first ray takes one
/// stratum at random, the edge rays the others, so an edge texel's rays are stratified);
/// else 1 (the first ray uniform over the texel, the edge rays stratified among themselves).
fn shared_strata(edge_rays: usize) -> usize {
    let s = ((edge_rays + 1) as f64).sqrt().round() as usize;
    if s >= 2 && s * s == edge_rays + 1 {
        s
    } else {
        1
    }
}

/// Inner edge of the band of hemi-octahedral texels near the horizon whose first ray the
/// lattice always traces: a texel centre's `max(|2u − 1|, |2v − 1|)`, which is `1 − z/ℓ₁`
/// of its direction ([`crate::sphere::hemi_oct_decode`]; 1 on the horizon). At 0.85 the band
/// is the outer 4 texels of each 32-texel row and column, 23% of the map.
pub const HORIZON_BAND: f64 = 0.85;

/// Whether texel `(i, j)` of an `n × n` hemi-octahedral map lies in the [`HORIZON_BAND`].
fn near_horizon(i: usize, j: usize, n: usize) -> bool {
    let coord = |k: usize| (2.0 * (k as f64 + 0.5) / n as f64 - 1.0).abs();
    coord(i).max(coord(j)) >= HORIZON_BAND
}

/// Whether row or column `k` of an `n`-texel side is on the spacing-2 lattice: even, or
/// the last (so every other index lies between two lattice indices).
fn on_lattice(k: usize, n: usize) -> bool {
    k.is_multiple_of(2) || k + 1 == n
}

/// A uniform point `(a, b) ∈ [0, 1)²` of stratum `k` (row-major) of a `strata × strata` grid
/// of a texel's `uv` square (`a` drawn first).
fn stratum_point(rng: &mut Pcg64, k: usize, strata: usize) -> (f64, f64) {
    let s = strata as f64;
    let a = ((k % strata) as f64 + rng.random::<f64>()) / s;
    let b = ((k / strata) as f64 + rng.random::<f64>()) / s;
    (a, b)
}

/// `seen / rays` as a `u8` fraction (`255` = all escaped).
fn quantise(seen: usize, rays: usize) -> u8 {
    ((seen as f64 / rays as f64) * 255.0).round() as u8
}

/// Whether texel `t` of an `n × n` map has a neighbour (8-connected, within the map)
/// whose value differs from its own.
fn on_edge(values: &[bool], n: usize, t: usize) -> bool {
    let (i, j) = (t % n, t / n);
    let here = values[t];
    let rows = j.saturating_sub(1)..=(j + 1).min(n - 1);
    rows.into_iter().any(|jj| {
        let cols = i.saturating_sub(1)..=(i + 1).min(n - 1);
        cols.into_iter().any(|ii| values[jj * n + ii] != here)
    })
}

/// SplitMix64 finaliser of `seed` and `v`: independent per-vertex streams.
fn mix(seed: u64, v: u64) -> u64 {
    let mut z = seed ^ v.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
