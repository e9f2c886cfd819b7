//! `relight-cpc render`: a finished run relit under any map and/or a sun
//! ([`relight_cpc::render::relight::render_result`]).

/// The flags of `render` (the subcommand's own help is on [`super::Command::Render`]).
#[derive(clap::Args)]
pub(crate) struct RenderArgs {
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
}

impl RenderArgs {
    /// Runs the subcommand; what it wrote, on stdout.
    pub(crate) fn execute(self) -> anyhow::Result<()> {
        let RenderArgs {
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
        } = self;
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
}
