//! Every kind of bad input and bad usage: `bake` exits non-zero with exactly one
//! `bake: error:` line naming the file and the problem, and writes nothing (no OUT, no .bin,
//! no report, no temporaries). Also the warning path (a dropped degenerate face), `--quiet`,
//! `--help` and `--version`.

use crate::common;

use bake_testkit::{file_names, fixture, GltfBuilder, POINTS, TRIANGLES};
use common::{
    bake, cube_with_sliver_json, report_without_timings, write_obj_with_material, write_text, Run,
    CUBE_WALLS, TRIANGLE,
};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Exit codes documented by `bake --help`.
const BAD_INPUT: i32 = 1;
const USAGE: i32 = 2;
const OUTPUT: i32 = 3;
const TOO_LARGE: i32 = 4;

/// Runs `bake [args] INPUT OUT/baked.gltf --report OUT/report.json` with an empty directory
/// OUT and checks the failure: exit `code`, one error line that names `input`'s file name and
/// contains every string of `problem`, and OUT holding nothing but, where the bake got past
/// planning its outputs, the failed bake's report with that line and code. Returns the error
/// line.
fn assert_rejected(input: &Path, args: &[&str], code: i32, problem: &[&str]) -> String {
    let out = tempfile::tempdir().expect("a temporary directory");
    let output = out.path().join("baked.gltf");
    let report = out.path().join("report.json");
    let mut command: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
    command.extend([
        input.as_os_str(),
        output.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
    ]);
    let run = bake(&command);
    let line = single_error_line(&run, code);
    let name = input.file_name().expect("a file name").to_string_lossy();
    assert!(line.contains(&*name), "{line:?} does not name {name:?}");
    for word in problem {
        assert!(line.contains(word), "{line:?} does not say {word:?}");
    }
    if report.exists() {
        let failed = bake_job::report::read_failed_report(&report).expect("a failed report");
        assert_eq!(format!("bake: error: {}", failed.failure.error), line);
        assert_eq!(i32::from(failed.failure.exit_code), code);
        std::fs::remove_file(&report).expect("remove the report");
    }
    assert_eq!(
        file_names(out.path()),
        Vec::<String>::new(),
        "a failed bake left files behind"
    );
    line
}

/// Exit `code` and exactly one non-warning stderr line, starting with `bake: error:`.
fn single_error_line(run: &Run, code: i32) -> String {
    assert_eq!(run.code, Some(code), "exit code: {run:#?}");
    let lines = run.error_lines();
    assert_eq!(lines.len(), 1, "one error line expected: {run:#?}");
    assert!(
        lines[0].starts_with("bake: error: "),
        "not an error line: {:?}",
        lines[0]
    );
    lines[0].to_string()
}

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary directory")
}

// ---- unreadable or unsupported files ----

#[test]
fn missing_input_file() {
    let dir = dir();
    let line = assert_rejected(
        &dir.path().join("absent.gltf"),
        &[],
        BAD_INPUT,
        &["cannot read"],
    );
    // The OS error is stated once, not repeated by the error chain.
    assert_eq!(line.matches("os error").count(), 1, "{line:?}");
}

#[test]
fn unsupported_extension() {
    let dir = dir();
    let input = dir.path().join("scene.txt");
    write_text(&input, "v 0 0 0\n");
    assert_rejected(&input, &[], BAD_INPUT, &["unsupported file extension"]);
}

// ---- malformed glTF / GLB ----

#[test]
fn truncated_gltf_json() {
    let dir = dir();
    let input = dir.path().join("truncated.gltf");
    let full =
        serde_json::to_string(&GltfBuilder::wall(&TRIANGLE, TRIANGLES, None).json()).unwrap();
    write_text(&input, &full[..full.len() / 2]);
    assert_rejected(&input, &[], BAD_INPUT, &["malformed glTF", "EOF"]);
}

