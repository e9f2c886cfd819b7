//! The sample points of the sky bases' texel averages ([`super::SkyBasis`]): per texel of
//! the full octahedral grid of side `n`, its `sub × sub` sub-texels' centre directions
//! `ω_i` and exact solid angles `Ω_i` ([`SphereGrid::sample_points`]), so that a basis
//! texel is `B_t = Σ_i Ω_i B(ω_i) / Σ_i Ω_i`.
//!
//! None of it depends on `θ`, and the `θ` search builds a basis per candidate (hundreds a
//! lighting step): computing each sub-texel's direction and solid angle again per
//! candidate cost a `--light sky` run 23–30% of its CPU
//! (`bench-results/sky-texel-samples.md`). They are computed once per `(n, sub)` and
//! shared, with each sample's view zenith angle `θ_v = acos ω_z` that the Hosek–Wilkie sky
//! reads, and the ground basis, which depends on no `θ` at all (the search takes its
//! responses once per photo from its Haar coefficients, also computed here, `SearchData::new`
//! in [`super::search`]). Every value is computed
//! by the same expressions in the same order as before, so the bases are the same to the
//! last bit.
//!
//! Where the basis is smooth across a texel the sky and the sun lobe average a coarser set
//! of samples instead ([`SkySampling`], `bench-results/sky-sampling.md`).

use std::sync::{Arc, Mutex, OnceLock};

use crate::sphere::{haar, SphereGrid};
use crate::Vec3;

/// Where the sky basis averages fewer samples per texel ([`super::SkyBasis::sky_map`]): the
/// Hosek–Wilkie radiance peaks only around the sun (its circumsolar and Mie terms) and
/// steepens only near the horizon (its `√cos θ_v` term), so a texel wholly
/// `above_horizon` radians above the horizon and at least `from_sun` radians (plus its own
/// radius) from the sun takes `coarse_sub × coarse_sub` sub-texels instead of
/// [`super::SUB_TEXELS`]².
///
/// The sun lobe's texels take the coarse samples where the lobe is below
/// `e^{−lobe_exponent}` of its peak ([`SkySampling::lobe_negligible_at`]).
#[derive(Debug, Clone, Copy)]
pub struct SkySampling {
    /// Sub-texels per side of the coarse samples.
    pub coarse_sub: usize,
    /// Least angle (radians) from the sun to a texel's nearest point for the sky's
    /// coarse samples.
    pub from_sun: f64,
    /// Least elevation (radians) of a texel's samples for the sky's coarse samples.
    pub above_horizon: f64,
    /// The exponent below the sun lobe's peak from which its texels take the coarse
    /// samples.
    pub lobe_exponent: f64,
}

impl SkySampling {
    /// Whether texel `t` of `samples` (the fine ones) may take the coarse samples under
    /// the sun `sun`.
    pub fn smooth_at(&self, samples: &TexelSamples, t: usize, sun: &Vec3) -> bool {
        samples.lowest_z[t] >= self.above_horizon.sin()
            && samples.angle_from(t, sun) >= self.from_sun
    }

    /// Whether the sun lobe of sharpness `kappa` is below `e^{−lobe_exponent}` of its
    /// peak over all of texel `t` (`κ (1 − cos γ_min) ≥ lobe_exponent`, `γ_min` the least
    /// angle from `sun` to the texel), where the coarse samples may average it.
    pub fn lobe_negligible_at(
        &self,
        samples: &TexelSamples,
        t: usize,
        sun: &Vec3,
        kappa: f64,
    ) -> bool {
        kappa * (1.0 - samples.angle_from(t, sun).cos()) >= self.lobe_exponent
    }
}

/// [`SKY_SAMPLING`]'s exponent below the sun lobe's peak from which its texels take the
/// coarse samples ([`SkySampling::lobe_negligible_at`]): `e^{−12} ≈ 6·10⁻⁶`.
pub const LOBE_COARSE_FROM: f64 = 12.0;

/// The sky basis's sampling ([`SkySampling`]).
pub const SKY_SAMPLING: SkySampling = SkySampling {
    coarse_sub: 3,
    from_sun: 15.0 * std::f64::consts::PI / 180.0,
    above_horizon: 2.0 * std::f64::consts::PI / 180.0,
    lobe_exponent: LOBE_COARSE_FROM,
};

/// The sub-texel samples of one grid (module docs).
#[derive(Debug)]
pub struct TexelSamples {
    /// Texels per side.
    pub n: usize,
    /// Sub-texels per texel side.
    pub sub: usize,
    /// `ω_i`, texel by texel (`sub²` per texel, texel `t`'s at `t·sub²..`).
    pub dir: Vec<Vec3>,
    /// `Ω_i`.
    pub weight: Vec<f64>,
    /// `θ_v = acos ω_z` as the sky model takes it.
    pub zenith: Vec<f32>,
    /// `Σ_i Ω_i` per texel, summed in sample order.
    pub area: Vec<f64>,
    /// Each texel's solid angle ([`SphereGrid::solid_angles`]).
    pub solid_angle: Vec<f64>,
    /// The ground basis's texel averages ([`super::ground`]), the same for every `θ` and
    /// channel.
    pub ground: Vec<f64>,
    /// [`Self::ground`]'s Haar coefficients, in every channel: what the search's ground
    /// responses are taken from.
    pub ground_haar: Vec<[f64; 3]>,
    /// Per texel, the unit mean of its sample directions (its centre).
    pub centre: Vec<Vec3>,
    /// Per texel, the largest angle (radians) from [`Self::centre`] to one of its samples.
    pub radius: Vec<f64>,
    /// Per texel, the least `ω_z` of its samples.
    pub lowest_z: Vec<f64>,
}

