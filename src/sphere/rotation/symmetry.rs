//! The eight mirror symmetries of the normal grid, which let [`super::Rotation`] build
//! `S_ν` for one normal in eight and copy the rest.
//!
//! Let `G` be one of the eight linear maps that keep `z` and permute or negate `x` and `y`
//! (the dihedral group of the square: `x ↦ ±x`, `y ↦ ±y`, optionally swapped first). The
//! full octahedral map (`|u| + |v| + |w|` folding) and its texel centres are invariant
//! under `G`, so `G` permutes the global texels and the normal grid's normals; the
//! hemi-octahedral local map is invariant under the same maps of the local `x, y`.
//!
//! The local frame ([`crate::sphere::local_frame`], Duff et al. 2017:
//! `x = (1 + a n_x², a n_x n_y, −n_x)`, `y = (a n_x n_y, 1 + a n_y², −n_y)`,
//! `a = −1/(1 + n_z)`) is equivariant: with `F(n) = [x y n]` as a matrix,
//!
//! `F(G n) = G F(n) L_G`,
//!
//! where `L_G` acts on local directions as `G` does on `x, y`, signs then swap: for
//! `G = (s_x, s_y, swap)`, `L_G(l) = (s_x l_x, s_y l_y, l_z)`, its two first components
//! exchanged when `swap`. (Negating `n_x` negates `a n_x n_y` and `n_x` and keeps
//! `1 + a n_x²`: `x ↦ −R_x x`, `y ↦ R_x y`; exchanging `n_x, n_y` exchanges `x` and `y`.)
//! So the world direction of local direction `l` at normal `G ν` is `G` of the world
//! direction of `L_G l` at `ν`, and every piece of `S_ν` (sub-texel directions, bilinear
//! taps, solid angles, the horizon mask, the Sinkhorn balancing) maps along:
//!
//! `S_{Gν}[j, G t] = S_ν[L_G j, t]`
//!
//! with `G t` and `L_G j` the texel permutations. The copy equals the direct construction
//! up to floating-point summation order (entries differ by at most an `f32` rounding;
//! test `symmetric_copies_match_the_direct_construction`).

use super::resampling::{resampling_flat_with, FlatRows, ResamplingGeometry};
use crate::sphere::SphereGrid;
use crate::Vec3;
use rayon::prelude::*;

/// `finish(S_ν)` for every normal `ν` of `normals` (in order), `S_ν` built for one normal
/// per orbit of the mirrors ([`NormalOrbits`]) and copied by permutation for the others;
/// only the built tables are held at once.
pub(super) fn by_symmetry<T: Send>(
    normals: &SphereGrid,
    geo: &ResamplingGeometry,
    finish: impl Fn(&FlatRows<f32>) -> T + Sync,
) -> Vec<T> {
    let orbits = NormalOrbits::new(normals, geo.global(), geo.local());
    let built: Vec<usize> = orbits.built().collect();
    let tables: Vec<FlatRows<f32>> = built
        .par_iter()
        .map(|&nu| {
            crate::stages::tick(1);
            resampling_flat_with(geo, &normals.texel_dir(nu))
        })
        .collect();
    let mut slot = vec![usize::MAX; normals.len()];
    for (k, &nu) in built.iter().enumerate() {
        slot[nu] = k;
    }
    (0..normals.len())
        .into_par_iter()
        .map(|nu| {
            let source = &tables[slot[orbits.source[nu]]];
            if orbits.source[nu] == nu {
                finish(source)
            } else {
                crate::stages::tick(1);
                finish(&orbits.copy(nu, source))
            }
        })
        .collect()
}

/// `G = (s_x, s_y, swap)`: `(x, y, z) ↦ (s_x x', s_y y', z)` with `(x', y') = (y, x)` when
/// `swap`, else `(x, y)` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Mirror {
    sx: f64,
    sy: f64,
    swap: bool,
}

