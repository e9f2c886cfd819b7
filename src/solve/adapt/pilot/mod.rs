//! The pilot fit of the adaptive model ([`super`], steps 2–4): a transport at
//! [`PILOT_GLOBAL`]² on the observations with one in [`HELDOUT_EVERY`] held out, then one
//! decision after the other, each scored by the held-out RMSE of short fits
//! ([`PILOT_ITERATIONS`] outer iterations): the material count (step 3), the weights'
//! sum-to-one prior and where it applies (step 3b), the basis BRDFs (step 4).

use super::sample::PilotView;
use super::*;
use crate::solve::matched::StartBrightness;

/// What the pilot needs from the run.
pub struct PilotInput<'a> {
    /// Env-frame vertex normals.
    pub normals_env: &'a [Vec3],
    /// Training observations.
    pub obs: &'a Observations,
    /// World → environment frame.
    pub env_from_world: &'a nalgebra::Matrix3<f64>,
    /// Visibility at the run's local resolution.
    pub vis: &'a Visibility,
    /// The full basis list.
    pub basis: &'a [BasisBrdf],
    /// Index of the Lambertian basis in `basis`.
    pub lambert: usize,
    /// Normal grid of the run's rotation.
    pub normal_grid: usize,
    /// Requested global resolution (the pilot uses at most this).
    pub global_resolution: usize,
    /// Requested coefficient budget.
    pub keep: usize,
    /// The run's estimator options (smoothness, ridge, …). Their `lighting_strata` stratify
    /// the pilot's lighting sample ([`PILOT_LIGHTING_SAMPLE`]): pass the run's
    /// ([`crate::solve::subsample::lighting_strata`]). Without strata the sample is uniform,
    /// and on a noise-free rendered scene that took a wrong material count
    /// (`bench-results/pilot-lighting-sample.md`).
    pub estimate: EstimateOptions,
    /// Per-vertex mean colours and whether seen (for k-means).
    pub mean_rgb: &'a [[f64; 3]],
    /// Whether each vertex is seen.
    pub seen: &'a [bool],
    /// A fixed material count, or `None` to choose it.
    pub materials: Option<usize>,
    /// Whether to choose the blending weights' sum-to-one prior (step 3b): free weights
    /// (`estimate.weights_sum`) against [`PILOT_WEIGHTS_SUM`] on every vertex, then on
    /// blended vertices.
    pub choose_weights_sum: bool,
    /// The start of the pilot's fits, or [`StartBrightness::Auto`] to choose it (step 3c).
    pub start: StartBrightness,
    /// Most seen vertices the pilot fits ([`pilot_vertices`]; 0 = every vertex); the run
    /// passes [`PILOT_MAX_VERTICES`] unless `--pilot-vertices` says otherwise.
    pub max_vertices: usize,
    /// Seed.
    pub seed: u64,
}

/// What the pilot decided.
#[derive(Debug, Clone)]
pub struct PilotOutcome {
    /// Number of materials.
    pub materials: usize,
    /// Why.
    pub materials_reason: String,
    /// Held-out RMSE per material count tried (`(K, rmse)`).
    pub material_scores: Vec<(usize, f64)>,
    /// Indices into the full basis list that are kept.
    pub kept: Vec<usize>,
    /// Each basis's largest share of the predicted radiance.
    pub shares: Vec<f64>,
    /// The shares, the held-out ablation and why bases were dropped.
    pub basis_reason: String,
    /// The λ systems' condition numbers (per channel) of the chosen pilot.
    pub kappa_lambda: [f64; 3],
    /// Largest lighting condition lower bound of the chosen pilot.
    pub kappa_lighting: f64,
    /// Pilot wall time, seconds.
    pub seconds: f64,
    /// The blending weights' sum-to-one prior the fit uses
    /// ([`EstimateOptions::weights_sum`]).
    pub weights_sum: f64,
    /// Which vertices it ties ([`EstimateOptions::weights_sum_scope`]).
    pub weights_sum_scope: SumScope,
    /// Why, when the pilot chose it ([`PilotInput::choose_weights_sum`]).
    pub weights_sum_reason: Option<String>,
    /// The fit's start (step 3c): [`StartBrightness::Matched`] or
    /// [`StartBrightness::Clustered`].
    pub start: StartBrightness,
    /// Why, when the pilot chose it ([`StartBrightness::Auto`]).
    pub start_reason: Option<String>,
}

