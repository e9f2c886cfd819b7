//! Where and when a photo was taken, from its EXIF block: the place (GPS latitude and
//! longitude, WGS84 degrees) and the instant in UTC. Together they fix the sun's position
//! in the sky ([`crate::solve::light::sky::clock`]).
//!
//! The instant must be UTC, which the camera's own clock (`DateTimeOriginal`) is not:
//! - `GPSDateStamp` + `GPSTimeStamp` (EXIF 2.3: UTC by definition) when both are present;
//! - else `DateTimeOriginal` with `OffsetTimeOriginal` (EXIF 2.31, `±HH:MM` from UTC);
//! - else none: a local time without its zone can be hours off, which would put the sun
//!   tens of degrees away, so such a photo has no [`GeoTag`] (its sun is searched).
//!
//! A tag that is missing, malformed or out of range (latitude beyond ±90°, longitude beyond
//! ±180°, a month 13) gives `None`: a photo without a usable geotag is not an error.

use std::path::Path;

use exif::{Exif, In, Tag, Value};

use crate::import::calendar::{civil_from_days, days_from_civil};

/// The place and UTC instant of a photo's capture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoTag {
    /// Degrees north (negative south), `[−90, 90]`.
    pub latitude: f64,
    /// Degrees east (negative west), `[−180, 180]`.
    pub longitude: f64,
    /// Seconds since 1970-01-01 00:00 UTC.
    pub utc_seconds: i64,
}

/// The geotag of the image at `path` (module docs); `None` when it has none usable.
pub fn geotag(path: &Path) -> Option<GeoTag> {
    let file = std::fs::File::open(path).ok()?;
    let exif = exif::Reader::new()
        .read_from_container(&mut std::io::BufReader::new(file))
        .ok()?;
    let latitude = signed_degrees(&exif, Tag::GPSLatitude, Tag::GPSLatitudeRef, b'S')?;
    let longitude = signed_degrees(&exif, Tag::GPSLongitude, Tag::GPSLongitudeRef, b'W')?;
    if !(-90.0..=90.0).contains(&latitude) || !(-180.0..=180.0).contains(&longitude) {
        return None;
    }
    let utc_seconds = gps_utc(&exif).or_else(|| offset_utc(&exif))?;
    Some(GeoTag {
        latitude,
        longitude,
        utc_seconds,
    })
}

/// A GPS coordinate `(degrees, minutes, seconds)` with its reference letter; negative when
/// the reference is `negative` (`S` or `W`).
fn signed_degrees(exif: &Exif, value: Tag, reference: Tag, negative: u8) -> Option<f64> {
    let dms = rationals(exif, value)?;
    if dms.len() != 3 || dms.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return None;
    }
    let magnitude = dms[0] + dms[1] / 60.0 + dms[2] / 3600.0;
    let sign = match ascii(exif, reference)?.first()? {
        c if *c == negative => -1.0,
        b'N' | b'E' => 1.0,
        _ => return None,
    };
    Some(sign * magnitude)
}

/// `GPSDateStamp` (`YYYY:MM:DD`) and `GPSTimeStamp` (hours, minutes, seconds) as UTC
/// seconds.
fn gps_utc(exif: &Exif) -> Option<i64> {
    let date = std::str::from_utf8(ascii(exif, Tag::GPSDateStamp)?).ok()?;
    let mut parts = date.trim_end_matches('\0').split(':');
    let mut next = || parts.next()?.trim().parse::<i64>().ok();
    let (y, m, d) = (next()?, next()?, next()?);
    let hms = rationals(exif, Tag::GPSTimeStamp)?;
    if hms.len() != 3 || hms.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return None;
    }
    let day_seconds = hms[0] * 3600.0 + hms[1] * 60.0 + hms[2];
    (day_seconds < 86_401.0).then_some(())?;
    Some(civil_seconds(y, m, d)? + day_seconds.round() as i64)
}

