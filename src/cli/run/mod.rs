//! The flags of `relight-cpc run` ([`RunArgs`]) and their translation into the library's
//! checked [`relight_cpc::run::RunOptions`] (`options.rs`). The tests check the flags against the
//! library's defaults, `--help` and the flag tables of `docs/flags.md` and the README.

mod options;

/// Flags of `run` (the README explains each default), grouped under headings in `--help`.
#[derive(clap::Args)]
pub(crate) struct RunArgs {
    /// The COLMAP workspace folder (default: the built-in example).
    #[arg(help_heading = "Input")]
    pub(crate) workspace: Option<std::path::PathBuf>,
    /// Use this mesh (PLY) instead of the one found in the workspace.
    #[arg(long, help_heading = "Input")]
    pub(crate) mesh: Option<std::path::PathBuf>,
    /// World up as X,Y,Z (default: estimated from the cameras).
    #[arg(
        long,
        value_delimiter = ',',
        allow_negative_numbers = true,
        help_heading = "Input"
    )]
    pub(crate) up: Option<Vec<f64>>,
    /// Pixels with any channel at or above this value (0-255) count as overexposed and are
    /// ignored.
    #[arg(long, default_value_t = 250.0, help_heading = "Input")]
    pub(crate) clip: f32,
    /// What an overexposed pixel tells the fit: `drop` (nothing, the paper), `bound` (its
    /// clipped channels are lower bounds of the radiance, its other channels values; every
    /// light model reads them), or `auto` (`bound` when
    /// a fifth or more of the training observations have a clipped channel).
    #[arg(long, default_value = "auto", value_parser = ["auto", "drop", "bound"], help_heading = "Input")]
    pub(crate) clipped: String,

    /// Number of materials, or `auto`.
    #[arg(long, default_value = "auto", help_heading = "Model")]
    pub(crate) materials: String,
    /// Reflectance lobes that materials mix, comma-separated: lambert (matte), phong:N and
    /// ggx:ALPHA (shiny; larger N or smaller ALPHA is sharper).
    #[arg(
        long,
        default_value = "lambert,phong:50,phong:500,ggx:0.3",
        help_heading = "Model"
    )]
    pub(crate) basis: String,
    /// `on`: a short trial fit decides what the scene needs (number of materials; lobes
    /// that carry under 1% of the light or barely change the held-out error are dropped;
    /// map detail from the sharpest lobe kept; duplicate photos skipped; the sizes given
    /// are upper bounds). `off`: the model exactly as given.
    #[arg(long, default_value = "on", value_parser = ["on", "off"], help_heading = "Model")]
    pub(crate) adaptive: String,
    /// Most seen surface points the adaptive trial fit reads (0 = every one, else at least
    /// 100): on a larger mesh it fits a seeded sample of about this many, which keeps its
    /// time and memory flat (at 100K points every choice and figure stayed the same in
    /// under a third of its time).
    #[arg(long, value_name = "N", default_value_t = relight_cpc::solve::adapt::PILOT_MAX_VERTICES, help_heading = "Model")]
    pub(crate) pilot_vertices: usize,
    /// Model of each photo's light: `paper` (a free non-negative map, the paper's),
    /// `prior` (the same map kept close to what real skies look like, learnt from real HDR
    /// maps), `shared` (one map per group of photos under one sky, per-photo gains), `sky`
    /// (an outdoor sun and sky per photo plus a penalised residual map), `auto` (every model
    /// that applies fitted, the one that best predicts the right halves of a few training
    /// photos held back whole kept and fitted again; that many times the fitting time,
    /// plus one), `constrained` (as `auto` without the paper's map, so one fit fewer).
    /// Default, below 50,000 vertices: `auto` when the fit keeps a shiny lobe
    /// (`constrained` with three or more materials and at least 20 training photos);
    /// `prior` over the Lambertian lobe alone with two or more materials and at least 20
    /// training photos; else `paper`.
    #[arg(long, value_parser = ["paper", "prior", "shared", "sky", "auto", "constrained"], help_heading = "Model")]
    pub(crate) light: Option<String>,
    /// Find people, cars and other things in front of the object in some photos (where a
    /// short trial fit disagrees with a photo over a patch of the surface), leave them out
    /// of the fit and draw them in outliers/*.png (two short trial fits more).
    #[arg(long, help_heading = "Model")]
    pub(crate) transients: bool,
    /// Let pixels within a few pixels of the object's outline or of a depth edge count
    /// fully (by default they count less: a small misregistration mixes the background in).
    #[arg(long, help_heading = "Model")]
    pub(crate) no_edge_margin: bool,
    /// Photos under one sky for `--light shared` (one map per group, per-photo exposure
    /// and white-balance gains): a text file of lines `<photo name> <group label>`.
    /// Without it, photos taken within --light-group-minutes of each other (EXIF time).
    #[arg(long, value_name = "FILE", help_heading = "Model")]
    pub(crate) light_groups: Option<std::path::PathBuf>,
    /// Photos whose EXIF capture times are at most this many minutes apart share a sky
    /// under `--light shared` (0 = never by time).
    #[arg(long, default_value_t = relight_cpc::run::DEFAULT_LIGHT_GROUP_MINUTES, help_heading = "Model")]
    pub(crate) light_group_minutes: f64,
    /// Under `--light sky`, search every photo's sun even where its EXIF gives the place
    /// (GPS) and UTC time of capture (by default those fix its sun, up to one north for
    /// the whole collection).
    #[arg(long, help_heading = "Model")]
    pub(crate) no_geotag_suns: bool,
    /// Under `--light auto` and `--loss auto`, score the candidate light models and losses
    /// on the right halves of this many training photos held back whole, then fit the one
    /// kept again with the run's own early stopping; 0 = score the light models on early
    /// stopping's held-back observations (and keep the robust loss).
    #[arg(long, default_value_t = relight_cpc::run::DEFAULT_LIGHT_CHOICE_HALVES, help_heading = "Model")]
    pub(crate) light_choice_halves: usize,
    /// What fixes the per-channel scale between colours and light, which photos can never
    /// tell apart: `start` (the balance of the starting colours) or `grey-world` (the
    /// surface's mean diffuse albedo is 0.5 in each channel).
    #[arg(long, default_value = "start", value_parser = ["start", "grey-world"], help_heading = "Model")]
    pub(crate) scale_anchor: String,
    /// Detail of each photo's recovered lighting: map side in texels, a power of two.
    #[arg(long, default_value_t = 64, help_heading = "Model")]
    pub(crate) global_resolution: usize,
    /// Detail of the per-vertex hemisphere (shadowing and reflection), a power of two; an
    /// upper bound when adaptive (the pilot takes half the global map's side, at least 16).
    #[arg(long, default_value_t = 32, help_heading = "Model")]
    pub(crate) local_resolution: usize,
    /// Hemisphere detail for the renders of held-out and training views, a power of two
    /// (default: --local-resolution; 64 draws sharp highlights more faithfully, at twice
    /// the shadowing and rendering cost).
    #[arg(long, help_heading = "Model")]
    pub(crate) render_local_resolution: Option<usize>,
    /// Number of surface directions (per side, a power of two) the light is pre-rotated
    /// to; vertices blend the nearest ones.
    #[arg(
        long,
        default_value_t = relight_cpc::run::RunOptions::DEFAULT_NORMAL_GRID,
        help_heading = "Model"
    )]
    pub(crate) normal_grid: usize,
    /// Light-transport terms kept per observation (0 = all): fewer is faster and coarser.
    #[arg(long, default_value_t = 128, help_heading = "Model")]
    pub(crate) keep: usize,
    /// Fraction of each blended lighting row's energy (an observation's transport rows
    /// summed with its material weights) its smallest entries may carry and be dropped;
    /// 0 = the exact blend. Default 0.001 (0.01 with --large-mesh or from 50K vertices).
    #[arg(long, value_name = "FRACTION", help_heading = "Model")]
    pub(crate) blend_tolerance: Option<f64>,
    /// Shadow rays per hemisphere texel, when --edge-rays is 0.
    #[arg(long, default_value_t = 2, help_heading = "Model")]
    pub(crate) rays_per_texel: usize,
    /// Shadow rays: one per hemisphere texel, then this many more where the shadow has an edge; 0 = --rays-per-texel everywhere. Default 4 (3 with --large-mesh or from 50K vertices).
    #[arg(long, value_name = "N", help_heading = "Model")]
    pub(crate) edge_rays: Option<usize>,
    /// Shadow rays: the first ray of every texel (1), or of every other texel in each direction (2), the texels between traced only where their traced neighbours disagree. Default 1 (2 with --large-mesh or from 50K vertices).
    #[arg(long, value_name = "N", help_heading = "Model")]
    pub(crate) ray_lattice: Option<usize>,

    /// Rounds of (fit the lighting, then fit the materials), at most.
    #[arg(
        long,
        default_value_t = relight_cpc::run::RunOptions::DEFAULT_MAX_ITERATIONS,
        help_heading = "Solver"
    )]
    pub(crate) iterations: usize,
    /// Stop when a round improves the fit by less than this fraction.
    #[arg(
        long,
        default_value_t = relight_cpc::run::RunOptions::DEFAULT_REL_TOL,
        help_heading = "Solver"
    )]
    pub(crate) tolerance: f64,
    /// How strongly the recovered lighting is smoothed, as a fraction of the system's
    /// largest value. `auto`: 1e-3, and 16 times that for the adaptive pilot from 20
    /// training photos, and for the fit when it keeps a shiny lobe, has two materials and
    /// 20 training photos or more on 32² maps (the weight is relative to the photos, and on
    /// a finer map the same number smooths less).
    #[arg(long, default_value = "auto", help_heading = "Solver")]
    pub(crate) smoothness: String,
    /// How strongly the recovered lighting's colour is smoothed over directions, relative
    /// to `--smoothness` (0 = off): white balance and exposure stay free, colour that
    /// changes with direction is penalised.
    #[arg(long, default_value_t = 0.0, help_heading = "Solver")]
    pub(crate) chroma_smoothness: f64,
    /// How pixels the model does not explain count: `robust` (outlier pixels played down,
    /// Huber), `plain` (least squares, as the paper), or `auto` (both fitted below 50K
    /// vertices, each scored on held-back halves of a few training photos, the better
    /// kept; `robust` from 50K vertices on).
    #[arg(long, default_value = "auto", value_parser = ["auto", "robust", "plain"], help_heading = "Solver")]
    pub(crate) loss: String,
    /// Re-weighting passes per lighting fit of the robust loss that play down outlier
    /// pixels (1 = plain least squares, whatever --loss says).
    #[arg(long, default_value_t = 3, value_name = "N", help_heading = "Solver")]
    pub(crate) irls_iterations: usize,
    /// Solver steps per lighting fit inside each round (each continues from the last);
    /// 0 = solve each lighting fit to convergence.
    #[arg(
        long,
        default_value_t = relight_cpc::run::RunOptions::default_lighting_qp_iterations(),
        value_name = "N",
        help_heading = "Solver"
    )]
    pub(crate) lighting_qp_iterations: usize,
    /// Inner linear-solver steps per lighting solver step (0 = the solver's own limit).
    #[arg(
        long,
        default_value_t = relight_cpc::run::RunOptions::default_lighting_cg_iterations(),
        value_name = "N",
        help_heading = "Solver"
    )]
    pub(crate) lighting_cg_iterations: usize,
    /// Stop after this many rounds without a better score on the held-back observations.
    #[arg(
        long,
        default_value_t = relight_cpc::run::RunOptions::DEFAULT_PATIENCE,
        help_heading = "Solver"
    )]
    pub(crate) patience: usize,
    /// Never stop for the patience before this round (the best round is still kept).
    #[arg(
        long,
        default_value_t = relight_cpc::solve::options::MIN_ITERATIONS,
        value_name = "N",
        help_heading = "Solver"
    )]
    pub(crate) min_iterations: usize,
    /// The first N rounds move each material's brightness per channel along the valley
    /// the free maps leave, with the lights re-solved (two more lighting steps a round);
    /// 0 = off, the paper's alternation; auto = 8 rounds from 9 training photos on with
    /// up to 4 materials, else off.
    #[arg(
        long,
        default_value = "auto",
        value_name = "auto|N",
        help_heading = "Solver"
    )]
    pub(crate) ratio_steps: String,
    /// The first N rounds move every material's lobes at once by a Gauss-Newton step with
    /// the lights re-solved (K x lobes + 2 more lighting steps a round); 0 = off; auto = 8
    /// rounds, the Jacobian updated by Broyden's secant after the first (2 more lighting
    /// steps a round), for two or more materials over the Lambertian lobe alone where the
    /// ratio step runs, else off.
    #[arg(
        long,
        default_value = "auto",
        value_name = "auto|N",
        help_heading = "Solver"
    )]
    pub(crate) varpro_steps: String,
    /// Starting points to try, the best kept: 1 = materials from colour clusters; 2 adds
    /// every shiny lobe at 0.3 × the matte weight, then one lobe per material in turn.
    /// Each costs one fit.
    #[arg(long, default_value_t = 1, help_heading = "Solver")]
    pub(crate) starts: usize,
    /// `brightness`: also fit from starts with each material but the first ½ or 2 × as
    /// bright (every combination up to 3 materials, one at a time above) and keep the fit
    /// closest to the training photos. Costs 2 fits with 2 materials, 8 with 3.
    #[arg(long, default_value = "off", value_parser = ["off", "brightness"], help_heading = "Solver")]
    pub(crate) start_search: String,
    /// `on`: after the fit, with 2 or more materials, fit again from its own materials
    /// re-anchored (each material the median fitted reflectance of the vertices it
    /// dominates, each vertex's weights projected on them) and keep the fit that predicts
    /// held-back observations better. `irradiance`: the second fit from the fit's weights
    /// with each material's Lambertian colour ratios fitted by a low-order irradiance model
    /// over the vertices one material holds that see most of the sky (Lambertian
    /// materials). `coarse-light`: the ratios fitted with each photo's light a coarse
    /// non-negative map seen through the vertices' shadows, over every seen vertex with
    /// the fit's blend of the materials, and the lights fitted again with those materials
    /// held, over the fit's
    /// weights and over them re-sorted; with a shiny lobe, each tied to its material's
    /// diffuse one by the fit's ratio, one held fit over the fit's weights re-sorted on the
    /// model's materials. `on+coarse-light`: `on`, then `coarse-light` from the fit kept.
    /// `auto`: `coarse-light` when the fit's basis is the Lambertian lobe alone, else none.
    /// One more fit each (`coarse-light` over Lambert alone: two).
    #[arg(long, default_value = "auto", value_parser = ["auto", "off", "on", "irradiance", "coarse-light", "on+coarse-light"], help_heading = "Solver")]
    pub(crate) restart: String,
    /// Where each material's starting brightness comes from: `clustered` (its colour
    /// cluster's median, the paper), `matched` (compared with the other materials at
    /// vertices of the same normal in the same photo, so shading does not darken it), or
    /// `auto` (the pilot's choice by held-out error; clustered with `--adaptive off`).
    #[arg(long, default_value = "auto", value_parser = ["auto", "clustered", "matched"], help_heading = "Solver")]
    pub(crate) start_brightness: String,
    /// Where the start's blending weights come from: `clustered` (from each vertex's hue
    /// distance to the colour clusters, the paper), `unmixed` (each vertex's mean colour
    /// split into the materials' colours by non-negative least squares, so a vertex where
    /// two materials blend starts blended), or `both` (a fit from each, the one that
    /// predicts held-back observations better kept; one more fit).
    #[arg(long, default_value = "clustered", value_parser = ["clustered", "unmixed", "both"], help_heading = "Solver")]
    pub(crate) start_weights: String,
    /// Outlier threshold floor, as a fraction of each photo's mean brightness: a residual
    /// within 1.345 × this is never played down (0 = from the residuals' spread alone).
    #[arg(
        long,
        default_value_t = relight_cpc::solve::ROBUST_FLOOR,
        help_heading = "Solver"
    )]
    pub(crate) robust_floor: f64,
    /// Prior that each surface point's material weights sum to one, as a multiple of what
    /// its photos charge for a change of its brightness (0 = off: free weights, as the
    /// paper). Keeps shading that all photos share out of the materials' colours. `auto`:
    /// the adaptive pilot fits both and keeps the prior where it predicts held-back
    /// observations at least 13% better, else the prior where materials blend when that
    /// predicts them better (free weights with --adaptive off).
    #[arg(long, default_value = "auto", help_heading = "Solver")]
    pub(crate) weights_sum: String,
    /// Where a given --weights-sum applies: every surface point, or only where materials
    /// blend (pure points keep a fifth of it, so a real object's texture stays free while
    /// the brightness ratio between materials is tied). With --weights-sum auto the pilot
    /// tries both.
    #[arg(long, default_value = "every", value_parser = ["every", "blends"], help_heading = "Solver")]
    pub(crate) weights_sum_on: String,
    /// Prior pulling each surface point's material weights toward its 8 nearest
    /// neighbours' mean, as a multiple of what its photos charge for a change of its
    /// brightness (0 = off, as the paper). `auto`: 0.1 when the trial fit keeps a shiny
    /// lobe (a point's shine shows in few photos, so its neighbours' weights help: glossy
    /// rendered scenes' material accuracy 0.97 → 0.98), else off (Lambert only: every
    /// photo constrains the weights; 0.1 raised the real Buddha photos' error by 3–5%)
    #[arg(long, default_value = "auto", help_heading = "Solver")]
    pub(crate) weights_smoothness: String,
    /// How readily each surface point drops materials it does not need, as a multiple of
    /// the Bayesian information criterion's penalty (0 = off: every material that lowers
    /// the point's error at all stays, as the paper). Without it a point of one material
    /// keeps a few percent of another wherever that fits the photos' noise. `auto`: 1 for
    /// two or more materials when the fit keeps a shiny lobe and has 20 training photos or
    /// more, else off.
    #[arg(long, default_value = "auto", help_heading = "Solver")]
    pub(crate) weights_bic: String,
    /// Specular lobes take the light's colour: one specular weight per material shared by
    /// R, G and B, the colour in the diffuse lobe (dielectrics: stone, paint, plastic,
    /// glaze). `off` gives each channel its own (coloured metals). `auto`: on in the fit
    /// when it keeps a shiny lobe and has three or more materials.
    #[arg(long, default_value = "auto", value_parser = ["auto", "on", "off"], help_heading = "Solver")]
    pub(crate) achromatic_specular: String,
    /// Fraction of the training observations held back to stop at the best round; 0 turns
    /// early stopping off.
    #[arg(long, default_value_t = 0.1, help_heading = "Solver")]
    pub(crate) validation: f64,
    /// Hold back whole blocks of this many consecutive mesh vertices (all their
    /// observations, their weights refitted after stopping) instead of single observations;
    /// 0 = single observations.
    #[arg(long, default_value_t = 0, help_heading = "Solver")]
    pub(crate) validation_block: usize,
    /// Hold back the right half of the object (as the `half` protocol splits it) in this
    /// many training photos, spread over the list, instead of random observations; 0 = off.
    #[arg(long, default_value_t = 0, help_heading = "Solver")]
    pub(crate) validation_halves: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1, help_heading = "Solver")]
    pub(crate) seed: u64,

    /// Light prior of the held-out `half` protocol's fit: `auto` (the training photos'
    /// maps as a prior on the new photo's low-order light, weighted as replaying the
    /// protocol on training photos says; without it the light model's own prior, if any),
    /// `off` (the Laplacian alone), `model` (the light model's own prior, `--light
    /// prior`'s, at 0.2× its noise levels) or a fixed weight η > 0 of the training maps'
    /// prior.
    #[arg(long, default_value = "auto", help_heading = "Evaluation")]
    pub(crate) half_prior: String,
    /// Laplacian weight of the held-out `half` protocol's light fit: `fit` (the training
    /// fit's own, as `--smoothness` chose it) or a fixed weight > 0.
    #[arg(long, default_value = "fit", help_heading = "Evaluation")]
    pub(crate) half_smoothness: String,
    /// Hold out these photos (image names, comma-separated) to score the result; `none`
    /// holds out nothing. Default: the workspace's truth/manifest.json list, else every 5th
    /// photo (at least one).
    #[arg(
        long,
        value_delimiter = ',',
        conflicts_with = "holdout_every",
        help_heading = "Evaluation"
    )]
    pub(crate) holdout: Option<Vec<String>>,
    /// Hold out every N-th photo in name order.
    #[arg(long, help_heading = "Evaluation")]
    pub(crate) holdout_every: Option<usize>,
    /// Skip the renders of the training views.
    #[arg(long, help_heading = "Evaluation")]
    pub(crate) no_training_renders: bool,

    /// Output folder (default: out/NAME, NAME = the workspace's folder name).
    #[arg(long, help_heading = "Output")]
    pub(crate) out: Option<std::path::PathBuf>,
    /// Replace a previous result in the output folder (never anything else).
    #[arg(long, help_heading = "Output")]
    pub(crate) force: bool,
    /// Print only warnings, errors and the final one-line summary.
    #[arg(long, help_heading = "Output")]
    pub(crate) quiet: bool,

    /// At most this many observations per photo in its lighting step, a stratified sample
    /// (by normal, open sky and material, weighted to keep the sums' expected value);
    /// 0 = every observation.
    #[arg(
        long,
        default_value_t = relight_cpc::run::DEFAULT_LIGHTING_SAMPLE,
        help_heading = "Performance"
    )]
    pub(crate) lighting_sample: usize,
    /// Worker threads (default: all cores).
    #[arg(long, help_heading = "Performance")]
    pub(crate) threads: Option<usize>,
    /// Faster settings for meshes of 50K vertices and more: --blend-tolerance 0.01
    /// --edge-rays 3 --ray-lattice 2 (at 100K vertices 9% less time at the same held-out
    /// error; on small meshes they cost accuracy). Without this flag the run uses them by
    /// itself from 50K vertices, unless one of the three or --no-large-mesh is given.
    #[arg(
        long,
        conflicts_with_all = ["blend_tolerance", "edge_rays", "ray_lattice", "no_large_mesh"],
        help_heading = "Performance"
    )]
    pub(crate) large_mesh: bool,
    /// The full settings on any mesh: never the --large-mesh ones by themselves.
    #[arg(long, help_heading = "Performance")]
    pub(crate) no_large_mesh: bool,
}

