//! Part 3: robustness to bright outliers (IRLS against plain least squares).

use super::*;

pub(crate) fn robust(md: &mut String) -> Value {
    let s = sizes_joint();
    let scene = joint_scene();
    let case = prepare(&scene, s, 1, "robust");
    md.push_str(&format!("## 3. Robustness: 5% bright outliers\n\nThe `{scene}` case of part 2; 5% of the training observations get `+u · y99` in every channel \
        (`u ~ U(0.5, 2)`, `y99` the 99th percentile of the observed values); ≤ 12 outer iterations each. Errors against the CLEAN data \
        and the truth; ratio = corrupted / clean (Huber IRLS). The *w-step cut* (`EstimateOptions::weights_reject`, default 4.685) \
        leaves observations whose lighting residual exceeds 4.685 σ out of the per-vertex blending-weight step. \
        With `ROBUST_SPECS` the rows are those specs (the first must be the clean reference).\n\n"));
    md.push_str(JOINT_HEADER);
    // Early stopping off: this part measures the robust loss over a fixed 12 iterations.
    let base = EstimateOptions {
        max_outer: 12,
        rel_tol: 1e-5,
        validation_fraction: 0.0,
        ..EstimateOptions::default()
    };
    let mut dirty = case.train.obs.clone();
    let hit = corrupt(&mut dirty, 0.05, 7);
    let mut rows = Vec::new();
    let mut fits = Vec::new();
    let cut = EstimateOptions::default().weights_reject;
    let table: Vec<(String, &Observations, EstimateOptions)> =
        if let Some(specs) = specs_from_env("ROBUST_SPECS", &base) {
            specs
                .into_iter()
                .map(|sp| {
                    let obs = if sp.dirty { &dirty } else { &case.train.obs };
                    (sp.label, obs, sp.opts)
                })
                .collect()
        } else {
            default_robust_rows(&base, &case.train.obs, &dirty, cut)
        };
    for (label, obs, o) in table {
        let label = label.as_str();
        eprintln!("robust: {label}");
        let (est, secs, _, _) = joint_fit(&case, obs, &o, PAPER_START);
        let f = joint_figures(&case, &est, &case.train.obs, secs);
        eprintln!("{f:?}");
        joint_row(md, label, &f);
        fits.push((label.to_string(), f.clone()));
        rows.push(json!({"fit": label, "options": format!("{o:?}"), "figures": f}));
    }
    robust_ratios(md, &fits, hit.len());
    json!({"corrupted": hit.len(), "fits": rows})
}

/// Part 3's default rows: clean and 5% outliers under Huber (with and without the w-step
/// cut), Tukey and plain least squares.
pub(crate) fn default_robust_rows<'a>(
    base: &EstimateOptions,
    clean: &'a Observations,
    dirty: &'a Observations,
    cut: Option<f64>,
) -> Vec<(String, &'a Observations, EstimateOptions)> {
    let mut out = Vec::new();
    for (label, obs, robust, weights_reject) in [
        (
            "clean, Huber IRLS (default)",
            clean,
            Robust::Huber { k: 1.345 },
            cut,
        ),
        (
            "5% outliers, Huber IRLS (default)",
            dirty,
            Robust::Huber { k: 1.345 },
            cut,
        ),
        (
            "5% outliers, Huber IRLS, no w-step cut",
            dirty,
            Robust::Huber { k: 1.345 },
            None,
        ),
        (
            "5% outliers, Tukey IRLS",
            dirty,
            Robust::Tukey { c: 4.685 },
            cut,
        ),
        ("5% outliers, no IRLS", dirty, Robust::None, cut),
        ("clean, no IRLS", clean, Robust::None, cut),
    ] {
        let o = EstimateOptions {
            robust,
            weights_reject,
            ..base.clone()
        };
        out.push((label.to_string(), obs, o));
    }
    out
}

/// Part 3's ratios of every row to the first (the clean reference).
pub(crate) fn robust_ratios(md: &mut String, fits: &[(String, JointFigures)], corrupted: usize) {
    let (c_ch, c_model, c_train) = (
        fits[0].1.heldout_rel_channel,
        fits[0].1.heldout_rel_model,
        fits[0].1.train_rel,
    );
    md.push_str(&format!(
        "\n{corrupted} observations corrupted. Ratios to the first row (held-out vs observations / held-out vs true model / train vs clean observations):\n\n"
    ));
    for (l, f) in &fits[1..] {
        md.push_str(&format!(
            "- {l}: ×{:.2} / ×{:.2} / ×{:.2}\n",
            f.heldout_rel_channel / c_ch,
            f.heldout_rel_model / c_model,
            f.train_rel / c_train
        ));
    }
    md.push('\n');
}
