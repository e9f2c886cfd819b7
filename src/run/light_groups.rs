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
    Ok(groups_by_time(&scene.photo_paths(train), minutes))
}

/// Groups of the photos at `paths` by EXIF capture time (module docs); `None` when
/// `minutes` is 0 or fewer than two photos are dated.
pub fn groups_by_time(paths: &[&Path], minutes: f64) -> Option<LightGroups> {
    if minutes <= 0.0 || !minutes.is_finite() {
        return None;
    }
    let times: Vec<Option<i64>> = paths
        .iter()
        .map(|p| crate::import::photo::capture_time(p))
        .collect();
    let dated = times.iter().filter(|t| t.is_some()).count();
    if dated < 2 {
        return None;
    }
    let window = (minutes * 60.0).round() as i64;
    let g = LightGroups::from_labels(&time_labels(&times, window), String::new());
    let source = format!(
        "{} groups of the {} training photos by EXIF capture time within {minutes} min ({dated} photos dated)",
        g.n_groups(),
        paths.len()
    );
    Some(LightGroups { source, ..g })
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
    fn photos_group_by_their_exif_capture_times() {
        // Four JPEGs: two at 10:00:00 and 10:04:00, one at 10:30:00, one without EXIF (a
        // PNG). With a 5-minute window: {0, 1}, {2}, {3}; with 0 minutes: no groups.
        use crate::import::photo::tests::jpeg_with_capture_time;
        let dir = std::env::temp_dir().join(format!("relight-groups-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut paths = Vec::new();
        for (i, stamp) in [
            "2025:06:01 10:00:00",
            "2025:06:01 10:04:00",
            "2025:06:01 10:30:00",
        ]
        .iter()
        .enumerate()
        {
            let p = dir.join(format!("p{i}.jpg"));
            std::fs::write(&p, jpeg_with_capture_time(stamp)).unwrap();
            paths.push(p);
        }
        let plain = dir.join("p3.png");
        image::RgbImage::new(2, 2).save(&plain).unwrap();
        paths.push(plain);
        let refs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
        let g = groups_by_time(&refs, 5.0).unwrap();
        assert_eq!(g.group, vec![0, 0, 1, 2]);
        assert!(g.source.contains("3 photos dated"), "{}", g.source);
        assert!(groups_by_time(&refs, 0.0).is_none());
        // One dated photo alone groups nothing.
        assert!(groups_by_time(&refs[2..], 5.0).is_none());
        std::fs::remove_dir_all(&dir).unwrap();
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
