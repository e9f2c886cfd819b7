//! Which per-photo light model a fit uses (issue 25, `--light`): the paper's free map,
//! the free map under the statistical prior of [`crate::solve::light::sh_prior`], one map
//! per group of photos under one sky with per-photo gains
//! ([`crate::solve::light::shared`]), the sun and sky of [`crate::solve::light::sky`], or
//! `auto`, which fits each that applies (`shared`
//! only when some group holds two photos or more) and keeps the one with the lowest
//! validation score (the same seeded held-back data for all, [`crate::solve::Validation`]),
//! as `--adaptive` chooses the model order by held-out error. `run` holds back the right
//! halves of a few training photos for that score and fits the model kept again with its
//! own early stopping (docs/method.md, "Choosing the light model"). `constrained` chooses
//! the same way among the models that constrain the map, all but the paper's free map:
//! with many photos the free maps can move brightness between the materials, which the
//! validation score does not see ([`crate::run::scene_light`]).

use crate::solve::light::sh_prior::LightPriorOptions;
use crate::solve::EstimateOptions;
use crate::{Error, Result};

/// Relative noise level of the SH shape term under `--light prior` (`σ = η · rms(y)`).
/// Measured on `spot-varying` (`bench-results/estimator-light.md`): noise-free, held-out
/// error against the true model 0.160 (paper) → 0.156 (0.1) → 0.113 (0.3) → 0.169 (1);
/// on 8-bit photos 0.147 (paper) against 0.147 (0.3): no gain there.
pub const PRIOR_SH_NOISE: f64 = 0.3;
/// Relative noise level of the Haar L1 term under `--light prior`: with the SH term at 0.3,
/// 0.03 gave 0.111 noise-free (0.113 without) and 0.148 on 8-bit photos; alone 0.03 gave
/// 0.120 / 0.143, 0.1 gave 0.128 noise-free and 0.3 raised the 8-bit figure to 0.182.
pub const PRIOR_HAAR_NOISE: f64 = 0.03;

/// The `--light` choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightChoice {
    /// The paper's free non-negative wavelet map per photo (Laplacian smoothness only).
    Paper,
    /// The free map plus the prior on its low-order shape and wavelet sparsity.
    Prior,
    /// One free map per group of photos, per-photo exposure and white-balance gains.
    Shared,
    /// A parametric sun and sky plus a penalised wavelet residual per photo.
    Sky,
    /// Every model that applies fitted; the lowest validation score kept.
    Auto,
    /// As `Auto` without the paper's free map: the prior, the sun and sky, and the shared
    /// map when some group holds two photos or more.
    Constrained,
}

impl LightChoice {
    /// Parse `paper`, `prior`, `shared`, `sky`, `auto` or `constrained`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "paper" => Ok(LightChoice::Paper),
            "prior" => Ok(LightChoice::Prior),
            "shared" => Ok(LightChoice::Shared),
            "sky" => Ok(LightChoice::Sky),
            "auto" => Ok(LightChoice::Auto),
            "constrained" => Ok(LightChoice::Constrained),
            other => Err(Error::Config(format!(
                "--light {other}: expected `paper`, `prior`, `shared`, `sky`, `auto` or `constrained`"
            ))),
        }
    }

    /// The name `parse` reads.
    pub fn name(self) -> &'static str {
        match self {
            LightChoice::Paper => "paper",
            LightChoice::Prior => "prior",
            LightChoice::Shared => "shared",
            LightChoice::Sky => "sky",
            LightChoice::Auto => "auto",
            LightChoice::Constrained => "constrained",
        }
    }

    /// Whether the choice fits several models and keeps one by validation (`auto`,
    /// `constrained`).
    pub fn chooses(self) -> bool {
        matches!(self, LightChoice::Auto | LightChoice::Constrained)
    }
}

