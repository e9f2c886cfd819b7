//! Up-front memory estimate of a run, checked before anything large is allocated.
//!
//! The large arrays of the method and their sizes (bytes), from the data structures that
//! hold them:
//!
//! - observations `P` (one per vertex × photo that sees it, [`crate::observe::Observations`]):
//!   vertex and photo ids, RGB, weight, direction — `36 P`;
//! - visibility `V_x` (Sec. 4.2, one byte per local texel, [`crate::transport::visibility::Visibility`]):
//!   `V · n_local²`, and the renderer's finer copy `V · n_render²` when
//!   `--render-local-resolution` differs (traced once at the finer side, averaged down for
//!   the estimator);
//! - precomputed rotations `R_ν` (Eq. 6, [`crate::sphere::rotation::Rotation`], factored form): one
//!   sparse row per local texel and grid normal, `n_normals² · n_local² · (8 + 6 e)` where a
//!   row touches `e ≈ (n_global / (√2 n_local) + 2)²` global texels (a local texel covers
//!   `n_global² / (2 n_local²)` global ones, plus the bilinear border; 11.7 at the defaults,
//!   measured 11.3);
//! - the photos, decoded at import and kept for the evaluation and the renders: linear
//!   RGB `f32` and an overexposure flag per pixel — `13 · pixels` over all photos;
//! - transport rows `T_x ρ_b` (Eq. 7–8, [`crate::transport::Transport`]): `P · B` rows of `keep`
//!   (index `u16`, value in half precision) entries plus an offset — `P · B · (4 keep + 8)`; the same
//!   for the held-out photos' observations (the held-out error tracked per iteration),
//!   counted as `min(P · held / photos, HELD_OUT_TRACKED_MAX)` observations before they
//!   are extracted (the tracker keeps at most [`HELD_OUT_TRACKED_MAX`]);
//! - the lighting step's merged rows (Eq. 10, one photo's rows merged with `β` into one
//!   sparse row per observation: `u32` index and three `f32`): one photo per worker thread
//!   at a time, `min(threads, photos) · (P / photos) · MERGED_FRACTION · B · keep · 16`,
//!   where [`MERGED_FRACTION`] (the union of an observation's `B` rows over their total
//!   length) was measured;
//! - the lighting solver (Eq. 10): per photo three channels of `n_global²` Haar coefficients
//!   in `f64`, and about [`SOLVER_VECTORS`] such vectors of GPCG / IRLS workspace —
//!   `photos · 3 · n_global² · 8 · SOLVER_VECTORS`.
//!
//! [`Budget::check`] compares the total with the available memory (a fraction
//! [`USABLE_FRACTION`] of `MemAvailable`, leaving room for the allocator and smaller
//! arrays) and, when it does not fit, returns [`Error::Memory`] naming the largest item and
//! one option change (`--keep`, `--local-resolution`, `--global-resolution`,
//! `--normal-grid`, or decimating the mesh) that would make the whole run fit.

use crate::{Error, Result};

/// Workspace vectors (of `3 · n_global²` f64 per photo) the lighting solver keeps: the
/// solution, gradient, projected gradient, search direction, `Aᵀ D y`, Laplacian product,
/// previous iterate and IRLS weights-related copy.
pub const SOLVER_VECTORS: u64 = 8;

/// Fraction of `MemAvailable` a run may plan to use.
pub const USABLE_FRACTION: f64 = 0.8;

/// Bytes per observation (`u32` vertex, `u32` photo, `[f32; 3]` rgb, `f32` weight,
/// `[f32; 3]` direction).
pub const OBSERVATION_BYTES: u64 = 36;

/// Held-out observations the per-iteration held-out tracker keeps at most (every `k`-th).
pub const HELD_OUT_TRACKED_MAX: u64 = 20_000;

/// Bytes per kept transport entry (`u16` Haar index, half-precision value).
pub const TRANSPORT_ENTRY_BYTES: u64 = (std::mem::size_of::<crate::transport::HaarIndex>()
    + std::mem::size_of::<crate::transport::TransportValue>())
    as u64;

/// Bytes per decoded photo pixel (`[f32; 3]` linear RGB, `bool` overexposed).
pub const PIXEL_BYTES: u64 = 13;

/// Entries of an observation's merged lighting row over the `B · keep` entries of its
/// basis rows (the rows of one vertex share most of their coarse Haar coefficients). An
/// upper bound from the measured peaks (`bench-results/archive/pipeline-scaling.md`): at 11,714
/// vertices, 7 bases, keep 128, the estimate stage peaked 24 MiB above the transport
/// stage, where 0.5 predicts 52 MiB.
pub const MERGED_FRACTION: f64 = 0.5;

