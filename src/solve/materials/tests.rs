use super::*;
use crate::transport::Transport;

/// One vertex's data for the `w` step: observations, transport (only its basis count
/// is read), basis responses `s` and materials `λ`.
struct OneVertex {
    obs: Observations,
    transport: Transport,
    s: Vec<[f64; 3]>,
    lambda: Vec<Vec<[f64; 3]>>,
}

impl OneVertex {
    /// The `w` step's weights from `w0` under `rules`, every observation at data weight 1.
    fn weights(&self, w0: &[f64], rules: WeightsRules) -> Vec<f64> {
        let dw = vec![[1.0; 3]; self.obs.len()];
        weights_step(&self.problem(), &self.s, &self.lambda, w0, &dw, rules)
            .unwrap()
            .weights
    }

    /// The `w` step's problem over this one vertex and its four photos.
    fn problem(&self) -> Problem<'_> {
        Problem {
            obs: &self.obs,
            transport: &self.transport,
            n_vertices: 1,
            n_photos: 4,
        }
    }
}

/// One vertex seen by four observations, two materials of one basis: the `w` step's
/// normal equations are 2 × 2, so the prior's minimiser has a closed form.
fn one_vertex() -> OneVertex {
    let mut obs = Observations::default();
    let s = vec![
        [1.0, 0.8, 0.6],
        [0.5, 0.9, 1.2],
        [1.5, 0.4, 0.7],
        [0.9, 1.1, 0.3],
    ];
    let rgb = [
        [0.9, 0.7, 0.5],
        [0.6, 0.8, 0.9],
        [1.1, 0.5, 0.6],
        [0.7, 0.9, 0.4],
    ];
    for (p, y) in rgb.iter().enumerate() {
        obs.vertex.push(0);
        obs.photo.push(p as u32);
        obs.rgb.push(*y);
        obs.weight.push(1.0);
        obs.dir.push([0.0, 0.0, 1.0]);
        obs.photo_ranges.push(p..p + 1);
    }
    let t = Transport {
        n_global: 2,
        n_basis: 1,
        n_obs: 4,
        offsets: vec![0; 5],
        ..Default::default()
    };
    let lambda = vec![vec![[0.8, 0.4, 0.2]], vec![[0.2, 0.4, 0.7]]];
    OneVertex {
        obs,
        transport: t,
        s,
        lambda,
    }
}

/// `(M, b)` of the plain `w` step: `M = Σ a aᵀ`, `b = Σ a y` over observations and
/// channels, `a_k = λ_{k,c} s_{p,c}`.
fn normal_equations(
    obs: &Observations,
    s: &[[f64; 3]],
    lambda: &[Vec<[f64; 3]>],
) -> ([[f64; 2]; 2], [f64; 2]) {
    let (mut m, mut b) = ([[0.0; 2]; 2], [0.0; 2]);
    for p in 0..obs.len() {
        for c in 0..3 {
            let a = [lambda[0][0][c] * s[p][c], lambda[1][0][c] * s[p][c]];
            for i in 0..2 {
                b[i] += a[i] * obs.rgb[p][c] as f64;
                for j in 0..2 {
                    m[i][j] += a[i] * a[j];
                }
            }
        }
    }
    (m, b)
}

fn solve2(m: [[f64; 2]; 2], b: [f64; 2]) -> [f64; 2] {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    [
        (m[1][1] * b[0] - m[0][1] * b[1]) / det,
        (m[0][0] * b[1] - m[1][0] * b[0]) / det,
    ]
}

