//! The values of `run`'s flags that are more than a number: `auto` or a value, or a choice
//! among named cases; each parse error is a plain [`Error::Config`] naming the flag.

use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result};

/// Whether `basis` keeps a lobe other than Lambert's, and the words a report's reason uses
/// for it (the `auto` rules that follow the fit's lobes).
pub(crate) fn shiny_lobes(basis: &[BasisBrdf]) -> (bool, &'static str) {
    if basis.iter().any(|b| !matches!(b, BasisBrdf::Lambert)) {
        (true, "a shiny lobe kept")
    } else {
        (false, "the Lambertian lobe alone")
    }
}

/// How many materials to fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MaterialCount {
    /// Choose from the data: with [`RunOptions::adaptive`](crate::run::RunOptions::adaptive), the smallest count within
    /// [`crate::solve::adapt::MATERIAL_TOL`] (one material:
    /// [`crate::solve::adapt::ONE_MATERIAL_TOL`]) of the best held-out error of a pilot fit
    /// ([`crate::solve::adapt`]); without it, the
    /// smallest count whose k-means clustering of the hue features leaves little
    /// unexplained (see [`choose_material_count`](crate::run::choose_material_count)).
    Auto,
    /// Exactly this many.
    Fixed(usize),
}

impl MaterialCount {
    /// The count when given (`--materials N`), `None` for `auto`.
    pub fn fixed(self) -> Option<usize> {
        match self {
            MaterialCount::Fixed(k) => Some(k),
            MaterialCount::Auto => None,
        }
    }
}

/// A flag's value that is `auto` (`None`) or a `T`; anything else is an error naming the
/// flag, the value and `what` a value must be.
fn parse_auto_or<T: std::str::FromStr>(s: &str, flag: &str, what: &str) -> Result<Option<T>> {
    if s == "auto" {
        return Ok(None);
    }
    s.parse()
        .map(Some)
        .map_err(|_| Error::Config(format!("{flag} {s}: expected auto or {what}")))
}

/// A prior's strength given as `auto` or a number: the blending weights' sum-to-one prior
/// ([`WeightsSum`]) and their neighbour prior ([`WeightsSmoothness`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PriorStrength {
    /// With [`RunOptions::adaptive`](crate::run::RunOptions::adaptive), the pilot's choice
    /// (each alias says how); without it, 0.
    Auto,
    /// This strength (0 = off, the paper's weights).
    Fixed(f64),
}

impl PriorStrength {
    /// `auto` or a number for `flag`, whose 0 means `zero` (checked by
    /// [`RunOptions::check`](crate::run::RunOptions::check)).
    pub fn parse(s: &str, flag: &str, zero: &str) -> Result<Self> {
        Ok(
            match parse_auto_or(s, flag, &format!("a number ≥ 0 (0 = {zero})"))? {
                None => PriorStrength::Auto,
                Some(v) => PriorStrength::Fixed(v),
            },
        )
    }

    /// The strength in effect before the pilot's choice, or without a pilot: `Auto` is 0.
    pub fn value(self) -> f64 {
        self.value_or(0.0)
    }

    /// The given strength, or `auto`'s value when the flag is `auto`.
    pub fn value_or(self, auto: f64) -> f64 {
        match self {
            PriorStrength::Auto => auto,
            PriorStrength::Fixed(v) => v,
        }
    }
}

/// The blending weights' sum-to-one prior
/// ([`EstimateOptions::weights_sum`](crate::solve::EstimateOptions::weights_sum); 0 = free
/// weights, as the paper). `Auto`: the pilot's choice between free weights and
/// [`crate::solve::adapt::PILOT_WEIGHTS_SUM`] by held-out error ([`crate::solve::adapt`],
/// step 3); without the pilot, free weights.
pub type WeightsSum = PriorStrength;

/// The neighbour prior on the blending weights
/// ([`EstimateOptions::weights_smoothness`](crate::solve::EstimateOptions::weights_smoothness);
/// 0 = off, the paper's independent weights). `Auto`: on at
/// [`crate::solve::adapt::NEIGHBOUR_PRIOR`] when the pilot keeps a shiny lobe, else off
/// ([`crate::solve::adapt::neighbour_prior_for`]); without the pilot, off.
pub type WeightsSmoothness = PriorStrength;

/// The rounds that take the ratio step ([`EstimateOptions::ratio_steps`](crate::solve::EstimateOptions::ratio_steps)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RatioSteps {
    /// [`crate::solve::ratio_step::default_rounds`] of the fit's training photos and
    /// materials: the step from [`crate::solve::ratio_step::MIN_PHOTOS`] photos on, up to
    /// [`crate::solve::ratio_step::MAX_MATERIALS`] materials.
    Auto,
    /// This many rounds (0 = off, the paper's alternation).
    Fixed(usize),
}

