//! `report.md`: the run report for people, in Markdown (the headline, the held-out
//! figures per protocol, the literature metrics, the truth check, the recovered suns of
//! `--light sky`, the model and its
//! reasons, the stages), beside `report.json` ([`super::RunReport::write`]).

use super::{metrics, RunReport};
use std::fmt::Write as _;

impl RunReport {
    /// The Markdown report.
    pub fn markdown(&self, with_maps: bool) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "# relight-cpc report\n");
        let _ = writeln!(
            s,
            "Workspace: `{}`, seed {}, relight-cpc {}.\n",
            self.workspace, self.seed, self.version
        );
        self.markdown_headline(&mut s);
        self.markdown_holdout(&mut s);
        self.markdown_truth_check(&mut s);
        if let Some(sky) = &self.model.sky {
            s.push_str(&sky.markdown());
        }
        self.markdown_training(&mut s);
        if with_maps {
            markdown_maps(&mut s);
        }
        self.markdown_model(&mut s);
        self.markdown_stages(&mut s);
        self.markdown_notes(&mut s);
        s
    }

    /// The held-out photos: the rule, each protocol's figures and the literature metrics.
    fn markdown_holdout(&self, s: &mut String) {
        let _ = writeln!(s, "## Held-out photos\n");
        if !self.holdout_rule.is_empty() {
            let _ = writeln!(s, "Held out: {}.\n", self.holdout_rule);
        }
        if self.holdout.is_empty() {
            let _ = writeln!(s, "No photo was held out.\n");
        } else {
            let _ = writeln!(
                s,
                "RMSE in linear RGB on the photo's [0, 1] scale over object pixels off its edges \
                 and not overexposed. Protocols (docs/method.md, \"Held-out evaluation\"): `truth` = the true light, `half` = light fitted \
                 on the left half of the object with the reflectance frozen, measured on the right \
                 half, `baseline` = no model: the per-vertex median of the training photos' colours \
                 times a per-channel gain fitted on the same left half, on `half`'s pixels, \
                 `mean` = the mean of the training maps. *raw* is the figure as rendered, \
                 *scaled* after the best global scale (shown).\n"
            );
            let _ = writeln!(
                s,
                "| image | protocol | RMSE raw | RMSE scaled | scale | PSNR raw (dB) | pixels |"
            );
            let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|");
            for h in &self.holdout {
                let _ = writeln!(
                    s,
                    "| {} | {} | {:.5} | {:.5} | {:.3} | {:.2} | {} |",
                    h.image, h.protocol, h.rmse, h.rmse_scaled, h.scale, h.psnr, h.pixels
                );
            }
            let _ = writeln!(s);
            self.markdown_metrics(s);
        }
    }

    /// The training fit and the error against run time.
    fn markdown_training(&self, s: &mut String) {
        let _ = writeln!(s, "## Training fit\n");
        let _ = writeln!(
            s,
            "RMSE over all training observations: **{:.5}**.\n",
            self.train_rmse
        );
        let _ = writeln!(s, "![RMSE per photo](plots/per_photo_rmse.png)\n");
        let _ = writeln!(s, "## Error against run time\n");
        let _ = writeln!(s, "![error against run time](plots/error_vs_time.png)\n");
        let _ = writeln!(s, "| seconds | objective | training RMSE | held-out RMSE |");
        let _ = writeln!(s, "|---:|---:|---:|---:|");
        for t in &self.timeline {
            let held = t
                .holdout_rmse
                .map_or("–".to_string(), |v| format!("{v:.5}"));
            let _ = writeln!(
                s,
                "| {:.2} | {:.6e} | {:.5} | {} |",
                t.seconds, t.objective, t.train_rmse, held
            );
        }
        let _ = writeln!(s);
    }

    /// The model, why it has its size, the adaptive decisions and the conditioning.
    fn markdown_model(&self, s: &mut String) {
        let _ = writeln!(s, "## Model\n");
        let m = &self.model;
        let facts: Vec<String> = m.facts().iter().map(|(l, v)| format!("{l}: {v}")).collect();
        let _ = writeln!(s, "{}.\n", facts.join("; "));
        for r in &m.reasons {
            let _ = writeln!(s, "- {r}");
        }
        let _ = writeln!(s);
        if let Some(decisions) = &m.adaptive {
            let _ = writeln!(
                s,
                "Adaptive model (`--adaptive on`; `--adaptive off` fits the full model):\n"
            );
            let _ = writeln!(s, "| what | full model | chosen | why |\n|---|---|---|---|");
            for d in decisions {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} |",
                    d.what,
                    d.full,
                    d.chosen,
                    d.reason.replace('|', "/")
                );
            }
            let _ = writeln!(s);
        }
        if !self.conditioning.is_empty() {
            let _ = writeln!(s, "Condition-number estimates of the solved systems:\n");
            for (k, v) in &self.conditioning {
                let _ = writeln!(s, "- {k}: {v:.3e}");
            }
            let _ = writeln!(s);
            if !self.conditioning_use.is_empty() {
                let _ = writeln!(s, "How the solver uses them:\n");
                for line in &self.conditioning_use {
                    let _ = writeln!(s, "- {line}");
                }
                let _ = writeln!(s);
            }
        }
    }

    /// Time and memory per stage.
    fn markdown_stages(&self, s: &mut String) {
        let _ = writeln!(s, "## Time and memory per stage\n");
        let _ = writeln!(s, "![stages](plots/stages.png)\n");
        let _ = writeln!(s, "| stage | wall s | CPU s | peak memory MiB |");
        let _ = writeln!(s, "|---|---:|---:|---:|");
        for st in &self.stage_details {
            let _ = writeln!(
                s,
                "| {} | {:.2} | {:.2} | {} |",
                st.name,
                st.seconds,
                st.cpu_seconds,
                st.peak_mib_label()
            );
        }
        let _ = writeln!(
            s,
            "\nPeak memory of the run: {:.1} MiB.\n",
            self.peak_memory_bytes as f64 / (1u64 << 20) as f64
        );
    }

    /// The run's notes.
    fn markdown_notes(&self, s: &mut String) {
        if !self.notes.is_empty() {
            let _ = writeln!(s, "## Notes\n");
            for n in &self.notes {
                let _ = writeln!(s, "- {n}");
            }
        }
    }

    /// The headline paragraph at the top of `report.md`.
    fn markdown_headline(&self, s: &mut String) {
        match &self.headline_detail {
            Some(h) => {
                let _ = writeln!(
                    s,
                    "**Headline: held-out error / baseline error = {:.3}** ({}).\n",
                    h.ratio,
                    h.explanation()
                );
                if let Some(p) = &self.half_fit_prior {
                    let _ = writeln!(s, "{}\n", p.sentence());
                }
            }
            None => {
                let _ = writeln!(
                    s,
                    "**Headline: none**: no held-out photo was scored under both `half` and \
                     `baseline`.\n"
                );
            }
        }
    }

    /// The literature metrics table.
    fn markdown_metrics(&self, s: &mut String) {
        if self.metrics.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "Literature metrics (Stanford-ORB definitions, after the per-channel scale \
             s_c = Σ y·ŷ / Σ ŷ² over the same pixels): PSNR-H on the linear images (times \
             Stanford-ORB's brightness factor, clipped at 4), PSNR-L on the sRGB images \
             (clipped to [0, 1]), SSIM on the sRGB images (11×11 Gaussian window, σ = 1.5), \
             both images zero off the scored pixels and the SSIM map averaged over them. \
             MSEs are over the object's pixels, not the whole frame as in Stanford-ORB's \
             tables.\n"
        );
        let _ = writeln!(
            s,
            "| image | protocol | PSNR-H (dB) | PSNR-L (dB) | SSIM | scale R, G, B |"
        );
        let _ = writeln!(s, "|---|---|---:|---:|---:|---|");
        for m in &self.metrics {
            let x = &m.metrics;
            let _ = writeln!(
                s,
                "| {} | {} | {:.2} | {:.2} | {:.4} | {:.3}, {:.3}, {:.3} |",
                m.image, m.protocol, x.psnr_h, x.psnr_l, x.ssim, x.scale[0], x.scale[1], x.scale[2]
            );
        }
        let _ = writeln!(s);
    }

    /// The truth check of synthetic workspaces.
    fn markdown_truth_check(&self, s: &mut String) {
        if self.truth_check.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "## Truth check: training photos under their true light\n"
        );
        let _ = writeln!(
            s,
            "The training photos (as many as five megapixels buy, spread over the training \
             list), each rendered from the fit under the light it was really taken in \
             (the workspace's `truth/`), against the same render under its fitted light; RMSE \
             in linear RGB after the best per-channel scale, over object pixels off its edges \
             and not overexposed, and relative to the photo's RMS there. A large gap means the fitted \
             maps absorbed wrong reflectance.\n"
        );
        let _ = writeln!(
            s,
            "| training photo | RMSE true light | relative | RMSE fitted light | relative | pixels |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
        for t in &self.truth_check {
            let _ = writeln!(
                s,
                "| {} | {:.5} | {:.1}% | {:.5} | {:.1}% | {} |",
                t.image,
                t.rmse_true_light,
                100.0 * t.relative_true_light,
                t.rmse_fitted_light,
                100.0 * t.relative_fitted_light,
                t.pixels
            );
        }
        let n = self.truth_check.len() as f64;
        let mean = |f: &dyn Fn(&metrics::TruthCheckEntry) -> f64| {
            self.truth_check.iter().map(f).sum::<f64>() / n
        };
        let _ = writeln!(
            s,
            "\nMean relative error: {:.1}% under the true light, {:.1}% under the fitted light.\n",
            100.0 * mean(&|t| t.relative_true_light),
            100.0 * mean(&|t| t.relative_fitted_light)
        );
        let floors: Option<Vec<f64>> = self
            .truth_check
            .iter()
            .map(|t| t.relative_true_reflectance)
            .collect();
        if let Some(fl) = floors.filter(|v| !v.is_empty()) {
            let _ = writeln!(
                s,
                "The TRUE reflectance rendered the same way under the true light: {:.1}% (the \
                 floor of this renderer and model; the fit's distance above it under the true \
                 light is reflectance the photos could still have told). The fit under the \
                 true light is {:.2}× the floor.\n",
                100.0 * fl.iter().sum::<f64>() / fl.len() as f64,
                metrics::truth_check_floor_ratio(&self.truth_check).unwrap_or(f64::NAN)
            );
        }
        self.markdown_albedo_truth(s);
    }

    /// Diffuse albedo per material against the truth (synthetic workspaces).
    fn markdown_albedo_truth(&self, s: &mut String) {
        let Some(a) = &self.albedo_truth else {
            return;
        };
        let _ = writeln!(
            s,
            "Diffuse albedo per material against the truth, after the per-channel scale \
             ×{:.4} / {:.4} / {:.4} that best matches the recovered per-vertex diffuse albedo to \
             the true one ({} vertices); largest ratio error {:.4}. The last two columns \
             compare the per-vertex diffuse albedo itself over the vertices of one true \
             material alone (true weight ≥ {}), which does not depend on how free blending \
             weights split brightness between `w` and `λ`: its mean (largest {:.4}), which \
             the vertices whose colour the photos leave open move (surfaces seen at grazing \
             angles or by no camera), and its median, the material's own albedo, with the \
             share of those vertices more than 10% off. The ratios between the materials' \
             medians, free of the scale, are the diffuse albedo ratios: largest error \
             **{:.4}**.\n",
            a.scale[0],
            a.scale[1],
            a.scale[2],
            a.vertices,
            a.max_ratio_error,
            crate::report::metrics::PURE_WEIGHT,
            a.max_pure_ratio_error,
            a.max_median_ratio_error
        );
        let _ = writeln!(
            s,
            "| material | true material (share) | recovered | scaled | true | ratio error R / G / B | pure vertices: mean albedo error R / G / B | pure vertices: median albedo error R / G / B |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
        let rgb = |v: [f64; 3]| format!("{:.4}, {:.4}, {:.4}", v[0], v[1], v[2]);
        for m in &a.materials {
            let _ = writeln!(
                s,
                "| {} | {} ({:.3}) | {} | {} | {} | {:+.4} / {:+.4} / {:+.4} | {} | {} |",
                m.material,
                m.true_material,
                m.agreement,
                rgb(m.recovered),
                rgb(m.recovered_scaled),
                rgb(m.truth),
                m.ratio_error[0],
                m.ratio_error[1],
                m.ratio_error[2],
                metrics::pure_errors(m),
                metrics::pure_median_errors(m)
            );
        }
        let _ = writeln!(s);
    }
}

/// The recovered environment maps' section (when the run drew them).
fn markdown_maps(s: &mut String) {
    let _ = writeln!(s, "## Environment maps\n");
    let _ = writeln!(
        s,
        "Lat-long, sky up (docs/conventions.md), tone-mapped with one shared exposure. Linear EXR files are in `envmaps/`.\n"
    );
    let _ = writeln!(s, "![environment maps](plots/envmaps.png)\n");
}
