//! Directions, frames and spherical maps: the one place where the geometric conventions of
//! docs/conventions.md live. Every other module calls these functions instead of restating them.
//!
//! Frames:
//! - the environment frame `(e_x, e_y, e_z)`: `e_z` = world up, `e_x` = world +X made
//!   orthogonal to up (world +Y when up is within 25° of ±X), `e_y = e_z × e_x`
//!   ([`env_frame`]). Environment maps (global octahedral, lat-long) are indexed by
//!   directions expressed in this frame.
//! - the local frame of a unit normal `n` (given in the environment frame):
//!   `z = n`, `x`, `y` from the branchless construction of Duff et al., "Building an
//!   Orthonormal Basis, Revisited" (JCGT 2017) ([`local_frame`]). Visibility, BRDF slices
//!   and the rotation `R_ν` all use this one construction.
//!
//! Spherical maps (Praun & Hoppe, "Spherical parametrization and remeshing", SIGGRAPH 2003;
//! the octahedron unfolded into a square, as in the paper's Sec. 4.1):
//!
//! - Full sphere, [`oct_encode`] / [`oct_decode`]: `p = d / (|x| + |y| + |z|)` lies on the
//!   octahedron `|p_x| + |p_y| + |p_z| = 1`. The upper half (`z ≥ 0`) is projected straight
//!   down onto the inner diamond `|a| + |b| ≤ 1` with `(a, b) = (p_x, p_y)`; the lower half
//!   is folded out into the four corner triangles, `(a, b) = ((1 − |p_y|) sgn p_x,
//!   (1 − |p_x|) sgn p_y)`. Then `uv = ((a + 1) / 2, (b + 1) / 2)`. Layout: the centre
//!   `uv = (½, ½)` is `+z` (up), the edge midpoints `(1, ½)`, `(½, 1)`, `(0, ½)`, `(½, 0)`
//!   are `+x`, `+y`, `−x`, `−y`, all four corners are `−z`; the inner diamond is the
//!   equator. Each outer edge folds at its midpoint: `(0, v) ≡ (0, 1 − v)`, likewise for
//!   the other three edges.
//! - Upper hemisphere, [`hemi_oct_encode`] / [`hemi_oct_decode`]: `p = d / (|x| + |y| + z)`,
//!   the diamond rotated by 45° to fill the square: `a = p_x + p_y`, `b = p_x − p_y`,
//!   `uv = ((a + 1) / 2, (b + 1) / 2)`. Layout: centre `+z`, corners `(1, 1)` = `+x`,
//!   `(0, 0)` = `−x`, `(1, 0)` = `+y`, `(0, 1)` = `−y`; the square's border is the horizon.
//! - Texels ([`SphereGrid`]): an `n × n` grid, `n` a power of two `≥ 2`, texel
//!   `t = j n + i` (row `j` along `v`, column `i` along `u`), centre
//!   `((i + ½)/n, (j + ½)/n)`. Both maps send straight lines within one octahedron face to
//!   great-circle arcs, and every face boundary runs through texel corners, so each texel
//!   split along the right diagonal is two exact spherical triangles: solid angles are
//!   exact (Van Oosterom & Strackee's triangle formula), and sum to `4π` (full) or `2π`
//!   (hemisphere) to rounding.

pub mod envmap;
pub mod haar;
pub mod rotation;
pub mod triple;

use crate::Vec3;

/// Orthonormal frame `[x, y, z]` with `z = n` (unit), right-handed (`x × y = z`).
///
/// The `sign = +1` branch of Duff et al. 2017, Listing 3, for every normal: the frame is
/// the smallest rotation taking `+z` to `n`, so it varies continuously over the whole
/// sphere except straight down (`n = −z`, where any tangent field must have a singularity:
/// there the fixed frame `x = +x, y = −y` is used). Duff's two-branch version flips the
/// tangents by 180° across `n_z = 0`, which the blended rotation of Eq. 6 cannot tolerate
/// for glossy lobes (`tests/suite/transport_blended.rs`); with this one only faces pointing
/// almost straight down (in the environment frame) blend frames that differ much.
pub fn local_frame(n: &Vec3) -> [Vec3; 3] {
    if n.z < -1.0 + 1e-12 {
        return [Vec3::x(), -Vec3::y(), *n];
    }
    let a = -1.0 / (1.0 + n.z);
    let b = n.x * n.y * a;
    let x = Vec3::new(1.0 + n.x * n.x * a, b, -n.x);
    let y = Vec3::new(b, 1.0 + n.y * n.y * a, -n.y);
    [x, y, *n]
}

