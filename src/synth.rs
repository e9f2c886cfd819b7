//! Known-truth synthetic COLMAP workspaces (`relight-cpc synth`).

pub mod data;
pub mod geometry;
