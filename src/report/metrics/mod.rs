//! Image metrics of the inverse-rendering literature, so held-out figures compare with
//! published work: PSNR-H, PSNR-L and SSIM as the Stanford-ORB benchmark defines them
//! (Kuang et al., NeurIPS 2023 Datasets and Benchmarks; its evaluation code
//! `orb/utils/metrics.py` and `orb/utils/test.py`), over the object's pixels.
//!
//! Given the photo `y` (ground truth, linear RGB) and a prediction `ŷ` over the mask `M`
//! (object pixels that count):
//! - **per-channel scale** (the scale of an inverse-rendering result is unknowable):
//!   `s_c = Σ_M y_c ŷ_c / Σ_M ŷ_c²`, and `ŷ'_c = s_c ŷ_c`; a channel predicted black on the
//!   whole mask keeps `s_c = 1`;
//! - **PSNR-H** (linear HDR): both images multiplied by Stanford-ORB's brightness factor
//!   `k = Σ_M srgb(clip(y, 0, 1)) / Σ_M clip(y, 0, 1)` (its `use_gt_median`: linear
//!   images are dark, `k` brings their mean to the sRGB image's), clipped to `[0, 4]`;
//!   `PSNR = −10 log₁₀ MSE` with the MSE over the mask's pixels and channels (peak 1);
//! - **PSNR-L** (LDR): `ŷ'` and `y` clipped to `[0, 1]` and sRGB-encoded (IEC 61966-2-1),
//!   then the same PSNR;
//! - **SSIM** (Wang et al., IEEE TIP 2004) on the sRGB images of PSNR-L: per channel,
//!   local statistics under an 11 × 11 Gaussian window (σ = 1.5, taps `exp(−i²/2σ²)`,
//!   `|i| ≤ 5`, normalised), `K1 = 0.01`, `K2 = 0.03`, dynamic range 1, population
//!   (not sample) covariances:
//!   `S = (2μ_yμ_ŷ + C1)(2σ_yŷ + C2) / ((μ_y² + μ_ŷ² + C1)(σ_y² + σ_ŷ² + C2))`,
//!   `C1 = K1²`, `C2 = K2²`; image borders mirrored half-sample (`d c b a | a b c d`). This is
//!   scikit-image's `structural_similarity(gaussian_weights=True, sigma=1.5,
//!   use_sample_covariance=False, data_range=1)` map (checked against it:
//!   `scripts/ssim_reference.py`).
//!
//! **Restriction to the object.** As Stanford-ORB does, both images are set to 0 outside
//! the mask before SSIM, so windows that straddle the silhouette see the same background
//! in both. The SSIM map is then averaged over the mask's pixels only (a background pixel
//! would score a perfect 1 and reward small objects). The map is evaluated on the mask's
//! bounding box grown by the window radius (5 pixels, clamped to the image): every window
//! centred on a mask pixel lies inside it, so the crop changes no value, it only saves work.
//!
//! **Where this differs from Stanford-ORB's code.** (1) Its MSEs are means over the whole
//! 512 × 512 frame with the background zeroed (`divide_mask=False`), so they depend on how
//! much of the frame the object fills; here the MSE is over the object's pixels, which gives
//! a PSNR lower by `10 log₁₀(frame pixels / object pixels)` than theirs on the same images.
//! (2) Its SSIM is kornia's with a 3 × 3 window, averaged over the whole frame; here the
//! standard 11 × 11 Gaussian window, averaged over the object. (3) It erodes the mask by a
//! 5 × 5 box (two pixels); the run's mask leaves out one pixel at the object's edges
//! (silhouette and depth jumps, the pixels that mix the object with its surroundings) and
//! overexposed pixels. (4) It floors each PSNR at that of a constant 0.5 prediction; that is
//! not done here.

use crate::import::photo::linear_to_srgb;
use serde::Serialize;

/// SSIM's `K1`.
pub const SSIM_K1: f64 = 0.01;
/// SSIM's `K2`.
pub const SSIM_K2: f64 = 0.03;
/// SSIM's Gaussian window σ in pixels.
pub const SSIM_SIGMA: f64 = 1.5;
/// SSIM's window radius: 11 × 11 taps.
pub const SSIM_RADIUS: usize = 5;
/// PSNR-H's clipping value (Stanford-ORB's `max_value` for HDR).
pub const PSNR_H_CLIP: f64 = 4.0;