impl TexelSamples {
    /// The samples of the full grid of side `n` at `sub × sub` sub-texels.
    pub fn new(n: usize, sub: usize) -> TexelSamples {
        let grid = SphereGrid::full(n);
        let per = sub.max(1) * sub.max(1);
        let (mut dir, mut weight) = (Vec::with_capacity(grid.len() * per), Vec::new());
        let mut area = Vec::with_capacity(grid.len());
        for t in 0..grid.len() {
            let mut a = 0.0;
            for (d, w) in grid.sample_points(t, sub) {
                dir.push(d);
                weight.push(w);
                a += w;
            }
            area.push(a);
        }
        let zenith = dir
            .iter()
            .map(|d| d.z.clamp(-1.0, 1.0).acos() as f32)
            .collect();
        let ground = (0..grid.len())
            .map(|t| {
                let i = t * per..(t + 1) * per;
                let sum: f64 = dir[i.clone()]
                    .iter()
                    .zip(&weight[i])
                    .fold(0.0, |acc, (d, w)| acc + w * super::ground(d));
                sum / area[t]
            })
            .collect::<Vec<f64>>();
        let mut h = ground.clone();
        haar::forward(&mut h, n);
        let ground_haar = h.into_iter().map(|v| [v; 3]).collect();
        let texel = |t: usize| &dir[t * per..(t + 1) * per];
        let centre: Vec<Vec3> = (0..grid.len())
            .map(|t| texel(t).iter().sum::<Vec3>().normalize())
            .collect();
        let radius = (0..grid.len())
            .map(|t| {
                let c = &centre[t];
                let least = texel(t).iter().fold(1.0_f64, |m, d| m.min(d.dot(c)));
                least.clamp(-1.0, 1.0).acos()
            })
            .collect();
        let lowest_z = (0..grid.len())
            .map(|t| texel(t).iter().fold(1.0_f64, |m, d| m.min(d.z)))
            .collect();
        TexelSamples {
            n,
            sub,
            dir,
            weight,
            zenith,
            area,
            solid_angle: grid.solid_angles(),
            ground,
            ground_haar,
            centre,
            radius,
            lowest_z,
        }
    }

    /// Samples per texel.
    pub fn per_texel(&self) -> usize {
        self.sub.max(1) * self.sub.max(1)
    }

    /// The least angle (radians) from the unit direction `dir` to texel `t`, bounded by its
    /// centre and radius: `max(0, ∠(centre_t, dir) − radius_t)`.
    pub fn angle_from(&self, t: usize, dir: &Vec3) -> f64 {
        let to_centre = self.centre[t].dot(dir).clamp(-1.0, 1.0).acos();
        (to_centre - self.radius[t]).max(0.0)
    }

    /// Per channel and texel, the mean of `f(samples, i, ω_i)` over the texel's samples:
    /// with `sampling`, the coarse ones (the same grid at `coarse_sub` sub-texels) where
    /// `use_coarse(sampling, t)`, else these.
    pub fn texel_means_mixed(
        &self,
        sampling: Option<&SkySampling>,
        use_coarse: impl Fn(&SkySampling, usize) -> bool,
        f: impl Fn(&TexelSamples, usize, &Vec3) -> [f64; 3],
    ) -> [Vec<f64>; 3] {
        let coarse = sampling.map(|k| (k, TexelSamples::shared(self.n, k.coarse_sub)));
        let n2 = self.n * self.n;
        let mut map: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n2]);
        for t in 0..n2 {
            let s = match &coarse {
                Some((k, c)) if use_coarse(k, t) => c.as_ref(),
                _ => self,
            };
            let v = s.texel_mean(t, &|i, d| f(s, i, d));
            for c in 0..3 {
                map[c][t] = v[c];
            }
        }
        map
    }

    /// Per channel, texel `t`'s mean of `f` over its solid angle:
    /// `Σ_i w_i f(i, d_i) / area_t` over its samples `i` (in order).
    pub fn texel_mean(&self, t: usize, f: &impl Fn(usize, &Vec3) -> [f64; 3]) -> [f64; 3] {
        let per = self.per_texel();
        let mut acc = [0.0_f64; 3];
        for i in t * per..(t + 1) * per {
            let v = f(i, &self.dir[i]);
            for c in 0..3 {
                acc[c] += self.weight[i] * v[c];
            }
        }
        acc.map(|a| a / self.area[t])
    }

    /// The shared samples of `(n, sub)`, computed at the first call.
    pub fn shared(n: usize, sub: usize) -> Arc<TexelSamples> {
        static CACHE: OnceLock<Mutex<Vec<Arc<TexelSamples>>>> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
        // A poisoned lock only means another thread panicked while pushing: the entries
        // present are complete.
        let mut list = cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(s) = list.iter().find(|s| s.n == n && s.sub == sub) {
            return Arc::clone(s);
        }
        let s = Arc::new(TexelSamples::new(n, sub));
        list.push(Arc::clone(&s));
        s
    }
}
