//! Criterion benchmark of the generator on the paper's largest maps.

use criterion::{Criterion, criterion_group, criterion_main};
use phalanx_gen::{GenConfig, generate};

fn generate_1024(c: &mut Criterion) {
    let config = GenConfig { size: 1024, density: 0.15, n_agents: 3, seed: 1, fov: 9 };
    let inst = generate(&config).unwrap();
    assert_eq!(inst.grid().n_blocked(), (0.15f64 * 1024.0 * 1024.0).round() as usize);
    c.bench_function("generate/1024x1024/d0.15/k3", |b| b.iter(|| generate(&config).unwrap()));
}

criterion_group!(benches, generate_1024);
criterion_main!(benches);
