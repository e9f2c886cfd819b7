//! The vertices the adaptive pilot reads ([`super`], step 2). Its decisions are statistics
//! of the scene (colour clusters, lobe shares, held-out scores), while its transport and
//! fits grow with the observations; so on a mesh with more than [`PILOT_MAX_VERTICES`]
//! seen vertices it reads a seeded sample of about that many ([`pilot_vertices`]) and
//! their observations ([`observations_of`]), and every vertex below that.

use std::borrow::Cow;

use super::mix64;
use crate::observe::Observations;

/// Most seen vertices the pilot fits ([`pilot_vertices`]). The pilot's
/// cost and memory grow with the observations: at 100K vertices × 13 photos of 1 MP with
/// every vertex it took 63 s of a 137 s run and set the run's peak (2,575 MiB, its
/// transport of 7 bases); its decisions are statistics of the scene (colour clusters,
/// lobe shares, held-out scores), which 25,000 vertices already estimate. Below this count
/// every vertex is fitted, as before: the built-in example and every mesh up to it are
/// unchanged.
pub const PILOT_MAX_VERTICES: usize = 25_000;
/// Fewest vertices `--pilot-vertices` may ask for (0 aside, every vertex): the pilot
/// clusters up to [`super::MAX_MATERIALS`] colours and scores every [`super::HELDOUT_EVERY`]-th
/// observation, so 100 leaves about 16 vertices a material at the cap and 20 vertices'
/// worth of held-out observations a photo sees. With 1 the sample held no seen vertex.
pub const PILOT_MIN_VERTICES: usize = 100;

/// The vertices the pilot fits: `None` (every vertex) when `max` is
/// 0 or at most `max` are seen; else the seen vertices whose seeded hash falls in one of
/// `m = ⌈seen / max⌉` buckets, about `seen / m` of them (at most about `max`), spread over
/// the mesh without regard to position, colour or photo.
pub fn pilot_vertices(seen: &[bool], max: usize, seed: u64) -> Option<Vec<bool>> {
    let n_seen = seen.iter().filter(|&&s| s).count();
    if max == 0 || n_seen <= max {
        return None;
    }
    let m = n_seen.div_ceil(max) as u64;
    let salt = seed ^ 0xA5A5_5A5A_C3C3_3C3C;
    Some(
        seen.iter()
            .enumerate()
            .map(|(v, &s)| s && mix64(salt, v as u64).is_multiple_of(m))
            .collect(),
    )
}

/// The observations of the vertices `keep`, in their order ([`Observations::gather`]).
pub fn observations_of(obs: &Observations, keep: &[bool]) -> Observations {
    let index: Vec<usize> = (0..obs.len())
        .filter(|&p| keep.get(obs.vertex[p] as usize).copied().unwrap_or(false))
        .collect();
    obs.gather(&index)
}

/// What the pilot reads: the observations and seen vertices of its sample, with the note
/// its material decision carries, or the run's own when every vertex is read.
pub(super) struct PilotView<'a> {
    /// The observations, before the pilot's held-out split.
    pub(super) obs: Cow<'a, Observations>,
    /// The seen vertices among them (k-means clusters these).
    pub(super) seen: Cow<'a, [bool]>,
    /// `"; every pilot fit ran on N of the M seen vertices …"`, when sampled.
    pub(super) note: Option<String>,
}

impl<'a> PilotView<'a> {
    /// The view of at most about `max` seen vertices ([`pilot_vertices`]; 0 = every one).
    pub(super) fn new(obs: &'a Observations, seen: &'a [bool], max: usize, seed: u64) -> Self {
        let Some(keep) = pilot_vertices(seen, max, seed) else {
            return PilotView {
                obs: Cow::Borrowed(obs),
                seen: Cow::Borrowed(seen),
                note: None,
            };
        };
        let count = |s: &[bool]| s.iter().filter(|&&v| v).count();
        let note = format!(
            "; every pilot fit ran on {} of the {} seen vertices (a seeded sample of about {max}, --pilot-vertices)",
            count(&keep),
            count(seen)
        );
        PilotView {
            obs: Cow::Owned(observations_of(obs, &keep)),
            seen: Cow::Owned(keep),
            note: Some(note),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pilot_samples_seen_vertices_only_above_its_cap() {
        // 100,000 vertices, every 5th unseen: 80,000 seen.
        let seen: Vec<bool> = (0..100_000).map(|v| v % 5 != 0).collect();
        // At or below the cap (or with 0, no cap) every vertex is fitted.
        assert!(pilot_vertices(&seen, 80_000, 1).is_none());
        assert!(pilot_vertices(&seen, 0, 1).is_none());
        let keep = pilot_vertices(&seen, PILOT_MAX_VERTICES, 1).expect("a sample");
        // m = ⌈80,000 / 25,000⌉ = 4 buckets: each seen vertex is kept with probability
        // 1/4, so the count is binomial(80,000, 1/4), mean 20,000, standard deviation
        // √(80,000 · 1/4 · 3/4) = 122.5; the tolerance is 5 of them (a fair hash fails it
        // with probability below 10⁻⁶).
        let n = keep.iter().filter(|&&k| k).count();
        assert!((n as f64 - 20_000.0).abs() < 5.0 * 122.5, "{n} kept");
        assert!(n <= PILOT_MAX_VERTICES);
        // Never an unseen vertex.
        assert!(keep.iter().zip(&seen).all(|(&k, &s)| s || !k));
        // Each quarter of the index range gets its share (the same binomial bound on
        // 20,000 seen vertices: mean 5,000, standard deviation 61.2).
        for q in keep.chunks(25_000) {
            let c = q.iter().filter(|&&k| k).count();
            assert!(
                (c as f64 - 5_000.0).abs() < 5.0 * 61.2,
                "{c} kept in a quarter"
            );
        }
        // The same seed gives the same sample; another seed another one.
        assert_eq!(
            pilot_vertices(&seen, PILOT_MAX_VERTICES, 1),
            Some(keep.clone())
        );
        let other = pilot_vertices(&seen, PILOT_MAX_VERTICES, 2).expect("a sample");
        let shared = keep.iter().zip(&other).filter(|(&a, &b)| a && b).count();
        // Independent samples share about 1/16 of the seen vertices (5,000).
        assert!(
            (shared as f64 - 5_000.0).abs() < 5.0 * 68.5,
            "{shared} shared"
        );
    }

    #[test]
    fn the_pilot_reads_every_observation_of_its_vertices_and_no_other() {
        // Two photos: photo 0 sees vertices 0, 1, 2; photo 1 sees 1, 2, 3.
        let vertex = vec![0, 1, 2, 1, 2, 3];
        let n = vertex.len();
        let obs = Observations {
            vertex,
            photo: vec![0, 0, 0, 1, 1, 1],
            rgb: (0..n).map(|p| [p as f32; 3]).collect(),
            weight: vec![1.0; n],
            dir: vec![[0.0, 0.0, 1.0]; n],
            photo_ranges: vec![0..3, 3..6],
            clipped: Vec::new(),
            bound_weight: Vec::new(),
        };
        let sub = observations_of(&obs, &[false, true, false, true]);
        assert_eq!(sub.vertex, vec![1, 1, 3]);
        assert_eq!(sub.rgb, vec![[1.0; 3], [3.0; 3], [5.0; 3]]);
        assert_eq!(sub.photo, vec![0, 1, 1]);
        assert_eq!(sub.photo_ranges, vec![0..1, 1..3]);
    }
}
