//! The flags of `relight-cpc run` ([`RunArgs`]) and their translation into the library's
//! checked [`relight_cpc::run::RunOptions`]. The tests check the flags against the
//! library's defaults, `--help` and the flag tables of `docs/flags.md` and the README.

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

    /// Number of materials, or `auto`.
    #[arg(long, default_value = "auto", help_heading = "Model")]
    pub(crate) materials: String,
    /// Reflectance lobes that materials mix, comma-separated: lambert (matte), phong:N and
    /// ggx:ALPHA (shiny; larger N or smaller ALPHA is sharper).
    #[arg(
        long,
        default_value = "lambert,phong:50,phong:500",
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
    /// that applies fitted, the one that predicts held-back observations best kept; that
    /// many times the fitting time).
    #[arg(long, default_value = "paper", value_parser = ["paper", "prior", "shared", "sky", "auto"], help_heading = "Model")]
    pub(crate) light: String,
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
    #[arg(long, default_value_t = 32, help_heading = "Model")]
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
    /// largest value.
    #[arg(long, default_value_t = 1e-3, help_heading = "Solver")]
    pub(crate) smoothness: f64,
    /// Re-weighting passes per lighting fit that play down outlier pixels (1 = plain least
    /// squares).
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
    /// Where each material's starting brightness comes from: `clustered` (its colour
    /// cluster's median, the paper), `matched` (compared with the other materials at
    /// vertices of the same normal in the same photo, so shading does not darken it), or
    /// `auto` (the pilot's choice by held-out error; clustered with `--adaptive off`).
    #[arg(long, default_value = "auto", value_parser = ["auto", "clustered", "matched"], help_heading = "Solver")]
    pub(crate) start_brightness: String,
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
    /// predicts them at least 3% better (free weights with --adaptive off).
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
    /// brightness (0 = off, as the paper). For objects whose materials change smoothly
    /// (painted regions, no fine texture): 0.1 lowered the rendered scenes' held-out error
    /// under the true light by up to 7% but raised the real Buddha photos' error by 2–5%.
    #[arg(long, default_value_t = 0.0, help_heading = "Solver")]
    pub(crate) weights_smoothness: f64,
    /// Specular lobes take the light's colour: one specular weight per material shared by
    /// R, G and B, the colour in the diffuse lobe (dielectrics).
    #[arg(long, help_heading = "Solver")]
    pub(crate) achromatic_specular: bool,
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
    /// protocol on training photos says, possibly not at all), `off` (the Laplacian alone)
    /// or a fixed weight η > 0.
    #[arg(long, default_value = "auto", help_heading = "Evaluation")]
    pub(crate) half_prior: String,
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
    /// The library's [`relight_cpc::run::RunOptions`] from the flags: the workspace (the
    /// built-in example when none) and output folder, the held-out photos, world up, then
    /// the model's, the estimator's and the run's settings, then those chosen by mesh size.
    pub(crate) fn options(self) -> anyhow::Result<relight_cpc::run::RunOptions> {
        use relight_cpc::run::{builtin_example, RunOptions};
        let workspace = match &self.workspace {
            Some(w) => w.clone(),
            None => builtin_example()?,
        };
        let out = self.out.clone().unwrap_or_else(|| default_out(&workspace));
        let mut o = RunOptions::new(workspace, out);
        o.mesh = self.mesh.clone();
        o.holdout = self.holdout_choice();
        o.up = self.up_vector()?;
        self.set_model(&mut o)?;
        self.set_solver(&mut o)?;
        self.set_run(&mut o);
        self.set_mesh_size(&mut o);
        Ok(o)
    }

    /// `--holdout` (names, or `none`) before `--holdout-every`, else the workspace's default.
    fn holdout_choice(&self) -> relight_cpc::run::Holdout {
        use relight_cpc::run::Holdout;
        match (&self.holdout, self.holdout_every) {
            (Some(names), _) if names.len() == 1 && names[0] == "none" => Holdout::None,
            (Some(names), _) => Holdout::Names(names.clone()),
            (None, Some(k)) => Holdout::Every(k),
            (None, None) => Holdout::Default,
        }
    }

    /// `--up X,Y,Z`, or `None` to estimate it from the cameras.
    fn up_vector(&self) -> anyhow::Result<Option<relight_cpc::Vec3>> {
        Ok(match self.up.as_deref() {
            None => None,
            Some([x, y, z]) => Some(relight_cpc::Vec3::new(*x, *y, *z)),
            Some(v) => anyhow::bail!(
                "--up: expected X,Y,Z (three numbers), got {} values",
                v.len()
            ),
        })
    }

    /// The model: materials, basis, map and hemisphere sides, coefficient budget, shadow
    /// rays, the adaptive pilot, and which pixels and observations count.
    fn set_model(&self, o: &mut relight_cpc::run::RunOptions) -> anyhow::Result<()> {
        use relight_cpc::run::MaterialCount;
        o.materials = match self.materials.as_str() {
            "auto" => MaterialCount::Auto,
            s => MaterialCount::Fixed(s.parse().map_err(|_| {
                anyhow::anyhow!("--materials {s}: expected a whole number or `auto`")
            })?),
        };
        o.basis = relight_cpc::transport::brdf::parse_list(&self.basis)?;
        o.global_resolution = self.global_resolution;
        o.local_resolution = self.local_resolution;
        o.render_local_resolution = self.render_local_resolution;
        o.normal_grid = self.normal_grid;
        o.keep = self.keep;
        // `o` holds the library's defaults; the three settings `--large-mesh` may set
        // change only when given.
        o.blend_tolerance = self.blend_tolerance.unwrap_or(o.blend_tolerance);
        o.rays_per_texel = self.rays_per_texel;
        o.edge_rays = self.edge_rays.unwrap_or(o.edge_rays);
        o.ray_lattice = self.ray_lattice.unwrap_or(o.ray_lattice);
        o.adaptive = self.adaptive == "on";
        o.pilot_vertices = self.pilot_vertices;
        o.clip = self.clip / 255.0;
        o.transients = self.transients;
        o.edge_margin = !self.no_edge_margin;
        Ok(())
    }

    /// The estimator: the alternation's caps and stopping, the light model and its
    /// groups, the starts, the robust loss, the weights' priors and the scale anchor.
    fn set_solver(&self, o: &mut relight_cpc::run::RunOptions) -> anyhow::Result<()> {
        o.max_iterations = self.iterations;
        o.rel_tol = self.tolerance;
        o.smoothness = self.smoothness;
        o.irls_iterations = self.irls_iterations;
        o.lighting_qp_iterations = self.lighting_qp_iterations;
        o.light = relight_cpc::solve::light::choose::LightChoice::parse(&self.light)?;
        o.validation = self.validation;
        o.validation_block = self.validation_block;
        o.validation_halves = self.validation_halves;
        o.half_prior = relight_cpc::run::half_prior::HalfPriorMode::parse(&self.half_prior)?;
        o.lighting_cg_iterations = self.lighting_cg_iterations;
        o.lighting_sample = self.lighting_sample;
        o.patience = self.patience;
        o.min_iterations = self.min_iterations;
        o.ratio_steps = relight_cpc::run::RatioSteps::parse(&self.ratio_steps)?;
        o.starts = self.starts;
        o.start_search = self.start_search == "brightness";
        o.start_brightness = relight_cpc::run::StartBrightness::parse(&self.start_brightness)?;
        o.robust_floor = self.robust_floor;
        o.weights_sum = relight_cpc::run::WeightsSum::parse(&self.weights_sum)?;
        o.weights_sum_scope = match self.weights_sum_on.as_str() {
            "blends" => relight_cpc::solve::SumScope::Blends {
                floor: relight_cpc::solve::BLEND_FLOOR,
            },
            _ => relight_cpc::solve::SumScope::Every,
        };
        o.weights_smoothness = self.weights_smoothness;
        o.achromatic_specular = self.achromatic_specular;
        o.light_groups = self.light_groups.clone();
        o.light_group_minutes = self.light_group_minutes;
        o.scale_anchor = relight_cpc::solve::normalise::ScaleAnchor::parse(&self.scale_anchor)?;
        Ok(())
    }

    /// The run itself: seed, console, replacing a previous result, the training renders.
    fn set_run(&self, o: &mut relight_cpc::run::RunOptions) {
        o.seed = self.seed;
        o.progress = !self.quiet;
        o.force = self.force;
        o.render_training = !self.no_training_renders;
    }

    /// The settings chosen by mesh size ([`relight_cpc::run::LARGE_MESH`]), unless the user
    /// chose (clap refuses `--large-mesh` beside any of the three).
    fn set_mesh_size(&self, o: &mut relight_cpc::run::RunOptions) {
        let given = self.blend_tolerance.is_some()
            || self.edge_rays.is_some()
            || self.ray_lattice.is_some();
        if self.large_mesh {
            relight_cpc::run::LARGE_MESH.apply(o);
        } else {
            o.large_mesh_auto = !given && !self.no_large_mesh;
        }
    }
}

