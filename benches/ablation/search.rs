//! Fits beyond the row's one (`ABLATION_RESTARTS`, `ABLATION_SEARCH`): restarts from
//! re-anchored materials and the search over the start's brightness per material, each
//! kept by the early-stopping validation score.

use super::*;
use relight_cpc::solve::materials::brightness::{brightness_starts, scale_lambert};
use relight_cpc::solve::materials::reanchor::{reanchor, Reweight};
use relight_cpc::solve::validation::{
    half_score, left_by_view, material_holdout_score, training_score,
};

/// `ABLATION_RESTARTS=N`: up to N restarts of the alternation from the last kept fit's
/// re-anchored materials ([`reanchor`], weights by `ABLATION_REWEIGHT=project|label`),
/// each a row; a restart is kept while its validation score improves. Returns the kept fit.
pub fn restarts(
    case: &Case,
    fl: &Floors,
    o: &EstimateOptions,
    mut est: Estimate,
    label: &str,
    done: &mut Vec<Done>,
) -> Estimate {
    let n = env_or("ABLATION_RESTARTS", 0);
    let how = match std::env::var("ABLATION_REWEIGHT").as_deref() {
        Ok("label") => Reweight::Label,
        _ => Reweight::Project,
    };
    let problem = case.train.problem(case.nv);
    let score = |e: &Estimate| e.validation.as_ref().map_or(f64::NAN, |v| v.best_error());
    for i in 1..=n {
        let init = reanchor(&est.lambda, &est.weights, &fl.seen, how).expect("re-anchoring");
        let t0 = Instant::now();
        let next = estimate(&problem, init, o, &mut |_, _| {}).unwrap();
        let seconds = t0.elapsed().as_secs_f64();
        let f = figures(case, fl, (&next, o), start_ratio_errors(case, fl), seconds);
        let row = format!("{label}, re-anchored ({how:?}) ×{i}");
        eprintln!("  {row}: {f:?}");
        let better = score(&next) < score(&est);
        done.push(Done {
            diagnosis: diagnosed(case, &next, &row),
            label: row,
            figures: f,
            k: None,
            note: format!("validation {:.5} against {:.5}", score(&next), score(&est)),
        });
        if !better {
            break;
        }
        est = next;
    }
    est
}

/// `ABLATION_SEARCH=1`: the fit from every start of [`brightness_starts`] around the
/// k-means start (material `k ≥ 1`'s Lambertian weight scaled by `c_k s^{e_k}`), each a
/// row; `s = 2` around `c = 1` in the first round, then `ABLATION_SEARCH_ROUNDS` − 1 more
/// rounds with `s` square-rooted around the kept `c`. Returns the fit with the lowest
/// score (the base fit `est` among them): `ABLATION_SEARCH_SCORE=validation` (default) the
/// early-stopping validation score, `half` protocol (b) on the training photos
/// ([`half_score`]), `material` leave one k-means group out ([`material_holdout_score`]),
/// `training` the data term on every training observation ([`training_score`]); every
/// row's note carries all four.
pub fn brightness_search(
    case: &Case,
    fl: &Floors,
    o: &EstimateOptions,
    est: Estimate,
    label: &str,
    done: &mut Vec<Done>,
) -> Estimate {
    if !env_flag("ABLATION_SEARCH") {
        return est;
    }
    let by = std::env::var("ABLATION_SEARCH_SCORE").unwrap_or_default();
    let init = start(case, &case.train.obs, case.lambda.len()).expect("k-means start");
    let k = init.lambda.len();
    let group = argmax_groups(&init.weights, k);
    let score = |e: &Estimate| {
        let (v, h, m, t) = (
            validation_of(e),
            train_half_score(case, o, e),
            train_material_score(case, o, e, &group),
            training_of(case, e),
        );
        let s = match by.as_str() {
            "half" => h,
            "material" => m,
            "training" => t,
            _ => v,
        };
        (
            s,
            format!("validation {v:.5}, half {h:.5}, material {m:.5}, training {t:.5}"),
        )
    };
    let s0 = score(&est);
    eprintln!("  base: {}", s0.1);
    if let Some(last) = done.last_mut() {
        last.note = s0.1.clone();
    }
    let search = Search {
        case,
        fl,
        o,
        label,
        score: &score,
    };
    let mut kept = Kept {
        est,
        factors: vec![1.0; k - 1],
        score: s0.0,
    };
    let mut step: f64 = 2.0;
    for _ in 0..env_or("ABLATION_SEARCH_ROUNDS", 1) {
        let centre = kept.factors.clone();
        for st in brightness_starts(&init, 0, &centre, step) {
            let next = search.fit(st.materials, &format!("{:.3?}", st.factors), done);
            search.offer(&mut kept, next, st.factors, done);
        }
        eprintln!("  search kept {:?}, score {:.5}", kept.factors, kept.score);
        step = step.sqrt();
    }
    if env_flag("ABLATION_SEARCH_CHANNELS") {
        channel_round(&search, &init, &mut kept, done);
    }
    kept.est
}

