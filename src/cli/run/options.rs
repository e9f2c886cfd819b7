//! The flags' translation into the library's checked [`relight_cpc::run::RunOptions`]:
//! the workspace and output folder, the held-out photos, world up, then the model's, the
//! estimator's and the run's settings, then those chosen by mesh size.

use super::RunArgs;

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
        o.clipped = relight_cpc::run::Clipped::parse(&self.clipped)?;
        o.transients = self.transients;
        o.edge_margin = !self.no_edge_margin;
        Ok(())
    }

    /// The estimator: the alternation's caps and stopping, the light model and its
    /// groups, the starts, the robust loss, the weights' priors and the scale anchor.
    fn set_solver(&self, o: &mut relight_cpc::run::RunOptions) -> anyhow::Result<()> {
        o.max_iterations = self.iterations;
        o.rel_tol = self.tolerance;
        o.smoothness =
            relight_cpc::run::PriorStrength::parse(&self.smoothness, "--smoothness", "off")?;
        if !(self.chroma_smoothness.is_finite() && self.chroma_smoothness >= 0.0) {
            anyhow::bail!(
                "--chroma-smoothness {}: expected a number ≥ 0 (0 = off)",
                self.chroma_smoothness
            );
        }
        o.chroma_smoothness = self.chroma_smoothness;
        o.irls_iterations = self.irls_iterations;
        o.loss = relight_cpc::solve::loss_choice::LossChoice::parse(&self.loss)?;
        o.lighting_qp_iterations = self.lighting_qp_iterations;
        match &self.light {
            Some(l) => o.light = relight_cpc::solve::light::choose::LightChoice::parse(l)?,
            None => o.light_by_scene = true,
        }
        o.validation = self.validation;
        o.validation_block = self.validation_block;
        o.validation_halves = self.validation_halves;
        o.half_prior = relight_cpc::run::half_prior::HalfPriorMode::parse(&self.half_prior)?;
        o.half_smoothness =
            relight_cpc::run::half_prior::HalfSmoothnessMode::parse(&self.half_smoothness)?;
        o.lighting_cg_iterations = self.lighting_cg_iterations;
        o.lighting_sample = self.lighting_sample;
        o.patience = self.patience;
        o.min_iterations = self.min_iterations;
        o.ratio_steps = relight_cpc::run::RatioSteps::parse(&self.ratio_steps)?;
        o.varpro_steps = relight_cpc::run::VarproSteps::parse(&self.varpro_steps)?;
        o.starts = self.starts;
        o.start_search = self.start_search == "brightness";
        o.restart = relight_cpc::run::Restart::parse(&self.restart)?;
        o.start_brightness = relight_cpc::run::StartBrightness::parse(&self.start_brightness)?;
        o.start_weights = relight_cpc::solve::cluster::StartWeights::parse(&self.start_weights)?;
        o.robust_floor = self.robust_floor;
        o.weights_sum = relight_cpc::run::WeightsSum::parse(
            &self.weights_sum,
            "--weights-sum",
            "free weights",
        )?;
        o.weights_sum_scope = match self.weights_sum_on.as_str() {
            "blends" => relight_cpc::solve::SumScope::Blends {
                floor: relight_cpc::solve::BLEND_FLOOR,
            },
            _ => relight_cpc::solve::SumScope::Every,
        };
        o.weights_smoothness = relight_cpc::run::WeightsSmoothness::parse(
            &self.weights_smoothness,
            "--weights-smoothness",
            "off",
        )?;
        o.weights_bic =
            relight_cpc::run::PriorStrength::parse(&self.weights_bic, "--weights-bic", "off")?;
        o.achromatic_specular = relight_cpc::run::Achromatic::parse(&self.achromatic_specular)?;
        o.light_groups = self.light_groups.clone();
        o.light_group_minutes = self.light_group_minutes;
        o.geotag_suns = !self.no_geotag_suns;
        o.light_choice_halves = self.light_choice_halves;
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