/// The literature metrics of one prediction against its photo.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct ImageMetrics {
    /// PSNR in dB of the linear images (brightness factor applied, clipped at 4).
    pub psnr_h: f64,
    /// PSNR in dB of the sRGB images (clipped to [0, 1]).
    pub psnr_l: f64,
    /// Mean SSIM of the sRGB images over the mask (mean of the three channels).
    pub ssim: f64,
    /// The per-channel scale `s_c` applied to the prediction.
    pub scale: [f64; 3],
    /// Pixels in the mask.
    pub pixels: usize,
}

/// Per-channel least-squares scale `s_c = Σ y_c ŷ_c / Σ ŷ_c²` over `mask` (1 for a channel
/// predicted black everywhere on it).
pub fn channel_scales(gt: &[[f32; 3]], pred: &[[f32; 3]], mask: &[bool]) -> [f64; 3] {
    let mut num = [0.0f64; 3];
    let mut den = [0.0f64; 3];
    for ((y, p), _) in gt.iter().zip(pred).zip(mask).filter(|(_, &m)| m) {
        for c in 0..3 {
            num[c] += y[c] as f64 * p[c] as f64;
            den[c] += p[c] as f64 * p[c] as f64;
        }
    }
    [0, 1, 2].map(|c| if den[c] > 0.0 { num[c] / den[c] } else { 1.0 })
}

/// PSNR in dB of a mean squared error against a peak of 1 (`+∞` for 0, NaN for NaN).
pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse > 0.0 {
        -10.0 * mse.log10()
    } else if mse == 0.0 {
        f64::INFINITY
    } else {
        f64::NAN
    }
}

/// Stanford-ORB's brightness factor `k = Σ srgb(clip(y, 0, 1)) / Σ clip(y, 0, 1)` over
/// `mask` (1 when the photo is black there).
pub fn gt_brightness_factor(gt: &[[f32; 3]], mask: &[bool]) -> f64 {
    let (mut enc, mut lin) = (0.0f64, 0.0f64);
    for (y, _) in gt.iter().zip(mask).filter(|(_, &m)| m) {
        for &v in y {
            let v = v.clamp(0.0, 1.0);
            lin += v as f64;
            enc += linear_to_srgb(v) as f64;
        }
    }
    if lin > 1e-8 {
        enc / lin
    } else {
        1.0
    }
}

/// PSNR-H of `pred` already scaled per channel (module docs).
pub fn psnr_h(gt: &[[f32; 3]], pred_scaled: &[[f32; 3]], mask: &[bool]) -> f64 {
    let k = gt_brightness_factor(gt, mask);
    let clip = |v: f64| (k * v).clamp(0.0, PSNR_H_CLIP);
    let (mut se, mut n) = (0.0f64, 0usize);
    for ((y, p), _) in gt.iter().zip(pred_scaled).zip(mask).filter(|(_, &m)| m) {
        for c in 0..3 {
            se += (clip(y[c] as f64) - clip(p[c] as f64)).powi(2);
        }
        n += 3;
    }
    psnr_from_mse(if n == 0 { f64::NAN } else { se / n as f64 })
}

/// sRGB encoding of a linear value clipped to `[0, 1]` (non-finite → 0).
pub fn srgb(v: f32) -> f64 {
    linear_to_srgb(if v.is_finite() { v } else { 0.0 }) as f64
}

/// PSNR-L of `pred` already scaled per channel (module docs).
pub fn psnr_l(gt: &[[f32; 3]], pred_scaled: &[[f32; 3]], mask: &[bool]) -> f64 {
    let (mut se, mut n) = (0.0f64, 0usize);
    for ((y, p), _) in gt.iter().zip(pred_scaled).zip(mask).filter(|(_, &m)| m) {
        for c in 0..3 {
            se += (srgb(y[c]) - srgb(p[c])).powi(2);
        }
        n += 3;
    }
    psnr_from_mse(if n == 0 { f64::NAN } else { se / n as f64 })
}