/// The pilot's transport, problem and held-out split, shared by all its fits.
struct Fitter<'a> {
    inp: &'a PilotInput<'a>,
    /// The pilot's observations, before its held-out split ([`pilot_vertices`]).
    obs: &'a Observations,
    /// The seen vertices among them (k-means clusters these).
    seen: &'a [bool],
    problem: Problem<'a>,
    held: &'a [usize],
    /// The held-out observations the material count is scored on ([`count_scored`]).
    count_held: &'a [usize],
    eopts: EstimateOptions,
    /// Visible fraction of every vertex's hemisphere (the matched start).
    open: &'a [f64],
    /// Whether the fits start from the brightness matched by normal (step 3c).
    matched: std::cell::Cell<bool>,
}

/// The weights' sum-to-one prior of one pilot fit: its strength and scope.
#[derive(Debug, Clone, Copy)]
struct SumPrior {
    strength: f64,
    scope: SumScope,
}

/// One pilot fit: the weights' prior it used, the estimate, its held-out RMSE, and that
/// RMSE over the observations that score the material count.
struct PilotFit {
    prior: SumPrior,
    est: solve::Estimate,
    heldout: f64,
    count_score: f64,
}

impl Fitter<'_> {
    /// The pilot fit with `k` materials on the bases `kept` (indices into the full list)
    /// with the weights' prior `prior`; `strict`: `None` when k-means finds fewer than `k`
    /// distinct clusters.
    fn fit(
        &self,
        k: usize,
        kept: &[usize],
        prior: SumPrior,
        strict: bool,
    ) -> Result<Option<PilotFit>> {
        let inp = self.inp;
        let mut init =
            crate::solve::cluster::initial_materials(inp.mean_rgb, self.seen, k, inp.seed)?;
        if strict && init.albedo.len() < k {
            return Ok(None);
        }
        if self.matched.get() {
            self.match_brightness(&mut init, true);
        }
        Ok(Some(self.fit_from(&init, kept, prior)?))
    }

    /// The pilot fit from the starting materials `init` on the bases `kept` with the
    /// weights' prior `prior`.
    fn fit_from(
        &self,
        init: &crate::solve::cluster::InitialMaterials,
        kept: &[usize],
        prior: SumPrior,
    ) -> Result<PilotFit> {
        let inp = self.inp;
        let sub;
        let problem = if kept.len() == inp.basis.len() {
            self.problem
        } else {
            sub = select_bases(self.problem.transport, kept)?;
            Problem {
                transport: &sub,
                ..self.problem
            }
        };
        let lambert = kept
            .iter()
            .position(|&b| b == inp.lambert)
            .unwrap_or(usize::MAX);
        let m0 = Materials0::from_initial(init, kept.len(), lambert);
        let opts = EstimateOptions {
            lambert_basis: lambert,
            weights_sum: prior.strength,
            weights_sum_scope: prior.scope,
            ..self.eopts.clone()
        };
        let est = solve::estimate(&problem, m0, &opts, &mut |_, _| {})?;
        let pred = solve::predict(&problem, &est);
        let heldout = heldout_rmse(self.obs, self.held, &pred);
        let count_score = heldout_rmse(self.obs, self.count_held, &pred);
        Ok(PilotFit {
            prior,
            est,
            heldout,
            count_score,
        })
    }

    /// `init` with its materials' brightness matched by normal on the pilot's training
    /// observations ([`crate::solve::matched`]); `force`: also when the materials' ratios
    /// are inconsistent.
    fn match_brightness(
        &self,
        init: &mut crate::solve::cluster::InitialMaterials,
        force: bool,
    ) -> crate::solve::matched::StartMatch {
        let normals = self.inp.normals_env;
        crate::solve::matched::match_start(init, self.problem.obs, normals, self.open, force)
    }

    /// Every basis of the full list.
    fn all(&self) -> Vec<usize> {
        (0..self.inp.basis.len()).collect()
    }

    /// The run's own prior (free weights unless `--weights-sum` gave one).
    fn run_prior(&self) -> SumPrior {
        SumPrior {
            strength: self.eopts.weights_sum,
            scope: self.eopts.weights_sum_scope,
        }
    }
}

