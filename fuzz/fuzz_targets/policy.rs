//! Fuzz target `policy`: the body [`phalanx_fuzz::policy`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::policy(data));