#[test]
fn sum_to_one_prior_matches_the_closed_form_and_its_hard_limit() {
    let v = one_vertex();
    let (obs, s, lambda) = (&v.obs, &v.s, &v.lambda);
    let w0 = vec![0.5, 0.5];
    // γ by hand: Σ_p Σ_c y² of the four observations.
    let y2: f64 = obs.rgb.iter().flatten().map(|&v| (v as f64).powi(2)).sum();
    let gamma = sum_weights_gamma(obs, 1, 0.3);
    assert!((gamma[0] - 0.3 * y2).abs() < 1e-12 * y2);
    let (m, b) = normal_equations(obs, s, lambda);
    // Soft prior: (M + γ 1 1ᵀ) w = b + γ 1. Both weights come out positive here, so
    // the NNLS solution is the unconstrained one: equal to rounding (1e-10 relative
    // covers the active-set solver's Cholesky on a 2 × 2 system).
    let g = gamma[0];
    let soft = solve2(
        [[m[0][0] + g, m[0][1] + g], [m[1][0] + g, m[1][1] + g]],
        [b[0] + g, b[1] + g],
    );
    assert!(soft.iter().all(|&v| v > 0.0), "{soft:?}");
    let w = v.weights(
        &w0,
        WeightsRules {
            gamma: Some(&gamma),
            ..Default::default()
        },
    );
    for k in 0..2 {
        assert!((w[k] - soft[k]).abs() < 1e-10, "{:?} vs {soft:?}", w);
    }
    // Off: the plain least squares, whose weights do not sum to one.
    let free = solve2(m, b);
    let w = v.weights(&w0, WeightsRules::default());
    for k in 0..2 {
        assert!((w[k] - free[k]).abs() < 1e-10);
    }
    assert!((free[0] + free[1] - 1.0).abs() > 0.05, "{free:?}");
    // The hard limit (τ = 10⁸): least squares on the line w₀ + w₁ = 1, by Lagrange:
    // w = M⁻¹ (b − ν 1) with ν chosen so that 1ᵀ w = 1. The soft solution is within
    // O(1/γ) of it: |M| ≈ 1, γ ≈ 10⁸ ⇒ 1e-6 is ample.
    let (mi_b, mi_1) = (solve2(m, b), solve2(m, [1.0, 1.0]));
    let nu = (mi_b[0] + mi_b[1] - 1.0) / (mi_1[0] + mi_1[1]);
    let hard = [mi_b[0] - nu * mi_1[0], mi_b[1] - nu * mi_1[1]];
    let gamma = sum_weights_gamma(obs, 1, 1e8);
    let w = v.weights(
        &w0,
        WeightsRules {
            gamma: Some(&gamma),
            ..Default::default()
        },
    );
    for k in 0..2 {
        assert!((w[k] - hard[k]).abs() < 1e-6, "{:?} vs {hard:?}", w);
    }
    // The penalty's value at a point off the line, by hand.
    let p = sum_weights_penalty(&[2.0, 0.0], &[0.7, 0.6, 5.0, 5.0], 2);
    assert!((p - 2.0 * 0.3f64.powi(2)).abs() < 1e-15);
}

/// A small two-material, two-lobe (Lambert + specular) problem: `V` vertices with
/// positive blends, each seen by `per` observations with pseudo-random positive basis
/// responses per channel; `y` = the truth's prediction times `1 + noise · u`, `u` in
/// [−1, 1] pseudo-random.
struct TiedCase {
    obs: Observations,
    transport: Transport,
    s: Vec<[f64; 3]>,
    weights: Vec<f64>,
}

/// The truth of [`tied_case`]: colour in the diffuse lobe, achromatic specular weights.
const TRUTH: [[[f64; 3]; 2]; 2] = [
    [[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]],
    [[0.2, 0.3, 0.6], [0.15, 0.15, 0.15]],
];

fn tied_case(noise: f64) -> TiedCase {
    let (nv, per, nb) = (6, 8, 2);
    let mut state = 12345u64;
    let mut rand = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let weights: Vec<f64> = (0..nv * 2).map(|_| 0.2 + 0.8 * rand()).collect();
    let mut obs = Observations::default();
    let mut s = Vec::new();
    for x in 0..nv {
        for _ in 0..per {
            let p = obs.vertex.len();
            let sp: Vec<[f64; 3]> = (0..nb).map(|_| [0, 1, 2].map(|_| 0.1 + rand())).collect();
            let y = [0, 1, 2].map(|c| {
                let clean: f64 = (0..2)
                    .map(|k| {
                        weights[x * 2 + k] * (0..nb).map(|b| TRUTH[k][b][c] * sp[b][c]).sum::<f64>()
                    })
                    .sum();
                (clean * (1.0 + noise * (2.0 * rand() - 1.0))) as f32
            });
            s.extend(sp);
            obs.vertex.push(x as u32);
            obs.photo.push(0);
            obs.rgb.push(y);
            obs.weight.push(1.0);
            obs.dir.push([0.0, 0.0, 1.0]);
            obs.photo_ranges.push(p..p + 1);
        }
    }
    let n = obs.vertex.len();
    let transport = Transport {
        n_global: 2,
        n_basis: nb,
        n_obs: n,
        offsets: vec![0; n * nb + 1],
        ..Default::default()
    };
    TiedCase {
        obs,
        transport,
        s,
        weights,
    }
}

