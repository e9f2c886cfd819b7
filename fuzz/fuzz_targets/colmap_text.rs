//! libFuzzer target: arbitrary bytes into the colmap text reader(s); see `relight_cpc_fuzz::colmap_text`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relight_cpc_fuzz::colmap_text(data);
});
