//! The data of one estimation ([`Problem`]: observations, their transport rows, sizes) and
//! the model's forward map over it: `β_{x,b,c} = Σ_k w_k(x) λ_{k,b,c}` (Eq. 11), the basis
//! responses `s_{p,b,c} = ⟨g_{p,b}, W x_{I(p),c}⟩` and the prediction
//! `ŷ_{p,c} = Σ_b β_{x,b,c} s_{p,b,c}` (Eq. 8).

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::observe::Observations;
use crate::solve::result::Estimate;
use crate::sphere::haar;
use crate::transport::Transport;
use crate::{Error, Result};

/// The data of one estimation: observations, their transport, and the sizes.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// Observations sorted by photo (`photo_ranges`).
    pub obs: &'a Observations,
    /// Transport rows `g_{p,b}`, one per observation and basis BRDF.
    pub transport: &'a Transport,
    /// Number of mesh vertices `V`.
    pub n_vertices: usize,
    /// Number of photos (`obs.photo_ranges.len()`).
    pub n_photos: usize,
}

impl Problem<'_> {
    /// Checks sizes and indices; `Error::Internal` naming the first inconsistency.
    pub fn validate(&self) -> Result<()> {
        self.check_observations()?;
        self.check_transport()?;
        self.check_photo_ranges()?;
        self.check_values()
    }

    /// The observation arrays agree in length (and the clipped channels with their bounds).
    fn check_observations(&self) -> Result<()> {
        let o = self.obs;
        let p = o.vertex.len();
        if o.photo.len() != p || o.rgb.len() != p || o.weight.len() != p {
            return invalid(format!(
                "observation arrays differ in length (vertex {p}, photo {}, rgb {}, weight {})",
                o.photo.len(),
                o.rgb.len(),
                o.weight.len()
            ));
        }
        let (nc, nb) = (o.clipped.len(), o.bound_weight.len());
        if nc != nb || (nc != 0 && nc != p) {
            return invalid(format!(
                "clipped channels ({nc}) and bound weights ({nb}) for {p} observations"
            ));
        }
        Ok(())
    }

    /// The transport has one row per observation and basis, a power-of-two map side, and
    /// indexes only that map's coefficients.
    fn check_transport(&self) -> Result<()> {
        let p = self.obs.vertex.len();
        let t = self.transport;
        if t.n_obs != p || t.offsets.len() != p * t.n_basis + 1 {
            return invalid(format!(
                "transport has {} observations × {} bases ({} offsets) for {p} observations",
                t.n_obs,
                t.n_basis,
                t.offsets.len()
            ));
        }
        if t.n_basis == 0 || t.n_global < 2 || !t.n_global.is_power_of_two() {
            return invalid(format!(
                "transport has {} bases and map side {}",
                t.n_basis, t.n_global
            ));
        }
        let n2 = (t.n_global * t.n_global) as u32;
        if let Some(i) = t.index.iter().position(|&m| u32::from(m) >= n2) {
            return invalid(format!(
                "transport entry {i} indexes coefficient {} ≥ {n2}",
                t.index[i]
            ));
        }
        Ok(())
    }

    /// One range per photo, inside the observations, holding only that photo's.
    fn check_photo_ranges(&self) -> Result<()> {
        let o = self.obs;
        let p = o.vertex.len();
        if o.photo_ranges.len() != self.n_photos {
            return invalid(format!(
                "{} photo ranges for {} photos",
                o.photo_ranges.len(),
                self.n_photos
            ));
        }
        for (i, r) in o.photo_ranges.iter().enumerate() {
            if r.end > p || r.start > r.end {
                return invalid(format!("photo {i} range {r:?} outside 0..{p}"));
            }
            if let Some(q) = r.clone().find(|&q| o.photo[q] as usize != i) {
                return invalid(format!(
                    "observation {q} is in photo {i}'s range but names photo {}",
                    o.photo[q]
                ));
            }
        }
        Ok(())
    }

    /// Every observation names a vertex of the mesh and has a finite, non-negative weight
    /// and a finite colour.
    fn check_values(&self) -> Result<()> {
        let o = self.obs;
        if let Some(q) = o.vertex.iter().position(|&x| x as usize >= self.n_vertices) {
            return invalid(format!(
                "observation {q} names vertex {} of {}",
                o.vertex[q], self.n_vertices
            ));
        }
        if let Some(q) = (0..o.vertex.len()).find(|&q| {
            !(o.weight[q].is_finite() && o.weight[q] >= 0.0)
                || o.rgb[q].iter().any(|v| !v.is_finite())
        }) {
            return invalid(format!(
                "observation {q} has weight {} and colour {:?}",
                o.weight[q], o.rgb[q]
            ));
        }
        Ok(())
    }
}