/// The normalised 11-tap Gaussian of SSIM (σ = 1.5).
pub fn ssim_kernel() -> [f64; 2 * SSIM_RADIUS + 1] {
    let mut k = [0.0; 2 * SSIM_RADIUS + 1];
    for (i, w) in k.iter_mut().enumerate() {
        let d = i as f64 - SSIM_RADIUS as f64;
        *w = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let s: f64 = k.iter().sum();
    k.iter_mut().for_each(|w| *w /= s);
    k
}

/// Half-sample mirror of index `i` into `0..n` (`d c b a | a b c d | d c b a`).
fn mirror(i: isize, n: usize) -> usize {
    let n = n as isize;
    let period = 2 * n;
    let mut j = i.rem_euclid(period);
    if j >= n {
        j = period - 1 - j;
    }
    j as usize
}

/// Separable Gaussian filter of a `width × height` single-channel image, mirrored borders.
/// Each output is `Σ_d k_d · in_{i+d}` summed in the order `d = −r..=r` (rows, then
/// columns); the interior, where no tap is mirrored, reads its window directly (the same
/// products in the same order as the mirrored border path).
fn gaussian_filter(img: &[f64], width: usize, height: usize) -> Vec<f64> {
    let k = ssim_kernel();
    let r = SSIM_RADIUS;
    let mirrored = |x: usize, n: usize, at: &dyn Fn(usize) -> f64| -> f64 {
        let mut acc = 0.0;
        for (j, w) in k.iter().enumerate() {
            acc += w * at(mirror(x as isize + j as isize - r as isize, n));
        }
        acc
    };
    let mut rows = vec![0.0; img.len()];
    for (src, dst) in img.chunks_exact(width).zip(rows.chunks_exact_mut(width)) {
        for (x, o) in dst.iter_mut().enumerate() {
            *o = if x >= r && x + r < width {
                let mut acc = 0.0;
                for (w, v) in k.iter().zip(&src[x - r..=x + r]) {
                    acc += w * v;
                }
                acc
            } else {
                mirrored(x, width, &|i| src[i])
            };
        }
    }
    let mut out = vec![0.0; img.len()];
    for (y, dst) in out.chunks_exact_mut(width).enumerate() {
        if y >= r && y + r < height {
            for (j, w) in k.iter().enumerate() {
                let src = &rows[(y + j - r) * width..(y + j - r + 1) * width];
                dst.iter_mut().zip(src).for_each(|(o, v)| *o += w * v);
            }
        } else {
            for (x, o) in dst.iter_mut().enumerate() {
                *o = mirrored(y, height, &|i| rows[i * width + x]);
            }
        }
    }
    out
}

/// The SSIM map of two single-channel `width × height` images on a dynamic range of 1
/// (module docs: scikit-image's Gaussian-weighted map).
pub fn ssim_map(a: &[f64], b: &[f64], width: usize, height: usize) -> Vec<f64> {
    let (c1, c2) = (SSIM_K1 * SSIM_K1, SSIM_K2 * SSIM_K2);
    let prod = |f: &dyn Fn(f64, f64) -> f64| -> Vec<f64> {
        a.iter().zip(b).map(|(&x, &y)| f(x, y)).collect()
    };
    let mu_a = gaussian_filter(a, width, height);
    let mu_b = gaussian_filter(b, width, height);
    let aa = gaussian_filter(&prod(&|x, _| x * x), width, height);
    let bb = gaussian_filter(&prod(&|_, y| y * y), width, height);
    let ab = gaussian_filter(&prod(&|x, y| x * y), width, height);
    (0..a.len())
        .map(|i| {
            let (ma, mb) = (mu_a[i], mu_b[i]);
            let va = aa[i] - ma * ma;
            let vb = bb[i] - mb * mb;
            let cov = ab[i] - ma * mb;
            ((2.0 * ma * mb + c1) * (2.0 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2))
        })
        .collect()
}

/// Inclusive pixel bounds `(x0, y0, x1, y1)` of `mask`, or `None` when it is empty.
fn mask_bounds(mask: &[bool], width: usize) -> Option<(usize, usize, usize, usize)> {
    let mut b: Option<(usize, usize, usize, usize)> = None;
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = (i % width, i / width);
        b = Some(match b {
            None => (x, y, x, y),
            Some((x0, y0, x1, y1)) => (x0.min(x), y0.min(y), x1.max(x), y1.max(y)),
        });
    }
    b
}

