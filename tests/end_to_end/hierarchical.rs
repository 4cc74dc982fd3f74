//! The hierarchical transport against the dense one on the same mesh, and the invariants every
//! bake keeps (energy balance, determinism across thread counts, no NaN, clean refusals).
//!
//! The sizes here are coarser than the acceptance sizes (Cornell at 27 mm, two rooms
//! at 0.2 m) so the dense references stay quick in a test build; the `#[ignore]`d
//! `*_at_acceptance_size` tests run those (`cargo test --release -- --ignored`).

use crate::common;

use bake_core::{Bake, Request, Settings, TransportKind};
use bake_testkit::fixture;
use common::bake;
use mesher::Subdivision;

fn run(name: &str, size: f64, transport: TransportKind, link_tolerance: Option<f64>) -> Bake {
    let scene = importer::load(&fixture(name)).expect("load the fixture");
    let request = Request {
        subdivision: Some(Subdivision::MaxSize(size)),
        transport,
        link_tolerance,
        irradiance: true,
        // The uniform mesh this test is about.
        refine: Some(false),
        ..Request::default()
    };
    let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
    bake_core::run(&scene, &settings, &bake_core::Silent).expect("bake")
}

/// Area-weighted RMS of the difference relative to the dense solution, and the largest
/// per-element difference relative to max(b_dense, the scene's mean b) (so that elements in
/// full shadow, b ≈ 0, are compared with the scene's light level rather than with 0).
fn differences(dense: &Bake, other: &Bake) -> (f64, f64) {
    let elements = &dense.mesh.elements;
    let area: f64 = elements.iter().map(|e| e.area).sum();
    let mean = elements
        .iter()
        .zip(&dense.solution.b)
        .map(|(e, b)| e.area * b.iter().sum::<f64>() / 3.0)
        .sum::<f64>()
        / area;
    let (mut num, mut den, mut worst) = (0.0, 0.0, 0.0f64);
    for ((e, d), h) in elements
        .iter()
        .zip(&dense.solution.b)
        .zip(&other.solution.b)
    {
        for c in 0..3 {
            num += e.area * (h[c] - d[c]).powi(2);
            den += e.area * d[c].powi(2);
            worst = worst.max((h[c] - d[c]).abs() / d[c].max(mean));
        }
    }
    ((num / den).sqrt(), worst)
}

fn compare(name: &str, size: f64) {
    let dense = run(name, size, TransportKind::Dense, None);
    let hierarchical = run(name, size, TransportKind::Hierarchical, Some(1e-3));
    assert_eq!(
        hierarchical.plan.transport().kind,
        TransportKind::Hierarchical
    );
    assert!(hierarchical.counts.links > 0);
    let (rms, worst) = differences(&dense, &hierarchical);
    println!(
        "{name} at {size}: {} elements, {} links, rms {rms:.4}, worst {worst:.4}",
        dense.mesh.elements.len(),
        hierarchical.counts.links
    );
    assert!(rms <= 0.01, "{name}: rms difference {rms}");
    assert!(worst <= 0.10, "{name}: worst element difference {worst}");
    // Reciprocal links conserve energy like the dense matrix does.
    for band in 0..3 {
        assert!(
            hierarchical.energy.imbalance[band] < 1e-5,
            "{name}: energy imbalance {:?}",
            hierarchical.energy.imbalance
        );
    }
    assert!(hierarchical
        .solution
        .b
        .iter()
        .chain(hierarchical.irradiance.iter().flatten())
        .all(|b| b.iter().all(|v| v.is_finite() && *v >= 0.0)));
}

#[test]
fn hierarchical_matches_dense_on_the_cornell_box() {
    compare("cornell.gltf", 60.0);
}

#[test]
fn hierarchical_matches_dense_on_the_two_rooms() {
    compare("two-rooms.gltf", 0.4);
}

#[test]
#[ignore = "dense reference of 4 243 elements: about 45 s in a release build"]
fn cornell_at_acceptance_size() {
    compare("cornell.gltf", 27.0);
}

