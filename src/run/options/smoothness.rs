//! `run --smoothness auto` (the default): the weight of the maps' Laplacian prior, raised
//! for fits with many training photos on maps finer than the pilot's, and for the pilot
//! itself when it has many training photos.
//!
//! The prior is `μ ‖Δ x‖²` on each map's texels `x` ([`crate::solve::light`]), with
//! `μ = s × max_t D_t`, `D_t` the texel-basis diagonal of the photo's data term
//! (`Σ α A_{o,t}²` over its observations `o`) and `s` this flag. A texel's transport
//! weight `A_{o,t}` grows with its solid angle, `Ω_t ∝ h²` for a texel side `h`, so
//! `D_t ∝ h⁴`; for a smooth light the graph Laplacian `Δx` shrinks as `h²` over `1/h²`
//! texels, so `‖Δx‖² ∝ h²`. The same `s` on a map of twice the side (the main fit's 32²
//! after the pilot's 16²) is a prior `2⁴ · 2² = 64` times weaker on the smooth part of the
//! light, relative to the photos; on a texel-sized sun `‖Δx‖²` grows by 16 and the prior is
//! unchanged.
//!
//! `auto` keeps `s` = [`SMOOTHNESS`] (1e-3), and multiplies it by
//! [`MANY_PHOTOS_FACTOR`] (16: the `h⁴` of the data diagonal alone) when the fit keeps a
//! shiny lobe, has two materials, [`SMOOTHNESS_FROM_PHOTOS`] training photos or more and a
//! global map of 32² (what was measured). Measured (`bench-results/smoothness-32.md`), the
//! ablation's `defaults` row at 32² / 16² maps (`run`'s size on the rendered Spot scenes),
//! 192² photos, 24 training photos, seeds 1–5: the glossy worst albedo ratio lower on 3 of
//! 5 (0.268 → 0.090 at seed 4, higher on 2). Through `run` on four 24-photo glossy Spots
//! the headline is lower on 4 of 4 (−1.0% to −5.1%, mostly the held-out light fit's own
//! weight), with the pilot's raised weight below the fit under the true training light
//! over its floor and the materials' median ratio on 4 of 4 (1.132 → 1.097, 0.132 →
//! 0.086), the held-out photos under their true light on 3 (−2.6% to −5.0%; +0.5%); with
//! the pilot at 1e-3 one of the four lost its GGX lobe and came out worse. With three
//! materials it is worse: in the ablation on 4 of 5 seeds (the held-out target lost on
//! 2), through `run` the held-out photos under their true light 5.0–7.0% higher on 3 of 5
//! seeds: so two materials only. Over the Lambertian lobe alone (where `run` fits the
//! light prior) the held-out photos under their true light rose 0.4–3.3% on 3 of 3. With
//! 6 training photos (the built-in example) 16× raised the headline 3.2–4.9% on 4 of 4
//! seeds (the held-out photos under their true light fell 3.4–8.0%), and 64× made the
//! headline of runs with 9 training photos 15–51% worse: so from 20 photos, at 16×.
//!
//! The pilot ([`pilot_smoothness_for`]) fits 16² maps with every lobe of `--basis` and
//! drops a lobe that carries less than 1% of every material's predicted radiance. From
//! [`SMOOTHNESS_FROM_PHOTOS`] training photos `auto` gives its maps 16× as well: with
//! many free maps at 1e-3 the maps carried part of the highlights, and on a glossy Spot the
//! true GGX 0.3 lobe got 0.64% and was dropped for Phong 50 (17% at 16×). Through `run` on
//! twelve 24-photo Spots this kept the true lobes on three runs (the held-out photos under
//! their true light 2.5–4.3% lower), changed the weights' prior on one diffuse run (+2.0%)
//! and left eight unchanged.

use super::values::{shiny_lobes, PriorStrength};
use crate::transport::brdf::BasisBrdf;

/// The Laplacian weight `s` of `run`'s maps when not raised (module docs).
pub const SMOOTHNESS: f64 = 1e-3;

/// Least training photos from which `--smoothness auto` raises the weight (module docs).
pub const SMOOTHNESS_FROM_PHOTOS: usize = 20;

/// The factor `--smoothness auto` puts on [`SMOOTHNESS`] with many photos on 32² maps.
pub const MANY_PHOTOS_FACTOR: f64 = 16.0;

/// The map side at which the raised weight was measured, and applies.
const RAISED_AT_SIDE: usize = 32;

/// The material count at which the raised weight was measured better, and applies: with
/// three it came out worse (module docs).
const RAISED_FOR_MATERIALS: usize = 2;

/// `s` raised: [`SMOOTHNESS`] × [`MANY_PHOTOS_FACTOR`].
const RAISED: f64 = SMOOTHNESS * MANY_PHOTOS_FACTOR;

/// `s` before the fit's size is known: the given value, else [`SMOOTHNESS`].
pub fn smoothness_base(opt: PriorStrength) -> f64 {
    opt.value_or(SMOOTHNESS)
}

