//! relight-cpc: reflectance and per-photo illumination from a COLMAP reconstruction,
//! after Haber, Fuchs, Bekaert, Seidel, Goesele and Lensch, "Relighting objects from image
//! collections", CVPR 2009.
//!
//! Data flows one way, one module per concept:
//!
//! ```text
//! workspace ─► colmap (cameras, images, points3D) ┐
//!           ─► mesh (PLY) ─► trace (BVH)          ├► scene ─► observe (observations)
//!           ─► photo (linear RGB, clip mask)      ┘
//! sphere (octahedral maps) ─► haar ─► triple (tripling coefficients) ─► rotation (R_ν)
//! envmap (EXR in/out)       brdf (basis slices)   visibility (per-vertex V)
//!                 └──────────────► transport (T_x ρ_b per observation, Eq. 7–8)
//!                                      └► solve (lighting Eq. 10, materials Eq. 11–12)
//!                                           └► render, reference, report
//! ```
//!
//! Conventions (directions, frames, map layouts) are fixed once, in [`sphere`] and
//! [`colmap`], and every other module uses those functions rather than restating them.

pub mod error;
pub mod out_dir;

// Scene import.
pub mod colmap;
pub mod mesh;
pub mod observe;
pub mod photo;
pub mod points;
pub mod scene;
pub mod trace;
pub mod workspace;

// The all-frequency core.
pub mod envmap;
pub mod haar;
pub mod rotation;
pub mod sphere;
pub mod triple;

// Light transport.
pub mod brdf;
pub mod reference;
pub mod render;
pub mod synth;
pub mod transport;
pub mod visibility;

// Estimation.
pub mod cluster;
pub mod estimate;
#[path = "solve/light/choose.rs"]
pub mod light_choose;
#[path = "solve/light/sh_prior.rs"]
pub mod light_sh_prior;
pub mod qp;
pub mod solve;
pub mod starts;

// The tool.
pub mod adapt;
pub mod bench;
pub mod budget;
pub mod export;
pub mod relight;
pub mod report;
pub mod run;
pub mod stages;

pub use error::{Error, Result};

/// 3-vectors for geometry (positions, directions) in f64.
pub type Vec3 = nalgebra::Vector3<f64>;