/// Direction `d` (environment or world coordinates) expressed in `frame`.
pub fn to_local(frame: &[Vec3; 3], d: &Vec3) -> Vec3 {
    Vec3::new(frame[0].dot(d), frame[1].dot(d), frame[2].dot(d))
}

/// Local direction `l` back to the coordinates `frame` is expressed in.
pub fn from_local(frame: &[Vec3; 3], l: &Vec3) -> Vec3 {
    frame[0] * l.x + frame[1] * l.y + frame[2] * l.z
}

/// The environment frame `[e_x, e_y, e_z]` for world `up` (need not be unit length).
/// Returns `None` when `up` is zero or not finite.
pub fn env_frame(up: &Vec3) -> Option<[Vec3; 3]> {
    let norm = up.norm();
    if !norm.is_finite() || norm == 0.0 {
        return None;
    }
    let ez = up / norm;
    let cos25 = 25.0_f64.to_radians().cos();
    let seed = if ez.x.abs() > cos25 {
        Vec3::y()
    } else {
        Vec3::x()
    };
    let ex = (seed - ez * ez.dot(&seed)).normalize();
    let ey = ez.cross(&ex);
    Some([ex, ey, ez])
}

/// `⌊x⌋` as an index, for `|x| < 2⁵²` (map coordinates): truncation corrected below zero,
/// the same value as `x.floor() as isize` without the library call `floor` compiles to
/// on x86-64 without SSE4.1.
#[inline]
fn floor_index(x: f64) -> isize {
    let t = x as isize;
    if (t as f64) > x {
        t - 1
    } else {
        t
    }
}

/// Full-sphere octahedral map: unit (or any non-zero) direction `d` to `uv ∈ [0, 1]²`.
pub fn oct_encode(d: &Vec3) -> [f64; 2] {
    let l1 = d.x.abs() + d.y.abs() + d.z.abs();
    let (px, py, pz) = (d.x / l1, d.y / l1, d.z / l1);
    let (a, b) = if pz >= 0.0 {
        (px, py)
    } else {
        ((1.0 - py.abs()).copysign(px), (1.0 - px.abs()).copysign(py))
    };
    [(a + 1.0) * 0.5, (b + 1.0) * 0.5]
}

/// Inverse of [`oct_encode`]: `uv ∈ [0, 1]²` to the unit direction.
pub fn oct_decode(uv: [f64; 2]) -> Vec3 {
    let a = 2.0 * uv[0] - 1.0;
    let b = 2.0 * uv[1] - 1.0;
    let z = 1.0 - a.abs() - b.abs();
    let (x, y) = if z >= 0.0 {
        (a, b)
    } else {
        ((1.0 - b.abs()).copysign(a), (1.0 - a.abs()).copysign(b))
    };
    Vec3::new(x, y, z).normalize()
}

/// Hemi-octahedral map of the upper hemisphere (`z ≥ 0`, local frame) to `uv ∈ [0, 1]²`.
/// Directions with `z < 0` are mapped as if `z` were 0 (their horizon projection).
pub fn hemi_oct_encode(d: &Vec3) -> [f64; 2] {
    let z = d.z.max(0.0);
    let l1 = d.x.abs() + d.y.abs() + z;
    let (px, py) = (d.x / l1, d.y / l1);
    [(px + py + 1.0) * 0.5, (px - py + 1.0) * 0.5]
}

