//! Part 2: joint recovery of materials and light, and the joint fit the other parts share.

use super::*;

/// The case's materials as text: per material its lobes with non-zero weight.
pub(crate) fn materials_text(case: &Case) -> String {
    case.lambda
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let lobes: Vec<String> = l
                .iter()
                .zip(&case.basis)
                .filter(|(v, _)| v.iter().any(|&x| x > 0.0))
                .map(|(v, b)| format!("{b:?} {:.2}/{:.2}/{:.2}", v[0], v[1], v[2]))
                .collect();
            format!("material {k}: {}", lobes.join(" + "))
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// The case's basis BRDFs as text.
pub(crate) fn basis_text(case: &Case) -> String {
    case.basis
        .iter()
        .map(|b| format!("{b:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Where a joint fit starts.
#[derive(Clone, Copy)]
pub(crate) enum Start {
    /// The clustered start, every non-Lambertian basis at this fraction of the material's
    /// mean Lambertian weight (0: the paper's start).
    Clustered(f64),
    /// The true materials.
    Truth,
    /// Start number `s` of [`starts::variants`] (gloss [`starts::GLOSS_FRACTION`]).
    Variant(usize),
    /// The first `n` of [`starts::variants`], the best kept ([`starts::estimate_best`]).
    Best(usize),
}

/// The paper's start: the clustered materials, Lambertian only.
pub(crate) const PAPER_START: Start = Start::Clustered(0.0);

impl Start {
    /// The starts this stands for, for `case` fitted to `obs`.
    fn starts(self, case: &Case, obs: &Observations) -> Vec<starts::Start> {
        let clustered = || initial(case, obs, case.lambda.len(), 1);
        let family = |n| starts::variants(clustered(), 0, starts::GLOSS_FRACTION, n);
        let one = |label: &str, materials| {
            vec![starts::Start {
                label: label.into(),
                materials,
            }]
        };
        match self {
            Start::Truth => one("the true materials", case.true_materials()),
            Start::Clustered(f) => one(
                &format!("clustered, glossy lobes at {f}"),
                starts::uniform_gloss(&clustered(), 0, f),
            ),
            Start::Variant(s) => {
                let mut v = family(s + 1);
                assert_eq!(v.len(), s + 1, "start {s} of {} variants", v.len());
                vec![v.pop().unwrap()]
            }
            Start::Best(n) => family(n),
        }
    }

    /// The single start this stands for (not [`Start::Best`] of more than one).
    pub(crate) fn materials(
        self,
        case: &Case,
        obs: &Observations,
    ) -> relight_cpc::solve::Materials0 {
        let mut v = self.starts(case, obs);
        assert_eq!(v.len(), 1, "this part fits from a single start");
        v.pop().unwrap().materials
    }
}

/// Joint fit of `case` from `start` (the best of several when it names several); the
/// timeline with the held-out error under the true light (per-channel scale) at every outer
/// iteration of every start.
pub(crate) fn joint_fit(
    case: &Case,
    obs: &Observations,
    opts: &EstimateOptions,
    start: Start,
) -> (Estimate, f64, Vec<Value>, MultiStart) {
    let problem = case.train_problem_with(obs);
    let tried = start.starts(case, obs);
    let mut tl = Vec::new();
    let t0 = Instant::now();
    let (est, record) = estimate_best(&problem, tried, opts, &mut |si, it, st| {
        let hp = predict_with(&case.held, case.nv, st.lambda, st.weights, &case.held.lights);
        let h = rel_rmse_per_channel(&case.held.obs, &hp);
        eprintln!(
            "  start {si} iteration {}: {:.1} s, objective {:.5e}, train RMSE {:.5}, validation {:?}, held-out rel {:.4}",
            tl.len() + 1,
            it.seconds,
            it.objective,
            it.train_rmse,
            it.validation_rel,
            h
        );
        tl.push(json!({"start": si, "seconds": it.seconds, "objective": it.objective, "train_rmse": it.train_rmse, "validation_rel": it.validation_rel, "heldout_rel_true_light": h}));
    })
    .unwrap();
    (est, t0.elapsed().as_secs_f64(), tl, record)
}

pub(crate) fn joint_row(md: &mut String, label: &str, f: &JointFigures) {
    md.push_str(&format!(
        "| {label} | {:.4} | {:.4} | {:.3} / {:.3} / {:.3} | {:.3} / {:.3} / {:.3} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} / {:.4} | {} | {:.1} |\n",
        f.assignment,
        f.assignment_pure,
        f.beta_ratio_errors[0],
        f.beta_ratio_errors[1],
        f.beta_ratio_errors[2],
        f.ratio_errors[0],
        f.ratio_errors[1],
        f.ratio_errors[2],
        f.train_rel,
        f.heldout_rel_channel,
        f.heldout_floor,
        f.heldout_rel_model,
        f.train_true_light,
        f.train_true_light_model,
        f.iterations,
        f.seconds
    ));
}

pub(crate) const JOINT_HEADER: &str = "| fit | assigned (all seen) | assigned (pure) | diffuse-ratio error R / G / B, per-vertex β (remix-invariant) | the same from λ (not invariant) | train rel. RMSE | held-out rel. RMSE (true light) | held-out floor (true reflectance) | held-out vs true model | training photos under their TRUE light: vs photos / vs true model | outer its | seconds |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";

pub(crate) fn joint(md: &mut String) -> Value {
    let s = sizes_joint();
    let scene = joint_scene();
    let mut case = prepare(&scene, s, joint_seed(), "joint");
    // `JOINT_NOISE_FREE=1`: every observation the true reflectance under the true light
    // through the case's own transport (floor 0: the estimator's own error).
    let clean = std::env::var("JOINT_NOISE_FREE").is_ok_and(|v| v == "1");
    if clean {
        noise_free(&mut case);
        md.push_str("**Noise-free** (`JOINT_NOISE_FREE=1`): every observation is the true model's prediction through the case's own transport.\n\n");
    }
    eprintln!(
        "{scene}: prepared in {:.1} + {:.1} s, {} vertices, {} train / {} held-out observations",
        case.seconds_synth,
        case.seconds_prepare,
        case.nv,
        case.train.obs.len(),
        case.held.obs.len()
    );
    md.push_str(&format!(
        "## 2. Joint recovery: `{scene}`\n\nSpot ({} vertices), two blended materials ({}), \
         {} training and {} held-out photos ({}², {} spp × {} MIS pairs), {}; basis = the true lobes \
         ({}); {}² global map, {}² local, {}² normal grid, all coefficients kept; K = 2 from the k-means start.\n\n\
         Materials are identifiable only up to a K×K non-negative remix (`w → w M⁻¹`, `λ → M λ` leaves every vertex's reflectance \
         `β = Σ_k w_k λ_k` unchanged) and each channel only up to the light colour (`λ_c → s_c λ_c`, maps `/ s_c`). The diffuse-ratio \
         error is therefore measured on what the data determine: per channel, the median estimated Lambertian weight `β̂_{{x,L,c}}` over the \
         vertices that are truly pure material 1 over the same median for material 2, against the truth's `λ_1,L,c / λ_2,L,c` \
         (the λ-based figure, not invariant, is shown beside it). Held-out photos are predicted under their TRUE maps with the \
         best scale per channel; the *floor* is the true reflectance doing the same (renderer noise, transport discretisation), \
         *vs true model* compares the estimated and the true reflectance's predictions through the same transport (the \
         estimator's own error, no renderer noise).\n\n",
        case.nv,
        materials_text(&case),
        case.train.views.len(),
        case.held.views.len(),
        s.width,
        s.spp,
        s.light_samples,
        match scene.as_str() {
            "spot-groups" => {
                "three real maps (courtyard, forest, city), photo i under map i mod 3, unrotated"
            }
            "spot-sky" if case.geotag_suns.is_some() => {
                "a clear sky (Hosek–Wilkie), sun lobe and ground per photo, the suns of one summer day's clock, every photo geotagged (`SYNTH_GEOTAG=1`)"
            }
            "spot-sky" => {
                "a clear sky (Hosek–Wilkie), sun lobe and ground per photo, a different sun each"
            }
            _ => "8 real maps cycling, each rotated",
        },
        basis_text(&case),
        s.global,
        s.local,
        s.normal_grid
    ));
    md.push_str(JOINT_HEADER);
    let mut rows = Vec::new();
    // The start, for reference: the k-means materials (Lambertian only) with the lights of
    // one lighting step.
    let start = EstimateOptions {
        max_outer: 1,
        ..EstimateOptions::default()
    };
    let long = EstimateOptions {
        max_outer: 30,
        rel_tol: 1e-5,
        ..EstimateOptions::default()
    };
    let from_specs: Option<Vec<(String, EstimateOptions, Start)>> =
        specs_from_env("JOINT_SPECS", &long).map(|v| {
            v.into_iter()
                .map(|sp| (sp.label, sp.opts, sp.start))
                .collect()
        });
    let variants: Vec<(String, EstimateOptions, Start)> = from_specs.unwrap_or_else(|| vec![
        ("after 1 outer iteration".into(), start, PAPER_START),
        (
            format!(
                "default options (early stopping: 10% validation, patience {}), ≤ 30 outer iterations",
                relight_cpc::solve::PATIENCE
            ),
            long.clone(),
            PAPER_START,
        ),
        (
            "no early stopping, ≤ 30 outer iterations".into(),
            EstimateOptions {
                validation_fraction: 0.0,
                ..long.clone()
            },
            PAPER_START,
        ),
    ]);
    let mut md_notes = Vec::new();
    for (label, o, from) in variants {
        let label = label.as_str();
        eprintln!("joint: {label}");
        let o = with_case_groups(&case, &with_case_priors(&case, &o));
        let (est, secs, tl, record) = joint_fit(&case, &case.train.obs, &o, from);
        let f = joint_figures(&case, &est, &case.train.obs, secs);
        eprintln!("{f:?}");
        joint_row(md, label, &f);
        if let Some(v) = &est.validation {
            md_notes.push(format!(
                "- {label}: {} validation observations; kept iteration {} of {} (validation rel. RMSE {:.4} there, {:.4} at the last){}.\n",
                v.observations,
                v.best_iteration,
                v.errors.len(),
                v.best_error(),
                v.errors.last().unwrap(),
                if v.stopped_early { ", stopped by patience" } else { "" }
            ));
        }
        if record.starts.len() > 1 {
            md_notes.push(format!(
                "- {label}: kept start {} by {}; {}.\n",
                record.chosen,
                record.criterion,
                record
                    .starts
                    .iter()
                    .enumerate()
                    .map(|(i, r)| {
                        let held = tl
                            .iter()
                            .filter(|t| t["start"] == i)
                            .nth(r.kept_iteration - 1)
                            .map_or(f64::NAN, |t| t["heldout_rel_true_light"].as_f64().unwrap_or(f64::NAN));
                        format!(
                            "start {i} ({}): score {:.4}, iteration {} of {} kept, held-out {held:.4}, {:.1} s",
                            r.label, r.score, r.kept_iteration, r.iterations, r.seconds
                        )
                    })
                    .collect::<Vec<_>>()
                    .join("; ")
            ));
        }
        rows.push(json!({"fit": label, "figures": f, "timeline": tl, "lambda": est.lambda, "normalisation": est.normalisation, "validation": est.validation, "starts": record}));
    }
    let truth_train = predict_with(
        &case.train,
        case.nv,
        &case.lambda,
        &case.weights,
        &case.train.lights,
    );
    let train_floor = rel_rmse(&case.train.obs, &truth_train, false).0;
    if !md_notes.is_empty() {
        md.push_str("\nEarly stopping (the figures above are of the iterate returned, `outer its` counts the iterations run; the JSON timeline has every iteration):\n\n");
        for n in md_notes {
            md.push_str(&n);
        }
    }
    md.push_str(&format!(
        "\nTraining floor (true reflectance, true light, training photos): {train_floor:.4}. \
         The timeline (objective, train RMSE and held-out error per outer iteration) is in `estimator.json`.\n\n"
    ));
    json!({"vertices": case.nv, "train_observations": case.train.obs.len(), "heldout_observations": case.held.obs.len(), "fits": rows, "train_floor_true_model": train_floor})
}
