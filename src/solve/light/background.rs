//! The background term of the lighting step (beyond the paper): each photo's background
//! pixels observe its map directly ([`crate::observe::background`]), so the photo's map
//! `x_{I,c}` (texels, the QP's variables) is pulled toward them:
//!
//! `E_bg,I = γ Σ_t n_{I,t} Σ_c (x_{I,t,c} − ȳ_{I,t,c})²`,
//!
//! `n_{I,t}` the photo's background pixels in texel `t` and `ȳ` their mean; `γ` weighs one
//! pixel against one observation of confidence 1 (the data term is `Σ_p α_p r_p²`). It is
//! a diagonal quadratic. The QP `min ½ xᵀ H x − bᵀ x` is `½ F` (as the data term
//! `Σ α r²` and the Laplacian's `μ ‖Δ x‖²` enter it), so it gains `a_t = γ n_t` on the
//! texel's diagonal of `H` and of the Jacobi scaling, and `a_t ȳ_{t,c}` in `b`.
//!
//! Unlike every other term of `F`, it is not invariant under `x → s x`, `β → β / s`: the
//! background fixes the scale between the maps and the reflectance, per channel, and with
//! it how bright each map is toward the directions the cameras look at. That is the point:
//! a free map per photo can trade brightness between directions for albedo ratios, and
//! the background pins the map in the directions it shows.

use crate::observe::background::{BackgroundLight, BackgroundTexel};

/// The background term of every photo of one problem (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct BackgroundTerm {
    /// `γ`: one background pixel's weight against one observation of confidence 1.
    pub weight: f64,
    /// Texels per side of the map the texels index; a coarser map of `n` per side (`n`
    /// dividing it) reads texel `(i, j)` as `(i f, j f)`'s parent, `f = n_global / n`
    /// (octahedral maps of power-of-two sides nest).
    pub n_global: usize,
    /// Per photo of the problem (its index), the texels its background observes.
    pub photos: BackgroundLight,
}

impl BackgroundTerm {
    /// Photo `photo`'s texels on a map of `n` per side, with the weight (`None` when it has
    /// none, `γ = 0`, or `n` does not divide [`Self::n_global`]).
    pub(crate) fn photo(&self, photo: usize, n: usize) -> Option<PhotoBackground<'_>> {
        let texels = self.photos.get(photo)?;
        let nests = n > 0 && n <= self.n_global && self.n_global.is_multiple_of(n);
        (self.weight > 0.0 && !texels.is_empty() && nests).then_some(PhotoBackground {
            gamma: self.weight,
            texels,
            n_from: self.n_global,
            n,
        })
    }

    /// `Σ_I E_bg,I` per channel, photo `I` (in order) seeing the map `g_I m_I` of
    /// `photo_maps` (`m` per channel, `n²` texels; `g` its gains, 1 for the paper's map).
    pub fn channel_penalty<'m>(
        &self,
        n: usize,
        photo_maps: impl IntoIterator<Item = (&'m [Vec<f64>; 3], [f64; 3])>,
    ) -> [f64; 3] {
        let mut e = [0.0; 3];
        for (i, (m, g)) in photo_maps.into_iter().enumerate() {
            if let Some(p) = self.photo(i, n) {
                let pe = p.energy(m, g);
                (0..3).for_each(|c| e[c] += pe[c]);
            }
        }
        e
    }
}

/// One photo's background term inside its lighting QP (variables channel-major, `n²`
/// texels per channel).
pub(crate) struct PhotoBackground<'a> {
    gamma: f64,
    texels: &'a [BackgroundTexel],
    /// The side of the map `texels` index, and of the map solved for.
    n_from: usize,
    n: usize,
}

