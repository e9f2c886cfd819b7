//! `run` without `--light` ([`RunOptions::light_by_scene`], [`scene_light`]): the light
//! model chosen per scene by validation (`auto`) on meshes below
//! [`LargeMeshSettings::FROM_VERTICES`] vertices whose fit keeps a shiny lobe, without the
//! paper's free map among the candidates (`constrained`) for
//! [`CONSTRAINED_FROM_MATERIALS`] or more materials from [`PRIOR_FROM_PHOTOS`] training
//! photos; below that size, over the Lambertian lobe alone, the prior of real skies
//! (`prior`) for two or more materials from [`PRIOR_FROM_PHOTOS`] training photos and the
//! paper's free map otherwise; the paper's map on larger meshes.
//!
//! `auto` ([`crate::solve::light::choose`]) fits every light model that applies (the
//! paper's map, the map under the prior of real skies, the sun and sky, and the shared map
//! when some photos were taken together) with the right halves of 4 training photos held
//! back, keeps the one that predicts those halves best, and fits it again: three to four
//! fits more than the paper's model alone, the sun and sky's the dearest. Measured
//! (2026-12-04, `bench-results/light-default.md`), `auto` against `paper`, run seed 1
//! unless stated:
//!
//! - the built-in example at seeds 1–6 (2.9K vertices, shiny lobes; `auto` kept `prior` at
//!   6 of 6): the headline 0.3853 → 0.3178 (mean; better at 6 of 6), the held-out photos
//!   under their true light 0.0415 → 0.0380 (better at 6 of 6), wall 3.4 → 14.7 s (4.05 →
//!   9.29 s with the sun and sky's faster search and basis, `bench-results/sky-sampling.md`);
//! - 13 rendered workspaces at 192² (`spot-three`, `spot-ggx`, `spot-diffuse`,
//!   `spot-varying`, `spot-sky` with and without geotags; synth seeds 2 and 3; 8 or 12
//!   photos): under the true light better on 4 (−1.9% to −17.7%, `prior` or `sky` kept),
//!   identical on 8 (`paper` kept) and 1.2% worse on geotagged `spot-sky`, whose headline falls 15%; the
//!   headline never worse; wall 2.2–5.0×;
//! - fits over the Lambertian lobe alone: `spot-diffuse` (2 workspaces) kept `paper`
//!   (identical figures at 2.2–2.4× the wall time), and the real Buddha photos (6.6K
//!   vertices; seeds 1–4, `sky` or `prior` kept) lost headline at 3 of 4 seeds (−0.1%,
//!   +2.4%, +1.4%, +1.3%) at 3.4–4.9× the wall time. With no shiny lobe the free map is
//!   seen only through the cosine lobe's low frequencies, and the right halves' score that
//!   ranks the light models does not carry to held-out photos;
//! - fits of two materials over the Lambertian lobe alone with many photos (2026-12-04,
//!   `bench-results/light-prior-many-photos.md`), `prior` forced against `paper`: on
//!   `spot-diffuse` with 24 training photos the worst albedo ratio better on 4 of 5 ablation
//!   seeds (median 0.062 → 0.052, relit better or equal on 5) and on 4 of 4 runs at 192²
//!   (the median ratios 0.024 / 0.037 / 0.046 / 0.050 → 0.022 / 0.026 / 0.034 / 0.038; the
//!   held-out photos under their true light −6% to +3%); with 18 training photos better on
//!   3 of 4 runs, the held-out photos under their true light +2% to +6% on 4 of 4; with 12
//!   better on 2 of 5 and 2 of 4. On 28 real grey photos of the Buddha (23 training, one
//!   material, so no ratio to hold) the prior's headline is +0.7% on average over 10
//!   seeds, better on 5 and worse on 5 (−2.2% to +3.2%): within the seeds' spread, and such
//!   a fit keeps the paper's map.
//!   `auto` does not find the prior's gain (its halves score kept `paper` on 3 of the 5
//!   ablation seeds, where the prior's ratios were the better ones);
//! - three materials with a shiny lobe and 24 training photos (2026-12-06,
//!   `bench-results/light-prior-shiny.md`, sections 3 and 8), `constrained` against
//!   `auto`: through `run` (`spot-three`, 128² and 192² photos, seeds 1–5) `auto` kept the
//!   paper's map on 2 of 10 workspaces and the prior on 8, which `constrained` keeps too
//!   (its scores are `auto`'s); on those 2 `constrained` kept the prior, under the true
//!   light 1.104× → 1.072× and 1.084× → 1.055× the floor, the headline −8.5% and −10.5%.
//!   In the ablation (32² maps, seeds 1–5, the held-out photos judged as `run` judges them)
//!   `auto` kept the paper's map on seeds 1–4, where `constrained` keeps the prior:
//!   material accuracy ≥ 0.98 on 3 seeds instead of 1, the held-out photos within 1.2×
//!   their floor on 5 of 5 either way (1.09 / 1.13 / 1.04 / 1.16× → 1.03 / 0.98 / 1.05 /
//!   1.02×), the worst albedo ratio lower on 3 of 4. With two materials the halves'
//!   choice stays: there the prior was worse on 2 of 3 `spot-ggx` workspaces;
//! - 100K vertices × 13 photos (`paper` kept): wall 82 → 288 s (3.5×), the estimate stage
//!   18 → 202 s.
//!
//! From 50K vertices (the large-mesh threshold) those extra fits would take the run past
//! the speed target (100K vertices × 13 photos in two minutes on two cores), so such a run
//! keeps the paper's map and says so in a note; `--light auto` makes the choice at any
//! size and over any basis.

