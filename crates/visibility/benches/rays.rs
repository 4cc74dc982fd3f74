//! Shadow-ray throughput on the Cornell box (fixtures/cornell.gltf, default subdivision: the
//! scene diagonal / 16): the visibility of every occludable element pair with the default
//! samples, on 1 and 2 threads (rays per second), and the occludability test of every element
//! pair (pairs per second).
//! Run: `cargo bench -p bake-visibility --bench rays`.

use bake_visibility::{pair_seed, Occluders, Patch, DEFAULT_SAMPLES};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use mesher::{default_max_element_size, mesh, Subdivision};
use rayon::prelude::*;

fn cornell() -> Vec<importer::Polygon> {
    let path = bake_testkit::fixture("cornell.gltf");
    importer::load(&path)
        .expect("fixtures/cornell.gltf")
        .polygons
}

fn rays(c: &mut Criterion) {
    let polygons = cornell();
    let m = mesh(
        &polygons,
        Subdivision::MaxSize(default_max_element_size(&polygons)),
    )
    .expect("mesh");
    let occluders = Occluders::new(&polygons).expect("occluders");
    let pairs = occluders.occludable_pairs();
    let n = m.elements.len();
    let patches: Vec<Patch> = (0..n).map(|e| Patch::element(&m, e)).collect();
    let occludable: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .filter(|&(i, j)| pairs.can_occlude(&occluders, &patches[i], &patches[j]))
        .collect();
    let cast = |&(i, j): &(usize, usize)| {
        u64::from(
            occluders
                .visibility(&patches[i], &patches[j], DEFAULT_SAMPLES, pair_seed(i, j))
                .rays,
        )
    };
    let total: u64 = occludable.iter().map(cast).sum();
    println!(
        "Cornell box: {n} elements, {} of {} element pairs occludable, {total} rays per pass",
        occludable.len(),
        n * (n - 1) / 2
    );

    let mut group = c.benchmark_group("cornell_rays");
    group.sample_size(10);
    group.throughput(Throughput::Elements(total));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        group.bench_function(format!("{threads}_threads"), |b| {
            b.iter(|| pool.install(|| occludable.par_iter().map(cast).sum::<u64>()))
        });
    }
    group.finish();

    let mut group = c.benchmark_group("cornell_occludable");
    group.sample_size(10);
    group.throughput(Throughput::Elements((n * (n - 1) / 2) as u64));
    group.bench_function("all_pairs_1_thread", |b| {
        b.iter(|| {
            (0..n)
                .map(|i| {
                    (i + 1..n)
                        .filter(|&j| pairs.can_occlude(&occluders, &patches[i], &patches[j]))
                        .count()
                })
                .sum::<usize>()
        })
    });
    group.finish();
}

criterion_group!(benches, rays);
criterion_main!(benches);
