//! The bench's scenes and settings: the synthetic scene per size, the quick and full modes, and the knob sweep of the error-against-time front.

use super::*;

/// Per-stage CPU seconds of a run, with a `total` entry, and its peak memory (MiB) as
/// `peak memory`.
pub(crate) fn stage_costs(run: &BenchRun) -> Vec<(String, f64)> {
    let mut v: Vec<(String, f64)> = run
        .stages
        .iter()
        .map(|s| (s.name.clone(), s.cpu_seconds))
        .collect();
    if run.outer_iterations > 0 {
        v.push(("lighting step".into(), run.steps.lighting_cpu_seconds));
        v.push(("material step".into(), run.steps.material_cpu_seconds));
    }
    v.push(("total".into(), run.total_cpu_seconds));
    v.push(("peak memory".into(), mib(run.peak_memory_bytes)));
    v
}

/// Photo size, renderer effort and default knobs for the mode.
pub(crate) fn mode_settings(
    quick: bool,
) -> (u32, u32, crate::transport::reference::Samples, Knobs) {
    if quick {
        (
            192,
            192,
            crate::transport::reference::Samples {
                per_pixel: 1,
                light: 16,
                seed: 1,
            },
            Knobs {
                global_resolution: 16,
                local_resolution: 8,
                normal_grid: 8,
                keep: 32,
                iterations: 3,
                lighting_qp: RunOptions::default_lighting_qp_iterations(),
            },
        )
    } else {
        // 1024² ≈ 1.05 MP, the paper's photo size; the reference renderer is kept cheap
        // (one path per pixel, 16 MIS pairs) since its noise is not what is measured.
        (
            1024,
            1024,
            crate::transport::reference::Samples {
                per_pixel: 1,
                light: 16,
                seed: 1,
            },
            Knobs {
                global_resolution: 64,
                local_resolution: 32,
                normal_grid: 32,
                keep: 128,
                iterations: RunOptions::DEFAULT_MAX_ITERATIONS,
                lighting_qp: RunOptions::default_lighting_qp_iterations(),
            },
        )
    }
}

/// The sweep's settings and the index of the dense reference among them.
pub(crate) fn sweep_knobs(base: Knobs, quick: bool) -> (Vec<Knobs>, usize) {
    // The rotation's accuracy knob is its normal grid (Eq. 6: the light is rotated into
    // `n × n` precomputed frames and blended between the four nearest); the rotation is
    // applied in factored form, without a threshold on its entries.
    // Two iteration counts: the outer alternation's cap and each lighting QP's GPCG cap.
    type Lists<'a> = (
        &'a [usize],
        &'a [usize],
        &'a [usize],
        &'a [usize],
        &'a [usize],
    );
    let (resolutions, keeps, iterations, grids, qps): Lists = if quick {
        (
            &[8, 16, 32],
            &[16, 32, 64, 0],
            &[1, 2, 3],
            &[4, 8, 16],
            &[2, 3, 5],
        )
    } else {
        (
            &[16, 32, 64],
            &[32, 64, 128, 0],
            &[2, 4, 8],
            &[16, 32, 64],
            &[3, 4, 5],
        )
    };
    let top = *resolutions.last().unwrap_or(&base.global_resolution);
    let mut list: Vec<Knobs> = Vec::new();
    let mut push = |k: Knobs| {
        if !list.contains(&k) {
            list.push(k);
        }
    };
    let at_top = Knobs {
        global_resolution: top,
        ..base
    };
    for &g in resolutions {
        push(Knobs {
            global_resolution: g,
            ..base
        });
    }
    for &k in keeps {
        push(Knobs { keep: k, ..at_top });
    }
    for &it in iterations {
        push(Knobs {
            iterations: it,
            ..at_top
        });
    }
    for &n in grids {
        push(Knobs {
            normal_grid: n,
            ..at_top
        });
    }
    for &q in qps {
        push(Knobs {
            lighting_qp: q,
            ..at_top
        });
    }
    let reference = Knobs { keep: 0, ..at_top };
    push(reference);
    let idx = list.iter().position(|k| *k == reference).unwrap_or(0);
    (list, idx)
}

/// What identifies a synth workspace: reused from `--work` only when all of it matches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct SceneParams {
    pub(crate) scene: String,
    pub(crate) vertices: usize,
    pub(crate) photos: usize,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) per_pixel: u32,
    pub(crate) light: u32,
    pub(crate) sample_seed: u64,
    pub(crate) seed: u64,
    /// `synth --exact-vertices` (absent in files written before the flag: false).
    #[serde(default)]
    pub(crate) exact_vertices: bool,
    /// What `synth` reported, kept so that a reused workspace reports it too.
    pub(crate) summary_vertices: usize,
    pub(crate) summary_photos: usize,
    pub(crate) render_seconds: f64,
}

