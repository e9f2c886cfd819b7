//! The `relight-cpc` command line: a thin shell over the library. clap parses, each
//! subcommand turns its flags into the library's checked options and calls one library
//! function; errors are printed with their cause chain and exit with status 1.

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "relight-cpc", version, about = "Reflectance and per-photo illumination from a COLMAP reconstruction (Haber et al., CVPR 2009)")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    // Each subcommand: one variant here, one arm in `dispatch`.
}

fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {}
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