impl RunArgs {
    /// Runs the fit on the workspace; one summary line (and with `--quiet` off, the
    /// held-out figures) on stdout.
    pub(crate) fn execute(self) -> anyhow::Result<()> {
        set_threads(self.threads)?;
        let quiet = self.quiet;
        let opts = self.options()?;
        let summary = relight_cpc::run::run(&opts)?;
        let r = &summary.report;
        let held = if r.holdout.is_empty() {
            "no held-out photo".to_string()
        } else {
            let mean =
                r.holdout.iter().map(|h| h.rmse_scaled).sum::<f64>() / r.holdout.len() as f64;
            format!(
                "held-out RMSE {mean:.5} (scaled, mean of {})",
                r.holdout.len()
            )
        };
        println!(
            "training RMSE {:.5}, {held}; report.html, report.md and report.json in {}",
            r.train_rmse,
            summary.out.display()
        );
        if !quiet {
            for h in &r.holdout {
                println!(
                    "held out {} ({}): RMSE {:.5} raw, {:.5} after scale {:.3}",
                    h.image, h.protocol, h.rmse, h.rmse_scaled, h.scale
                );
            }
            if let Some(h) = &r.headline_detail {
                println!(
                    "headline: held-out error / baseline error = {:.3} (half {:.5}, baseline {:.5}, {} photo(s))",
                    h.ratio, h.method_rmse, h.baseline_rmse, h.photos
                );
            }
        }
        Ok(())
    }
}

/// Size rayon's global pool (once, before any parallel work).
fn set_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(n) = threads {
        if n == 0 {
            anyhow::bail!("--threads 0: at least one thread is needed");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