/// `out/NAME`, `NAME` the workspace folder's name (`result` when it has none).
fn default_out(workspace: &std::path::Path) -> std::path::PathBuf {
    let name = workspace
        .canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_owned()))
        .unwrap_or_else(|| "result".into());
    std::path::Path::new("out").join(name)
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
mod tests {
    use crate::{Cli, Command};
    use clap::Parser;

    /// `run`'s flags repeat most defaults as literals beside `RunOptions::new`: parsing a
    /// bare `run WS --out OUT` must give the library's defaults, but for the two the CLI
    /// sets on purpose (`--adaptive on` and the large-mesh settings by mesh size; the
    /// library's defaults are the full model and the options as given).
    #[test]
    fn bare_run_flags_give_the_library_defaults() {
        let cli = Cli::try_parse_from(["relight-cpc", "run", "ws", "--out", "o"]).unwrap();
        let Command::Run(args) = cli.command else {
            panic!("`run` parsed as another subcommand");
        };
        let got = args.options().unwrap();
        let mut want = relight_cpc::run::RunOptions::new("ws".into(), "o".into());
        assert!(!want.adaptive, "the library's default is the full model");
        want.adaptive = true;
        assert!(
            !want.large_mesh_auto,
            "the library's default is the options as given"
        );
        want.large_mesh_auto = true;
        // Debug prints every field, floats to the last bit, so this is exact equality.
        assert_eq!(format!("{got:?}"), format!("{want:?}"));
    }