fn lambda_of(case: &TiedCase, coupling: LambdaCoupling) -> Vec<Vec<[f64; 3]>> {
    let problem = Problem {
        obs: &case.obs,
        transport: &case.transport,
        n_vertices: 6,
        n_photos: case.obs.photo_ranges.len(),
    };
    let dw = vec![[1.0; 3]; case.obs.len()];
    let l = lambda_step(
        &problem,
        &case.s,
        &case.weights,
        2,
        &dw,
        Some([0.0; 3]),
        0.0,
        coupling,
    )
    .unwrap();
    l.lambda
}

const TIED: LambdaCoupling = LambdaCoupling {
    achromatic_except: Some(0),
    pruned: &[],
};

#[test]
fn achromatic_step_recovers_an_achromatic_truth_without_noise() {
    let case = tied_case(0.0);
    let lam = lambda_of(&case, TIED);
    // The observations are stored as f32 (relative rounding 6e-8) and the system is
    // well conditioned (responses in [0.1, 1.1], blends in [0.2, 1]): 1e-5 absolute on
    // weights of 0.15–0.8 leaves a margin of ~100 over the rounding's effect.
    for k in 0..2 {
        for b in 0..2 {
            for c in 0..3 {
                let d = (lam[k][b][c] - TRUTH[k][b][c]).abs();
                assert!(
                    d < 1e-5,
                    "λ[{k}][{b}][{c}] {} vs {}",
                    lam[k][b][c],
                    TRUTH[k][b][c]
                );
            }
        }
    }
}

/// The tied NNLS against the least squares of the reduced design solved directly
/// (SVD of the stacked rows, one per observation and channel, columns: the 2 × 3
/// diffuse weights and the 2 shared specular ones).
#[test]
fn achromatic_step_is_the_least_squares_of_the_reduced_design() {
    let case = tied_case(0.05);
    let lam = lambda_of(&case, TIED);
    let free = lambda_of(&case, LambdaCoupling::default());
    let np = case.obs.len();
    let mut a = DMatrix::<f64>::zeros(np * 3, 8);
    let mut y = DVector::<f64>::zeros(np * 3);
    for p in 0..np {
        let x = case.obs.vertex[p] as usize;
        for c in 0..3 {
            let r = p * 3 + c;
            for k in 0..2 {
                let w = case.weights[x * 2 + k];
                a[(r, k * 3 + c)] = w * case.s[p * 2][c];
                a[(r, 6 + k)] = w * case.s[p * 2 + 1][c];
            }
            y[r] = case.obs.rgb[p][c] as f64;
        }
    }
    let z = a.clone().svd(true, true).solve(&y, 1e-14).unwrap();
    // Every z is positive, so the NNLS optimum is the unconstrained one; both are
    // solved in f64 on a system with condition number ~10²: 1e-9 is ample.
    assert!(z.iter().all(|&v| v > 0.0), "{z}");
    for k in 0..2 {
        for c in 0..3 {
            assert!((lam[k][0][c] - z[k * 3 + c]).abs() < 1e-9, "{lam:?} vs {z}");
            assert!((lam[k][1][c] - z[6 + k]).abs() < 1e-9, "{lam:?} vs {z}");
        }
    }
    // The constraint binds: the free channels' specular weights differ by more than
    // the 5% noise allows to vanish (> 1e-3), and fit the data at least as well.
    let spread = |l: &[[f64; 3]]| {
        let v = l[1];
        v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
    };
    assert!(
        spread(&free[0]) > 1e-3 || spread(&free[1]) > 1e-3,
        "{free:?}"
    );
    let sse = |l: &[Vec<[f64; 3]>]| {
        let mut e = 0.0;
        for p in 0..np {
            let x = case.obs.vertex[p] as usize;
            for c in 0..3 {
                let pred: f64 = (0..2)
                    .map(|k| {
                        case.weights[x * 2 + k]
                            * (0..2)
                                .map(|b| l[k][b][c] * case.s[p * 2 + b][c])
                                .sum::<f64>()
                    })
                    .sum();
                e += (pred - case.obs.rgb[p][c] as f64).powi(2);
            }
        }
        e
    };
    assert!(sse(&free) <= sse(&lam) * (1.0 + 1e-12));
}

