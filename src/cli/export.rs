//! `relight-cpc export`: a finished run as binary glTF and environment maps for other tools
//! ([`relight_cpc::export::export_result`]).

/// The flags of `export` (the subcommand's own help is on [`super::Command::Export`]).
#[derive(clap::Args)]
pub(crate) struct ExportArgs {
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
}

impl ExportArgs {
    /// Runs the subcommand; what it wrote, on stdout.
    pub(crate) fn execute(self) -> anyhow::Result<()> {
        let ExportArgs {
            result_dir,
            gltf,
            envmaps,
            force,
        } = self;
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
}