/// A uniformly random unit direction for tests: a point drawn uniformly in the cube
/// `[−1, 1]³`, kept when it lies in the unit ball (and not within 0.1 of the centre, where
/// rounding would bias its direction), normalised.
#[cfg(test)]
pub(crate) fn random_unit(rng: &mut impl rand::Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

/// Inverse of [`hemi_oct_encode`]: `uv ∈ [0, 1]²` to a unit direction with `z ≥ 0`.
pub fn hemi_oct_decode(uv: [f64; 2]) -> Vec3 {
    let a = 2.0 * uv[0] - 1.0;
    let b = 2.0 * uv[1] - 1.0;
    let px = 0.5 * (a + b);
    let py = 0.5 * (a - b);
    let z = (1.0 - px.abs() - py.abs()).max(0.0);
    Vec3::new(px, py, z).normalize()
}

/// Solid angle of the spherical triangle with unit vertices `a`, `b`, `c`
/// (Van Oosterom & Strackee 1983: `tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a)`).
pub fn spherical_triangle_area(a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    let num = a.dot(&b.cross(c)).abs();
    let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
    2.0 * num.atan2(den)
}

/// An `n × n` texel grid over the full octahedral map or the hemi-octahedral map
/// (layout in the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SphereGrid {
    /// Texels per side (a power of two, at least 2).
    pub n: usize,
    /// `true`: hemi-octahedral map of `z ≥ 0`; `false`: full octahedral map.
    pub hemi: bool,
}

impl SphereGrid {
    /// Full-sphere octahedral grid. Panics unless `n` is a power of two `≥ 2`
    /// (resolutions are checked where the user gives them).
    pub fn full(n: usize) -> Self {
        assert!(
            n >= 2 && n.is_power_of_two(),
            "octahedral grid size {n} is not a power of two >= 2"
        );
        SphereGrid { n, hemi: false }
    }

    /// Hemi-octahedral grid. Panics unless `n` is a power of two `≥ 2`.
    pub fn hemi(n: usize) -> Self {
        assert!(
            n >= 2 && n.is_power_of_two(),
            "hemi-octahedral grid size {n} is not a power of two >= 2"
        );
        SphereGrid { n, hemi: true }
    }

    /// Number of texels, `n²`.
    pub fn len(&self) -> usize {
        self.n * self.n
    }

    /// Always `false` (a grid has at least 4 texels).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Map `uv` to a direction with this grid's map.
    pub fn decode(&self, uv: [f64; 2]) -> Vec3 {
        if self.hemi {
            hemi_oct_decode(uv)
        } else {
            oct_decode(uv)
        }
    }

    /// Map a direction to `uv` with this grid's map.
    pub fn encode(&self, d: &Vec3) -> [f64; 2] {
        if self.hemi {
            hemi_oct_encode(d)
        } else {
            oct_encode(d)
        }
    }

    /// Direction of the centre of texel `t`.
    pub fn texel_dir(&self, t: usize) -> Vec3 {
        let (i, j) = (t % self.n, t / self.n);
        let nf = self.n as f64;
        self.decode([(i as f64 + 0.5) / nf, (j as f64 + 0.5) / nf])
    }

    /// The texel containing direction `d`.
    pub fn texel_of(&self, d: &Vec3) -> usize {
        let uv = self.encode(d);
        let nf = self.n as f64;
        let i = ((uv[0] * nf) as usize).min(self.n - 1);
        let j = ((uv[1] * nf) as usize).min(self.n - 1);
        j * self.n + i
    }

    /// Whether texel `t` must be split along its main diagonal `(i, j)–(i+1, j+1)` (else the
    /// anti-diagonal) so that both halves lie in one octahedron face each.
    fn main_diagonal(&self, t: usize) -> bool {
        let (i, j) = (t % self.n, t / self.n);
        let half = self.n / 2;
        let same_quadrant_sign = (i >= half) == (j >= half);
        // Hemi: faces meet along a = b and a = −b; full: along the diamond |a| + |b| = 1.
        same_quadrant_sign == self.hemi
    }

