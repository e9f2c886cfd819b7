//! The sun and sky a `--light sky` fit recovered, per training photo: the sun's elevation
//! and azimuth in the environment frame (`e_z` up, azimuth from `e_x` toward `e_y`), the
//! same direction in world coordinates, turbidity and the sun lobe's sharpness, and where
//! the sun came from (the photo's geotag with the searched north, or the free search).
//! With geotags the collection's north is given as a frame azimuth and each sun's compass
//! azimuth follows from it. On a synthetic workspace each sun is set beside the one it
//! was rendered with: the angle between them, and north's error.

use std::fmt::Write;

use serde::Serialize;

/// One training photo's recovered sun.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct SkySunEntry {
    /// Image name.
    pub image: String,
    /// `geotag` (the clock's sun turned by the searched north) or `search`.
    pub sun_from: String,
    /// Elevation above the horizon, degrees.
    pub elevation_degrees: f64,
    /// Azimuth in the environment frame, degrees in `[0, 360)`.
    pub azimuth_degrees: f64,
    /// Compass azimuth (clockwise from north), degrees, when north is known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compass_azimuth_degrees: Option<f64>,
    /// The direction toward the sun in world coordinates (the reconstruction's).
    pub sun_world: [f64; 3],
    /// Atmospheric turbidity.
    pub turbidity: f64,
    /// Sharpness `κ` of the sun lobe.
    pub sun_lobe_kappa: f64,
    /// The angle to the sun the photo was rendered with, degrees (synthetic workspaces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_error_degrees: Option<f64>,
}

/// The sun-and-sky fit of the training photos.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct SkyReport {
    /// The frame azimuth of north, degrees, when geotags fixed it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub north_degrees: Option<f64>,
    /// North's error against the truth's, degrees in `[0, 180]` (synthetic workspaces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_north_error_degrees: Option<f64>,
    /// The angle between the up estimated from the cameras (the environment frame's
    /// `e_z`, the horizon a geotag's sun is placed from) and the truth's, degrees
    /// (synthetic workspaces).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cameras_up_error_degrees: Option<f64>,
    /// Per training photo.
    pub photos: Vec<SkySunEntry>,
}

impl SkyReport {
    /// The median of the suns' errors against the truth, when every photo has one.
    pub fn median_truth_error(&self) -> Option<f64> {
        let mut e: Vec<f64> = self
            .photos
            .iter()
            .map(|p| p.truth_error_degrees)
            .collect::<Option<_>>()?;
        if e.is_empty() {
            return None;
        }
        e.sort_by(f64::total_cmp);
        let m = e.len() / 2;
        Some(if e.len() % 2 == 1 {
            e[m]
        } else {
            0.5 * (e[m - 1] + e[m])
        })
    }

    /// One paragraph: where the suns came from, north, and the truth's errors.
    pub fn summary(&self) -> String {
        let n = self.photos.len();
        let tagged = self
            .photos
            .iter()
            .filter(|p| p.sun_from == "geotag")
            .count();
        let mut s = format!(
            "The sun of {tagged} of the {n} training photos from their geotags, of {} by search",
            n - tagged
        );
        if let Some(north) = self.north_degrees {
            let _ = write!(s, "; north at frame azimuth {north:.1}°");
            if let Some(e) = self.truth_north_error_degrees {
                let _ = write!(s, " ({e:.2}° from the truth's)");
            }
        }
        if let (Some(c), true) = (self.cameras_up_error_degrees, self.north_degrees.is_some()) {
            let _ = write!(
                s,
                "; the cameras' up, the horizon the geotags' suns are placed from, is {c:.2}° \
                 from the truth's"
            );
        }
        if let Some(m) = self.median_truth_error() {
            let worst = self
                .photos
                .iter()
                .filter_map(|p| p.truth_error_degrees)
                .fold(0.0, f64::max);
            let _ = write!(
                s,
                "; against the suns the photos were rendered with: median {m:.2}°, worst {worst:.2}°"
            );
        }
        s.push('.');
        s
    }