/// The pilot fit (module docs, steps 2–4).
pub fn pilot(inp: &PilotInput) -> Result<PilotOutcome> {
    let t0 = std::time::Instant::now();
    let data = PilotData::new(inp)?;
    let fitter = Fitter {
        open: &data.open,
        matched: std::cell::Cell::new(inp.start == StartBrightness::Matched),
        inp,
        obs: &data.view.obs,
        seen: &data.view.seen,
        problem: Problem {
            obs: &data.split,
            transport: &data.tr,
            n_vertices: inp.normals_env.len(),
            n_photos: data.split.photo_ranges.len(),
        },
        held: &data.held,
        count_held: &data.count_held,
        eopts: pilot_options(inp),
    };
    let mut count = material_count(&fitter, data.g)?;
    if let Some(note) = &data.view.note {
        count.reason += note;
    }
    let (chosen, weights_sum_reason) = if inp.choose_weights_sum {
        let (kept, why) = choose_weights_sum(&fitter, count.k, count.fit)?;
        (kept, Some(why))
    } else {
        (count.fit, None)
    };
    let (chosen, start_reason) = if inp.start == StartBrightness::Auto {
        let (kept, why) = choose_start(&fitter, count.k, chosen)?;
        (kept, Some(why))
    } else {
        (chosen, None)
    };
    let bases = basis_choice(&fitter, count.k, &chosen)?;
    let est = &chosen.est;
    Ok(PilotOutcome {
        materials: count.k,
        materials_reason: count.reason,
        material_scores: count.scores,
        kept: bases.kept,
        shares: bases.shares,
        basis_reason: bases.reason,
        kappa_lambda: est.conditioning.lambda,
        kappa_lighting: est.conditioning.lighting_max().unwrap_or(0.0),
        seconds: t0.elapsed().as_secs_f64(),
        weights_sum: chosen.prior.strength,
        weights_sum_scope: chosen.prior.scope,
        weights_sum_reason,
        start: if fitter.matched.get() {
            StartBrightness::Matched
        } else {
            StartBrightness::Clustered
        },
        start_reason,
    })
}

/// What every pilot fit reads (step 2): the pilot's vertices and observations, their
/// held-out split, and the transport at the pilot's map sides.
struct PilotData<'a> {
    /// The global side, `≤` [`PILOT_GLOBAL`].
    g: usize,
    view: PilotView<'a>,
    /// The training half of the split and the held-out observations.
    split: Observations,
    held: Vec<usize>,
    /// The held-out observations the material count is scored on ([`count_scored`]).
    count_held: Vec<usize>,
    tr: Transport,
    /// Visible fraction of every vertex's hemisphere at the pilot's local side.
    open: Vec<f64>,
}

impl<'a> PilotData<'a> {
    fn new(inp: &PilotInput<'a>) -> Result<Self> {
        let g = PILOT_GLOBAL.min(inp.global_resolution);
        let l = PILOT_LOCAL.min(inp.vis.n_local);
        // The run traces at the pilot's side first: then the visibility is read as it is.
        let vis = downsample_visibility(inp.vis, l);
        let rot = Rotation::new(g, l, inp.normal_grid.min(16), RotationForm::Factored);
        let topts = TransportOptions {
            n_global: g,
            n_local: l,
            keep: if inp.keep == 0 {
                g * g / 2
            } else {
                inp.keep.min(g * g / 2)
            },
        };
        let view = PilotView::new(inp.obs, inp.seen, inp.max_vertices, inp.seed);
        let (split, held) = holdout_split(&view.obs, inp.seed);
        let count_held = count_scored(&split, &held, inp.normals_env.len());
        let tr = transport::build(
            inp.normals_env,
            &split,
            inp.env_from_world,
            &vis,
            inp.basis,
            &rot,
            &topts,
        )?;
        Ok(PilotData {
            g,
            view,
            split,
            held,
            count_held,
            tr,
            open: vis.open_fractions(),
        })
    }
}

