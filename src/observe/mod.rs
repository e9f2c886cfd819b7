//! Observations: which mesh vertex is seen in which photo, the linear RGB seen there and
//! its confidence — the data term of the paper's objective (Eq. 9),
//! `Σ_p α_p (y_p − ρ_xᵀ T_x L̃_I)²`, one `p` per (vertex, photo) pair kept here.
//!
//! Vertex `x` (unit normal `n`) is observed in view `I` (camera centre `C`) when all hold:
//!
//! 1. **in front and inside**: `X_cam = R x + t` has `z > 0` and its pixel `π(X_cam)` lies in
//!    `[m, W − m] × [m, H − m]` (`m = margin_px`), and the camera model does not fold there
//!    ([`Camera::project_checked`](crate::import::colmap::Camera::project_checked): unprojecting the pixel gives back the ray);
//! 2. **facing**: `cos θ = n · ω_o > min_cos`, `ω_o = (C − x) / |C − x|`;
//! 3. **unoccluded**: the ray from `C` toward `x` hits nothing before `|x − C| − δ_x`,
//!    `δ_x` = the mean length of the edges at `x` (at least [`SceneBvh::ray_offset`]).
//!    Like a z-buffer test with a tolerance of one mesh edge: geometry within an edge of the
//!    vertex cannot hide it at the mesh's own resolution. A shadow ray started at
//!    `x + ε n` can instead clip the vertex's own neighbours where the mesh is rough; on
//!    the colmap-dense-buddha Poisson mesh the two tests differ by well under 1% of the
//!    observations, nearly all the occlusion there being by geometry 30–100 edges in front.
//! 4. **not on a depth discontinuity**: four probe rays from `C` through the pixels
//!    `π(X_cam) ± (r, 0)`, `± (0, r)` (`r = probe_px`, the reach of the bilinear sample
//!    plus a margin) must hit the mesh at the depth the vertex's tangent plane predicts,
//!    `t_plane = n · (x − C) / (n · d)`, within a relative `depth_discontinuity`:
//!    `|t_hit − t_plane| ≤ τ · t_plane`. A probe that misses, hits a nearer occluder, or
//!    passes behind the silhouette flags the vertex: its pixel mixes two surfaces.
//!
//! The sample `y_p` is the photo's bilinear linear RGB at `π(X_cam)`. Its confidence is a
//! ramp in the cosine that vanishes at the cut-off, so nothing jumps at `min_cos`:
//!
//! `α_p = ((cos θ − min_cos) / (1 − min_cos))^grazing_power`, and `α_p = 0` when any pixel
//! under the bilinear footprint is overexposed (the observation is kept with zero weight,
//! so counts stay honest). Its clipped channels, those where a pixel under the footprint is
//! at the clip level, are lower bounds of the radiance: the observation records them and
//! the confidence it would have had ([`Observations::clipped`], `bound_weight`), which a fit
//! reads as a one-sided term when asked ([`crate::solve::EstimateOptions::clipped_bounds`]).
//!
//! **Margins** ([`margins`]): with [`ObserveOptions::edge_margin`], `α_p` is further
//! multiplied by a ramp in the pixel distance from `π(X_cam)` to the nearest silhouette or
//! depth edge of the rasterised mesh, 0 within `inner_px`, 1 from `outer_px` on.
//!
//! Output is a struct of arrays sorted by photo then vertex, identical for any thread count:
//! each photo's vertices are processed in parallel with rayon and collected in order.

pub mod background;
pub mod cone;
pub mod inspect;
pub mod margins;
pub mod outliers;
pub mod raster;
pub mod trace;

use std::ops::Range;

use rayon::prelude::*;

use crate::import::photo::Photo;
use crate::import::scene::View;
use crate::observe::trace::SceneBvh;
use crate::{import::mesh::Mesh, Vec3};

