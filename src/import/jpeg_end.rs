//! Whether a JPEG file holds its whole image: a walk over its markers to the end-of-image
//! marker (ITU-T T.81, Annex B).
//!
//! The JPEG decoder `image` uses fills the rows a truncated file lacks and reports no
//! error, so an interrupted download or copy would enter the fit as a photo with a grey or
//! black lower part. A complete JPEG is `SOI` (`FF D8`), marker segments, and one or more
//! scans, ending in `EOI` (`FF D9`):
//!
//! - a marker is `FF` (any number of fill `FF`s) then its code; `RSTn` (`D0`–`D7`) and
//!   `TEM` (`01`) stand alone, every other marker is followed by a 16-bit big-endian length
//!   that counts itself and the segment's data (B.1.1.4);
//! - a scan is an `SOS` (`DA`) segment followed by entropy-coded data, in which a data byte
//!   `FF` is always stuffed as `FF 00` and restart markers may appear (B.1.1.5): the scan
//!   ends at the first `FF` followed by any other byte, the next marker.
//!
//! Segments are skipped by their lengths, so a thumbnail inside an `APP1` (Exif) segment,
//! with an `EOI` of its own, is never taken for the end of the image; progressive files
//! (several scans, with tables between them) walk the same way. Bytes after `EOI` (some
//! cameras append data there) are ignored.

/// Why a JPEG is incomplete: the byte offset where its data ran out, and what was being
/// read there.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Truncated {
    /// Length of the file in bytes: where its data ends.
    pub ends_at: usize,
    /// What the walk was reading when the data ended, in words.
    pub reading: &'static str,
}

impl std::fmt::Display for Truncated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the JPEG data ends at byte {} while reading {}, before its end-of-image marker: \
             the file is truncated (an interrupted download or copy?)",
            self.ends_at, self.reading
        )
    }
}

/// Start of image, end of image, start of scan.
const SOI: u8 = 0xD8;
const EOI: u8 = 0xD9;
const SOS: u8 = 0xDA;

/// `Ok` when `bytes` (a file that starts with the JPEG signature `FF D8`) reaches its
/// end-of-image marker (module docs); files without that signature are not JPEGs and
/// pass, and so do files damaged where a marker must begin (the check is for truncation;
/// the decoder judges damage).
pub fn check_complete(bytes: &[u8]) -> Result<(), Truncated> {
    if bytes.len() < 2 || bytes[0] != 0xFF || bytes[1] != SOI {
        return Ok(());
    }
    let truncated = |reading| Truncated {
        ends_at: bytes.len(),
        reading,
    };
    let mut i = 2;
    loop {
        let (code, after) = match read_marker(bytes, i) {
            Marker::At(code, after) => (code, after),
            Marker::Ends => return Err(truncated("a marker")),
            // Damaged, not cut short: whether it decodes is the decoder's to say.
            Marker::Missing => return Ok(()),
        };
        i = match code {
            EOI => return Ok(()),
            0x01 | 0xD0..=0xD7 => after,
            _ => {
                let len = segment_len(bytes, after).ok_or(truncated("a segment's length"))?;
                let end = after + len;
                if len < 2 || end > bytes.len() {
                    return Err(truncated("a marker segment"));
                }
                if code == SOS {
                    scan_end(bytes, end).ok_or(truncated("the compressed image data"))?
                } else {
                    end
                }
            }
        };
    }
}

/// What stands where a marker must begin.
enum Marker {
    /// A marker: its code and the offset after it, fill bytes skipped.
    At(u8, usize),
    /// The data ends first.
    Ends,
    /// A byte other than `FF`: the file is damaged there, not truncated.
    Missing,
}

/// The marker at `i` ([`Marker`]).
fn read_marker(bytes: &[u8], mut i: usize) -> Marker {
    match bytes.get(i) {
        None => return Marker::Ends,
        Some(&b) if b != 0xFF => return Marker::Missing,
        Some(_) => {}
    }
    while bytes.get(i) == Some(&0xFF) {
        i += 1;
    }
    match bytes.get(i) {
        Some(&code) => Marker::At(code, i + 1),
        None => Marker::Ends,
    }
}

/// The 16-bit big-endian segment length at `i`.
fn segment_len(bytes: &[u8], i: usize) -> Option<usize> {
    let hi = *bytes.get(i)? as usize;
    let lo = *bytes.get(i + 1)? as usize;
    Some(hi << 8 | lo)
}