#[test]
#[ignore = "dense reference of 3 656 elements: about 40 s in a release build"]
fn two_rooms_at_acceptance_size() {
    compare("two-rooms.gltf", 0.2);
}

/// Coarse links make the hierarchical answer less accurate, never unstable: a tighter link
/// tolerance gets closer to the dense answer.
#[test]
fn tighter_link_tolerance_converges_to_dense() {
    let dense = run("cornell.gltf", 60.0, TransportKind::Dense, None);
    let mut previous = f64::INFINITY;
    for t in [3e-2, 1e-2, 1e-3] {
        let h = run("cornell.gltf", 60.0, TransportKind::Hierarchical, Some(t));
        let (rms, _) = differences(&dense, &h);
        assert!(rms < previous, "link tolerance {t}: rms {rms} ≥ {previous}");
        previous = rms;
    }
}

#[test]
fn hierarchical_bakes_are_bit_identical_with_one_and_two_threads() {
    let bake_with = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(|| run("cornell.gltf", 60.0, TransportKind::Hierarchical, None))
    };
    let (one, two) = (bake_with(1), bake_with(2));
    assert_eq!(one.counts, two.counts);
    let bits = |b: &Bake| -> Vec<u64> {
        b.solution
            .b
            .iter()
            .flat_map(|v| v.iter().map(|x| x.to_bits()))
            .collect()
    };
    assert_eq!(bits(&one), bits(&two));
}

#[test]
fn auto_picks_the_transport_by_cost_and_says_why() {
    // A tiny convex scene (nothing can occlude), not refined: dense, exact and affordable.
    let tiny = run("cube.gltf", 0.25, TransportKind::Auto, None);
    assert_eq!(tiny.plan.transport().kind, TransportKind::Dense);
    let reason = &tiny.plan.transport().reason;
    assert!(reason.contains("estimated cost"), "{reason}");
    assert!(reason.contains("exact"), "{reason}");
    // The same cube refined by default: the dense transport's pairs at its 2 000-element
    // budget cost more than the hierarchy's links at its 4 000, which then refines further.
    let small = {
        let scene = importer::load(&fixture("cube.gltf")).expect("load the fixture");
        let request = Request {
            subdivision: Some(Subdivision::MaxSize(0.1)),
            ..Request::default()
        };
        let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
        bake_core::run(&scene, &settings, &bake_core::Silent).expect("bake")
    };
    let choice = small.plan.transport();
    assert_eq!(
        choice.kind,
        TransportKind::Hierarchical,
        "{}",
        choice.reason
    );
    assert!(choice.reason.contains("(refined)"), "{}", choice.reason);
    assert!(small.plan.refines_by_default());
    assert!(small.mesh.elements.len() > bake_core::DENSE_CROSSOVER);
    // A small scene with occluders: the dense transport's rays per element pair would cost
    // more than the hierarchy's per link, which then refines by default, further.
    let occluded = run("cornell.gltf", 60.0, TransportKind::Auto, None);
    let choice = occluded.plan.transport();
    assert_eq!(choice.kind, TransportKind::Hierarchical);
    assert!(choice.reason.contains("come between"), "{}", choice.reason);
    assert!(occluded.plan.refines_by_default());
    // Refinement off, the cube's 600 elements: the dense transport's 0.17 s against the
    // hierarchy's 0.03 s.
    let uniform = run("cube.gltf", 0.1, TransportKind::Auto, None);
    assert_eq!(uniform.plan.transport().kind, TransportKind::Hierarchical);
    assert_eq!(
        occluded.plan.element_budget(occluded.mesh.elements.len()),
        bake_core::OCCLUDED_MAX_ELEMENTS
    );
    let large = run("cornell.gltf", 25.0, TransportKind::Auto, None);
    assert!(large.mesh.elements.len() > bake_core::DENSE_CROSSOVER);
    assert_eq!(large.plan.transport().kind, TransportKind::Hierarchical);
}