#[test]
fn json_that_is_not_gltf() {
    let dir = dir();
    let input = dir.path().join("notgltf.gltf");
    write_text(&input, r#"{ "hello": "world", "items": [1, 2, 3] }"#);
    assert_rejected(&input, &[], BAD_INPUT, &["malformed glTF", "asset"]);
}

#[test]
fn gltf_buffer_pointing_at_a_missing_bin() {
    let dir = dir();
    let input = dir.path().join("external.gltf");
    let root =
        GltfBuilder::wall(&TRIANGLE, TRIANGLES, None).json_with_buffer_uri("external-data.bin");
    common::write_json(&input, &root);
    assert_rejected(
        &input,
        &[],
        BAD_INPUT,
        &["malformed glTF", "external-data.bin"],
    );
}

#[test]
fn glb_with_a_bad_header() {
    let dir = dir();
    // Version 1 (GLB is version 2).
    let v1 = dir.path().join("version1.glb");
    let mut bytes = b"glTF".to_vec();
    bytes.extend(1u32.to_le_bytes());
    bytes.extend(12u32.to_le_bytes());
    std::fs::write(&v1, &bytes).unwrap();
    assert_rejected(&v1, &[], BAD_INPUT, &["GLB", "version 1"]);
    // A header whose length runs past the end of the file.
    let long = dir.path().join("long.glb");
    let mut bytes = b"glTF".to_vec();
    bytes.extend(2u32.to_le_bytes());
    bytes.extend(4096u32.to_le_bytes());
    std::fs::write(&long, &bytes).unwrap();
    assert_rejected(&long, &[], BAD_INPUT, &["GLB", "length"]);
    // Only the magic.
    let short = dir.path().join("short.glb");
    std::fs::write(&short, b"glTF").unwrap();
    assert_rejected(&short, &[], BAD_INPUT, &["GLB", "truncated"]);
}

// ---- malformed OBJ ----

#[test]
fn obj_face_referencing_a_missing_vertex() {
    let dir = dir();
    let input = dir.path().join("dangling.obj");
    write_text(&input, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n");
    assert_rejected(&input, &[], BAD_INPUT, &["malformed OBJ", "line 4", "99"]);
}

#[test]
fn obj_garbage() {
    let dir = dir();
    let input = dir.path().join("garbage.obj");
    write_text(&input, "v 0 zero 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_rejected(&input, &[], BAD_INPUT, &["malformed OBJ", "parse"]);
    // Text with nothing OBJ in it is read as an empty scene.
    let prose = dir.path().join("prose.obj");
    write_text(&prose, "This is not a model.\nJust two lines of prose.\n");
    assert_rejected(&prose, &[], BAD_INPUT, &["nothing left to bake"]);
}

// ---- non-finite positions ----

#[test]
fn gltf_nan_and_infinite_position() {
    let dir = dir();
    for (name, bad) in [("nan.gltf", f32::NAN), ("inf.gltf", f32::INFINITY)] {
        let input = dir.path().join(name);
        let mut positions = TRIANGLE;
        positions[1][0] = bad;
        GltfBuilder::wall(&positions, TRIANGLES, None).write_embedded(&input);
        assert_rejected(
            &input,
            &[],
            BAD_INPUT,
            &["mesh \"wall\"", "face 0", "not finite"],
        );
    }
}

#[test]
fn obj_nan_and_infinite_position() {
    let dir = dir();
    // `tobj` parses `nan` and `inf` as floats; the importer must refuse them.
    for (name, bad) in [("nan.obj", "nan"), ("inf.obj", "inf"), ("minf.obj", "-inf")] {
        let input = dir.path().join(name);
        write_text(
            &input,
            &format!("o wall\nv 0 0 0\nv 1 {bad} 0\nv 0 1 0\nf 1 2 3\n"),
        );
        assert_rejected(
            &input,
            &[],
            BAD_INPUT,
            &["mesh \"wall\"", "face 0", "not finite"],
        );
    }
}

// ---- invalid material values ----

#[test]
fn gltf_colour_overflowing_to_infinity() {
    let dir = dir();
    let input = dir.path().join("huge.gltf");
    // JSON has no NaN; 1e999 is the closest a file can get to a non-finite colour.
    let text = serde_json::to_string(
        &GltfBuilder::wall(
            &TRIANGLE,
            TRIANGLES,
            Some(json!({ "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.5, 0.5, 1.0] } })),
        )
        .json(),
    )
    .unwrap()
    .replacen("[0.5,0.5,0.5,1.0]", "[1e999,0.5,0.5,1.0]", 1);
    assert!(text.contains("1e999"));
    write_text(&input, &text);
    assert_rejected(&input, &[], BAD_INPUT, &["malformed glTF", "out of range"]);
}

#[test]
fn obj_nan_colour() {
    let dir = dir();
    for (stem, line) in [("kdnan", "Kd nan 0.5 0.5"), ("kenan", "Ke 1 nan 1")] {
        let input = write_obj_with_material(dir.path(), stem, line);
        assert_rejected(
            &input,
            &[],
            BAD_INPUT,
            &["material \"paint\"", "mesh \"wall\"", "not finite"],
        );
    }
}

#[test]
fn reflectance_outside_zero_one() {
    let dir = dir();
    let input = dir.path().join("bright.gltf");
    GltfBuilder::wall(
        &TRIANGLE,
        TRIANGLES,
        Some(json!({ "pbrMetallicRoughness": { "baseColorFactor": [1.5, 0.5, 0.5, 1.0] } })),
    )
    .write_embedded(&input);
    assert_rejected(
        &input,
        &[],
        BAD_INPUT,
        &["mesh \"wall\"", "1.5", "outside [0, 1]"],
    );
    for (stem, line) in [("kd15", "Kd 1.5 0.5 0.5"), ("kdneg", "Kd 0.5 -0.25 0.5")] {
        let input = write_obj_with_material(dir.path(), stem, line);
        assert_rejected(
            &input,
            &[],
            BAD_INPUT,
            &["material \"paint\"", "mesh \"wall\"", "outside [0, 1]"],
        );
    }
}

#[test]
fn negative_emission() {
    let dir = dir();
    let input = write_obj_with_material(dir.path(), "keneg", "Kd 0.5 0.5 0.5\nKe -1 0 0");
    assert_rejected(
        &input,
        &[],
        BAD_INPUT,
        &["material \"paint\"", "mesh \"wall\"", "negative"],
    );
    // The schema forbids a negative emissiveFactor; the importer refuses it all the same,
    // and a negative KHR_materials_emissive_strength too.
    let factor = dir.path().join("factor.gltf");
    GltfBuilder::wall(
        &TRIANGLE,
        TRIANGLES,
        Some(json!({ "emissiveFactor": [-1.0, 0.0, 0.0] })),
    )
    .write_embedded(&factor);
    assert_rejected(&factor, &[], BAD_INPUT, &["mesh \"wall\"", "negative"]);
    let strength = dir.path().join("strength.gltf");
    GltfBuilder::wall(
        &TRIANGLE,
        TRIANGLES,
        Some(json!({
            "emissiveFactor": [1.0, 1.0, 1.0],
            "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": -2.0 } }
        })),
    )
    .write_embedded(&strength);
    assert_rejected(&strength, &[], BAD_INPUT, &["mesh \"wall\"", "negative"]);
}

// ---- nothing left to bake ----

#[test]
fn gltf_with_only_points() {
    let dir = dir();
    let input = dir.path().join("points.gltf");
    GltfBuilder::wall(&TRIANGLE, POINTS, None).write_embedded(&input);
    assert_rejected(&input, &[], BAD_INPUT, &["nothing left to bake"]);
}

#[test]
fn obj_with_only_vertices() {
    let dir = dir();
    let input = dir.path().join("cloud.obj");
    write_text(&input, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n");
    assert_rejected(&input, &[], BAD_INPUT, &["nothing left to bake"]);
}

#[test]
fn gltf_with_only_degenerate_triangles() {
    let dir = dir();
    let input = dir.path().join("flat.gltf");
    GltfBuilder::wall(
        &[
            // collinear
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            // a repeated vertex
            [0.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ],
        TRIANGLES,
        None,
    )
    .write_embedded(&input);
    assert_rejected(&input, &[], BAD_INPUT, &["nothing left to bake"]);
}

// ---- usage ----

/// A valid input and an output path in an empty directory, for usage tests.
fn usage_run(args: &[&str]) -> (Run, tempfile::TempDir) {
    let out = dir();
    let cube = fixture("cube.gltf");
    let output = out.path().join("baked.glb");
    let mut command: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
    command.extend([cube.as_os_str(), output.as_os_str()]);
    (bake(&command), out)
}

#[test]
fn usage_errors_exit_2() {
    let none = bake(Vec::<&str>::new());
    assert_eq!(none.code, Some(USAGE), "{none:#?}");
    assert!(none.stderr.contains("required"), "{none:#?}");

    for (args, says) in [
        (&["--subdiv", "0"][..], "--subdiv"),
        (&["--no-such-flag"][..], "--no-such-flag"),
        (
            &["--subdiv", "2", "--max-element-size", "0.1"][..],
            "cannot be used with",
        ),
        (&["--shading", "glossy"][..], "glossy"),
        (&["--quality", "ultra"][..], "ultra"),
        (&["--ff-estimator", "monte-carlo"][..], "monte-carlo"),
        (&["--ff-points", "4"][..], "--ff-points"),
        (&["--ff-tolerance", "0"][..], "--ff-tolerance"),
        (&["--ff-tolerance", "1.5"][..], "--ff-tolerance"),
        (&["--bounces", "4000000000"][..], "--bounces"),
        (&["--bounces", "10001"][..], "--bounces"),
        (
            &["--ff-estimator", "contour", "--ff-tolerance", "1e-3"][..],
            "applies only to --ff-estimator auto",
        ),
    ] {
        let (run, out) = usage_run(args);
        assert_eq!(run.code, Some(USAGE), "{args:?}: {run:#?}");
        assert!(run.stderr.starts_with("error: "), "{args:?}: {run:#?}");
        assert!(run.stderr.contains(says), "{args:?}: {run:#?}");
        assert_eq!(file_names(out.path()), Vec::<String>::new(), "{args:?}");
    }
}

/// Values clap accepts but the bake refuses: exit 1 (invalid value), one line.
#[test]
fn invalid_option_values_exit_1() {
    for (args, says) in [
        (&["--exposure", "-1"][..], "--exposure"),
        (&["--exposure=-1"][..], "--exposure"),
        (&["--exposure", "nan"][..], "--exposure"),
        (&["--max-element-size", "0"][..], "--max-element-size"),
        (&["--max-element-size", "-0.5"][..], "--max-element-size"),
        (&["--max-element-size", "inf"][..], "--max-element-size"),
    ] {
        let (run, out) = usage_run(args);
        let line = single_error_line(&run, BAD_INPUT);
        assert!(line.contains(says), "{args:?}: {line:?}");
        assert_eq!(file_names(out.path()), Vec::<String>::new(), "{args:?}");
    }
}

#[test]
fn version_and_help() {
    let version = bake(["--version"]).success();
    assert_eq!(
        version.stdout.trim(),
        format!("bake {}", env!("CARGO_PKG_VERSION"))
    );
    let help = bake(["--help"]).success();
    for flag in [
        "--subdiv",
        "--max-element-size",
        "--bounces",
        "--shading",
        "--exposure",
        "--report",
        "--threads",
        "--quiet",
        "--ff-segments",
        "--ff-order",
    ] {
        assert!(help.stdout.contains(flag), "--help does not mention {flag}");
    }
    assert!(
        help.stdout.contains("Exit codes"),
        "--help lists the exit codes"
    );
}

// ---- output errors ----

#[test]
fn output_in_a_missing_directory() {
    for name in ["baked.gltf", "baked.glb"] {
        let out = dir();
        let output = out.path().join("no-such-dir").join(name);
        let run = bake([fixture("cube.gltf"), output]);
        let line = single_error_line(&run, OUTPUT);
        assert!(
            line.contains(name) && line.contains("no-such-dir"),
            "{line:?}"
        );
        assert_eq!(file_names(out.path()), Vec::<String>::new());
    }
}

#[test]
fn report_in_a_missing_directory_writes_nothing() {
    let out = dir();
    let output = out.path().join("baked.glb");
    let report = out.path().join("no-such-dir").join("report.json");
    let run = bake([
        fixture("cube.gltf").as_os_str(),
        output.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
    ]);
    let line = single_error_line(&run, OUTPUT);
    assert!(line.contains("report.json"), "{line:?}");
    // Refused before the bake: OUT is not written either.
    assert_eq!(file_names(out.path()), Vec::<String>::new());
}

#[test]
fn unsupported_output_extension() {
    let out = dir();
    let run = bake([fixture("cube.gltf"), out.path().join("baked.png")]);
    let line = single_error_line(&run, OUTPUT);
    assert!(line.contains("baked.png"), "{line:?}");
    assert_eq!(file_names(out.path()), Vec::<String>::new());
}

// ---- warnings and --quiet ----

/// The importer's warnings are printed as soon as the scene is read: a bake refused later
/// (here by its element count) still shows them, before its error line.
#[test]
fn import_warnings_show_even_when_the_bake_is_refused_later() {
    let dir = dir();
    let input = dir.path().join("cube-sliver.gltf");
    common::write_json(&input, &cube_with_sliver_json());
    let line = assert_rejected(
        &input,
        &["--max-element-size", "1e-300"],
        BAD_INPUT,
        &["elements"],
    );
    let out = dir.path().join("o.glb");
    let run = bake([
        "--max-element-size".as_ref(),
        "1e-300".as_ref(),
        input.as_os_str(),
        out.as_os_str(),
    ]);
    let warnings = run.warning_lines();
    assert_eq!(warnings.len(), 1, "{run:#?}");
    assert!(warnings[0].contains("degenerate"), "{warnings:?}");
    let warning_at = run.stderr.find("bake: warning:");
    let error_at = run.stderr.find("bake: error:");
    assert!(warning_at < error_at, "{run:#?}");
    assert!(run.stderr.contains(&line), "{run:#?}");
}

/// Bakes `input` at --subdiv 4 into `dir`; returns the run and the report path.
fn bake_cube_like(dir: &Path, input: &Path, tag: &str, quiet: bool) -> (Run, PathBuf) {
    let report = dir.join(format!("{tag}.json"));
    let output = dir.join(format!("{tag}.glb"));
    let mut args = vec![
        "--subdiv".into(),
        "4".into(),
        "--report".into(),
        report.clone().into_os_string(),
        input.into(),
        output.into_os_string(),
    ];
    if quiet {
        args.push("--quiet".into());
    }
    (bake(&args), report)
}

#[test]
fn a_degenerate_face_is_dropped_with_a_warning() {
    let dir = dir();
    let input = dir.path().join("cube-sliver.gltf");
    common::write_json(&input, &cube_with_sliver_json());
    let (run, report_path) = bake_cube_like(dir.path(), &input, "sliver", false);
    let run = run.success();
    let warnings = run.warning_lines();
    assert_eq!(warnings.len(), 1, "{run:#?}");
    assert!(
        warnings[0].contains("sliver") && warnings[0].contains("degenerate"),
        "{warnings:?}"
    );
    let with_sliver = report_without_timings(&report_path);
    assert_eq!(with_sliver.counts.degenerate_dropped, 1);
    assert_eq!(with_sliver.counts.faces_read, 2 * CUBE_WALLS.len() + 1);
    assert_eq!(with_sliver.counts.polygons, CUBE_WALLS.len());
    assert_eq!(with_sliver.warnings.len(), 1);

    let (plain, plain_path) = bake_cube_like(dir.path(), &fixture("cube.gltf"), "plain", false);
    plain.success();
    let plain = report_without_timings(&plain_path);
    assert_eq!(plain.counts.degenerate_dropped, 0);
    assert_eq!(with_sliver.elements.len(), plain.elements.len());
    for (k, (a, b)) in with_sliver.elements.iter().zip(&plain.elements).enumerate() {
        assert_eq!(a.polygon, b.polygon, "element {k}");
        assert_eq!(a.centroid, b.centroid, "element {k}");
        for band in 0..3 {
            assert!(
                (a.b[band] - b.b[band]).abs() <= 1e-12,
                "element {k} band {band}: {} vs {}",
                a.b[band],
                b.b[band]
            );
        }
    }
}

#[test]
fn quiet_prints_nothing_on_success() {
    let dir = dir();
    // Without --quiet the cube prints a summary line; with it, nothing.
    let (loud, _) = bake_cube_like(dir.path(), &fixture("cube.gltf"), "loud", false);
    assert!(!loud.success().stderr.is_empty());
    let (quiet, _) = bake_cube_like(dir.path(), &fixture("cube.gltf"), "quiet", true);
    assert_eq!(quiet.success().stderr, "");
    // Warnings are silenced too.
    let input = dir.path().join("cube-sliver.gltf");
    common::write_json(&input, &cube_with_sliver_json());
    let (quiet, report) = bake_cube_like(dir.path(), &input, "quiet-sliver", true);
    assert_eq!(quiet.success().stderr, "");
    // ... though the report still records them.
    assert_eq!(report_without_timings(&report).warnings.len(), 1);
}

// ---- input files: regular, capped, inside the scene's folder ----

/// Runs `bake` and kills it after 20 s: a refusal must come at once (a FIFO must not block).
fn bake_within_20_s(args: &[&std::ffi::OsStr]) -> Run {
    use std::io::Read;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_bake"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start bake");
    let started = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("poll bake") {
            break status;
        }
        if started.elapsed() > std::time::Duration::from_secs(20) {
            let _ = child.kill();
            panic!("bake {args:?} ran past 20 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let mut stdout = String::new();
    let mut stderr = String::new();
    if let Some(mut out) = child.stdout.take() {
        let _ = out.read_to_string(&mut stdout);
    }
    if let Some(mut err) = child.stderr.take() {
        let _ = err.read_to_string(&mut stderr);
    }
    Run {
        code: status.code(),
        stdout,
        stderr,
    }
}

#[cfg(unix)]
#[test]
fn a_fifo_a_directory_and_dev_zero_are_refused_at_once() {
    let dir = dir();
    let fifo = dir.path().join("fifo.gltf");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("run mkfifo");
    assert!(made.success());
    let zero = dir.path().join("zero.glb");
    std::os::unix::fs::symlink("/dev/zero", &zero).expect("symlink");
    let folder = dir.path().join("folder.obj");
    std::fs::create_dir(&folder).expect("mkdir");
    let out = dir.path().join("out");
    std::fs::create_dir(&out).expect("mkdir");
    for (input, says) in [
        (&fifo, "not a regular file"),
        (&zero, "not a regular file"),
        (&folder, "a directory"),
    ] {
        let output = out.join("o.gltf");
        let run = bake_within_20_s(&[input.as_os_str(), output.as_os_str()]);
        let line = single_error_line(&run, BAD_INPUT);
        assert!(line.contains(says), "{line}");
        assert_eq!(file_names(&out), Vec::<String>::new());
    }
}

#[test]
fn inputs_outside_the_folder_are_refused_unless_allowed() {
    let dir = dir();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir_all(scenes.join("sub")).expect("mkdir");
    let outside = dir.path().join("outside.bin");
    std::fs::write(&outside, bake_testkit::position_bytes(&TRIANGLE)).expect("write");
    let builder = GltfBuilder::wall(&TRIANGLE, TRIANGLES, None);
    let absolute = outside.display().to_string();
    let file_uri = format!("file://{absolute}");
    for (name, uri) in [
        ("up.gltf", "../outside.bin"),
        ("up2.gltf", "sub/../../outside.bin"),
        ("absolute.gltf", absolute.as_str()),
        ("file-uri.gltf", file_uri.as_str()),
    ] {
        let input = scenes.join(name);
        common::write_json(&input, &builder.json_with_buffer_uri(uri));
        let line = assert_rejected(&input, &[], BAD_INPUT, &["--allow-outside-paths"]);
        assert!(line.contains("buffer 0"), "{line}");
        // Given the flag, the same file bakes.
        let out = dir.path().join(format!("{name}.glb"));
        bake([
            "--allow-outside-paths".as_ref(),
            "--subdiv".as_ref(),
            "1".as_ref(),
            "--quiet".as_ref(),
            input.as_os_str(),
            out.as_os_str(),
        ])
        .success();
    }
    // An mtllib outside the folder: an error, not a missing library's warning.
    let obj = scenes.join("m.obj");
    write_text(
        &obj,
        "mtllib ../paint.mtl\nusemtl paint\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    write_text(
        &dir.path().join("paint.mtl"),
        "newmtl paint\nKd 0.5 0.5 0.5\n",
    );
    assert_rejected(&obj, &[], BAD_INPUT, &["mtllib", "--allow-outside-paths"]);
}

// ---- the cost is estimated before the work ----

#[test]
fn element_counts_too_large_for_the_mesher_or_memory_are_refused_before_meshing() {
    // 1e-4 on the unit cube: 6 × 10^8 elements (a 48 GB reservation used to abort); 1e-300
    // overflowed the count past the check.
    for size in ["1e-4", "1e-300"] {
        let started = std::time::Instant::now();
        // Past the memory available: too large for this machine (4); past the mesher's
        // fixed limit: bad input everywhere (1).
        let memory = size == "1e-4" && Path::new("/proc/meminfo").exists();
        let line = assert_rejected(
            &fixture("cube.gltf"),
            &["--max-element-size", size],
            if memory { TOO_LARGE } else { BAD_INPUT },
            &["elements"],
        );
        // 1e-4: 6 × 10^8 elements fit the mesher's 2^30 but not the memory (the message
        // gives the estimate and MemAvailable); 1e-300: over the mesher's limit.
        let says = match size {
            "1e-4" if Path::new("/proc/meminfo").exists() => "of memory is available",
            "1e-4" => "elements",
            _ => "at least 10^600 elements, more than the mesher's limit",
        };
        assert!(line.contains(says), "{size}: {line}");
        assert!(
            started.elapsed().as_secs() < 10,
            "{size}: took {:?}",
            started.elapsed()
        );
    }
}

#[test]
fn an_obj_with_too_many_faces_is_refused_before_parsing() {
    let dir = dir();
    let obj = dir.path().join("many.obj");
    // One face more than the importer's limit of 2^22 (33 MB of text).
    let mut text = String::with_capacity(8 * ((1 << 22) + 2) + 32);
    text.push_str("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for _ in 0..(1u32 << 22) + 1 {
        text.push_str("f 1 2 3\n");
    }
    write_text(&obj, &text);
    drop(text);
    assert_rejected(&obj, &[], BAD_INPUT, &["too large", "4194304 faces"]);
}