/// Mean SSIM over `mask` of two sRGB images (`width × height`, channels averaged), both
/// set to 0 outside the mask (module docs: restriction to the object). NaN for an empty
/// mask.
pub fn ssim_masked(
    gt: &[[f64; 3]],
    pred: &[[f64; 3]],
    width: usize,
    height: usize,
    mask: &[bool],
) -> f64 {
    let Some((x0, y0, x1, y1)) = mask_bounds(mask, width) else {
        return f64::NAN;
    };
    let x0 = x0.saturating_sub(SSIM_RADIUS);
    let y0 = y0.saturating_sub(SSIM_RADIUS);
    let x1 = (x1 + SSIM_RADIUS).min(width - 1);
    let y1 = (y1 + SSIM_RADIUS).min(height - 1);
    let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
    let index = |cx: usize, cy: usize| (y0 + cy) * width + x0 + cx;
    let mut sum = 0.0;
    let mut n = 0usize;
    for c in 0..3 {
        let crop = |img: &[[f64; 3]]| -> Vec<f64> {
            (0..cw * ch)
                .map(|j| {
                    let i = index(j % cw, j / cw);
                    if mask[i] {
                        img[i][c]
                    } else {
                        0.0
                    }
                })
                .collect()
        };
        let map = ssim_map(&crop(gt), &crop(pred), cw, ch);
        for (j, s) in map.iter().enumerate() {
            if mask[index(j % cw, j / cw)] {
                sum += s;
                n += 1;
            }
        }
    }
    sum / n as f64
}

/// PSNR-H, PSNR-L and SSIM of `pred` against the photo `gt` (linear RGB, `width × height`)
/// over `mask`, after the per-channel scale (module docs).
pub fn image_metrics(
    gt: &[[f32; 3]],
    pred: &[[f32; 3]],
    width: usize,
    height: usize,
    mask: &[bool],
) -> ImageMetrics {
    let scale = channel_scales(gt, pred, mask);
    let scaled: Vec<[f32; 3]> = pred
        .iter()
        .map(|p| [0, 1, 2].map(|c| (p[c] as f64 * scale[c]) as f32))
        .collect();
    let encode = |img: &[[f32; 3]]| -> Vec<[f64; 3]> { img.iter().map(|p| p.map(srgb)).collect() };
    ImageMetrics {
        psnr_h: psnr_h(gt, &scaled, mask),
        psnr_l: psnr_l(gt, &scaled, mask),
        ssim: ssim_masked(&encode(gt), &encode(&scaled), width, height, mask),
        scale,
        pixels: mask.iter().filter(|&&m| m).count(),
    }
}

/// One held-out photo's literature metrics under one protocol (`report.json` key
/// `metrics`).
#[derive(Debug, Clone, Serialize)]
pub struct MetricsEntry {
    /// Image name as in `images.txt`.
    pub image: String,
    /// The protocol of the prediction (`truth`, `half`, `baseline`, `mean`), on the same
    /// pixels as its `holdout` entry.
    pub protocol: String,
    /// The figures.
    #[serde(flatten)]
    pub metrics: ImageMetrics,
}

/// The headline figure: the method's held-out error over the naive baseline's, protocol
/// `half` against `baseline` on the same photos and pixels ([`crate::run`]'s baseline).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Headline {
    /// `method_rmse / baseline_rmse`.
    pub ratio: f64,
    /// Mean over the photos of protocol `half`'s RMSE after the best global scale.
    pub method_rmse: f64,
    /// The same mean for protocol `baseline`.
    pub baseline_rmse: f64,
    /// Held-out photos scored under both.
    pub photos: usize,
}

impl Headline {
    /// What the figure is, in words (the report's parenthesis after it).
    pub fn explanation(&self) -> String {
        format!(
            "{} photo(s), protocol `half` against `baseline` on the same pixels, RMSE after \
             scale {:.5} against {:.5}; below 1 the fit predicts photos it never saw better \
             than the median of the training photos' colours does",
            self.photos, self.method_rmse, self.baseline_rmse
        )
    }

    /// From `(half, baseline)` RMSE pairs, one per photo (non-finite pairs left out);
    /// `None` when no pair remains or the baseline's mean is 0.
    pub fn from_pairs(pairs: &[(f64, f64)]) -> Option<Headline> {
        let ok: Vec<_> = pairs
            .iter()
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .collect();
        let n = ok.len();
        let method_rmse = ok.iter().map(|p| p.0).sum::<f64>() / n as f64;
        let baseline_rmse = ok.iter().map(|p| p.1).sum::<f64>() / n as f64;
        (n > 0 && baseline_rmse > 0.0).then(|| Headline {
            ratio: method_rmse / baseline_rmse,
            method_rmse,
            baseline_rmse,
            photos: n,
        })
    }
}