/// All observations, struct of arrays, sorted by photo then vertex.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Observations {
    /// Observed vertex (index into [`Mesh::positions`]).
    pub vertex: Vec<u32>,
    /// Photo index (into `Scene::views` / the `photos` slice).
    pub photo: Vec<u32>,
    /// Linear RGB sample `y_p`.
    pub rgb: Vec<[f32; 3]>,
    /// Confidence `α_p` (module docs); 0 when overexposed.
    pub weight: Vec<f32>,
    /// Unit world direction from the vertex toward the camera centre (`ω_o`, world frame).
    pub dir: Vec<[f32; 3]>,
    /// Observations of photo `i` are `photo_ranges[i]`.
    pub photo_ranges: Vec<Range<usize>>,
    /// Per observation, the channels of `rgb` that are lower bounds (bit `c`,
    /// [`crate::import::photo::Sample::clipped`]): a pixel under its footprint was at the clip
    /// level there. Empty, or one entry per observation.
    pub clipped: Vec<u8>,
    /// Per observation, the confidence an overexposed one takes when the fit reads its
    /// clipped channels as lower bounds (`α_p` as if not overexposed; 0 for the others and
    /// for any masked out): [`crate::solve::EstimateOptions::clipped_bounds`]. Empty with
    /// `clipped`.
    pub bound_weight: Vec<f32>,
}

impl Observations {
    /// Gives observation `p` no weight, as a bound too ([`Observations::bound_weight`]).
    pub fn mask_out(&mut self, p: usize) {
        self.weight[p] = 0.0;
        if let Some(b) = self.bound_weight.get_mut(p) {
            *b = 0.0;
        }
    }

    /// Gives each observation that can be read as a lower bound its bound weight as its
    /// weight, at the vertices an observation of positive weight (a value) also reads: a
    /// vertex seen only clipped would have nothing holding its weights from above.
    pub fn weigh_bounds(&mut self, n_vertices: usize) {
        let seen = self.seen_vertices(n_vertices);
        self.weigh_bounds_at(|x| seen[x]);
    }

    /// Gives each observation that can be read as a lower bound its bound weight as its
    /// weight, at the vertices `at` accepts.
    pub fn weigh_bounds_at(&mut self, at: impl Fn(usize) -> bool) {
        for (p, &b) in self.bound_weight.iter().enumerate() {
            if at(self.vertex[p] as usize) {
                self.weight[p] = self.weight[p].max(b);
            }
        }
    }

    /// Whether any observation can be read as a lower bound.
    pub fn has_bounds(&self) -> bool {
        self.bound_weight.iter().any(|&b| b > 0.0)
    }

    /// Number of observations.
    pub fn len(&self) -> usize {
        self.vertex.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.vertex.is_empty()
    }

    /// Bytes held by the arrays.
    pub fn memory_bytes(&self) -> usize {
        self.len() * (4 + 4 + 12 + 4 + 12)
            + self.clipped.len()
            + self.bound_weight.len() * 4
            + self.photo_ranges.len() * 16
    }

    /// How many photos see each of `n_vertices` vertices.
    pub fn views_per_vertex(&self, n_vertices: usize) -> Vec<u32> {
        let mut count = vec![0u32; n_vertices];
        for &v in &self.vertex {
            if let Some(c) = count.get_mut(v as usize) {
                *c += 1;
            }
        }
        count
    }

    /// Per vertex, whether an observation of positive weight reads it: the vertices the
    /// material step fits (one read only at weight 0 keeps its start weights, as one no
    /// photo sees).
    pub fn seen_vertices(&self, n_vertices: usize) -> Vec<bool> {
        let mut seen = vec![false; n_vertices];
        for (&v, &w) in self.vertex.iter().zip(&self.weight) {
            if w > 0.0 {
                if let Some(s) = seen.get_mut(v as usize) {
                    *s = true;
                }
            }
        }
        seen
    }

    /// The observations at positions `index` (ascending), in that order; each photo's
    /// range is that of its kept observations.
    pub fn gather(&self, index: &[usize]) -> Observations {
        let mut out = Observations {
            vertex: index.iter().map(|&p| self.vertex[p]).collect(),
            photo: index.iter().map(|&p| self.photo[p]).collect(),
            rgb: index.iter().map(|&p| self.rgb[p]).collect(),
            weight: index.iter().map(|&p| self.weight[p]).collect(),
            dir: index.iter().map(|&p| self.dir[p]).collect(),
            photo_ranges: Vec::with_capacity(self.photo_ranges.len()),
            clipped: gather_some(&self.clipped, index),
            bound_weight: gather_some(&self.bound_weight, index),
        };
        for range in &self.photo_ranges {
            let start = index.partition_point(|&p| p < range.start);
            let end = index.partition_point(|&p| p < range.end);
            out.photo_ranges.push(start..end);
        }
        out
    }
}