#[test]
fn neighbour_pull_matches_the_closed_form_and_its_hard_limit() {
    let v = one_vertex();
    let (obs, s, lambda) = (&v.obs, &v.s, &v.lambda);
    // Vertex 0 (the fitted one) has one neighbour, vertex 1, whose weights are fixed here:
    // the pull's mean is vertex 1's weights.
    let m_nb = [0.2, 0.9];
    let w0 = vec![0.5, 0.5, m_nb[0], m_nb[1]];
    let graph = propagate::VertexGraph {
        offsets: vec![0, 1, 1],
        targets: vec![1],
    };
    let (m, b) = normal_equations(obs, s, lambda);
    for eta in [0.05, 1.0] {
        let pull = NeighbourPull {
            eta: &[eta, 1.0],
            graph: &graph,
        };
        // (M + η I) w = b + η w̄: both weights positive, so NNLS gives the unconstrained
        // solution, equal to rounding (1e-10 as above).
        let want = solve2(
            [[m[0][0] + eta, m[0][1]], [m[1][0], m[1][1] + eta]],
            [b[0] + eta * m_nb[0], b[1] + eta * m_nb[1]],
        );
        assert!(want.iter().all(|&v| v > 0.0), "{want:?}");
        let w = v.weights(
            &w0,
            WeightsRules {
                pull: Some(pull),
                ..Default::default()
            },
        );
        for k in 0..2 {
            assert!((w[k] - want[k]).abs() < 1e-10, "{:?} vs {want:?}", w);
        }
        // The penalty η ‖w − w̄‖² of that answer (vertex 1 has no neighbours: no term).
        let mut both = w.clone();
        both.extend_from_slice(&m_nb);
        let pen = eta * ((want[0] - m_nb[0]).powi(2) + (want[1] - m_nb[1]).powi(2));
        assert!((pull.penalty(&both, 2) - pen).abs() < 1e-12);
    }
    // The hard limit: the neighbours' mean itself, within O(1/η) (|M| ≈ 1, η = 10⁸).
    let pull = NeighbourPull {
        eta: &[1e8, 1.0],
        graph: &graph,
    };
    let w = v.weights(
        &w0,
        WeightsRules {
            pull: Some(pull),
            ..Default::default()
        },
    );
    for k in 0..2 {
        assert!((w[k] - m_nb[k]).abs() < 1e-6, "{:?}", w);
    }
    // A neighbour without fitted weights (η = 0) is not pulled toward: no pull at all.
    let pull = NeighbourPull {
        eta: &[1.0, 0.0],
        graph: &graph,
    };
    let free = v.weights(&w0, WeightsRules::default());
    let w = v.weights(
        &w0,
        WeightsRules {
            pull: Some(pull),
            ..Default::default()
        },
    );
    assert_eq!(w, free);
}

#[test]
fn blend_share_is_zero_at_a_pure_vertex_and_one_at_an_even_blend() {
    // By hand from b = min(1, 2 (1 − max_k w_k / Σ_k w_k)); every value is a short
    // binary fraction or the ratio of two, so 1e-15 only covers the last bit.
    let cases: [(&[f64], f64); 7] = [
        (&[1.0, 0.0], 0.0),
        (&[0.0, 3.0], 0.0),
        (&[0.5, 0.5], 1.0),
        (&[0.7, 0.3], 0.6),
        (&[1.4, 0.6], 0.6),      // invariant to the row's scale
        (&[1.0, 1.0, 1.0], 1.0), // largest share ⅓ < ½: capped at 1
        (&[0.0, 0.0], 1.0),      // no material yet: the tie stays whole
    ];
    for (w, want) in cases {
        assert!((blend_share(w) - want).abs() < 1e-15, "{w:?}");
    }
    // γ scaled per vertex (rows of V × K = 3 × 2), pure vertices kept at the floor.
    let gamma = [2.0, 3.0, 4.0];
    let weights = [1.0, 0.0, 0.7, 0.3, 0.5, 0.5];
    let scaled = blend_scaled_gamma(&gamma, &weights, 2, 0.2);
    let want = [2.0 * 0.2, 3.0 * 0.6, 4.0];
    for x in 0..3 {
        assert!((scaled[x] - want[x]).abs() < 1e-15, "{scaled:?}");
    }
}

/// `nv` vertices seen by `np` photos each (one basis), two materials with correlated
/// colours; vertex `x`'s true weights `truth(x)` and Gaussian noise of σ on every channel.
fn noisy_vertices(
    nv: usize,
    np: usize,
    sigma: f64,
    truth: impl Fn(usize) -> [f64; 2],
) -> (OneVertex, usize) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let lambda = vec![vec![[0.8, 0.5, 0.3]], vec![[0.5, 0.5, 0.6]]];
    let (mut obs, mut s) = (Observations::default(), Vec::new());
    for p in 0..np {
        let start = obs.len();
        for x in 0..nv {
            let sp = [0, 1, 2].map(|_| 0.5 + rng.random::<f64>());
            let w = truth(x);
            let y = [0, 1, 2].map(|c| {
                let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
                let e = (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
                ((w[0] * lambda[0][0][c] + w[1] * lambda[1][0][c]) * sp[c] + sigma * e) as f32
            });
            obs.vertex.push(x as u32);
            obs.photo.push(p as u32);
            obs.rgb.push(y);
            obs.weight.push(1.0);
            obs.dir.push([0.0, 0.0, 1.0]);
            s.push(sp);
        }
        obs.photo_ranges.push(start..obs.len());
    }
    let n = obs.len();
    let transport = Transport {
        n_global: 2,
        n_basis: 1,
        n_obs: n,
        offsets: vec![0; n + 1],
        ..Default::default()
    };
    (
        OneVertex {
            obs,
            transport,
            s,
            lambda,
        },
        np,
    )
}