    /// Exact solid angle of the uv rectangle `[u0, u1] × [v0, v1]`, split along the main
    /// diagonal or the anti-diagonal (the rectangle must not cross a face boundary except
    /// along that diagonal).
    fn rect_solid_angle(&self, u0: f64, v0: f64, u1: f64, v1: f64, main: bool) -> f64 {
        let c00 = self.decode([u0, v0]);
        let c10 = self.decode([u1, v0]);
        let c01 = self.decode([u0, v1]);
        let c11 = self.decode([u1, v1]);
        if main {
            spherical_triangle_area(&c00, &c10, &c11) + spherical_triangle_area(&c00, &c11, &c01)
        } else {
            spherical_triangle_area(&c00, &c10, &c01) + spherical_triangle_area(&c10, &c11, &c01)
        }
    }

    /// Exact solid angle of texel `t`.
    pub fn solid_angle(&self, t: usize) -> f64 {
        let (i, j) = (t % self.n, t / self.n);
        let nf = self.n as f64;
        self.rect_solid_angle(
            i as f64 / nf,
            j as f64 / nf,
            (i + 1) as f64 / nf,
            (j + 1) as f64 / nf,
            self.main_diagonal(t),
        )
    }

    /// Exact solid angles of all texels (sum `4π` full, `2π` hemisphere).
    pub fn solid_angles(&self) -> Vec<f64> {
        (0..self.len()).map(|t| self.solid_angle(t)).collect()
    }

    /// Texel `(i, j)` of the grid extended by one texel beyond each border, folded back
    /// into the grid: across the full map's outer edges by the edge fold, across the
    /// hemisphere's border by clamping.
    fn wrap(&self, i: isize, j: isize) -> usize {
        let n = self.n as isize;
        let (mut i, mut j) = (i, j);
        if self.hemi {
            i = i.clamp(0, n - 1);
            j = j.clamp(0, n - 1);
        } else {
            if i < 0 || i >= n {
                i = i.clamp(0, n - 1);
                j = n - 1 - j;
            }
            if j < 0 || j >= n {
                j = j.clamp(0, n - 1);
                i = n - 1 - i;
            }
        }
        (j * n + i) as usize
    }

    /// Bilinear interpolation weights `(texel, weight)` at direction `d` between the four
    /// nearest texel centres (weights sum to 1). Continuous in `d` everywhere: across the
    /// full map's folded edges the grid is continued by the fold; at the hemisphere's
    /// border the border texels are repeated.
    pub fn bilinear(&self, d: &Vec3) -> [(usize, f64); 4] {
        let uv = self.encode(d);
        let nf = self.n as f64;
        let x = uv[0] * nf - 0.5;
        let y = uv[1] * nf - 0.5;
        let (i0, j0) = (floor_index(x), floor_index(y));
        let (fx, fy) = (x - i0 as f64, y - j0 as f64);
        let n = self.n as isize;
        if i0 >= 0 && j0 >= 0 && i0 + 1 < n && j0 + 1 < n {
            // All four taps inside the grid: `wrap` is the identity.
            let t = (j0 * n + i0) as usize;
            return [
                (t, (1.0 - fx) * (1.0 - fy)),
                (t + 1, fx * (1.0 - fy)),
                (t + self.n, (1.0 - fx) * fy),
                (t + self.n + 1, fx * fy),
            ];
        }
        [
            (self.wrap(i0, j0), (1.0 - fx) * (1.0 - fy)),
            (self.wrap(i0 + 1, j0), fx * (1.0 - fy)),
            (self.wrap(i0, j0 + 1), (1.0 - fx) * fy),
            (self.wrap(i0 + 1, j0 + 1), fx * fy),
        ]
    }

    /// The 4-neighbours `[left, right, below (j − 1), above (j + 1)]` of texel `t`, across
    /// the full map's folded edges. On the hemisphere's border a missing neighbour is `t`
    /// itself (so it adds nothing to a Laplacian).
    pub fn neighbors(&self, t: usize) -> [usize; 4] {
        let (i, j) = ((t % self.n) as isize, (t / self.n) as isize);
        [
            self.wrap(i - 1, j),
            self.wrap(i + 1, j),
            self.wrap(i, j - 1),
            self.wrap(i, j + 1),
        ]
    }

