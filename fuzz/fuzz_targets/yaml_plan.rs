//! Fuzz target `yaml_plan`: the body [`phalanx_fuzz::yaml_plan`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::yaml_plan(data));
