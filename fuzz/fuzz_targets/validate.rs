//! Fuzz target `validate`: the body [`phalanx_fuzz::validate_plan`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::validate_plan(data));
