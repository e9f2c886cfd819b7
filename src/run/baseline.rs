//! The naive baseline every held-out figure is judged against (issue 28): no light, no
//! reflectance, only the training photos' colours.
//!
//! - **Per-vertex median.** `m_x,c` = the median over the training observations of vertex
//!   `x` (those with blending weight `α > 0`, the ones the fit uses) of their linear colour
//!   in channel `c`, each channel on its own; an even count takes the mean of the two
//!   middle values. A vertex no training photo sees gets the median of the seen vertices'
//!   medians (per channel), so the baseline covers every pixel the method's render covers.
//! - **Interpolation.** The held-out view's raster interpolates `m` across each visible
//!   triangle with its perspective-correct barycentrics, as the method's renders
//!   interpolate per-vertex radiance ([`crate::render::shade_vertices`]).
//! - **Gain.** One gain per channel, `g_c = Σ_L y_c m_c / Σ_L m_c²` over the pixels `L` of
//!   the left half of the object (the pixels that count with `x` below the middle of the
//!   object's bounding box): the half on which protocol `half` fits the photo's light. The
//!   prediction is `g ⊙ m`, scored like `half` on the right half only.
//!
//! `headline` = mean over the held-out photos of `half`'s RMSE after scale divided by the
//! same mean of `baseline`'s, on the same pixels: below 1 the fitted reflectance and light
//! predict an unseen photo better than its training colours do.

use crate::import::mesh::Mesh;
use crate::observe::raster::Raster;
use crate::observe::Observations;
use crate::stats::median;

/// The baseline's per-vertex colours.
#[derive(Debug, Clone)]
pub(crate) struct VertexMedians {
    /// Median linear colour per vertex (unseen vertices filled, module docs).
    pub rgb: Vec<[f32; 3]>,
    /// Vertices no training observation saw.
    pub unseen: usize,
}

/// Per-vertex, per-channel medians of the observations with `weight > 0`; `None` for a
/// vertex without any.
pub fn vertex_medians(
    vertex: &[u32],
    rgb: &[[f32; 3]],
    weight: &[f32],
    n_vertices: usize,
) -> Vec<Option<[f32; 3]>> {
    // Counting sort of the observations by vertex.
    let mut start = vec![0usize; n_vertices + 1];
    for (&x, &w) in vertex.iter().zip(weight) {
        if w > 0.0 && (x as usize) < n_vertices {
            start[x as usize + 1] += 1;
        }
    }
    for i in 0..n_vertices {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut by_vertex = vec![[0.0f32; 3]; start[n_vertices]];
    for ((&x, &w), c) in vertex.iter().zip(weight).zip(rgb) {
        if w > 0.0 && (x as usize) < n_vertices {
            by_vertex[fill[x as usize]] = *c;
            fill[x as usize] += 1;
        }
    }
    let mut scratch = Vec::new();
    (0..n_vertices)
        .map(|x| {
            let obs = &by_vertex[start[x]..start[x + 1]];
            if obs.is_empty() {
                return None;
            }
            let mut out = [0.0f32; 3];
            for (c, o) in out.iter_mut().enumerate() {
                scratch.clear();
                scratch.extend(obs.iter().map(|p| p[c]).filter(|v| v.is_finite()));
                *o = median(&mut scratch).unwrap_or(0.0);
            }
            Some(out)
        })
        .collect()
}

impl VertexMedians {
    /// The baseline's colours from the training observations (module docs).
    pub(crate) fn from_observations(obs: &Observations, n_vertices: usize) -> Self {
        let medians = vertex_medians(&obs.vertex, &obs.rgb, &obs.weight, n_vertices);
        fill_unseen(&medians)
    }
}

/// Fill the vertices without a median with the per-channel median of the others' (0 when
/// no vertex was seen).
pub(crate) fn fill_unseen(medians: &[Option<[f32; 3]>]) -> VertexMedians {
    let seen: Vec<[f32; 3]> = medians.iter().flatten().copied().collect();
    let mut fallback = [0.0f32; 3];
    let mut scratch: Vec<f32> = Vec::with_capacity(seen.len());
    for (c, f) in fallback.iter_mut().enumerate() {
        scratch.clear();
        scratch.extend(seen.iter().map(|p| p[c]));
        *f = median(&mut scratch).unwrap_or(0.0);
    }
    VertexMedians {
        rgb: medians.iter().map(|m| m.unwrap_or(fallback)).collect(),
        unseen: medians.len() - seen.len(),
    }
}

/// The baseline's prediction of a held-out view: the medians interpolated over `raster`,
/// times the per-channel gain fitted on `photo` over `fit_mask` (the left half). Returns
/// the prediction (background 0) and the gain.
pub(crate) fn predict(
    mesh: &Mesh,
    raster: &Raster,
    medians: &VertexMedians,
    photo: &[[f32; 3]],
    fit_mask: &[bool],
) -> (Vec<[f32; 3]>, [f64; 3]) {
    let m = crate::render::shade_vertices(raster, mesh, &medians.rgb);
    let gain = crate::report::metrics::channel_scales(photo, &m, fit_mask);
    let pred = m
        .iter()
        .map(|p| [0, 1, 2].map(|c| (p[c] as f64 * gain[c]) as f32))
        .collect();
    (pred, gain)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_per_vertex_and_channel_by_brute_force() {
        // Vertex 0: red 0.1, 0.5, 0.3 (α > 0) and 0.9 at α = 0 (ignored) → 0.3;
        // vertex 1: 0.2, 0.4 (even count) → 0.3; vertex 2 unseen → filled with the
        // median of the seen medians.
        let vertex = [0u32, 0, 0, 0, 1, 1];
        let weight = [1.0f32, 0.5, 1.0, 0.0, 1.0, 1.0];
        let rgb = [
            [0.1f32, 1.0, 5.0],
            [0.5, 2.0, 4.0],
            [0.3, 3.0, 3.0],
            [0.9, 9.0, 9.0],
            [0.2, 0.0, 1.0],
            [0.4, 1.0, 2.0],
        ];
        let m = vertex_medians(&vertex, &rgb, &weight, 3);
        assert_eq!(m[0], Some([0.3, 2.0, 4.0]));
        assert_eq!(m[1], Some([0.3, 0.5, 1.5]));
        assert_eq!(m[2], None);
        let filled = fill_unseen(&m);
        assert_eq!(filled.unseen, 1);
        // Median of {0.3, 0.3}, {2.0, 0.5}, {4.0, 1.5}.
        assert_eq!(filled.rgb[2], [0.3, 1.25, 2.75]);
    }
}
