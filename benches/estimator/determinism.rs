//! Part 4: determinism, bitwise, on 1 and 2 threads.

use super::*;

pub(crate) fn determinism(md: &mut String) -> Value {
    let s = Sizes {
        width: 64,
        vertices: 2000,
        spp: 4,
        ..sizes_joint()
    };
    let case = prepare("spot-varying", s, 1, "determinism");
    let o = EstimateOptions {
        max_outer: 4,
        ..EstimateOptions::default()
    };
    let bits = estimate_bits;
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| bits(&joint_fit(&case, &case.train.obs, &o, PAPER_START).0))
    };
    let a = run(2);
    let b = run(2);
    let c = run(1);
    let same_ab = a == b;
    let same_ac = a == c;
    md.push_str(&format!(
        "## 4. Determinism\n\n`spot-varying` at 64², 4 outer iterations, the k-means start included: {} output numbers (maps, λ, w). \
         Two runs on 2 threads bitwise identical: {same_ab}; 2 threads against 1 thread bitwise identical: {same_ac}.\n\n",
        a.len()
    ));
    json!({"values": a.len(), "identical_same_threads": same_ab, "identical_1_vs_2_threads": same_ac})
}
