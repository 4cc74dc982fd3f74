//! Runs the Khronos glTF validator (tools/validate.mjs) on the exporter's outputs.
//! Skipped with a message when `node` or the validator is missing, unless
//! `BAKE_REQUIRE_VALIDATOR=1`, which turns a missing validator into a failure.
//! Install it with `bash tools/install-validator`.

mod common;

// The shared `common` module names it.
use bake_exporter::ExportError;

use bake_exporter::{write_gltf, Bake, Shading};
use bake_testkit::{skip, validator_available, validator_output};
use common::sample_bake;

#[test]
fn outputs_validate_without_errors_or_warnings() {
    if !validator_available() {
        skip(
            "BAKE_REQUIRE_VALIDATOR",
            "the validator is not installed (run: bash tools/install-validator)",
        );
        return;
    }
    let fixture = sample_bake();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut files = Vec::new();
    for (shading, tag) in [(Shading::Smooth, "smooth"), (Shading::Flat, "flat")] {
        let bake = Bake {
            scene: &fixture.scene,
            mesh: &fixture.mesh,
            radiosity: &fixture.radiosity,
            irradiance: None,
            error: None,
            shading,
            exposure: 0.9,
            probes: None,
        };
        for extension in ["gltf", "glb"] {
            let path = dir.path().join(format!("{tag} bake.{extension}"));
            write_gltf(&path, &bake).expect("write the baked glTF");
            files.push(path);
        }
    }
    let output = validator_output(&files);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("{stdout}{stderr}");
    assert!(
        output.status.success(),
        "validator found problems:\n{stdout}{stderr}"
    );
    let summaries = stdout
        .lines()
        .filter(|line| line.ends_with("infos"))
        .filter(|line| line.contains(": 0 errors, 0 warnings,"))
        .count();
    assert_eq!(
        summaries,
        files.len(),
        "one clean summary per file:\n{stdout}"
    );
}
