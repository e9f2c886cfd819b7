//! What a sun-and-sky fit recovered, for the report: per photo its sun, turbidity and
//! lobe and where the sun came from, and the collection's north when the photos were
//! geotagged. Directions are in the environment frame (`e_z` up, azimuth from `e_x`
//! toward `e_y`, [`super::SunSky::from_angles`]).

use super::SunSky;

/// One photo's recovered sun and sky.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkyPhotoFit {
    /// Sun direction, turbidity and lobe sharpness.
    pub theta: SunSky,
    /// Whether the sun came from the photo's geotag (only the north searched) rather
    /// than from the free search.
    pub from_clock: bool,
}

/// The sun-and-sky fit of every photo of the problem, in its photo order.
#[derive(Debug, Clone, PartialEq)]
pub struct SkyFit {
    /// Per photo.
    pub photos: Vec<SkyPhotoFit>,
    /// The frame azimuth of north, radians, when geotags fixed it.
    pub north: Option<f64>,
}

impl SkyPhotoFit {
    /// The sun's elevation above the frame's horizon, radians.
    pub fn elevation(&self) -> f64 {
        self.theta.sun.z.clamp(-1.0, 1.0).asin()
    }

    /// The sun's frame azimuth, radians in `[0, 2π)`.
    pub fn azimuth(&self) -> f64 {
        let d = &self.theta.sun;
        d.y.atan2(d.x).rem_euclid(std::f64::consts::TAU)
    }

    /// The sun's compass azimuth (clockwise from north, [`super::clock`]) when north lies
    /// at frame azimuth `north`: `A = ν − φ`, in `[0, 2π)`.
    pub fn compass_azimuth(&self, north: f64) -> f64 {
        (north - self.azimuth()).rem_euclid(std::f64::consts::TAU)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::light::sky::clock::ClockSun;

    /// The angles read back are the ones a clock sun was placed with, and the compass
    /// azimuth inverts [`ClockSun::frame_azimuth`] (both exact up to rounding: 1e-12).
    #[test]
    fn angles_round_trip_through_the_frame() {
        use std::f64::consts::TAU;
        let clock = ClockSun {
            elevation: 0.4,
            compass_azimuth: 2.5,
        };
        let north = 1.1;
        let fit = SkyPhotoFit {
            theta: SunSky::from_angles(clock.frame_azimuth(north), clock.elevation, 3.0, 64.0),
            from_clock: true,
        };
        assert!((fit.elevation() - 0.4).abs() < 1e-12);
        assert!((fit.azimuth() - (north - 2.5_f64).rem_euclid(TAU)).abs() < 1e-12);
        assert!((fit.compass_azimuth(north) - 2.5).abs() < 1e-12);
    }
}
