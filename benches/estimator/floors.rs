//! Part 6: the floors against samples per pixel and transport resolution.

use super::*;

/// Part 6: the floors (the TRUE reflectance under the TRUE light through the transport,
/// against the rendered photos) against samples per pixel and transport resolution, to
/// split the renderer's Monte-Carlo noise from the transport's discretisation; written to
/// `bench-results/estimator-floors.*`.
pub(crate) fn floors(md: &mut String) -> Value {
    // `FLOOR_WIDTH`: photo side (default 64); `FLOOR_SPP`: the sample counts (comma list).
    let width: u32 = std::env::var("FLOOR_WIDTH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64);
    md.push_str(&format!("## 6. Floors: Monte-Carlo noise against discretisation\n\n\
        Floor = relative RMSE of the TRUE reflectance under the TRUE light through the transport against the rendered photos \
        (training and held-out photos apart). Photos {width}², the same render reused for every transport of a row group \
        (only the transport is rebuilt). Noise halves with 4× the samples; discretisation does not move with samples.\n\n\
        | scene | spp × MIS pairs | global² / local² | floor (train) | floor (held out) | seconds synth / prepare |\n|---|---|---|---|---|---|\n"));
    let mut rows = Vec::new();
    // (scene, samples per pixel, (global, local) transports).
    type Group<'a> = (&'a str, Vec<u32>, Vec<(usize, usize)>);
    let groups: Vec<Group> = vec![
        ("sphere-diffuse", vec![16, 64], vec![(32, 16), (64, 32)]),
        ("sphere-glossy", vec![16, 64], vec![(32, 16), (64, 32)]),
        ("sphere-specular", vec![16, 64], vec![(32, 16), (64, 32)]),
        ("spot-varying", vec![8, 32], vec![(16, 8), (32, 16)]),
        ("spot-ggx", vec![8, 32], vec![(16, 8), (32, 16), (64, 32)]),
    ];
    // `FLOOR_NORMAL_GRID`: the rotations' normal grid side (default 16).
    let normal_grid: usize = std::env::var("FLOOR_NORMAL_GRID")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(16);
    let spp_override: Option<Vec<u32>> = std::env::var("FLOOR_SPP")
        .ok()
        .map(|v| v.split(',').map(|x| x.trim().parse().unwrap()).collect());
    let only = std::env::var("FLOOR_SCENES").ok();
    for (scene, spps, trans) in groups {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|v| v == scene))
        {
            continue;
        }
        for spp in spp_override.clone().unwrap_or(spps) {
            let s0 = Sizes {
                width,
                vertices: 2_500,
                spp,
                ..sizes_known()
            };
            let dir = scratch(&format!("floors-{scene}-{spp}-{width}"));
            let secs = synthesize(scene, &dir.0.join("ws"), s0, 1);
            for &(g, l) in &trans {
                let s = Sizes {
                    global: g,
                    local: l,
                    normal_grid,
                    ..s0
                };
                // `prepare_in` takes ownership of a scratch guard; the real guard `dir`
                // outlives it and removes the folder at the end of the spp loop body.
                let case = prepare_in(scene, Scratch(dir.0.clone()), secs, s, 1);
                let t = predict_with(
                    &case.train,
                    case.nv,
                    &case.lambda,
                    &case.weights,
                    &case.train.lights,
                );
                let ft = rel_rmse(&case.train.obs, &t, false).0;
                let h = case.predict_held(&case.lambda, &case.weights);
                let fh = if case.held.obs.is_empty() {
                    f64::NAN
                } else {
                    rel_rmse(&case.held.obs, &h, false).0
                };
                eprintln!("floors {scene} spp {spp} {g}/{l}: train {ft:.4}, held {fh:.4}, {secs:.1} / {:.1} s", case.seconds_prepare);
                md.push_str(&format!(
                    "| {scene} | {spp} × {} | {g}² / {l}² | {ft:.4} | {} | {secs:.1} / {:.1} |\n",
                    s.light_samples,
                    if fh.is_finite() {
                        format!("{fh:.4}")
                    } else {
                        "–".into()
                    },
                    case.seconds_prepare
                ));
                rows.push(json!({"scene": scene, "spp": spp, "light_samples": s.light_samples, "global": g, "local": l, "floor_train": ft, "floor_heldout": if fh.is_finite() { json!(fh) } else { Value::Null }, "observations": case.train.obs.len(), "seconds_synth": secs, "seconds_prepare": case.seconds_prepare}));
                std::mem::forget(case.scratch);
            }
        }
    }
    md.push('\n');
    json!(rows)
}
