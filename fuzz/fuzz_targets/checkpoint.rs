//! Fuzz target `checkpoint`: the body [`phalanx_fuzz::checkpoint`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::checkpoint(data));
