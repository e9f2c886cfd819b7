//! Which training photos share a sky (`--light shared`,
//! [`crate::solve::light::shared`]): from the user's groups file (`--light-groups FILE`),
//! else from the photos' EXIF capture times ([`crate::import::photo::capture_time`]).
//!
//! The groups file is text, one photo a line: the photo's name as the workspace lists it
//! (COLMAP's image name), whitespace, and a group label (the last word of the line). Blank
//! lines and lines starting with `#` are skipped. Training photos the file does not name
//! keep a map of their own.
//!
//! By time: photos are sorted by capture time and a photo joins the group of the one
//! before it when they were taken at most `--light-group-minutes` apart (single linkage:
//! a slow walk round the object stays one group). Photos without a capture time keep a
//! map of their own.

use std::path::Path;

use crate::import::scene::Scene;
use crate::solve::light::shared::LightGroups;
use crate::{Error, Result};

/// One line of a groups file: a photo and its group label.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupEntry {
    /// The photo's name.
    pub photo: String,
    /// Its group label.
    pub group: String,
}

/// Parses a groups file's `text` (module docs); `known` are the workspace's photo names.
/// Errors name `path`, the line and what is wrong.
pub fn parse_groups(path: &Path, text: &str, known: &[&str]) -> Result<Vec<GroupEntry>> {
    let mut out: Vec<GroupEntry> = Vec::new();
    let bad = |line: usize, message: String| Error::Format {
        path: path.to_path_buf(),
        location: format!("line {line}"),
        message,
    };
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((photo, group)) = line.rsplit_once(char::is_whitespace) else {
            return Err(bad(
                i + 1,
                format!("`{line}`: expected a photo name, then its group label"),
            ));
        };
        let photo = photo.trim_end();
        if !known.contains(&photo) {
            return Err(bad(
                i + 1,
                format!(
                    "`{photo}` is not a photo of this workspace (names as the workspace lists them, e.g. `{}`)",
                    known.first().unwrap_or(&"")
                ),
            ));
        }
        if let Some(prev) = out.iter().find(|e| e.photo == photo) {
            return Err(bad(
                i + 1,
                format!(
                    "`{photo}` is already in group `{}` on an earlier line",
                    prev.group
                ),
            ));
        }
        out.push(GroupEntry {
            photo: photo.to_string(),
            group: group.to_string(),
        });
    }
    Ok(out)
}

/// Group labels by capture time (module docs): photos at most `window_s` seconds after
/// the previous one (in time order) share its label; photos without a time get labels of
/// their own. Labels are arbitrary distinct numbers.
pub fn time_labels(times: &[Option<i64>], window_s: i64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..times.len()).filter(|&i| times[i].is_some()).collect();
    order.sort_by_key(|&i| (times[i], i));
    let mut label: Vec<usize> = (0..times.len()).collect();
    for w in order.windows(2) {
        let (a, b) = (w[0], w[1]);
        if let (Some(ta), Some(tb)) = (times[a], times[b]) {
            if tb - ta <= window_s {
                label[b] = label[a];
            }
        }
    }
    label
}

/// The groups of the training views `train` (indices into `scene.views`), or `None` when
/// neither a file nor capture times give any.
pub(crate) fn resolve(
    file: Option<&Path>,
    minutes: f64,
    scene: &Scene,
    train: &[usize],
) -> Result<Option<LightGroups>> {
    let names: Vec<&str> = scene.views.iter().map(|v| v.image.name.as_str()).collect();
    if let Some(path) = file {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let entries = parse_groups(path, &text, &names)?;
        let labels: Vec<String> = train
            .iter()
            .map(|&v| {
                let name = names[v];
                entries
                    .iter()
                    .find(|e| e.photo == name)
                    .map_or_else(|| format!("\u{0}photo {name}"), |e| e.group.clone())
            })
            .collect();
        let g = LightGroups::from_labels(&labels, String::new());
        let source = format!(
            "{} groups of the {} training photos from {}",
            g.n_groups(),
            train.len(),
            path.display()
        );
        return Ok(Some(LightGroups { source, ..g }));
    }
    if minutes <= 0.0 || !minutes.is_finite() {
        return Ok(None);
    }
    let times: Vec<Option<i64>> = train
        .iter()
        .map(|&v| crate::import::photo::capture_time(&scene.views[v].photo_path))
        .collect();
    let dated = times.iter().filter(|t| t.is_some()).count();
    if dated < 2 {
        return Ok(None);
    }
    let window = (minutes * 60.0).round() as i64;
    let g = LightGroups::from_labels(&time_labels(&times, window), String::new());
    let source = format!(
        "{} groups of the {} training photos by EXIF capture time within {minutes} min ({dated} photos dated)",
        g.n_groups(),
        train.len()
    );
    Ok(Some(LightGroups { source, ..g }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_labels_chain_photos_within_the_window() {
        // 0 s, 100 s, 250 s chain with a 150 s window (gaps 100 and 150); 1000 s is alone;
        // the undated photo keeps its own label.
        let times = [Some(250), Some(0), None, Some(1000), Some(100)];
        let l = time_labels(&times, 150);
        assert_eq!(l[0], l[1]);
        assert_eq!(l[4], l[1]);
        assert_ne!(l[3], l[1]);
        assert_ne!(l[2], l[1]);
        assert_ne!(l[2], l[3]);
        // A gap of one second more than the window splits.
        let l = time_labels(&[Some(0), Some(151)], 150);
        assert_ne!(l[0], l[1]);
    }

    #[test]
    fn groups_file_reads_names_with_spaces_and_rejects_bad_lines() {
        let p = Path::new("groups.txt");
        let known = ["a.jpg", "my photo.jpg", "c.jpg"];
        let ok = parse_groups(p, "# sky\n\na.jpg morning\nmy photo.jpg  noon\n", &known).unwrap();
        assert_eq!(ok.len(), 2);
        assert_eq!(ok[1].photo, "my photo.jpg");
        assert_eq!(ok[1].group, "noon");
        let e = parse_groups(p, "a.jpg x\nlonely\n", &known)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("groups.txt: line 2") && e.contains("lonely"),
            "{e}"
        );
        let e = parse_groups(p, "b.jpg x\n", &known)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 1") && e.contains("`b.jpg` is not a photo"),
            "{e}"
        );
        let e = parse_groups(p, "a.jpg x\na.jpg y\n", &known)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 2") && e.contains("already in group `x`"),
            "{e}"
        );
    }
}
