//! `report.html`: one page a person opens from disk in any browser. Images are relative
//! files of the result folder (no server, no script needed to show them); the page holds:
//!
//! - per held-out photo: photo | render | difference, the difference as a heat map of the
//!   per-pixel error `e = sqrt(⅓ Σ_c (y_c − s·ŷ_c)²)` (linear RGB, the render after the best
//!   global scale `s` of [`super::compare`]) over `[0, e_max]`, `e_max` the 99th percentile
//!   of `e` over the object (stated beside a colour bar); the panels are written by
//!   [`write_panels`];
//! - per training photo: a thumbnail beside its recovered environment map (lat-long, sky
//!   up), all maps tone-mapped with ONE exposure (the 99th percentile of all their
//!   luminances maps to white) so their brightness compares; for synthetic workspaces the
//!   true map too (re-expressed in the fit's environment frame, with one exposure shared by
//!   the true maps: the overall scale of the fit is not observable, paper Eq. 9);
//! - material swatches (the diffuse colour) and each material's lobe weights;
//! - time and memory per stage, error against run time, the model choices and why, and
//!   the literature metrics of `report.json`'s `metrics` key when present.

mod images;

use images::heat_css;
#[cfg(test)]
use images::HEAT;
pub use images::{
    heat, pixel_errors, quantile, shared_exposure, write_map_png, write_panels, write_thumbnail,
    DiffRange,
};

use super::RunReport;
use crate::{Error, Result};
use std::fmt::Write as _;
use std::path::Path;

/// One training photo's row: thumbnail and maps, as file names relative to the result.
#[derive(Debug, Clone)]
pub struct TrainingRow {
    /// Image name.
    pub image: String,
    /// The photo's thumbnail.
    pub thumbnail: String,
    /// The recovered map, tone-mapped.
    pub fitted_map: String,
    /// The true map, tone-mapped (synthetic workspaces).
    pub true_map: Option<String>,
}

/// One material's swatch and parameters.
#[derive(Debug, Clone)]
pub struct Swatch {
    /// sRGB colour of the diffuse lobe (normalised by the largest diffuse value over the
    /// materials).
    pub srgb: [u8; 3],
    /// `(lobe label, RGB weight)` per basis lobe.
    pub lobes: Vec<(String, [f64; 3])>,
}

/// What the page shows besides `report.json`'s figures.
#[derive(Debug, Clone, Default)]
pub struct HtmlInputs {
    /// Training rows.
    pub training: Vec<TrainingRow>,
    /// The exposure (linear factor) shared by the recovered maps.
    pub fitted_exposure: f32,
    /// The exposure shared by the true maps.
    pub true_exposure: Option<f32>,
    /// The per-channel scale applied to the recovered maps to match the true ones (then
    /// both are shown at `true_exposure`).
    pub map_scale: Option<[f32; 3]>,
    /// Material swatches.
    pub materials: Vec<Swatch>,
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A relative file reference for `src`/`href` (path segments percent-encoded where needed).
fn href(rel: &str) -> String {
    rel.split('/')
        .map(|seg| {
            seg.bytes()
                .map(|b| match b {
                    b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                        (b as char).to_string()
                    }
                    _ => format!("%{b:02X}"),
                })
                .collect::<String>()
        })
        .collect::<Vec<_>>()
        .join("/")
}