/// `DateTimeOriginal` shifted to UTC by `OffsetTimeOriginal` (`±HH:MM`).
fn offset_utc(exif: &Exif) -> Option<i64> {
    let stamp = ascii(exif, Tag::DateTimeOriginal)?;
    let t = exif::DateTime::from_ascii(stamp).ok()?;
    let offset = std::str::from_utf8(ascii(exif, Tag::OffsetTimeOriginal)?).ok()?;
    let offset = offset.trim_end_matches('\0');
    let sign = match offset.as_bytes().first()? {
        b'+' => 1,
        b'-' => -1,
        _ => return None,
    };
    let (h, m) = offset[1..].split_once(':')?;
    let (h, m) = (h.parse::<i64>().ok()?, m.parse::<i64>().ok()?);
    if h > 14 || m >= 60 || t.hour >= 24 || t.minute >= 60 || t.second > 60 {
        return None;
    }
    let (y, mo, d) = (i64::from(t.year), i64::from(t.month), i64::from(t.day));
    let local = civil_seconds(y, mo, d)?
        + i64::from(t.hour) * 3600
        + i64::from(t.minute) * 60
        + i64::from(t.second);
    Some(local - sign * (h * 3600 + m * 60))
}

/// Seconds from 1970-01-01 to the start of `y-m-d`, for a valid date.
fn civil_seconds(y: i64, m: i64, d: i64) -> Option<i64> {
    ((1..=12).contains(&m) && (1..=31).contains(&d)).then(|| days_from_civil(y, m, d) * 86_400)
}

/// The rational values of `tag` in the primary image's IFDs, as `f64`.
fn rationals(exif: &Exif, tag: Tag) -> Option<Vec<f64>> {
    match &exif.get_field(tag, In::PRIMARY)?.value {
        Value::Rational(v) => Some(v.iter().map(|r| r.to_f64()).collect()),
        _ => None,
    }
}

/// The first ASCII string of `tag` in the primary image's IFDs.
fn ascii(exif: &Exif, tag: Tag) -> Option<&[u8]> {
    match &exif.get_field(tag, In::PRIMARY)?.value {
        Value::Ascii(v) => v.first().map(Vec::as_slice),
        _ => None,
    }
}

