//! The search for one photo's non-linear sun and sky values `θ = (s, T, κ)` with the
//! residual fixed (module docs of [`crate::solve::light::sky`]): for each candidate the
//! nine colour weights by NNLS and the weighted squared error; a grid of sun directions,
//! then a pattern search with halving steps. The sky basis depends on the sun and `T`, the
//! lobe on the sun and `κ`, so a move in `κ` reuses the sky (the Hosek–Wilkie radiance at
//! every sub-texel, most of a `--light sky` run's time) and its response, and a move in
//! `T` the lobe; and the grid's maps, which depend on no photo, are made once per process
//! (`grid_maps`). On the built-in example `--light auto` takes 0.85× the wall time,
//! `--light sky` 0.82× on `spot-sky` and 0.79× on geotagged `spot-sky` (the sun fixed,
//! only `κ` and `T` searched), every figure the same (`bench-results/sky-basis-reuse.md`).

use nalgebra::{DMatrix, DVector};
use std::sync::{Arc, Mutex, MutexGuard};

use super::{
    SkyBasis, SunSky, TexelSamples, GRID_SUNS, GROUND, KAPPA_RANGE, N_BASIS, SKY, SUB_TEXELS, SUN,
};
use crate::solve::light::system::PhotoSystem;
use crate::solve::problem::haar3;
use crate::solve::qp::{nnls, NnlsOptions};
use crate::Result;

/// Which of the pattern search's coordinates `(azimuth, elevation, ln κ, T)` move.
pub type FreeCoords = [bool; 4];
/// Every coordinate free.
pub const ALL_FREE: FreeCoords = [true; 4];
/// The sun's direction fixed (a geotag gives it): only `κ` and `T` move.
pub const SUN_FIXED: FreeCoords = [false, false, true, true];

/// One evaluated `θ`: its bases, NNLS weights and weighted squared error. The bases are
/// the search's kept maps, shared: a search evaluates hundreds of `θ` and keeps one, so
/// the [`SkyBasis`] is assembled only when asked for ([`Candidate::basis`]).
#[derive(Clone)]
pub struct Candidate {
    /// The non-linear values.
    pub theta: SunSky,
    /// The sky map at `theta` (with its response).
    sky: Arc<Part>,
    /// The sun lobe at `theta` (with its response).
    lobe: Arc<Part>,
    /// The samples whose ground map completes the bases.
    samples: Arc<TexelSamples>,
    /// `w_{j,c}` (basis, channel), `≥ 0`.
    pub weights: [[f64; 3]; N_BASIS],
    /// `Σ_q Σ_c d_{q,c} (y_{q,c} − Σ_j w_{j,c} s_{q,j,c})²`.
    pub sse: f64,
}

/// The nine weights by NNLS, per channel independently, from the bases' responses
/// `resp[j][q][c]` (basis `j`'s prediction of row `q`), the row weights `dw` and targets
/// `y`; and the weighted squared error at them.
pub fn weights_nnls(
    resp: [&[[f64; 3]]; N_BASIS],
    dw: &[[f64; 3]],
    y: &[[f64; 3]],
) -> Result<([[f64; 3]; N_BASIS], f64)> {
    let mut w = [[0.0; 3]; N_BASIS];
    let mut sse = 0.0;
    for c in 0..3 {
        let mut g = DMatrix::<f64>::zeros(N_BASIS, N_BASIS);
        let mut rhs = DVector::<f64>::zeros(N_BASIS);
        let mut yy = 0.0;
        for (q, (d, yq)) in dw.iter().zip(y).enumerate() {
            let (d, t) = (d[c], yq[c]);
            if d == 0.0 {
                continue;
            }
            yy += d * t * t;
            for j in 0..N_BASIS {
                let sj = resp[j][q][c];
                rhs[j] += d * sj * t;
                for k in j..N_BASIS {
                    g[(j, k)] += d * sj * resp[k][q][c];
                }
            }
        }
        for j in 0..N_BASIS {
            for k in 0..j {
                g[(j, k)] = g[(k, j)];
            }
        }
        let x = nnls(&g, &rhs, &NnlsOptions::default())?;
        let quad = (&g * &x).dot(&x);
        sse += (yy - 2.0 * rhs.dot(&x) + quad).max(0.0);
        for j in 0..N_BASIS {
            w[j][c] = x[j];
        }
    }
    Ok((w, sse))
}

