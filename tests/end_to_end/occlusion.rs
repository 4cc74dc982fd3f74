//! Hidden surfaces end to end: the cube casts no ray and keeps its exact form factors, the
//! Cornell box's blocks cast shadows without leaking light through their contact lines, the
//! unlit room of the two-room scene sees the light only through the doorway, and the result
//! does not depend on the thread count.

use crate::common;

use bake_job::report::{ElementEntry, Report};
use bake_testkit::fixture;
use common::{bake, report_without_timings};
use form_factor::{ContourOptions, FormFactors, Occlusion};
use mesher::{mesh, Subdivision};
use visibility::Occluders;

/// Bakes `input` with `args` and returns its report.
fn report(input: &str, args: &[&str]) -> Report {
    let dir = tempfile::tempdir().expect("tempdir");
    let (out, report) = (dir.path().join("out.glb"), dir.path().join("report.json"));
    let mut all: Vec<String> = vec![
        fixture(input).display().to_string(),
        out.display().to_string(),
    ];
    all.extend(
        [
            "--report",
            &report.display().to_string(),
            "--quiet",
            "--target",
            "vertex",
        ]
        .map(String::from),
    );
    all.extend(args.iter().map(|s| s.to_string()));
    bake(&all).success();
    report_without_timings(&report)
}

#[test]
fn the_cube_casts_no_ray_and_keeps_its_exact_form_factors() {
    let scene = importer::load(&fixture("cube.gltf")).expect("cube");
    let m = mesh(&scene.polygons, Subdivision::Count(5)).expect("mesh");
    let exact = FormFactors::new(&m, ContourOptions::default()).dense();
    let occluders = Occluders::new(&scene.polygons).expect("occluders");
    let pairs = occluders.occludable_pairs();
    assert!(pairs.is_empty() && !pairs.effects().occlusion);
    let occlusion = Occlusion {
        occluders: &occluders,
        pairs: &pairs,
        samples: 289,
    };
    let with = FormFactors::new(&m, ContourOptions::default())
        .with_occlusion(occlusion)
        .dense();
    assert_eq!(with.stats.visibility.rays_cast, 0);
    assert_eq!(with.stats.visibility.pairs_occludable, 0);
    assert_eq!(
        with.stats.visibility.pairs_tested,
        with.stats.pairs_integrated
    );
    // Bit for bit the same matrix, hence the same radiosities.
    assert!(exact
        .data
        .iter()
        .zip(&with.data)
        .all(|(a, b)| a.to_bits() == b.to_bits()));

    let r = report("cube.gltf", &["--subdiv", "5"]);
    assert_eq!((r.counts.rays_cast, r.counts.pairs_occludable), (0, 0));
    assert!(!r.effects.occlusion, "{}", r.effects.reason);
}

/// Is the floor point (x, z) inside the convex footprint `quad` (x, z corners, any winding)?
fn inside(quad: &[[f64; 2]; 4], x: f64, z: f64, margin: f64) -> bool {
    let sign = |k: usize| {
        let (a, b) = (quad[k], quad[(k + 1) % 4]);
        let (ex, ez) = (b[0] - a[0], b[1] - a[1]);
        ((x - a[0]) * ez - (z - a[1]) * ex) / (ex * ex + ez * ez).sqrt()
    };
    let d: Vec<f64> = (0..4).map(sign).collect();
    d.iter().all(|&v| v > margin) || d.iter().all(|&v| v < -margin)
}

const SHORT: [[f64; 2]; 4] = [[290.0, 114.0], [240.0, 272.0], [82.0, 225.0], [130.0, 65.0]];
const TALL: [[f64; 2]; 4] = [
    [423.0, 247.0],
    [472.0, 406.0],
    [314.0, 456.0],
    [265.0, 296.0],
];

fn floor(r: &Report) -> Vec<&ElementEntry> {
    r.elements
        .iter()
        .filter(|e| e.normal[1] > 0.999 && e.centroid[1].abs() < 1e-6)
        .collect()
}