impl Mirror {
    /// All eight, the identity first.
    pub(super) fn all() -> [Mirror; 8] {
        let mut out = [Mirror {
            sx: 1.0,
            sy: 1.0,
            swap: false,
        }; 8];
        for (k, m) in out.iter_mut().enumerate() {
            m.swap = k & 4 != 0;
            m.sx = if k & 1 != 0 { -1.0 } else { 1.0 };
            m.sy = if k & 2 != 0 { -1.0 } else { 1.0 };
        }
        out
    }

    /// `G d` in world (environment) coordinates.
    pub(super) fn world(&self, d: &Vec3) -> Vec3 {
        let (x, y) = if self.swap { (d.y, d.x) } else { (d.x, d.y) };
        Vec3::new(self.sx * x, self.sy * y, d.z)
    }

    /// `L_G l` in local coordinates: signs first, then the swap (module docs).
    pub(super) fn local(&self, l: &Vec3) -> Vec3 {
        let (x, y) = (self.sx * l.x, self.sy * l.y);
        if self.swap {
            Vec3::new(y, x, l.z)
        } else {
            Vec3::new(x, y, l.z)
        }
    }
}

/// The texel permutation `t ↦` the texel of `f(direction of t)` on `grid`, checked to be a
/// bijection that maps texel centres onto texel centres.
fn permutation(grid: &SphereGrid, f: impl Fn(&Vec3) -> Vec3) -> Vec<u32> {
    let perm: Vec<u32> = (0..grid.len())
        .map(|t| {
            let d = f(&grid.texel_dir(t));
            let image = grid.texel_of(&d);
            debug_assert!((grid.texel_dir(image) - d).norm() < 1e-9, "texel {t}");
            image as u32
        })
        .collect();
    debug_assert!({
        let mut seen = vec![false; perm.len()];
        perm.iter()
            .all(|&p| !std::mem::replace(&mut seen[p as usize], true))
    });
    perm
}

/// For every normal of the grid, the normal whose table it copies and the mirror that maps
/// that one onto it, with each mirror's texel permutations.
pub(super) struct NormalOrbits {
    /// `source[ν]`: the smallest index in `ν`'s orbit; `ν` itself for the built ones.
    source: Vec<usize>,
    /// `mirror[ν]`: index into [`Mirror::all`] of `G` with `G (direction of source[ν]) =
    /// direction of ν`.
    mirror: Vec<usize>,
    /// Per mirror: `G t` of every global texel `t`.
    perm_global: Vec<Vec<u32>>,
    /// Per mirror: `L_G j` of every local texel `j`.
    perm_local: Vec<Vec<u32>>,
}

impl NormalOrbits {
    /// Orbits of the normals of `normals` under [`Mirror::all`], for tables from the
    /// `global` map to the `local` one.
    pub(super) fn new(normals: &SphereGrid, global: &SphereGrid, local: &SphereGrid) -> Self {
        let mirrors = Mirror::all();
        let image = |nu: usize, g: &Mirror| normals.texel_of(&g.world(&normals.texel_dir(nu)));
        let source: Vec<usize> = (0..normals.len())
            .map(|nu| mirrors.iter().map(|g| image(nu, g)).min().unwrap_or(nu))
            .collect();
        let mirror = (0..normals.len())
            .map(|nu| {
                mirrors
                    .iter()
                    .position(|g| image(source[nu], g) == nu)
                    .unwrap_or(0)
            })
            .collect();
        NormalOrbits {
            source,
            mirror,
            perm_global: mirrors
                .iter()
                .map(|g| permutation(global, |d| g.world(d)))
                .collect(),
            perm_local: mirrors
                .iter()
                .map(|g| permutation(local, |d| g.local(d)))
                .collect(),
        }
    }

