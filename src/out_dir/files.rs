//! [`OutFiles`]: named result files in a shared folder (`bench`'s reports, `export
//! --gltf`'s `.glb`), each guarded on its own instead of the folder (module docs of
//! [`super`]).

use super::{check_not_root_or_home, refuse, resolve, unwritable, write_synced};
use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Named result files in a shared folder: `bench` writes `NAME.json`, `NAME.md`, ... into
/// one folder of many results, `export --gltf` one `.glb`, usually beside the result it
/// came from. The folder is not the result, so it may hold anything else, inputs
/// included; what is protected is each named file:
/// - the folder must not be `/` or the home folder;
/// - a named file that is an input, or a folder holding one, is refused;
/// - a previous result, recognised by `is_ours` on the first name, is refused without
///   `force` and replaced with it; a file of one of the names that is not ours is refused
///   even with `force`;
/// - each write checks again: a file that appeared after the claim and that this claim
///   did not write is never replaced.
///
/// Write each file with [`OutFiles::write`] (temporary file, then rename).
#[derive(Debug)]
pub struct OutFiles {
    folder: PathBuf,
    /// The claimed names with whether each may be replaced now: a previous result taken
    /// with `force`, or a file this claim wrote.
    names: Mutex<Vec<(String, bool)>>,
}

impl OutFiles {
    /// Claims `names` in `folder` (created when absent).
    pub fn claim(
        folder: &Path,
        names: &[&str],
        force: bool,
        inputs: &[&Path],
        is_ours: impl Fn(&Path) -> bool,
    ) -> Result<OutFiles> {
        check_not_root_or_home(folder)?;
        if folder.exists() && !folder.is_dir() {
            return Err(refuse(
                folder,
                "is a file, not a folder; choose a new folder",
            ));
        }
        for name in names {
            check_not_an_input(&folder.join(name), inputs)?;
        }
        let present = check_named_files(folder, names, force, is_ours)?;
        std::fs::create_dir_all(folder).map_err(|e| unwritable(folder, folder, e))?;
        let probe = folder.join(format!(".relight-cpc-probe.{}", std::process::id()));
        std::fs::write(&probe, b"").map_err(|e| unwritable(folder, folder, e))?;
        let _ = std::fs::remove_file(&probe);
        let names = names
            .iter()
            .map(|n| (n.to_string(), present.contains(&folder.join(n))))
            .collect();
        Ok(OutFiles {
            folder: folder.to_path_buf(),
            names: Mutex::new(names),
        })
    }

    /// The folder.
    pub fn folder(&self) -> &Path {
        &self.folder
    }

    /// Writes `name` atomically: `bytes` go to a hidden temporary file beside it, flushed,
    /// then renamed over the old file.
    pub fn write(&self, name: &str, bytes: &[u8]) -> Result<PathBuf> {
        self.write_with(name, |tmp| write_synced(tmp, bytes))
    }

