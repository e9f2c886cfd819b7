//! `relight-cpc synth`: a known-truth synthetic COLMAP workspace
//! ([`relight_cpc::synth::build`]).

/// The flags of `synth` (the subcommand's own help is on [`super::Command::Synth`]).
#[derive(clap::Args)]
pub(crate) struct SynthArgs {
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
    /// The linear value the object's 99th-percentile brightness is exposed to: 1 clips
    /// about 1% of its pixels, 0.6 nearly none.
    #[arg(long, default_value_t = 1.0)]
    exposure_peak: f64,
    /// Photos lit by the same map share its rotation, so they share a sky (for
    /// `run --light shared`; scenes whose map turns from photo to photo).
    #[arg(long)]
    shared_skies: bool,
    /// Suns from a day's clock: each photo of a sun-and-sky scene (spot-sky) is taken at
    /// a time of one summer day at one place, its sun from the solar position, and its PNG
    /// carries that place and UTC time as an EXIF geotag (for `run --light sky`).
    #[arg(long)]
    geotag: bool,
    /// The pixels the object does not cover show the map it is lit by, as a photo's sky
    /// does; without it they are black.
    #[arg(long)]
    sky_background: bool,
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
}

impl SynthArgs {
    /// Runs the subcommand; what it wrote, on stdout.
    pub(crate) fn execute(self) -> anyhow::Result<()> {
        let SynthArgs {
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
            exposure_peak,
            shared_skies,
            geotag,
            sky_background,
            spp,
            light_samples,
            points,
            force,
        } = self;
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
            exposure_peak,
            shared_skies,
            geotag,
            sky_background,
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
}
