//! The same input gives the same bits whatever the thread count: the BVH is built, the polygon
//! pairs classified and every element pair's visibility estimated inside a 1-thread and a
//! 2-thread pool.

mod common;

use bake_visibility::{Counters, Occluders, DEFAULT_SAMPLES};
use mesher::{mesh, Subdivision};
use rayon::prelude::*;

#[test]
fn visibility_is_bit_identical_with_1_and_2_threads() {
    let (polygons, _) = common::cornell();
    let m = mesh(&polygons, Subdivision::MaxSize(150.0)).unwrap();
    let n = m.elements.len();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let occluders = Occluders::new(&polygons).unwrap();
            let pairs = occluders.occludable_pairs();
            let rows: Vec<Vec<(u64, u32)>> = (0..n)
                .into_par_iter()
                .map(|i| {
                    (0..n)
                        .map(|j| {
                            let v = occluders.element_pair(&pairs, &m, i, j, DEFAULT_SAMPLES);
                            (v.fraction.to_bits(), v.rays)
                        })
                        .collect()
                })
                .collect();
            (pairs, rows)
        })
    };
    let (pairs1, rows1) = run(1);
    let (pairs2, rows2) = run(2);
    assert_eq!(pairs1, pairs2);
    assert_eq!(rows1, rows2);
    // Symmetric: (i, j) and (j, i) are the same estimate.
    let mut counters = Counters::default();
    for (i, row) in rows1.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            assert_eq!(*v, rows1[j][i]);
        }
    }
    let occluders = Occluders::new(&polygons).unwrap();
    let pairs = occluders.occludable_pairs();
    for i in 0..n {
        for j in i + 1..n {
            counters.add(&occluders.element_pair(&pairs, &m, i, j, DEFAULT_SAMPLES));
        }
    }
    assert!(counters.rays_cast > 0 && counters.pairs_occludable < counters.pairs_tested);
    let partial = rows1
        .iter()
        .flatten()
        .filter(|(f, _)| f64::from_bits(*f) > 0.0 && f64::from_bits(*f) < 1.0)
        .count();
    assert!(partial > 100, "{partial}");
}