    /// Like [`OutFiles::write`] for a writer that takes a path: `write` fills a hidden
    /// temporary file beside `name`, which is then renamed over it (removed on error).
    pub fn write_with(
        &self,
        name: &str,
        write: impl FnOnce(&Path) -> Result<()>,
    ) -> Result<PathBuf> {
        let path = self.folder.join(name);
        self.check_replaceable(name, &path)?;
        let ext = Path::new(name)
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        // The extension stays last: some writers pick the format from it.
        let tmp = self.folder.join(format!(
            ".{name}.relight-cpc-staging.{}{ext}",
            std::process::id()
        ));
        if let Err(e) = write(&tmp) {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
        std::fs::rename(&tmp, &path).map_err(|e| Error::io(&path, e))?;
        if let Some(entry) = self.lock_names().iter_mut().find(|(n, _)| n == name) {
            entry.1 = true;
        }
        Ok(path)
    }

    fn lock_names(&self) -> std::sync::MutexGuard<'_, Vec<(String, bool)>> {
        self.names.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Refuses a name that was not claimed, and an existing file this claim may not
    /// replace (one that appeared after the claim).
    fn check_replaceable(&self, name: &str, path: &Path) -> Result<()> {
        let names = self.lock_names();
        let Some((_, replaceable)) = names.iter().find(|(n, _)| n == name) else {
            return Err(Error::Internal(format!(
                "{}: {name} was not claimed",
                self.folder.display()
            )));
        };
        if !replaceable && std::fs::symlink_metadata(path).is_ok() {
            return Err(refuse(
                path,
                "appeared while the command ran and was not written by it; it is left as it was",
            ));
        }
        Ok(())
    }
}

/// The named files already in `folder`: all of them a previous result (its first name
/// recognised by `is_ours`) and `force` given, or an error.
fn check_named_files(
    folder: &Path,
    names: &[&str],
    force: bool,
    is_ours: impl Fn(&Path) -> bool,
) -> Result<Vec<PathBuf>> {
    let present: Vec<PathBuf> = names
        .iter()
        .map(|n| folder.join(n))
        .filter(|p| std::fs::symlink_metadata(p).is_ok())
        .collect();
    let Some(first) = present.first() else {
        return Ok(present);
    };
    let main = folder.join(names[0]);
    if !main.is_file() || !is_ours(&main) {
        return Err(refuse(
            folder,
            format!(
                "{} exists and is not a relight-cpc result; choose another folder or name (--force only replaces a previous result)",
                first.display()
            ),
        ));
    }
    if !force {
        return Err(refuse(
            folder,
            format!(
                "holds a previous result ({}); pass --force to replace it, or choose another folder or name",
                main.display()
            ),
        ));
    }
    Ok(present)
}

/// Refuses a file `out` that is an input, or a folder that holds one (a file is only
/// ever replaced whole, so the inputs' folders themselves are not at risk).
fn check_not_an_input(out: &Path, inputs: &[&Path]) -> Result<()> {
    let target = resolve(out)?;
    for input in inputs {
        let Ok(inp) = input.canonicalize() else {
            continue; // A missing input is the reader's error, with its own message.
        };
        let shown = input.display();
        if inp == target {
            return Err(refuse(
                out,
                format!("is the input {shown}; it would be overwritten: choose another name"),
            ));
        }
        if inp.starts_with(&target) {
            return Err(refuse(
                out,
                format!("contains the input {shown}: choose another name"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("relight-outfiles-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn ours(p: &Path) -> bool {
        std::fs::read(p).is_ok_and(|b| b.starts_with(b"ours"))
    }

    /// A file beside an input is fine (the folder holding the input is not replaced); the
    /// input itself, or a name that is a folder holding it, is refused.
    #[test]
    fn named_files_may_sit_beside_an_input_but_never_replace_it() {
        let d = scratch("files-input");
        let ws = d.join("ws");
        std::fs::create_dir_all(ws.join("sparse")).unwrap();
        std::fs::write(ws.join("mesh.ply"), "input").unwrap();
        let files = OutFiles::claim(&d, &["a.glb"], false, &[&ws], ours).unwrap();
        files.write("a.glb", b"ours").unwrap();
        let e = OutFiles::claim(&ws, &["mesh.ply"], true, &[&ws.join("mesh.ply")], |_| true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("is the input"), "{e}");
        let e = OutFiles::claim(&d, &["ws"], true, &[&ws.join("mesh.ply")], |_| true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("contains the input"), "{e}");
        assert_eq!(std::fs::read(ws.join("mesh.ply")).unwrap(), b"input");
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A previous result of the names is replaced only with `force`; a foreign file of one
    /// of the names never; nor one that appears after the claim.
    #[test]
    fn named_files_replace_only_their_own_earlier_output_and_only_with_force() {
        let d = scratch("files-own");
        let files = OutFiles::claim(&d, &["r.json", "r.md"], false, &[], ours).unwrap();
        files.write("r.json", b"ours 1").unwrap();
        files.write("r.json", b"ours 2").unwrap(); // its own file, within one claim
        let e = OutFiles::claim(&d, &["r.json", "r.md"], false, &[], ours)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--force"), "{e}");
        let files = OutFiles::claim(&d, &["r.json", "r.md"], true, &[], ours).unwrap();
        std::fs::write(d.join("r.md"), "appeared meanwhile").unwrap();
        files.write("r.json", b"ours 3").unwrap();
        let e = files.write("r.md", b"x").unwrap_err().to_string();
        assert!(e.contains("appeared while"), "{e}");
        assert_eq!(
            std::fs::read(d.join("r.md")).unwrap(),
            b"appeared meanwhile"
        );
        std::fs::write(d.join("f.json"), "[1]").unwrap();
        let e = OutFiles::claim(&d, &["f.json"], true, &[], ours)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a relight-cpc result"), "{e}");
        assert_eq!(std::fs::read(d.join("f.json")).unwrap(), b"[1]");
        let e = OutFiles::claim(Path::new("/"), &["x"], true, &[], ours)
            .unwrap_err()
            .to_string();
        assert!(e.contains("root folder"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