/// The offset of the marker that ends the entropy-coded data starting at `i`: the first
/// `FF` not followed by a stuffed `00` or a restart code. `None` when the data ends first.
fn scan_end(bytes: &[u8], mut i: usize) -> Option<usize> {
    loop {
        let at = i + bytes.get(i..)?.iter().position(|&b| b == 0xFF)?;
        match *bytes.get(at + 1)? {
            0x00 | 0xD0..=0xD7 => i = at + 2,
            // Fill bytes before a marker: `read_marker` skips them.
            _ => return Some(at),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A baseline JPEG as the `image` crate encodes it: a 24 × 16 gradient.
    fn baseline_jpeg() -> Vec<u8> {
        let img = image::RgbImage::from_fn(24, 16, |x, y| {
            image::Rgb([(x * 10) as u8, (y * 15) as u8, ((x + y) * 6) as u8])
        });
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Jpeg).unwrap();
        out.into_inner()
    }

    #[test]
    fn a_whole_jpeg_is_complete_and_every_shorter_prefix_is_not() {
        let jpeg = baseline_jpeg();
        assert_eq!(check_complete(&jpeg), Ok(()));
        // Every cut, in the headers and in the compressed data alike, loses the EOI.
        for cut in 2..jpeg.len() {
            let err = check_complete(&jpeg[..cut]).unwrap_err();
            assert_eq!(err.ends_at, cut);
        }
    }

    #[test]
    fn a_camera_jpeg_cut_anywhere_in_its_data_decodes_and_is_refused() {
        // A real camera JPEG (the Buddha collection, tests/fixtures/colmap-dense-buddha).
        // The decoder returns a whole 512 × 288 image from any cut in the compressed data:
        // why the check exists. If the decoder ever refuses these, the check is a second
        // line of defence only and this test says so.
        let jpeg =
            include_bytes!("../../tests/fixtures/colmap-dense-buddha/dense/images/00006.jpg");
        assert_eq!(check_complete(jpeg), Ok(()));
        for cut in [2000, jpeg.len() / 2, jpeg.len() - 3] {
            let decoded = image::load_from_memory(&jpeg[..cut]).map(|i| (i.width(), i.height()));
            assert_eq!(decoded.ok(), Some((512, 288)), "cut at {cut}");
            let err = check_complete(&jpeg[..cut]).unwrap_err();
            assert_eq!(err.reading, "the compressed image data");
        }
    }

    #[test]
    fn bytes_after_the_end_of_image_are_ignored() {
        let mut jpeg = baseline_jpeg();
        jpeg.extend_from_slice(b"\xFF\xD8 trailing camera data \xFF\xDA\x00");
        assert_eq!(check_complete(&jpeg), Ok(()));
    }

    #[test]
    fn a_thumbnail_end_in_an_app1_segment_does_not_end_the_image() {
        // An APP1 segment holding a whole JPEG (a thumbnail with its own EOI), inserted
        // after SOI; then the main image cut in its compressed data.
        let thumb = baseline_jpeg();
        let jpeg = baseline_jpeg();
        let mut with_thumb = jpeg[..2].to_vec();
        let len = (thumb.len() + 2) as u16;
        with_thumb.extend_from_slice(&[0xFF, 0xE1]);
        with_thumb.extend_from_slice(&len.to_be_bytes());
        with_thumb.extend_from_slice(&thumb);
        with_thumb.extend_from_slice(&jpeg[2..]);
        assert_eq!(check_complete(&with_thumb), Ok(()));
        let cut = with_thumb.len() - 40;
        assert!(check_complete(&with_thumb[..cut]).is_err());
    }

    #[test]
    fn a_progressive_jpeg_walks_through_its_scans() {
        // Written by ImageMagick (`convert -size 32x24 gradient:red-blue -interlace Plane`):
        // several SOS scans with Huffman tables between them.
        let jpeg = include_bytes!("../../tests/fixtures/photos/progressive-32x24.jpg");
        let sos = jpeg.windows(2).filter(|w| w == &[0xFF, SOS]).count();
        assert!(sos >= 2, "the fixture is not progressive ({sos} scans)");
        assert_eq!(check_complete(jpeg), Ok(()));
        assert!(check_complete(&jpeg[..jpeg.len() - 10]).is_err());
    }

    #[test]
    fn a_damaged_marker_is_left_to_the_decoder_not_called_truncated() {
        // The first segment's length grown by one: the walk lands a byte past the next
        // marker, on a byte that is not FF. The file is damaged, not short.
        let mut jpeg = baseline_jpeg();
        let len = u16::from_be_bytes([jpeg[4], jpeg[5]]) + 1;
        jpeg[4..6].copy_from_slice(&len.to_be_bytes());
        assert_eq!(check_complete(&jpeg), Ok(()));
    }

    #[test]
    fn files_that_are_not_jpegs_pass() {
        assert_eq!(check_complete(b"\x89PNG\r\n"), Ok(()));
        assert_eq!(check_complete(b""), Ok(()));
    }
}
