//! `relight-cpc bench`: the whole pipeline timed on synthetic scenes
//! ([`relight_cpc::bench::bench`]).

/// The flags of `bench` (the subcommand's own help is on [`super::Command::Bench`]).
#[derive(clap::Args)]
pub(crate) struct BenchArgs {
    /// Minimum vertex counts of the vertex-scaling runs.
    /// [default: 10000,100000,400000; --quick: 2000,8000,32000]
    #[arg(long, value_delimiter = ',')]
    sizes: Option<Vec<usize>>,
    /// Photo counts of the photo-scaling runs.
    /// [default: 6,13,30; --quick: 4,8,16]
    #[arg(long, value_delimiter = ',')]
    photos: Option<Vec<usize>>,
    /// Photos of the vertex-scaling runs.
    /// [default: 13; --quick: 6]
    #[arg(long)]
    base_photos: Option<usize>,
    /// Minimum vertices of the photo-scaling runs.
    /// [default: 100000; --quick: 8000]
    #[arg(long)]
    base_vertices: Option<usize>,
    /// The synth scene.
    /// [default: spot-varying; --quick: sphere-plane]
    #[arg(long)]
    scene: Option<String>,
    /// Meshes of exactly the --sizes / --base-vertices counts (spot scenes), or the
    /// first subdivision level at or above them.
    /// [default: on for spot-varying; --quick: off]
    #[arg(long)]
    exact_vertices: Option<bool>,
    /// Output folder.
    #[arg(long, default_value = "bench-results")]
    out: std::path::PathBuf,
    /// Small photos and maps: a smoke run of a few minutes.
    #[arg(long)]
    quick: bool,
    /// Skip the error-against-time sweep.
    #[arg(long)]
    no_sweep: bool,
    /// Only the error-against-time sweep, on the smallest of --sizes (no scaling runs).
    #[arg(long, conflicts_with = "no_sweep")]
    sweep_only: bool,
    /// Keep the synth workspaces in this folder and reuse one built with the same
    /// parameters (default: a temporary folder, removed at the end).
    #[arg(long)]
    work: Option<std::path::PathBuf>,
    /// Fit the paper's Minerva model: 6 materials, 7 basis BRDFs (lambert, ggx:0.1,
    /// ggx:0.2, ggx:0.35, ggx:0.6, phong:50, phong:500), --adaptive off.
    #[arg(long)]
    minerva: bool,
    /// Number of materials of every fit, or `auto` [default: auto; --minerva: 6].
    #[arg(long)]
    materials: Option<String>,
    /// Basis BRDFs of every fit, as `run --basis` [default: run's; --minerva: 7 lobes].
    #[arg(long)]
    basis: Option<String>,
    /// Also fit each vertex-scaling scene with the adaptive model (`--adaptive on`).
    #[arg(long)]
    adaptive_rows: bool,
    /// Fit with `run --large-mesh` (its settings beside the knobs).
    #[arg(long)]
    large_mesh: bool,
    /// No per-stage progress of the runs.
    #[arg(long)]
    quiet: bool,
    /// Outer iterations of the scaling runs [default: run's, 8] (the sweep sets its own).
    #[arg(long)]
    iterations: Option<usize>,
    /// File stem of the outputs: OUT/NAME.{json,md,png}.
    #[arg(long, default_value = "pipeline")]
    name: String,
    /// Replace a previous result of the same --name in --out.
    #[arg(long)]
    force: bool,
}

impl BenchArgs {
    /// Runs the subcommand; what it wrote, on stdout.
    pub(crate) fn execute(self) -> anyhow::Result<()> {
        let opts = self.options()?;
        let r = relight_cpc::bench::bench(&opts)?;
        println!(
            "bench: {} runs in {:.0} s; results in {}",
            r.vertex_runs.len() + r.photo_runs.len() + r.adaptive_runs.len() + r.sweep.len(),
            r.seconds,
            opts.out.display()
        );
        Ok(())
    }

    /// The library's [`relight_cpc::bench::BenchOptions`] from the flags: the quick or
    /// full grid, its sizes and scene, the model, then the run's own settings.
    fn options(self) -> anyhow::Result<relight_cpc::bench::BenchOptions> {
        use relight_cpc::bench::BenchOptions;
        let mut opts = if self.quick {
            BenchOptions::quick(self.out.clone())
        } else {
            BenchOptions::new(self.out.clone())
        };
        self.set_sizes(&mut opts);
        self.set_model(&mut opts)?;
        if self.iterations == Some(0) {
            anyhow::bail!("--iterations: at least 1");
        }
        if self.name.is_empty() || self.name.contains(['/', '\\']) {
            anyhow::bail!(
                "--name `{}`: a file stem without path separators",
                self.name
            );
        }
        opts.no_sweep = self.no_sweep;
        opts.sweep_only = self.sweep_only;
        opts.adaptive_rows = self.adaptive_rows;
        opts.progress = !self.quiet && !self.quick;
        opts.iterations = self.iterations;
        opts.force = self.force;
        // Each fit in its own process: its peak memory is then its own.
        opts.executable = Some(std::env::current_exe().map_err(|e| {
            anyhow::anyhow!("bench: cannot find this executable to run the fits: {e}")
        })?);
        opts.name = self.name;
        opts.work = self.work;
        Ok(opts)
    }

    /// The grid: vertex counts, photo counts, the base row, and the scene with whether its
    /// vertex counts are exact.
    fn set_sizes(&self, opts: &mut relight_cpc::bench::BenchOptions) {
        if let Some(sizes) = &self.sizes {
            opts.sizes.clone_from(sizes);
        }
        if let Some(photos) = &self.photos {
            opts.photos.clone_from(photos);
        }
        opts.base_photos = self.base_photos.unwrap_or(opts.base_photos);
        opts.base_vertices = self.base_vertices.unwrap_or(opts.base_vertices);
        if let Some(s) = &self.scene {
            // The default's exact sizes need a spot scene: another scene turns them off
            // unless asked for.
            opts.exact_vertices &= s.starts_with("spot-") && s != "spot-textured";
            opts.scene = s.clone();
        }
        opts.exact_vertices = self.exact_vertices.unwrap_or(opts.exact_vertices);
    }

    /// The fitted model: the Minerva one or the default, its materials, basis and
    /// `--large-mesh`.
    fn set_model(&self, opts: &mut relight_cpc::bench::BenchOptions) -> anyhow::Result<()> {
        if self.minerva {
            opts.model = relight_cpc::bench::Model::minerva();
        }
        if let Some(m) = &self.materials {
            opts.model.materials = match m.as_str() {
                "auto" => None,
                k => Some(k.parse().map_err(|_| {
                    anyhow::anyhow!("--materials `{k}`: a positive integer or `auto`")
                })?),
            };
        }
        if self.basis.is_some() {
            opts.model.basis = self.basis.clone();
        }
        opts.model.large_mesh = self.large_mesh;
        Ok(())
    }
}