/// `s` of the adaptive pilot (16² maps, every lobe of `--basis`) for `--smoothness` given
/// as `opt` with `photos` training photos, and with `auto` and the weight raised why: ×
/// [`MANY_PHOTOS_FACTOR`] from [`SMOOTHNESS_FROM_PHOTOS`] training photos (module docs).
pub fn pilot_smoothness_for(opt: PriorStrength, photos: usize) -> (f64, Option<String>) {
    if let PriorStrength::Fixed(v) = opt {
        return (v, None);
    }
    if photos < SMOOTHNESS_FROM_PHOTOS {
        return (SMOOTHNESS, None);
    }
    (
        RAISED,
        Some(format!(
            "the pilot's maps at Laplacian weight {RAISED:.1e} = {SMOOTHNESS:.0e} × {MANY_PHOTOS_FACTOR} (--smoothness auto: {photos} training photos, from {SMOOTHNESS_FROM_PHOTOS}): with many free maps a weaker prior lets the maps carry the highlights, and the pilot then drops the shiny lobe that makes them"
        )),
    )
}

/// `s` of `--smoothness` given as `opt` for a fit of `materials` materials over `basis`
/// from `photos` training photos on `global_side`² maps, and with `auto` why.
pub fn smoothness_for(
    opt: PriorStrength,
    photos: usize,
    materials: usize,
    global_side: usize,
    basis: &[BasisBrdf],
) -> (f64, Option<String>) {
    if let PriorStrength::Fixed(v) = opt {
        return (v, None);
    }
    let (shiny, lobes) = shiny_lobes(basis);
    let raised = shiny
        && photos >= SMOOTHNESS_FROM_PHOTOS
        && materials == RAISED_FOR_MATERIALS
        && global_side == RAISED_AT_SIDE;
    let fit =
        format!("{materials} material(s), {photos} training photos, {global_side}² maps, {lobes}");
    if raised {
        (
            RAISED,
            Some(format!(
                "the maps' Laplacian weight {RAISED:.1e} = {SMOOTHNESS:.0e} × {MANY_PHOTOS_FACTOR} (--smoothness auto: {fit}): relative to the photos, the same weight on a {RAISED_AT_SIDE}² map is a prior 16–64× weaker than on the pilot's 16², which left the free maps room to move brightness between the materials; --smoothness 1e-3 keeps the weight"
            )),
        )
    } else {
        (
            SMOOTHNESS,
            Some(format!(
                "the maps' Laplacian weight {SMOOTHNESS:.0e} (--smoothness auto: {fit}; raised ×{MANY_PHOTOS_FACTOR} with a shiny lobe, {RAISED_FOR_MATERIALS} materials and {SMOOTHNESS_FROM_PHOTOS} training photos or more on {RAISED_AT_SIDE}² maps)"
            )),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_raises_the_weight_with_a_shiny_lobe_two_materials_and_twenty_photos_on_32_maps_only() {
        let auto = PriorStrength::Auto;
        let shiny = [BasisBrdf::Lambert, BasisBrdf::Ggx { alpha: 0.3 }];
        let matte = [BasisBrdf::Lambert];
        assert_eq!(smoothness_for(auto, 24, 2, 32, &shiny).0, 1.6e-2);
        assert_eq!(smoothness_for(auto, 20, 2, 32, &shiny).0, 1.6e-2);
        assert_eq!(smoothness_for(auto, 24, 2, 32, &matte).0, 1e-3);
        assert_eq!(smoothness_for(auto, 19, 2, 32, &shiny).0, 1e-3);
        assert_eq!(smoothness_for(auto, 24, 2, 16, &shiny).0, 1e-3);
        assert_eq!(smoothness_for(auto, 24, 2, 64, &shiny).0, 1e-3);
        assert_eq!(smoothness_for(auto, 24, 3, 32, &shiny).0, 1e-3);
        assert_eq!(smoothness_for(auto, 24, 1, 32, &shiny).0, 1e-3);
        let why = smoothness_for(auto, 6, 2, 32, &shiny).1.unwrap();
        assert!(
            why.contains("2 material(s), 6 training photos, 32² maps"),
            "{why}"
        );
        let given = PriorStrength::Fixed(2e-3);
        assert_eq!(smoothness_for(given, 24, 3, 32, &shiny), (2e-3, None));
        assert_eq!(smoothness_base(given), 2e-3);
        assert_eq!(smoothness_base(auto), SMOOTHNESS);
    }

    #[test]
    fn auto_raises_the_pilots_weight_from_twenty_photos_only() {
        let auto = PriorStrength::Auto;
        assert_eq!(pilot_smoothness_for(auto, 19), (SMOOTHNESS, None));
        let (s, why) = pilot_smoothness_for(auto, 20);
        assert_eq!(s, 1.6e-2);
        assert!(why.unwrap().contains("20 training photos"));
        let given = PriorStrength::Fixed(2e-3);
        assert_eq!(pilot_smoothness_for(given, 24), (2e-3, None));
    }
}