/// A training photo rendered from the fit under the true light it was taken in
/// (synthetic workspaces: `report.json` key `truth_check`).
#[derive(Debug, Clone, Serialize)]
pub struct TruthCheckEntry {
    /// Image name.
    pub image: String,
    /// RMSE (linear RGB) after the per-channel scale, under the photo's true light.
    pub rmse_true_light: f64,
    /// `rmse_true_light` over the photo's RMS on the same pixels.
    pub relative_true_light: f64,
    /// The per-channel scale under the true light.
    pub scale_true_light: [f64; 3],
    /// The same figures for the photo's fitted light (same renderer, same pixels).
    pub rmse_fitted_light: f64,
    /// `rmse_fitted_light` over the photo's RMS.
    pub relative_fitted_light: f64,
    /// The floor: the TRUE reflectance (the truth's materials and weights in its own
    /// lobes) rendered the same way under the true light; absent when the truth uses a lobe
    /// of a type this build does not know.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_true_reflectance: Option<f64>,
    /// `rmse_true_reflectance` over the photo's RMS.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_true_reflectance: Option<f64>,
    /// Pixels compared.
    pub pixels: usize,
}

/// The fit's mean relative error under the true light over the floor's mean (the true
/// reflectance rendered the same way): how far above what the photos allow the fit is, the
/// figure the "held-out error ≤ 1.2× the photo floor" reads. `None` unless every
/// photo has a floor.
pub fn truth_check_floor_ratio(rows: &[TruthCheckEntry]) -> Option<f64> {
    let floors: Option<Vec<f64>> = rows.iter().map(|t| t.relative_true_reflectance).collect();
    let floors = floors.filter(|f| !f.is_empty())?;
    let fit: f64 = rows.iter().map(|t| t.relative_true_light).sum();
    Some(fit / floors.iter().sum::<f64>())
}

/// Diffuse albedo per material, recovered against the truth (synthetic workspaces:
/// `report.json` key `albedo_truth`, [`crate::run`]'s `truth_check` module).
#[derive(Debug, Clone, Serialize, Default)]
pub struct AlbedoTruth {
    /// The per-channel scale `s_c = Σ_x b_{x,c} β_{x,c} / Σ_x β_{x,c}²` applied to the
    /// recovered albedo: the least-squares match of the recovered per-vertex diffuse
    /// albedo `β` to the true one `b` (the scale photos cannot fix, whatever the anchor).
    pub scale: [f64; 3],
    /// Vertices compared (those with a blending weight in both).
    pub vertices: usize,
    /// Per recovered material.
    pub materials: Vec<AlbedoTruthEntry>,
    /// The largest `|ratio_error|` over materials and channels.
    pub max_ratio_error: f64,
    /// The largest finite `|pure_ratio_error|` over materials and channels.
    pub max_pure_ratio_error: f64,
    /// The diffuse albedo ratios between materials (issue 25's target): over every ordered
    /// pair of materials `(k, l)` and channel, `|(1 + m_k) / (1 + m_l) − 1|` with `m` the
    /// [`AlbedoTruthEntry::pure_median_error`]s, the largest finite one (0 with fewer than two
    /// materials). Free of the per-channel scale: `s_c` cancels in the ratio.
    pub max_median_ratio_error: f64,
}

/// One recovered material's diffuse albedo against its true material's.
#[derive(Debug, Clone, Serialize)]
pub struct AlbedoTruthEntry {
    /// Index of the recovered material.
    pub material: usize,
    /// The true material it stands for: the most frequent true dominant material over the
    /// vertices this material dominates.
    pub true_material: String,
    /// The share of those vertices whose true dominant material is `true_material`.
    pub agreement: f64,
    /// Recovered `λ_{k,lambert,c}` (after the run's scale anchor).
    pub recovered: [f64; 3],
    /// `s_c` × recovered.
    pub recovered_scaled: [f64; 3],
    /// The true diffuse albedo.
    pub truth: [f64; 3],
    /// `recovered_scaled / truth − 1` per channel.
    pub ratio_error: [f64; 3],
    /// Vertices of the true material alone (true weight ≥ [`PURE_WEIGHT`]) that this
    /// material dominates.
    pub pure_vertices: usize,
    /// Over those vertices, the mean scaled per-vertex diffuse albedo `s_c β_{x,c}` over the
    /// truth, − 1, per channel (NaN without such vertices). Unlike [`Self::ratio_error`] it
    /// does not depend on how free blending weights are normalised between `w` and `λ`.
    pub pure_ratio_error: [f64; 3],
    /// Over the same vertices, the median of `s_c β_{x,c}` over the truth, − 1, per channel
    /// (NaN without such vertices): the material's own albedo, which the vertices whose
    /// colour the photos leave open (surfaces seen at grazing angles, dark and by few
    /// cameras, or by none) do not move as they move the mean: their weights cannot go below
    /// zero, so their noise only adds other materials.
    pub pure_median_error: [f64; 3],
    /// The share of those vertices whose `s_c β_{x,c}` is off the truth by more than
    /// [`PURE_OFF`] in some channel (0 without such vertices).
    pub pure_off_share: f64,
}

