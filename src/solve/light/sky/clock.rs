//! The sun's direction from where and when a photo was taken (its EXIF geotag,
//! [`crate::import::geotag`]), for the sun-and-sky model.
//!
//! **The sun in the sky.** For latitude `φ`, longitude `λ` and a UTC instant, the solar
//! position algorithm of Blanco-Muriel et al. 2001 ("Computing the solar vector", Solar
//! Energy 70(5), the PSA algorithm; the `spa` crate, accurate to 0.5′ from 1999 on) gives
//! the sun's zenith angle `z` and its compass azimuth `A` (clockwise from north, seen from
//! above). Its elevation is `e = π/2 − z`.
//!
//! **The sun in the environment frame.** The frame's `e_z` is world up (from the cameras),
//! so the elevation carries over; its `e_x` points wherever the reconstruction put it, so
//! north lies at an unknown azimuth `ν` of the frame, the same for every photo of one
//! reconstruction. The frame is right-handed with `e_z` up, so its azimuth runs
//! counter-clockwise seen from above and the sun of photo `I` lies at frame azimuth
//! `ν − A_I`, elevation `e_I`. One unknown `ν` for the collection replaces a free
//! two-angle search per photo; [`super::model::SkyLight`] finds `ν` by the summed error of
//! the photos with a geotag ([`north_grid`], then [`north_refinement`]).

use crate::import::geotag::GeoTag;

/// Coarse candidates of `ν`: every 5°.
pub const NORTH_GRID_STEP: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// Refinement candidates of `ν` around the best coarse one: every 0.5° within ±2.5° (the
/// coarse spacing's half), so `ν` ends within 0.25° of the best on a 0.5° grid.
pub const NORTH_FINE_STEP: f64 = 0.5 * std::f64::consts::PI / 180.0;
const NORTH_FINE_HALF_WIDTH: i32 = 5;

/// The sun of one photo as the clock and place give it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockSun {
    /// Elevation above the horizon, radians.
    pub elevation: f64,
    /// Compass azimuth, radians clockwise from north.
    pub compass_azimuth: f64,
}

impl ClockSun {
    /// The sun at `tag`'s place and instant; `None` when it is below the horizon (no sun
    /// lights the photo) or the place is out of range.
    pub fn at(tag: &GeoTag) -> Option<ClockSun> {
        let utc = chrono::DateTime::from_timestamp(tag.utc_seconds, 0)?;
        let pos = spa::solar_position::<spa::StdFloatOps>(utc, tag.latitude, tag.longitude).ok()?;
        let elevation = (90.0 - pos.zenith_angle).to_radians();
        (elevation > 0.0).then_some(ClockSun {
            elevation,
            compass_azimuth: pos.azimuth.to_radians(),
        })
    }

    /// The sun's azimuth in the environment frame when north lies at frame azimuth
    /// `north` (module docs).
    pub fn frame_azimuth(&self, north: f64) -> f64 {
        north - self.compass_azimuth
    }
}

/// The suns of the training photos (in the problem's photo order) that have a geotag.
#[derive(Debug, Clone, PartialEq)]
pub struct ClockSuns {
    /// Per photo, its sun, or `None` (no geotag, or the sun below the horizon).
    pub per_photo: Vec<Option<ClockSun>>,
    /// Where they came from, in words (the report's).
    pub source: String,
}

impl ClockSuns {
    /// The number of photos with a sun.
    pub fn count(&self) -> usize {
        self.per_photo.iter().flatten().count()
    }
}

/// The coarse candidates of `ν`: `[0, 2π)` every [`NORTH_GRID_STEP`].
pub fn north_grid() -> Vec<f64> {
    let n = (std::f64::consts::TAU / NORTH_GRID_STEP).round() as usize;
    (0..n).map(|k| k as f64 * NORTH_GRID_STEP).collect()
}

/// The refinement candidates of `ν` around `centre` (every [`NORTH_FINE_STEP`] within
/// half the coarse spacing).
pub fn north_refinement(centre: f64) -> Vec<f64> {
    (-NORTH_FINE_HALF_WIDTH..=NORTH_FINE_HALF_WIDTH)
        .map(|j| centre + f64::from(j) * NORTH_FINE_STEP)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::calendar::days_from_civil;

    /// The worked example of NREL's Solar Position Algorithm (Reda & Andreas 2004,
    /// NREL/TP-560-34302, Table A5.1): Golden, Colorado, 17 October 2003 12:30:30 local
    /// time at UTC−7, i.e. 19:30:30 UTC; topocentric zenith 50.11162°, azimuth 194.34024°.
    /// The NREL value includes atmospheric refraction at 820 mbar and 11 °C (about 0.016°
    /// at 40° elevation), which the PSA algorithm leaves out, and PSA is accurate to 0.5′
    /// (0.008°): 0.05° bounds both with margin. A degree here would turn the sun by less
    /// than a tenth of a texel of the finest map the transport uses.
    #[test]
    fn the_sun_matches_nrel_spa_worked_example() {
        let tag = GeoTag {
            latitude: 39.742_476,
            longitude: -105.1786,
            utc_seconds: days_from_civil(2003, 10, 17) * 86_400 + 19 * 3600 + 30 * 60 + 30,
        };
        let sun = ClockSun::at(&tag).unwrap();
        let zenith = 90.0 - sun.elevation.to_degrees();
        assert!((zenith - 50.111_62).abs() < 0.05, "zenith {zenith}");
        let az = sun.compass_azimuth.to_degrees();
        assert!((az - 194.340_24).abs() < 0.05, "azimuth {az}");
    }

    /// At night there is no sun: the same place at 07:30 UTC (00:30 local).
    #[test]
    fn no_sun_below_the_horizon() {
        let tag = GeoTag {
            latitude: 39.742_476,
            longitude: -105.1786,
            utc_seconds: days_from_civil(2003, 10, 17) * 86_400 + 7 * 3600 + 30 * 60,
        };
        assert_eq!(ClockSun::at(&tag), None);
    }

    /// East (compass 90°) lies a quarter turn clockwise of north seen from above: with
    /// north on the frame's `e_y` (azimuth 90°), east is on `e_x` (azimuth 0).
    #[test]
    fn compass_east_is_clockwise_of_north() {
        let east = ClockSun {
            elevation: 0.3,
            compass_azimuth: std::f64::consts::FRAC_PI_2,
        };
        let north = std::f64::consts::FRAC_PI_2;
        assert!(east.frame_azimuth(north).abs() < 1e-12);
    }

    #[test]
    fn the_refinement_spans_half_the_coarse_spacing() {
        let g = north_grid();
        assert_eq!(g.len(), 72);
        let r = north_refinement(1.0);
        assert!((r[0] - (1.0 - NORTH_GRID_STEP / 2.0)).abs() < 1e-12);
        assert!((r[r.len() - 1] - (1.0 + NORTH_GRID_STEP / 2.0)).abs() < 1e-12);
    }
}