use super::{LargeMeshSettings, RunOptions};
use crate::solve::light::choose::LightChoice;
use crate::transport::brdf::BasisBrdf;

/// Least training photos from which a fit of two or more materials over the Lambertian
/// lobe alone takes the prior of real skies (`--light prior`) instead of the paper's free
/// map (module docs). Each photo's free map can move brightness between surfaces that face
/// different ways, which moves the albedo ratios between materials; the more photos, the
/// more maps to move it. The ablation's `spot-diffuse` with 24 training photos: the worst
/// ratio better on 4 of 5 seeds, at 192² through `run` on 4 of 4; with 18 on 3 of 4 runs
/// but the held-out photos under their true light 2–6% worse on 4 of 4; with 12, better on
/// 2 of 5 and 2 of 4 (`bench-results/light-prior-many-photos.md`). 20 lies between 18
/// and 24.
pub const PRIOR_FROM_PHOTOS: usize = 20;

/// Least materials from which a fit with a shiny lobe and [`PRIOR_FROM_PHOTOS`] training
/// photos chooses its light model without the paper's free map (`--light constrained`:
/// the prior of real skies, the sun and sky, the shared map, kept by validation) instead
/// of `--light auto` (module docs). Every free map can move brightness between the
/// materials; the halves score that `auto` ranks the models by does not see it. With three
/// materials `constrained` was better wherever it changed the model (2 of 10 workspaces
/// through `run`, 4 of 5 ablation seeds). With two it trades: on the glossy `spot-varying`
/// the ablation's worst ratio lower on 3 of 5 seeds and higher on 2, through `run` lower
/// on 5 of 6, but on `spot-ggx` (one shiny material) worse on 2 of 3
/// (`bench-results/light-prior-shiny.md`), so two materials keep `auto`.
pub const CONSTRAINED_FROM_MATERIALS: usize = 3;

/// What the light model of a run without `--light` depends on.
#[derive(Debug, Clone, Copy)]
pub struct FitShape<'a> {
    /// Mesh vertices.
    pub vertices: usize,
    /// The lobes the fit keeps.
    pub basis: &'a [BasisBrdf],
    /// Training photos.
    pub photos: usize,
    /// The materials the fit starts with (`run`: the start's clusters, which the photos'
    /// colours can make fewer than the pilot or `--materials` asked for); `None` when not
    /// known.
    pub materials: Option<usize>,
}

impl FitShape<'_> {
    /// Two or more materials over the Lambertian lobe alone, from [`PRIOR_FROM_PHOTOS`]
    /// training photos: the albedo ratios between materials that many free maps can move.
    fn many_maps_over_lambert(&self) -> bool {
        matches!(self.basis, [BasisBrdf::Lambert]) && self.many_maps(2)
    }

    /// [`CONSTRAINED_FROM_MATERIALS`] or more materials with a shiny lobe, from
    /// [`PRIOR_FROM_PHOTOS`] training photos: the fit `--light constrained` serves.
    fn many_maps_many_materials(&self) -> bool {
        !matches!(self.basis, [BasisBrdf::Lambert]) && self.many_maps(CONSTRAINED_FROM_MATERIALS)
    }

    /// At least `least_materials` materials (known) and [`PRIOR_FROM_PHOTOS`] training
    /// photos.
    fn many_maps(&self, least_materials: usize) -> bool {
        self.materials.is_some_and(|k| k >= least_materials) && self.photos >= PRIOR_FROM_PHOTOS
    }
}

