//! Which photos a run holds out when the user does not say (issue 27): on a synthetic
//! workspace the truth manifest's list; on any other workspace every
//! [`DEFAULT_HOLDOUT_EVERY`]-th registered photo in name order, and at least one when
//! there are two or more (the last), so a real workspace is judged on photos the fit never
//! saw unless `--holdout none` asks otherwise. A lone photo is never held out: the fit
//! needs one.

/// The default stride on workspaces without truth: one photo in five is held out.
pub const DEFAULT_HOLDOUT_EVERY: usize = 5;

/// Indices (into the name-ordered registered views) of the default held-out photos of a
/// workspace without truth: every [`DEFAULT_HOLDOUT_EVERY`]-th, starting with the
/// [`DEFAULT_HOLDOUT_EVERY`]-th; the last when that picks none and there are at least two.
pub fn default_holdout(n_views: usize) -> Vec<usize> {
    let every: Vec<usize> = (0..n_views)
        .filter(|i| (i + 1) % DEFAULT_HOLDOUT_EVERY == 0)
        .collect();
    if every.is_empty() && n_views >= 2 {
        vec![n_views - 1]
    } else {
        every
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_fifth_at_least_one_never_the_only_photo() {
        assert_eq!(default_holdout(0), Vec::<usize>::new());
        assert_eq!(default_holdout(1), Vec::<usize>::new());
        assert_eq!(default_holdout(2), vec![1]);
        assert_eq!(default_holdout(4), vec![3]);
        assert_eq!(default_holdout(5), vec![4]);
        assert_eq!(default_holdout(12), vec![4, 9]);
        // Never all of them: at least n − ⌈n/5⌉ photos stay for the fit.
        for n in 2..40 {
            let h = default_holdout(n);
            assert!(!h.is_empty() && h.len() < n, "{n}: {h:?}");
        }
    }
}