/// The sizes that decide a run's memory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sizes {
    /// Mesh vertices `V`.
    pub vertices: u64,
    /// Photos used for fitting.
    pub photos: u64,
    /// Held-out photos (their observations get transport rows too).
    pub held_photos: u64,
    /// Pixels of all decoded photos (training and held out).
    pub photo_pixels: u64,
    /// Worker threads (each merges one photo's lighting rows at a time).
    pub threads: u64,
    /// Observations `P` (an upper bound before extraction: [`Sizes::observations_upper_bound`]).
    pub observations: u64,
    /// Basis BRDFs `B`.
    pub basis: u64,
    /// Global map side `n_global` (`--global-resolution`).
    pub global_resolution: u64,
    /// Local map side `n_local` (`--local-resolution`).
    pub local_resolution: u64,
    /// The renderer's local map side `n_render` (`--render-local-resolution`); equal to
    /// `local_resolution` (or 0) when the renderer shares the estimator's visibility.
    pub render_local_resolution: u64,
    /// Normal-grid side of the rotation tables (`--normal-grid`).
    pub normal_grid: u64,
    /// Kept coefficients per transport row (`--keep`; 0 keeps all `n_global²`).
    pub keep: u64,
}

impl Sizes {
    /// At most every vertex in every photo, and at most one observation per pixel.
    pub fn observations_upper_bound(vertices: u64, photos: u64, total_pixels: u64) -> u64 {
        vertices.saturating_mul(photos).min(total_pixels)
    }

    fn kept(&self) -> u64 {
        let full = self
            .global_resolution
            .saturating_mul(self.global_resolution);
        if self.keep == 0 {
            full
        } else {
            self.keep.min(full)
        }
    }
}

/// One line of the estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// What is stored.
    pub name: &'static str,
    /// Estimated bytes.
    pub bytes: u64,
}

/// The estimate: one [`Item`] per large array.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// The sizes it was computed from.
    pub sizes: Sizes,
    /// The items, in pipeline order.
    pub items: Vec<Item>,
}

fn mul(xs: &[u64]) -> u64 {
    xs.iter().fold(1u64, |a, &x| a.saturating_mul(x))
}

/// Global texels touched by one row of `S_ν` (module docs).
fn rotation_row_entries(n_global: u64, n_local: u64) -> f64 {
    let r = n_global as f64 / (std::f64::consts::SQRT_2 * n_local.max(1) as f64) + 2.0;
    r * r
}

/// The memory estimate for `s` (saturating: absurd sizes give `u64::MAX`, never overflow).
pub fn estimate(s: &Sizes) -> Budget {
    let nl2 = mul(&[s.local_resolution, s.local_resolution]);
    let ng2 = mul(&[s.global_resolution, s.global_resolution]);
    let rot_row = 8.0 + 6.0 * rotation_row_entries(s.global_resolution, s.local_resolution);
    let rot_rows = mul(&[s.normal_grid, s.normal_grid, nl2]) as f64;
    let rotation = (rot_rows * rot_row).min(u64::MAX as f64) as u64;
    let items = vec![
        Item {
            name: "observations",
            bytes: mul(&[s.observations, OBSERVATION_BYTES]),
        },
        Item {
            name: "visibility",
            bytes: mul(&[s.vertices, nl2]),
        },
        Item {
            name: "render visibility",
            bytes: if s.render_local_resolution == s.local_resolution {
                0
            } else {
                mul(&[
                    s.vertices,
                    s.render_local_resolution,
                    s.render_local_resolution,
                ])
            },
        },
        Item {
            name: "rotation tables",
            bytes: rotation,
        },
        Item {
            name: "photos",
            bytes: mul(&[s.photo_pixels, PIXEL_BYTES]),
        },
        Item {
            name: "transport rows",
            bytes: mul(&[
                s.observations,
                s.basis,
                s.kept()
                    .saturating_mul(TRANSPORT_ENTRY_BYTES)
                    .saturating_add(8),
            ]),
        },
        Item {
            name: "held-out transport rows",
            bytes: mul(&[
                (s.observations.saturating_mul(s.held_photos) / s.photos.max(1))
                    .min(HELD_OUT_TRACKED_MAX),
                s.basis,
                s.kept()
                    .saturating_mul(TRANSPORT_ENTRY_BYTES)
                    .saturating_add(8),
            ]),
        },
        Item {
            name: "lighting merged rows",
            bytes: {
                let per_photo = s.observations.div_ceil(s.photos.max(1)) as f64;
                let merged = (MERGED_FRACTION * mul(&[s.basis, s.kept()]) as f64).ceil();
                let b = s.threads.clamp(1, s.photos.max(1)) as f64 * per_photo * merged * 16.0;
                b.min(u64::MAX as f64) as u64
            },
        },
        Item {
            name: "lighting solver",
            bytes: mul(&[s.photos, 3, ng2, 8, SOLVER_VECTORS]),
        },
    ];
    Budget { sizes: *s, items }
}

