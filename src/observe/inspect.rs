//! `inspect`: the report of what import found. It loads the scene ([`load_scene`],
//! [`load_photos`]), adds the BVH and observation extraction ([`crate::observe`]) and
//! summarises per photo:
//! - `observed_vertices`: observations kept in that photo;
//! - `overexposed_fraction`: the fraction of those observations whose bilinear footprint
//!   touches an overexposed pixel (weight 0); `overexposed_pixel_fraction` is the same over
//!   all the photo's pixels;
//! - `mean_confidence`: mean `α_p` over the photo's observations;
//! - `reprojection_error_px`: mean `|π(R X + t) − x_obs|` over the photo's 2D points with a
//!   3D point ([`Reconstruction::reprojection_errors`](crate::import::colmap::Reconstruction::reprojection_errors)), leaving out (and counting in
//!   `reprojection_outliers`) errors above 4 px, the mapper's own filter threshold: they are
//!   not bundle-adjusted observations but artefacts such as keypoints that a folding radial
//!   distortion matched to far-away points, which `image_undistorter` then moves to their
//!   true place (14 of 1581 in the colmap-buddha fixture, at ~60 px each).

/// Reprojection errors above this (pixels) are outliers in [`InspectReport`]: COLMAP's
/// mapper filters observations at 4 px (`--Mapper.filter_max_reproj_error`).
pub const REPROJECTION_OUTLIER_PX: f64 = 4.0;

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use crate::import::colmap::ImageId;
use crate::import::mesh::MeshCleanup;
use crate::import::photo::{Photo, DEFAULT_CLIP};
use crate::import::points::DistanceStats;
use crate::import::scene::{load_photos, load_scene, Scene};
use crate::import::workspace::Workspace;
use crate::observe::trace::SceneBvh;
use crate::observe::{extract_with_stats, Observations, ObserveOptions, ViewStats};
use crate::Result;

/// Per-photo figures of [`InspectReport`] (module docs).
#[derive(Debug, Clone, serde::Serialize)]
pub struct ImageReport {
    /// Image name in the model.
    pub name: String,
    /// Photo width in pixels.
    pub width: u32,
    /// Photo height in pixels.
    pub height: u32,
    /// Observations kept in this photo.
    pub observed_vertices: usize,
    /// Fraction of those observations on overexposed pixels.
    pub overexposed_fraction: f64,
    /// Fraction of the photo's pixels that are overexposed.
    pub overexposed_pixel_fraction: f64,
    /// Mean confidence `α_p` over the photo's observations (0 without any).
    pub mean_confidence: f64,
    /// Mean reprojection error of the photo's 2D points with a 3D point, outliers left out
    /// (module docs); `null` without any.
    pub reprojection_error_px: Option<f64>,
    /// Observations the mean is taken over.
    pub reprojection_observations: usize,
    /// Observations left out for an error above 4 px.
    pub reprojection_outliers: usize,
    /// Number of 2D points with a 3D point in this image.
    pub points2d_with_3d: usize,
    /// Candidate counts (inside, facing, occluded, discontinuity, ...).
    pub candidates: ViewStats,
}

/// The fused point cloud's part of [`InspectReport`].
#[derive(Debug, Clone, serde::Serialize)]
pub struct FusedReport {
    /// The file.
    pub path: String,
    /// Points read.
    pub points: usize,
    /// Whether colours / normals were carried to the mesh.
    pub colors: bool,
    /// See `colors`.
    pub normals: bool,
    /// Mesh-vertex-to-nearest-point distances.
    pub distance: DistanceStats,
}

/// What `relight-cpc inspect` prints: what was found and picked, counts, per-photo figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct InspectReport {
    /// The workspace folder.
    pub workspace: String,
    /// What discovery picked and passed over.
    pub notes: Vec<String>,
    /// The model folder read.
    pub sparse_dir: String,
    /// The photo folder.
    pub images_dir: String,
    /// The mesh read.
    pub mesh_path: String,
    /// Cameras in the model.
    pub cameras: usize,
    /// Registered images in the model.
    pub images_registered: usize,
    /// 3D points in the model.
    pub points3d: usize,
    /// Mean reprojection error over all observations of all 3D points, outliers left out
    /// (pixels).
    pub mean_reprojection_error_px: Option<f64>,
    /// Vertices after cleaning.
    pub mesh_vertices: usize,
    /// Faces after cleaning.
    pub mesh_faces: usize,
    /// Faces dropped as degenerate (the rest of the cleaning is in `mesh_cleanup`).
    pub dropped_faces: usize,
    /// Everything cleaning changed.
    pub mesh_cleanup: MeshCleanup,
    /// Photos used.
    pub views_used: usize,
    /// Photos left out, with the reason.
    pub skipped: Vec<String>,
    /// Observations kept over all photos.
    pub observations: usize,
    /// Of those, the overexposed ones with a clipped channel: what `run --clipped` reads as
    /// lower bounds ([`Observations::clipped`]).
    pub clipped_observations: usize,
    /// Vertices seen by at least one photo.
    pub vertices_observed: usize,
    /// The fused point cloud, when present.
    pub fused: Option<FusedReport>,
    /// One entry per photo used, in name order.
    pub per_image: Vec<ImageReport>,
}