fn img(rel: &str, alt: &str, class: &str) -> String {
    format!(
        "<img src=\"{}\" alt=\"{}\" class=\"{class}\" loading=\"eager\">",
        href(rel),
        esc(alt)
    )
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}\
th{background:#f4f4f4}td.l,th.l{text-align:left}img.panel{width:260px;image-rendering:auto}\
img.thumb{width:160px}img.map{width:320px}img.plot{max-width:100%}\
.bar{height:12px;width:260px;display:inline-block;vertical-align:middle;border:1px solid #888}\
.sw{width:48px;height:48px;display:inline-block;border:1px solid #444;vertical-align:middle}\
figure{display:inline-block;margin:4px}figcaption{font-size:85%;color:#555}";

/// The headline (protocol `half` over the naive baseline) and the light prior `half`
/// fitted with, as report.md gives them; nothing without a headline.
fn headline(s: &mut String, r: &RunReport) {
    let Some(h) = &r.headline_detail else {
        return;
    };
    let _ = writeln!(
        s,
        "<p><b>Headline: held-out error / baseline error = {:.3}</b> ({}).</p>",
        h.ratio,
        esc_prose(&h.explanation())
    );
    if let Some(p) = &r.half_fit_prior {
        let _ = writeln!(s, "<p>{}</p>", esc_prose(&p.sentence()));
    }
}

/// report.md's prose for HTML: its code marks (backticks) dropped, then escaped.
fn esc_prose(text: &str) -> String {
    esc(&text.replace('`', ""))
}

/// The held-out section: one row per image and protocol, from the panels beside
/// `renders/STEM.PROTOCOL.png`.
fn held_out_section(s: &mut String, r: &RunReport, dir: &Path) {
    let _ = writeln!(s, "<h2 id=\"held-out\">Held-out photos</h2>");
    if r.holdout.is_empty() {
        let _ = writeln!(
            s,
            "<p>No photo was held out, so nothing measures how well the result predicts a \
             new view. Run again with <code>--holdout-every 5</code> or \
             <code>--holdout NAME,...</code>.</p>"
        );
        return;
    }
    headline(s, r);
    let _ = writeln!(
        s,
        "<p>Photo | render (after the best global scale) | difference. The difference is the \
         per-pixel error in linear RGB on the photo's [0, 1] scale, coloured from 0 to the \
         99th percentile over the object (grey: not object).</p>"
    );
    for h in &r.holdout {
        let stem = format!(
            "renders/panels/{}.{}",
            crate::render::views::file_stem(&h.image),
            h.protocol
        );
        let range: Option<DiffRange> =
            std::fs::read_to_string(dir.join(format!("{stem}.diff.json")))
                .ok()
                .and_then(|t| serde_json::from_str(&t).ok());
        let _ = writeln!(
            s,
            "<h3>{} <small>({}: RMSE {:.5} raw, {:.5} after scale {:.3}; PSNR {:.2} dB)</small></h3>",
            esc(&h.image),
            esc(&h.protocol),
            h.rmse,
            h.rmse_scaled,
            h.scale,
            h.psnr
        );
        if range.is_none() {
            let _ = writeln!(s, "<p>(no panels were written for this view)</p>");
            continue;
        }
        let _ = writeln!(s, "<div>");
        for (ext, cap) in [
            ("photo", "photo"),
            ("render", "render"),
            ("diff", "difference"),
        ] {
            let _ = writeln!(
                s,
                "<figure>{}<figcaption>{cap}</figcaption></figure>",
                img(
                    &format!("{stem}.{ext}.png"),
                    &format!("{} {cap}", h.image),
                    "panel"
                )
            );
        }
        if let Some(rg) = range {
            let _ = writeln!(
                s,
                "<p>colour scale: {:.4} <span class=\"bar\" style=\"background:{}\"></span> {:.4} \
                 (largest error {:.4})</p>",
                rg.min,
                heat_css(),
                rg.max,
                rg.peak
            );
        }
        let _ = writeln!(s, "</div>");
    }
}

fn training_section(s: &mut String, r: &RunReport, inputs: &HtmlInputs) {
    let _ = writeln!(
        s,
        "<h2 id=\"training\">Training photos and recovered light</h2>"
    );
    let _ = writeln!(
        s,
        "<p>RMSE over all training observations: <b>{:.5}</b>. Each environment map is a \
         lat-long view of the whole sphere, sky up; all recovered maps share one exposure \
         (×{:.3}) so their brightness compares{}.</p>",
        r.train_rmse,
        inputs.fitted_exposure,
        match (inputs.map_scale, inputs.true_exposure) {
            (Some(s), Some(_)) => format!(
                "; the true maps are the light as each camera saw it (map × exposure × white balance), \
                 the recovered maps are multiplied by the one per-channel scale that best matches them \
                 to the true maps (×{:.4} / {:.4} / {:.4}: photos cannot fix it), and both share the \
                 true maps' exposure, so brightness and colour compare across the row",
                s[0], s[1], s[2]
            ),
            (None, Some(e)) => format!(
                "; the true maps share another (×{e:.3}): the fit's overall scale is not observable"
            ),
            _ => String::new(),
        }
    );
    let _ = writeln!(
        s,
        "<table><tr><th class=\"l\">photo</th><th>RMSE</th><th>thumbnail</th><th>recovered map</th>{}</tr>",
        if inputs.true_exposure.is_some() { "<th>true map</th>" } else { "" }
    );
    for row in &inputs.training {
        let rmse = r
            .train
            .iter()
            .find(|t| t.image == row.image)
            .map_or("–".to_string(), |t| format!("{:.5}", t.rmse));
        let _ = write!(
            s,
            "<tr><td class=\"l\">{}</td><td>{rmse}</td><td>{}</td><td>{}</td>",
            esc(&row.image),
            img(&row.thumbnail, &row.image, "thumb"),
            img(
                &row.fitted_map,
                &format!("recovered map of {}", row.image),
                "map"
            )
        );
        if let Some(t) = &row.true_map {
            let _ = write!(
                s,
                "<td>{}</td>",
                img(t, &format!("true map of {}", row.image), "map")
            );
        }
        let _ = writeln!(s, "</tr>");
    }
    let _ = writeln!(s, "</table>");
    let _ = writeln!(
        s,
        "<p>{}</p>",
        img("plots/per_photo_rmse.png", "RMSE per photo", "plot")
    );
    truth_check_table(s, &r.truth_check);
    if let Some(sky) = &r.model.sky {
        sky_table(s, sky);
    }
}

/// The recovered sun of every training photo (`--light sky`), beside the truth's where
/// there is one ([`crate::report::sky`]).
fn sky_table(s: &mut String, sky: &crate::report::sky::SkyReport) {
    let _ = writeln!(
        s,
        "<h3 id=\"sky\">Sun and sky</h3><p>{}</p><table><tr>",
        esc(&sky.summary())
    );
    for (i, h) in sky.header().iter().enumerate() {
        let class = if i < 2 { " class=\"l\"" } else { "" };
        let _ = write!(s, "<th{class}>{}</th>", esc(h));
    }
    let _ = writeln!(s, "</tr>");
    for row in sky.rows() {
        let _ = write!(s, "<tr>");
        for (i, c) in row.iter().enumerate() {
            let class = if i < 2 { " class=\"l\"" } else { "" };
            let _ = write!(s, "<td{class}>{}</td>", esc(c));
        }
        let _ = writeln!(s, "</tr>");
    }
    let _ = writeln!(s, "</table>");
}

/// The truth check of synthetic workspaces: training photos rendered from the fit under the
/// light they were really taken in, beside their fitted light, and the floor (the true
/// reflectance, in its own lobes, under the true light) where every photo has one.
fn truth_check_table(s: &mut String, rows: &[crate::report::metrics::TruthCheckEntry]) {
    if rows.is_empty() {
        return;
    }
    let floor = rows.iter().all(|t| t.relative_true_reflectance.is_some());
    let _ = writeln!(
        s,
        "<h3 id=\"truth-check\">Truth check: training photos under their true light</h3>\
         <p>Each photo rendered from the fit under the light it was really taken in, against \
         the same render under its fitted light: relative RMSE after the best per-channel \
         scale, over object pixels off its edges and not overexposed. A large gap means the \
         fitted maps absorbed wrong reflectance.{}</p>",
        if floor {
            " The last column renders the TRUE reflectance the same way: the floor of this \
             renderer and model; the fit's distance above it is reflectance the photos could \
             still have told."
        } else {
            ""
        }
    );
    let _ = writeln!(
        s,
        "<table><tr><th class=\"l\">training photo</th><th>true light</th><th>fitted light</th>{}<th>pixels</th></tr>",
        if floor { "<th>true reflectance, true light</th>" } else { "" }
    );
    let pct = |v: f64| format!("{:.1}%", 100.0 * v);
    for t in rows {
        let _ = writeln!(
            s,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td>{}<td>{}</td></tr>",
            esc(&t.image),
            pct(t.relative_true_light),
            pct(t.relative_fitted_light),
            match (floor, t.relative_true_reflectance) {
                (true, Some(v)) => format!("<td>{}</td>", pct(v)),
                _ => String::new(),
            },
            t.pixels
        );
    }
    let n = rows.len() as f64;
    let mean = |f: &dyn Fn(&crate::report::metrics::TruthCheckEntry) -> f64| {
        rows.iter().map(f).sum::<f64>() / n
    };
    let _ = writeln!(
        s,
        "<tr><td class=\"l\"><b>mean</b></td><td><b>{}</b></td><td><b>{}</b></td>{}<td></td></tr></table>",
        pct(mean(&|t| t.relative_true_light)),
        pct(mean(&|t| t.relative_fitted_light)),
        if floor {
            format!(
                "<td><b>{}</b></td>",
                pct(mean(&|t| t.relative_true_reflectance.unwrap_or(f64::NAN)))
            )
        } else {
            String::new()
        }
    );
    if let Some(r) = crate::report::metrics::truth_check_floor_ratio(rows) {
        let _ = writeln!(
            s,
            "<p>The fit under the true light is <b>{r:.2}×</b> the floor.</p>"
        );
    }
}

fn materials_section(s: &mut String, r: &RunReport, inputs: &HtmlInputs) {
    materials_table(s, inputs);
    if let Some(a) = &r.albedo_truth {
        albedo_truth_table(s, a);
    }
}

/// Recovered diffuse albedo per material against the truth (synthetic workspaces).
fn albedo_truth_table(s: &mut String, a: &crate::report::metrics::AlbedoTruth) {
    let _ = writeln!(
        s,
        "<h3 id=\"albedo-truth\">Diffuse albedo against the truth</h3><p>Each recovered \
         material beside the true material most of its vertices belong to. The recovered albedo \
         is multiplied by the per-channel scale that best matches the recovered per-vertex \
         diffuse albedo to the true one over {} vertices (×{:.4} / {:.4} / {:.4}: photos cannot \
         fix it); the ratio error is scaled / true − 1 (largest: <b>{:.4}</b>). The last \
         two columns compare the scaled per-vertex diffuse albedo itself over the vertices of \
         one true material alone (true weight ≥ {}), which does not depend on how free \
         blending weights split brightness between w and λ: its mean (largest: \
         <b>{:.4}</b>), which the vertices whose colour the photos leave open move (surfaces \
         seen at grazing angles or by no camera), and its median, the material's own albedo, \
         with the share of those vertices more than 10% off. The ratios between the \
         materials' medians, free of the scale, are the diffuse albedo ratios (largest \
         error: <b>{:.4}</b>).</p>",
        a.vertices,
        a.scale[0],
        a.scale[1],
        a.scale[2],
        a.max_ratio_error,
        crate::report::metrics::PURE_WEIGHT,
        a.max_pure_ratio_error,
        a.max_median_ratio_error
    );
    let _ = writeln!(
        s,
        "<table><tr><th class=\"l\">material</th><th class=\"l\">true material (share)</th>\
         <th>recovered</th><th>scaled</th><th>true</th><th>ratio error R / G / B</th>\
         <th>pure vertices: mean albedo error R / G / B</th>\
         <th>pure vertices: median albedo error R / G / B</th></tr>"
    );
    let rgb = |v: [f64; 3]| format!("{:.4}, {:.4}, {:.4}", v[0], v[1], v[2]);
    for m in &a.materials {
        let _ = writeln!(
            s,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{} ({:.3})</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{:+.4} / {:+.4} / {:+.4}</td><td>{}</td><td>{}</td></tr>",
            m.material,
            esc(&m.true_material),
            m.agreement,
            rgb(m.recovered),
            rgb(m.recovered_scaled),
            rgb(m.truth),
            m.ratio_error[0],
            m.ratio_error[1],
            m.ratio_error[2],
            crate::report::metrics::pure_errors(m),
            crate::report::metrics::pure_median_errors(m)
        );
    }
    let _ = writeln!(s, "</table>");
}

fn materials_table(s: &mut String, inputs: &HtmlInputs) {
    let _ = writeln!(s, "<h2 id=\"materials\">Materials</h2>");
    let _ = writeln!(
        s,
        "<p>Each material mixes the basis lobes with these RGB weights (paper Eq. 11); the \
         swatch is the diffuse (lambert) colour, normalised by the brightest material.</p>"
    );
    let Some(first) = inputs.materials.first() else {
        return;
    };
    let _ = write!(s, "<table><tr><th class=\"l\">material</th><th>swatch</th>");
    for (label, _) in &first.lobes {
        let _ = write!(s, "<th>{}</th>", esc(label));
    }
    let _ = writeln!(s, "</tr>");
    for (k, m) in inputs.materials.iter().enumerate() {
        let [r, g, b] = m.srgb;
        let _ = write!(
            s,
            "<tr><td class=\"l\">{k}</td><td><span class=\"sw\" style=\"background:rgb({r},{g},{b})\"></span></td>"
        );
        for (_, w) in &m.lobes {
            let _ = write!(s, "<td>{:.4}, {:.4}, {:.4}</td>", w[0], w[1], w[2]);
        }
        let _ = writeln!(s, "</tr>");
    }
    let _ = writeln!(s, "</table>");
}

fn stages_section(s: &mut String, r: &RunReport) {
    let _ = writeln!(s, "<h2 id=\"time\">Time and memory per stage</h2>");
    let _ = writeln!(
        s,
        "<p>{}</p>",
        img("plots/stages.png", "time per stage", "plot")
    );
    let _ = writeln!(
        s,
        "<table><tr><th class=\"l\">stage</th><th>wall s</th><th>CPU s</th><th>peak memory MiB</th></tr>"
    );
    for st in &r.stage_details {
        let _ = writeln!(
            s,
            "<tr><td class=\"l\">{}</td><td>{:.2}</td><td>{:.2}</td><td>{}</td></tr>",
            esc(&st.name),
            st.seconds,
            st.cpu_seconds,
            st.peak_mib_label()
        );
    }
    let _ = writeln!(s, "</table>");
    let _ = writeln!(s, "<h2 id=\"error-time\">Error against run time</h2>");
    let _ = writeln!(
        s,
        "<p>{}</p>",
        img("plots/error_vs_time.png", "error against run time", "plot")
    );
}

fn model_section(s: &mut String, r: &RunReport) {
    let m = &r.model;
    let _ = writeln!(s, "<h2 id=\"model\">Model choices and why</h2>");
    let facts: Vec<String> = m
        .facts()
        .iter()
        .map(|(l, v)| format!("{l}: {}", esc(v)))
        .collect();
    let _ = writeln!(s, "<p>{}.</p><ul>", facts.join("; "));
    for reason in &m.reasons {
        let _ = writeln!(s, "<li>{}</li>", esc(reason));
    }
    if let Some(a) = &m.scale_anchor {
        let _ = writeln!(
            s,
            "<li>scale anchor <code>{}</code>: {}</li>",
            esc(&a.name),
            esc(&a.rule)
        );
    }
    let _ = writeln!(s, "</ul>");
    if let Some(ds) = &m.adaptive {
        let _ = writeln!(
            s,
            "<table><tr><th class=\"l\">what</th><th class=\"l\">full model</th><th class=\"l\">chosen</th><th class=\"l\">why</th></tr>"
        );
        for d in ds {
            let _ = writeln!(
                s,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                esc(&d.what),
                esc(&d.full),
                esc(&d.chosen),
                esc(&d.reason)
            );
        }
        let _ = writeln!(s, "</table>");
    }
}

/// One JSON value as text for a table cell (numbers to 4 significant decimals).
fn cell(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Number(n) => n
            .as_f64()
            .map_or_else(|| n.to_string(), |f| format!("{f:.4}")),
        serde_json::Value::String(t) => esc(t),
        serde_json::Value::Null => "–".into(),
        other => esc(&other.to_string()),
    }
}

/// The literature metrics (`metrics` of report.json), whatever their shape: an array of
/// records is a table; an object of scalars a two-column table; nested objects recurse.
fn metrics_section(s: &mut String, json: &serde_json::Value) {
    let _ = writeln!(s, "<h2 id=\"metrics\">Literature metrics</h2>");
    match json.get("metrics") {
        None | Some(serde_json::Value::Null) => {
            let _ = writeln!(s, "<p>This run's report has no literature metrics.</p>");
        }
        Some(m) => metrics_value(s, m),
    }
}

fn metrics_value(s: &mut String, v: &serde_json::Value) {
    use serde_json::Value;
    match v {
        Value::Array(rows) if rows.iter().all(|r| r.is_object()) && !rows.is_empty() => {
            let mut cols: Vec<String> = Vec::new();
            for r in rows {
                for k in r.as_object().into_iter().flat_map(|o| o.keys()) {
                    if !cols.contains(k) {
                        cols.push(k.clone());
                    }
                }
            }
            let _ = write!(s, "<table><tr>");
            for c in &cols {
                let _ = write!(s, "<th>{}</th>", esc(c));
            }
            let _ = writeln!(s, "</tr>");
            for r in rows {
                let _ = write!(s, "<tr>");
                for c in &cols {
                    let _ = write!(s, "<td>{}</td>", r.get(c).map_or("–".into(), cell));
                }
                let _ = writeln!(s, "</tr>");
            }
            let _ = writeln!(s, "</table>");
        }
        Value::Object(o) => {
            let _ = writeln!(s, "<table>");
            for (k, v) in o {
                if v.is_object() || v.is_array() {
                    let _ = writeln!(s, "<tr><th class=\"l\">{}</th><td class=\"l\">", esc(k));
                    metrics_value(s, v);
                    let _ = writeln!(s, "</td></tr>");
                } else {
                    let _ = writeln!(
                        s,
                        "<tr><th class=\"l\">{}</th><td>{}</td></tr>",
                        esc(k),
                        cell(v)
                    );
                }
            }
            let _ = writeln!(s, "</table>");
        }
        other => {
            let _ = writeln!(s, "<p>{}</p>", cell(other));
        }
    }
}

/// The page (module docs). `json` is `report.json`'s value (for keys other parts of the
/// tool add, such as `metrics`); `dir` the result folder (to read the panels' ranges).
pub fn page(r: &RunReport, json: &serde_json::Value, inputs: &HtmlInputs, dir: &Path) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>relight-cpc report</title><style>{STYLE}</style></head><body>"
    );
    let _ = writeln!(s, "<h1>relight-cpc report</h1>");
    let _ = writeln!(
        s,
        "<p>Workspace <code>{}</code>, seed {}, relight-cpc {}. Also: \
         <a href=\"report.md\">report.md</a>, <a href=\"report.json\">report.json</a>.</p>",
        esc(&r.workspace),
        r.seed,
        esc(&r.version)
    );
    let _ = writeln!(
        s,
        "<p><a href=\"#held-out\">held-out</a> · <a href=\"#training\">training</a> · \
         <a href=\"#materials\">materials</a> · <a href=\"#time\">time</a> · \
         <a href=\"#error-time\">error/time</a> · <a href=\"#model\">model</a> · \
         <a href=\"#metrics\">metrics</a> · <a href=\"#notes\">notes</a></p>"
    );
    held_out_section(&mut s, r, dir);
    training_section(&mut s, r, inputs);
    materials_section(&mut s, r, inputs);
    stages_section(&mut s, r);
    model_section(&mut s, r);
    metrics_section(&mut s, json);
    let _ = writeln!(s, "<h2 id=\"notes\">Notes</h2><ul>");
    for n in &r.notes {
        let _ = writeln!(s, "<li>{}</li>", esc(n));
    }
    let _ = writeln!(s, "</ul></body></html>");
    s
}

/// Write `dir/report.html` (after `report.json`, whose value it reads for `metrics`).
pub fn write(dir: &Path, r: &RunReport, inputs: &HtmlInputs) -> Result<()> {
    let jp = dir.join("report.json");
    let json: serde_json::Value = std::fs::read_to_string(&jp)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or(serde_json::Value::Null);
    let path = dir.join("report.html");
    std::fs::write(&path, page(r, &json, inputs, dir)).map_err(|e| Error::io(&path, e))
}

/// Every `src="..."` of a page, in order (for tests and checks).
pub fn image_sources(html: &str) -> Vec<String> {
    html.split("<img src=\"")
        .skip(1)
        .filter_map(|rest| rest.split('"').next().map(str::to_string))
        .collect()
}

#[cfg(test)]
mod tests;