/// The EXIF fields of a geotag: GPS place and UTC date and time (what [`geotag`] reads
/// first), as a TIFF block for [`image::ImageEncoder::set_exif_metadata`].
pub fn exif_block(tag: &GeoTag) -> crate::Result<Vec<u8>> {
    use exif::{Field, Rational};
    let dms = |deg: f64| {
        let a = deg.abs();
        let d = a.floor();
        let m = ((a - d) * 60.0).floor();
        let s = ((a - d) * 60.0 - m) * 60.0;
        vec![
            Rational::from((d as u32, 1)),
            Rational::from((m as u32, 1)),
            Rational::from(((s * 1e4).round() as u32, 10_000)),
        ]
    };
    let ascii = |s: &str| Value::Ascii(vec![s.as_bytes().to_vec()]);
    let days = tag.utc_seconds.div_euclid(86_400);
    let secs = tag.utc_seconds.rem_euclid(86_400) as u32;
    let (y, m, d) = civil_from_days(days);
    let field = |tag, value| Field {
        tag,
        ifd_num: In::PRIMARY,
        value,
    };
    let fields = [
        field(
            Tag::GPSLatitudeRef,
            ascii(if tag.latitude < 0.0 { "S" } else { "N" }),
        ),
        field(Tag::GPSLatitude, Value::Rational(dms(tag.latitude))),
        field(
            Tag::GPSLongitudeRef,
            ascii(if tag.longitude < 0.0 { "W" } else { "E" }),
        ),
        field(Tag::GPSLongitude, Value::Rational(dms(tag.longitude))),
        field(Tag::GPSDateStamp, ascii(&format!("{y:04}:{m:02}:{d:02}"))),
        field(
            Tag::GPSTimeStamp,
            Value::Rational(vec![
                Rational::from((secs / 3600, 1)),
                Rational::from((secs / 60 % 60, 1)),
                Rational::from((secs % 60, 1)),
            ]),
        ),
    ];
    let mut writer = exif::experimental::Writer::new();
    fields.iter().for_each(|f| writer.push_field(f));
    let mut tiff = std::io::Cursor::new(Vec::new());
    writer
        .write(&mut tiff, false)
        .map_err(|e| crate::Error::Internal(format!("cannot write an EXIF geotag: {e}")))?;
    Ok(tiff.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("relight-geotag-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A 4×4 grey PNG carrying `block` as its eXIf chunk (the image crate's encoder).
    fn png_with_exif(path: &Path, block: Vec<u8>) {
        use image::ImageEncoder;
        let file = std::fs::File::create(path).unwrap();
        let mut enc = image::codecs::png::PngEncoder::new(file);
        enc.set_exif_metadata(block).unwrap();
        enc.write_image(&[128; 48], 4, 4, image::ExtendedColorType::Rgb8)
            .unwrap();
    }

    #[test]
    fn a_written_geotag_reads_back_south_and_west() {
        let dir = temp_dir("round-trip");
        let tag = GeoTag {
            latitude: -33.856_784,
            longitude: -151.215_297,
            // 2024-02-29 23:59:30 UTC
            utc_seconds: 19_782 * 86_400 + 86_370,
        };
        let path = dir.join("a.png");
        png_with_exif(&path, exif_block(&tag).unwrap());
        let back = geotag(&path).unwrap();
        // Seconds of arc are written to 1e-4″ (3e-8°).
        assert!((back.latitude - tag.latitude).abs() < 1e-7, "{back:?}");
        assert!((back.longitude - tag.longitude).abs() < 1e-7, "{back:?}");
        assert_eq!(back.utc_seconds, tag.utc_seconds);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_local_time_needs_its_offset() {
        use exif::{Field, Rational};
        let dir = temp_dir("offset");
        let field = |tag, value| Field {
            tag,
            ifd_num: In::PRIMARY,
            value,
        };
        let ascii = |s: &str| Value::Ascii(vec![s.as_bytes().to_vec()]);
        let deg =
            |d: u32| Value::Rational(vec![(d, 1).into(), (0, 1).into(), Rational::from((0, 1))]);
        let mut fields = vec![
            field(Tag::GPSLatitudeRef, ascii("N")),
            field(Tag::GPSLatitude, deg(48)),
            field(Tag::GPSLongitudeRef, ascii("E")),
            field(Tag::GPSLongitude, deg(2)),
            field(Tag::DateTimeOriginal, ascii("2024:03:01 01:30:00")),
        ];
        let write = |fields: &[Field], name: &str| {
            let mut writer = exif::experimental::Writer::new();
            fields.iter().for_each(|f| writer.push_field(f));
            let mut tiff = std::io::Cursor::new(Vec::new());
            writer.write(&mut tiff, false).unwrap();
            let path = dir.join(name);
            png_with_exif(&path, tiff.into_inner());
            geotag(&path)
        };
        // The camera's clock alone: no UTC instant, no geotag.
        assert_eq!(write(&fields, "local.png"), None);
        // 01:30 at +02:00 is 23:30 UTC the day before (2024-02-29, day 19782).
        fields.push(field(Tag::OffsetTimeOriginal, ascii("+02:00")));
        let tag = write(&fields, "offset.png").unwrap();
        assert_eq!(tag.utc_seconds, 19_782 * 86_400 + 23 * 3600 + 30 * 60);
        assert_eq!((tag.latitude, tag.longitude), (48.0, 2.0));
        // A latitude beyond 90°: no geotag.
        fields[1] = field(Tag::GPSLatitude, deg(91));
        assert_eq!(write(&fields, "bad.png"), None);
        // No EXIF at all, or no file: no geotag, no error.
        let plain = dir.join("plain.png");
        image::RgbImage::new(2, 2).save(&plain).unwrap();
        assert_eq!(geotag(&plain), None);
        assert_eq!(geotag(&dir.join("missing.png")), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
