//! The `relight-cpc` command line: a thin shell over the library. clap parses, each
//! subcommand turns its flags into the library's checked options and calls one library
//! function; errors are printed with their cause chain and exit with status 1.

use clap::Parser;

mod cli;

use cli::{dispatch, Command};

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
