//! Form-factor throughput: element pairs per second for the dense matrix of the paper's cube
//! at several subdivisions (all pairs, each unordered pair integrated once, all cores), and
//! per estimator at one subdivision.
//! Run: `cargo bench -p bake-form-factor --bench pairs`.

use bake_form_factor::{ContourOptions, Estimator, FormFactors, TriangleRule};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use importer::{Origin, Polygon, Side};
use mesher::{mesh, Subdivision};

fn cube() -> Vec<Polygon> {
    reference::unit_cube_walls()
        .iter()
        .enumerate()
        .map(|(k, c)| Polygon {
            vertices: c.to_vec(),
            normal: (c[1] - c[0]).cross(c[2] - c[0]).normalize(),
            material: 0,
            origin: Origin {
                node: k,
                mesh: k,
                primitive: 0,
                face: 0,
                side: Side::Front,
            },
        })
        .collect()
}

fn dense(c: &mut Criterion) {
    let mut group = c.benchmark_group("cube_dense");
    group.sample_size(10);
    for n in [4u32, 7, 12] {
        let m = mesh(&cube(), Subdivision::Count(n)).expect("mesh");
        let elements = m.elements.len() as u64;
        group.throughput(Throughput::Elements(elements * (elements - 1) / 2));
        group.bench_function(format!("subdiv_{n}"), |b| {
            b.iter(|| FormFactors::new(&m, ContourOptions::default()).dense())
        });
    }
    group.finish();
}

/// Pairs per second of each estimator on the cube at 8 × 8 per wall (384 elements).
fn estimators(c: &mut Criterion) {
    let mut group = c.benchmark_group("cube_8_estimator");
    group.sample_size(10);
    let m = mesh(&cube(), Subdivision::Count(8)).expect("mesh");
    let elements = m.elements.len() as u64;
    group.throughput(Throughput::Elements(elements * (elements - 1) / 2));
    let mut estimators = vec![
        ("contour".to_string(), Estimator::Contour),
        ("point-point".to_string(), Estimator::PointPoint),
    ];
    for rule in TriangleRule::ALL {
        estimators.push((
            format!("point-polygon-{}", rule.points()),
            Estimator::PointPolygon(rule),
        ));
    }
    for tolerance in [1e-2, 1e-3, 1e-4, 1e-6] {
        estimators.push((format!("auto-{tolerance:e}"), Estimator::Auto { tolerance }));
    }
    for (name, estimator) in estimators {
        group.bench_function(name, |b| {
            b.iter(|| {
                FormFactors::new(&m, ContourOptions::default())
                    .with_estimator(estimator)
                    .dense()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, dense, estimators);
criterion_main!(benches);
