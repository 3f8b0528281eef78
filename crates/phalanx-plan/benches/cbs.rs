//! Criterion benchmark of CBS on seeded formation instances.

fn main() {}