#[test]
fn the_cli_reports_the_transport_and_refuses_direct_with_hierarchical() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("out.glb");
    let report = dir.path().join("r.json");
    let input = fixture("two-rooms.gltf");
    bake([
        input.as_os_str(),
        out.as_os_str(),
        "--transport".as_ref(),
        "hierarchical".as_ref(),
        "--max-element-size".as_ref(),
        "0.5".as_ref(),
        "--report".as_ref(),
        report.as_os_str(),
        "--quiet".as_ref(),
    ])
    .success();
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).expect("report")).expect("json");
    assert_eq!(r["transport"]["kind"], "hierarchical");
    assert_eq!(r["options"]["transport"], "hierarchical");
    assert_eq!(r["options"]["solver"], "iterative");
    assert!(r["counts"]["links"].as_u64().unwrap_or(0) > 0);
    assert!(
        r["counts"]["nodes"].as_u64().unwrap_or(0) > r["counts"]["elements"].as_u64().unwrap_or(0)
    );
    let refused = bake([
        input.as_os_str(),
        dir.path().join("x.glb").as_os_str(),
        "--transport".as_ref(),
        "hierarchical".as_ref(),
        "--solver".as_ref(),
        "direct".as_ref(),
    ]);
    assert_eq!(refused.code, Some(1), "{refused:?}");
    assert!(refused
        .stderr
        .contains("--solver direct needs the dense transport"));
    assert!(!dir.path().join("x.glb").exists());
}

#[test]
#[ignore = "measurement table: dense vs hierarchical at the acceptance sizes (minutes, release)"]
fn acceptance_table() {
    // BAKE_QUICK: coarser meshes (seconds instead of minutes).
    let scenes = if std::env::var_os("BAKE_QUICK").is_some() {
        [("cornell.gltf", 60.0), ("two-rooms.gltf", 0.4)]
    } else {
        [("cornell.gltf", 27.0), ("two-rooms.gltf", 0.2)]
    };
    for (name, size) in scenes {
        let start = std::time::Instant::now();
        let dense = run(name, size, TransportKind::Dense, None);
        println!("{name}: dense {:.2} s", start.elapsed().as_secs_f64());
        for t in [1e-2, 3e-3, 1e-3] {
            let start = std::time::Instant::now();
            let h = run(name, size, TransportKind::Hierarchical, Some(t));
            let s = start.elapsed().as_secs_f64();
            let (rms, worst) = differences(&dense, &h);
            let mut rows: Vec<(f64, usize)> = dense
                .solution
                .b
                .iter()
                .zip(&h.solution.b)
                .enumerate()
                .map(|(k, (d, x))| ((x[0] - d[0]).abs() / d[0].max(0.05), k))
                .collect();
            rows.sort_by(|a, b| b.0.total_cmp(&a.0));
            for &(r, k) in rows.iter().take(3) {
                let el = &dense.mesh.elements[k];
                println!(
                    "  worst {r:.3}: element {k} polygon {} area {:.4} centroid {:?} dense {:.4} h {:.4}",
                    el.polygon, el.area, el.centroid, dense.solution.b[k][0], h.solution.b[k][0]
                );
            }
            println!(
                "{name} {t}: {s:.2} s, {} links, {} rays, rms {rms:.4}, worst {worst:.4}",
                h.counts.links, h.counts.rays_cast
            );
        }
    }
}

const BANDS_U64: u64 = 3;

/// Records what a bake tells its progress bar: (stage, total, steps advanced).
#[derive(Default)]
struct Recorder(std::sync::Mutex<Vec<(String, u64, u64)>>);

impl bake_core::Progress for Recorder {
    fn start(&self, stage: &str, total: u64) {
        if let Ok(mut v) = self.0.lock() {
            v.push((stage.to_string(), total, 0));
        }
    }
    fn advance(&self, steps: u64) {
        if let Ok(mut v) = self.0.lock() {
            if let Some(last) = v.last_mut() {
                last.2 += steps;
            }
        }
    }
    fn finish(&self) {}
}

