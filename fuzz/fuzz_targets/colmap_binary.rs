//! libFuzzer target: arbitrary bytes into the colmap binary reader(s); see `relight_cpc_fuzz::colmap_binary`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relight_cpc_fuzz::colmap_binary(data);
});
