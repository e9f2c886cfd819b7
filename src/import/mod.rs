//! Import: a COLMAP workspace's model (cameras, images, points3D), the mesh, the photos
//! and the fused points carried to the mesh, gathered into a [`scene::Scene`].

pub mod calendar;
pub mod colmap;
pub mod geotag;
pub mod jpeg_end;
pub mod mesh;
pub mod photo;
pub mod points;
pub mod scene;
pub mod workspace;