impl RatioSteps {
    /// `auto` or a whole number.
    pub fn parse(s: &str) -> Result<Self> {
        Ok(
            match parse_auto_or(s, "--ratio-steps", "a whole number of rounds (0 = off)")? {
                None => RatioSteps::Auto,
                Some(n) => RatioSteps::Fixed(n),
            },
        )
    }

    /// `auto` or `fixed`, as the report names the mode.
    pub fn mode(self) -> &'static str {
        match self {
            RatioSteps::Auto => "auto",
            RatioSteps::Fixed(_) => "fixed",
        }
    }

    /// The rounds for a fit of `materials` materials on `training_photos` photos.
    pub fn rounds(self, training_photos: usize, materials: usize) -> usize {
        match self {
            RatioSteps::Auto => {
                crate::solve::ratio_step::default_rounds(training_photos, materials)
            }
            RatioSteps::Fixed(n) => n,
        }
    }
}

/// The rounds that take the variable-projection step
/// ([`EstimateOptions::varpro_steps`](crate::solve::EstimateOptions::varpro_steps)) and
/// how its Jacobian is had.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VarproSteps {
    /// [`crate::solve::varpro_step::default_rounds`] of the fit's training photos,
    /// materials and basis, the Jacobian by Broyden's update after the first round.
    Auto,
    /// This many rounds (0 = off), the Jacobian by forward differences every round.
    Fixed(usize),
}

impl VarproSteps {
    /// `auto` or a whole number.
    pub fn parse(s: &str) -> Result<Self> {
        Ok(
            match parse_auto_or(s, "--varpro-steps", "a whole number of rounds (0 = off)")? {
                None => VarproSteps::Auto,
                Some(n) => VarproSteps::Fixed(n),
            },
        )
    }

    /// `auto` or `fixed`, as the report names the mode.
    pub fn mode(self) -> &'static str {
        match self {
            VarproSteps::Auto => "auto",
            VarproSteps::Fixed(_) => "fixed",
        }
    }

    /// What the step makes of a fit of `materials` materials over `basis` on
    /// `training_photos` photos ([`VarproPlan`]).
    pub fn plan(self, training_photos: usize, materials: usize, basis: &[BasisBrdf]) -> VarproPlan {
        if let VarproSteps::Fixed(rounds) = self {
            return VarproPlan {
                rounds,
                broyden: false,
                why: None,
            };
        }
        let (shiny, lobes) = shiny_lobes(basis);
        let rounds = crate::solve::varpro_step::default_rounds(training_photos, materials, !shiny);
        let fit = format!("{materials} material(s), {training_photos} training photos, {lobes}");
        let why = if rounds > 0 {
            format!("the first {rounds} rounds move every material's lobes by a Gauss-Newton step with the lights re-solved, its Jacobian by Broyden's update (--varpro-steps auto: {fit}); --varpro-steps 0 is the paper's alternation")
        } else if shiny {
            format!("no variable-projection step (--varpro-steps auto: {fit}; on the rendered glossy scene it left the worst albedo ratio worse on 5 of 5 seeds); --varpro-steps 8 takes it")
        } else {
            format!("no variable-projection step (--varpro-steps auto: {fit}; it takes two or more materials and the ratio step's bounds)")
        };
        VarproPlan {
            rounds,
            broyden: true,
            why: Some(why),
        }
    }
}

/// What `--varpro-steps` makes of one fit
/// ([`EstimateOptions::varpro_steps`](crate::solve::EstimateOptions::varpro_steps)).
#[derive(Debug, Clone, PartialEq)]
pub struct VarproPlan {
    /// The rounds that take the step (0 = none).
    pub rounds: usize,
    /// The Jacobian carried over by Broyden's update after the first round
    /// ([`crate::solve::varpro_step::broyden_update`]), else forward differences each round.
    pub broyden: bool,
    /// With `auto`, what it chose and why, for the report's reasons.
    pub why: Option<String>,
}

/// The second fit after the first (`--restart`; [`crate::solve::materials::reanchor`],
/// [`crate::solve::materials::irradiance`], [`crate::solve::materials::coarse_light`]);
/// any is kept only when it predicts the held-back observations better.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Restart {
    /// [`Restart::CoarseLight`] when the fit's basis is the Lambertian lobe alone, else
    /// none ([`Restart::resolve`], `auto`).
    #[default]
    Auto,
    /// None (the paper's single fit).
    Off,
    /// From the fit's own materials re-anchored (`on`).
    Reanchor,
    /// From the fit's weights normalised and each material's Lambertian ratios fitted by
    /// an order-2 irradiance model over its pure, open vertices (`irradiance`).
    Irradiance,
    /// From the fit's weights normalised and each material's Lambertian ratios fitted with
    /// each photo's light a coarse non-negative map seen through the Lambertian transport,
    /// over every seen observation with the fit's blend of the materials
    /// ([`crate::solve::materials::coarse_light_blend`]), the lights fitted again with
    /// those materials held,
    /// over the fit's weights and over them re-sorted (`coarse-light`,
    /// [`crate::solve::materials::coarse_light`]). Over a basis with shiny lobes, each tied
    /// to its material's diffuse lobe by the fit's ratio, one held fit over the fit's
    /// weights re-sorted on the model's materials
    /// ([`crate::solve::materials::coarse_light_shiny`]).
    CoarseLight,
    /// [`Restart::Reanchor`], then [`Restart::CoarseLight`] from the fit kept
    /// (`on+coarse-light`): the re-anchored fit sorts the vertices the first fit's
    /// clustered start left in the wrong material, and the coarse-light model reads its
    /// ratios over those weights ([`Restart::steps`]).
    ReanchorCoarseLight,
}

