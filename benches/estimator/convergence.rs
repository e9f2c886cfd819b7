//! Part 5: convergence of the alternation on noise-free data.

use super::*;

/// Part 5: convergence of the alternation on noise-free data (`noise_free`), per outer
/// iteration, for option variants; written to `bench-results/estimator-convergence.*`.
pub(crate) fn convergence(md: &mut String) -> Value {
    let s = Sizes {
        spp: 1,
        ..sizes_joint()
    };
    let iters: usize = std::env::var("CONVERGENCE_ITERS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(30);
    let scene = joint_scene();
    let mut case = prepare(&scene, s, 1, "convergence");
    noise_free(&mut case);
    md.push_str(&format!(
        "## 5. Convergence on noise-free data\n\n`{scene}` ({} vertices, {} training / {} held-out photos, {}², {}² global, {}² local, all coefficients) \
         with every observation replaced by the TRUE reflectance under the TRUE light through the case's own transport: the model \
         reproduces the data exactly, so the floor is 0 and what remains is the estimator's own error. K = 2 from the k-means start \
         unless stated; ≤ {iters} outer iterations, `rel_tol` 0. Held-out = the held-out photos under their true light (best scale per channel).\n\n",
        case.nv,
        case.train.views.len(),
        case.held.views.len(),
        s.width,
        s.global,
        s.local
    ));
    let base = EstimateOptions {
        max_outer: iters,
        rel_tol: 0.0,
        validation_fraction: 0.0,
        ..EstimateOptions::default()
    };
    let none = EstimateOptions {
        robust: Robust::None,
        ..base.clone()
    };
    let variants: Vec<(&str, EstimateOptions, Start)> =
        vec![
        ("default options, no early stopping", base.clone(), PAPER_START),
        (
            "the same, started at the TRUE materials",
            base.clone(),
            Start::Truth,
        ),
        ("no IRLS", none.clone(), PAPER_START),
        ("no IRLS, started at the TRUE materials", none.clone(), Start::Truth),
        (
            "no IRLS, smoothness 1e-5",
            EstimateOptions {
                smoothness: 1e-5,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, no extrapolation",
            EstimateOptions {
                extrapolate: false,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, 3 material sweeps",
            EstimateOptions {
                material_sweeps: 3,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, gauge fixed every iteration",
            EstimateOptions {
                fix_gauge: true,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "Huber IRLS in the lighting step only, material step α with the 4.685σ cut",
            EstimateOptions {
                materials_cut_only: true,
                ..base.clone()
            },
            PAPER_START,
        ),
        (
            "default, early stopping (10% validation, patience 3)",
            EstimateOptions {
                validation_fraction: 0.1,
                patience: 3,
                ..base.clone()
            },
            PAPER_START,
        ),
        (
            "Huber k = 3",
            EstimateOptions {
                robust: Robust::Huber { k: 3.0 },
                ..base.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, early stopping (10% validation, patience 3)",
            EstimateOptions {
                validation_fraction: 0.1,
                patience: 3,
                ..none.clone()
            },
            PAPER_START,
        ),
        (
            "no IRLS, started at the TRUE materials, early stopping (10% validation, patience 3)",
            EstimateOptions {
                validation_fraction: 0.1,
                patience: 3,
                ..none.clone()
            },
            Start::Truth,
        ),
    ];
    let variants: Vec<(String, EstimateOptions, Start)> =
        match specs_from_env("CONVERGENCE_SPECS", &base) {
            Some(specs) => specs
                .into_iter()
                .map(|sp| (sp.label, sp.opts, sp.start))
                .collect(),
            None => variants
                .into_iter()
                .map(|(l, o, t)| (l.to_string(), o, t))
                .collect(),
        };
    let only = std::env::var("CONVERGENCE_VARIANTS")
        .ok()
        .filter(|_| std::env::var("CONVERGENCE_SPECS").is_err());
    md.push_str("| fit | outer its | train rel. RMSE after 1 / 5 / 10 / 20 / last | held-out rel. RMSE after 1 / 5 / 10 / 20 / last | best held-out (iteration) | returned estimate's held-out | seconds |\n|---|---|---|---|---|---|---|\n");
    let mut rows = Vec::new();
    for (vi, (label, o, start)) in variants.into_iter().enumerate() {
        if let Some(sel) = &only {
            if !sel.split(',').any(|v| v == vi.to_string()) {
                continue;
            }
        }
        eprintln!("convergence: {label}");
        let problem = case.train.problem(case.nv);
        let init = start.materials(&case, &case.train.obs);
        let mut tl: Vec<Value> = Vec::new();
        let (mut tr, mut he) = (Vec::new(), Vec::new());
        let t0 = Instant::now();
        let est = estimate(&problem, init, &o, &mut |it, st| {
            let hp = predict_with(&case.held, case.nv, st.lambda, st.weights, &case.held.lights);
            let h = rel_rmse_per_channel(&case.held.obs, &hp);
            let tp = predict_with(&case.train, case.nv, st.lambda, st.weights, st.lights);
            let t = rel_rmse(&case.train.obs, &tp, false).0;
            let lam_l: Vec<f64> = (0..3)
                .map(|c| st.lambda.iter().map(|l| l[0][c]).sum::<f64>())
                .collect();
            let light_sum: f64 = st.lights.iter().flat_map(|l| l.iter().flatten()).sum();
            eprintln!(
                "  {label} it {}: {:.1} s, objective {:.5e}, train rel {t:.5}, held-out rel {h:.5}, Σλ_L {lam_l:.4?}, Σ light {light_sum:.4e}",
                tl.len() + 1,
                it.seconds,
                it.objective
            );
            tr.push(t);
            he.push(h);
            tl.push(json!({"seconds": it.seconds, "objective": it.objective, "train_rel": t, "heldout_rel_true_light": h, "lambda_lambert_sum": lam_l, "light_sum": light_sum}));
        })
        .unwrap();
        let secs = t0.elapsed().as_secs_f64();
        let pick = |v: &[f64]| {
            [1usize, 5, 10, 20]
                .iter()
                .map(|&i| v.get(i - 1).map_or("–".to_string(), |x| format!("{x:.4}")))
                .chain(std::iter::once(format!("{:.4}", v.last().unwrap())))
                .collect::<Vec<_>>()
                .join(" / ")
        };
        let (bi, bh) =
            he.iter().enumerate().fold(
                (0, f64::INFINITY),
                |a, (i, &h)| if h < a.1 { (i, h) } else { a },
            );
        let ret = rel_rmse_per_channel(
            &case.held.obs,
            &case.predict_held(&est.lambda, &est.weights),
        );
        let ret_it = est.kept_iteration();
        md.push_str(&format!(
            "| {label} | {} of ≤ {} | {} | {} | {bh:.4} ({}) | {ret:.4} (iteration {ret_it}) | {secs:.1} |\n",
            est.timeline.len(),
            o.max_outer,
            pick(&tr),
            pick(&he),
            bi + 1
        ));
        rows.push(json!({"fit": label, "options": format!("{o:?}"), "from_truth": matches!(start, Start::Truth), "timeline": tl, "seconds": secs, "iterations": est.timeline.len(), "returned_heldout_rel": ret, "returned_iteration": ret_it}));
    }
    md.push('\n');
    json!({"vertices": case.nv, "train_observations": case.train.obs.len(), "heldout_observations": case.held.obs.len(), "fits": rows})
}
