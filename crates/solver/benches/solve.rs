//! Times `solve_direct` (three coloured bands: three LU factorisations), restarted GMRES to
//! 1e-12 and 8 bounces, for n = 500, 1000, 2000: the solver's cost per N.

use std::hint::black_box;
use std::time::Duration;

use bake_solver::{solve_bounces, solve_direct, solve_iterative, DenseMatrix, IterativeOptions};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode};

/// Deterministic bench data: positive rows with F_ii = 0 summing to 0.9 (a slightly open scene),
/// coloured reflectances and a few emitters. A multiplicative hash keeps it dependency-free.
fn scene(n: usize) -> (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let hash = |k: u64| {
        let z = k.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        ((z ^ (z >> 29)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut f = vec![0.0; n * n];
    for i in 0..n {
        let row = &mut f[i * n..(i + 1) * n];
        for (j, v) in row.iter_mut().enumerate() {
            *v = if i == j {
                0.0
            } else {
                0.05 + hash((i * n + j) as u64)
            };
        }
        let sum: f64 = row.iter().sum();
        row.iter_mut().for_each(|v| *v *= 0.9 / sum);
    }
    let rho = (0..n)
        .map(|i| [0.75, 0.5, 0.25 + 0.5 * hash(i as u64)])
        .collect();
    let e = (0..n)
        .map(|i| if i % 50 == 0 { [1.0; 3] } else { [0.0; 3] })
        .collect();
    (f, rho, e)
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("solve_direct_rgb");
    // 10 samples of one or more solves each; about 15 s in all on 2 cores.
    group
        .sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(500));
    for (n, seconds) in [(500, 2), (1000, 3), (2000, 7)] {
        group.measurement_time(Duration::from_secs(seconds));
        let (f, rho, e) = scene(n);
        let f = DenseMatrix::new(n, &f).expect("bench matrix is n x n");
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| solve_direct(black_box(&f), black_box(&rho), black_box(&e)))
        });
    }
    group.finish();
}

/// The O(n²)-per-iteration solvers on the same systems.
fn iterative(c: &mut Criterion) {
    let mut group = c.benchmark_group("solve_iterative_rgb");
    group
        .sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for n in [500, 1000, 2000] {
        let (f, rho, e) = scene(n);
        let f = DenseMatrix::new(n, &f).expect("bench matrix is n x n");
        let options = IterativeOptions::default();
        group.bench_with_input(BenchmarkId::new("gmres", n), &n, |b, _| {
            b.iter(|| solve_iterative(black_box(&f), black_box(&rho), black_box(&e), &options))
        });
        group.bench_with_input(BenchmarkId::new("bounces_8", n), &n, |b, _| {
            b.iter(|| solve_bounces(black_box(&f), black_box(&rho), black_box(&e), 8))
        });
    }
    group.finish();
}

criterion_group!(benches, bench, iterative);
criterion_main!(benches);