/// `v` at positions `index`, or empty when `v` is.
fn gather_some<T: Copy>(v: &[T], index: &[usize]) -> Vec<T> {
    if v.is_empty() {
        Vec::new()
    } else {
        index.iter().map(|&p| v[p]).collect()
    }
}

/// Tunables of [`extract`] (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct ObserveOptions {
    /// Pixels kept clear of the photo border (`m`). Default 2.
    pub margin_px: f64,
    /// Exponent of the grazing ramp. Default 1.
    pub grazing_power: f64,
    /// Minimum `cos θ` between normal and view direction. Default 0.1 (about 84°).
    pub min_cos: f64,
    /// Relative depth jump `τ` that marks a discontinuity. Default 0.02.
    pub depth_discontinuity: f64,
    /// Probe offset `r` in pixels; 0 disables the discontinuity test. Default 1.5.
    pub probe_px: f64,
    /// Down-weighting near silhouettes and depth edges ([`margins`]); `None`: off.
    /// Default [`DEFAULT_EDGE_MARGIN`].
    pub edge_margin: Option<margins::EdgeMargin>,
}

/// Default of [`ObserveOptions::edge_margin`].
pub const DEFAULT_EDGE_MARGIN: Option<margins::EdgeMargin> = Some(margins::EdgeMargin {
    inner_px: 1.0,
    outer_px: 3.0,
    depth_jump: margins::DEPTH_JUMP,
});

impl Default for ObserveOptions {
    fn default() -> Self {
        ObserveOptions {
            margin_px: 2.0,
            grazing_power: 1.0,
            min_cos: 0.1,
            depth_discontinuity: 0.02,
            probe_px: 1.5,
            edge_margin: DEFAULT_EDGE_MARGIN,
        }
    }
}

/// Why candidate (vertex, photo) pairs were kept or rejected, per view.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ViewStats {
    /// Vertices projecting inside the photo (with the margin).
    pub inside: usize,
    /// Of those, vertices facing the camera.
    pub facing: usize,
    /// Of those, vertices whose ray to the camera is blocked.
    pub occluded: usize,
    /// Of the unoccluded, vertices on a depth discontinuity.
    pub discontinuity: usize,
    /// Observations kept.
    pub observed: usize,
    /// Kept observations on overexposed pixels (weight 0).
    pub overexposed: usize,
    /// Kept observations given weight 0 by the edge margin ([`margins`]).
    pub near_edge: usize,
}

/// `α` for a cosine (module docs); 0 at or below `min_cos`.
pub fn grazing_confidence(cos: f64, opts: &ObserveOptions) -> f64 {
    if cos.is_nan() || cos <= opts.min_cos {
        return 0.0;
    }
    let ramp = ((cos - opts.min_cos) / (1.0 - opts.min_cos)).clamp(0.0, 1.0);
    ramp.powf(opts.grazing_power)
}

/// One kept observation before it is split into arrays.
struct Record {
    vertex: u32,
    /// Camera pixel `π(X_cam)`.
    px: [f64; 2],
    rgb: [f32; 3],
    weight: f32,
    /// Channels that are lower bounds ([`Observations::clipped`]).
    clipped: u8,
    /// The weight as a bound ([`Observations::bound_weight`]).
    bound_weight: f32,
    dir: [f32; 3],
}

enum Outcome {
    Outside,
    BackFacing,
    Occluded,
    Discontinuity,
    Kept(Record, bool),
}

/// The per-view quantities every vertex test needs.
struct ViewGeometry<'a> {
    rot: nalgebra::Matrix3<f64>,
    t: Vec3,
    center: Vec3,
    view: &'a View,
    photo: &'a Photo,
    /// Camera pixel → photo pixel scale (1 when the sizes agree, as `load_photos` checks).
    scale: [f64; 2],
}

impl<'a> ViewGeometry<'a> {
    /// The view's camera pose and the camera → photo pixel scale.
    fn new(view: &'a View, photo: &'a Photo) -> Self {
        let cam = &view.camera;
        ViewGeometry {
            rot: *view.image.cam_from_world_rotation().matrix(),
            t: Vec3::from(view.image.tvec),
            center: view.image.center(),
            view,
            photo,
            scale: [
                photo.width as f64 / cam.width.max(1) as f64,
                photo.height as f64 / cam.height.max(1) as f64,
            ],
        }
    }
}