impl InspectReport {
    /// Builds the report from a loaded scene, its photos and the extracted observations.
    pub fn new(
        scene: &Scene,
        photos: &[Photo],
        obs: &Observations,
        stats: &[ViewStats],
    ) -> InspectReport {
        let tally = ReprojectionTally::new(scene);
        let per_image = (0..scene.views.len())
            .map(|i| image_report(scene, i, photos, obs, stats, &tally))
            .collect();
        let ws = &scene.workspace;
        InspectReport {
            workspace: ws.root.display().to_string(),
            notes: ws.notes.clone(),
            sparse_dir: ws.sparse_dir.display().to_string(),
            images_dir: ws.images_dir.display().to_string(),
            mesh_path: ws.mesh_path.display().to_string(),
            cameras: scene.recon.cameras.len(),
            images_registered: scene.recon.images.len(),
            points3d: scene.recon.points3d.len(),
            mean_reprojection_error_px: tally.mean,
            mesh_vertices: scene.mesh.positions.len(),
            mesh_faces: scene.mesh.faces.len(),
            dropped_faces: scene.cleanup.degenerate_faces + scene.cleanup.invalid_faces,
            mesh_cleanup: scene.cleanup.clone(),
            views_used: scene.views.len(),
            skipped: scene.skipped.clone(),
            observations: obs.len(),
            clipped_observations: obs.clipped.iter().filter(|&&m| m != 0).count(),
            vertices_observed: obs
                .views_per_vertex(scene.mesh.positions.len())
                .iter()
                .filter(|&&c| c > 0)
                .count(),
            fused: scene.fused.as_ref().map(|f| FusedReport {
                path: f.path.display().to_string(),
                points: f.n_points,
                colors: f.colors.is_some(),
                normals: f.normals.is_some(),
                distance: f.stats,
            }),
            per_image,
        }
    }
}

/// One image's reprojection errors: the sum of its inlier errors (pixels), its inliers
/// and its outliers (beyond [`REPROJECTION_OUTLIER_PX`]).
#[derive(Default)]
struct ImageReprojection {
    inlier_sum_px: f64,
    inliers: usize,
    outliers: usize,
}

impl ImageReprojection {
    /// The mean inlier error in pixels (`None` without inliers).
    fn mean_px(&self) -> Option<f64> {
        (self.inliers > 0).then(|| self.inlier_sum_px / self.inliers as f64)
    }
}

/// The model's reprojection errors: per image ([`ImageReprojection`]), and the mean over
/// all inliers.
struct ReprojectionTally {
    per_image: BTreeMap<ImageId, ImageReprojection>,
    mean: Option<f64>,
}

impl ReprojectionTally {
    fn new(scene: &Scene) -> Self {
        let mut per_image: BTreeMap<ImageId, ImageReprojection> = BTreeMap::new();
        let mut all = ImageReprojection::default();
        for (_, image, e) in scene.recon.reprojection_errors() {
            let s = per_image.entry(image).or_default();
            if e <= REPROJECTION_OUTLIER_PX {
                s.inlier_sum_px += e;
                s.inliers += 1;
                all.inlier_sum_px += e;
                all.inliers += 1;
            } else {
                s.outliers += 1;
            }
        }
        ReprojectionTally {
            per_image,
            mean: all.mean_px(),
        }
    }
}