impl Budget {
    /// Sum of the items (saturating).
    pub fn total(&self) -> u64 {
        self.items
            .iter()
            .fold(0u64, |a, i| a.saturating_add(i.bytes))
    }

    /// The largest item.
    pub fn largest(&self) -> &Item {
        self.items
            .iter()
            .max_by_key(|i| i.bytes)
            .unwrap_or(&self.items[0])
    }

    /// `Ok` when the total fits in `available_bytes`; otherwise [`Error::Memory`] naming the
    /// largest item and one option change that would make the run fit.
    pub fn check(&self, available_bytes: u64) -> Result<()> {
        let total = self.total();
        if total <= available_bytes {
            return Ok(());
        }
        let largest = self.largest();
        Err(Error::Memory {
            what: format!(
                "the run ({} of {} in total; {})",
                largest.name,
                mib(largest.bytes),
                self.items
                    .iter()
                    .map(|i| format!("{} {}", i.name, mib(i.bytes)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            needed_bytes: total,
            available_bytes,
            hint: suggest(&self.sizes, available_bytes),
        })
    }
}

fn mib(b: u64) -> String {
    format!("{:.0} MiB", b as f64 / (1024.0 * 1024.0))
}

/// The mildest single option change that makes the run fit, or the vertex count to
/// decimate the mesh to.
///
/// Each option is lowered alone, never below the CLI's minimum: `--keep` to the largest
/// count that fits, the map sides and the normal grid halved until they fit. The change of
/// the smallest factor wins (the first of equal ones, in that order). When none fits, the
/// mesh is decimated (observations scale with vertices).
fn suggest(s: &Sizes, available: u64) -> String {
    let fits = |t: &Sizes| estimate(t).total() <= available;
    let halved = |name: &str, v: u64, min: u64, set: &dyn Fn(u64) -> Sizes| {
        halving_hint(name, v, min, &|x| fits(&set(x)))
    };
    let hints = [
        keep_hint(s, &fits),
        halved("local-resolution", s.local_resolution, 4, &|x| Sizes {
            local_resolution: x,
            ..*s
        }),
        halved(
            "render-local-resolution",
            s.render_local_resolution,
            s.local_resolution.max(4),
            &|x| Sizes {
                render_local_resolution: x,
                ..*s
            },
        ),
        halved("normal-grid", s.normal_grid, 4, &|x| Sizes {
            normal_grid: x,
            ..*s
        }),
        halved("global-resolution", s.global_resolution, 4, &|x| Sizes {
            global_resolution: x,
            ..*s
        }),
    ];
    let mut best: Option<(u64, String)> = None;
    for (factor, text) in hints.into_iter().flatten() {
        if best.as_ref().is_none_or(|(f, _)| factor < *f) {
            best = Some((factor, text));
        }
    }
    if let Some((_, text)) = best {
        return text;
    }
    if s.vertices > 1 {
        let lo = largest_fitting(s.vertices, |mid| {
            fits(&Sizes {
                vertices: mid,
                observations: ((s.observations as u128 * mid as u128) / s.vertices as u128) as u64,
                ..*s
            })
        });
        if lo >= 1 {
            return format!(
                "no single option fits; decimate the mesh (--mesh) to about {lo} vertices"
            );
        }
    }
    "no option change fits; use fewer photos or a machine with more memory".into()
}

/// `--keep`: the largest count that fits, and the factor it lowers the kept count by.
fn keep_hint(s: &Sizes, fits: &dyn Fn(&Sizes) -> bool) -> Option<(u64, String)> {
    let kept = s.kept();
    if kept <= 1 {
        return None;
    }
    // `largest_fitting` returns a count it saw fit, or 0.
    let lo = largest_fitting(kept, |mid| fits(&Sizes { keep: mid, ..*s }));
    (lo >= 1).then(|| (kept.div_ceil(lo), format!("--keep {lo} would fit")))
}

/// `--NAME`: `v` halved until it fits (`fits`), not below `min`; the factor and the hint.
fn halving_hint(name: &str, v: u64, min: u64, fits: &dyn Fn(u64) -> bool) -> Option<(u64, String)> {
    let mut x = v / 2;
    while x >= min {
        if fits(x) {
            return Some((v / x, format!("--{name} {x} would fit")));
        }
        x /= 2;
    }
    None
}

/// Bisection on `(0, hi)` for the largest value where `fits` holds, `fits` taken to be
/// monotone (true up to a point, false after); 0 when it holds nowhere below `hi`.
fn largest_fitting(hi: u64, fits: impl Fn(u64) -> bool) -> u64 {
    let (mut lo, mut hi) = (0u64, hi);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// [`estimate`] checked against [`crate::stages::available_memory_bytes`] (× [`USABLE_FRACTION`]);
/// when the available memory is unknown the check passes.
pub fn check(s: &Sizes) -> Result<Budget> {
    let budget = estimate(s);
    if let Some(avail) = crate::stages::available_memory_bytes() {
        budget.check((avail as f64 * USABLE_FRACTION) as u64)?;
    }
    Ok(budget)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn defaults(vertices: u64, photos: u64) -> Sizes {
        Sizes {
            vertices,
            photos,
            held_photos: 1,
            photo_pixels: (photos + 1) * 1000,
            threads: 2,
            observations: vertices * photos,
            basis: 3,
            global_resolution: 64,
            local_resolution: 32,
            render_local_resolution: 64,
            normal_grid: 32,
            keep: 128,
        }
    }

    #[test]
    fn items_match_hand_counts() {
        // Independent hand count from the module's formulas: 1000 vertices × 4 photos.
        let b = estimate(&defaults(1000, 4));
        let get = |n: &str| b.items.iter().find(|i| i.name == n).unwrap().bytes;
        assert_eq!(get("observations"), 4000 * 36);
        assert_eq!(get("visibility"), 1000 * 1024);
        assert_eq!(get("render visibility"), 1000 * 4096);
        let shared = estimate(&Sizes {
            render_local_resolution: 32,
            ..defaults(1000, 4)
        });
        assert_eq!(
            shared
                .items
                .iter()
                .find(|i| i.name == "render visibility")
                .unwrap()
                .bytes,
            0
        );
        assert_eq!(get("transport rows"), 4000 * 3 * (128 * 4 + 8));
        // One held-out photo of four training ones: a quarter of the observations.
        assert_eq!(get("held-out transport rows"), 1000 * 3 * (128 * 4 + 8));
        // … and never more than the tracker keeps (100K vertices: 100,000 would be a quarter).
        let big = estimate(&defaults(100_000, 4));
        let held = big
            .items
            .iter()
            .find(|i| i.name == "held-out transport rows");
        assert_eq!(held.unwrap().bytes, 20_000 * 3 * (128 * 4 + 8));
        assert_eq!(get("photos"), 5000 * 13);
        // Two threads, 1000 observations per photo, ⌈f · 3 · 128⌉ merged entries of 16 B.
        let merged = (MERGED_FRACTION * 384.0).ceil() as u64;
        assert_eq!(get("lighting merged rows"), 2 * 1000 * merged * 16);
        assert_eq!(get("lighting solver"), 4 * 3 * 4096 * 8 * 8);
        // Rotation: the commit log measured 72 MiB at 64/32/32 (rotation.rs, c8979c3);
        // the estimate must be within 10 % of that.
        let rot = get("rotation tables") as f64 / (1024.0 * 1024.0);
        assert!((rot - 72.0).abs() < 7.2, "rotation {rot} MiB");
    }

    #[test]
    fn million_vertices_refused_with_option() {
        // 1.2 M vertices, 4 photos: transport 4.8 M × 3 × 520 B ≈ 7.0 GiB, visibility 1.2 GiB.
        let s = defaults(1_200_000, 4);
        let b = estimate(&s);
        let avail = 8u64 << 30;
        let err = b.check(avail).unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, Error::Memory { .. }));
        assert!(text.contains("transport rows"), "{text}");
        assert!(text.contains("--keep"), "{text}");
        // The suggestion is honest: the suggested keep fits, keep+1 does not.
        let k: u64 = text
            .split("--keep ")
            .nth(1)
            .and_then(|t| t.split_whitespace().next())
            .and_then(|t| t.parse().ok())
            .unwrap();
        assert!(estimate(&Sizes { keep: k, ..s }).total() <= avail);
        assert!(estimate(&Sizes { keep: k + 1, ..s }).total() > avail);
    }

    #[test]
    fn decimation_when_no_option_fits() {
        // 50 M vertices: visibility alone at n_local = 4 is 800 MB > 512 MiB.
        let s = defaults(50_000_000, 2);
        let err = estimate(&s).check(512 << 20).unwrap_err().to_string();
        assert!(err.contains("decimate the mesh"), "{err}");
    }

    #[test]
    fn small_run_fits_and_absurd_sizes_saturate() {
        assert!(estimate(&defaults(2500, 4)).check(1 << 30).is_ok());
        let huge = Sizes {
            vertices: u64::MAX,
            observations: u64::MAX,
            ..defaults(1, 1)
        };
        let b = estimate(&huge);
        assert_eq!(b.total(), u64::MAX);
        assert!(b.check(u64::MAX - 1).is_err());
    }

    #[test]
    fn observation_bound() {
        assert_eq!(Sizes::observations_upper_bound(10, 3, 1000), 30);
        assert_eq!(
            Sizes::observations_upper_bound(1_000_000, 3, 64 * 64 * 3),
            12288
        );
    }
}
