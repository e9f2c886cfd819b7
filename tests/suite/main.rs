//! The integration tests, built as one binary: one link instead of one per file (39 of
//! them, each carrying its own copy of the library and its dependencies, filled CI's disk).
//! Run one file's tests with `cargo test --test suite -- FILE::`.

#[path = "../agreement_support/mod.rs"]
mod agreement_support;
#[path = "../support/colmap_model.rs"]
mod colmap_model;
#[path = "../support/octahedron.rs"]
mod octahedron;
#[path = "../support/random.rs"]
mod random;
#[path = "../support/scratch.rs"]
mod scratch;
#[path = "../support/synth_case.rs"]
mod synth_case;
#[path = "../support/uv_sphere.rs"]
mod uv_sphere;

mod adapt;
mod bench_isolated;
mod brdf_slices;
mod clipped_bounds;
mod cluster_init;
mod colmap_camera;
mod colmap_errors;
mod colmap_fixture;
mod colmap_roundtrip;
mod colmap_synth_fixture;
mod core_fixture;
mod core_pipeline;
mod estimate_planted;
mod estimate_scale;
mod estimate_shared;
mod estimate_sky;
mod estimate_synth;
mod extreme_pipeline;
mod extreme_units;
mod half_prior;
mod inspect_buddha;
mod inspect_dense_buddha;
mod malformed_inputs;
mod mesh_ply;
mod observe_cube;
mod photo_load;
mod propagate_synth;
mod proptest_parsers;
mod qp_kkt;
mod ratio_step;
mod realphoto_effects;
mod reference_analytic;
mod reference_cost;
mod relight_render;
mod render_frames;
mod render_raster;
mod restart;
mod result_use;
mod run_baseline;
mod run_example;
mod run_fixtures;
mod scene_import;
mod start_search;
mod synth_data;
mod synth_workspace;
mod transport_agreement;
mod transport_blended;
mod transport_furnace;
mod varpro_step;
mod visibility_known;
mod workspace_dense_buddha;
mod workspace_discover;