/// The estimator's options for a pilot fit: the run's, cut to [`PILOT_ITERATIONS`] outer
/// iterations without the robust loss, with the pilot's solver caps and lighting sample.
fn pilot_options(inp: &PilotInput) -> EstimateOptions {
    EstimateOptions {
        max_outer: PILOT_ITERATIONS,
        rel_tol: 0.0,
        robust: Robust::None,
        irls_iters: 1,
        lambert_basis: inp.lambert,
        alternation_cg_iters: Some(PILOT_CG_ITERS),
        alternation_qp_iters: Some(
            inp.estimate
                .alternation_qp_iters
                .map_or(PILOT_QP_ITERS, |q| q.min(PILOT_QP_ITERS)),
        ),
        lighting_sample: match inp.estimate.lighting_sample {
            0 => PILOT_LIGHTING_SAMPLE,
            n => n.min(PILOT_LIGHTING_SAMPLE),
        },
        ..inp.estimate.clone()
    }
}

/// The material count (step 3) and the pilot fit with it (free weights, every basis).
struct CountChoice {
    k: usize,
    reason: String,
    /// Held-out RMSE per count tried.
    scores: Vec<(usize, f64)>,
    fit: PilotFit,
}

/// Step 3: the count given, or the smallest within [`MATERIAL_TOL`] of the best held-out
/// RMSE over `K = 1 …` [`MAX_MATERIALS`], the search ending once [`COUNT_PATIENCE`] counts
/// past the current choice have not changed it (`g`: the pilot's map side, for the reason).
fn material_count(f: &Fitter, g: usize) -> Result<CountChoice> {
    let (all, free) = (f.all(), f.run_prior());
    if let Some(k) = f.inp.materials {
        let fit = f.fit(k, &all, free, false)?.ok_or_else(|| Error::Numeric {
            stage: "adaptive pilot".into(),
            message: format!("no fit with {k} materials"),
        })?;
        return Ok(CountChoice {
            k,
            reason: format!("materials: {k}, as given by --materials"),
            scores: vec![(k, fit.count_score)],
            fit,
        });
    }
    // `fits[i]` and `heldout[i]` are of `K = i + 1`.
    let (mut fits, mut heldout) = (Vec::new(), Vec::new());
    let mut stop = format!("{MAX_MATERIALS} is the cap");
    for k in 1..=MAX_MATERIALS {
        let Some(fit) = f.fit(k, &all, free, true)? else {
            stop = format!("k-means finds no {k}th distinct colour cluster");
            break;
        };
        heldout.push(fit.count_score);
        fits.push(fit);
        if count_search_done(&heldout) && k < MAX_MATERIALS {
            stop = format!(
                "the {COUNT_PATIENCE} counts after K={} did not change the choice",
                smallest_as_good(&heldout) + 1
            );
            break;
        }
    }
    let scores: Vec<(usize, f64)> = (1..).zip(heldout.iter().copied()).collect();
    let pick = smallest_as_good(&heldout);
    let (k, fit) = (pick + 1, fits.swap_remove(pick));
    let table = scores
        .iter()
        .map(|(k, e)| format!("K={k}: {e:.4e}"))
        .collect::<Vec<_>>()
        .join(", ");
    let reason = format!(
        "materials: {k} (auto), the smallest count within {:.0}% of the best held-out RMSE (one material within {:.0}%) of a {PILOT_ITERATIONS}-iteration pilot at {g}² on 1 in {HELDOUT_EVERY} observations held out, scored at vertices at least {COUNT_MIN_SEEN} training observations see ({table}); the search ends because {stop}",
        100.0 * MATERIAL_TOL,
        100.0 * ONE_MATERIAL_TOL
    );
    Ok(CountChoice {
        k,
        reason,
        scores,
        fit,
    })
}

