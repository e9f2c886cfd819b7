//! relight-cpc: reflectance and per-photo illumination from a COLMAP reconstruction,
//! after Haber, Fuchs, Bekaert, Seidel, Goesele and Lensch, "Relighting objects from image
//! collections", CVPR 2009.
//!
//! Data flows one way, through one folder per pipeline stage; a stage uses only the stages
//! above it:
//!
//! ```text
//! import     workspace ─► colmap (cameras, images, points3D), mesh (PLY), photo (linear
//!            RGB, clip mask), points (fused cloud) ─► scene
//! observe    trace (BVH) ─► observations per vertex and photo; inspect
//! sphere     octahedral maps ─► haar ─► triple (tripling coefficients), rotation (R_ν),
//!            envmap (EXR in/out)
//! transport  brdf (basis slices), visibility (per-vertex V) ─► transport (T_x ρ_b per
//!            observation, Eq. 7–8); reference (the brute-force renderer of Eq. 1)
//! solve      estimate (lighting Eq. 10, materials Eq. 11–12), qp, cluster, starts,
//!            adapt, budget
//! render     raster, wavelet renderer, relight (`render` subcommand)
//! report     report.json, report.html, metrics, plots
//! export     glTF scene and environment maps for other tools
//! run        the `run` subcommand: import → observe → prepare → fit → evaluate → write
//! ```
//!
//! `synth` (built-in synthetic scenes) and `bench` (the `bench` subcommand) sit beside the
//! pipeline and use it. Conventions (directions, frames, map layouts) are fixed once, in
//! [`sphere`] and [`import::colmap`], and every other module uses those functions rather
//! than restating them.

pub mod error;
pub mod out_dir;

// Pipeline stages, in the order data flows through them.
pub mod export;
pub mod import;
pub mod observe;
pub mod render;
pub mod report;
pub mod run;
pub mod solve;
pub mod sphere;
pub mod transport;

// Built-in scenes and the `bench` subcommand, outside the pipeline.
pub mod bench;
pub mod synth;

// Wall time, CPU time and memory per stage; order statistics the stages share.
pub mod stages;
pub mod stats;

pub use error::{Error, Result};

/// 3-vectors for geometry (positions, directions) in f64.
pub type Vec3 = nalgebra::Vector3<f64>;