impl Restart {
    /// `auto`, `off`, `on`, `irradiance`, `coarse-light` or `on+coarse-light`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(Restart::Auto),
            "off" => Ok(Restart::Off),
            "on" => Ok(Restart::Reanchor),
            "irradiance" => Ok(Restart::Irradiance),
            "coarse-light" => Ok(Restart::CoarseLight),
            "on+coarse-light" => Ok(Restart::ReanchorCoarseLight),
            _ => Err(Error::Config(format!(
                "--restart {s}: expected auto, off, on, irradiance, coarse-light or on+coarse-light"
            ))),
        }
    }

    /// The restart a fit over `basis` makes: `Auto` is [`Restart::CoarseLight`] when the
    /// basis holds the Lambertian lobe alone and [`Restart::Off`] otherwise. Over a shiny
    /// basis the restart ties each shiny lobe to its material's diffuse one; through `run`
    /// at 192² it was made on 7 of 8 rendered runs (one skipped), the validation score kept
    /// it on all 7 and the error under the true light rose on all 7 (0.4–2.6%; `bench-results/coarse-light-start.md` section
    /// 15). Not
    /// [`Restart::ReanchorCoarseLight`]: on the real Buddha photos its re-anchored fit is
    /// kept by validation margins of 0.4% and 1.4% and raises the headline held-out error
    /// by 0.6% and 1.3% (seeds 1–2, section 11 of that file). Any other mode is itself.
    pub fn resolve(self, basis: &[BasisBrdf]) -> Restart {
        match self {
            Restart::Auto if matches!(basis, [BasisBrdf::Lambert]) => Restart::CoarseLight,
            Restart::Auto => Restart::Off,
            mode => mode,
        }
    }

    /// The second fits a resolved mode makes, in order, each from the fit kept before it:
    /// none for `Off` (and the unresolved `Auto`), two for `ReanchorCoarseLight`, else
    /// the mode itself.
    pub fn steps(self) -> &'static [Restart] {
        match self {
            Restart::Auto | Restart::Off => &[],
            Restart::Reanchor => &[Restart::Reanchor],
            Restart::Irradiance => &[Restart::Irradiance],
            Restart::CoarseLight => &[Restart::CoarseLight],
            Restart::ReanchorCoarseLight => &[Restart::Reanchor, Restart::CoarseLight],
        }
    }
}

