//! What `synth` writes beside the photos: the truth manifest and materials (JSON), and the small file helpers.

use super::*;

#[derive(serde::Serialize)]
pub(crate) struct PhotoTruth {
    pub(crate) name: String,
    pub(crate) env: String,
    pub(crate) map: String,
    pub(crate) rotation_texels: usize,
    pub(crate) rotation_radians: f64,
    pub(crate) held_out: bool,
    pub(crate) exposure: f64,
    pub(crate) white_balance: [f64; 3],
    /// The sun direction (environment frame) of a sun-and-sky map.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) sun: Option<[f64; 3]>,
}

#[derive(serde::Serialize)]
pub(crate) struct Manifest<'a> {
    pub(crate) scene: &'a str,
    pub(crate) description: &'a str,
    pub(crate) seed: u64,
    pub(crate) up: [f64; 3],
    pub(crate) env_frame: [[f64; 3]; 3],
    pub(crate) env_convention: &'a str,
    pub(crate) static_illumination: bool,
    /// Under `--geotag`, the frame azimuth of north (radians).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) north_radians: Option<f64>,
    pub(crate) held_out: Vec<String>,
    pub(crate) photos: &'a [PhotoTruth],
    pub(crate) image_size: [u32; 2],
    pub(crate) samples_per_pixel: u32,
    pub(crate) light_sample_pairs: u32,
    pub(crate) noise_sigma: f64,
    pub(crate) vertices: usize,
    pub(crate) faces: usize,
    pub(crate) mesh: &'a str,
    pub(crate) weights: &'a str,
    pub(crate) materials: &'a str,
    pub(crate) credits: &'a str,
}

#[derive(serde::Serialize)]
pub(crate) struct MaterialsTruth<'a> {
    pub(crate) lobes: &'a [Lobe],
    pub(crate) formulas: [&'a str; 4],
    pub(crate) materials: Vec<MaterialTruth<'a>>,
    pub(crate) photo_model: &'a str,
    pub(crate) photos: Vec<PhotoScale<'a>>,
}

#[derive(serde::Serialize)]
pub(crate) struct MaterialTruth<'a> {
    pub(crate) name: &'a str,
    /// `lambda[b] = [r, g, b]` weight of lobe b.
    pub(crate) lambda: &'a [[f64; 3]],
}

#[derive(serde::Serialize)]
pub(crate) struct PhotoScale<'a> {
    pub(crate) name: &'a str,
    pub(crate) exposure: f64,
    pub(crate) white_balance: [f64; 3],
}

pub(crate) fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| Error::Internal(format!("cannot serialise {}: {e}", path.display())))?;
    std::fs::write(path, text + "\n").map_err(|e| Error::io(path, e))
}

pub(crate) fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|e| Error::io(path, e))
}

/// An 8-bit PNG of `channels` (1 or 3) channels, with `exif` as its EXIF block when
/// given.
pub(crate) fn save_png(
    path: &Path,
    width: u32,
    height: u32,
    bytes: Vec<u8>,
    channels: u8,
) -> Result<()> {
    save_png_exif(path, width, height, bytes, channels, None)
}

/// [`save_png`] with an optional EXIF block (a TIFF structure, as
/// [`crate::import::geotag::exif_block`] writes).
pub(crate) fn save_png_exif(
    path: &Path,
    width: u32,
    height: u32,
    bytes: Vec<u8>,
    channels: u8,
    exif: Option<Vec<u8>>,
) -> Result<()> {
    let err = |m: String| Error::Image {
        path: path.to_path_buf(),
        message: m,
    };
    let color = if channels == 3 {
        image::ExtendedColorType::Rgb8
    } else {
        image::ExtendedColorType::L8
    };
    use image::ImageEncoder;
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut enc = image::codecs::png::PngEncoder::new(std::io::BufWriter::new(file));
    if let Some(block) = exif {
        enc.set_exif_metadata(block)
            .map_err(|e| err(e.to_string()))?;
    }
    enc.write_image(&bytes, width, height, color)
        .map_err(|e| err(e.to_string()))
}

/// Standard normal deviate (Box–Muller).
pub(crate) fn gaussian(rng: &mut Pcg32) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}
