//! End-to-end physics of `bake`: the furnace identity, colour bleeding, the bounce series,
//! direct light against closed-form form factors, and format independence. Each test runs the
//! real binary on real files and reads its JSON report.

use bake_job::report::{read_report, ElementEntry, Report};
use bake_testkit::fixture;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `bake input out.glb --report r.json --ff-estimator contour args...` and returns the
/// report. These tests check the physics to ~1e-10, so they use the exact form factors (the
/// default `auto` estimator keeps each pair within its 1e-3 tolerance; see tests/end_to_end/quality.rs).
fn bake(input: &Path, args: &[&str]) -> Report {
    let dir = tempfile::tempdir().expect("tempdir");
    let (out, report) = (dir.path().join("out.glb"), dir.path().join("report.json"));
    let result = Command::new(env!("CARGO_BIN_EXE_bake"))
        .arg(input)
        .arg(&out)
        .arg("--report")
        .arg(&report)
        .arg("--quiet")
        .args(["--ff-estimator", "contour"])
        // The uniform mesh: these tests compare solves element by element and check symmetry.
        .args(["--refine", "off"])
        .args(args)
        .output()
        .expect("run bake");
    assert!(
        result.status.success(),
        "bake failed: {}",
        String::from_utf8_lossy(&result.stderr)
    );
    read_report(&report).expect("report")
}