    /// `s × s` sub-texels of texel `t`: the centre direction of each and its exact solid
    /// angle (the weights sum to the texel's solid angle). `s ≥ 1`.
    pub fn sample_points(&self, t: usize, s: usize) -> impl Iterator<Item = (Vec3, f64)> {
        let s = s.max(1);
        let (i, j) = (t % self.n, t / self.n);
        let nf = self.n as f64;
        let main = self.main_diagonal(t);
        let step = 1.0 / (nf * s as f64);
        let (u0, v0) = (i as f64 / nf, j as f64 / nf);
        let grid = *self;
        (0..s * s).map(move |k| {
            let (a, b) = (k % s, k / s);
            let ua = u0 + a as f64 * step;
            let va = v0 + b as f64 * step;
            let w = grid.rect_solid_angle(ua, va, ua + step, va + step, main);
            let d = grid.decode([ua + 0.5 * step, va + 0.5 * step]);
            (d, w)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_frame_is_orthonormal_and_right_handed() {
        // Tolerance 1e-12: a handful of f64 operations on unit-length inputs.
        for n in [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 2.0, 3.0).normalize(),
            Vec3::new(-0.3, 0.1, -0.9).normalize(),
            Vec3::new(1.0, 0.0, 0.0),
        ] {
            let f = local_frame(&n);
            for i in 0..3 {
                assert!((f[i].norm() - 1.0).abs() < 1e-12);
                for j in 0..i {
                    assert!(f[i].dot(&f[j]).abs() < 1e-12);
                }
            }
            assert!((f[0].cross(&f[1]) - f[2]).norm() < 1e-12);
            let d = Vec3::new(0.2, -0.5, 0.7);
            assert!((from_local(&f, &to_local(&f, &d)) - d).norm() < 1e-12);
        }
    }

    #[test]
    fn env_frame_follows_design_section_3() {
        let f = env_frame(&Vec3::new(0.0, 2.0, 0.0)).unwrap();
        assert!((f[2] - Vec3::y()).norm() < 1e-12);
        assert!((f[0] - Vec3::x()).norm() < 1e-12);
        assert!((f[1] - Vec3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        // Up near +X: e_x comes from world +Y instead.
        let f = env_frame(&Vec3::new(1.0, 0.1, 0.0)).unwrap();
        assert!(f[0].dot(&Vec3::y()) > 0.9);
        assert!(env_frame(&Vec3::zeros()).is_none());
    }

    use proptest::prelude::*;

    fn unit(x: f64, y: f64, z: f64) -> Option<Vec3> {
        let v = Vec3::new(x, y, z);
        (v.norm() > 1e-3).then(|| v.normalize())
    }

    proptest! {
        // Round trips: a handful of f64 operations, so 1e-12 absolute on unit vectors.
        #[test]
        fn oct_round_trip(x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64) {
            if let Some(d) = unit(x, y, z) {
                let uv = oct_encode(&d);
                prop_assert!((0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1]));
                prop_assert!((oct_decode(uv) - d).norm() < 1e-12);
            }
        }

        #[test]
        fn oct_uv_round_trip(u in 0.0..1.0f64, v in 0.0..1.0f64) {
            let uv2 = oct_encode(&oct_decode([u, v]));
            // Off the folded border (where two uv name one direction) uv is recovered.
            if u > 1e-9 && v > 1e-9 {
                prop_assert!((uv2[0] - u).abs() < 1e-12 && (uv2[1] - v).abs() < 1e-12);
            }
        }

        #[test]
        fn hemi_round_trip(x in -1.0..1.0f64, y in -1.0..1.0f64, z in 0.0..1.0f64) {
            if let Some(d) = unit(x, y, z) {
                let uv = hemi_oct_encode(&d);
                prop_assert!((0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1]));
                prop_assert!((hemi_oct_decode(uv) - d).norm() < 1e-12);
                let uv2 = hemi_oct_encode(&hemi_oct_decode(uv));
                prop_assert!((uv2[0] - uv[0]).abs() < 1e-12 && (uv2[1] - uv[1]).abs() < 1e-12);
            }
        }

        #[test]
        fn texel_of_texel_dir(t in 0usize..256, hemi in any::<bool>()) {
            let g = if hemi { SphereGrid::hemi(16) } else { SphereGrid::full(16) };
            prop_assert_eq!(g.texel_of(&g.texel_dir(t)), t);
        }

        // The interior fast path and the integer floor give the general formula's taps
        // and weights exactly (`floor` and `wrap` for all four taps): compared with
        // `assert_eq!`, at 8² (many border taps) and 32².
        #[test]
        fn bilinear_equals_the_wrapped_formula(x in -1.0..1.0f64, y in -1.0..1.0f64,
                                               z in -1.0..1.0f64, hemi in any::<bool>(),
                                               big in any::<bool>()) {
            if let Some(d) = unit(x, y, if hemi { z.abs() } else { z }) {
                let n = if big { 32 } else { 8 };
                let g = if hemi { SphereGrid::hemi(n) } else { SphereGrid::full(n) };
                let uv = g.encode(&d);
                let (xf, yf) = (uv[0] * n as f64 - 0.5, uv[1] * n as f64 - 0.5);
                let (x0, y0) = (xf.floor(), yf.floor());
                let (fx, fy) = (xf - x0, yf - y0);
                let (i0, j0) = (x0 as isize, y0 as isize);
                let want = [
                    (g.wrap(i0, j0), (1.0 - fx) * (1.0 - fy)),
                    (g.wrap(i0 + 1, j0), fx * (1.0 - fy)),
                    (g.wrap(i0, j0 + 1), (1.0 - fx) * fy),
                    (g.wrap(i0 + 1, j0 + 1), fx * fy),
                ];
                prop_assert_eq!(g.bilinear(&d), want);
            }
        }

        // Bilinear weights are continuous: two directions 1e-7 rad apart get weights per
        // texel that differ by at most a few 1e-7 × n (the weights' Lipschitz constant in
        // uv is n, and the map's is at most ~2 per radian).
        #[test]
        fn bilinear_is_continuous(x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64,
                                  ex in -1.0..1.0f64, ey in -1.0..1.0f64, hemi in any::<bool>()) {
            if let Some(d) = unit(x, y, if hemi { z.abs() } else { z }) {
                let g = if hemi { SphereGrid::hemi(8) } else { SphereGrid::full(8) };
                let mut e = Vec3::new(ex, ey, 0.3);
                e -= d * d.dot(&e);
                if e.norm() < 1e-3 { return Ok(()); }
                let d2 = (d + e.normalize() * 1e-7).normalize();
                if hemi && d2.z < 0.0 { return Ok(()); }
                let mut w1 = vec![0.0; g.len()];
                let mut w2 = vec![0.0; g.len()];
                for (t, w) in g.bilinear(&d) { w1[t] += w; }
                for (t, w) in g.bilinear(&d2) { w2[t] += w; }
                let sum: f64 = w1.iter().sum();
                prop_assert!((sum - 1.0).abs() < 1e-12);
                for t in 0..g.len() {
                    prop_assert!((w1[t] - w2[t]).abs() < 1e-5, "texel {} {} {}", t, w1[t], w2[t]);
                }
            }
        }
    }

    #[test]
    fn bilinear_is_continuous_across_the_folds() {
        // (ε, v) and (ε, 1 − v) are ~2ε apart on the sphere (the edge u = 0 folds at its
        // midpoint); likewise at the other edges and the −z corners. The weights per texel
        // must agree to O(n ε).
        let g = SphereGrid::full(8);
        let eps = 1e-10;
        let pairs = [
            ([eps, 0.3], [eps, 0.7]),
            ([1.0 - eps, 0.1], [1.0 - eps, 0.9]),
            ([0.2, eps], [0.8, eps]),
            ([0.45, 1.0 - eps], [0.55, 1.0 - eps]),
            ([eps, eps], [1.0 - eps, 1.0 - eps]),
            ([eps, 1.0 - eps], [1.0 - eps, eps]),
        ];
        for (a, b) in pairs {
            let (da, db) = (oct_decode(a), oct_decode(b));
            assert!((da - db).norm() < 1e-8);
            let mut wa = vec![0.0; g.len()];
            let mut wb = vec![0.0; g.len()];
            for (t, w) in g.bilinear(&da) {
                wa[t] += w;
            }
            for (t, w) in g.bilinear(&db) {
                wb[t] += w;
            }
            for t in 0..g.len() {
                assert!((wa[t] - wb[t]).abs() < 1e-7, "{a:?} {b:?} texel {t}");
            }
        }
    }

    #[test]
    fn layout_corners_are_as_documented() {
        let close = |a: Vec3, b: Vec3| (a - b).norm() < 1e-12;
        assert!(close(oct_decode([0.5, 0.5]), Vec3::z()));
        assert!(close(oct_decode([1.0, 0.5]), Vec3::x()));
        assert!(close(oct_decode([0.5, 1.0]), Vec3::y()));
        assert!(close(oct_decode([0.0, 0.0]), -Vec3::z()));
        assert!(close(oct_decode([0.0, 0.3]), oct_decode([0.0, 0.7])));
        assert!(close(hemi_oct_decode([1.0, 1.0]), Vec3::x()));
        assert!(close(hemi_oct_decode([1.0, 0.0]), Vec3::y()));
        assert!(close(hemi_oct_decode([0.5, 0.5]), Vec3::z()));
    }

    /// Solid angle of a texel by brute-force quadrature: the Jacobian of the uv → sphere
    /// map by central differences at the centres of an m × m sub-grid (midpoint rule).
    fn quadrature_solid_angle(g: &SphereGrid, t: usize, m: usize) -> f64 {
        let (i, j) = (t % g.n, t / g.n);
        let h = 1.0 / (g.n * m) as f64;
        let eps = h * 1e-3;
        let mut sum = 0.0;
        for b in 0..m {
            for a in 0..m {
                let u = (i * m + a) as f64 * h + 0.5 * h;
                let v = (j * m + b) as f64 * h + 0.5 * h;
                let d = g.decode([u, v]);
                let du = (g.decode([u + eps, v]) - g.decode([u - eps, v])) / (2.0 * eps);
                let dv = (g.decode([u, v + eps]) - g.decode([u, v - eps])) / (2.0 * eps);
                sum += du.cross(&dv).dot(&d).abs() * h * h;
            }
        }
        sum
    }

    #[test]
    fn solid_angles_match_quadrature_and_sum_to_sphere() {
        use std::f64::consts::PI;
        for (g, total) in [
            (SphereGrid::full(8), 4.0 * PI),
            (SphereGrid::hemi(8), 2.0 * PI),
        ] {
            let sa = g.solid_angles();
            // The exact triangle decomposition must tile the sphere: rounding only.
            assert!((sa.iter().sum::<f64>() - total).abs() < 1e-12);
            for (t, &s) in sa.iter().enumerate() {
                // Midpoint rule with 40×40 sub-cells: the map is smooth within a face, and
                // the face boundary (a diagonal) passes through sub-cell corners, so the
                // error is O(h²) ≈ 1e-4 relative; allow 1e-3.
                let q = quadrature_solid_angle(&g, t, 40);
                assert!(
                    (q - s).abs() < 1e-3 * s,
                    "texel {t}: exact {s} quadrature {q}"
                );
                // Sub-texel weights sum to the texel's solid angle.
                let sub: f64 = g.sample_points(t, 3).map(|(_, w)| w).sum();
                assert!((sub - s).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn neighbors_are_adjacent_on_the_sphere() {
        // Every 4-neighbour's centre is within ~2 texel widths of the texel's centre (texel
        // width on the full 16² map is at most ~π/16 rad), and the relation is symmetric.
        let g = SphereGrid::full(16);
        for t in 0..g.len() {
            for nb in g.neighbors(t) {
                let ang = g.texel_dir(t).angle(&g.texel_dir(nb));
                assert!(
                    ang < 2.0 * std::f64::consts::PI / 16.0,
                    "texel {t} -> {nb}: {ang}"
                );
                assert!(g.neighbors(nb).contains(&t));
            }
        }
    }
}