/// Index of the smallest count whose held-out RMSE (`heldout[i]` for `K = i + 1`) is within
/// [`count_tol`] of the best (the first, when no score is finite).
fn smallest_as_good(heldout: &[f64]) -> usize {
    let best = heldout.iter().copied().fold(f64::INFINITY, f64::min);
    (0..heldout.len())
        .find(|&i| as_good(heldout[i], best, count_tol(i + 1)) || !best.is_finite())
        .unwrap_or(0)
}

/// Whether the count search may end: the [`COUNT_PATIENCE`] counts scored after the
/// current choice ([`smallest_as_good`]) did not change it.
fn count_search_done(heldout: &[f64]) -> bool {
    heldout.len() > smallest_as_good(heldout) + COUNT_PATIENCE
}

/// The basis BRDFs kept (step 4), each basis's largest share and why.
struct BasisChoice {
    kept: Vec<usize>,
    shares: Vec<f64>,
    reason: String,
}

/// Step 4: the shares of `full` (the pilot with `k` materials and every basis), then the
/// held-out ablation against `full` ([`held_out_ablation`]).
fn basis_choice(f: &Fitter, k: usize, full: &PilotFit) -> Result<BasisChoice> {
    let inp = f.inp;
    let shares = basis_shares(&f.problem, &full.est);
    let kept: Vec<usize> = (0..inp.basis.len())
        .filter(|&b| b == inp.lambert || shares[b] >= DROP_SHARE)
        .collect();
    let dropped: Vec<usize> = (0..inp.basis.len()).filter(|b| !kept.contains(b)).collect();
    let mut reasons = vec![format!(
        "largest share of a material's predicted radiance in the pilot: {}",
        inp.basis
            .iter()
            .zip(&shares)
            .map(|(b, s)| format!("{} {:.2}%", b.label(), 100.0 * s))
            .collect::<Vec<_>>()
            .join(", ")
    )];
    if !dropped.is_empty() {
        reasons.push(format!(
            "dropped {}: each carries less than {:.0}% of the predicted radiance of every material and channel in the pilot (largest share {})",
            dropped.iter().map(|&b| inp.basis[b].label()).collect::<Vec<_>>().join(", "),
            100.0 * DROP_SHARE,
            dropped.iter().map(|&b| format!("{} {:.2}%", inp.basis[b].label(), 100.0 * shares[b])).collect::<Vec<_>>().join(", ")
        ));
    }
    let worst = full
        .est
        .conditioning
        .lambda
        .iter()
        .copied()
        .fold(0.0, f64::max);
    if worst > KAPPA_LAMBDA {
        // Lobes the photos cannot tell apart: the ablation below drops all but one of
        // them, since leaving one out costs no held-out error.
        reasons.push(format!(
            "the pilot's λ system has condition number {worst:.1e} > {KAPPA_LAMBDA:.0e}: some lobes are nearly indistinguishable in these photos"
        ));
    }
    let order = ablation_order(inp.basis, &shares, &kept, inp.lambert);
    let kept = held_out_ablation(f, k, full, &order, kept, &mut reasons)?;
    Ok(BasisChoice {
        kept,
        shares,
        reason: reasons.join("; "),
    })
}

