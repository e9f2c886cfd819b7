//! libFuzzer target: arbitrary bytes into the ply reader(s); see `relight_cpc_fuzz::ply`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relight_cpc_fuzz::ply(data);
});
