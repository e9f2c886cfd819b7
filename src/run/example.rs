//! The built-in example workspace, embedded in the binary.
//!
//! `build.rs` embeds every file of `examples/spot` (a small `synth` workspace made from real
//! data: the Spot mesh and real HDR maps; see `examples/README.md`). On first use the files
//! are unpacked into a cache folder (`$XDG_CACHE_HOME/relight-cpc`, else
//! `$HOME/.cache/relight-cpc`, else the system's temporary folder), in a subfolder named by
//! the tool's version and a hash of the embedded bytes (FNV-1a, 64 bit), so an installed
//! binary works from any folder and a new version never reads an old copy. The unpacking
//! goes to a temporary sibling renamed into place, so an interrupted unpack is never used.

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// `(path relative to the workspace, bytes)` of every file of the example.
static FILES: &[(&str, &[u8])] = include!(concat!(env!("OUT_DIR"), "/builtin_example.rs"));

/// FNV-1a (64 bit) over the files' names and bytes.
fn content_hash() -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for (name, bytes) in FILES {
        for &b in name.as_bytes().iter().chain(*bytes) {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

fn cache_root() -> PathBuf {
    let env_dir = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    env_dir("XDG_CACHE_HOME")
        .or_else(|| env_dir("HOME").map(|h| h.join(".cache")))
        .unwrap_or_else(std::env::temp_dir)
        .join("relight-cpc")
}

/// Write the embedded files below `dir`.
fn unpack_into(dir: &Path) -> Result<()> {
    for (rel, bytes) in FILES {
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        std::fs::write(&path, bytes).map_err(|e| Error::io(&path, e))?;
    }
    Ok(())
}

/// The built-in example's folder (`.../spot`), unpacked on first use.
pub fn builtin_example() -> Result<PathBuf> {
    if FILES.is_empty() {
        return Err(Error::Config(
            "this build has no built-in example; pass a COLMAP workspace folder".into(),
        ));
    }
    let base = cache_root().join(format!(
        "example-{}-{:016x}",
        env!("CARGO_PKG_VERSION"),
        content_hash()
    ));
    let ws = base.join("spot");
    if ws.join(".complete").is_file() {
        return Ok(ws);
    }
    let hint = |e: Error| {
        Error::Config(format!(
            "cannot unpack the built-in example into {}: {e}; pass a COLMAP workspace folder instead",
            base.display()
        ))
    };
    std::fs::create_dir_all(&base).map_err(|e| hint(Error::io(&base, e)))?;
    let tmp = base.join(format!("spot.partial-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    unpack_into(&tmp).map_err(hint)?;
    let marker = tmp.join(".complete");
    std::fs::write(&marker, b"").map_err(|e| hint(Error::io(&marker, e)))?;
    if std::fs::rename(&tmp, &ws).is_err() {
        // Another process unpacked it first (or a stale copy without the marker is there).
        let _ = std::fs::remove_dir_all(&tmp);
        if !ws.join(".complete").is_file() {
            std::fs::remove_dir_all(&ws).map_err(|e| hint(Error::io(&ws, e)))?;
            unpack_into(&ws).map_err(hint)?;
            std::fs::write(ws.join(".complete"), b"").map_err(|e| hint(Error::io(&ws, e)))?;
        }
    }
    Ok(ws)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unpacked example holds the same bytes as the source tree's examples/spot, file
    /// for file (the embedded list is complete and unaltered).
    #[test]
    fn unpacked_example_matches_the_source_tree() {
        let ws = builtin_example().unwrap();
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/spot");
        let mut n = 0;
        for (rel, bytes) in FILES {
            assert_eq!(std::fs::read(src.join(rel)).unwrap(), *bytes, "{rel}");
            assert_eq!(std::fs::read(ws.join(rel)).unwrap(), *bytes, "{rel}");
            n += 1;
        }
        assert!(
            n >= 5 && ws.join("sparse/images.txt").is_file(),
            "{n} files"
        );
    }
}