impl ViewGeometry<'_> {
    /// Whether the probe through camera pixel `px` meets the tangent plane `(x, n)` where the
    /// mesh is (module docs, test 4).
    fn probe_agrees(&self, bvh: &SceneBvh, px: [f64; 2], x: &Vec3, n: &Vec3, tau: f64) -> bool {
        let Some(d_cam) = self.view.camera.unproject(px) else {
            return false;
        };
        let d = self.rot.transpose() * d_cam;
        let denom = n.dot(&d);
        if denom >= 0.0 {
            return false; // the probe sees the back of the tangent plane: a silhouette
        }
        let t_plane = n.dot(&(x - self.center)) / denom;
        match bvh.intersect(&self.center, &d, 0.0, f64::INFINITY) {
            Some(hit) => (hit.t - t_plane).abs() <= tau * t_plane,
            None => false,
        }
    }

    fn test(
        &self,
        mesh: &Mesh,
        bvh: &SceneBvh,
        v: usize,
        reach: f64,
        opts: &ObserveOptions,
    ) -> Outcome {
        let x = mesh.positions[v];
        let n = mesh.normals[v];
        let cam = &self.view.camera;
        let p_cam = self.rot * x + self.t;
        let Some(px) = cam.project(&p_cam) else {
            return Outcome::Outside;
        };
        let m = opts.margin_px;
        let (w, h) = (cam.width as f64, cam.height as f64);
        let inside = px[0] >= m && px[0] <= w - m && px[1] >= m && px[1] <= h - m;
        // A radial model with k < 0 folds back beyond r² = −1/(3k): points far outside the
        // view land inside the photo. The (iterative) check only for pixels that would be kept.
        if !inside || cam.project_checked(&p_cam).is_none() {
            return Outcome::Outside;
        }
        let to_cam = self.center - x;
        let dist = to_cam.norm();
        if dist.is_nan() || dist <= 0.0 {
            return Outcome::Outside;
        }
        let wo = to_cam / dist;
        let cos = n.dot(&wo);
        if cos.is_nan() || cos <= opts.min_cos {
            return Outcome::BackFacing;
        }
        // Camera ray toward the vertex, stopping one edge length short of it.
        let t_max = dist - reach.max(bvh.ray_offset());
        if t_max > 0.0 && bvh.occluded(&self.center, &(-wo), 0.0, t_max) {
            return Outcome::Occluded;
        }
        if opts.probe_px > 0.0 {
            let r = opts.probe_px;
            for off in [[r, 0.0], [-r, 0.0], [0.0, r], [0.0, -r]] {
                let probe = [px[0] + off[0], px[1] + off[1]];
                if !self.probe_agrees(bvh, probe, &x, &n, opts.depth_discontinuity) {
                    return Outcome::Discontinuity;
                }
            }
        }
        let Some(sample) = self
            .photo
            .sample_bounds([px[0] * self.scale[0], px[1] * self.scale[1]])
        else {
            return Outcome::Outside;
        };
        let (over, alpha) = (sample.overexposed, grazing_confidence(cos, opts) as f32);
        let bound = over && sample.clipped != 0;
        Outcome::Kept(
            Record {
                vertex: v as u32,
                px,
                rgb: sample.rgb,
                weight: if over { 0.0 } else { alpha },
                clipped: if bound { sample.clipped } else { 0 },
                bound_weight: if bound { alpha } else { 0.0 },
                dir: [wo.x as f32, wo.y as f32, wo.z as f32],
            },
            over,
        )
    }
}