/// The element of `report` whose centroid is nearest `p` (and whose normal is `n`).
fn element_at(report: &Report, p: [f64; 3], n: [f64; 3]) -> &ElementEntry {
    report
        .elements
        .iter()
        .filter(|e| (0..3).all(|k| (e.normal[k] - n[k]).abs() < 1e-9))
        .min_by(|a, b| dist(a.centroid, p).total_cmp(&dist(b.centroid, p)))
        .expect("an element with that normal")
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// One box wall: corner, edge a, edge b (a × b points inward), cuts along a (fractions).
type Strips = ([f64; 3], [f64; 3], [f64; 3], &'static [f64]);

/// A closed box [0,X]×[0,Y]×[0,Z], walls facing inward, each wall cut into unequal strips,
/// every face with the given Kd and Ke, as OBJ + MTL.
fn write_box_obj(dir: &Path, size: [f64; 3], rho: f64, e: f64) -> PathBuf {
    let [x, y, z] = size;
    // (corner, a, b) with a × b pointing into the box; strips cut along a at these fractions.
    let faces: [Strips; 6] = [
        ([0., 0., 0.], [0., 0., z], [x, 0., 0.], &[0.0, 0.3, 1.0]),
        ([0., y, 0.], [x, 0., 0.], [0., 0., z], &[0.0, 1.0]),
        (
            [0., 0., 0.],
            [0., y, 0.],
            [0., 0., z],
            &[0.0, 0.2, 0.7, 1.0],
        ),
        ([x, 0., 0.], [0., 0., z], [0., y, 0.], &[0.0, 0.55, 1.0]),
        ([0., 0., 0.], [x, 0., 0.], [0., y, 0.], &[0.0, 1.0]),
        ([0., 0., z], [0., y, 0.], [x, 0., 0.], &[0.0, 0.4, 1.0]),
    ];
    let mut obj = String::from("mtllib box.mtl\no box\nusemtl wall\n");
    let mut count = 0;
    for (c, a, b, cuts) in faces {
        for w in cuts.windows(2) {
            let at = |s: f64, t: f64| [0, 1, 2].map(|k| c[k] + a[k] * s + b[k] * t);
            for p in [at(w[0], 0.0), at(w[1], 0.0), at(w[1], 1.0), at(w[0], 1.0)] {
                obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
            }
            obj += &format!(
                "f {} {} {} {}\n",
                count + 1,
                count + 2,
                count + 3,
                count + 4
            );
            count += 4;
        }
    }
    std::fs::write(dir.join("box.obj"), obj).expect("write obj");
    let mtl = format!("newmtl wall\nKd {rho} {rho} {rho}\nKe {e} {e} {e}\n");
    std::fs::write(dir.join("box.mtl"), mtl).expect("write mtl");
    dir.join("box.obj")
}

#[test]
fn furnace_box_with_unequal_elements_gives_e_over_one_minus_rho() {
    // b = e + ρ Σ_j F_ij b_j with Σ_j F_ij = 1 everywhere: b = e / (1 − ρ) = 10.
    let dir = tempfile::tempdir().expect("tempdir");
    let input = write_box_obj(dir.path(), [1.0, 0.5, 2.0], 0.9, 1.0);
    let report = bake(&input, &["--max-element-size", "0.17"]);
    let areas: Vec<f64> = report.elements.iter().map(|e| e.area).collect();
    let (lo, hi) = (
        areas.iter().cloned().fold(f64::MAX, f64::min),
        areas.iter().cloned().fold(0.0, f64::max),
    );
    assert!(hi / lo > 1.5, "element areas should differ: {lo} .. {hi}");
    // OBJ/MTL values arrive as f64 (tobj's `use_f64`): ρ = 0.9 exactly as written.
    let rho = 0.9;
    assert!(report
        .elements
        .iter()
        .all(|e| e.rho == [rho; 3] && e.e == [1.0; 3]));
    let expect = 1.0 / (1.0 - rho);
    let worst = report
        .elements
        .iter()
        .flat_map(|e| e.b)
        .map(|b| (b - expect).abs() / expect)
        .fold(0.0, f64::max);
    eprintln!(
        "furnace: {} elements, max relative error {worst:.2e}",
        report.elements.len()
    );
    // The issue asks for 1e-5; the form factors' row sums (~1e-10) allow far less.
    assert!(worst < 1e-8, "{worst}");
}

#[test]
fn red_and_blue_walls_bleed_onto_the_floor() {
    let report = bake(&fixture("cube.gltf"), &["--subdiv", "7"]);
    let up = [0.0, 1.0, 0.0];
    // Floor (y = 0) elements in the middle row, next to the red (x = 0) and blue (x = 1) walls.
    let by_red = element_at(&report, [0.5 / 7.0, 0.0, 3.5 / 7.0], up);
    let by_blue = element_at(&report, [6.5 / 7.0, 0.0, 3.5 / 7.0], up);
    assert!(by_red.b[0] > by_red.b[2], "{:?}", by_red.b);
    assert!(by_blue.b[2] > by_blue.b[0], "{:?}", by_blue.b);
    // Mirror-symmetric scene: the two bleeds mirror each other (to quadrature accuracy).
    let asymmetry = (by_red.b[0] - by_blue.b[2])
        .abs()
        .max((by_red.b[2] - by_blue.b[0]).abs());
    eprintln!(
        "floor by red wall {:?}, by blue wall {:?}, asymmetry {asymmetry:.1e}",
        by_red.b, by_blue.b
    );
    assert!(asymmetry < 1e-9);
}

#[test]
fn direct_light_matches_closed_form_form_factors() {
    // One element per wall, K = 0: b = e + ρ F_{i,emitter} e (the paper's Figure 7a).
    let report = bake(&fixture("cube.gltf"), &["--subdiv", "1", "--bounces", "0"]);
    // glTF stores factors as f32: ρ = 0.6 arrives as 0.6f32.
    let grey = 0.6f32 as f64;
    let opposed = 0.199_824_895_698_387_46; // unit squares 1 apart (Howell C-11)
    let adjacent = 0.200_043_776_075_403_16; // unit squares sharing an edge (Howell C-14)
    let check = |p: [f64; 3], n: [f64; 3], expect: [f64; 3]| {
        let b = element_at(&report, p, n).b;
        for k in 0..3 {
            assert!(
                (b[k] - expect[k]).abs() < 1e-10,
                "{p:?}: {b:?} vs {expect:?}"
            );
        }
    };
    check([0.5, 0.5, 0.0], [0.0, 0.0, 1.0], [grey * opposed; 3]);
    check([0.5, 0.0, 0.5], [0.0, 1.0, 0.0], [grey * adjacent; 3]);
    check(
        [0.0, 0.5, 0.5],
        [1.0, 0.0, 0.0],
        [0.75 * adjacent, 0.25 * adjacent, 0.25 * adjacent],
    );
    check([0.5, 0.5, 1.0], [0.0, 0.0, -1.0], [1.0; 3]);
}

#[test]
fn bounces_converge_to_the_direct_solve() {
    let args = |k: &str| {
        vec!["--subdiv", "3", "--bounces", k]
            .into_iter()
            .map(String::from)
            .collect::<Vec<_>>()
    };
    let exact = bake(&fixture("cube.gltf"), &["--subdiv", "3"]);
    let mut previous = f64::INFINITY;
    for k in ["0", "1", "2", "4", "8", "16", "32", "64"] {
        let a = args(k);
        let r = bake(
            &fixture("cube.gltf"),
            &a.iter().map(String::as_str).collect::<Vec<_>>(),
        );
        let err = r
            .elements
            .iter()
            .zip(&exact.elements)
            .flat_map(|(a, b)| (0..3).map(move |c| (a.b[c] - b.b[c]).abs()))
            .fold(0.0, f64::max);
        eprintln!("K = {k}: max |b_K − b| = {err:.3e}");
        assert!(err < previous, "error must shrink with K");
        // Truncation only removes light: every partial sum is below the full solution.
        assert!(r
            .elements
            .iter()
            .zip(&exact.elements)
            .all(|(a, b)| (0..3).all(|c| a.b[c] <= b.b[c] + 1e-15)));
        previous = err;
    }
    assert!(previous < 1e-8, "{previous}");
}

#[test]
fn every_input_format_gives_the_same_radiosities() {
    let reference = bake(&fixture("cube.gltf"), &["--subdiv", "4"]);
    for name in ["cube.glb", "cube-embedded.gltf", "cube.obj"] {
        let other = bake(&fixture(name), &["--subdiv", "4"]);
        assert_eq!(other.elements.len(), reference.elements.len(), "{name}");
        for e in &reference.elements {
            let o = element_at(&other, e.centroid, e.normal);
            assert!(
                dist(o.centroid, e.centroid) < 1e-9,
                "{name}: no element at {:?}",
                e.centroid
            );
            for c in 0..3 {
                // glTF stores ρ and e as f32; OBJ/MTL text is read as f64, so the OBJ's
                // materials differ from the glTF's by f32 rounding (~3e-8 relative).
                let tolerance = if name.ends_with(".obj") {
                    2e-7 * e.b[c].abs().max(1e-3)
                } else {
                    1e-9
                };
                assert!(
                    (o.b[c] - e.b[c]).abs() < tolerance,
                    "{name}: {:?} vs {:?}",
                    o.b,
                    e.b
                );
            }
        }
    }
}
