//! The imported scene: a COLMAP workspace's model, mesh, registered photos and fused points.

use std::path::PathBuf;

use crate::colmap::{Camera, Image};

/// One registered image whose photo is on disk, with its camera.
#[derive(Debug, Clone)]
pub struct View {
    /// The registered image (pose, name, 2D points).
    pub image: Image,
    /// Its camera (intrinsics and distortion).
    pub camera: Camera,
    /// The photo file.
    pub photo_path: PathBuf,
}
