//! The `relight-cpc` command line: a thin shell over the library. clap parses, each
//! subcommand turns its flags into the library's checked options and calls one library
//! function; errors are printed with their cause chain and exit with status 1.

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "relight-cpc",
    version,
    about = "Reflectance and per-photo illumination from a COLMAP reconstruction (Haber et al., CVPR 2009)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    // Each subcommand: one variant here, one arm in `dispatch`.
    /// Fit reflectance and per-photo illumination to a COLMAP workspace, evaluate held-out
    /// photos, and write maps, materials, renders and a report. Without WORKSPACE it runs
    /// on the built-in example (examples/spot).
    Run(RunArgs),
    /// Show what a COLMAP workspace holds: what was found and picked, counts, and per photo
    /// the observed vertices, overexposure, confidence and reprojection error.
    Inspect {
        /// The COLMAP workspace folder.
        workspace: std::path::PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Use this mesh instead of searching the workspace.
        #[arg(long)]
        mesh: Option<std::path::PathBuf>,
    },
    /// Relight a finished run (RESULT_DIR of `run`) under any lat-long environment map
    /// (the run's environment frame, materials.json "env_frame") and/or a sun, from a
    /// registered camera or every camera of a COLMAP text model; writes NAME.exr (linear,
    /// alpha = mask), NAME.png (sRGB) and NAME.mask.png per camera.
    Render {
        /// The result folder written by `relight-cpc run`.
        result_dir: std::path::PathBuf,
        /// Lat-long EXR environment map.
        #[arg(long)]
        env: Option<std::path::PathBuf>,
        /// One registered camera, by image name (default: every registered camera).
        #[arg(long, conflicts_with = "cameras")]
        camera: Option<String>,
        /// A folder with COLMAP text cameras.txt and images.txt: render every image there.
        #[arg(long)]
        cameras: Option<std::path::PathBuf>,
        /// Output folder.
        #[arg(long)]
        out: std::path::PathBuf,
        /// Sun direction X,Y,Z in the environment frame (a 1° disc).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        sun: Option<Vec<f64>>,
        /// Sun radiance (all channels).
        #[arg(long, default_value_t = 1000.0)]
        sun_radiance: f64,
        /// Linear exposure factor for the PNG.
        #[arg(long, default_value_t = 1.0)]
        exposure: f64,
        /// Output width in pixels (height keeps the camera's aspect).
        #[arg(long)]
        resolution: Option<u32>,
    },
    /// Write a known-truth synthetic COLMAP workspace (photos rendered by the reference
    /// renderer, ground truth in OUT_DIR/truth/).
    Synth {
        /// Scene name (see --list).
        scene: Option<String>,
        /// Output folder.
        out_dir: Option<std::path::PathBuf>,
        /// Print the scene names, one per line, and exit.
        #[arg(long)]
        list: bool,
        /// Photo width in pixels.
        #[arg(long, default_value_t = 256)]
        width: u32,
        /// Photo height in pixels.
        #[arg(long, default_value_t = 256)]
        height: u32,
        /// Number of photos (default: the scene's).
        #[arg(long)]
        photos: Option<usize>,
        /// Seed of every random choice.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Minimum number of mesh vertices (default about 10K).
        #[arg(long)]
        vertices: Option<usize>,
        /// Exactly --vertices vertices: whole subdivision steps, then a partial, conforming
        /// one (spot scenes only)
        #[arg(long)]
        exact_vertices: bool,
        /// Gaussian noise σ on the linear [0, 1] photo scale.
        #[arg(long, default_value_t = 0.0)]
        noise: f64,
        /// Random per-photo white balance.
        #[arg(long)]
        white_balance: bool,
        /// Primary rays per pixel.
        #[arg(long, default_value_t = 4)]
        spp: u32,
        /// MIS sample pairs (environment + BRDF) per shading point.
        #[arg(long, default_value_t = 64)]
        light_samples: u32,
        /// Surface points sampled for points3D.txt.
        #[arg(long, default_value_t = 3000)]
        points: usize,
    },
    /// Benchmark the whole pipeline on synthetic scenes: per-stage wall time, CPU time and
    /// peak memory, growth with vertices and photos, and held-out error against run time
    /// over the speed knobs; writes OUT/NAME.{json,md,png} (NAME = --name, default pipeline).
    Bench {
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
        /// No per-stage progress of the runs.
        #[arg(long)]
        quiet: bool,
        /// Outer iterations of the scaling runs [default: run's, 8] (the sweep sets its own).
        #[arg(long)]
        iterations: Option<usize>,
        /// File stem of the outputs: OUT/NAME.{json,md,png}.
        #[arg(long, default_value = "pipeline")]
        name: String,
    },
}

