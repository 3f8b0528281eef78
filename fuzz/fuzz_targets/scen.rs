//! Fuzz target `scen`: the body [`phalanx_fuzz::scen`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::scen(data));
