//! libFuzzer target: arbitrary bytes into the envmap reader(s); see `relight_cpc_fuzz::envmap`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    relight_cpc_fuzz::envmap(data);
});
