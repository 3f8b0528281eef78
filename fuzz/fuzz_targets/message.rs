//! Fuzz target `message`: the body [`phalanx_fuzz::message`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::message(data));