/// Step 4's held-out ablation: a lobe the shares keep may still be one the data cannot
/// tell from the others (with a free light per photo, a sharp lobe can mimic the diffuse
/// shading of a single view). Each kept non-Lambertian basis in `order` (sharpest first,
/// [`ablation_order`]) is left out in turn; it goes when the pilot without it (and without
/// those already dropped) predicts the held-out observations within [`BASIS_TOL`] of the
/// pilot with every basis (`full`). The comparison is always against that full pilot, so
/// the drops together cost at most `BASIS_TOL` of held-out error. The first lobe kept ends
/// it: the broader ones stay untested (stand-ins, module docs). Returns the bases kept
/// and adds why to `reasons`.
fn held_out_ablation(
    f: &Fitter,
    k: usize,
    full: &PilotFit,
    order: &[usize],
    mut kept: Vec<usize>,
    reasons: &mut Vec<String>,
) -> Result<Vec<usize>> {
    let basis = f.inp.basis;
    let (mut ablation, mut stay) = (Vec::new(), None);
    for (i, &b) in order.iter().enumerate() {
        let trial: Vec<usize> = kept.iter().copied().filter(|&x| x != b).collect();
        let Some(fit) = f.fit(k, &trial, full.prior, false)? else {
            continue;
        };
        let (e, ok) = (fit.heldout, as_good(fit.heldout, full.heldout, BASIS_TOL));
        ablation.push(format!(
            "without {} {e:.4e}{}",
            basis[b].label(),
            if ok { " (dropped)" } else { " (kept)" }
        ));
        if !ok {
            stay = broader_stay(basis, &order[i + 1..]);
            break;
        }
        kept = trial;
    }
    if !ablation.is_empty() {
        reasons.push(format!(
            "held-out RMSE of the pilot with every basis {:.4e}; {}: a basis goes when leaving it out costs at most {:.0}%",
            full.heldout,
            ablation.join(", "),
            100.0 * BASIS_TOL
        ));
    }
    reasons.extend(stay);
    Ok(kept)
}

/// Why the lobes `rest` (broader than the shiny lobe the ablation just kept) stay without a
/// test; `None` when there are none.
fn broader_stay(basis: &[BasisBrdf], rest: &[usize]) -> Option<String> {
    (!rest.is_empty()).then(|| {
        let names: Vec<String> = rest.iter().map(|&b| basis[b].label()).collect();
        format!(
            "{} kept untested: broader than a kept shiny lobe, which would stand in for it in the pilot",
            names.join(", ")
        )
    })
}

/// The order in which the held-out ablation leaves out the kept non-Lambertian bases:
/// sharpest lobe first ([`BasisBrdf::lobe_sigma`]), then smallest share. Of two lobes
/// the pilot cannot tell apart (leaving either out costs nothing) the first one tried
/// goes; sharpest first makes it the one the full fit pays most for (module docs, step 4).
fn ablation_order(
    basis: &[BasisBrdf],
    shares: &[f64],
    kept: &[usize],
    lambert: usize,
) -> Vec<usize> {
    let mut order: Vec<usize> = kept.iter().copied().filter(|&b| b != lambert).collect();
    order.sort_by(|&a, &b| {
        basis[a]
            .lobe_sigma()
            .total_cmp(&basis[b].lobe_sigma())
            .then(shares[a].total_cmp(&shares[b]))
    });
    order
}