    /// `--large-mesh` means exactly the three flags its help names and refuses to be
    /// combined with any of them (the user would not know which value won); without it
    /// the run chooses by mesh size unless one of them or `--no-large-mesh` is given.
    #[test]
    fn large_mesh_means_the_flags_its_help_names() {
        use clap::CommandFactory;
        let cli = Cli::command();
        let run = cli.find_subcommand("run").unwrap();
        let help = run
            .get_arguments()
            .find(|a| a.get_long() == Some("large-mesh"))
            .and_then(|a| a.get_help())
            .unwrap()
            .to_string();
        // The help lists the flags after "and more:" up to the parenthesis.
        let named = help
            .split("more: ")
            .nth(1)
            .unwrap()
            .split(" (")
            .next()
            .unwrap();
        let flags: Vec<&str> = named.split_whitespace().collect();
        assert_eq!(flags.len(), 6, "three flags with values in {help:?}");
        let parse = |extra: &[&str]| {
            let base = ["relight-cpc", "run", "ws", "--out", "o"];
            Cli::try_parse_from(base.iter().chain(extra).copied())
        };
        let options = |extra: &[&str]| {
            let Command::Run(args) = parse(extra).unwrap().command else {
                panic!("`run` parsed as another subcommand");
            };
            args.options().unwrap()
        };
        let on = options(&["--large-mesh"]);
        assert_eq!(format!("{on:?}"), format!("{:?}", options(&flags)));
        assert!(!on.large_mesh_auto);
        let bare = options(&[]);
        assert!(bare.large_mesh_auto, "chosen by mesh size by default");
        assert!(!relight_cpc::run::LARGE_MESH.in_effect(&bare));
        let mut off = options(&["--no-large-mesh"]);
        assert!(!off.large_mesh_auto);
        off.large_mesh_auto = true;
        assert_eq!(
            format!("{off:?}"),
            format!("{bare:?}"),
            "nothing else changes"
        );
        let conflict = |extra: &[&str]| {
            let err = parse(extra).err().expect("a conflict");
            assert_eq!(
                err.kind(),
                clap::error::ErrorKind::ArgumentConflict,
                "{extra:?}"
            );
        };
        conflict(&["--large-mesh", "--no-large-mesh"]);
        // The lighting step cap is every run's choice, not one of the settings.
        assert!(options(&["--lighting-qp-iterations", "5"]).large_mesh_auto);
        for pair in flags.chunks(2) {
            conflict(&["--large-mesh", pair[0], pair[1]]);
            assert!(
                !options(pair).large_mesh_auto,
                "{pair:?} is the user's choice"
            );
        }
    }