/// Which photos are held out.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Holdout {
    /// The workspace's `truth/manifest.json` list when present, else every 5th registered
    /// photo, at least one ([`default_holdout`](crate::run::default_holdout)).
    #[default]
    Default,
    /// No photo.
    None,
    /// These image names.
    Names(Vec<String>),
    /// Every N-th registered photo (by name order), starting with the N-th.
    Every(usize),
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--ratio-steps`: `auto` follows the photo threshold and the material bound, a number
    /// is taken as given (0 included), anything else is refused in words that name the flag
    /// and the value.
    #[test]
    fn ratio_steps_parse_auto_or_a_count_and_auto_follows_the_photo_and_material_bounds() {
        use crate::solve::ratio_step::{DEFAULT_ROUNDS, MAX_MATERIALS, MIN_PHOTOS};
        let auto = RatioSteps::parse("auto").unwrap();
        assert_eq!(auto, RatioSteps::Auto);
        assert_eq!(auto.rounds(MIN_PHOTOS - 1, 2), 0);
        assert_eq!(auto.rounds(MIN_PHOTOS, 2), DEFAULT_ROUNDS);
        assert_eq!(auto.rounds(MIN_PHOTOS, MAX_MATERIALS + 1), 0);
        assert_eq!(RatioSteps::parse("0").unwrap().rounds(100, 2), 0);
        assert_eq!(RatioSteps::parse("3").unwrap().rounds(1, 6), 3);
        for bad in ["eight", "-1", "2.5", ""] {
            let err = RatioSteps::parse(bad).unwrap_err().to_string();
            assert!(err.contains(&format!("--ratio-steps {bad}")), "{err}");
            assert!(err.contains("expected auto or a whole number"), "{err}");
        }
    }

    /// `--varpro-steps`: `auto` takes Broyden's Jacobian and 8 rounds only for two or more
    /// materials over the Lambertian lobe alone where the ratio step runs; a count takes
    /// forward differences; anything else refused in words that name the flag and value.
    #[test]
    fn varpro_steps_auto_follows_the_basis_materials_and_photos() {
        use crate::solve::ratio_step::{MAX_MATERIALS, MIN_PHOTOS};
        use crate::solve::varpro_step::DEFAULT_ROUNDS;
        let matte = [BasisBrdf::Lambert];
        let shiny = [BasisBrdf::Lambert, BasisBrdf::Ggx { alpha: 0.3 }];
        let auto = VarproSteps::parse("auto").unwrap();
        let on = auto.plan(MIN_PHOTOS, 2, &matte);
        assert_eq!((on.rounds, on.broyden), (DEFAULT_ROUNDS, true));
        assert!(on.why.unwrap().contains("Broyden"));
        let shiny_fit = auto.plan(MIN_PHOTOS, 2, &shiny);
        assert_eq!(shiny_fit.rounds, 0);
        assert!(shiny_fit.why.unwrap().contains("a shiny lobe kept"));
        assert_eq!(auto.plan(MIN_PHOTOS, 1, &matte).rounds, 0);
        assert_eq!(auto.plan(MIN_PHOTOS - 1, 2, &matte).rounds, 0);
        assert_eq!(auto.plan(MIN_PHOTOS, MAX_MATERIALS + 1, &matte).rounds, 0);
        let fixed = VarproSteps::parse("3").unwrap().plan(1, 6, &shiny);
        assert_eq!(
            fixed,
            VarproPlan {
                rounds: 3,
                broyden: false,
                why: None
            }
        );
        for bad in ["eight", "-1", ""] {
            let err = VarproSteps::parse(bad).unwrap_err().to_string();
            assert!(err.contains(&format!("--varpro-steps {bad}")), "{err}");
            assert!(err.contains("expected auto or a whole number"), "{err}");
        }
    }

    /// `--restart`: the six names, and anything else refused in words that name the flag
    /// and the value.
    #[test]
    fn restart_parses_its_six_names_and_refuses_others() {
        assert_eq!(Restart::parse("auto").unwrap(), Restart::Auto);
        assert_eq!(Restart::parse("off").unwrap(), Restart::Off);
        assert_eq!(Restart::parse("on").unwrap(), Restart::Reanchor);
        assert_eq!(Restart::parse("irradiance").unwrap(), Restart::Irradiance);
        assert_eq!(
            Restart::parse("coarse-light").unwrap(),
            Restart::CoarseLight
        );
        assert_eq!(
            Restart::parse("on+coarse-light").unwrap(),
            Restart::ReanchorCoarseLight
        );
        assert_eq!(Restart::default(), Restart::Auto);
        for bad in ["yes", "Irradiance", "coarse-light+on", ""] {
            let err = Restart::parse(bad).unwrap_err().to_string();
            assert!(err.contains(&format!("--restart {bad}:")), "{err}");
            assert!(
                err.contains("expected auto, off, on, irradiance, coarse-light or on+coarse-light"),
                "{err}"
            );
        }
    }

    /// `--restart auto` is the coarse-light restart over the Lambertian lobe alone and none
    /// over any basis with a shiny lobe; every other mode is itself whatever the basis;
    /// each resolved mode's steps are the fits it names, in order.
    #[test]
    fn auto_restart_is_coarse_light_only_over_the_lambertian_lobe_alone() {
        let lambert = [BasisBrdf::Lambert];
        let shiny = [BasisBrdf::Lambert, BasisBrdf::Phong { exponent: 50.0 }];
        assert_eq!(Restart::Auto.resolve(&lambert), Restart::CoarseLight);
        assert_eq!(Restart::Auto.resolve(&shiny), Restart::Off);
        assert_eq!(Restart::Auto.resolve(&shiny[1..]), Restart::Off);
        let all = [
            Restart::Off,
            Restart::Reanchor,
            Restart::Irradiance,
            Restart::CoarseLight,
            Restart::ReanchorCoarseLight,
        ];
        for mode in all {
            assert_eq!(mode.resolve(&lambert), mode);
            assert_eq!(mode.resolve(&shiny), mode);
        }
        assert!(Restart::Off.steps().is_empty());
        assert_eq!(
            Restart::ReanchorCoarseLight.steps(),
            [Restart::Reanchor, Restart::CoarseLight]
        );
        for single in [Restart::Reanchor, Restart::Irradiance, Restart::CoarseLight] {
            assert_eq!(single.steps(), [single]);
        }
    }
}