/// Flags of `run` (the README explains each default).
#[derive(clap::Args)]
struct RunArgs {
    /// The COLMAP workspace (default: the built-in example).
    workspace: Option<std::path::PathBuf>,
    /// Output folder (default: out/NAME, NAME = the workspace's folder name).
    #[arg(long)]
    out: Option<std::path::PathBuf>,
    /// Use this mesh instead of the workspace's.
    #[arg(long)]
    mesh: Option<std::path::PathBuf>,
    /// Hold out these photos (image names, comma-separated); `none` holds out nothing.
    /// Default: the workspace's truth/manifest.json list, if any.
    #[arg(long, value_delimiter = ',', conflicts_with = "holdout_every")]
    holdout: Option<Vec<String>>,
    /// Hold out every N-th photo in name order.
    #[arg(long)]
    holdout_every: Option<usize>,
    /// World up as X,Y,Z (default: estimated from the cameras).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    up: Option<Vec<f64>>,
    /// Number of materials, or `auto`.
    #[arg(long, default_value = "auto")]
    materials: String,
    /// Basis BRDFs, comma-separated: lambert, phong:N, ggx:ALPHA.
    #[arg(long, default_value = "lambert,phong:50,phong:500")]
    basis: String,
    /// Global (octahedral) environment map side, a power of two.
    #[arg(long, default_value_t = 64)]
    global_resolution: usize,
    /// Local (hemi-octahedral) map side, a power of two.
    #[arg(long, default_value_t = 32)]
    local_resolution: usize,
    /// Local map side of the renderer (held-out views, renders, `render`), a power of two;
    /// default --local-resolution (64 draws known sharp lobes more faithfully, at twice the
    /// visibility and evaluation cost).
    #[arg(long)]
    render_local_resolution: Option<usize>,
    /// Normal-grid side of the precomputed rotations, a power of two.
    #[arg(long, default_value_t = 32)]
    normal_grid: usize,
    /// Haar coefficients kept per transport row (0 = all).
    #[arg(long, default_value_t = 128)]
    keep: usize,
    /// Visibility rays per local texel.
    #[arg(long, default_value_t = 2)]
    rays_per_texel: usize,
    /// Outer (lighting + materials) iterations at most.
    #[arg(long, default_value_t = 8)]
    iterations: usize,
    /// Stop when the objective improves by less than this fraction.
    #[arg(long, default_value_t = 1e-3)]
    tolerance: f64,
    /// Laplacian smoothness of the maps, as a fraction of the system's largest value.
    #[arg(long, default_value_t = 1e-3)]
    smoothness: f64,
    /// IRLS passes per lighting step (1 = plain least squares).
    #[arg(long, default_value_t = 3)]
    irls_iterations: usize,
    /// GPCG iterations per lighting QP inside the alternation (each starts from the
    /// previous iterate); 0 = solve every lighting QP to the KKT tolerance.
    #[arg(long, default_value_t = relight_cpc::run::RunOptions::default_lighting_qp_iterations())]
    lighting_qp_iterations: usize,
    /// Conjugate-gradient steps per GPCG iteration of a lighting QP inside the alternation
    /// (each is one Hessian product); 0 = the solver's own cap.
    #[arg(long, default_value_t = relight_cpc::run::RunOptions::default_lighting_cg_iterations())]
    lighting_cg_iterations: usize,
    /// Early stopping: outer iterations without a better validation score before the
    /// alternation stops.
    #[arg(long, default_value_t = relight_cpc::run::RunOptions::default_patience())]
    patience: usize,
    /// Starts of the alternation to try, the best by validation score kept: 1 = the
    /// paper's clustered start; 2 adds every glossy lobe at 0.3 × the Lambertian weight,
    /// then one lobe per material in cyclic order. Each start costs one estimate.
    #[arg(long, default_value_t = 1)]
    starts: usize,
    /// Lower bound on IRLS's robust scale, as a fraction of each photo's RMS radiance: a
    /// residual within 1.345 × this is never down-weighted (0 = the residuals' MAD alone).
    #[arg(long, default_value_t = relight_cpc::estimate::ROBUST_FLOOR)]
    robust_floor: f64,
    /// Fraction of the training observations held back (seeded) to stop the alternation
    /// at its best iterate; 0 turns early stopping off.
    #[arg(long, default_value_t = 0.1)]
    validation: f64,
    /// Overexposure threshold on the 8-bit scale: a pixel with any channel at or above it
    /// is ignored.
    #[arg(long, default_value_t = 250.0)]
    clip: f32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// No progress output.
    #[arg(long)]
    quiet: bool,
    /// Replace the output folder if it exists.
    #[arg(long)]
    force: bool,
    /// Skip the renders of the training views.
    #[arg(long)]
    no_training_renders: bool,
    /// `on`: a short pilot fit decides what the scene needs (materials by held-out error;
    /// basis BRDFs dropped when they carry under 1% of the radiance or leaving them out
    /// costs under 1% of held-out error; map resolution and coefficient budget from the
    /// kept lobes' width; duplicate photos skipped; the resolutions and --keep given are
    /// upper bounds); `off`: the full model as given.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    adaptive: String,
    /// Per-photo light model: `paper` (a free non-negative wavelet map, the paper's),
    /// `prior` (the same map under a prior learnt from real HDR maps: Gaussian on its
    /// low-order spherical harmonics, sparse wavelet detail), `auto` (both fitted, the lower
    /// validation error kept; twice the estimation time).
    #[arg(long, default_value = "paper", value_parser = ["paper", "prior", "auto"])]
    light: String,
}