#[test]
fn cornell_blocks_cast_shadows_without_leaking_through_their_contact_lines() {
    // Direct light only (K = 0): b = e + ρ · (light from the emitter).
    let r = report(
        "cornell.gltf",
        &["--max-element-size", "40", "--bounces", "0"],
    );
    assert!(r.effects.occlusion && r.counts.rays_cast > 0);
    let floor = floor(&r);
    let size = 40.0 * std::f64::consts::SQRT_2;
    let direct = |e: &ElementEntry| e.b[0];
    let under: Vec<_> = floor
        .iter()
        .filter(|e| {
            [SHORT, TALL]
                .iter()
                .any(|q| inside(q, e.centroid[0], e.centroid[2], size))
        })
        .collect();
    let open: Vec<_> = floor
        .iter()
        .filter(|e| {
            [SHORT, TALL]
                .iter()
                .all(|q| !inside(q, e.centroid[0], e.centroid[2], -2.0 * size))
        })
        .collect();
    assert!(!under.is_empty() && !open.is_empty());
    // Wholly under a block: no light at all.
    assert!(
        under.iter().all(|e| direct(e) == 0.0),
        "light under a block"
    );
    let open_mean = open.iter().map(|e| direct(e)).sum::<f64>() / open.len() as f64;
    let open_min = open.iter().map(|e| direct(e)).fold(f64::MAX, f64::min);
    eprintln!("floor direct light: open mean {open_mean:.4}, open min {open_min:.4}, {} elements under blocks", under.len());
    // Elements straddling a footprint edge (centroid inside, within one element of the edge)
    // are no brighter than the open floor just outside them (5% for sampling noise).
    for q in [SHORT, TALL] {
        for e in floor
            .iter()
            .filter(|e| inside(&q, e.centroid[0], e.centroid[2], 0.0))
        {
            let near_outside = floor.iter().filter(|o| {
                !inside(&q, o.centroid[0], o.centroid[2], 0.0)
                    && (o.centroid[0] - e.centroid[0]).hypot(o.centroid[2] - e.centroid[2])
                        < 1.6 * size
            });
            let brightest = near_outside.map(|o| direct(o)).fold(0.0, f64::max);
            assert!(
                direct(e) <= brightest * 1.05 + 1e-12,
                "leak at {:?}: {} > {}",
                e.centroid,
                direct(e),
                brightest
            );
        }
    }
}

#[test]
fn the_unlit_room_sees_the_light_only_through_the_doorway() {
    // Room A: x < 3.9, lit; partition 3.9..4.1 with a door (z 1.5..2.5, y < 2); room B: x > 4.1.
    let direct = report(
        "two-rooms.gltf",
        &["--max-element-size", "0.4", "--bounces", "0"],
    );
    let full = report("two-rooms.gltf", &["--max-element-size", "0.4"]);
    let in_b = |e: &&ElementEntry| e.centroid[0] > 4.1 + 1e-6;
    let partition_b = |e: &&ElementEntry| (e.centroid[0] - 4.1).abs() < 1e-6 && e.normal[0] > 0.999;
    let ceiling_b = |e: &&ElementEntry| in_b(e) && e.normal[1] < -0.999;
    let floor_b = |e: &&ElementEntry| in_b(e) && e.normal[1] > 0.999;
    // The light is in A's ceiling, above the door's top: B's ceiling and the partition's face
    // in B are out of its sight. They get no direct light at all, only bounced light.
    for (name, pick) in [
        (
            "partition face in B",
            &partition_b as &dyn Fn(&&ElementEntry) -> bool,
        ),
        ("ceiling of B", &ceiling_b),
    ] {
        let d: Vec<_> = direct.elements.iter().filter(|e| pick(e)).collect();
        let f: Vec<_> = full.elements.iter().filter(|e| pick(e)).collect();
        assert!(!d.is_empty(), "{name}");
        assert!(d.iter().all(|e| e.b == [0.0; 3]), "{name} is lit directly");
        assert!(
            f.iter().all(|e| e.b.iter().all(|&v| v > 0.0)),
            "{name} gets no bounced light"
        );
    }
    // Some of B's floor sees the light through the doorway.
    let lit = direct
        .elements
        .iter()
        .filter(floor_b)
        .filter(|e| e.b[0] > 0.0)
        .count();
    let dark = direct
        .elements
        .iter()
        .filter(floor_b)
        .filter(|e| e.b[0] == 0.0)
        .count();
    eprintln!("room B floor: {lit} elements lit through the door, {dark} out of its sight");
    assert!(lit > 0 && dark > 0);
}

#[test]
fn occluded_bakes_are_bit_identical_with_one_and_two_threads() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}.glb"));
        let rep = dir.path().join(format!("t{threads}.json"));
        let args = [
            fixture("cornell.gltf").display().to_string(),
            out.display().to_string(),
            "--report".into(),
            rep.display().to_string(),
            "--max-element-size".into(),
            "80".into(),
            "--threads".into(),
            threads.into(),
            "--target".into(),
            "vertex".into(),
            "--quiet".into(),
        ];
        bake(&args).success();
        let mut report = report_without_timings(&rep);
        report.options["output"] = serde_json::Value::Null;
        outputs.push((std::fs::read(&out).expect("output"), report));
    }
    assert!(outputs[0].1.counts.rays_cast > 0);
    assert!(
        outputs[0].0 == outputs[1].0,
        "output bytes differ between 1 and 2 threads"
    );
    assert_eq!(outputs[0].1, outputs[1].1);
}