/// An inconsistent estimation problem: an internal error (the pipeline built it wrong).
fn invalid(m: String) -> Result<()> {
    Err(Error::Internal(format!("estimation problem: {m}")))
}

/// `f(i)` for `i` in `0..sizes.len()`, in parallel, in index order, the items started
/// largest first: each worker takes the largest item not yet started (greedy "longest
/// processing time first"). A few items of unequal cost (photos: 10 of 10K–19K
/// observations at 46,850 vertices) split in halves by index leave one core idle while
/// the other finishes its larger half; largest first bounds the idle tail by the smallest
/// items. Each `f(i)` runs alone, so the results do not depend on the order.
pub fn par_largest_first<T, F>(sizes: &[usize], f: F) -> Vec<T>
where
    T: Send,
    F: Fn(usize) -> T + Sync + Send,
{
    use rayon::iter::ParallelBridge;
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(sizes[i]), i));
    let mut done: Vec<(usize, T)> = order.into_iter().par_bridge().map(|i| (i, f(i))).collect();
    done.sort_by_key(|d| d.0);
    done.into_iter().map(|d| d.1).collect()
}

/// `β_{x,b,c} = Σ_k w_k(x) λ_{k,b,c}`, row-major `V × B`.
pub fn beta_per_vertex(
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    n_vertices: usize,
) -> Vec<[f64; 3]> {
    let k_count = lambda.len();
    let nb = lambda.first().map_or(0, |l| l.len());
    let mut out = vec![[0.0; 3]; n_vertices * nb];
    for x in 0..n_vertices {
        for (k, lk) in lambda.iter().enumerate() {
            let w = weights[x * k_count + k];
            if w == 0.0 {
                continue;
            }
            for b in 0..nb {
                for c in 0..3 {
                    out[x * nb + b][c] += w * lk[b][c];
                }
            }
        }
    }
    out
}

/// Haar coefficients of three texel maps, interleaved per coefficient.
pub(crate) fn haar3(tex: &[Vec<f64>; 3], n: usize) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0; 3]; n * n];
    for (c, t) in tex.iter().enumerate() {
        let mut h = t.clone();
        haar::forward(&mut h, n);
        for (o, v) in out.iter_mut().zip(&h) {
            o[c] = *v;
        }
    }
    out
}

/// `s_{p,b,c} = ⟨g_{p,b}, W x_{I(p),c}⟩` for every observation and basis, row-major `P × B`.
pub fn basis_responses(problem: &Problem, lights: &[[Vec<f64>; 3]]) -> Vec<[f64; 3]> {
    let t = problem.transport;
    let n = t.n_global;
    let nb = t.n_basis;
    let hs: Vec<Vec<[f64; 3]>> = lights.par_iter().map(|l| haar3(l, n)).collect();
    let mut out = vec![[0.0; 3]; problem.obs.vertex.len() * nb];
    out.par_chunks_mut(nb.max(1))
        .enumerate()
        .for_each(|(p, o)| {
            let h = &hs[problem.obs.photo[p] as usize];
            for (b, ob) in o.iter_mut().enumerate() {
                let (idx, val) = t.row(p, b);
                let mut acc = [0.0; 3];
                for (&m, &g) in idx.iter().zip(val) {
                    let hm = h[m as usize];
                    for c in 0..3 {
                        acc[c] += f64::from(g) * hm[c];
                    }
                }
                *ob = acc;
            }
        });
    out
}