/// One light model to fit: its name and the estimator's options for it.
#[derive(Debug, Clone)]
pub struct LightCandidate {
    /// `paper`, `prior`, `shared` or `sky`.
    pub name: &'static str,
    /// `base` with the model's light terms.
    pub options: EstimateOptions,
}

/// The models `choice` fits, from the estimator options `base` (whose `light_prior` and
/// `light_sky` are replaced; its `light_groups`, the photo groups when known, are kept by
/// `shared` alone).
pub fn candidates(choice: LightChoice, base: &EstimateOptions) -> Result<Vec<LightCandidate>> {
    let paper = || LightCandidate {
        name: "paper",
        options: EstimateOptions {
            light_prior: None,
            light_sky: None,
            light_groups: None,
            ..base.clone()
        },
    };
    let shared = || -> Result<LightCandidate> {
        let Some(groups) = &base.light_groups else {
            return Err(Error::Config(
                "--light shared: no photo groups; give --light-groups FILE, or photos whose EXIF capture times lie within --light-group-minutes of each other".into(),
            ));
        };
        Ok(LightCandidate {
            name: "shared",
            options: EstimateOptions {
                light_prior: None,
                light_groups: Some(groups.clone()),
                light_sky: None,
                ..base.clone()
            },
        })
    };
    let any_shared = base.light_groups.as_ref().is_some_and(|g| g.any_shared());
    let prior = || -> Result<LightCandidate> {
        Ok(LightCandidate {
            name: "prior",
            options: EstimateOptions {
                light_prior: Some(LightPriorOptions::builtin(
                    PRIOR_SH_NOISE,
                    PRIOR_HAAR_NOISE,
                )?),
                light_sky: None,
                light_groups: None,
                ..base.clone()
            },
        })
    };
    let sky = || LightCandidate {
        name: "sky",
        options: EstimateOptions {
            light_prior: None,
            light_groups: None,
            light_sky: Some(crate::solve::light::sky::SkyOptions::default()),
            ..base.clone()
        },
    };
    Ok(match choice {
        LightChoice::Paper => vec![paper()],
        LightChoice::Prior => vec![prior()?],
        LightChoice::Shared => vec![shared()?],
        LightChoice::Sky => vec![sky()],
        // `auto` and `constrained` fit the same list, `constrained` without the paper's map.
        LightChoice::Auto | LightChoice::Constrained => {
            let mut models = Vec::with_capacity(4);
            if choice == LightChoice::Auto {
                models.push(paper());
            }
            models.push(prior()?);
            if any_shared {
                models.push(shared()?);
            }
            models.push(sky());
            models
        }
    })
}

/// What was chosen and why (the report's words).
#[derive(Debug, Clone, serde::Serialize, Default, PartialEq)]
pub struct LightDecision {
    /// The model used.
    pub model: String,
    /// One sentence: the flag's model (the default or as given), or the validation scores
    /// compared.
    pub why: String,
    /// `(model, validation score)` per model fitted (score NaN without validation).
    pub scores: Vec<(String, f64)>,
}