/// With `bic = 1` a vertex of one material keeps a second one about as often as BIC's
/// rate predicts, and a real blend keeps both. 400 pure vertices and 100 blends (60/40),
/// 20 photos × 3 channels each (`ln 60 = 4.09`), σ = 0.03. Expected share of pure vertices
/// keeping the second material: `½ P(χ²₁ > 4.09) = 0.0215` (support.rs's tests), with σ²
/// estimated from the step's own residuals; its standard deviation over 400 is 0.0072, so
/// 0.06 is more than 5 of them. Without BIC, NNLS keeps it on about half (its unconstrained
/// estimate is unbiased around 0): more than 0.3 allows 8 standard deviations (0.025).
#[test]
fn bic_drops_the_second_material_of_pure_vertices_and_keeps_blends() {
    let (nv, pure) = (500, 400);
    let truth = |x: usize| if x < pure { [1.0, 0.0] } else { [0.6, 0.4] };
    let (v, np) = noisy_vertices(nv, 20, 0.03, truth);
    let problem = Problem {
        obs: &v.obs,
        transport: &v.transport,
        n_vertices: nv,
        n_photos: np,
    };
    let dw = vec![[1.0; 3]; v.obs.len()];
    let w0 = vec![0.5; nv * 2];
    let share = |bic: f64| {
        let rules = WeightsRules {
            bic,
            ..Default::default()
        };
        let w = weights_step(&problem, &v.s, &v.lambda, &w0, &dw, rules).unwrap();
        let kept = (0..pure).filter(|&x| w.weights[2 * x + 1] > 0.0).count();
        let blends = (pure..nv).filter(|&x| w.weights[2 * x] > 0.0 && w.weights[2 * x + 1] > 0.0);
        (kept as f64 / pure as f64, blends.count())
    };
    let (with_bic, blends) = share(1.0);
    assert!(
        with_bic < 0.06,
        "pure vertices keeping a second material: {with_bic}"
    );
    assert_eq!(blends, nv - pure, "every blend keeps both materials");
    let (without, _) = share(0.0);
    assert!(without > 0.3, "NNLS alone: {without}");
}

/// A pruned entry ([`crate::solve::lobe_prune`]) held at zero: the step's other entries
/// against the least squares of the design without that column, solved directly (SVD of
/// the stacked rows per channel: columns the other three `λ_{k,b,c}`).
#[test]
fn pruned_entry_is_held_at_zero_and_the_rest_solve_the_reduced_design() {
    let case = tied_case(0.05);
    // Material 1's specular lobe (index 1·2 + 1, the weaker) held at zero.
    let pruned = [false, false, false, true];
    let coupling = LambdaCoupling {
        achromatic_except: None,
        pruned: &pruned,
    };
    let lam = lambda_of(&case, coupling);
    let np = case.obs.len();
    let cols = [(0, 0), (0, 1), (1, 0)];
    for c in 0..3 {
        assert_eq!(lam[1][1][c], 0.0);
        let mut a = DMatrix::<f64>::zeros(np, 3);
        let mut y = DVector::<f64>::zeros(np);
        for p in 0..np {
            let x = case.obs.vertex[p] as usize;
            for (j, &(k, b)) in cols.iter().enumerate() {
                a[(p, j)] = case.weights[x * 2 + k] * case.s[p * 2 + b][c];
            }
            y[p] = case.obs.rgb[p][c] as f64;
        }
        let z = a.svd(true, true).solve(&y, 1e-14).unwrap();
        // Every z is positive (the dropped lobe's light goes to the others), so the NNLS
        // optimum is the unconstrained one; both in f64 on a system with condition number
        // ~10²: 1e-9 is ample.
        assert!(z.iter().all(|&v| v > 0.0), "{z}");
        for (j, &(k, b)) in cols.iter().enumerate() {
            assert!((lam[k][b][c] - z[j]).abs() < 1e-9, "{lam:?} vs {z}");
        }
    }
}