/// Model prediction per observation: `Σ_b β_{x,b,c} s_{p,b,c}`.
pub fn predict(problem: &Problem, est: &Estimate) -> Vec<[f64; 3]> {
    let beta = beta_per_vertex(&est.lambda, &est.weights, problem.n_vertices);
    let s = basis_responses(problem, &est.lights);
    predict_from(problem, &beta, &s)
}

/// [`predict`] from per-vertex reflectance `beta` (`V × B`) and the basis responses `s`
/// ([`basis_responses`]).
pub fn predict_from(problem: &Problem, beta: &[[f64; 3]], s: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let nb = problem.transport.n_basis;
    (0..problem.obs.vertex.len())
        .into_par_iter()
        .map(|p| {
            let x = problem.obs.vertex[p] as usize;
            let mut y = [0.0; 3];
            for b in 0..nb {
                for c in 0..3 {
                    y[c] += beta[x * nb + b][c] * s[p * nb + b][c];
                }
            }
            y
        })
        .collect()
}

/// Observations per fixed-size chunk in ordered parallel reductions.
pub(crate) const CHUNK: usize = 4096;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::TransportValue;

    /// Two observations of one photo, of vertices 0 and 1, one basis over a 2² map.
    fn observations() -> Observations {
        Observations {
            vertex: vec![0, 1],
            photo: vec![0, 0],
            rgb: vec![[0.5; 3]; 2],
            weight: vec![1.0, 1.0],
            dir: vec![[0.0, 0.0, 1.0]; 2],
            photo_ranges: std::iter::once(0..2).collect(),
            clipped: Vec::new(),
            bound_weight: Vec::new(),
        }
    }

    fn transport() -> Transport {
        Transport {
            n_global: 2,
            n_basis: 1,
            n_obs: 2,
            offsets: vec![0, 1, 2],
            index: vec![0, 3],
            value: vec![TransportValue::from_f64(0.5); 2],
        }
    }

    /// The error of validating `obs` and `t` as a problem of 2 vertices and 1 photo, or
    /// `None` when it is accepted.
    fn refusal(obs: &Observations, t: &Transport) -> Option<String> {
        let problem = Problem {
            obs,
            transport: t,
            n_vertices: 2,
            n_photos: 1,
        };
        problem.validate().err().map(|e| e.to_string())
    }

    /// What the refusal must say, and the one change that makes a part inconsistent.
    type Corruption<T> = (&'static str, fn(&mut T));

    /// The consistent problem passes; each inconsistency, made one at a time, is refused
    /// with what is wrong named (every check's first line of defence).
    #[test]
    fn each_inconsistency_is_refused_and_named() {
        let (obs, t) = (observations(), transport());
        assert_eq!(refusal(&obs, &t), None);
        let obs_cases: [Corruption<Observations>; 7] = [
            ("arrays differ in length", |o| o.rgb.push([0.0; 3])),
            ("clipped channels (1)", |o| o.clipped.push(0)),
            ("2 photo ranges for 1 photos", |o| o.photo_ranges.push(2..2)),
            ("outside 0..2", |o| o.photo_ranges[0] = 0..3),
            ("in photo 0's range but names photo 1", |o| o.photo[1] = 1),
            ("names vertex 5 of 2", |o| o.vertex[1] = 5),
            ("has weight NaN", |o| o.weight[0] = f32::NAN),
        ];
        for (want, corrupt) in obs_cases {
            let mut bad = observations();
            corrupt(&mut bad);
            let err = refusal(&bad, &t).unwrap_or_default();
            assert!(err.contains(want), "{want}: {err}");
        }
        let t_cases: [Corruption<Transport>; 3] = [
            ("(2 offsets) for 2 observations", |t| {
                t.offsets.pop();
            }),
            ("map side 3", |t| t.n_global = 3),
            ("indexes coefficient 4 ≥ 4", |t| t.index[1] = 4),
        ];
        for (want, corrupt) in t_cases {
            let mut bad = transport();
            corrupt(&mut bad);
            let err = refusal(&obs, &bad).unwrap_or_default();
            assert!(err.contains(want), "{want}: {err}");
        }
    }
}
