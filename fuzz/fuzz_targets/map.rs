//! Fuzz target `map`: the body [`phalanx_fuzz::map`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::map(data));
