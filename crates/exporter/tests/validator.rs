//! Runs the Khronos glTF validator (tools/validate.mjs) on the exporter's outputs.
//! Skipped with a message when `node` or the validator is missing, unless
//! `BAKE_REQUIRE_VALIDATOR=1`, which turns a missing validator into a failure.
//! Install it with `bash tools/install-validator`.

mod common;

use bake_exporter::{write_gltf, Bake, Shading};
use common::fixture;
use std::path::PathBuf;
use std::process::Command;

fn tools_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tools")
}

/// Whether `node` runs and the validator package is installed.
fn validator_available() -> bool {
    let installed = tools_dir()
        .join(".validator/node_modules/gltf-validator/package.json")
        .is_file();
    let node_runs = Command::new("node")
        .arg("--version")
        .output()
        .map(|output| output.status.success())
        .unwrap_or(false);
    installed && node_runs
}

#[test]
fn outputs_validate_without_errors_or_warnings() {
    if !validator_available() {
        let required = std::env::var("BAKE_REQUIRE_VALIDATOR").is_ok_and(|v| v == "1");
        assert!(
            !required,
            "BAKE_REQUIRE_VALIDATOR=1 but the validator is not installed \
             (run: bash tools/install-validator)"
        );
        println!("skipped: validator not installed (run: bash tools/install-validator)");
        return;
    }
    let fixture = fixture();
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
        };
        for extension in ["gltf", "glb"] {
            let path = dir.path().join(format!("{tag} bake.{extension}"));
            write_gltf(&path, &bake).expect("write the baked glTF");
            files.push(path);
        }
    }
    let output = Command::new("node")
        .arg(tools_dir().join("validate.mjs"))
        .args(&files)
        .output()
        .expect("run node tools/validate.mjs");
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