/// What the search reads for one photo: its lighting system (rows, weights `dw`), the
/// targets with the residual's prediction taken off, and the ground basis's responses,
/// which no `θ` changes ([`TexelSamples::ground_haar`]); and the sky and sun-lobe bases of
/// the latest `θ`s with their responses ([`Part`]), since the pattern search's moves in
/// `κ` leave the sky as it was and its moves in `T` the lobe.
pub(crate) struct SearchData<'a> {
    /// The photo's system (its `dw` the row weights).
    sys: &'a PhotoSystem,
    /// `y − A r` per row.
    target: &'a [[f64; 3]],
    /// `A W B_ground` per row.
    ground: Vec<[f64; 3]>,
    /// The sub-texel samples of the bases.
    samples: Arc<TexelSamples>,
    /// The latest sky bases (key: sun, `T`), newest first.
    skies: Mutex<Vec<Arc<Part>>>,
    /// The latest sun lobes (key: sun, `κ`), newest first.
    lobes: Mutex<Vec<Arc<Part>>>,
}

impl Candidate {
    /// The bases at `theta`.
    pub fn basis(&self) -> SkyBasis {
        let mut maps: [[Vec<f64>; 3]; N_BASIS] = Default::default();
        maps[SKY] = self.sky.map.clone();
        maps[SUN] = self.lobe.map.clone();
        maps[GROUND] = std::array::from_fn(|_| self.samples.ground.clone());
        SkyBasis {
            n: self.samples.n,
            maps,
        }
    }
}

/// One basis map at some `θ`, keyed by the bits of the values it depends on, and its
/// response `A W B` per row.
struct Part {
    key: [u64; 4],
    map: [Vec<f64>; 3],
    response: Vec<[f64; 3]>,
}

/// Bases kept per kind: a round of the pattern search moves from one point.
const PARTS_KEPT: usize = 4;

