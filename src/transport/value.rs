//! [`TransportValue`]: a kept transport coefficient in IEEE 754 half precision.
//!
//! Rounding (round to nearest even, [`half::f16::from_f64`]): within `2⁻¹¹ |g|`
//! (`4.9·10⁻⁴` relative) for `|g| ≥ 2⁻¹⁴ ≈ 6.1·10⁻⁵`, within `2⁻²⁵ ≈ 3·10⁻⁸` below (the
//! subnormals); magnitudes beyond the largest half, 65,504, are stored as ±65,504
//! (transport values are texel integrals of a BRDF times a solid angle, below 10 for every
//! basis lobe). Every product with a value is accumulated in `f64` (`f64::from`). The
//! rounding is far below what the truncation to `keep` coefficients drops (the `ℓ²` norm of
//! the dropped tail), and it stores an entry in 4 bytes with its `u16` index instead of 6
//! (docs/benchmarks.md, "Memory").
//!
//! Decoding is exact for finite halves, with no table, inlined where it is read: a normal
//! half's 15 magnitude bits shifted into an `f32`'s exponent and significand, plus `112`
//! on the exponent (the bias difference, an integer addition); a subnormal's 10-bit
//! significand converted to `f32` (exactly) times `2⁻²⁴`; the two selected without a
//! branch. No arithmetic ever sees a subnormal `f32`: the earlier decoding (the shifted
//! bits times `2¹¹²` as an `f32` multiplication) did for every subnormal half, and on CPUs
//! that handle a subnormal operand in microcode (Intel's, without denormals-are-zero) that
//! multiplication cost about a hundred cycles, which the material step's responses, reading
//! every kept coefficient of every observation, paid on each small coefficient.

/// A transport coefficient stored as the bits of an IEEE 754 half (`binary16`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[repr(transparent)]
pub struct TransportValue(u16);

impl TransportValue {
    /// `+0`.
    pub const ZERO: Self = TransportValue(0);

    /// `v` rounded to the nearest half (ties to even), finite magnitudes beyond 65,504
    /// saturated; NaN is stored as 0 (a transport row never holds one).
    pub fn from_f64(v: f64) -> Self {
        if v.is_nan() {
            return Self::ZERO;
        }
        let max = f64::from(half::f16::MAX);
        TransportValue(half::f16::from_f64(v.clamp(-max, max)).to_bits())
    }

    /// [`TransportValue::from_f64`] of an `f32`.
    pub fn from_f32(v: f32) -> Self {
        Self::from_f64(f64::from(v))
    }

    /// The stored value, exactly.
    #[inline]
    pub fn to_f32(self) -> f32 {
        let h = u32::from(self.0);
        let bits = h & 0x7fff;
        // Normal: the exponent rebased by 127 − 15 = 112 (in the f32 exponent field).
        let normal = f32::from_bits((bits << 13) + (112 << 23));
        // Subnormal (or zero): significand · 2⁻²⁴, both factors exact in f32.
        let subnormal = bits as f32 * f32::from_bits(0x3380_0000);
        let magnitude = if bits < 0x400 { subnormal } else { normal };
        f32::from_bits(magnitude.to_bits() | ((h & 0x8000) << 16))
    }
}

impl From<TransportValue> for f64 {
    #[inline]
    fn from(v: TransportValue) -> f64 {
        f64::from(v.to_f32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decoding_matches_the_half_crate_for_every_finite_half() {
        // All 63,488 finite bit patterns (both signs, zeros and subnormals included) against
        // the `half` crate's own conversion: exact equality.
        for bits in 0..=u16::MAX {
            let reference = half::f16::from_bits(bits);
            if !reference.is_finite() {
                continue;
            }
            let got = TransportValue(bits).to_f32();
            assert_eq!(
                got.to_bits(),
                reference.to_f32().to_bits(),
                "bits {bits:#06x}"
            );
        }
    }

    #[test]
    fn encoding_rounds_within_the_stated_bounds() {
        // Relative 2⁻¹¹ for normal magnitudes, absolute 2⁻²⁵ for subnormal ones, saturation
        // beyond 65,504, NaN to 0.
        let mut v = 1.234_567e-9_f64;
        while v < 6.0e4 {
            for x in [v, -v] {
                let r = f64::from(TransportValue::from_f64(x));
                let bound = if x.abs() >= 2f64.powi(-14) {
                    x.abs() * 2f64.powi(-11)
                } else {
                    2f64.powi(-25)
                };
                assert!((r - x).abs() <= bound, "{x} stored as {r}");
            }
            v *= 1.37;
        }
        assert_eq!(f64::from(TransportValue::from_f64(1e9)), 65504.0);
        assert_eq!(f64::from(TransportValue::from_f64(-1e9)), -65504.0);
        assert_eq!(f64::from(TransportValue::from_f64(f64::NAN)), 0.0);
    }
}
