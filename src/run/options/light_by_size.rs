//! `run` without `--light`: the light model chosen per scene by validation (`auto`) on
//! meshes below [`LargeMeshSettings::FROM_VERTICES`] vertices, the paper's free map from
//! there ([`RunOptions::light_by_size`]).
//!
//! `auto` ([`crate::solve::light::choose`]) fits every light model that applies (the
//! paper's map, the map under the prior of real skies, the sun and sky, and the shared map
//! when some photos were taken together) with the right halves of 4 training photos held
//! back, keeps the one that predicts those halves best, and fits it again: three to four
//! fits more than the paper's model alone, the sun and sky's the dearest. Measured on this build (2026-12-04,
//! `bench-results/light-default.md`), `auto` against `paper`, run seed 1 unless stated:
//!
//! - the built-in example at seeds 1–6 (2.9K vertices; `auto` kept `prior` at 6 of 6): the
//!   headline 0.3853 → 0.3178 (mean; better at 6 of 6), the held-out photos under their
//!   true light 0.0415 → 0.0380 (better at 6 of 6), wall 3.4 → 14.7 s;
//! - eight rendered workspaces at 192² (`spot-three`, `spot-ggx`, `spot-diffuse`,
//!   `spot-varying`, synth seeds 2 and 3): under the true light better on 3 (−1.9% to
//!   −6.6%, `prior` or `sky` kept) and identical on 5 (`paper` kept), never worse; the
//!   headline never worse; wall 2.2–4.6×;
//! - the real Buddha photos (seeds 1–2, `sky` kept): headline −0.1% and +2.4%, wall
//!   4.9× and 3.4×.
//!
//! - 100K vertices × 13 photos (`paper` kept): wall 82 → 288 s (3.5×), the estimate
//!   stage 18 → 202 s.
//!
//! From 50K vertices (the large-mesh threshold) those extra fits would take the run past
//! the speed target (100K vertices × 13 photos in two minutes on two cores), so such a run
//! keeps the paper's map and says so in a note; `--light auto` makes the choice at any
//! size.

use super::{LargeMeshSettings, RunOptions};
use crate::solve::light::choose::LightChoice;

/// The light model a run without `--light` uses on a mesh of `vertices` (module docs).
pub fn light_for_mesh(vertices: usize) -> LightChoice {
    if vertices < LargeMeshSettings::FROM_VERTICES {
        LightChoice::Auto
    } else {
        LightChoice::Paper
    }
}

/// The options a run on a mesh of `vertices` uses when `o.light_by_size` (`Some`, with
/// the light model of [`light_for_mesh`] and the note that says why), else `None`.
pub fn sized_light(o: &RunOptions, vertices: usize) -> Option<(RunOptions, String)> {
    if !o.light_by_size {
        return None;
    }
    let light = light_for_mesh(vertices);
    let from = LargeMeshSettings::FROM_VERTICES;
    let note = match light {
        LightChoice::Auto => format!(
            "light model chosen by validation (--light auto, the default below {from} vertices: the mesh has {vertices}); --light paper fits the paper's map alone, 2–5× faster"
        ),
        _ => format!(
            "light model: the paper's free map (--light paper, the default from {from} vertices: the mesh has {vertices}, and --light auto's extra fits took 3.5× the run's time at 100K vertices); --light auto chooses by validation at any size"
        ),
    };
    let mut sized = o.clone();
    sized.light = light;
    Some((sized, note))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without `light_by_size` the options stay as given; with it the light model follows
    /// the mesh's size on either side of the threshold, and nothing else changes.
    #[test]
    fn the_light_follows_the_mesh_size_only_when_not_given() {
        let from = LargeMeshSettings::FROM_VERTICES;
        let given = RunOptions::new("ws".into(), "out".into());
        assert!(sized_light(&given, 10).is_none());
        let mut auto = given.clone();
        auto.light_by_size = true;
        for (vertices, want) in [
            (1, LightChoice::Auto),
            (from - 1, LightChoice::Auto),
            (from, LightChoice::Paper),
            (10 * from, LightChoice::Paper),
        ] {
            let (sized, note) = sized_light(&auto, vertices).unwrap();
            assert_eq!(sized.light, want, "{vertices} vertices");
            assert!(note.contains(&vertices.to_string()), "{note}");
            let mut back = sized.clone();
            back.light = auto.light;
            assert_eq!(format!("{back:?}"), format!("{auto:?}"));
        }
    }
}
