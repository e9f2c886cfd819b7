//! PNG figures for the report, drawn with plotters (bitmap backend, text through ab_glyph
//! with the DejaVu Sans font embedded in the binary, so no system fonts are needed).

use crate::{Error, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

const FONT: &str = "sans-serif";
static FONT_BYTES: &[u8] = include_bytes!("DejaVuSans.ttf");
static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        // The embedded font is a valid TTF: a failure here would be a build defect, and
        // plotters then falls back to drawing no text rather than failing.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: format!("could not draw the figure: {e}"),
    }
}

/// One named line of `(x, y)` points.
pub struct Series<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Points, in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub color: RGBColor,
}

/// Colours for series, in order.
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(127, 127, 127),
];

/// A line chart with a logarithmic y axis (non-positive values are left out), one panel per
/// entry of `panels` stacked vertically: `(title, y label, series)`.
pub fn line_panels(path: &Path, x_label: &str, panels: &[(&str, &str, Vec<Series>)]) -> Result<()> {
    register_font();
    let height = 320 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (area, (title, y_label, series)) in areas.iter().zip(panels) {
        let pts = series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| p.1 > 0.0);
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in pts {
            if x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.1, 1.0);
        }
        if x1 - x0 < 1e-9 {
            x1 = x0 + 1.0;
        }
        if y1 / y0 < 1.5 {
            y0 /= 1.25;
            y1 *= 1.25;
        }
        if y1 / y0 > 20.0 {
            draw_panel(
                path,
                area,
                title,
                x_label,
                y_label,
                series,
                x0..x1,
                (y0..y1).log_scale(),
            )?;
        } else {
            let pad = 0.05 * (y1 - y0);
            draw_panel(
                path,
                area,
                title,
                x_label,
                y_label,
                series,
                x0..x1,
                (y0 - pad).max(0.0)..y1 + pad,
            )?;
        }
    }
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}

/// Where [`bars`] printed one row's label: its text and the label's vertical centre in
/// pixels of the PNG (for tests that check labels against the bars' pixels).
#[derive(Debug, Clone, PartialEq)]
pub struct BarLabel {
    /// The label text.
    pub text: String,
    /// Pixel row of the label's centre.
    pub y_px: i32,
}

/// The row drawn in segment `y` of a bar chart of `n` rows (top row first): bars are
/// stacked from the bottom, so segment `y` holds row `n − 1 − y`.
fn row_of_segment(n: usize, y: usize) -> Option<usize> {
    (y < n).then(|| n - 1 - y)
}

/// Horizontal bars, one per `(label, value, color)`, top to bottom in `rows` order, with the
/// value printed after each bar and the label centred on its bar (segmented y axis: the
/// label of segment `y` is drawn at its centre, the bar fills it). Returns where each label
/// was printed.
pub fn bars(
    path: &Path,
    title: &str,
    x_label: &str,
    rows: &[(String, f64, RGBColor)],
    value_fmt: &dyn Fn(f64) -> String,
) -> Result<Vec<BarLabel>> {
    use plotters::coord::ranged1d::SegmentValue;
    register_font();
    let height = (60 + 26 * rows.len().max(1)) as u32 + 40;
    let root = BitMapBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let vmax = rows
        .iter()
        .map(|r| r.1)
        .filter(|v| v.is_finite())
        .fold(0.0_f64, f64::max)
        .max(1e-12);
    let n = rows.len().max(1);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 20))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(200)
        // One row would make the discrete range empty (0..0): give it a second, empty slot.
        .build_cartesian_2d(0.0..vmax * 1.3, (0..(n - 1).max(1)).into_segmented())
        .map_err(|e| plot_err(path, e))?;
    let labelled = std::cell::RefCell::new(Vec::new());
    let label_of = |v: &SegmentValue<usize>| match v {
        SegmentValue::CenterOf(y) => row_of_segment(n, *y)
            .and_then(|r| rows.get(r))
            .map(|r| r.0.clone()),
        _ => None,
    };
    chart
        .configure_mesh()
        .disable_y_mesh()
        .x_desc(x_label)
        .label_style((FONT, 13))
        .y_labels(n)
        .y_label_formatter(&|v| {
            let text = label_of(v).unwrap_or_default();
            if let SegmentValue::CenterOf(y) = v {
                labelled.borrow_mut().push((*y, text.clone()));
            }
            text
        })
        .draw()
        .map_err(|e| plot_err(path, e))?;
    draw_bar_rows(&mut chart, path, rows, vmax, value_fmt)?;
    let mut out: Vec<BarLabel> = labelled
        .borrow()
        .iter()
        .filter(|(_, t)| !t.is_empty())
        .map(|(y, text)| BarLabel {
            text: text.clone(),
            y_px: chart.backend_coord(&(0.0, SegmentValue::CenterOf(*y))).1,
        })
        .collect();
    out.dedup();
    drop(chart);
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(out)
}

/// A bar chart's drawing area: values along `x`, one segment per row along `y`.
type BarChart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    plotters::coord::cartesian::Cartesian2d<
        plotters::coord::types::RangedCoordf64,
        plotters::coord::ranged1d::SegmentedCoord<plotters::coord::types::RangedCoordusize>,
    >,
>;

