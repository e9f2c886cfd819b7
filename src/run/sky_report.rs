//! The report's sun-and-sky section ([`crate::report::sky`]) from a `--light sky` fit:
//! each training photo's sun in the run's environment frame, in world coordinates
//! (`world = env_from_worldᵀ · env`) and, on a synthetic workspace, against the sun it was
//! rendered with. The truth's directions are in the truth's own environment frame, so
//! they are carried into the run's through world coordinates:
//! `s_run = env_from_world · truth_env_from_worldᵀ · s_truth`; north likewise, as the
//! horizontal direction `(cos ν, sin ν, 0)` of the truth's frame. The cameras' up (the
//! run's `e_z`) is set beside the truth's: a clock sun is placed from the run's horizon,
//! so that tilt moves every geotagged sun.

use nalgebra::Matrix3;

use super::truth::Truth;
use super::Fitted;
use crate::report::sky::{SkyReport, SkySunEntry};
use crate::solve::light::sky::summary::{SkyFit, SkyPhotoFit};
use crate::Vec3;

/// The section, when the fit was the sun-and-sky model's.
pub(crate) fn sky_report(fitted: &Fitted, truth: Option<&Truth>) -> Option<SkyReport> {
    let fit = fitted.est.sky.as_ref()?;
    let frames = truth.map(|t| Frames {
        truth: t.env_from_world,
        run: fitted.env_from_world,
        truth_north: t.north,
    });
    let photos = fitted
        .train
        .iter()
        .zip(&fit.photos)
        .map(|(&v, p)| {
            let name = &fitted.scene.views[v].image.name;
            let truth_sun = truth.and_then(|t| t.photos.get(name)).and_then(|t| t.sun);
            let error = truth_sun
                .zip(frames.as_ref())
                .map(|(s, f)| p.theta.sun.angle(&f.to_run(&s)).to_degrees());
            entry(name, p, fit, &fitted.env_from_world, error)
        })
        .collect();
    let mut report = SkyReport {
        north_degrees: fit
            .north
            .map(|n| n.rem_euclid(std::f64::consts::TAU).to_degrees()),
        photos,
        ..Default::default()
    };
    if let Some(f) = &frames {
        add_truth_frame(&mut report, fit.north, &fitted.env_from_world, f);
    }
    Some(report)
}

/// With the truth: north's error, and how far the cameras' up (the frame's `e_z`) is from
/// the truth's (a clock sun is placed from the frame's horizon, so that tilt moves it).
fn add_truth_frame(
    report: &mut SkyReport,
    north: Option<f64>,
    env_from_world: &Matrix3<f64>,
    f: &Frames,
) {
    let truth_up = f.truth.transpose() * Vec3::z();
    let cameras_up = env_from_world.transpose() * Vec3::z();
    report.cameras_up_error_degrees = Some(cameras_up.angle(&truth_up).to_degrees());
    report.truth_north_error_degrees = north.zip(f.truth_north).map(|(got, want)| {
        let d = f.to_run(&Vec3::new(want.cos(), want.sin(), 0.0));
        azimuth_gap(got, d.y.atan2(d.x)).to_degrees()
    });
}

/// One photo's row.
fn entry(
    name: &str,
    p: &SkyPhotoFit,
    fit: &SkyFit,
    env_from_world: &Matrix3<f64>,
    truth_error_degrees: Option<f64>,
) -> SkySunEntry {
    let world = env_from_world.transpose() * p.theta.sun;
    SkySunEntry {
        image: name.to_string(),
        sun_from: if p.from_clock { "geotag" } else { "search" }.to_string(),
        elevation_degrees: p.elevation().to_degrees(),
        azimuth_degrees: p.azimuth().to_degrees(),
        compass_azimuth_degrees: fit.north.map(|n| p.compass_azimuth(n).to_degrees()),
        sun_world: [world.x, world.y, world.z],
        turbidity: p.theta.turbidity,
        sun_lobe_kappa: p.theta.kappa,
        truth_error_degrees,
    }
}

/// The truth's environment frame and the run's (rows `e_x, e_y, e_z` in world
/// coordinates), and the truth's north (a frame azimuth of the truth's).
struct Frames {
    truth: Matrix3<f64>,
    run: Matrix3<f64>,
    truth_north: Option<f64>,
}

impl Frames {
    /// A direction of the truth's frame in the run's.
    fn to_run(&self, d: &Vec3) -> Vec3 {
        self.run * (self.truth.transpose() * d)
    }
}

/// The gap between two azimuths, radians in `[0, π]`.
fn azimuth_gap(a: f64, b: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    ((a - b + PI).rem_euclid(TAU) - PI).abs()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    /// The run's frame turned 30° about up from the truth's, then tilted 2° about its
    /// `e_x` (as a camera-estimated up would be): a truth sun lands where that rotation
    /// puts it, the cameras' up is 2° off the truth's, and a north of 70° (the truth's
    /// 100° less the turn) is within the tilt's effect on an azimuth (under 0.1° at 2°);
    /// exact figures to rounding (1e-9). Checked against the rotations applied directly.
    #[test]
    fn the_truth_is_carried_into_the_runs_frame() {
        let truth = Matrix3::<f64>::identity();
        let turn = Rotation3::from_axis_angle(&Vec3::z_axis(), -30f64.to_radians());
        let tilt = Rotation3::from_axis_angle(&Vec3::x_axis(), 2f64.to_radians());
        // Rows of the run's frame in world coordinates: run = R · world.
        let r = (tilt * turn).into_inner();
        let f = Frames {
            truth,
            run: r,
            truth_north: Some(100f64.to_radians()),
        };
        let sun = Vec3::new(0.3, -0.5, 0.8).normalize();
        assert!(f.to_run(&sun).angle(&(r * sun)) < 1e-9);
        let mut report = SkyReport::default();
        add_truth_frame(&mut report, Some(70f64.to_radians()), &r, &f);
        let up = report.cameras_up_error_degrees.unwrap();
        assert!((up - 2.0).abs() < 1e-9, "{report:?}");
        assert!(
            report.truth_north_error_degrees.unwrap() < 0.1,
            "{report:?}"
        );
        let flat = Frames {
            run: turn.into_inner(),
            ..f
        };
        add_truth_frame(&mut report, Some(70f64.to_radians()), &flat.run, &flat);
        assert!(
            report.truth_north_error_degrees.unwrap() < 1e-9,
            "{report:?}"
        );
        assert!(
            report.cameras_up_error_degrees.unwrap() < 1e-9,
            "{report:?}"
        );
        let gap = |a: f64, b: f64| azimuth_gap(a.to_radians(), b.to_radians()).to_degrees();
        assert!((gap(350.0, 10.0) - 20.0).abs() < 1e-9);
        assert!((gap(0.0, 180.0) - 180.0).abs() < 1e-9);
    }
}