/// Step 3b: the pilot with `k` materials and free weights (`free`) against the same with
/// the sum-to-one prior at [`PILOT_WEIGHTS_SUM`] on every vertex, kept when it lowers the
/// held-out RMSE by more than [`WEIGHTS_SUM_GAIN`]; else against the prior on blended
/// vertices ([`SumScope::Blends`] at [`BLEND_FLOOR`]), kept when it lowers it by more than
/// [`BLEND_GAIN`]; else the paper's free weights. Returns the fit kept and why.
fn choose_weights_sum(f: &Fitter, k: usize, free: PilotFit) -> Result<(PilotFit, String)> {
    let (every, blends) = (100.0 * WEIGHTS_SUM_GAIN, 100.0 * BLEND_GAIN);
    let trials = [
        SumTrial {
            prior: SumPrior {
                strength: PILOT_WEIGHTS_SUM,
                scope: SumScope::Every,
            },
            label: "sum-to-one prior",
            gain: WEIGHTS_SUM_GAIN,
            kept: format!("the weights' sum-to-one prior at {PILOT_WEIGHTS_SUM}"),
            rule: format!("the prior goes in when it lowers that by more than {every:.0}%"),
        },
        SumTrial {
            prior: SumPrior {
                strength: PILOT_WEIGHTS_SUM,
                scope: SumScope::Blends { floor: BLEND_FLOOR },
            },
            label: "on blended vertices",
            gain: BLEND_GAIN,
            kept: format!("the weights' sum-to-one prior at {PILOT_WEIGHTS_SUM} on blended vertices (pure ones at {BLEND_FLOOR} of it)"),
            rule: format!("the prior goes in everywhere when it lowers that by more than {every:.0}%, on blended vertices when it lowers that by more than {blends:.0}%"),
        },
    ];
    let all = f.all();
    let mut figures = vec![format!("free weights {:.4e}", free.heldout)];
    for t in trials {
        let Some(with) = f.fit(k, &all, t.prior, false)? else {
            continue;
        };
        figures.push(trial_figure(t.label, free.heldout, with.heldout));
        if lowers(free.heldout, with.heldout, t.gain) {
            let why = format!(
                "{}: held-out RMSE of the pilot with {k} materials: {}; {}",
                t.kept,
                figures.join(", "),
                t.rule
            );
            return Ok((with, why));
        }
    }
    let why = format!(
        "free weights, as the paper: held-out RMSE of the pilot with {k} materials: {}; the prior goes in everywhere only when it lowers that by more than {every:.0}%, on blended vertices by more than {blends:.0}%",
        figures.join(", ")
    );
    Ok((free, why))
}

/// One trial of step 3b: the prior, its label among the reason's figures, the fall of the
/// held-out RMSE it must bring, and the reason's head and rule when it is kept.
struct SumTrial {
    prior: SumPrior,
    label: &'static str,
    gain: f64,
    kept: String,
    rule: String,
}

/// Step 3c: the pilot with `k` materials and `chosen`'s prior refitted from the
/// brightness matched by normal, kept (and every later fit started so) when its held-out
/// RMSE is at most [`START_TOL`] above `chosen`'s.
fn choose_start(f: &Fitter, k: usize, chosen: PilotFit) -> Result<(PilotFit, String)> {
    let mut init = crate::solve::cluster::initial_materials(f.inp.mean_rgb, f.seen, k, f.inp.seed)?;
    let matched_start = f.match_brightness(&mut init, false);
    if !matched_start.applied() {
        return Ok((
            chosen,
            format!(
                "the clustered colours, as the paper: {}",
                matched_start.describe()
            ),
        ));
    }
    let matched = f.fit_from(&init, &f.all(), chosen.prior)?;
    let figures = format!(
        "held-out RMSE of the pilot with {k} materials: clustered {:.4e}, {}; a consistent matched start is kept unless it raises that by more than {}%",
        chosen.heldout,
        trial_figure("matched", chosen.heldout, matched.heldout),
        100.0 * START_TOL
    );
    if matched.heldout <= (1.0 + START_TOL) * chosen.heldout {
        f.matched.set(true);
        Ok((
            matched,
            format!(
                "each material's brightness matched by normal: {figures}; {}",
                matched_start.describe()
            ),
        ))
    } else {
        Ok((
            chosen,
            format!(
                "the clustered colours, as the paper: {figures} (the matched start: {})",
                matched_start.describe()
            ),
        ))
    }
}

/// `"{label} {with:.4e} ({change:+.1}%)"`, the change against free weights.
fn trial_figure(label: &str, free: f64, with: f64) -> String {
    format!("{label} {with:.4e} ({:+.1}%)", 100.0 * (with / free - 1.0))
}

/// Whether a trial's held-out RMSE `with` is lower than `free`'s by more than `gain`
/// (relative).
fn lowers(free: f64, with: f64, gain: f64) -> bool {
    with < (1.0 - gain) * free
}

#[cfg(test)]
mod tests;