impl PhotoBackground<'_> {
    /// Per observed texel: its index on the solved map, `a_t = γ n_t` and `ȳ_t`. Texels
    /// that share a parent on a coarser map each add their own term, whose sum is the
    /// parent's up to a constant.
    fn weights(&self) -> impl Iterator<Item = (usize, f64, [f64; 3])> + '_ {
        let f = self.n_from / self.n;
        self.texels.iter().map(move |b| {
            let t = b.texel as usize;
            let (i, j) = (t % self.n_from / f, t / self.n_from / f);
            (
                j * self.n + i,
                self.gamma * f64::from(b.pixels),
                b.mean.map(f64::from),
            )
        })
    }

    // The photo's map is `g_c x_c` with a per-channel gain `g` (1 for the paper's map; the
    // exposure and white balance of a photo under a shared map, [`super::shared`]):
    // `E = Σ_t a_t (g_c x_{t,c} − ȳ_{t,c})²`, whose QP in `x` has `g_c² a_t` on the
    // diagonal and `g_c a_t ȳ_{t,c}` in `b`.

    /// `b_{c,t} += g_c a_t ȳ_{t,c}`.
    pub(crate) fn add_rhs(&self, b: &mut [f64], g: [f64; 3]) {
        let n2 = b.len() / 3;
        for (t, a, y) in self.weights() {
            (0..3).for_each(|c| b[c * n2 + t] += g[c] * a * y[c]);
        }
    }

    /// The Hessian's diagonal part: `out_{c,t} += g_c² a_t v_{c,t}`.
    pub(crate) fn add_normal(&self, v: &[f64], out: &mut [f64], g: [f64; 3]) {
        let n2 = v.len() / 3;
        for (t, a, _) in self.weights() {
            (0..3).for_each(|c| out[c * n2 + t] += g[c] * g[c] * a * v[c * n2 + t]);
        }
    }

    /// The Jacobi diagonal: `d_{c,t} += g_c² a_t`.
    pub(crate) fn add_diagonal(&self, d: &mut [f64], g: [f64; 3]) {
        let n2 = d.len() / 3;
        for (t, a, _) in self.weights() {
            (0..3).for_each(|c| d[c * n2 + t] += g[c] * g[c] * a);
        }
    }

    /// The gain's normal equation with the map `m` fixed: per channel
    /// `(Σ_t a_t ȳ_{t,c} m_{t,c}, Σ_t a_t m_{t,c}²)`, to add to the data's.
    pub(crate) fn gain_sums(&self, m: &[Vec<f64>; 3]) -> ([f64; 3], [f64; 3]) {
        let (mut num, mut den) = ([0.0; 3], [0.0; 3]);
        for (t, a, y) in self.weights() {
            for c in 0..3 {
                num[c] += a * y[c] * m[c][t];
                den[c] += a * m[c][t] * m[c][t];
            }
        }
        (num, den)
    }

    /// `E_bg` per channel at the map `g m` (`m` per channel, texels).
    pub(crate) fn energy(&self, m: &[Vec<f64>; 3], g: [f64; 3]) -> [f64; 3] {
        let mut e = [0.0; 3];
        for (t, a, y) in self.weights() {
            (0..3).for_each(|c| e[c] += a * (g[c] * m[c][t] - y[c]).powi(2));
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn term() -> BackgroundTerm {
        BackgroundTerm {
            weight: 0.5,
            n_global: 2,
            photos: vec![vec![
                BackgroundTexel {
                    texel: 1,
                    pixels: 4,
                    mean: [1.0, 2.0, 3.0],
                },
                BackgroundTexel {
                    texel: 3,
                    pixels: 2,
                    mean: [0.5, 0.0, 1.0],
                },
            ]],
        }
    }

    /// The QP's pieces are the energy's: with `H` from `add_normal` and `b` from `add_rhs`,
    /// `E(x) = xᵀ H x − 2 bᵀ x + E(0)` for any `x` (an exact identity of a quadratic; the
    /// tolerance is rounding), and the diagonal is `H`'s on unit vectors.
    #[test]
    fn the_qp_pieces_are_the_energy() {
        let t = term();
        let p = t.photo(0, 2).unwrap();
        let n2 = 4;
        let x: Vec<f64> = (0..3 * n2).map(|i| 0.3 * i as f64 - 1.0).collect();
        let split =
            |v: &[f64]| -> [Vec<f64>; 3] { [0, 1, 2].map(|c| v[c * n2..(c + 1) * n2].to_vec()) };
        let g = [1.0, 0.5, 2.0];
        let e = |v: &[f64]| p.energy(&split(v), g).iter().sum::<f64>();
        let mut hx = vec![0.0; 3 * n2];
        p.add_normal(&x, &mut hx, g);
        let mut b = vec![0.0; 3 * n2];
        p.add_rhs(&mut b, g);
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
        let quad = dot(&x, &hx) - 2.0 * dot(&b, &x) + e(&vec![0.0; 3 * n2]);
        assert!(
            (quad - e(&x)).abs() < 1e-9 * e(&x).max(1.0),
            "{quad} {}",
            e(&x)
        );
        let mut d = vec![0.0; 3 * n2];
        p.add_diagonal(&mut d, g);
        for i in 0..3 * n2 {
            let mut u = vec![0.0; 3 * n2];
            u[i] = 1.0;
            let mut hu = vec![0.0; 3 * n2];
            p.add_normal(&u, &mut hu, g);
            assert_eq!(d[i], hu[i]);
        }
        // Texel 1 holds 4 pixels at weight ½: a = 2; texel 3: a = 1; the others nothing
        // (red's gain is 1).
        assert_eq!(&d[..n2], &[0.0, 2.0, 0.0, 1.0]);
        // The gain's normal equation is the energy's minimiser in `g` with `x` fixed: the
        // energy at `num / den` is no higher than at 0.9× and 1.1× of it.
        let xm = split(&x);
        let (num, den) = p.gain_sums(&xm);
        for c in 0..3 {
            let at = |s: f64| {
                let mut gg = [1.0; 3];
                gg[c] = s * num[c] / den[c];
                p.energy(&xm, gg)[c]
            };
            assert!(at(1.0) <= at(0.9) && at(1.0) <= at(1.1), "channel {c}");
        }
    }

    /// On a coarser map a texel reads its parent: texels (2, 3) and (3, 2) of a 4² map are
    /// (1, 1) and (1, 1) of the 2² map, texel (0, 1) is (0, 0); each adds its own weight
    /// there (the sum of their terms is the parent's up to a constant).
    #[test]
    fn a_coarser_map_reads_each_texel_at_its_parent() {
        let texel = |i: u32, j: u32, pixels| BackgroundTexel {
            texel: j * 4 + i,
            pixels,
            mean: [1.0; 3],
        };
        let t = BackgroundTerm {
            weight: 1.0,
            n_global: 4,
            photos: vec![vec![texel(2, 3, 1), texel(3, 2, 2), texel(0, 1, 5)]],
        };
        let mut d = vec![0.0; 3 * 4];
        t.photo(0, 2).unwrap().add_diagonal(&mut d, [1.0; 3]);
        assert_eq!(&d[..4], &[5.0, 0.0, 0.0, 3.0]);
        let mut d = vec![0.0; 3 * 16];
        t.photo(0, 4).unwrap().add_diagonal(&mut d, [1.0; 3]);
        assert_eq!((d[14], d[11], d[4]), (1.0, 2.0, 5.0));
        assert!(t.photo(0, 3).is_none(), "3 does not divide 4");
    }

    /// The energy vanishes at the background's own means and is off where `γ = 0` or a
    /// photo has no background.
    #[test]
    fn the_energy_is_zero_at_the_means_and_off_without_weight() {
        let t = term();
        let mut m = [vec![9.0; 4], vec![9.0; 4], vec![9.0; 4]];
        for b in &t.photos[0] {
            (0..3).for_each(|c| m[c][b.texel as usize] = f64::from(b.mean[c]));
        }
        assert_eq!(t.channel_penalty(2, [(&m, [1.0; 3])]), [0.0; 3]);
        assert!(t.photo(1, 2).is_none());
        assert!(t.photo(0, 4).is_none(), "a finer map than the texels'");
        let off = BackgroundTerm { weight: 0.0, ..t };
        assert!(off.photo(0, 2).is_none());
        assert_eq!(off.channel_penalty(2, [(&m, [1.0; 3])]), [0.0; 3]);
    }
}