    /// The normals whose tables are built (one per orbit).
    pub(super) fn built(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.source.len()).filter(|&nu| self.source[nu] == nu)
    }

    /// `S_ν` from `S_{source[ν]}` (`rows`): row `j` is row `L_G j` of `rows` with its
    /// global texels mapped by `G`, re-sorted ascending.
    pub(super) fn copy(&self, nu: usize, rows: &FlatRows<f32>) -> FlatRows<f32> {
        let (perm_g, perm_l) = (
            &self.perm_global[self.mirror[nu]],
            &self.perm_local[self.mirror[nu]],
        );
        let mut out = FlatRows {
            offsets: Vec::with_capacity(rows.offsets.len()),
            entries: Vec::with_capacity(rows.entries.len()),
        };
        out.offsets.push(0);
        for &src in perm_l {
            let start = out.entries.len();
            out.entries.extend(
                rows.row(src as usize)
                    .iter()
                    .map(|&(t, w)| (perm_g[t as usize], w)),
            );
            out.entries[start..].sort_unstable_by_key(|e| e.0);
            out.offsets.push(out.entries.len() as u32);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::super::resampling::{resampling_rows, DEFAULT_SUPERSAMPLE};
    use super::super::{Rotation, RotationForm};
    use super::*;
    use crate::sphere::local_frame;

    #[test]
    fn the_local_frame_is_equivariant_under_every_mirror() {
        // F(G n) l = G F(n) L_G l (module docs) for normals all over the sphere and a
        // generic local direction. Tolerance 1e-12: a few f64 operations on unit vectors.
        let l = Vec3::new(0.3, -0.5, 0.81).normalize();
        for k in 0..200 {
            let z = -0.99 + 1.98 * (k as f64 + 0.5) / 200.0;
            let phi = 2.4 * k as f64;
            let r = (1.0 - z * z).sqrt();
            let n = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            for g in Mirror::all() {
                let lhs = crate::sphere::from_local(&local_frame(&g.world(&n)), &l);
                let rhs = g.world(&crate::sphere::from_local(&local_frame(&n), &g.local(&l)));
                assert!((lhs - rhs).norm() < 1e-12, "n {n:?}, {g:?}");
            }
        }
    }

    #[test]
    fn symmetric_copies_match_the_direct_construction() {
        // Every normal's table, copied or built, against `resampling_rows` for that normal,
        // applied to a generic global map: the copies differ from a direct build only in
        // the order of floating-point sums, so each local texel within 1e-6 of the map's
        // range (a few f32 roundings of weights that sum to 1).
        for (ng, nl, nn) in [(16, 8, 8), (8, 8, 4)] {
            let rot = Rotation::new(ng, nl, nn, RotationForm::Factored);
            let normals = SphereGrid::full(nn);
            let global: Vec<f64> = (0..ng * ng)
                .map(|t| ((t * 37 % 101) as f64) / 100.0)
                .collect();
            let mut local = vec![0.0; nl * nl];
            for nu in 0..normals.len() {
                rot.resample_texels(nu, &global, &mut local);
                let rows = resampling_rows(&normals.texel_dir(nu), ng, nl, DEFAULT_SUPERSAMPLE);
                for (j, row) in rows.iter().enumerate() {
                    let direct: f64 = row
                        .iter()
                        .map(|&(t, w)| w as f64 * global[t as usize])
                        .sum();
                    assert!(
                        (local[j] - direct).abs() < 1e-6,
                        "{ng}/{nl}/{nn} normal {nu} texel {j}"
                    );
                }
            }
        }
    }

    #[test]
    fn about_one_normal_in_eight_is_built() {
        // Orbits of the mirror group have 8 normals, but 4 on the diagonals x = ±y, which
        // hold 2n of the grid's texel centres (the axes x = 0 and y = 0 hold none on an
        // even grid): (n² − 2n)/8 + 2n/4 = n²/8 + n/4 orbits. Each normal's source maps
        // onto it by its mirror.
        for n in [4, 8, 32] {
            let normals = SphereGrid::full(n);
            let orbits = NormalOrbits::new(&normals, &SphereGrid::full(8), &SphereGrid::hemi(4));
            let built = orbits.built().count();
            assert_eq!(built, n * n / 8 + n / 4, "n {n}");
            for nu in 0..normals.len() {
                let g = Mirror::all()[orbits.mirror[nu]];
                let image = normals.texel_of(&g.world(&normals.texel_dir(orbits.source[nu])));
                assert_eq!(image, nu);
            }
        }
    }
}