impl<'a> SearchData<'a> {
    /// The search over `sys` toward `target`.
    pub fn new(sys: &'a PhotoSystem, target: &'a [[f64; 3]]) -> SearchData<'a> {
        let samples = TexelSamples::shared(sys.n, SUB_TEXELS);
        let mut ground = vec![[0.0; 3]; target.len()];
        sys.forward_rows(&samples.ground_haar, &mut ground);
        SearchData {
            sys,
            target,
            ground,
            samples,
            skies: Mutex::new(Vec::new()),
            lobes: Mutex::new(Vec::new()),
        }
    }

    /// `θ` evaluated: bases, responses, NNLS. The same values as building
    /// [`SkyBasis::new`] afresh: a basis is reused only for the same bits of what it
    /// depends on.
    pub fn evaluate(&self, theta: SunSky) -> Result<Candidate> {
        self.evaluate_with(
            theta,
            || SkyBasis::sky_map(&self.samples, &theta),
            || SkyBasis::lobe_map(&self.samples, &theta),
        )
    }

    /// [`Self::evaluate`] with the sky and lobe maps made by `sky_map` and `lobe_map` when
    /// they are not kept.
    fn evaluate_with(
        &self,
        theta: SunSky,
        sky_map: impl FnOnce() -> Result<[Vec<f64>; 3]>,
        lobe_map: impl FnOnce() -> [Vec<f64>; 3],
    ) -> Result<Candidate> {
        let sun = [theta.sun.x, theta.sun.y, theta.sun.z].map(f64::to_bits);
        let sky_key = [sun[0], sun[1], sun[2], theta.turbidity.to_bits()];
        let lobe_key = [sun[0], sun[1], sun[2], theta.kappa.to_bits()];
        let sky = self.part(&self.skies, sky_key, sky_map)?;
        let lobe = self.part(&self.lobes, lobe_key, || Ok(lobe_map()))?;
        let mut resp: [&[[f64; 3]]; N_BASIS] = [&[]; N_BASIS];
        resp[SKY] = &sky.response;
        resp[SUN] = &lobe.response;
        resp[GROUND] = &self.ground;
        let (weights, sse) = weights_nnls(resp, &self.sys.dw, self.target)?;
        Ok(Candidate {
            theta,
            sky,
            lobe,
            samples: self.samples.clone(),
            weights,
            sse,
        })
    }

    /// The basis of `key` from `kept`, or made by `make` (with its response) and kept.
    fn part(
        &self,
        kept: &Mutex<Vec<Arc<Part>>>,
        key: [u64; 4],
        make: impl FnOnce() -> Result<[Vec<f64>; 3]>,
    ) -> Result<Arc<Part>> {
        let found = lock(kept).iter().find(|p| p.key == key).cloned();
        if let Some(p) = found {
            return Ok(p);
        }
        let map = make()?;
        let mut response = vec![[0.0; 3]; self.target.len()];
        self.sys
            .forward_rows(&haar3(&map, self.sys.n), &mut response);
        let part = Arc::new(Part { key, map, response });
        let mut kept = lock(kept);
        kept.insert(0, part.clone());
        kept.truncate(PARTS_KEPT);
        Ok(part)
    }

    /// The best of [`GRID_SUNS`] sun directions evenly spread over the upper hemisphere
    /// (a Fibonacci spiral, uniform in `s_z`) at turbidity `turbidity` and lobe `kappa`.
    /// Their maps are the same for every photo and round ([`grid_maps`]).
    pub fn grid(&self, turbidity: f64, kappa: f64) -> Result<Candidate> {
        let points = grid_maps(&self.samples, turbidity, kappa)?;
        let mut best: Option<Candidate> = None;
        for p in points.iter() {
            let c = self.evaluate_with(p.theta, || Ok(p.sky.clone()), || p.lobe.clone())?;
            if best.as_ref().is_none_or(|b| c.sse < b.sse) {
                best = Some(c);
            }
        }
        Ok(best.expect("the grid has points"))
    }

    /// Pattern search over the `free` ones of `(azimuth, elevation, ln κ, T)` from
    /// `start`: each round tries `±step` per coordinate and moves on any decrease; a round
    /// without one halves every step; it ends when the angular step is below `min_angle`
    /// (radians) or after `max_evals` evaluations.
    pub fn refine(
        &self,
        start: Candidate,
        steps: [f64; 4],
        free: FreeCoords,
        min_angle: f64,
        max_evals: usize,
    ) -> Result<Candidate> {
        let mut x = clamp_coords(coords(&start.theta));
        let mut best = start;
        let mut steps = steps;
        let mut evals = 0;
        while steps[0] >= min_angle && evals < max_evals {
            let mut improved = false;
            for i in (0..4).filter(|&i| free[i]) {
                for sign in [1.0, -1.0] {
                    let mut x2 = x;
                    x2[i] += sign * steps[i];
                    let x2 = clamp_coords(x2);
                    if x2 == x {
                        continue;
                    }
                    let c = self.evaluate(from_coords(x2))?;
                    evals += 1;
                    if c.sse < best.sse {
                        best = c;
                        x = x2;
                        improved = true;
                    }
                }
            }
            if !improved {
                steps.iter_mut().for_each(|s| *s *= 0.5);
            }
        }
        Ok(best)
    }
}

/// `(azimuth, elevation, ln κ, T)` of `θ`.
fn coords(t: &SunSky) -> [f64; 4] {
    let (az, el) = t.angles();
    [az, el, t.kappa.ln(), t.turbidity]
}

/// Coordinates clamped to the model's ranges (elevation `[0, π/2]`, `κ` in
/// [`KAPPA_RANGE`], `T` in `[1, 10]`).
fn clamp_coords(x: [f64; 4]) -> [f64; 4] {
    [
        x[0],
        x[1].clamp(0.0, std::f64::consts::FRAC_PI_2),
        x[2].clamp(KAPPA_RANGE.0.ln(), KAPPA_RANGE.1.ln()),
        x[3].clamp(1.0, 10.0),
    ]
}

/// `θ` from (clamped) coordinates.
fn from_coords(x: [f64; 4]) -> SunSky {
    SunSky::from_angles(x[0], x[1], x[3], x[2].exp())
}

/// One sun of the grid ([`SearchData::grid`]): `θ` and its sky and lobe maps.
struct GridPoint {
    theta: SunSky,
    sky: [Vec<f64>; 3],
    lobe: [Vec<f64>; 3],
}

