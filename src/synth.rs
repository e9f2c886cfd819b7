//! Known-truth synthetic COLMAP workspaces (`relight-cpc synth`).

pub mod geometry;
