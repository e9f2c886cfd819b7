//! Light transport per observation (paper Eq. 5–8), precomputed once per run.
//!
//! For observation `p` (vertex `x` seen from local direction `ω_o`) and basis BRDF `b`, the
//! radiance under a distant light `L̃` (one colour channel, global octahedral map, Haar
//! coefficients `L̃_m`) is linear in the light:
//!
//! `s_{p,b}(L̃) = ∫_Ω ρ_b(ω_o, ω) V_x(ω) (R_{n_x} L̃)(ω) dω = Σ_m g_{p,b,m} L̃_m`
//!
//! where `R_n` is the blended wavelet rotation (Eq. 6) into the vertex's local frame and the
//! local triple product (Eq. 5, with `T_x = Σ_l C_klm V_l`, Eq. 7) has been folded into the
//! global transport vector `g_{p,b} = R_nᵀ T_x ρ_b(ω_o)`. The model of an observation
//! (Eq. 8, 11) is then, per channel `c`,
//! `y_{p,c} = Σ_b β_{x,b,c} s_{p,b}(L̃_{I(p),c})`, with `β_{x,b,c} = Σ_k w_k(x) λ_{k,b,c}`.
//!
//! [`Transport`] stores the `g_{p,b}` sparsely (the kept Haar coefficients, largest first
//! after truncation), in compressed rows indexed by `p * n_basis + b`.

/// Sparse per-observation, per-basis transport vectors in the global Haar basis.
#[derive(Debug, Clone, Default)]
pub struct Transport {
    /// The global octahedral map is `n_global × n_global` texels; Haar index space
    /// `0..n_global²` (the layout of [`crate::haar`]).
    pub n_global: usize,
    /// Number of basis BRDFs `B`.
    pub n_basis: usize,
    /// Number of observations `P`.
    pub n_obs: usize,
    /// Row `r = p * n_basis + b` spans `index[offsets[r]..offsets[r + 1]]`.
    pub offsets: Vec<usize>,
    /// Haar coefficient indices of the kept entries.
    pub index: Vec<u32>,
    /// Values of the kept entries.
    pub value: Vec<f32>,
}

impl Transport {
    /// The kept entries `(indices, values)` of `g_{p,b}`.
    pub fn row(&self, p: usize, b: usize) -> (&[u32], &[f32]) {
        let r = p * self.n_basis + b;
        let (lo, hi) = (self.offsets[r], self.offsets[r + 1]);
        (&self.index[lo..hi], &self.value[lo..hi])
    }

    /// `s_{p,b}(L̃) = Σ_m g_{p,b,m} L̃_m` for one channel of a light given by its Haar
    /// coefficients (`light.len() == n_global²`).
    pub fn response(&self, p: usize, b: usize, light: &[f64]) -> f64 {
        let (idx, val) = self.row(p, b);
        idx.iter()
            .zip(val)
            .map(|(&m, &g)| g as f64 * light[m as usize])
            .sum()
    }

    /// Bytes held by the sparse rows.
    pub fn memory_bytes(&self) -> usize {
        self.offsets.len() * std::mem::size_of::<usize>()
            + self.index.len() * std::mem::size_of::<u32>()
            + self.value.len() * std::mem::size_of::<f32>()
    }
}
