//! The output-folder contract shared by every command that writes (`run`, `render`,
//! `synth`, `bench`, and any later one).
//!
//! Checked before any work, by [`OutDir::claim`] (a whole folder is the result) or
//! [`OutFiles::claim`] (named files in a shared folder, `bench` and `export --gltf`: the
//! rules below hold for each named file instead of the folder, see there):
//! - an absent folder is created (and its parents);
//! - a previous result, recognised by the stamp file [`STAMP`] the tool writes last (it
//!   holds the tool's version and the command), is refused without `force`; with `force`
//!   it is replaced atomically: the new result is written into a hidden sibling staging
//!   folder, the old folder is renamed aside, the new one renamed into place, and only
//!   then the old one is removed;
//! - any other non-empty folder (or a file) is refused even with `force`, naming a few of
//!   its entries;
//! - never `/`, the home folder, the workspace or an input file's folder, or a folder
//!   that contains the workspace or an input: refused with the reason.
//!
//! Interruption: the stamp is written last, into the staging folder, so a partial result
//! never looks finished, and the previous result is only touched by the final renames.
//! [`install_interrupt_cleanup`] (called once by the CLI) removes staging folders on
//! SIGINT, SIGTERM and SIGHUP; a staging folder left by a killed process (SIGKILL, power
//! loss) is hidden, unstamped, and removed by the next claim of the same folder.

use crate::{Error, Result};
use std::path::{Component, Path, PathBuf};
use std::sync::Mutex;

pub mod exr;
mod files;
pub use files::OutFiles;

/// Name of the stamp file a finished result carries.
pub const STAMP: &str = ".relight-cpc-result.json";

/// Name of the marker inside a staging folder (holds the writer's process id).
const STAGING_MARKER: &str = ".relight-cpc-staging";

/// Staging folders of this process, removed by the interrupt handler. The lock is also
/// held across the final renames, so an interrupt never lands between them.
static STAGING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// What an existing output path holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Existing {
    /// Nothing there.
    Absent,
    /// An empty folder.
    Empty,
    /// A result of this tool (its stamp's text).
    Result(String),
    /// Something else: up to five entry names and the total count.
    Foreign { entries: Vec<String>, total: usize },
    /// A file (or other non-folder).
    NotAFolder,
}

/// What `path` holds now.
pub fn classify(path: &Path) -> Result<Existing> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Existing::Absent),
        Err(e) if e.raw_os_error() == Some(20) => {
            return Err(refuse(
                path,
                format!(
                    "cannot be created: {} is a file, not a folder",
                    first_file(path).display()
                ),
            ))
        }
        Err(e) => return Err(Error::io(path, e)),
    };
    if !meta.is_dir() {
        return Ok(Existing::NotAFolder);
    }
    let stamp = path.join(STAMP);
    if stamp.is_file() {
        let text = std::fs::read_to_string(&stamp).unwrap_or_default();
        return Ok(Existing::Result(text));
    }
    let mut names: Vec<String> = std::fs::read_dir(path)
        .map_err(|e| Error::io(path, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if names.is_empty() {
        return Ok(Existing::Empty);
    }
    names.sort();
    let total = names.len();
    names.truncate(5);
    Ok(Existing::Foreign {
        entries: names,
        total,
    })
}

fn refuse(path: &Path, message: impl Into<String>) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// `path` made absolute with symlinks of its existing part resolved and `.`/`..` of the
/// rest applied, so two spellings of one folder compare equal.
pub fn resolve(path: &Path) -> Result<PathBuf> {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(|e| Error::io(".", e))?
            .join(path)
    };
    // Component by component, as the OS walks a path: each existing prefix is resolved
    // (symlinks) before a following `..` applies to it.
    let mut base = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::ParentDir => {
                base.pop();
            }
            Component::CurDir => {}
            other => {
                base.push(other);
                if let Ok(real) = base.canonicalize() {
                    base = real;
                }
            }
        }
    }
    Ok(base)
}

