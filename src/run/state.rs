//! The state that travels between the stages of `run` ([`super::pipeline`]): one named
//! struct per stage boundary, each holding what the later stages read.

use std::sync::Arc;

use nalgebra::Matrix3;

use super::evaluate::Evaluation;
use super::truth::Truth;
use super::RunOptions;
use crate::import::photo::Photo;
use crate::import::scene::Scene;
use crate::observe::trace::SceneBvh;
use crate::observe::Observations;
use crate::solve::adapt::Decision;
use crate::sphere::rotation::Rotation;
use crate::stages::Stages;
use crate::transport::visibility::Visibility;
use crate::transport::{Transport, TransportOptions};
use crate::Vec3;

/// What every stage adds to: the stage records and the report's notes.
pub(crate) struct RunLog {
    pub(crate) stages: Stages,
    pub(crate) notes: Vec<String>,
}

/// After import: the scene, its decoded photos, the truth (synthetic workspaces) and the
/// split into training and held-out views.
pub(crate) struct Imported {
    pub(crate) scene: Scene,
    pub(crate) photos: Vec<Photo>,
    pub(crate) truth: Option<Truth>,
    /// Held-out views (indices into `scene.views`).
    pub(crate) held: Vec<usize>,
    /// Training views.
    pub(crate) train: Vec<usize>,
    /// How the held-out photos were chosen, in words.
    pub(crate) holdout_rule: String,
}

/// After observation extraction: the BVH, the training photos' observations, the training
/// views kept (duplicates dropped by the adaptive model) and the adaptive decisions so far.
pub(crate) struct Observed {
    pub(crate) bvh: SceneBvh,
    pub(crate) obs: Observations,
    pub(crate) train: Vec<usize>,
    pub(crate) decisions: Vec<Decision>,
}

/// After preparation: frames, visibility, the effective options (the adaptive pilot's
/// choices), the rotation and the transport rows.
pub(crate) struct Prepared {
    pub(crate) env_from_world: Matrix3<f64>,
    pub(crate) normals_env: Vec<Vec3>,
    pub(crate) vis: Arc<Visibility>,
    pub(crate) render_vis: Arc<Visibility>,
    /// The options in effect: `opts` with the pilot's decisions.
    pub(crate) eff: RunOptions,
    /// The pilot's material count and its reason.
    pub(crate) pilot_k: Option<(usize, String)>,
    pub(crate) mean_rgb: Vec<[f64; 3]>,
    pub(crate) seen: Vec<bool>,
    pub(crate) rot: Rotation,
    pub(crate) topts: TransportOptions,
    pub(crate) tr: Transport,
    /// Per-vertex strata of the lighting sample.
    pub(crate) strata: Vec<u32>,
}

/// After the evaluation: the held-out figures and the truth check.
pub(crate) struct Evaluated {
    pub(crate) evaluation: Evaluation,
    pub(crate) holdout_rule: String,
    pub(crate) half_fit_prior: Option<crate::report::HalfFitPriorReport>,
}