/// The report of view `i` of the scene: its size, observations, overexposure, confidence,
/// reprojection errors and how many of its keypoints have a 3D point.
fn image_report(
    scene: &Scene,
    i: usize,
    photos: &[Photo],
    obs: &Observations,
    stats: &[ViewStats],
    tally: &ReprojectionTally,
) -> ImageReport {
    let v = &scene.views[i];
    let range = obs.photo_ranges.get(i).cloned().unwrap_or(0..0);
    let n = range.len();
    let w = &obs.weight[range];
    let s = stats.get(i).copied().unwrap_or_default();
    let err = tally.per_image.get(&v.image.id);
    let per_observation = |count: f64| if n > 0 { count / n as f64 } else { 0.0 };
    ImageReport {
        name: v.image.name.clone(),
        width: v.camera.width,
        height: v.camera.height,
        observed_vertices: n,
        overexposed_fraction: per_observation(s.overexposed as f64),
        overexposed_pixel_fraction: photos.get(i).map_or(0.0, |p| p.overexposed_fraction()),
        mean_confidence: per_observation(w.iter().map(|&x| x as f64).sum::<f64>()),
        reprojection_error_px: err.and_then(ImageReprojection::mean_px),
        reprojection_observations: err.map_or(0, |e| e.inliers),
        reprojection_outliers: err.map_or(0, |e| e.outliers),
        points2d_with_3d: v
            .image
            .points2d
            .iter()
            .filter(|p| p.point3d_id.is_some())
            .count(),
        candidates: s,
    }
}

/// Discovers, loads and extracts observations with the default options, and reports.
pub fn inspect(ws_root: &Path, mesh_override: Option<&Path>) -> Result<InspectReport> {
    inspect_with(
        ws_root,
        mesh_override,
        DEFAULT_CLIP,
        &ObserveOptions::default(),
    )
}

/// [`inspect`] with a chosen clip threshold and observation options.
pub fn inspect_with(
    ws_root: &Path,
    mesh_override: Option<&Path>,
    clip: f32,
    opts: &ObserveOptions,
) -> Result<InspectReport> {
    let ws = Workspace::discover(ws_root, mesh_override)?;
    let scene = load_scene(ws)?;
    let photos = load_photos(&scene, clip)?;
    let bvh = SceneBvh::new(&scene.mesh);
    let (obs, stats) = extract_with_stats(&scene.mesh, &bvh, &scene.views, &photos, opts);
    Ok(InspectReport::new(&scene, &photos, &obs, &stats))
}

impl fmt::Display for InspectReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "workspace {}", self.workspace)?;
        for n in &self.notes {
            writeln!(f, "  {n}")?;
        }
        let err = self
            .mean_reprojection_error_px
            .map_or("-".to_string(), |e| format!("{e:.3} px"));
        writeln!(
            f,
            "model: {} cameras, {} registered images, {} 3D points, mean reprojection error {err}",
            self.cameras, self.images_registered, self.points3d
        )?;
        let c = &self.mesh_cleanup;
        writeln!(
            f,
            "mesh: {} vertices, {} faces; dropped {} degenerate + {} invalid faces and {} unreferenced vertices; normals {}",
            self.mesh_vertices,
            self.mesh_faces,
            c.degenerate_faces,
            c.invalid_faces,
            c.unreferenced_vertices,
            if c.normals_computed { "computed (area-weighted)" } else { "from the file" }
        )?;
        if let Some(fr) = &self.fused {
            writeln!(
                f,
                "fused points: {} ({} points); mesh-to-points distance mean {:.4}, median {:.4}, p95 {:.4}, max {:.4}",
                fr.path, fr.points, fr.distance.mean, fr.distance.median, fr.distance.p95, fr.distance.max
            )?;
        }
        writeln!(
            f,
            "photos: {} used, {} skipped; {} observations of {} vertices",
            self.views_used,
            self.skipped.len(),
            self.observations,
            self.vertices_observed
        )?;
        for s in &self.skipped {
            writeln!(f, "  skipped {s}")?;
        }
        writeln!(
            f,
            "  with a clipped channel: {} ({:.1}%; `run --clipped` reads them as lower bounds or leaves them out)",
            self.clipped_observations,
            100.0 * self.clipped_observations as f64 / self.observations.max(1) as f64
        )?;
        writeln!(
            f,
            "  {:<24} {:>9} {:>8} {:>8} {:>9} {:>9}",
            "photo", "observed", "overexp", "mean α", "reproj px", "occluded"
        )?;
        for im in &self.per_image {
            let e = im
                .reprojection_error_px
                .map_or("-".to_string(), |e| format!("{e:.3}"));
            writeln!(
                f,
                "  {:<24} {:>9} {:>8.3} {:>8.3} {:>9} {:>9}",
                im.name,
                im.observed_vertices,
                im.overexposed_fraction,
                im.mean_confidence,
                e,
                im.candidates.occluded
            )?;
        }
        Ok(())
    }
}
