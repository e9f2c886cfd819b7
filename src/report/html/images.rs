//! The pictures `report.html` shows, written as files beside it: the heat-map panels of
//! each held-out photo (per-pixel error `e = sqrt(⅓ Σ_c (y_c − s·ŷ_c)²)` over `[0, e_max]`,
//! `e_max` its 99th percentile over the object), maps tone-mapped with one shared exposure,
//! and box-filtered thumbnails.

use crate::sphere::envmap::LatLong;
use crate::{Error, Result};
use std::path::Path;

/// The heat map's control points (perceptually ordered black → purple → orange → yellow,
/// after matplotlib's "inferno"), evenly spaced over `[0, 1]`.
pub(super) const HEAT: [[u8; 3]; 6] = [
    [0, 0, 4],
    [66, 10, 104],
    [147, 38, 103],
    [221, 81, 58],
    [252, 165, 10],
    [252, 255, 164],
];

/// Colour of `t ∈ [0, 1]` (clamped) on the heat map, linear between control points.
pub fn heat(t: f64) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (HEAT.len() - 1) as f64;
    let i = (x.floor() as usize).min(HEAT.len() - 2);
    let f = x - i as f64;
    [0, 1, 2].map(|c| (HEAT[i][c] as f64 * (1.0 - f) + HEAT[i + 1][c] as f64 * f).round() as u8)
}

/// The CSS gradient of the heat map (for the colour bar).
pub(super) fn heat_css() -> String {
    let stops: Vec<String> = HEAT
        .iter()
        .map(|c| format!("rgb({},{},{})", c[0], c[1], c[2]))
        .collect();
    format!("linear-gradient(to right, {})", stops.join(", "))
}

/// Per-pixel error `e` (module docs) where `mask` holds, `None` elsewhere.
pub fn pixel_errors(
    photo: &[[f32; 3]],
    render: &[[f32; 3]],
    mask: &[bool],
    scale: f32,
) -> Vec<Option<f32>> {
    photo
        .iter()
        .zip(render)
        .zip(mask)
        .map(|((p, q), &m)| {
            m.then(|| {
                let s: f32 = (0..3).map(|c| (p[c] - scale * q[c]).powi(2)).sum();
                (s / 3.0).sqrt()
            })
        })
        .collect()
}

/// The `q`-quantile (0..1) of the finite values, `None` if there are none.
pub fn quantile(values: impl Iterator<Item = f32>, q: f64) -> Option<f32> {
    let mut v: Vec<f32> = values.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f32::total_cmp);
    let i = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(v[i])
}

/// The range of a difference image, written beside it as `STEM.diff.json`.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct DiffRange {
    /// Error at the bottom of the colour bar (0).
    pub min: f32,
    /// Error at the top of the colour bar (the 99th percentile over the object).
    pub max: f32,
    /// The largest error over the object.
    pub peak: f32,
}

fn save_rgb(path: &Path, w: u32, h: u32, px: &[u8]) -> Result<()> {
    image::save_buffer(path, px, w, h, image::ColorType::Rgb8).map_err(|e| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Write `STEM.photo.png`, `STEM.render.png` (after `scale`), `STEM.diff.png` (heat map,
/// grey outside the object) and `STEM.diff.json` (its range) for one view; `stem` is a path
/// without extension. `mask` marks the object pixels.
pub fn write_panels(
    stem: &Path,
    size: (u32, u32),
    photo: &[[f32; 3]],
    render: &[[f32; 3]],
    mask: &[bool],
    scale: f32,
) -> Result<DiffRange> {
    let (w, h) = size;
    let with = |ext: &str| {
        let mut s = stem.as_os_str().to_owned();
        s.push(ext);
        std::path::PathBuf::from(s)
    };
    let scaled: Vec<[f32; 3]> = render
        .iter()
        .zip(mask)
        .map(|(q, &m)| if m { q.map(|v| v * scale) } else { [0.0; 3] })
        .collect();
    crate::render::write_png(&with(".photo.png"), w, h, photo, None, 1.0)?;
    crate::render::write_png(&with(".render.png"), w, h, &scaled, None, 1.0)?;
    let e = pixel_errors(photo, render, mask, scale);
    let max = quantile(e.iter().flatten().copied(), 0.99)
        .filter(|v| *v > 0.0)
        .unwrap_or(1e-6);
    let peak = e.iter().flatten().copied().fold(0.0f32, f32::max);
    let px: Vec<u8> = e
        .iter()
        .flat_map(|v| match v {
            Some(v) => heat((*v / max) as f64),
            None => [96, 96, 96],
        })
        .collect();
    save_rgb(&with(".diff.png"), w, h, &px)?;
    let range = DiffRange {
        min: 0.0,
        max,
        peak,
    };
    let json = serde_json::to_string(&range).map_err(|e| Error::Config(e.to_string()))?;
    let jp = with(".diff.json");
    std::fs::write(&jp, json).map_err(|e| Error::io(&jp, e))?;
    Ok(range)
}

/// The linear factor mapping the 99th percentile of all maps' luminances to 1.
pub fn shared_exposure(maps: &[&LatLong]) -> f32 {
    let lum = maps
        .iter()
        .flat_map(|m| m.rgb.iter())
        .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]);
    match quantile(lum, 0.99) {
        Some(v) if v > 0.0 => 1.0 / v,
        _ => 1.0,
    }
}

/// Write a lat-long map as an sRGB PNG at `exposure`.
pub fn write_map_png(path: &Path, ll: &LatLong, exposure: f32) -> Result<()> {
    crate::render::write_png(
        path,
        ll.width as u32,
        ll.height as u32,
        &ll.rgb,
        None,
        exposure,
    )
}

/// Write a thumbnail `width` pixels wide (box filter over whole source pixels), sRGB PNG.
pub fn write_thumbnail(path: &Path, size: (u32, u32), rgb: &[[f32; 3]], width: u32) -> Result<()> {
    let (w, h) = (size.0 as usize, size.1 as usize);
    let tw = (width as usize).min(w).max(1);
    let th = ((h * tw).div_ceil(w.max(1))).max(1);
    let mut out = vec![[0.0f32; 3]; tw * th];
    for (i, o) in out.iter_mut().enumerate() {
        let (x, y) = (i % tw, i / tw);
        let (x0, x1) = (x * w / tw, ((x + 1) * w / tw).max(x * w / tw + 1).min(w));
        let (y0, y1) = (y * h / th, ((y + 1) * h / th).max(y * h / th + 1).min(h));
        let mut acc = [0.0f32; 3];
        for yy in y0..y1 {
            for xx in x0..x1 {
                let p = rgb.get(yy * w + xx).copied().unwrap_or([0.0; 3]);
                for c in 0..3 {
                    acc[c] += p[c];
                }
            }
        }
        let n = ((x1 - x0) * (y1 - y0)).max(1) as f32;
        *o = acc.map(|v| v / n);
    }
    crate::render::write_png(path, tw as u32, th as u32, &out, None, 1.0)
}
