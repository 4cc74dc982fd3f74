//! Compressed and quantised input end to end (issue 29): `bake` bakes a Draco copy and a
//! gltfpack meshopt + quantised copy of the Cornell box to exit 0, with element radiosities
//! that match the uncompressed bake within what the quantisation moves, and writes
//! uncompressed outputs that name none of the compression extensions (and that the Khronos
//! validator passes, where it is installed).

use crate::common;

#[path = "../../crates/importer/tests/draco_writer/mod.rs"]
mod draco_writer;

use bake_job::report::{read_report, Report};
use bake_testkit::{fixture, skip, validate_clean};
use common::bake;
use std::path::Path;
use std::process::Command;

const ARGS: [&str; 6] = [
    "--max-element-size",
    "80",
    "--target",
    "vertex",
    "--quiet",
    "--report",
];

/// Bakes `input` into `dir/<stem>.gltf` and returns the report and the output's JSON text.
fn bake_report(input: &Path, dir: &Path, stem: &str) -> (Report, String) {
    let out = dir.join(format!("{stem}.gltf"));
    let report = dir.join(format!("{stem}.json"));
    let mut args = vec![input.display().to_string(), out.display().to_string()];
    args.extend(ARGS.iter().map(|s| s.to_string()));
    args.push(report.display().to_string());
    bake(&args).success();
    let text = std::fs::read_to_string(&out).expect("the output glTF");
    // The Khronos validator, where installed: 0 errors, 0 warnings.
    validate_clean(&[out]);
    (read_report(&report).expect("the report"), text)
}

/// Matches every element of `b` to the element of `a` with the nearest centroid and the
/// same normal; asserts the centroids within `tol` and returns the largest radiosity
/// difference relative to the largest radiosity of `a`.
fn radiosity_deviation(a: &Report, b: &Report, tol: f64) -> f64 {
    assert_eq!(a.elements.len(), b.elements.len(), "element counts differ");
    let peak = a.elements.iter().flat_map(|e| e.b).fold(0.0f64, f64::max);
    assert!(peak > 0.0);
    let distance = |x: [f64; 3], y: [f64; 3]| {
        ((x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)).sqrt()
    };
    let mut worst: f64 = 0.0;
    for e in &b.elements {
        let m = a
            .elements
            .iter()
            .filter(|f| distance(f.normal, e.normal) < 1e-3)
            .min_by(|f, g| {
                distance(f.centroid, e.centroid).total_cmp(&distance(g.centroid, e.centroid))
            })
            .expect("an element with the same normal");
        let d = distance(m.centroid, e.centroid);
        assert!(
            d <= tol,
            "element at {:?} is {d} from its match",
            e.centroid
        );
        for k in 0..3 {
            worst = worst.max((m.b[k] - e.b[k]).abs() / peak);
        }
    }
    worst
}

fn assert_plain(output: &str) {
    for name in [
        "KHR_draco_mesh_compression",
        "EXT_meshopt_compression",
        "KHR_mesh_quantization",
    ] {
        assert!(!output.contains(name), "the output still names {name}");
    }
}

#[test]
fn draco_cornell_bakes_like_the_uncompressed_one() {
    let dir = tempfile::tempdir().unwrap();
    let (plain, _) = bake_report(&fixture("cornell.gltf"), dir.path(), "plain");
    let draco_dir = dir.path().join("draco");
    std::fs::create_dir(&draco_dir).unwrap();
    // Blender's default: 14-bit positions, edgebreaker (speed 5).
    let input = draco_writer::write_draco(&fixture("cornell.gltf"), &draco_dir, 14, 5);
    let (draco, output) = bake_report(&input, dir.path(), "draco");
    assert_plain(&output);
    // A 14-bit step over the 559-unit box is 0.034: centroids move by less.
    let worst = radiosity_deviation(&plain, &draco, 0.034);
    eprintln!("Draco: largest radiosity difference {worst:.2e} of the peak");
    assert!(worst < 1e-3, "{worst}");
}

#[test]
fn meshopt_quantised_cornell_bakes_like_the_uncompressed_one() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cornell-cq.glb");
    let run = Command::new("gltfpack")
        .arg("-i")
        .arg(fixture("cornell.gltf"))
        .arg("-o")
        .arg(&input)
        .arg("-c")
        .output();
    match run {
        Ok(out) => assert!(out.status.success(), "{out:?}"),
        Err(e) => {
            return skip(
                "BAKE_REQUIRE_GLTFPACK",
                &format!("gltfpack does not run ({e}; tools/ci-clients installs it)"),
            )
        }
    }
    let (plain, _) = bake_report(&fixture("cornell.gltf"), dir.path(), "plain");
    let (packed, output) = bake_report(&input, dir.path(), "packed");
    assert_plain(&output);
    let worst = radiosity_deviation(&plain, &packed, 0.034);
    eprintln!("meshopt + quantisation: largest radiosity difference {worst:.2e} of the peak");
    assert!(worst < 1e-3, "{worst}");
}
