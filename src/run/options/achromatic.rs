//! `run --achromatic-specular auto|on|off`: whether each material's specular lobes take
//! the light's colour (one weight per material shared by R, G and B, the colour in the
//! diffuse lobe: Shafer's dichromatic model of dielectrics, docs/method.md "Achromatic
//! specular lobes"). `auto` (the default) ties them in the full fit when it keeps a shiny
//! lobe and has [`ACHROMATIC_FROM_MATERIALS`] or more materials; the adaptive pilot fits
//! free colours, so the count and the lobes it chooses do not depend on the rule. `on`
//! ties them in the pilot too; `off` frees them (coloured metals).
//!
//! Measured (`bench-results/achromatic-default.md`), the ablation's `defaults` row at
//! `run`'s 32² / 16² maps, 8-bit 192² photos, 24 training photos, seeds 1–5. Three
//! materials: the worst diffuse albedo ratio lower on 4 of 5 seeds (mean 0.127 → 0.086;
//! free colours put the blue of the orange GGX material, whose diffuse weight 0.2 is below
//! its specular 0.25, into its specular lobe), material accuracy ≥ 0.98 on 4 seeds instead
//! of 3, held-out and relit within ±2%. Two glossy materials: the worst ratio lower on 2 of
//! 5 and higher on 3, in the ablation and through `run` alike, held-out −1% to +5.5%; on
//! `spot-ggx` (an orange GGX and a blue Lambertian material, 24 training photos at 128², through
//! `run`) higher on 3 of 3 seeds. Coloured metals need free colours too, so the rule starts
//! at three materials. The built-in example (two materials) and the real Buddha photos (the
//! Lambertian lobe alone) are unchanged.

use super::values::shiny_lobes;
use crate::error::{Error, Result};
use crate::transport::brdf::BasisBrdf;

/// Least materials from which `--achromatic-specular auto` ties the specular colours
/// (module docs).
pub const ACHROMATIC_FROM_MATERIALS: usize = 3;

/// `--achromatic-specular`: the specular lobes' colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Achromatic {
    /// Tied in the full fit with a shiny lobe and [`ACHROMATIC_FROM_MATERIALS`] materials.
    Auto,
    /// Tied in the pilot and the fit.
    On,
    /// Free per channel (the paper's).
    Off,
}

impl Achromatic {
    /// `auto`, `on` or `off`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(Achromatic::Auto),
            "on" => Ok(Achromatic::On),
            "off" => Ok(Achromatic::Off),
            other => Err(Error::Config(format!(
                "--achromatic-specular {other}: expected auto, on or off"
            ))),
        }
    }
}

/// Whether the full fit of `materials` materials over `basis` ties the specular colours
/// under `flag`, and with `auto` and a shiny lobe why.
pub fn achromatic_for(
    flag: Achromatic,
    materials: usize,
    basis: &[BasisBrdf],
) -> (bool, Option<String>) {
    let (shiny, lobes) = shiny_lobes(basis);
    match flag {
        Achromatic::On => (true, None),
        Achromatic::Off => (false, None),
        Achromatic::Auto if !shiny => (false, None),
        Achromatic::Auto => {
            let on = materials >= ACHROMATIC_FROM_MATERIALS;
            let fit = format!("{materials} material(s), {lobes}");
            let why = if on {
                format!("specular lobes achromatic, the colour in the diffuse lobe as for dielectrics (--achromatic-specular auto: {fit}); --achromatic-specular off for coloured metals")
            } else {
                format!("specular lobes coloured per channel (--achromatic-specular auto: {fit}; ties them from {ACHROMATIC_FROM_MATERIALS} materials, --achromatic-specular on forces it)")
            };
            (on, Some(why))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_ties_a_shiny_fit_from_three_materials() {
        let shiny = [BasisBrdf::Lambert, BasisBrdf::Ggx { alpha: 0.3 }];
        let matte = [BasisBrdf::Lambert];
        let auto = Achromatic::Auto;
        assert!(achromatic_for(auto, 3, &shiny).0);
        assert!(!achromatic_for(auto, 2, &shiny).0);
        assert_eq!(achromatic_for(auto, 4, &matte), (false, None));
        let why = achromatic_for(auto, 3, &shiny).1.unwrap();
        assert!(why.contains("3 material(s)"), "{why}");
        assert_eq!(achromatic_for(Achromatic::On, 1, &matte), (true, None));
        assert_eq!(achromatic_for(Achromatic::Off, 5, &shiny), (false, None));
        assert!(Achromatic::parse("sometimes").is_err());
        assert_eq!(Achromatic::parse("on").unwrap(), Achromatic::On);
    }
}