/// Mean length of the edges at each vertex (0 for a vertex without faces); each edge is
/// counted once per incident face.
pub fn mean_edge_lengths(mesh: &Mesh) -> Vec<f64> {
    let mut sum = vec![0.0; mesh.positions.len()];
    let mut count = vec![0u32; mesh.positions.len()];
    for f in &mesh.faces {
        for j in 0..3 {
            let (a, b) = (f[j] as usize, f[(j + 1) % 3] as usize);
            let l = (mesh.positions[a] - mesh.positions[b]).norm();
            sum[a] += l;
            sum[b] += l;
            count[a] += 1;
            count[b] += 1;
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(&s, &c)| if c > 0 { s / c as f64 } else { 0.0 })
        .collect()
}

/// Extracts the observations of every vertex in every view (module docs).
/// `photos[i]` is the photo of `views[i]` (a `Photo` or a reference to one, so callers
/// need not copy full-resolution images); views without a photo are skipped.
pub fn extract<P: std::borrow::Borrow<Photo>>(
    mesh: &Mesh,
    bvh: &SceneBvh,
    views: &[View],
    photos: &[P],
    opts: &ObserveOptions,
) -> Observations {
    extract_with_stats(mesh, bvh, views, photos, opts).0
}

/// [`extract`], also returning per-view counts of kept and rejected candidates.
pub fn extract_with_stats<P: std::borrow::Borrow<Photo>>(
    mesh: &Mesh,
    bvh: &SceneBvh,
    views: &[View],
    photos: &[P],
    opts: &ObserveOptions,
) -> (Observations, Vec<ViewStats>) {
    let mut obs = Observations::default();
    let mut stats = Vec::with_capacity(views.len());
    let reach = mean_edge_lengths(mesh);
    for (i, view) in views.iter().enumerate() {
        let start = obs.len();
        let s = match photos.get(i).map(|p| p.borrow()) {
            Some(photo) => {
                let geo = ViewGeometry::new(view, photo);
                let outcomes: Vec<Outcome> = (0..mesh.positions.len())
                    .into_par_iter()
                    .with_min_len(512)
                    .map(|v| geo.test(mesh, bvh, v, reach[v], opts))
                    .collect();
                let margin = ViewMargin::new(mesh, view, opts);
                keep_outcomes(outcomes, i as u32, margin.as_ref(), &mut obs)
            }
            None => ViewStats::default(),
        };
        obs.photo_ranges.push(start..obs.len());
        stats.push(s);
    }
    (obs, stats)
}

/// One view's tested vertices tallied ([`ViewStats`]); the kept ones, their weight scaled
/// by the edge margin when on, appended to `obs` as photo `photo`.
fn keep_outcomes(
    outcomes: Vec<Outcome>,
    photo: u32,
    margin: Option<&ViewMargin>,
    obs: &mut Observations,
) -> ViewStats {
    let mut s = ViewStats::default();
    for o in outcomes {
        let Some((mut r, over)) = s.tally(o) else {
            continue;
        };
        if let Some(m) = margin {
            let f = m.factor(r.px);
            if r.weight > 0.0 && f == 0.0 {
                s.near_edge += 1;
            }
            r.weight *= f;
            r.bound_weight *= f;
        }
        s.overexposed += over as usize;
        obs.vertex.push(r.vertex);
        obs.photo.push(photo);
        obs.rgb.push(r.rgb);
        obs.weight.push(r.weight);
        obs.dir.push(r.dir);
        obs.clipped.push(r.clipped);
        obs.bound_weight.push(r.bound_weight);
    }
    s
}

impl ViewStats {
    /// Count one vertex's outcome; a kept one is returned with whether it is overexposed.
    fn tally(&mut self, o: Outcome) -> Option<(Record, bool)> {
        let (inside, facing) = (
            !matches!(o, Outcome::Outside),
            !matches!(o, Outcome::Outside | Outcome::BackFacing),
        );
        self.inside += inside as usize;
        self.facing += facing as usize;
        match o {
            Outcome::Outside | Outcome::BackFacing => None,
            Outcome::Occluded => {
                self.occluded += 1;
                None
            }
            Outcome::Discontinuity => {
                self.discontinuity += 1;
                None
            }
            Outcome::Kept(r, over) => {
                self.observed += 1;
                Some((r, over))
            }
        }
    }
}

/// The edge margin of one view ([`margins`]): each camera pixel's distance to the nearest
/// silhouette or depth edge, and the margin that turns it into a weight factor.
struct ViewMargin<'a> {
    margin: &'a margins::EdgeMargin,
    distance: Vec<f32>,
    width: usize,
    height: usize,
}

impl<'a> ViewMargin<'a> {
    /// `None` when the options have no edge margin.
    fn new(mesh: &Mesh, view: &View, opts: &'a ObserveOptions) -> Option<Self> {
        let m = opts.edge_margin.as_ref()?;
        let cam = &view.camera;
        Some(ViewMargin {
            margin: m,
            distance: margins::edge_distance(mesh, cam, &view.image, m.depth_jump),
            width: cam.width as usize,
            height: cam.height as usize,
        })
    }

