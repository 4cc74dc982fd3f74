//! Every kind of output `bake` writes goes through the Khronos glTF validator: each fixture in
//! `fixtures/` (found by listing the directory, so new fixtures are covered as they land) ×
//! `.gltf`/`.glb` × `--shading smooth|flat` × every entry of [`MODES`]. All outputs are
//! validated in one `node tools/validate.mjs` call; each must have 0 errors and 0 warnings,
//! and infos only of the codes [`EXPLAINED_INFOS`] lists, with the reason.
//!
//! Skipped with a message when the validator is not installed (`tools/install-validator`),
//! unless `BAKE_REQUIRE_VALIDATOR=1` (as `tools/test` sets).

use crate::common;

use bake_testkit::{fixtures_dir, validator_or_skip, validator_output};
use common::bake;
use std::path::{Path, PathBuf};

/// Output modes: extra arguments, one bake per entry and per fixture, container and shading.
/// The default `--target both` writes the vertex and the lightmap bake; other `--target`
/// modes write OUT alone.
const MODES: &[&[&str]] = &[
    &[],
    // COLOR_0 clamped to 1 on bright elements (the validator rejects values above 1).
    &["--exposure", "4"],
    // Unlit materials with the bake as their base-colour texture on TEXCOORD_1.
    &["--target", "baked-texture"],
];
const CONTAINERS: [&str; 2] = ["gltf", "glb"];
const SHADINGS: [&str; 2] = ["smooth", "flat"];
/// Keeps the run short: every polygon gets 2×2 elements.
const SUBDIV: &str = "2";
/// Validator info codes that are expected, and why. Any other info fails the test.
const EXPLAINED_INFOS: &[(&str, &str)] = &[
    (
        "UNSUPPORTED_EXTENSION",
        "lightmap bakes use MOZ_lightmap (what three.js's glTF lightmap loader reads), which the \
         validator does not know",
    ),
    (
        "UNUSED_OBJECT",
        "the lightmap texture and TEXCOORD_1 are referenced only from MOZ_lightmap, which the \
         validator does not read",
    ),
    (
        "IMAGE_NPOT_DIMENSIONS",
        "lightmap atlases (and the baked textures, which share their layout) are packed to \
         the charts' size, not to a power of two",
    ),
];

/// The scenes in `fixtures/`: every .gltf, .glb and .obj (the .bin and .mtl files are their
/// side files), sorted by name.
fn fixtures() -> Vec<PathBuf> {
    let dir = fixtures_dir();
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("list fixtures/")
        .map(|entry| entry.expect("a directory entry").path())
        .filter(|path| {
            path.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| ["gltf", "glb", "obj"].contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    scenes.sort();
    scenes
}

/// `cube.gltf` + smooth + [] + glb → `cube.gltf-smooth.glb`; a mode's arguments are
/// appended to the name (`--target lightmap` → `-target-lightmap`).
fn output_name(input: &Path, shading: &str, mode: &[&str], container: &str) -> String {
    let input = input
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tag: String = mode
        .iter()
        .map(|a| format!("-{}", a.trim_start_matches('-')))
        .collect();
    format!("{input}-{shading}{tag}.{container}")
}

/// One validator message line: `  <severity> <CODE> <pointer>: <text>`.
fn message_code(line: &str) -> Option<(&str, &str)> {
    let mut words = line.split_whitespace();
    let severity = words.next()?;
    let code = words.next()?;
    Some((severity, code))
}

#[test]
fn every_output_mode_of_every_fixture_is_validator_clean() {
    if !validator_or_skip() {
        return;
    }
    let scenes = fixtures();
    assert!(
        scenes.iter().any(|p| p.ends_with("cube.gltf")),
        "{scenes:?}"
    );
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut outputs = Vec::new();
    for input in &scenes {
        for mode in MODES {
            for shading in SHADINGS {
                for container in CONTAINERS {
                    let output = dir
                        .path()
                        .join(output_name(input, shading, mode, container));
                    let mut args: Vec<&std::ffi::OsStr> = vec![
                        "--quiet".as_ref(),
                        "--subdiv".as_ref(),
                        SUBDIV.as_ref(),
                        "--shading".as_ref(),
                        shading.as_ref(),
                    ];
                    args.extend(mode.iter().map(std::ffi::OsStr::new));
                    args.extend([input.as_os_str(), output.as_os_str()]);
                    let run = bake(&args);
                    assert_eq!(run.code, Some(0), "bake {args:?} failed: {run:#?}");
                    outputs.push(output.clone());
                    if mode.contains(&"--target") {
                        continue;
                    }
                    // The default `--target both` writes the lightmap bake beside OUT.
                    let stem = output.file_stem().unwrap_or_default().to_string_lossy();
                    let side = output.with_file_name(format!("{stem}.lightmap.{container}"));
                    assert!(
                        side.exists(),
                        "no lightmap bake beside {}",
                        output.display()
                    );
                    outputs.push(side);
                }
            }
        }
    }

    let output = validator_output(&outputs);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    // The summary lines, with paths relative to the temporary directory.
    let prefix = format!("{}/", dir.path().display());
    println!("{}", stdout.replace(&prefix, ""));
    assert!(
        output.status.success(),
        "the validator found errors or warnings:\n{stdout}{stderr}"
    );

    let mut summaries = 0;
    let mut unexplained = Vec::new();
    for line in stdout.lines() {
        if !line.starts_with(' ') {
            assert!(
                line.contains(": 0 errors, 0 warnings, "),
                "not clean: {line}"
            );
            summaries += 1;
        } else if let Some((severity, code)) = message_code(line) {
            let explained = severity == "info" && EXPLAINED_INFOS.iter().any(|(c, _)| *c == code);
            if !explained {
                unexplained.push(line.to_string());
            }
        }
    }
    assert_eq!(summaries, outputs.len(), "one summary per file:\n{stdout}");
    assert!(
        unexplained.is_empty(),
        "validator messages not explained in EXPLAINED_INFOS:\n{}",
        unexplained.join("\n")
    );
    println!(
        "{} outputs ({} fixtures × {} containers × {} shadings × {} modes) validator-clean",
        outputs.len(),
        scenes.len(),
        CONTAINERS.len(),
        SHADINGS.len(),
        MODES.len()
    );
}
