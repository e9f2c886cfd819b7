//! Scale measurement (not a check; `#[ignore]`d): one photo of an issue-9-sized lighting
//! step — 64×64 map (4096 texels per channel), 38,000 observations (≈ 500K / 13 photos),
//! B = 7 basis BRDFs, 64 kept Haar coefficients per transport row — timed through
//! `lighting_step_full`. Figures go to `target/bench/estimate_scale.json`.
//!
//! Run: `cargo test --release --test suite -- --ignored --nocapture estimate_scale::`.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use relight_cpc::observe::Observations;
use relight_cpc::solve::{lighting_step_full, EstimateOptions, Problem, Robust};
use relight_cpc::transport::{Transport, TransportValue};
use std::time::Instant;

#[test]
#[ignore]
fn lighting_step_at_issue_9_scale() {
    let (n, nb, np, nnz, nv) = (64usize, 7usize, 38_000usize, 64usize, 100_000usize);
    let mut rng = Pcg64::seed_from_u64(5);
    let mut obs = Observations::default();
    let mut offsets = vec![0usize];
    let mut index = Vec::with_capacity(np * nb * nnz);
    let mut value = Vec::with_capacity(np * nb * nnz);
    for _ in 0..np {
        obs.vertex.push(rng.random_range(0..nv as u32));
        obs.photo.push(0);
        obs.rgb.push([0.0; 3]);
        obs.weight.push(1.0);
        obs.dir.push([0.0, 0.0, 1.0]);
        for _ in 0..nb {
            // Coarse coefficients (the scaling function and low levels) are kept most often.
            index.push(0);
            value.push(TransportValue::from_f64(0.05));
            for _ in 1..nnz {
                let level = rng.random_range(1..7u32);
                let side = 1usize << level;
                let m = rng.random_range(0..side * side).max(1);
                index.push(m as u16);
                value.push(TransportValue::from_f32((rng.random::<f32>() - 0.5) * 0.02));
            }
            offsets.push(index.len());
        }
    }
    obs.photo_ranges.push(0..np);
    let transport = Transport {
        n_global: n,
        n_basis: nb,
        n_obs: np,
        offsets,
        index,
        value,
    };
    // Data from a smooth positive light so the QP has a meaningful answer.
    let beta = vec![[0.3, 0.25, 0.2]; nv * nb];
    let mut light = vec![0.0; n * n];
    for (t, v) in light.iter_mut().enumerate() {
        *v = 1.0 + ((t % n) as f64 / n as f64 * 3.0).sin().abs();
    }
    relight_cpc::sphere::haar::forward(&mut light, n);
    for p in 0..np {
        let x = obs.vertex[p] as usize;
        let mut y = [0.0; 3];
        for b in 0..nb {
            let s = transport.response(p, b, &light);
            for c in 0..3 {
                y[c] += beta[x * nb + b][c] * s;
            }
        }
        obs.rgb[p] = y.map(|v| v.max(0.0) as f32);
    }
    let problem = Problem {
        obs: &obs,
        transport: &transport,
        n_vertices: nv,
        n_photos: 1,
    };
    let mut figures = Vec::new();
    for (name, robust, tol) in [
        ("ls_tol1e-6", Robust::None, 1e-6),
        ("huber4_tol1e-6", Robust::Huber { k: 1.345 }, 1e-6),
    ] {
        let opts = EstimateOptions {
            robust,
            irls_iters: 4,
            qp_rel_tol: tol,
            ..EstimateOptions::default()
        };
        let t0 = Instant::now();
        let r = lighting_step_full(&problem, &beta, 0, None, None, &opts).unwrap();
        let secs = t0.elapsed().as_secs_f64();
        let line = serde_json::json!({
            "case": name,
            "observations": np, "basis": nb, "kept_per_row": nnz, "texels_per_channel": n * n,
            "seconds": secs, "matvecs": r.matvecs,
            "ms_per_matvec": 1e3 * secs / r.matvecs.max(1) as f64,
            "converged": r.converged, "cond_lower_bound": r.cond_lower_bound,
        });
        eprintln!("{line}");
        figures.push(line);
    }
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("estimate_scale.json"),
        serde_json::to_string_pretty(&figures).unwrap(),
    )
    .unwrap();
}
