//! Part 1: known reflectance, unknown light (paper Sec. 6.1).

use super::*;

pub(crate) fn known(md: &mut String) -> Value {
    md.push_str("## 1. Known reflectance, unknown light (paper Sec. 6.1)\n\n");
    // `KNOWN_NOISE_FREE=1`: every observation replaced by the true map's prediction
    // through the case's own transport ([`noise_free`]; 1 spp, the render is discarded),
    // so the floor is 0 and the fit's error is the estimator's own.
    let clean = std::env::var("KNOWN_NOISE_FREE").is_ok_and(|v| v == "1");
    let mut s = sizes_known();
    if clean {
        s.spp = 1;
        md.push_str(
            "**Noise-free** (`KNOWN_NOISE_FREE=1`): every observation is the TRUE map's prediction through the \
             case's own transport, so the floor is 0 and the fit error is the estimator's own (the Laplacian's \
             bias, the QP's stopping rule); the spp below only made the discarded render.\n\n",
        );
    }
    md.push_str(&format!(
        "Spheres (`synth`, {}² photos, ≥{} vertices, {} spp × {} MIS pairs) under the courtyard map; \
         {}² global map, {}² local, {}² normal grid, all Haar coefficients kept; \
         the true λ and weights fixed, only the training photos' maps estimated (default options).\n\n\
         *Floor* = the TRUE map through the same transport against the same photos: what the renderer's \
         Monte-Carlo noise and the transport's discretisation leave; a fit cannot be judged below it. \
         *Fit* = the recovered maps' re-render error. Level correlation = `Σ ĥ h / sqrt(Σ ĥ² Σ h²)` of the \
         estimated and true maps' Haar detail coefficients at level m (m × m nodes), all photos and channels: \
         1 = that band's detail recovered up to scale.\n\n",
        s.width, s.vertices, s.spp, s.light_samples, s.global, s.local, s.normal_grid
    ));
    md.push_str("| scene | floor rel. RMSE (true map) | fit rel. RMSE | fit / floor | level corr. m=1 | 2 | 4 | 8 | 16 | map rel. error (block means) 2² | 4² | 8² | 32² | held-out rel. (mean map, best scale) | seconds (prepare / estimate) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    let mut rows = Vec::new();
    let mut cmp = String::from("\nThe Laplacian weight `μ = 10⁻³ × scale` for two choices of the system's scale \
        (`EstimateOptions::smoothness_scale`; `TexelMax`, the default, is used above).\n\n\
        | scene | scale | μ (photo 0, R) | fit rel. RMSE | level corr. m=4 | 8 | 16 | lighting matvecs | seconds |\n|---|---|---|---|---|---|---|---|---|\n");
    let only = std::env::var("KNOWN_SCENES").ok();
    for scene in ["sphere-diffuse", "sphere-glossy", "sphere-specular"] {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|v| v == scene))
        {
            continue;
        }
        let mut case = prepare(scene, s, 1, scene);
        if clean {
            noise_free(&mut case);
        }
        eprintln!(
            "{scene}: prepared in {:.1} + {:.1} s, {} vertices, {} observations",
            case.seconds_synth,
            case.seconds_prepare,
            case.nv,
            case.train.obs.len()
        );
        let (floor, _) = known_rel_rmse(&case, &case.train.lights);
        let mut variants = Vec::new();
        for scale in [SmoothnessScale::TexelMax, SmoothnessScale::HaarMax] {
            let opts = EstimateOptions {
                smoothness_scale: scale,
                ..EstimateOptions::default()
            };
            let t0 = Instant::now();
            let est = fit_known_reflectance(&case, &opts);
            let secs = t0.elapsed().as_secs_f64();
            let (train_rel, train_rmse) = known_rel_rmse(&case, &est.lights);
            let errs: Vec<f64> = RESOLUTIONS
                .iter()
                .map(|&r| map_error(&est.lights, &case.train.lights, s.global, r))
                .collect();
            let corr = level_correlation(&est.lights, &case.train.lights, s.global);
            cmp.push_str(&format!(
                "| {scene} | {scale:?} | {:.3e} | {train_rel:.4} | {} | {} | {secs:.1} |\n",
                est.mu[0][0],
                corr[2..]
                    .iter()
                    .take(3) // m = 4, 8, 16, the table's columns (the JSON has every level)
                    .map(|e| format!("{:.3}", e.1))
                    .collect::<Vec<_>>()
                    .join(" | "),
                est.conditioning.lighting_matvecs,
            ));
            eprintln!(
                "{scene} {scale:?}: floor {floor:.4}, fit {train_rel:.4}, level corr {corr:?}, map errors {errs:?}, {secs:.1} s"
            );
            variants.push(json!({
                "smoothness_scale": format!("{scale:?}"),
                "mu": est.mu.first(),
                "train_rel_rmse": train_rel,
                "level_correlation": corr.iter().map(|(m, r)| json!({"level": m, "correlation": r})).collect::<Vec<_>>(),
                "map_rel_error": RESOLUTIONS.iter().zip(&errs).map(|(r, e)| json!({"resolution": r, "error": e})).collect::<Vec<_>>(),
                "lighting_matvecs": est.conditioning.lighting_matvecs,
                "seconds_estimate": secs,
            }));
            if scale != EstimateOptions::default().smoothness_scale {
                continue;
            }
            // Held out: static illumination, so the mean of the fitted maps (the photos'
            // exposure differences are removed by the best global scale).
            let n2 = s.global * s.global;
            let mean: [Vec<f64>; 3] = [0, 1, 2].map(|c| {
                let mut m = vec![0.0; n2];
                for l in &est.lights {
                    for (a, b) in m.iter_mut().zip(&l[c]) {
                        *a += b / est.lights.len() as f64;
                    }
                }
                m
            });
            let held_lights = vec![mean; case.held.views.len()];
            let hp = predict_with(
                &case.held,
                case.nv,
                &case.lambda,
                &case.weights,
                &held_lights,
            );
            let (held_rel, _) = rel_rmse(&case.held.obs, &hp, true);
            md.push_str(&format!(
                "| {scene} | {floor:.4} | {train_rel:.4} | {} | {} | {} | {held_rel:.4} | {:.1} / {secs:.1} |\n",
                // Noise-free, the floor is rounding (the observations are stored in f32).
                if clean { "–".to_string() } else { format!("{:.3}", train_rel / floor) },
                corr.iter()
                    .take(5) // m = 1 … 16, the table's columns (the JSON has every level)
                    .map(|e| format!("{:.3}", e.1))
                    .collect::<Vec<_>>()
                    .join(" | "),
                [0usize, 1, 2, 4]
                    .iter()
                    .map(|&i| format!("{:.3}", errs[i]))
                    .collect::<Vec<_>>()
                    .join(" | "),
                case.seconds_synth + case.seconds_prepare,
            ));
            rows.push(json!({
                "scene": scene,
                "vertices": case.nv,
                "train_photos": case.train.views.len(),
                "train_observations": case.train.obs.len(),
                "floor_rel_rmse_true_map": floor,
                "train_rel_rmse": train_rel,
                "train_rmse": train_rmse,
                "heldout_rel_rmse_mean_map_best_scale": held_rel,
                "level_correlation": corr.iter().map(|(m, r)| json!({"level": m, "correlation": r})).collect::<Vec<_>>(),
                "map_rel_error": RESOLUTIONS.iter().zip(&errs).map(|(r, e)| json!({"resolution": r, "error": e})).collect::<Vec<_>>(),
                "mu": est.mu.first(),
                "qp_unconverged": est.conditioning.qp_unconverged,
                "lighting_matvecs": est.conditioning.lighting_matvecs,
                "seconds_estimate": secs,
                "seconds_synth": case.seconds_synth,
                "seconds_prepare": case.seconds_prepare,
            }));
        }
        rows.push(json!({"scene": scene, "smoothness_scale_comparison": variants}));
    }
    md.push_str(&cmp);
    md.push_str("\nRelative RMSE = `sqrt(Σ(y − ŷ)²) / sqrt(Σ y²)` over the observations with α > 0 and all channels. \
        Map error = `‖T_r − s E_r‖ / ‖T_r‖` over every training photo's map, `T_r`, `E_r` the true and fitted maps as `r × r` block means \
        (what a BRDF of that bandwidth sees), `s` one global least-squares scale fitted at full resolution.\n\n");
    json!(rows)
}