/// Every long phase of a hierarchical bake shows progress: the first linking pass by
/// polygon, each refinement pass by kept link (each to its end), and the solve by operator
/// application (open-ended: as many as GMRES made).
#[test]
fn every_phase_of_a_hierarchical_bake_reports_progress() {
    let scene = importer::load(&fixture("two-rooms.gltf")).expect("load the fixture");
    let request = Request {
        subdivision: Some(Subdivision::MaxSize(0.4)),
        transport: TransportKind::Hierarchical,
        link_tolerance: Some(1e-3),
        // The uniform mesh this test is about.
        refine: Some(false),
        ..Request::default()
    };
    let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
    let recorder = Recorder::default();
    let baked = bake_core::run(&scene, &settings, &recorder).expect("bake");
    let stages = recorder.0.into_inner().expect("the record");
    let names: Vec<&str> = stages.iter().map(|s| s.0.as_str()).collect();
    let first = stages
        .iter()
        .find(|s| s.0 == "links")
        .unwrap_or_else(|| panic!("no links stage in {names:?}"));
    assert_eq!(first.1, scene.polygons.len() as u64);
    assert_eq!(first.2, first.1, "the first pass ends at its total");
    let passes: Vec<_> = stages
        .iter()
        .filter(|s| s.0.starts_with("links pass"))
        .collect();
    assert_eq!(
        passes.len() as u32 + 1,
        baked.counts.refinement_passes,
        "{names:?}"
    );
    for (k, pass) in passes.iter().enumerate() {
        assert_eq!(pass.0, format!("links pass {}", k + 2));
        assert!(pass.1 > 0 && pass.2 == pass.1, "{pass:?}");
    }
    let solve = stages
        .iter()
        .find(|s| s.0 == "solve")
        .expect("a solve stage");
    assert_eq!(solve.1, 0, "open-ended");
    let iterations: u32 = baked.solution.iterations.iter().sum();
    assert!(
        solve.2 >= u64::from(iterations) / BANDS_U64 && solve.2 > 0,
        "{solve:?} for {iterations} iterations"
    );
}

/// A scene where nothing emits (and no light shines) has b = 0 exactly: no transport is
/// built, on either path, and the bake says why.
#[test]
fn a_scene_without_light_builds_no_transport() {
    let mut scene = importer::load(&fixture("two-rooms.gltf")).expect("load the fixture");
    for m in &mut scene.materials {
        m.emission = [0.0; 3];
    }
    for transport in [TransportKind::Dense, TransportKind::Hierarchical] {
        let request = Request {
            subdivision: Some(Subdivision::MaxSize(0.4)),
            transport,
            irradiance: true,
            // The uniform mesh this test is about.
            refine: Some(false),
            ..Request::default()
        };
        let settings = Settings::resolve(&request, &scene.polygons).expect("settings");
        let baked = bake_core::run(&scene, &settings, &bake_core::Silent).expect("bake");
        assert!(baked.solution.b.iter().all(|b| *b == [0.0; 3]));
        assert!(baked.irradiance.iter().flatten().all(|h| *h == [0.0; 3]));
        assert_eq!(baked.counts.links, 0);
        assert_eq!(baked.counts.pairs_evaluated, 0);
        assert_eq!(baked.counts.rays_cast, 0);
        assert!(
            baked.plan.transport().reason.contains("not built"),
            "{}",
            baked.plan.transport().reason
        );
        assert_eq!(baked.energy.imbalance, [0.0; 3]);
        assert!(baked
            .warnings
            .iter()
            .any(|w| w.contains("no emitters and no lights")));
    }
}

