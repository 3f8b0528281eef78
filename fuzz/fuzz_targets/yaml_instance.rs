//! Fuzz target `yaml_instance`: the body [`phalanx_fuzz::yaml_instance`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| phalanx_fuzz::yaml_instance(data));
