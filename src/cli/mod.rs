//! The subcommands of `relight-cpc`: one module each, with its flags ([`clap::Args`]) and
//! what it runs (one library call, its summary on stdout).

use clap::Subcommand;

mod bench;
mod export;
mod inspect;
mod render;
mod run;
mod synth;

use bench::BenchArgs;
use export::ExportArgs;
use inspect::InspectArgs;
use render::RenderArgs;
pub(crate) use run::RunArgs;
use synth::SynthArgs;

#[derive(Subcommand)]
pub(crate) enum Command {
    // Each subcommand: one variant here, its flags and what it runs in a module of its own.
    /// Fit reflectance and per-photo illumination to a COLMAP workspace, evaluate held-out
    /// photos, and write maps, materials, renders and a report. Without WORKSPACE it runs
    /// on the built-in example (a small synthetic scene carried inside the program).
    Run(Box<RunArgs>),
    /// Show what a COLMAP workspace holds: what was found and picked, counts, and per photo
    /// the observed vertices, overexposure, confidence and reprojection error.
    Inspect(InspectArgs),
    /// Relight a finished run (RESULT_DIR of `run`) under any lat-long environment map
    /// (the run's environment frame, materials.json "env_frame") and/or a sun, from a
    /// registered camera or every camera of a COLMAP text model; writes NAME.exr (linear,
    /// alpha = mask), NAME.png (sRGB) and NAME.mask.png per camera.
    Render(RenderArgs),
    /// Export a finished run (RESULT_DIR of `run`) for other tools: the mesh as binary glTF
    /// with per-vertex base colour and roughness approximating the fitted materials, and/or
    /// the recovered environment maps as lat-long EXR + Radiance HDR in Blender's convention.
    Export(ExportArgs),
    /// Write a known-truth synthetic COLMAP workspace (photos rendered by the reference
    /// renderer, ground truth in OUT_DIR/truth/).
    Synth(SynthArgs),
    /// Benchmark the whole pipeline on synthetic scenes: per-stage wall time, CPU time and
    /// peak memory, growth with vertices and photos, and held-out error against run time
    /// over the speed knobs; writes OUT/NAME.{json,md,png} (NAME = --name, default pipeline).
    Bench(BenchArgs),
}

/// Runs one subcommand.
pub(crate) fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Run(args) => args.execute(),
        Command::Inspect(args) => args.execute(),
        Command::Render(args) => args.execute(),
        Command::Export(args) => args.execute(),
        Command::Synth(args) => args.execute(),
        Command::Bench(args) => args.execute(),
    }
}