impl SceneParams {
    pub(crate) fn same_scene(&self, o: &SceneParams) -> bool {
        (
            &self.scene,
            self.vertices,
            self.photos,
            self.width,
            self.height,
            self.per_pixel,
            self.light,
            self.sample_seed,
            self.seed,
            self.exact_vertices,
        ) == (
            &o.scene,
            o.vertices,
            o.photos,
            o.width,
            o.height,
            o.per_pixel,
            o.light,
            o.sample_seed,
            o.seed,
            o.exact_vertices,
        )
    }
}

/// A workspace ready to fit.
pub(crate) struct BenchScene {
    pub(crate) dir: PathBuf,
    pub(crate) vertices: usize,
    pub(crate) photos: usize,
    pub(crate) render_seconds: f64,
    pub(crate) reused: bool,
}

/// Build a synth workspace in `work` for `(vertices, photos)`, or reuse the one there whose
/// `bench-params.json` (written last, so only a finished build has it) matches.
pub(crate) fn scene(
    opts: &BenchOptions,
    work: &Path,
    vertices: usize,
    photos: usize,
) -> Result<BenchScene> {
    let (width, height, samples, _) = mode_settings(opts.quick);
    let dir = work.join(format!(
        "{}-v{vertices}-p{photos}-{width}x{height}",
        opts.scene
    ));
    let want = SceneParams {
        scene: opts.scene.clone(),
        vertices,
        photos,
        width,
        height,
        per_pixel: samples.per_pixel,
        light: samples.light,
        sample_seed: samples.seed,
        seed: 1,
        exact_vertices: opts.exact_vertices,
        summary_vertices: 0,
        summary_photos: 0,
        render_seconds: 0.0,
    };
    if let Some(s) = reusable(&dir, &want) {
        eprintln!("bench: reusing {}", dir.display());
        return Ok(s);
    }
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    }
    build_scene(dir, want, samples)
}

/// The workspace in `dir` when its `bench-params.json` describes the scene `want`.
fn reusable(dir: &Path, want: &SceneParams) -> Option<BenchScene> {
    let text = std::fs::read_to_string(dir.join("bench-params.json")).ok()?;
    let have = serde_json::from_str::<SceneParams>(&text).ok()?;
    have.same_scene(want).then(|| BenchScene {
        dir: dir.to_path_buf(),
        vertices: have.summary_vertices,
        photos: have.summary_photos,
        render_seconds: have.render_seconds,
        reused: true,
    })
}

/// `synth` of the scene `want` into `dir`, then its `bench-params.json` (last: it marks
/// the build finished).
fn build_scene(
    dir: PathBuf,
    mut want: SceneParams,
    samples: crate::transport::reference::Samples,
) -> Result<BenchScene> {
    let (vertices, photos) = (want.vertices, want.photos);
    let (width, height) = (want.width, want.height);
    eprintln!(
        "bench: synth {} with {}{vertices} vertices, {photos} photos of {width}×{height} ({} primary ray(s)/pixel, {} MIS pairs) → {}",
        want.scene,
        if want.exact_vertices { "" } else { "≥ " },
        samples.per_pixel,
        samples.light,
        dir.display()
    );
    let t0 = std::time::Instant::now();
    let s = synth::build(
        &want.scene,
        &dir,
        &SynthOptions {
            width,
            height,
            photos: Some(photos),
            seed: want.seed,
            vertices: Some(vertices),
            exact_vertices: want.exact_vertices,
            samples,
            ..SynthOptions::default()
        },
    )?;
    eprintln!(
        "bench: synth done in {:.1} s ({} vertices, renderer {:.1} s)",
        t0.elapsed().as_secs_f64(),
        s.vertices,
        s.render_seconds
    );
    want.summary_vertices = s.vertices;
    want.summary_photos = s.photos.len();
    want.render_seconds = s.render_seconds;
    let text = serde_json::to_string_pretty(&want)
        .map_err(|e| Error::Internal(format!("bench: could not encode scene parameters: {e}")))?;
    let params_path = dir.join("bench-params.json");
    std::fs::write(&params_path, text).map_err(|e| Error::io(&params_path, e))?;
    Ok(BenchScene {
        dir,
        vertices: s.vertices,
        photos: s.photos.len(),
        render_seconds: s.render_seconds,
        reused: false,
    })
}
