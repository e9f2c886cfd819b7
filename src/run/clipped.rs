//! `--clipped`: what the fit does with the overexposed observations' clipped channels
//! (docs/method.md, "Clipped channels as lower bounds"). `auto` reads them as lower bounds
//! when at least [`CLIPPED_AUTO_SHARE`] of the training observations have one, else leaves
//! them out as the paper does: at the few percent a normal exposure clips, the two readings
//! differ within the runs' spread; where much is blown out, the bounds choose the right
//! material count and hold the albedo ratios (`bench-results/clipped-bounds.md`).

use crate::observe::Observations;
use crate::run::options::{Clipped, RunOptions, CLIPPED_AUTO_SHARE};
use crate::run::state::RunLog;

/// The observations of `obs` a fit can read as bounds (bound weight > 0), and their share.
fn bound_share(obs: &Observations) -> (usize, f64) {
    let bounds = obs.bound_weight.iter().filter(|&&b| b > 0.0).count();
    (bounds, bounds as f64 / obs.len().max(1) as f64)
}

/// Whether `--clipped auto` reads the bounds of the training observations `obs`: at least
/// [`CLIPPED_AUTO_SHARE`] of them have one.
pub fn auto_reads_bounds(obs: &Observations) -> bool {
    bound_share(obs).1 >= CLIPPED_AUTO_SHARE
}

/// The options with `--clipped auto` resolved for `obs` (`None` when nothing to resolve);
/// the report's note says how many observations have a clipped channel and what the fit
/// does with them.
pub(super) fn resolve(
    opts: &RunOptions,
    obs: &Observations,
    log: &mut RunLog,
) -> Option<RunOptions> {
    let (bounds, share) = bound_share(obs);
    let rule = match opts.clipped {
        Clipped::Auto if auto_reads_bounds(obs) => Clipped::Bound,
        Clipped::Auto => Clipped::Drop,
        given => given,
    };
    let why = match (opts.clipped, rule) {
        (Clipped::Auto, _) => format!(
            " (--clipped auto: {:.1}% of the observations, {} {:.0}%)",
            100.0 * share,
            if rule == Clipped::Bound {
                "at least"
            } else {
                "under"
            },
            100.0 * CLIPPED_AUTO_SHARE
        ),
        _ => String::new(),
    };
    let what = match rule {
        Clipped::Bound => "their clipped channels read as lower bounds, their other channels as values, at vertices an un-clipped observation also reads",
        _ => "left out",
    };
    log.notes.push(format!(
        "overexposed observations with a clipped channel: {bounds} of {}; {what}{why}",
        obs.len()
    ));
    (rule != opts.clipped).then(|| RunOptions {
        clipped: rule,
        ..opts.clone()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::state::RunLog;
    use crate::stages::Stages;

    fn obs_with_bounds(bounds: usize, n: usize) -> Observations {
        Observations {
            bound_weight: (0..n).map(|p| if p < bounds { 1.0 } else { 0.0 }).collect(),
            clipped: (0..n).map(|p| u8::from(p < bounds)).collect(),
            vertex: vec![0; n],
            ..Observations::default()
        }
    }

    /// `auto` turns to `bound` at the share and not below it; a given rule stays; the note
    /// names the count and the rule.
    #[test]
    fn auto_reads_bounds_from_the_share_on() {
        let opts = RunOptions::new("ws".into(), "out".into());
        assert_eq!(opts.clipped, Clipped::Auto, "the default");
        let mut log = RunLog {
            stages: Stages::new(),
            notes: Vec::new(),
        };
        let at = resolve(&opts, &obs_with_bounds(20, 100), &mut log).unwrap();
        assert_eq!(at.clipped, Clipped::Bound);
        assert!(
            log.notes[0].contains("20 of 100; their clipped channels"),
            "{}",
            log.notes[0]
        );
        let below = resolve(&opts, &obs_with_bounds(19, 100), &mut log).unwrap();
        assert_eq!(below.clipped, Clipped::Drop);
        assert!(
            log.notes[1].contains("left out (--clipped auto: 19.0%"),
            "{}",
            log.notes[1]
        );
        let given = RunOptions {
            clipped: Clipped::Drop,
            ..opts
        };
        assert!(resolve(&given, &obs_with_bounds(90, 100), &mut log).is_none());
        assert!(log.notes[2].ends_with("left out"), "{}", log.notes[2]);
    }
}