/// `pure_ratio_error` as `"+e / +e / +e (n)"`, or `–` without pure vertices.
pub fn pure_errors(m: &AlbedoTruthEntry) -> String {
    pure_column(m, m.pure_ratio_error, &m.pure_vertices.to_string())
}

/// One pure-vertex column: `"+e / +e / +e (note)"`, or `–` without pure vertices.
fn pure_column(m: &AlbedoTruthEntry, e: [f64; 3], note: &str) -> String {
    if m.pure_vertices == 0 {
        return "–".into();
    }
    format!("{:+.4} / {:+.4} / {:+.4} ({note})", e[0], e[1], e[2])
}

/// Least true blending weight of a vertex that counts as its true material alone.
pub const PURE_WEIGHT: f64 = 0.95;

/// How far a pure vertex's scaled diffuse albedo may be off the truth in a channel before
/// [`AlbedoTruthEntry::pure_off_share`] counts it: 10%, three times the 3% target
/// for the materials' ratios, so a vertex counted is off by more than any material may be.
pub const PURE_OFF: f64 = 0.1;

/// `pure_median_error` as `"+e / +e / +e"` with the off share in percent, or `–` without
/// pure vertices.
pub fn pure_median_errors(m: &AlbedoTruthEntry) -> String {
    let note = format!(
        "{:.1}% off by > {:.0}%",
        100.0 * m.pure_off_share,
        100.0 * PURE_OFF
    );
    pure_column(m, m.pure_median_error, &note)
}

/// The element at index `⌊n / 2⌋` of `values` in ascending order (NaN when empty): the
/// median for an odd count, the upper of the two middle values for an even one. The
/// report's median pure-vertex albedo ([`AlbedoTruthEntry::pure_median_error`]) and the
/// ablation's ratio errors read the same element.
pub fn upper_median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// [`AlbedoTruth::max_median_ratio_error`] of `materials`.
pub fn max_median_ratio_error(materials: &[AlbedoTruthEntry]) -> f64 {
    let mut worst: f64 = 0.0;
    for a in materials {
        for b in materials {
            if std::ptr::eq(a, b) {
                continue;
            }
            for c in 0..3 {
                let r = (1.0 + a.pure_median_error[c]) / (1.0 + b.pure_median_error[c]) - 1.0;
                if r.is_finite() {
                    worst = worst.max(r.abs());
                }
            }
        }
    }
    worst
}

/// RMSE over `mask`'s pixels and channels of `gt − s ⊙ pred` with the per-channel scale
/// `s` of [`channel_scales`], and the RMS of `gt` there: `(rmse, rms, s)`.
pub fn rmse_after_channel_scale(
    gt: &[[f32; 3]],
    pred: &[[f32; 3]],
    mask: &[bool],
) -> (f64, f64, [f64; 3]) {
    let s = channel_scales(gt, pred, mask);
    let (mut se, mut yy, mut n) = (0.0f64, 0.0f64, 0usize);
    for ((y, p), _) in gt.iter().zip(pred).zip(mask).filter(|(_, &m)| m) {
        for c in 0..3 {
            se += (y[c] as f64 - s[c] * p[c] as f64).powi(2);
            yy += (y[c] as f64).powi(2);
        }
        n += 3;
    }
    if n == 0 {
        return (f64::NAN, f64::NAN, s);
    }
    ((se / n as f64).sqrt(), (yy / n as f64).sqrt(), s)
}

#[cfg(test)]
mod tests;