/// Each row's bar in its segment ([`row_of_segment`]'s inverse: row `i` of `n` fills segment
/// `n − 1 − i`) with its value printed after it; a value that is not finite draws as 0.
fn draw_bar_rows(
    chart: &mut BarChart,
    path: &Path,
    rows: &[(String, f64, RGBColor)],
    vmax: f64,
    value_fmt: &dyn Fn(f64) -> String,
) -> Result<()> {
    use plotters::coord::ranged1d::SegmentValue;
    let n = rows.len().max(1);
    for (i, (_, v, color)) in rows.iter().enumerate() {
        let y = n - 1 - i;
        let v = if v.is_finite() { *v } else { 0.0 };
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [
                    (0.0, SegmentValue::Exact(y)),
                    (v, SegmentValue::Exact(y + 1)),
                ],
                color.filled(),
            )))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(std::iter::once(Text::new(
                value_fmt(v),
                (v + vmax * 0.01, SegmentValue::CenterOf(y)),
                (FONT, 13),
            )))
            .map_err(|e| plot_err(path, e))?;
    }
    Ok(())
}

/// A gallery of linear RGB images (e.g. lat-long environment maps), each tone-mapped with
/// one shared exposure (the 99th percentile of all luminances maps to 1), sRGB-encoded, in a
/// grid with captions. `images`: `(caption, width, height, pixels)`.
pub fn gallery(path: &Path, images: &[(String, usize, usize, &[[f32; 3]])]) -> Result<()> {
    register_font();
    let cols = images.len().clamp(1, 4);
    let rows = images.len().div_ceil(cols).max(1);
    let cell_w = 256usize;
    let cell_h = images
        .iter()
        .map(|(_, w, h, _)| (cell_w * h).div_ceil((*w).max(1)))
        .max()
        .unwrap_or(128);
    let (w, h) = (cols * cell_w + 8 * (cols + 1), rows * (cell_h + 24) + 8);
    let mut lum: Vec<f32> = images
        .iter()
        .flat_map(|(_, _, _, px)| {
            px.iter()
                .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
        })
        .filter(|v| v.is_finite())
        .collect();
    lum.sort_by(f32::total_cmp);
    let white = lum
        .get(((lum.len() as f64) * 0.99) as usize)
        .copied()
        .filter(|v| *v > 0.0)
        .unwrap_or(1.0);
    let root = BitMapBackend::new(path, (w as u32, h as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    for (idx, (caption, iw, ih, px)) in images.iter().enumerate() {
        let (cx, cy) = (
            8 + (idx % cols) * (cell_w + 8),
            8 + (idx / cols) * (cell_h + 24),
        );
        let dh = (cell_w * ih).div_ceil((*iw).max(1));
        for y in 0..dh {
            for x in 0..cell_w {
                let sx = (x * iw / cell_w).min(iw.saturating_sub(1));
                let sy = (y * ih / dh.max(1)).min(ih.saturating_sub(1));
                let p = px.get(sy * iw + sx).copied().unwrap_or([0.0; 3]);
                let c = |v: f32| (crate::render::srgb_encode(v / white) * 255.0).round() as u8;
                root.draw_pixel(
                    ((cx + x) as i32, (cy + y) as i32),
                    &RGBColor(c(p[0]), c(p[1]), c(p[2])),
                )
                .map_err(|e| plot_err(path, e))?;
            }
        }
        root.draw(&Text::new(
            caption.clone(),
            (cx as i32, (cy + dh + 4) as i32),
            (FONT, 14),
        ))
        .map_err(|e| plot_err(path, e))?;
    }
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}

/// One panel of [`line_panels`] on any y axis (linear or logarithmic).
#[allow(clippy::too_many_arguments)]
fn draw_panel<DB, Y>(
    path: &Path,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    x_range: std::ops::Range<f64>,
    y_range: Y,
) -> Result<()>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    Y: plotters::coord::ranged1d::AsRangedCoord<Value = f64>,
    <Y as plotters::coord::ranged1d::AsRangedCoord>::CoordDescType:
        plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range, y_range)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .y_label_formatter(&|v| format!("{v:.3e}"))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for s in series {
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.1 > 0.0 && p.0.is_finite() && p.1.is_finite())
            .collect();
        let color = s.color;
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(|e| plot_err(path, e))?
            .label(s.label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
            .map_err(|e| plot_err(path, e))?;
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each printed label sits on its own bar: the PNG's pixel at the label's height, just
    /// right of the axis, has the colour of the bar of the row with that label (every row
    /// a different colour, all bars long enough to be sampled), for 1, 2 and 7 rows.
    #[test]
    fn bar_labels_sit_on_their_bars() {
        let dir = std::env::temp_dir().join(format!("relight-bars-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for n in [1usize, 2, 7] {
            let rows: Vec<(String, f64, RGBColor)> = (0..n)
                .map(|i| {
                    let c = RGBColor((30 * i) as u8, 200 - (20 * i) as u8, (90 + 20 * i) as u8);
                    (format!("row {i}"), 1.0 + i as f64, c)
                })
                .collect();
            let path = dir.join(format!("bars{n}.png"));
            let labels = bars(&path, "t", "x", &rows, &|v| format!("{v}")).unwrap();
            assert_eq!(labels.len(), n, "{labels:?}");
            let img = image::open(&path).unwrap().into_rgb8();
            // The plot area starts after the 12 px margin and the 200 px label area; the
            // shortest bar (value 1 of at most 1.3·n) spans > 20 px from there.
            let x = 12 + 200 + 6;
            for l in &labels {
                let row = rows.iter().find(|r| r.0 == l.text).unwrap();
                let px = img.get_pixel(x, l.y_px as u32).0;
                assert_eq!(
                    px,
                    [row.2 .0, row.2 .1, row.2 .2],
                    "n={n}: label {:?}",
                    l.text
                );
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