/// Refuses `/`, the home folder, and any folder that is or contains the folder of an
/// input (`inputs`: the workspace, a mesh, an environment map, ...).
pub fn check_not_protected(out: &Path, inputs: &[&Path]) -> Result<()> {
    check_not_root_or_home(out)?;
    let target = resolve(out)?;
    for input in inputs {
        let Ok(inp) = input.canonicalize() else {
            continue; // A missing input is the reader's error, with its own message.
        };
        let (folder, what) = if inp.is_dir() {
            (inp.clone(), "the input folder")
        } else {
            match inp.parent() {
                Some(p) => (p.to_path_buf(), "the folder of the input file"),
                None => continue,
            }
        };
        let shown = input.display();
        if target == folder {
            return Err(refuse(
                out,
                format!("is {what} {shown}; results would overwrite it: choose a new folder"),
            ));
        }
        if folder.starts_with(&target) {
            return Err(refuse(
                out,
                format!("contains the input {shown}; replacing it would delete the input: choose a new folder"),
            ));
        }
    }
    Ok(())
}

/// Refuses `/` and the home folder as an output folder.
fn check_not_root_or_home(out: &Path) -> Result<()> {
    let target = resolve(out)?;
    if target.parent().is_none() {
        return Err(refuse(
            out,
            "is the file system's root folder; choose a new folder",
        ));
    }
    if let Some(home) = std::env::var_os("HOME").filter(|h| !h.is_empty()) {
        if resolve(Path::new(&home)).ok().as_deref() == Some(target.as_path()) {
            return Err(refuse(out, "is your home folder; choose a new folder"));
        }
    }
    Ok(())
}

/// Refuses what must never be replaced, and a previous result without `force`.
fn check_existing(out: &Path, state: &Existing, force: bool) -> Result<()> {
    match state {
        Existing::Absent | Existing::Empty => Ok(()),
        Existing::Result(_) if force => Ok(()),
        Existing::Result(_) => Err(refuse(
            out,
            "holds a previous result; pass --force to replace it, or choose another folder",
        )),
        Existing::NotAFolder => Err(refuse(
            out,
            "is a file, not a folder; choose a new folder (--force does not replace it)",
        )),
        Existing::Foreign { entries, total } => {
            let more = if *total > entries.len() {
                format!(" and {} more", total - entries.len())
            } else {
                String::new()
            };
            Err(refuse(
                out,
                format!(
                    "is not empty and is not a relight-cpc result (it holds {}{more}); \
                     choose a new or empty folder (--force only replaces a previous result)",
                    entries.join(", ")
                ),
            ))
        }
    }
}

