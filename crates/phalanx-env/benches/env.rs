//! Criterion benchmarks of the environment (placeholder).
fn main() {}
