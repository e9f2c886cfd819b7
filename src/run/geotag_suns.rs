//! The training photos' suns from their geotags (`--light sky`,
//! [`crate::solve::light::sky::clock`]): each photo's EXIF place and UTC instant
//! ([`crate::import::geotag`]) give its sun's elevation and compass azimuth. Photos
//! without a usable geotag, or taken with the sun below the horizon, keep a searched sun.

use std::path::Path;

use crate::import::geotag::geotag;
use crate::import::scene::Scene;
use crate::solve::light::sky::clock::{ClockSun, ClockSuns};

/// The suns of the training photos `train` (views of `scene`, in the problem's photo
/// order); `None` when none has one.
pub fn resolve(scene: &Scene, train: &[usize]) -> Option<ClockSuns> {
    suns_of(&scene.photo_paths(train))
}

/// The suns of the photos at `paths` (module docs); `None` when none has one.
pub fn suns_of(paths: &[&Path]) -> Option<ClockSuns> {
    let tags: Vec<_> = paths.iter().map(|p| geotag(p)).collect();
    let per_photo: Vec<Option<ClockSun>> = tags
        .iter()
        .map(|t| t.as_ref().and_then(ClockSun::at))
        .collect();
    let (tagged, lit) = (
        tags.iter().flatten().count(),
        per_photo.iter().flatten().count(),
    );
    if lit == 0 {
        return None;
    }
    let dark = if lit < tagged {
        format!("; {} taken with the sun below the horizon", tagged - lit)
    } else {
        String::new()
    };
    let source = format!(
        "the sun of {lit} of the {} training photos from their geotags (EXIF GPS place and UTC time), north searched{dark}",
        paths.len()
    );
    Some(ClockSuns { per_photo, source })
}
