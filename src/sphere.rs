//! Directions, frames and spherical maps: the one place where the geometric conventions of
//! DESIGN §3 live. Every other module calls these functions instead of restating them.
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

use crate::Vec3;

/// Orthonormal frame `[x, y, z]` with `z = n` (unit), right-handed (`x × y = z`).
/// Duff et al. 2017, Listing 3.
pub fn local_frame(n: &Vec3) -> [Vec3; 3] {
    let sign = 1.0_f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let x = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let y = Vec3::new(b, sign + n.y * n.y * a, -n.y);
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
}
