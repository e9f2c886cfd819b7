//! Margins at depth edges and silhouettes: an observation within a few pixels of the
//! object's silhouette or of a depth discontinuity in its photo is down-weighted, because a
//! small misregistration (camera pose, mesh, lens) mixes the other surface into its colour.
//!
//! Per view, the mesh is rasterised ([`crate::observe::raster::rasterize`], z-buffer depth `z`).
//! A covered pixel `p` is an **edge pixel** when a 4-neighbour `q` is background (the
//! silhouette) or covered with `|z_p − z_q| > τ · min(z_p, z_q)` (a depth discontinuity,
//! `τ` = [`EdgeMargin::depth_jump`]; both sides are marked). `d(p)` is the Euclidean distance
//! from pixel `p`'s centre to the nearest edge pixel's centre, exact, by the separable
//! lower-envelope transform of Felzenszwalb & Huttenlocher ("Distance Transforms of Sampled
//! Functions", Theory of Computing 8, 2012): a 1-D squared distance transform
//! `D(x) = min_q ((x − q)² + f(q))` down every column, then along every row.
//!
//! An observation at pixel `π` keeps `α · m(d)` with the ramp
//! `m(d) = clamp((d − inner) / (outer − inner), 0, 1)` (`d` at the pixel containing `π`):
//! 0 within `inner` pixels of an edge, 1 from `outer` on, linear between, so nothing jumps.
//! A photo border is not an edge (the border margin is [`super::ObserveOptions::margin_px`]).

/// The relative depth jump between neighbouring pixels that marks a depth edge, for the
/// observations' margin ([`super::DEFAULT_EDGE_MARGIN`]) and the pixels a run scores
/// (`run::shading::valid_mask`).
pub const DEPTH_JUMP: f64 = 0.05;

/// Tunables of the margin (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeMargin {
    /// Distance (pixels) up to which the weight is 0.
    pub inner_px: f64,
    /// Distance (pixels) from which the weight is 1.
    pub outer_px: f64,
    /// Relative depth jump `τ` between neighbouring pixels that marks a discontinuity.
    pub depth_jump: f64,
}

/// Edge pixels of a depth raster (`f32::INFINITY` = background), row-major `width × height`
/// (module docs).
pub fn edge_pixels(depth: &[f32], width: usize, height: usize, depth_jump: f64) -> Vec<bool> {
    let mut edge = vec![false; depth.len()];
    let covered = |z: f32| z.is_finite();
    let jump = |a: f32, b: f32| (a - b).abs() as f64 > depth_jump * a.min(b) as f64;
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            let z = depth[i];
            // Right and down neighbours: every adjacent pair is looked at once.
            for (ok, j) in [(x + 1 < width, i + 1), (y + 1 < height, i + width)] {
                if !ok {
                    continue;
                }
                let w = depth[j];
                match (covered(z), covered(w)) {
                    (true, false) => edge[i] = true,
                    (false, true) => edge[j] = true,
                    (true, true) if jump(z, w) => {
                        edge[i] = true;
                        edge[j] = true;
                    }
                    _ => {}
                }
            }
        }
    }
    edge
}

/// 1-D squared distance transform `D(x) = min_q ((x − q)² + f(q))` (Felzenszwalb &
/// Huttenlocher's lower envelope of parabolas); `f` may hold `+∞`.
fn sdt_1d(f: &[f64], out: &mut [f64], v: &mut Vec<usize>, z: &mut Vec<f64>) {
    let n = f.len();
    v.clear();
    z.clear();
    for q in 0..n {
        if !f[q].is_finite() {
            continue;
        }
        let qf = q as f64;
        loop {
            let Some(&p) = v.last() else {
                v.push(q);
                z.push(f64::NEG_INFINITY);
                break;
            };
            let pf = p as f64;
            // Where the parabola at q overtakes the one at p.
            let s = ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
            if s <= *z.last().unwrap_or(&f64::NEG_INFINITY) {
                v.pop();
                z.pop();
            } else {
                v.push(q);
                z.push(s);
                break;
            }
        }
    }
    if v.is_empty() {
        out.iter_mut().for_each(|o| *o = f64::INFINITY);
        return;
    }
    let mut k = 0;
    for (x, o) in out.iter_mut().enumerate() {
        let xf = x as f64;
        while k + 1 < v.len() && z[k + 1] < xf {
            k += 1;
        }
        let d = xf - v[k] as f64;
        *o = d * d + f[v[k]];
    }
}