/// Index of the candidate to keep from their validation scores (lower is better; the
/// first on ties or when no score is finite) and the decision's words.
pub fn decide(choice: LightChoice, names: &[&str], scores: &[f64]) -> (usize, LightDecision) {
    let mut best = 0;
    for (i, s) in scores.iter().enumerate() {
        if s.is_finite() && (scores[best].is_nan() || *s < scores[best]) {
            best = i;
        }
    }
    let list = names
        .iter()
        .zip(scores)
        .map(|(n, s)| format!("{n} {s:.5}"))
        .collect::<Vec<_>>()
        .join(", ");
    let why = match choice {
        c if c.chooses() && names.len() > 1 => format!(
            "--light {}: the lower validation score (relative RMSE of the held-back observations) of {list}{}",
            c.name(),
            if c == LightChoice::Constrained { " (the paper's free map not a candidate)" } else { "" }
        ),
        c if c.chooses() => format!("--light {}: {} is the only model fitted", c.name(), names[best]),
        LightChoice::Paper => "--light paper: the paper's \
            free map per photo (--light auto fits every model that applies and keeps the one \
            that predicts held-back data best)"
            .to_string(),
        c => format!("--light {}, as given", c.name()),
    };
    (
        best,
        LightDecision {
            model: names[best].to_string(),
            why,
            scores: names
                .iter()
                .zip(scores)
                .map(|(n, s)| (n.to_string(), *s))
                .collect(),
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_keeps_the_lower_finite_score() {
        let (i, d) = decide(LightChoice::Auto, &["paper", "prior"], &[0.12, 0.10]);
        assert_eq!((i, d.model.as_str()), (1, "prior"));
        assert!(d.why.contains("paper 0.12000"), "{}", d.why);
        let (i, _) = decide(LightChoice::Auto, &["paper", "prior"], &[0.10, 0.10]);
        assert_eq!(i, 0, "ties keep the paper's model");
        let (i, _) = decide(LightChoice::Auto, &["paper", "prior"], &[f64::NAN, 0.2]);
        assert_eq!(i, 1, "a NaN score never wins");
        let (i, d) = decide(LightChoice::Prior, &["prior"], &[f64::NAN]);
        assert_eq!((i, d.why.as_str()), (0, "--light prior, as given"));
        let (i, d) = decide(LightChoice::Constrained, &["prior", "sky"], &[0.2, 0.1]);
        assert_eq!(i, 1);
        assert!(
            d.why.starts_with("--light constrained: ") && d.why.contains("not a candidate"),
            "{}",
            d.why
        );
        let (_, d) = decide(LightChoice::Paper, &["paper"], &[f64::NAN]);
        assert!(d.why.starts_with("--light paper: "), "{}", d.why);
    }

    #[test]
    fn parse_reads_the_names_and_rejects_others() {
        for c in [
            LightChoice::Paper,
            LightChoice::Prior,
            LightChoice::Shared,
            LightChoice::Sky,
            LightChoice::Auto,
            LightChoice::Constrained,
        ] {
            assert_eq!(LightChoice::parse(c.name()).unwrap(), c);
        }
        let e = LightChoice::parse("skies").unwrap_err().to_string();
        assert!(e.contains("--light skies"), "{e}");
    }

    #[test]
    fn shared_needs_groups_and_alone_keeps_them() {
        use crate::solve::light::shared::LightGroups;
        let base = EstimateOptions::default();
        let e = candidates(LightChoice::Shared, &base)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--light-groups"), "{e}");
        let names = |v: &[LightCandidate]| v.iter().map(|c| c.name).collect::<Vec<_>>();
        assert_eq!(
            names(&candidates(LightChoice::Auto, &base).unwrap()),
            ["paper", "prior", "sky"]
        );
        // Groups of one photo each: `auto` does not fit `shared` (it would be `paper`).
        let single = EstimateOptions {
            light_groups: Some(LightGroups::from_labels(&[0, 1, 2], String::new())),
            ..base.clone()
        };
        assert_eq!(
            names(&candidates(LightChoice::Auto, &single).unwrap()).len(),
            3
        );
        assert_eq!(
            names(&candidates(LightChoice::Constrained, &single).unwrap()),
            ["prior", "sky"]
        );
        let grouped = EstimateOptions {
            light_groups: Some(LightGroups::from_labels(&[0, 0, 1], String::new())),
            ..base
        };
        assert_eq!(
            names(&candidates(LightChoice::Constrained, &grouped).unwrap()),
            ["prior", "shared", "sky"]
        );
        let c = candidates(LightChoice::Auto, &grouped).unwrap();
        assert_eq!(names(&c), ["paper", "prior", "shared", "sky"]);
        for m in &c {
            assert_eq!(m.options.light_groups.is_some(), m.name == "shared");
            assert_eq!(m.options.light_sky.is_some(), m.name == "sky");
        }
    }
}
