//! Photos that add nothing (step 1 of the adaptive model, [`super`]): a training photo is
//! *redundant* when every vertex it observes (`α > 0`) is already observed by an earlier
//! kept photo from within [`DUPLICATE_ANGLE_DEG`] of the same direction and with the same
//! colour (every channel within [`DUPLICATE_RGB`] of it, relative to the brighter of the
//! two, plus one 8-bit step): the same view under the same light, no new equation of Eq. 9.

use crate::observe::Observations;

/// Viewing directions closer than this count as the same view (photo redundancy).
pub const DUPLICATE_ANGLE_DEG: f64 = 1.0;
/// Relative colour difference below which two observations count as the same.
pub const DUPLICATE_RGB: f64 = 0.02;

/// Photos (indices into `obs.photo_ranges`) that add no new observation (module docs,
/// step 1), each with the earlier kept photo it duplicates most.
pub fn redundant_photos(obs: &Observations, n_vertices: usize) -> Vec<(usize, usize)> {
    let cos_max = DUPLICATE_ANGLE_DEG.to_radians().cos();
    // Per vertex, the kept observations (indices) so far.
    let mut seen: Vec<Vec<usize>> = vec![Vec::new(); n_vertices];
    let mut out = Vec::new();
    let same = |p: usize, q: usize| -> bool {
        let (a, b) = (obs.dir[p], obs.dir[q]);
        let cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) as f64;
        cos >= cos_max
            && (0..3).all(|c| {
                let (y, z) = (obs.rgb[p][c] as f64, obs.rgb[q][c] as f64);
                (y - z).abs() <= DUPLICATE_RGB * y.max(z) + 1.0 / 255.0
            })
    };
    for (i, range) in obs.photo_ranges.iter().enumerate() {
        let useful: Vec<usize> = range.clone().filter(|&p| obs.weight[p] > 0.0).collect();
        let mut votes: Vec<usize> = Vec::new();
        let dup = !useful.is_empty()
            && useful.iter().all(|&p| {
                match seen[obs.vertex[p] as usize].iter().find(|&&q| same(p, q)) {
                    Some(&q) => {
                        votes.push(obs.photo[q] as usize);
                        true
                    }
                    None => false,
                }
            });
        if dup {
            votes.sort_unstable();
            let mut best = (0, votes[0]);
            let mut run = (0, votes[0]);
            for &v in &votes {
                run = if v == run.1 { (run.0 + 1, v) } else { (1, v) };
                if run.0 > best.0 {
                    best = run;
                }
            }
            out.push((i, best.1));
        } else {
            for &p in &useful {
                seen[obs.vertex[p] as usize].push(p);
            }
        }
    }
    out
}

/// `obs` without the photos `drop` (indices into `photo_ranges`), photo indices renumbered.
pub fn drop_photos(obs: &Observations, drop: &[usize]) -> Observations {
    let mut out = Observations::default();
    let mut new_index = 0u32;
    for (i, range) in obs.photo_ranges.iter().enumerate() {
        if drop.contains(&i) {
            continue;
        }
        let lo = out.vertex.len();
        for p in range.clone() {
            out.vertex.push(obs.vertex[p]);
            out.photo.push(new_index);
            out.rgb.push(obs.rgb[p]);
            out.weight.push(obs.weight[p]);
            out.dir.push(obs.dir[p]);
            if !obs.clipped.is_empty() {
                out.clipped.push(obs.clipped[p]);
                out.bound_weight.push(obs.bound_weight[p]);
            }
        }
        out.photo_ranges.push(lo..out.vertex.len());
        new_index += 1;
    }
    out
}
