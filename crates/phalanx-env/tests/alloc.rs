//! Counts heap allocations during steady-state steps.
fn main() {}