/// Euclidean distance (pixels, between pixel centres) from every pixel to the nearest
/// `true` pixel of `mask`; `+∞` everywhere when there is none (module docs).
pub fn distance_to(mask: &[bool], width: usize, height: usize) -> Vec<f32> {
    let mut d: Vec<f64> = mask
        .iter()
        .map(|&m| if m { 0.0 } else { f64::INFINITY })
        .collect();
    let (mut v, mut z) = (Vec::new(), Vec::new());
    let mut col = vec![0.0; height];
    let mut out = vec![0.0; height.max(width)];
    for x in 0..width {
        for y in 0..height {
            col[y] = d[y * width + x];
        }
        sdt_1d(&col, &mut out[..height], &mut v, &mut z);
        for y in 0..height {
            d[y * width + x] = out[y];
        }
    }
    for y in 0..height {
        let row = &mut d[y * width..(y + 1) * width];
        let input = row.to_vec();
        sdt_1d(&input, &mut out[..width], &mut v, &mut z);
        row.copy_from_slice(&out[..width]);
    }
    d.iter().map(|&s| s.sqrt() as f32).collect()
}

/// The ramp `m(d)` (module docs).
pub fn margin_factor(d: f64, m: &EdgeMargin) -> f64 {
    if d.is_nan() {
        return 0.0;
    }
    if m.outer_px <= m.inner_px {
        return if d >= m.outer_px { 1.0 } else { 0.0 };
    }
    ((d - m.inner_px) / (m.outer_px - m.inner_px)).clamp(0.0, 1.0)
}

/// Distance to the nearest edge pixel of the mesh as `camera` sees it from `image`
/// (module docs), at the camera's resolution.
pub fn edge_distance(
    mesh: &crate::import::mesh::Mesh,
    camera: &crate::import::colmap::Camera,
    image: &crate::import::colmap::Image,
    depth_jump: f64,
) -> Vec<f32> {
    let raster = crate::observe::raster::rasterize(mesh, camera, image);
    let (w, h) = (raster.width as usize, raster.height as usize);
    let edges = edge_pixels(&raster.depth, w, h, depth_jump);
    distance_to(&edges, w, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_transform_matches_brute_force() {
        // A pseudo-random sparse mask on 23 × 17: every pixel's distance against the
        // minimum over all marked pixels (exact up to f32 rounding).
        let (w, h) = (23usize, 17usize);
        let mut state = 12345u64;
        let mask: Vec<bool> = (0..w * h)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 33).is_multiple_of(29)
            })
            .collect();
        assert!(mask.iter().filter(|&&m| m).count() >= 3);
        let d = distance_to(&mask, w, h);
        for y in 0..h {
            for x in 0..w {
                let brute = (0..w * h)
                    .filter(|&j| mask[j])
                    .map(|j| {
                        let (dx, dy) = ((j % w) as f64 - x as f64, (j / w) as f64 - y as f64);
                        (dx * dx + dy * dy).sqrt()
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    (d[y * w + x] as f64 - brute).abs() < 1e-5,
                    "({x}, {y}): {} vs {brute}",
                    d[y * w + x]
                );
            }
        }
        assert!(distance_to(&[false; 6], 3, 2)
            .iter()
            .all(|v| v.is_infinite()));
    }

    #[test]
    fn edges_are_silhouettes_and_depth_jumps() {
        // 6 × 3: columns 0–1 background, 2–3 at depth 1, 4–5 at depth 2 (a jump of 100%).
        let inf = f32::INFINITY;
        let row = [inf, inf, 1.0, 1.0, 2.0, 2.0];
        let depth: Vec<f32> = row.iter().cycle().take(18).copied().collect();
        let e = edge_pixels(&depth, 6, 3, 0.05);
        for y in 0..3 {
            let r: Vec<bool> = (0..6).map(|x| e[y * 6 + x]).collect();
            // Column 2 (silhouette), columns 3 and 4 (the jump); background never.
            assert_eq!(r, vec![false, false, true, true, true, false], "row {y}");
        }
        // Below the threshold the step is not an edge.
        let e = edge_pixels(&depth, 6, 3, 1.5);
        assert!(!e[3] && !e[4] && e[2]);
    }

    #[test]
    fn ramp_is_zero_inside_one_outside_linear_between() {
        let m = EdgeMargin {
            inner_px: 1.0,
            outer_px: 3.0,
            depth_jump: 0.05,
        };
        assert_eq!(margin_factor(0.0, &m), 0.0);
        assert_eq!(margin_factor(1.0, &m), 0.0);
        assert_eq!(margin_factor(2.0, &m), 0.5);
        assert_eq!(margin_factor(3.0, &m), 1.0);
        assert_eq!(margin_factor(f64::INFINITY, &m), 1.0);
        assert_eq!(margin_factor(f64::NAN, &m), 0.0);
    }
}