/// The search's best fit so far: the estimate, its start's brightness factors (material
/// `j ≥ 1`'s Lambertian weight scaled by `factors[j − 1]`) and its score.
struct Kept {
    est: Estimate,
    factors: Vec<f64>,
    score: f64,
}

/// What every fit of [`brightness_search`] shares: the case, its floors, the options, the
/// row's label and the score that picks the kept fit.
struct Search<'a> {
    case: &'a Case,
    fl: &'a Floors,
    o: &'a EstimateOptions,
    label: &'a str,
    score: &'a dyn Fn(&Estimate) -> (f64, String),
}

impl Search<'_> {
    /// One fit from start `m`, pushed as the row `{label}, start brightness ×{what}`.
    fn fit(&self, m: Materials0, what: &str, done: &mut Vec<Done>) -> Estimate {
        let (case, fl) = (self.case, self.fl);
        let problem = case.train.problem(case.nv);
        let t0 = Instant::now();
        let next = estimate(&problem, m, self.o, &mut |_, _| {}).unwrap();
        let fig = figures(
            case,
            fl,
            (&next, self.o),
            start_ratio_errors(case, fl),
            t0.elapsed().as_secs_f64(),
        );
        let row = format!("{}, start brightness ×{what}", self.label);
        eprintln!("  {row}: {fig:?}");
        done.push(Done {
            diagnosis: None,
            label: row,
            figures: fig,
            k: None,
            note: String::new(),
        });
        next
    }

    /// Scores `next` (the last row pushed), notes the scores on its row and keeps it, with
    /// `factors`, when it scores lower than `kept`; returns whether it was kept.
    fn offer(&self, kept: &mut Kept, next: Estimate, factors: Vec<f64>, done: &mut [Done]) -> bool {
        let (score, note) = (self.score)(&next);
        eprintln!("    {note}");
        if let Some(last) = done.last_mut() {
            last.note = note;
        }
        let better = score < kept.score;
        if better {
            *kept = Kept {
                est: next,
                factors,
                score,
            };
        }
        better
    }
}

/// `ABLATION_SEARCH_CHANNELS=1`: one more round that scales one channel of one material
/// `j ≥ 1`'s Lambertian weight by √2 or 1/√2 around the kept start (`2 × 3 × (K − 1)` fits),
/// the lowest score kept. The first rounds scale R, G and B together, while the kept
/// fits' albedo ratio errors differ per channel.
fn channel_round(search: &Search, init: &Materials0, kept: &mut Kept, done: &mut Vec<Done>) {
    let mut centre = init.clone();
    for (j, &f) in kept.factors.iter().enumerate() {
        scale_lambert(&mut centre, j + 1, 0, [f; 3]);
    }
    let mut kept_what = String::from("none");
    for j in 1..centre.lambda.len() {
        for ch in 0..3 {
            for f in [std::f64::consts::SQRT_2, std::f64::consts::FRAC_1_SQRT_2] {
                let mut m = centre.clone();
                let mut factor = [1.0; 3];
                factor[ch] = f;
                scale_lambert(&mut m, j, 0, factor);
                let what = format!("{:.3?}, material {j} channel {ch} ×{f:.3}", kept.factors);
                let next = search.fit(m, &what, done);
                let factors = kept.factors.clone();
                if search.offer(kept, next, factors, done) {
                    kept_what = what;
                }
            }
        }
    }
    eprintln!("  channel round kept {kept_what}, score {:.5}", kept.score);
}

/// Protocol (b) on the training photos for fit `e` ([`half_score`]).
fn train_half_score(case: &Case, o: &EstimateOptions, e: &Estimate) -> f64 {
    let problem = case.train.problem(case.nv);
    let beta = relight_cpc::solve::beta_per_vertex(&e.lambda, &e.weights, case.nv);
    let left = left_by_view(&case.train.obs, &case.positions);
    half_score(&problem, &beta, &e.lights, &left, o).expect("half score")
}

/// Leave one material group out on the training photos for fit `e`
/// ([`material_holdout_score`]), the groups `group` (per vertex).
fn train_material_score(case: &Case, o: &EstimateOptions, e: &Estimate, group: &[usize]) -> f64 {
    let problem = case.train.problem(case.nv);
    let beta = relight_cpc::solve::beta_per_vertex(&e.lambda, &e.weights, case.nv);
    material_holdout_score(&problem, &beta, &e.lights, group, o).expect("material score")
}

/// The data term of fit `e` on every training observation ([`training_score`]).
fn training_of(case: &Case, e: &Estimate) -> f64 {
    let problem = case.train.problem(case.nv);
    let beta = relight_cpc::solve::beta_per_vertex(&e.lambda, &e.weights, case.nv);
    training_score(&problem, &beta, &e.lights)
}

/// Per vertex, the material with the largest weight (`weights` row-major `V × k`).
fn argmax_groups(weights: &[f64], k: usize) -> Vec<usize> {
    weights
        .chunks(k)
        .map(|r| (0..k).max_by(|&a, &b| r[a].total_cmp(&r[b])).unwrap_or(0))
        .collect()
}

/// The early-stopping validation score of a fit (NaN without validation).
fn validation_of(e: &Estimate) -> f64 {
    e.validation.as_ref().map_or(f64::NAN, |v| v.best_error())
}