impl RunArgs {
    fn options(self) -> anyhow::Result<relight_cpc::run::RunOptions> {
        use relight_cpc::run::{builtin_example, Holdout, MaterialCount, RunOptions};
        let workspace = self.workspace.unwrap_or_else(builtin_example);
        let out = self.out.unwrap_or_else(|| {
            let name = workspace
                .canonicalize()
                .ok()
                .and_then(|p| p.file_name().map(|n| n.to_owned()))
                .unwrap_or_else(|| "result".into());
            std::path::Path::new("out").join(name)
        });
        let mut o = RunOptions::new(workspace, out);
        o.mesh = self.mesh;
        o.holdout = match (self.holdout, self.holdout_every) {
            (Some(names), _) if names.len() == 1 && names[0] == "none" => Holdout::None,
            (Some(names), _) => Holdout::Names(names),
            (None, Some(k)) => Holdout::Every(k),
            (None, None) => Holdout::Default,
        };
        o.up = match self.up.as_deref() {
            None => None,
            Some([x, y, z]) => Some(relight_cpc::Vec3::new(*x, *y, *z)),
            Some(v) => anyhow::bail!(
                "--up: expected X,Y,Z (three numbers), got {} values",
                v.len()
            ),
        };
        o.materials = match self.materials.as_str() {
            "auto" => MaterialCount::Auto,
            s => MaterialCount::Fixed(s.parse().map_err(|_| {
                anyhow::anyhow!("--materials {s}: expected a whole number or `auto`")
            })?),
        };
        o.basis = relight_cpc::brdf::parse_list(&self.basis)?;
        o.global_resolution = self.global_resolution;
        o.local_resolution = self.local_resolution;
        o.render_local_resolution = self.render_local_resolution;
        o.normal_grid = self.normal_grid;
        o.keep = self.keep;
        o.rays_per_texel = self.rays_per_texel;
        o.max_iterations = self.iterations;
        o.rel_tol = self.tolerance;
        o.smoothness = self.smoothness;
        o.irls_iterations = self.irls_iterations;
        o.lighting_qp_iterations = self.lighting_qp_iterations;
        o.validation = self.validation;
        o.lighting_cg_iterations = self.lighting_cg_iterations;
        o.patience = self.patience;
        o.starts = self.starts;
        o.robust_floor = self.robust_floor;
        o.clip = self.clip / 255.0;
        o.seed = self.seed;
        o.progress = !self.quiet;
        o.force = self.force;
        o.render_training = !self.no_training_renders;
        o.adaptive = self.adaptive == "on";
        o.light = relight_cpc::light_choose::LightChoice::parse(&self.light)?;
        Ok(o)
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

fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Run(args) => {
            set_threads(args.threads)?;
            let quiet = args.quiet;
            let opts = args.options()?;
            let summary = relight_cpc::run::run(&opts)?;
            if !quiet {
                let r = &summary.report;
                println!(
                    "training RMSE {:.5}; results, report.md and report.json in {}",
                    r.train_rmse,
                    summary.out.display()
                );
                for h in &r.holdout {
                    println!(
                        "held out {} ({}): RMSE {:.5} raw, {:.5} after scale {:.3}",
                        h.image, h.protocol, h.rmse, h.rmse_scaled, h.scale
                    );
                }
            }
            Ok(())
        }
        Command::Render {
            result_dir,
            env,
            camera,
            cameras,
            out,
            sun,
            sun_radiance,
            exposure,
            resolution,
        } => {
            use relight_cpc::relight::{self, CameraSelection, RenderOptions, Sun};
            if let Some(d) = &sun {
                if d.len() != 3 {
                    anyhow::bail!("--sun takes three numbers X,Y,Z, got {}", d.len());
                }
            }
            let opts = RenderOptions {
                env,
                sun: sun.map(|d| Sun {
                    dir: relight_cpc::Vec3::new(d[0], d[1], d[2]),
                    radiance: [sun_radiance; 3],
                }),
                cameras: match (camera, cameras) {
                    (Some(name), _) => CameraSelection::Named(name),
                    (None, Some(dir)) => CameraSelection::Folder(dir),
                    (None, None) => CameraSelection::AllRegistered,
                },
                out,
                exposure,
                resolution,
            };
            let s = relight::render_result(&result_dir, &opts)?;
            for v in &s.views {
                println!(
                    "{}: {} object pixels -> {}",
                    v.name,
                    v.covered,
                    v.png.display()
                );
            }
            println!(
                "{} views rendered in {:.2} s (loading {:.2} s)",
                s.views.len(),
                s.render_seconds,
                s.load_seconds
            );
            Ok(())
        }
        Command::Inspect {
            workspace,
            json,
            mesh,
        } => {
            let report = relight_cpc::scene::inspect(&workspace, mesh.as_deref())?;
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{report}");
            }
            Ok(())
        }
        Command::Synth {
            scene,
            out_dir,
            list,
            width,
            height,
            photos,
            seed,
            vertices,
            exact_vertices,
            noise,
            white_balance,
            spp,
            light_samples,
            points,
        } => {
            if list {
                for name in relight_cpc::synth::scene_names() {
                    println!("{name}");
                }
                return Ok(());
            }
            let (Some(scene), Some(out_dir)) = (scene, out_dir) else {
                anyhow::bail!("usage: relight-cpc synth SCENE OUT_DIR (or --list)");
            };
            let opts = relight_cpc::synth::SynthOptions {
                width,
                height,
                photos,
                seed,
                vertices,
                exact_vertices,
                noise,
                white_balance,
                samples: relight_cpc::reference::Samples {
                    per_pixel: spp,
                    light: light_samples,
                    seed,
                },
                points,
            };
            let s = relight_cpc::synth::build(&scene, &out_dir, &opts)?;
            println!(
                "{}: {} photos ({} held out), {} vertices, {} faces, {} points3D, {} observations, rendering {:.1} s",
                s.scene,
                s.photos.len(),
                s.held_out.len(),
                s.vertices,
                s.faces,
                s.points3d,
                s.observations,
                s.render_seconds
            );
            Ok(())
        }
        Command::Bench {
            sizes,
            photos,
            base_photos,
            base_vertices,
            scene,
            exact_vertices,
            out,
            quick,
            no_sweep,
            sweep_only,
            work,
            minerva,
            materials,
            basis,
            adaptive_rows,
            quiet,
            iterations,
            name,
        } => {
            use relight_cpc::bench::BenchOptions;
            let mut opts = if quick {
                BenchOptions::quick(out)
            } else {
                BenchOptions::new(out)
            };
            opts.sizes = sizes.unwrap_or(opts.sizes);
            opts.photos = photos.unwrap_or(opts.photos);
            opts.base_photos = base_photos.unwrap_or(opts.base_photos);
            opts.base_vertices = base_vertices.unwrap_or(opts.base_vertices);
            if let Some(s) = scene {
                // The default's exact sizes need a spot scene: another scene turns them off
                // unless asked for.
                opts.exact_vertices &= s.starts_with("spot-") && s != "spot-textured";
                opts.scene = s;
            }
            opts.exact_vertices = exact_vertices.unwrap_or(opts.exact_vertices);
            opts.no_sweep = no_sweep;
            opts.sweep_only = sweep_only;
            opts.work = work;
            if minerva {
                opts.model = relight_cpc::bench::Model::minerva();
            }
            if let Some(m) = materials {
                opts.model.materials = match m.as_str() {
                    "auto" => None,
                    k => Some(k.parse().map_err(|_| {
                        anyhow::anyhow!("--materials `{k}`: a positive integer or `auto`")
                    })?),
                };
            }
            if basis.is_some() {
                opts.model.basis = basis;
            }
            opts.adaptive_rows = adaptive_rows;
            opts.progress = !quiet && !quick;
            if iterations == Some(0) {
                anyhow::bail!("--iterations: at least 1");
            }
            opts.iterations = iterations;
            if name.is_empty() || name.contains(['/', '\\']) {
                anyhow::bail!("--name `{name}`: a file stem without path separators");
            }
            opts.name = name;
            // Each fit in its own process: its peak memory is then its own.
            opts.executable = Some(std::env::current_exe().map_err(|e| {
                anyhow::anyhow!("bench: cannot find this executable to run the fits: {e}")
            })?);
            let r = relight_cpc::bench::bench(&opts)?;
            println!(
                "bench: {} runs in {:.0} s; results in {}",
                r.vertex_runs.len() + r.photo_runs.len() + r.adaptive_runs.len() + r.sweep.len(),
                r.seconds,
                opts.out.display()
            );
            Ok(())
        }
    }
}

