//! EXR files the tool writes (environment maps, renders): 32-bit float RGB or RGBA, the
//! `exr` crate's fast lossless encoding (RLE, 64 × 64 tiles), tiles in increasing order
//! and compressed one after another, so that the same pixels always give the same bytes.
//! The crate's `write_rgb_file` compresses tiles on every core and writes each as it is
//! done (line order "unspecified"), so two runs of the same fit wrote different files.

use exr::prelude::*;
use std::path::Path;

/// The encoding of every EXR the tool writes (module docs).
const ENCODING: Encoding = Encoding {
    line_order: LineOrder::Increasing,
    ..Encoding::FAST_LOSSLESS
};

/// Write `width × height` RGB pixels, `rgb(x, y)` each, to `path`.
pub fn write_rgb(
    path: &Path,
    width: usize,
    height: usize,
    rgb: impl Sync + Fn(usize, usize) -> (f32, f32, f32),
) -> exr::error::UnitResult {
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| rgb(p.x(), p.y()));
    let image = Image::from_layer(layer((width, height), channels));
    image.write().non_parallel().to_file(path)
}

/// Write `width × height` RGBA pixels, `rgba(x, y)` each, to `path`.
pub fn write_rgba(
    path: &Path,
    width: usize,
    height: usize,
    rgba: impl Sync + Fn(usize, usize) -> (f32, f32, f32, f32),
) -> exr::error::UnitResult {
    let channels = SpecificChannels::rgba(|p: Vec2<usize>| rgba(p.x(), p.y()));
    let image = Image::from_layer(layer((width, height), channels));
    image.write().non_parallel().to_file(path)
}

/// One unnamed layer of `channels` in [`ENCODING`].
fn layer<'s, C>(size: (usize, usize), channels: C) -> Layer<C>
where
    C: exr::image::write::channels::WritableChannels<'s> + 's,
{
    Layer::new(size, LayerAttributes::default(), ENCODING, channels)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 300 × 200 image spans 5 × 4 tiles: written twice, the files are the same bytes
    /// (with the crate's parallel writer the tiles' order followed the threads), and read
    /// back, every pixel is the one written (f32, lossless).
    #[test]
    fn the_same_pixels_give_the_same_bytes_and_read_back_exactly() {
        let dir = std::env::temp_dir().join(format!("relight-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h) = (300, 200);
        let px = move |x: usize, y: usize| {
            let v = ((x * 7919 + y * 104_729) % 1000) as f32 / 137.0;
            (v, 0.5 * v, x as f32 / w as f32, (y % 2) as f32)
        };
        let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
        for _ in 0..4 {
            write_rgba(&a, w, h, px).unwrap();
            write_rgba(&b, w, h, px).unwrap();
            assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
        }
        let img = read_first_rgba_layer_from_file(
            &a,
            |res, _| vec![(0.0f32, 0.0f32, 0.0f32, 0.0f32); res.width() * res.height()],
            move |buf, pos, p: (f32, f32, f32, f32)| buf[pos.y() * w + pos.x()] = p,
        )
        .unwrap();
        let got = &img.layer_data.channel_data.pixels;
        for y in 0..h {
            for x in 0..w {
                assert_eq!(got[y * w + x], px(x, y), "pixel ({x}, {y})");
            }
        }
        let rgb = |x, y| {
            let p = px(x, y);
            (p.0, p.1, p.2)
        };
        let (c, d) = (dir.join("c.exr"), dir.join("d.exr"));
        write_rgb(&c, w, h, rgb).unwrap();
        write_rgb(&d, w, h, rgb).unwrap();
        assert_eq!(std::fs::read(&c).unwrap(), std::fs::read(&d).unwrap());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
