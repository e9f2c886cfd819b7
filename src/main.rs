//! The `relight-cpc` command line: a thin shell over the library. clap parses, each
//! subcommand turns its flags into the library's checked options and calls one library
//! function; errors are printed with their cause chain and exit with status 1.

use clap::{Parser, Subcommand};

mod run_args;

use run_args::RunArgs;

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
    /// on the built-in example (a small synthetic scene carried inside the program).
    Run(Box<RunArgs>),
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
        /// Lat-long environment map, .exr or Radiance .hdr, in the run's convention
        /// (docs/envmap-convention.md).
        #[arg(long)]
        env: Option<std::path::PathBuf>,
        /// Turn the map by DEG degrees about the up axis (counter-clockwise seen from above).
        #[arg(
            long,
            default_value_t = 0.0,
            allow_negative_numbers = true,
            value_name = "DEG"
        )]
        rotate: f64,
        /// Render N frames orbiting each camera around the object, plus a looping GIF (and
        /// an MP4 when ffmpeg is installed).
        #[arg(long, value_name = "N")]
        turntable: Option<usize>,
        /// Around the object: `env` (the map as seen by the camera), `transparent`, or a
        /// colour (black, white, grey, #RRGGBB).
        #[arg(long, default_value = "transparent")]
        background: relight_cpc::render::views::Background,
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
        /// Replace a previous result in --out.
        #[arg(long)]
        force: bool,
    },
    /// Export a finished run (RESULT_DIR of `run`) for other tools: the mesh as binary glTF
    /// with per-vertex base colour and roughness approximating the fitted materials, and/or
    /// the recovered environment maps as lat-long EXR + Radiance HDR in Blender's convention.
    Export {
        /// The result folder written by `relight-cpc run`.
        result_dir: std::path::PathBuf,
        /// Write the mesh to this .glb file.
        #[arg(long)]
        gltf: Option<std::path::PathBuf>,
        /// Write every recovered environment map into this folder (NAME.exr, NAME.hdr).
        #[arg(long)]
        envmaps: Option<std::path::PathBuf>,
        /// Replace a previous export (never anything else).
        #[arg(long)]
        force: bool,
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
        /// Replace a previous result in OUT_DIR.
        #[arg(long)]
        force: bool,
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
    },
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
            rotate,
            turntable,
            background,
            force,
        } => {
            use relight_cpc::render::relight::{self, CameraSelection, RenderOptions, Sun};
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
                force,
                exposure,
                resolution,
                rotate_deg: rotate,
                turntable,
                background,
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
            for a in &s.animations {
                println!("turntable: {}", a.display());
            }
            println!(
                "{} views rendered in {:.2} s (loading {:.2} s)",
                s.views.len(),
                s.render_seconds,
                s.load_seconds
            );
            Ok(())
        }
        Command::Export {
            result_dir,
            gltf,
            envmaps,
            force,
        } => {
            let opts = relight_cpc::export::ExportOptions {
                gltf,
                envmaps,
                force,
            };
            let s = relight_cpc::export::export_result(&result_dir, &opts)?;
            if let Some((path, g)) = &s.gltf {
                println!(
                    "{}: {} vertices, {} triangles, {} materials (roughness {}), {} bytes",
                    path.display(),
                    g.vertices,
                    g.triangles,
                    g.materials.len(),
                    g.materials
                        .iter()
                        .map(|(r, n)| format!("{r:.2}: {n} triangles"))
                        .collect::<Vec<_>>()
                        .join(", "),
                    g.bytes
                );
            }
            for p in &s.envmaps {
                println!("{}", p.display());
            }
            Ok(())
        }
        Command::Inspect {
            workspace,
            json,
            mesh,
        } => {
            let report = relight_cpc::observe::inspect::inspect(&workspace, mesh.as_deref())?;
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
            force,
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
                samples: relight_cpc::transport::reference::Samples {
                    per_pixel: spp,
                    light: light_samples,
                    seed,
                },
                points,
            };
            let claim = relight_cpc::out_dir::OutDir::claim(&out_dir, force, &[], "synth")?;
            let s = relight_cpc::synth::build(&scene, claim.path(), &opts)?;
            claim.commit()?;
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
            large_mesh,
            quiet,
            iterations,
            name,
            force,
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
            opts.model.large_mesh = large_mesh;
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
            opts.force = force;
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
    relight_cpc::out_dir::install_interrupt_cleanup();
    let cli = Cli::parse();
    if let Err(err) = dispatch(cli.command) {
        for line in error_lines(&err) {
            eprintln!("{line}");
        }
        std::process::exit(1);
    }
}

/// What the CLI prints for a failure: `error: ` and the message, then each cause.
fn error_lines(err: &anyhow::Error) -> Vec<String> {
    let mut lines = vec![format!("error: {err}")];
    lines.extend(err.chain().skip(1).map(|c| format!("  caused by: {c}")));
    lines
}

#[cfg(test)]
mod tests {
    use super::error_lines;

    #[test]
    fn a_cause_the_message_already_quotes_is_not_printed_again() {
        let path = std::path::Path::new("/no/such/map.hdr");
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let err = anyhow::Error::from(relight_cpc::Error::io(path, io));
        assert_eq!(
            error_lines(&err),
            vec!["error: /no/such/map.hdr: No such file".to_string()]
        );
        // A cause with words of its own is printed.
        let err = anyhow::Error::from(std::io::Error::other("disk full")).context("writing out/");
        assert_eq!(
            error_lines(&err),
            vec![
                "error: writing out/".to_string(),
                "  caused by: disk full".to_string()
            ]
        );
    }
}
