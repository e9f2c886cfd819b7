//! `relight-cpc inspect`: what a COLMAP workspace holds, as text or JSON
//! ([`relight_cpc::observe::inspect`]).

/// The flags of `inspect` (the subcommand's own help is on [`super::Command::Inspect`]).
#[derive(clap::Args)]
pub(crate) struct InspectArgs {
    /// The COLMAP workspace folder.
    workspace: std::path::PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Use this mesh instead of searching the workspace.
    #[arg(long)]
    mesh: Option<std::path::PathBuf>,
}

impl InspectArgs {
    /// Runs the subcommand; what it wrote, on stdout.
    pub(crate) fn execute(self) -> anyhow::Result<()> {
        let InspectArgs {
            workspace,
            json,
            mesh,
        } = self;
        let report = relight_cpc::observe::inspect::inspect(&workspace, mesh.as_deref())?;
        if json {
            println!("{}", serde_json::to_string_pretty(&report)?);
        } else {
            print!("{report}");
        }
        Ok(())
    }
}