/// The light model of a run without `--light` (`o.light_by_scene`) for a fit of `shape`,
/// with the report note that says why (module docs); `None` when `--light` was given.
pub fn scene_light(o: &RunOptions, shape: FitShape) -> Option<(LightChoice, String)> {
    if !o.light_by_scene {
        return None;
    }
    let (vertices, basis) = (shape.vertices, shape.basis);
    let from = LargeMeshSettings::FROM_VERTICES;
    Some(if vertices >= from {
        (LightChoice::Paper, format!(
            "light model: the paper's free map (--light paper, the default from {from} vertices: the mesh has {vertices}, and --light auto's extra fits took 3.5× the run's time at 100K vertices); --light auto chooses by validation at any size"
        ))
    } else if shape.many_maps_over_lambert() {
        (LightChoice::Prior, format!(
            "light model: each photo's map under the prior of real skies (--light not given; the fit keeps the Lambertian lobe alone, with {} materials and {} training photos, at least {PRIOR_FROM_PHOTOS}: with that many free maps the prior holds the materials' albedo ratios better); --light paper fits the paper's free map",
            shape.materials.unwrap_or_default(),
            shape.photos
        ))
    } else if matches!(basis, [BasisBrdf::Lambert]) {
        (LightChoice::Paper, format!(
            "light model: the paper's free map (--light not given, and the fit keeps the Lambertian lobe alone with {} training photos and {}: there the light models measured no better, the real Buddha photos' headline +1.3% on average under --light auto; from {PRIOR_FROM_PHOTOS} photos and two materials the prior of real skies); --light auto chooses by validation",
            shape.photos,
            match shape.materials {
                Some(1) => "one material".to_string(),
                Some(k) => format!("{k} materials"),
                None => "a material count not yet chosen".to_string(),
            }
        ))
    } else if shape.many_maps_many_materials() {
        (LightChoice::Constrained, format!(
            "light model chosen by validation without the paper's free map (--light constrained: --light not given, the fit keeps a shiny lobe with {} materials and {} training photos, at least {CONSTRAINED_FROM_MATERIALS} and {PRIOR_FROM_PHOTOS}: with that many free maps the maps move brightness between the materials); --light auto lets the paper's map compete",
            shape.materials.unwrap_or_default(),
            shape.photos
        ))
    } else {
        (LightChoice::Auto, format!(
            "light model chosen by validation (--light auto, the default below {from} vertices when the fit keeps a shiny lobe: the mesh has {vertices}); --light paper fits the paper's map alone, 2–5× faster"
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without `light_by_scene` the light stays as given; with it `auto` only below the
    /// size threshold and with a shiny lobe; below it, over the Lambertian lobe alone, the
    /// prior with two or more materials and [`PRIOR_FROM_PHOTOS`] training photos; else the
    /// paper's map; with a shiny lobe, `constrained` from [`CONSTRAINED_FROM_MATERIALS`]
    /// materials and [`PRIOR_FROM_PHOTOS`] training photos, else `auto`; a note naming the
    /// mesh's size, the lobes or the photos.
    #[test]
    fn the_light_follows_the_mesh_size_and_lobes_only_when_not_given() {
        let from = LargeMeshSettings::FROM_VERTICES;
        let lambert = [BasisBrdf::Lambert];
        let shiny = [BasisBrdf::Lambert, BasisBrdf::Phong { exponent: 50.0 }];
        let given = RunOptions::new("ws".into(), "out".into());
        let shape = |vertices, basis, photos, materials| FitShape {
            vertices,
            basis,
            photos,
            materials,
        };
        assert!(scene_light(&given, shape(10, &shiny, 30, Some(2))).is_none());
        assert!(scene_light(&given, shape(10, &lambert, 30, Some(2))).is_none());
        let mut auto = given.clone();
        auto.light_by_scene = true;
        let many = PRIOR_FROM_PHOTOS;
        for (vertices, basis, photos, k, want) in [
            (1, &shiny[..], 12, Some(2), LightChoice::Auto),
            (from - 1, &shiny[..], many, Some(2), LightChoice::Auto),
            (from, &shiny[..], 12, None, LightChoice::Paper),
            (10 * from, &shiny[..], many, Some(2), LightChoice::Paper),
            (1, &lambert[..], 12, Some(2), LightChoice::Paper),
            (1, &lambert[..], many - 1, Some(3), LightChoice::Paper),
            (1, &lambert[..], many, Some(2), LightChoice::Prior),
            (
                from - 1,
                &lambert[..],
                10 * many,
                Some(4),
                LightChoice::Prior,
            ),
            (1, &shiny[..], many, Some(3), LightChoice::Constrained),
            (
                from - 1,
                &shiny[..],
                10 * many,
                Some(5),
                LightChoice::Constrained,
            ),
            (1, &shiny[..], many - 1, Some(3), LightChoice::Auto),
            (1, &shiny[..], many, None, LightChoice::Auto),
            (from, &shiny[..], many, Some(3), LightChoice::Paper),
            (1, &lambert[..], many, Some(1), LightChoice::Paper),
            (1, &lambert[..], many, None, LightChoice::Paper),
            (10 * from, &lambert[..], many, Some(2), LightChoice::Paper),
        ] {
            let (light, note) = scene_light(&auto, shape(vertices, basis, photos, k)).unwrap();
            assert_eq!(
                light, want,
                "{vertices} vertices, {basis:?}, {photos} photos, {k:?}"
            );
            let says = note.contains(&vertices.to_string())
                || note.contains("Lambertian")
                || note.contains("shiny lobe");
            assert!(says, "{note}");
            if matches!(light, LightChoice::Prior | LightChoice::Constrained) {
                assert!(
                    note.contains(&format!("{photos} training photos")),
                    "{note}"
                );
            }
        }
    }
}