/// The grid's [`GRID_SUNS`] suns at `(turbidity, kappa)` with their maps over `samples`,
/// made at the first call per `(n, sub, turbidity, kappa)` and shared: the maps depend on
/// no photo and no round, and the grid is searched for every photo in the first rounds.
fn grid_maps(
    samples: &Arc<TexelSamples>,
    turbidity: f64,
    kappa: f64,
) -> Result<Arc<Vec<GridPoint>>> {
    type Key = (usize, usize, u64, u64);
    type Grids = Vec<(Key, Arc<Vec<GridPoint>>)>;
    static CACHE: std::sync::OnceLock<Mutex<Grids>> = std::sync::OnceLock::new();
    let key = (samples.n, samples.sub, turbidity.to_bits(), kappa.to_bits());
    let mut list = lock(CACHE.get_or_init(|| Mutex::new(Vec::new())));
    if let Some((_, points)) = list.iter().find(|(k, _)| *k == key) {
        return Ok(points.clone());
    }
    let golden = std::f64::consts::PI * (3.0 - 5.0_f64.sqrt());
    let points = (0..GRID_SUNS)
        .map(|i| {
            let z = (i as f64 + 0.5) / GRID_SUNS as f64;
            let theta = SunSky::from_angles(golden * i as f64, z.asin(), turbidity, kappa);
            Ok(GridPoint {
                theta,
                sky: SkyBasis::sky_map(samples, &theta)?,
                lobe: SkyBasis::lobe_map(samples, &theta),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let points = Arc::new(points);
    list.push((key, points.clone()));
    Ok(points)
}

/// The guard of `m`, also after a panic elsewhere (the kept bases stay valid: each is
/// complete before it is inserted).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::light::sky::SkyBasis;

    /// The pattern search's moves through one [`SearchData`], which keeps the bases of
    /// earlier `θ`s, give bit for bit what a fresh [`SearchData`] (and [`SkyBasis::new`])
    /// gives at each `θ`; a move in `κ` or `T` keeps one of the two bases.
    #[test]
    fn kept_bases_give_the_fresh_evaluation_bit_for_bit() {
        let (_t, _beta, sys) = crate::solve::light::system::tests::random_blend_system(5, 0.0);
        let target: Vec<[f64; 3]> = (0..sys.dw.len())
            .map(|q| {
                let v = 0.2 + 0.1 * ((q * 7919) % 13) as f64;
                [v, 0.8 * v, 0.6 * v]
            })
            .collect();
        let a = SunSky::from_angles(0.7, 0.5, 3.0, 64.0);
        let thetas = [
            a,
            SunSky { kappa: 128.0, ..a },
            SunSky {
                turbidity: 4.0,
                ..a
            },
            SunSky::from_angles(0.9, 0.5, 3.0, 64.0),
            a,
        ];
        let kept = SearchData::new(&sys, &target);
        for theta in thetas {
            let x = kept.evaluate(theta).unwrap();
            let fresh = SearchData::new(&sys, &target).evaluate(theta).unwrap();
            assert_eq!(x.sse.to_bits(), fresh.sse.to_bits());
            assert_eq!(x.weights, fresh.weights);
            assert_eq!(x.basis().maps, fresh.basis().maps);
            let built = SkyBasis::new(sys.n, SUB_TEXELS, &theta).unwrap();
            assert_eq!(x.basis().maps, built.maps);
        }
        // Skies: (a, T 3), (a, T 4), (moved sun, T 3); lobes: (a, κ 64), (a, κ 128),
        // (moved sun, κ 64).
        assert_eq!(lock(&kept.skies).len(), 3);
        assert_eq!(lock(&kept.lobes).len(), 3);
        // The grid from the shared maps: the lowest error of a fresh evaluation of each
        // of its suns (the first on ties), bit for bit.
        let points = grid_maps(&TexelSamples::shared(sys.n, SUB_TEXELS), 3.0, 64.0).unwrap();
        let fresh = SearchData::new(&sys, &target);
        let mut best: Option<Candidate> = None;
        for p in points.iter() {
            let c = fresh.evaluate(p.theta).unwrap();
            if best.as_ref().is_none_or(|b| c.sse < b.sse) {
                best = Some(c);
            }
        }
        let (best, grid) = (best.unwrap(), kept.grid(3.0, 64.0).unwrap());
        assert_eq!(grid.sse.to_bits(), best.sse.to_bits());
        assert_eq!(grid.basis().maps, best.basis().maps);
    }
}
