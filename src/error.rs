//! The library's one error type.
//!
//! Every variant that comes from a file carries the path and, where there is one, the line
//! (text formats) or record (binary formats, counted from 0) and what was expected, so a
//! user can open the file and see what is wrong. The CLI prints `Display` and exits 1.

use std::path::PathBuf;

/// Result with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong, and where.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file could not be opened, read or written. The message carries the I/O error's
    /// words, so the I/O error is not also reported as this error's source (a printer that
    /// walks the source chain, as the CLI does, would say it twice).
    #[error("{path}: {io}")]
    Io { path: PathBuf, io: std::io::Error },
    /// The file was read but its content is malformed. `location` is e.g. `line 12`,
    /// `record 3 (image id 7)` or `byte 1024`.
    #[error("{path}: {location}: {message}")]
    Format {
        path: PathBuf,
        location: String,
        message: String,
    },
    /// An image file could not be decoded, or does not fit its camera.
    #[error("{path}: {message}")]
    Image { path: PathBuf, message: String },
    /// A COLMAP workspace lacks a part that the job needs.
    #[error("workspace {path}: {message}")]
    Workspace { path: PathBuf, message: String },
    /// The output folder cannot be used (src/out_dir/ says which folders are refused).
    #[error("output folder {path}: {message}")]
    Output { path: PathBuf, message: String },
    /// A user option or a combination of options is invalid.
    #[error("invalid option: {0}")]
    Config(String),
    /// An internal invariant does not hold: data handed between the library's own stages
    /// (or by a library caller) is inconsistent, e.g. sizes that disagree. A bug, not a
    /// user's mistake; the message names the inconsistency.
    #[error("internal error: {0}")]
    Internal(String),
    /// The job would need more memory than the machine has.
    #[error("not enough memory: {what} needs about {needed_bytes} bytes but {available_bytes} are available; {hint}")]
    Memory {
        what: String,
        needed_bytes: u64,
        available_bytes: u64,
        hint: String,
    },
    /// A numerical stage could not produce a finite, meaningful answer.
    #[error("numerical failure in {stage}: {message}")]
    Numeric { stage: String, message: String },
}

impl Error {
    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, io: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            io,
        }
    }

    /// An [`Error::Format`] for `path` at `location`.
    pub fn format(
        path: impl Into<PathBuf>,
        location: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::Format {
            path: path.into(),
            location: location.into(),
            message: message.into(),
        }
    }
}