/// The hidden sibling `.NAME.relight-cpc-TAG.PID` of `target`.
fn sibling(target: &Path, tag: &str) -> Result<PathBuf> {
    let name = target
        .file_name()
        .ok_or_else(|| refuse(target, "needs a folder name"))?;
    let parent = target.parent().unwrap_or(Path::new("/"));
    Ok(parent.join(format!(
        ".{}.relight-cpc-{tag}.{}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Removes staging and set-aside folders of `target` left by processes that no longer run
/// (only folders carrying the staging marker, i.e. written by this tool).
fn remove_stale(target: &Path) {
    let (Some(name), Some(parent)) = (target.file_name(), target.parent()) else {
        return;
    };
    let prefix = format!(".{}.relight-cpc-", name.to_string_lossy());
    let Ok(dir) = std::fs::read_dir(parent) else {
        return;
    };
    for entry in dir.filter_map(|e| e.ok()) {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix) else {
            continue;
        };
        let pid = rest.rsplit('.').next().unwrap_or("");
        let alive = Path::new("/proc").join(pid).exists() || !Path::new("/proc/self").exists();
        let ours =
            entry.path().join(STAGING_MARKER).is_file() || entry.path().join(STAMP).is_file();
        if !alive && ours && rest.starts_with("staging.") {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// A claimed output folder: write into [`OutDir::path`], then [`OutDir::commit`]. Dropped
/// without a commit (an error, a panic), the staging folder is removed and the previous
/// result, if any, is left as it was.
#[derive(Debug)]
pub struct OutDir {
    /// The folder as the user named it.
    target: PathBuf,
    /// The same folder, resolved.
    resolved: PathBuf,
    staging: PathBuf,
    force: bool,
    command: String,
    committed: bool,
}

impl OutDir {
    /// Checks `out` against the contract (module docs) before any work and creates the
    /// staging folder. `inputs`: every folder or file the command reads; `command`: the
    /// subcommand's name, recorded in the stamp.
    pub fn claim(out: &Path, force: bool, inputs: &[&Path], command: &str) -> Result<OutDir> {
        check_not_protected(out, inputs)?;
        let target = resolve(out)?;
        let state = classify(&target)?;
        check_existing(out, &state, force)?;
        let parent = target.parent().unwrap_or(Path::new("/"));
        std::fs::create_dir_all(parent).map_err(|e| unwritable(out, parent, e))?;
        remove_stale(&target);
        let staging = sibling(&target, "staging")?;
        if staging.join(STAGING_MARKER).is_file() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        std::fs::create_dir(&staging).map_err(|e| unwritable(out, parent, e))?;
        std::fs::write(staging.join(STAGING_MARKER), std::process::id().to_string())
            .map_err(|e| unwritable(out, &staging, e))?;
        lock_staging().push(staging.clone());
        Ok(OutDir {
            target: out.to_path_buf(),
            resolved: target,
            staging,
            force,
            command: command.to_string(),
            committed: false,
        })
    }

    /// Where to write the result (the staging folder).
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The final folder, as the user named it.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Writes the stamp (last) and moves the result into place, replacing a previous
    /// result only now and only if `force` was given. Returns the final folder.
    pub fn commit(mut self) -> Result<PathBuf> {
        std::fs::remove_file(self.staging.join(STAGING_MARKER))
            .map_err(|e| Error::io(&self.staging, e))?;
        let stamp = serde_json::json!({
            "tool": "relight-cpc",
            "version": env!("CARGO_PKG_VERSION"),
            "command": self.command,
            "written_unix_seconds": std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0),
        });
        let stamp_path = self.staging.join(STAMP);
        write_synced(&stamp_path, format!("{stamp:#}\n").as_bytes())?;
        let mut staging = lock_staging();
        // Checked again: the folder may have changed while the command ran.
        let state = classify(&self.resolved)?;
        check_existing(&self.target, &state, self.force)?;
        match state {
            Existing::Result(_) => {
                let old = sibling(&self.resolved, "old")?;
                std::fs::rename(&self.resolved, &old).map_err(|e| Error::io(&self.resolved, e))?;
                if let Err(e) = std::fs::rename(&self.staging, &self.resolved) {
                    let _ = std::fs::rename(&old, &self.resolved);
                    return Err(Error::io(&self.resolved, e));
                }
                std::fs::remove_dir_all(&old).map_err(|e| Error::io(&old, e))?;
            }
            Existing::Empty => {
                std::fs::remove_dir(&self.resolved).map_err(|e| Error::io(&self.resolved, e))?;
                std::fs::rename(&self.staging, &self.resolved)
                    .map_err(|e| Error::io(&self.resolved, e))?;
            }
            _ => std::fs::rename(&self.staging, &self.resolved)
                .map_err(|e| Error::io(&self.resolved, e))?,
        }
        staging.retain(|p| p != &self.staging);
        self.committed = true;
        Ok(self.target.clone())
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if !self.committed {
            let mut staging = lock_staging();
            let _ = std::fs::remove_dir_all(&self.staging);
            staging.retain(|p| p != &self.staging);
        }
    }
}

fn lock_staging() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    STAGING.lock().unwrap_or_else(|p| p.into_inner())
}

/// Writes `bytes` to `path` and flushes them to disk (a full disk fails here, not later).
fn write_synced(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let mut f = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    f.write_all(bytes).map_err(|e| Error::io(path, e))?;
    f.sync_all().map_err(|e| Error::io(path, e))
}

/// The error for a folder the tool cannot write into.
fn unwritable(out: &Path, at: &Path, e: std::io::Error) -> Error {
    let why = match e.raw_os_error() {
        Some(30) => "the file system is read-only".to_string(),
        Some(13) | Some(1) => "permission denied".to_string(),
        Some(28) => "the disk is full".to_string(),
        Some(20) => format!("{} is a file, not a folder", first_file(at).display()),
        _ => e.to_string(),
    };
    refuse(out, format!("cannot write in {}: {why}", at.display()))
}

/// The first ancestor of `path` that exists and is not a folder (for "is a file").
fn first_file(path: &Path) -> PathBuf {
    path.ancestors()
        .filter(|a| a.exists() && !a.is_dir())
        .last()
        .unwrap_or(path)
        .to_path_buf()
}

/// Removes this process's staging folders on SIGINT, SIGTERM or SIGHUP, then exits with
/// 128 + the signal number. Call once, first thing in `main`, before any thread starts:
/// the signals are blocked in the calling thread (and so in every thread started after)
/// and taken by one thread with `sigwait`, so the cleanup runs as ordinary code. Child
/// processes start with the default mask (the standard library resets it).
#[cfg(unix)]
pub fn install_interrupt_cleanup() {
    // SAFETY: plain libc calls on a local, initialised signal set.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for s in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            libc::sigaddset(&mut set, s);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        let _ = std::thread::Builder::new()
            .name("interrupt-cleanup".into())
            .spawn(move || {
                let mut sig: libc::c_int = 0;
                if libc::sigwait(&set, &mut sig) == 0 {
                    let staging = lock_staging();
                    for p in staging.iter() {
                        let _ = std::fs::remove_dir_all(p);
                        eprintln!("interrupted: removed the unfinished output {}", p.display());
                    }
                    std::process::exit(128 + sig);
                }
            });
    }
}

/// No signal handling off Unix: a staging folder left behind is hidden and unstamped.
#[cfg(not(unix))]
pub fn install_interrupt_cleanup() {}

/// Write `bytes` to `path` through a temporary sibling file renamed into place, so an
/// interrupted write never leaves a file that looks complete.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::Config(format!("{}: needs a file name", path.display())))?;
    let tmp = path.with_file_name(format!(".{}.partial", name.to_string_lossy()));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("relight-outdir-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn resolve_applies_dot_dot_past_the_existing_part() {
        let d = scratch("resolve");
        let a = resolve(&d.join("x/../y")).unwrap();
        assert_eq!(a, d.canonicalize().unwrap().join("y"));
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A symlink to the workspace, and `..` taken after it, are seen through: the OS would
    /// write into the workspace or its parent.
    #[cfg(unix)]
    #[test]
    fn symlinks_to_an_input_are_seen_through() {
        let d = scratch("symlink");
        let ws = d.join("data/ws");
        std::fs::create_dir_all(&ws).unwrap();
        let link = d.join("link");
        std::os::unix::fs::symlink(&ws, &link).unwrap();
        let e = check_not_protected(&link, &[&ws]).unwrap_err().to_string();
        assert!(e.contains("is the input folder"), "{e}");
        let e = check_not_protected(&link.join(".."), &[&ws])
            .unwrap_err()
            .to_string();
        assert!(e.contains("contains the input"), "{e}");
        assert!(check_not_protected(&d.join("elsewhere"), &[&ws]).is_ok());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn claim_then_commit_writes_the_stamp_last_and_replaces_only_with_force() {
        let d = scratch("commit");
        let out = d.join("res");
        let c = OutDir::claim(&out, false, &[], "test").unwrap();
        std::fs::write(c.path().join("a.txt"), "1").unwrap();
        assert!(!out.exists(), "nothing at the target before the commit");
        c.commit().unwrap();
        assert!(out.join(STAMP).is_file());
        let again = OutDir::claim(&out, false, &[], "test")
            .unwrap_err()
            .to_string();
        assert!(again.contains("--force"), "{again}");
        let c = OutDir::claim(&out, true, &[], "test").unwrap();
        std::fs::write(c.path().join("b.txt"), "2").unwrap();
        c.commit().unwrap();
        assert!(out.join("b.txt").is_file() && !out.join("a.txt").exists());
        let leftovers: Vec<_> = std::fs::read_dir(&d).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "no staging or old folder left");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