    /// `run --help` groups its flags under the six headings, in plain words: none of the
    /// solver's jargon appears, and every flag with a default shows it.
    #[test]
    fn run_help_is_grouped_and_plain() {
        use clap::CommandFactory;
        let mut cli = Cli::command();
        let run = cli.find_subcommand_mut("run").unwrap();
        let help = run.render_long_help().to_string();
        for h in [
            "Input",
            "Model",
            "Solver",
            "Evaluation",
            "Output",
            "Performance",
        ] {
            assert!(help.contains(&format!("{h}:")), "no heading {h}:\n{help}");
        }
        for jargon in ["GPCG", "KKT", "IRLS", "MAD", "QP"] {
            let words = help.split(|c: char| !c.is_ascii_alphanumeric());
            assert!(!words.into_iter().any(|w| w == jargon), "{jargon} in help");
        }
        for arg in run.get_arguments() {
            // Switches (--force, ...) have the default `false`, which clap does not show.
            let switch = !arg.get_action().takes_values();
            if arg.get_default_values().len() == 1 && !arg.is_hide_default_value_set() && !switch {
                let d = arg.get_default_values()[0].to_string_lossy().into_owned();
                assert!(
                    help.contains(&format!("[default: {d}]")),
                    "--{:?}",
                    arg.get_long()
                );
            }
        }
    }

    /// The flags a flag table names (`| \`--a N\`, \`--b T\` | 8, 1e-3 | ...`), each with
    /// its stated default: a row's flags and its defaults pair up in order.
    fn flag_rows(text: &str) -> Vec<(String, Vec<String>)> {
        let mut rows = Vec::new();
        for row in text.lines().filter(|l| l.starts_with("| `--")) {
            let cells: Vec<&str> = row.split(" | ").collect();
            let flags: Vec<String> = cells[0]
                .split("`--")
                .skip(1)
                .map(|f| f.split([' ', '`']).next().unwrap().to_string())
                .collect();
            let values: Vec<String> = cells[1]
                .split(", ")
                .map(|v| v.trim_matches('`').to_string())
                .collect();
            for (i, flag) in flags.iter().enumerate() {
                let value = (values.len() == flags.len()).then(|| values[i].clone());
                rows.push((flag.clone(), value.into_iter().collect()));
            }
        }
        rows
    }

    /// Checks every row of a flag table against clap: the flag exists in `run`, and where
    /// clap applies a default the row states it. Returns the flags named.
    fn check_flag_table(doc: &str, text: &str) -> std::collections::BTreeSet<String> {
        use clap::CommandFactory;
        let cli = Cli::command();
        let run = cli.find_subcommand("run").unwrap();
        let same = |doc: &str, clap: &str| match (doc.parse::<f64>(), clap.parse::<f64>()) {
            (Ok(a), Ok(b)) => a == b,
            _ => doc == clap,
        };
        let mut named = std::collections::BTreeSet::new();
        for (flag, value) in flag_rows(text) {
            let arg = run
                .get_arguments()
                .find(|a| a.get_long() == Some(flag.as_str()))
                .unwrap_or_else(|| panic!("{doc} names --{flag}, which `run` does not have"));
            let d = arg.get_default_values();
            if d.len() == 1 {
                let clap = d[0].to_string_lossy();
                let value = value.first().unwrap_or_else(|| {
                    panic!("{doc}: the row of --{flag} does not pair flags with defaults")
                });
                assert!(
                    same(value, &clap),
                    "{doc} gives --{flag} the default `{value}`, clap `{clap}`"
                );
            }
            named.insert(flag);
        }
        named
    }

    /// docs/flags.md names every flag of `run` and states each default clap applies; the
    /// README's shorter table states the same defaults for the flags it names.
    #[test]
    fn flag_tables_state_the_cli_defaults() {
        use clap::CommandFactory;
        let cli = Cli::command();
        let run = cli.find_subcommand("run").unwrap();
        let all: std::collections::BTreeSet<String> = run
            .get_arguments()
            .filter_map(|a| a.get_long())
            .filter(|l| *l != "help")
            .map(str::to_string)
            .collect();
        let documented = check_flag_table("docs/flags.md", include_str!("../../docs/flags.md"));
        let missing: Vec<_> = all.difference(&documented).collect();
        assert!(missing.is_empty(), "docs/flags.md lacks {missing:?}");
        let readme = check_flag_table("README.md", include_str!("../../README.md"));
        // The README keeps a short table of the flags a user tunes first; fewer than 8
        // means its table was lost or mangled (it has 12 today).
        assert!(readme.len() >= 8, "README names only {readme:?}");
    }
}
