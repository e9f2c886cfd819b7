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
}

fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
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