/// How well a hierarchical bake's per-element error estimate bounds its difference from the
/// dense solve of the same mesh (issue 31: ≥ 90% of element-bands bounded, median
/// true/estimate ≥ 0.1). Per estimate (the total, and the part the transports differ in: all
/// but discretisation, which both share): the share of element-bands with |h − d| ≤ estimate
/// and the median of |h − d| / estimate.
fn estimate_against_dense(dense: &Bake, h: &Bake) -> Vec<(&'static str, f64, f64)> {
    type Part = fn(&bake_core::error::Parts, usize) -> f64;
    let parts: [(&'static str, Part); 4] = [
        ("total", |p, c| p.total()[c]),
        ("transport", |p, c| {
            (p.form_factors[c].powi(2)
                + p.visibility[c].powi(2)
                + p.solver[c].powi(2)
                + p.links[c].powi(2))
            .sqrt()
        }),
        ("links", |p, c| p.links[c]),
        ("visibility", |p, c| p.visibility[c]),
    ];
    parts
        .iter()
        .map(|&(name, part)| {
            let (mut bounded, mut ratios) = (0usize, Vec::new());
            for ((d, x), p) in dense.solution.b.iter().zip(&h.solution.b).zip(&h.error) {
                for c in 0..3 {
                    let (truth, estimate) = ((x[c] - d[c]).abs(), part(p, c));
                    bounded += usize::from(truth <= estimate);
                    if estimate > 0.0 {
                        ratios.push(truth / estimate);
                    }
                }
            }
            ratios.sort_by(f64::total_cmp);
            let median = ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN);
            (name, bounded as f64 / (3 * h.error.len()) as f64, median)
        })
        .collect()
}

/// The hierarchical bake's error estimate covers its difference from the dense solve of the
/// same mesh (issue 31): the part the transports differ in (all but discretisation, which both
/// share) bounds ≥ 90% of element-bands and is informative, median difference / estimate ≥
/// 0.1 (measured 98.7% and 0.109 here; at 27 mm, 4 243 elements, 98.6% and 0.108, and on the
/// two rooms 94.9% and 0.213: `error_estimate_against_dense_table`); the whole estimate
/// bounds ≥ 90% too.
#[test]
fn the_error_estimate_covers_the_difference_from_dense() {
    let dense = run("cornell.gltf", 60.0, TransportKind::Dense, None);
    let h = run("cornell.gltf", 60.0, TransportKind::Hierarchical, None);
    let table = estimate_against_dense(&dense, &h);
    println!("{table:?}");
    let row = |name: &str| table.iter().find(|r| r.0 == name).copied().expect("row");
    let (_, bounded, _) = row("total");
    assert!(bounded >= 0.9, "total bounds {bounded}");
    let (_, bounded, median) = row("transport");
    assert!(bounded >= 0.9, "the transport part bounds {bounded}");
    assert!(
        median >= 0.1,
        "transport part: median difference / estimate {median}"
    );
}

#[test]
#[ignore = "measurement: dense references of ~4 000 elements (minutes, release)"]
fn error_estimate_against_dense_table() {
    // BAKE_QUICK: coarser meshes (seconds instead of minutes).
    let scenes = if std::env::var_os("BAKE_QUICK").is_some() {
        [("cornell.gltf", 60.0), ("two-rooms.gltf", 0.4)]
    } else {
        [("cornell.gltf", 27.0), ("two-rooms.gltf", 0.2)]
    };
    for (name, size) in scenes {
        let dense = run(name, size, TransportKind::Dense, None);
        let h = run(name, size, TransportKind::Hierarchical, None);
        let (rms, worst) = differences(&dense, &h);
        println!(
            "{name} at {size}: {} elements, rms {rms:.4}, worst {worst:.4}, condition {:?}, rho max {}",
            h.mesh.elements.len(),
            h.solution.condition,
            h.accuracy.rho_max
        );
        for (part, bounded, median) in estimate_against_dense(&dense, &h) {
            println!("  {part:>22}: bounded {bounded:.3}, median true/estimate {median:.3}");
        }
    }
}