fn main() {
    let cli = Cli::parse();
    if let Err(err) = dispatch(cli.command) {
        eprintln!("error: {err}");
        for cause in err.chain().skip(1) {
            eprintln!("  caused by: {cause}");
        }
        std::process::exit(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `run`'s flags repeat most defaults as literals beside `RunOptions::new`: parsing a
    /// bare `run WS --out OUT` must give the library's defaults, but for the one the CLI
    /// sets on purpose (`--adaptive on`; the library's default is the full model as given).
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
        // Debug prints every field, floats to the last bit, so this is exact equality.
        assert_eq!(format!("{got:?}"), format!("{want:?}"));
    }

    /// The README's table of `run` flags states each default clap applies. A row's flags
    /// and its defaults pair up in order (`--iterations N`, `--tolerance T` | 8, 1e-3);
    /// flags without a clap default (`--threads`, `--up`, ...) are described in words.
    #[test]
    fn readme_flag_table_states_the_cli_defaults() {
        use clap::CommandFactory;
        let cli = Cli::command();
        let run = cli.find_subcommand("run").unwrap();
        let default_of = |flag: &str| {
            let arg = run
                .get_arguments()
                .find(|a| a.get_long() == Some(flag))
                .unwrap_or_else(|| panic!("README names --{flag}, which `run` does not have"));
            let d = arg.get_default_values();
            (d.len() == 1).then(|| d[0].to_string_lossy().into_owned())
        };
        let same = |readme: &str, clap: &str| match (readme.parse::<f64>(), clap.parse::<f64>()) {
            (Ok(a), Ok(b)) => a == b,
            _ => readme == clap,
        };
        let mut checked = 0;
        for row in include_str!("../README.md")
            .lines()
            .filter(|l| l.starts_with("| `--"))
        {
            let cells: Vec<&str> = row.split(" | ").collect();
            let flags: Vec<&str> = cells[0]
                .split("`--")
                .skip(1)
                .map(|f| f.split([' ', '`']).next().unwrap())
                .collect();
            let values: Vec<&str> = cells[1].split(", ").map(|v| v.trim_matches('`')).collect();
            for (i, flag) in flags.iter().enumerate() {
                let Some(clap) = default_of(flag) else {
                    continue;
                };
                assert_eq!(values.len(), flags.len(), "README row of --{flag}: {row}");
                assert!(
                    same(values[i], &clap),
                    "README gives --{flag} the default `{}`, clap `{clap}`",
                    values[i]
                );
                checked += 1;
            }
        }
        // 20 flags of the table have a clap default; fewer means rows were lost.
        assert_eq!(checked, 20, "README defaults checked");
    }
}