    /// The table's rows as cells: photo, source, elevation, azimuth, compass azimuth,
    /// turbidity, κ and (with the truth) the error.
    pub fn rows(&self) -> Vec<Vec<String>> {
        let truth = self.photos.iter().any(|p| p.truth_error_degrees.is_some());
        self.photos
            .iter()
            .map(|p| {
                let mut r = vec![
                    p.image.clone(),
                    p.sun_from.clone(),
                    format!("{:.1}°", p.elevation_degrees),
                    format!("{:.1}°", p.azimuth_degrees),
                    p.compass_azimuth_degrees
                        .map_or("–".into(), |a| format!("{a:.1}°")),
                    format!("{:.2}", p.turbidity),
                    format!("{:.0}", p.sun_lobe_kappa),
                ];
                if truth {
                    r.push(
                        p.truth_error_degrees
                            .map_or("–".into(), |e| format!("{e:.2}°")),
                    );
                }
                r
            })
            .collect()
    }

    /// The column heads of [`SkyReport::rows`].
    pub fn header(&self) -> Vec<&'static str> {
        let mut h = vec![
            "training photo",
            "sun from",
            "elevation",
            "frame azimuth",
            "compass azimuth",
            "turbidity",
            "sun lobe κ",
        ];
        if self.photos.iter().any(|p| p.truth_error_degrees.is_some()) {
            h.push("error against the truth's sun");
        }
        h
    }

    /// The section of `report.md`.
    pub fn markdown(&self) -> String {
        let mut s = String::from("## Sun and sky\n\n");
        let _ = writeln!(s, "{}\n", self.summary());
        let head = self.header();
        let _ = writeln!(s, "| {} |", head.join(" | "));
        let _ = writeln!(s, "|---|---|{}|", vec!["---:"; head.len() - 2].join("|"));
        for r in self.rows() {
            let _ = writeln!(s, "| {} |", r.join(" | "));
        }
        s.push('\n');
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(image: &str, from: &str, err: Option<f64>) -> SkySunEntry {
        SkySunEntry {
            image: image.into(),
            sun_from: from.into(),
            elevation_degrees: 30.0,
            azimuth_degrees: 120.0,
            truth_error_degrees: err,
            ..Default::default()
        }
    }

    /// The summary counts the sources and takes the median and worst of the errors; the
    /// table has one row per photo and a truth column only when there is a truth.
    #[test]
    fn summary_and_table_follow_the_entries() {
        let r = SkyReport {
            north_degrees: Some(104.1),
            truth_north_error_degrees: Some(0.3),
            cameras_up_error_degrees: Some(2.19),
            photos: vec![
                entry("a.png", "geotag", Some(1.0)),
                entry("b.png", "geotag", Some(3.0)),
                entry("c.png", "search", Some(2.0)),
                entry("d.png", "geotag", Some(10.0)),
            ],
        };
        assert_eq!(r.median_truth_error(), Some(2.5));
        let s = r.summary();
        assert!(
            s.contains("3 of the 4 training photos from their geotags, of 1 by search"),
            "{s}"
        );
        assert!(
            s.contains("north at frame azimuth 104.1° (0.30° from the truth's)"),
            "{s}"
        );
        assert!(s.contains("median 2.50°, worst 10.00°"), "{s}");
        assert!(s.contains("placed from, is 2.19° from the truth's"), "{s}");
        let md = r.markdown();
        assert_eq!(
            md.lines().filter(|l| l.starts_with("| ")).count(),
            1 + 4,
            "{md}"
        );
        assert!(md.contains("error against the truth's sun"));
        let plain = SkyReport {
            photos: vec![entry("a.png", "search", None)],
            ..Default::default()
        };
        assert_eq!(plain.median_truth_error(), None);
        assert!(!plain.markdown().contains("truth"), "{}", plain.markdown());
    }
}
