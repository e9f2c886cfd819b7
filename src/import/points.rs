//! COLMAP's fused dense point cloud (`dense/fused.ply`) carried to the mesh vertices.
//!
//! For every mesh vertex `x_v` the nearest fused point `q(v) = argmin_q |x_v − q|` is found
//! with a kiddo k-d tree (exact nearest neighbour, squared Euclidean metric). Its colour
//! (sRGB as COLMAP stores it, scaled to `[0, 1]`) and normal are carried over for
//! diagnostics and for the colour initialisation of the materials (paper Sec. 5.3), and the
//! mesh-to-points distances `d_v = |x_v − q(v)|` summarise how well the mesh fits the dense
//! reconstruction: mean, median, 95th percentile and maximum (percentiles by the
//! nearest-rank rule on the sorted distances).

use std::path::{Path, PathBuf};

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::import::mesh::{read_ply_data, Mesh};
use crate::{Error, Result, Vec3};

/// Summary of a set of distances.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct DistanceStats {
    /// Arithmetic mean.
    pub mean: f64,
    /// Median (nearest rank).
    pub median: f64,
    /// 95th percentile (nearest rank).
    pub p95: f64,
    /// Maximum.
    pub max: f64,
}

impl DistanceStats {
    /// Statistics of `d` (all zeros when empty).
    pub fn of(d: &[f64]) -> DistanceStats {
        if d.is_empty() {
            return DistanceStats::default();
        }
        let mut s = d.to_vec();
        s.sort_by(f64::total_cmp);
        let rank = |p: f64| {
            let k = ((p * s.len() as f64).ceil() as usize).clamp(1, s.len());
            s[k - 1]
        };
        DistanceStats {
            mean: s.iter().sum::<f64>() / s.len() as f64,
            median: rank(0.5),
            p95: rank(0.95),
            max: s[s.len() - 1],
        }
    }
}

/// The fused cloud's data at each mesh vertex.
#[derive(Debug, Clone, Default)]
pub struct FusedTransfer {
    /// The fused point cloud file.
    pub path: PathBuf,
    /// Number of fused points read.
    pub n_points: usize,
    /// Per mesh vertex: the nearest point's colour in `[0, 1]`, when the cloud has colours.
    pub colors: Option<Vec<[f32; 3]>>,
    /// Per mesh vertex: the nearest point's unit normal, when the cloud has normals.
    pub normals: Option<Vec<Vec3>>,
    /// Per mesh vertex: distance to the nearest point.
    pub distance: Vec<f32>,
    /// Summary of `distance`.
    pub stats: DistanceStats,
}

/// Nearest-point transfer from an in-memory cloud (module docs). Returns, per query, the
/// index of the nearest point and the distance to it. Errors when `points` is empty.
pub fn nearest_points(points: &[Vec3], queries: &[Vec3]) -> Result<Vec<(usize, f64)>> {
    if points.is_empty() {
        return Err(Error::Numeric {
            stage: "fused point transfer".into(),
            message: "the point cloud is empty".into(),
        });
    }
    let entries: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let tree: ImmutableKdTree<f64, 3> =
        ImmutableKdTree::new_from_slice(&entries).map_err(|e| Error::Numeric {
            stage: "fused point transfer".into(),
            message: format!("cannot build the k-d tree: {e:?}"),
        })?;
    let q: Vec<[f64; 3]> = queries.iter().map(|p| [p.x, p.y, p.z]).collect();
    let found = tree
        .query_batch(&q)
        .nearest_one::<SquaredEuclidean<f64>>()
        .execute();
    Ok(found
        .iter()
        .map(|r| (r.item as usize, r.distance.max(0.0).sqrt()))
        .collect())
}

/// Reads `fused.ply` (a PLY vertex list, as COLMAP's `stereo_fusion` writes it: `x y z`,
/// `nx ny nz`, `red green blue`) and transfers it to `mesh` (module docs).
pub fn transfer(path: &Path, mesh: &Mesh) -> Result<FusedTransfer> {
    let data = read_ply_data(path)?;
    if data.positions.is_empty() {
        return Err(Error::format(
            path,
            "header",
            "the point cloud has no vertices",
        ));
    }
    let nearest = nearest_points(&data.positions, &mesh.positions)?;
    let colors = data
        .colors
        .as_ref()
        .map(|c| nearest.iter().map(|&(i, _)| c[i]).collect());
    let normals = data.normals.as_ref().map(|n| {
        nearest
            .iter()
            .map(|&(i, _)| n[i].try_normalize(1e-300).unwrap_or_else(Vec3::zeros))
            .collect()
    });
    let d: Vec<f64> = nearest.iter().map(|&(_, d)| d).collect();
    Ok(FusedTransfer {
        path: path.to_path_buf(),
        n_points: data.positions.len(),
        colors,
        normals,
        distance: d.iter().map(|&x| x as f32).collect(),
        stats: DistanceStats::of(&d),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn kd_nearest_matches_brute_force() {
        let mut rng = Pcg64::seed_from_u64(3);
        let mut pt = || Vec3::new(rng.random(), rng.random(), rng.random());
        let points: Vec<Vec3> = (0..500).map(|_| pt()).collect();
        let queries: Vec<Vec3> = (0..200).map(|_| pt()).collect();
        let got = nearest_points(&points, &queries).unwrap();
        for (q, (i, d)) in queries.iter().zip(got) {
            let best = points
                .iter()
                .map(|p| (p - q).norm())
                .fold(f64::INFINITY, f64::min);
            // Same metric, exact search: equal up to the sqrt of a rounded square (1e-12).
            assert!((d - best).abs() < 1e-12);
            assert!(((points[i] - q).norm() - best).abs() < 1e-12);
        }
        assert!(nearest_points(&[], &queries).is_err());
    }

    #[test]
    fn stats_use_nearest_rank() {
        let d: Vec<f64> = (1..=20).map(|i| i as f64).collect();
        let s = DistanceStats::of(&d);
        assert_eq!(s.mean, 10.5);
        assert_eq!(s.median, 10.0); // rank ceil(0.5·20) = 10
        assert_eq!(s.p95, 19.0); // rank ceil(0.95·20) = 19
        assert_eq!(s.max, 20.0);
    }
}