    /// The weight factor at camera pixel `px` (0 outside the image).
    fn factor(&self, px: [f64; 2]) -> f32 {
        let (ix, iy) = (px[0].floor(), px[1].floor());
        let (w, h) = (self.width as f64, self.height as f64);
        let dist = if ix >= 0.0 && iy >= 0.0 && ix < w && iy < h {
            self.distance[iy as usize * self.width + ix as usize] as f64
        } else {
            0.0
        };
        margins::margin_factor(dist, self.margin) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gather_keeps_records_and_recounts_each_photos_range() {
        // Three photos of 4, 0 and 3 observations; keep positions 1, 3 (photo 0) and 5
        // (photo 2): ranges 0..2, 2..2, 2..3, every record copied whole.
        let n = 7;
        let obs = Observations {
            vertex: (0..n as u32).map(|p| 10 + p).collect(),
            photo: vec![0, 0, 0, 0, 2, 2, 2],
            rgb: (0..n).map(|p| [p as f32; 3]).collect(),
            weight: (0..n).map(|p| 0.1 * p as f32).collect(),
            dir: (0..n).map(|p| [0.0, p as f32, 1.0]).collect(),
            photo_ranges: vec![0..4, 4..4, 4..7],
            clipped: Vec::new(),
            bound_weight: Vec::new(),
        };
        let g = obs.gather(&[1, 3, 5]);
        assert_eq!(g.photo_ranges, vec![0..2, 2..2, 2..3]);
        for (i, &p) in [1usize, 3, 5].iter().enumerate() {
            assert_eq!(g.vertex[i], obs.vertex[p]);
            assert_eq!(g.photo[i], obs.photo[p]);
            assert_eq!(g.rgb[i], obs.rgb[p]);
            assert_eq!(g.weight[i], obs.weight[p]);
            assert_eq!(g.dir[i], obs.dir[p]);
        }
    }

    #[test]
    fn folded_radial_projections_are_not_observed() {
        // SIMPLE_RADIAL f = 100, c = (100, 100), k = −0.1 folds at r² = −1/(3k) = 10/3. A
        // small triangle around normalized (2.5, 0) at depth 1 distorts to 2.5·(1 − 0.625)
        // = 0.9375 → pixel x ≈ 194: inside the 200-px photo, but not where it is. The same
        // triangle around (0.5, 0.2) is observed (all three corners).
        use crate::import::colmap::{Camera, CameraId, CameraModel, Image, ImageId};
        let cam = Camera::new(
            CameraId(1),
            CameraModel::SimpleRadial,
            200,
            200,
            vec![100.0, 100.0, 100.0, -0.1],
        )
        .unwrap();
        let view = View {
            image: Image::from_pose(
                ImageId(1),
                "a",
                CameraId(1),
                &nalgebra::Rotation3::identity(),
                &Vec3::zeros(),
            ),
            camera: cam,
            photo_path: "a".into(),
        };
        let photo = Photo::from_linear(200, 200, vec![[0.5; 3]; 200 * 200]);
        for (centre, expect) in [((2.5, 0.0), 0usize), ((0.5, 0.2), 3)] {
            // Facing the camera (normal −z), 0.01 across.
            let p = |dx: f64, dy: f64| Vec3::new(centre.0 + dx, centre.1 + dy, 1.0);
            let (mesh, _) = Mesh::from_parts(
                vec![p(0.0, 0.0), p(0.0, 0.01), p(0.01, 0.0)],
                vec![[0, 1, 2]],
            );
            assert!(mesh.normals[0].z < -0.99);
            let bvh = SceneBvh::new(&mesh);
            let opts = ObserveOptions {
                probe_px: 0.0,
                ..Default::default()
            };
            let obs = extract(
                &mesh,
                &bvh,
                std::slice::from_ref(&view),
                std::slice::from_ref(&photo),
                &opts,
            );
            assert_eq!(obs.len(), expect, "triangle at {centre:?}");
        }
    }

    #[test]
    fn confidence_ramp_matches_formula() {
        let o = ObserveOptions {
            min_cos: 0.2,
            grazing_power: 2.0,
            ..Default::default()
        };
        assert_eq!(grazing_confidence(0.2, &o), 0.0);
        assert_eq!(grazing_confidence(-1.0, &o), 0.0);
        assert!((grazing_confidence(1.0, &o) - 1.0).abs() < 1e-15);
        // (0.6 − 0.2)/0.8 = 0.5, squared.
        assert!((grazing_confidence(0.6, &o) - 0.25).abs() < 1e-15);
        assert_eq!(grazing_confidence(f64::NAN, &o), 0.0);
    }
}
