//! Bakes checked in real viewers, and build-system behaviour:
//!
//! - `bake preview` (the built-in software rasterizer): the pixel at each element's projected
//!   centroid is that element's colour, flat and smooth differ as the paper's Figures 6 and 8
//!   do, renders are deterministic, exit codes;
//! - pyrender + trimesh + pygltflib (`tests/python/test_render.py`, in the virtualenv that
//!   `tools/ci-clients` makes): skipped with a message when the venv is missing, unless
//!   `BAKE_REQUIRE_CLIENTS=1`;
//! - Blender (`tools/blender-check`): skipped when `blender` is not installed, unless
//!   `BAKE_REQUIRE_BLENDER=1`;
//! - the one-line summary a bake ends with.

use crate::common;

use bake_job::report::{read_report, Report};
use bake_testkit::{blender_or_skip, fixture, skip};
use common::{bake, bake_in, Run, CUBE_WALLS};
use preview::image::RgbImage;
use preview::{srgb8, Camera};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Largest difference allowed between a pixel and the colour it should show (of 255).
const TOLERANCE: i32 = 2;
const SIZE: u32 = 512;

/// Bakes `fixtures/cube.gltf` at --subdiv 4 into `dir/name` (with a report) and returns the
/// output path and the report.
fn bake_cube(dir: &Path, name: &str, shading: &str) -> (PathBuf, Report) {
    let output = dir.join(name);
    let report = dir.join(format!("{name}.json"));
    bake([
        "--quiet".as_ref(),
        "--subdiv".as_ref(),
        "4".as_ref(),
        "--shading".as_ref(),
        shading.as_ref(),
        "--report".as_ref(),
        report.as_os_str(),
        fixture("cube.gltf").as_os_str(),
        output.as_os_str(),
    ])
    .success();
    (output, read_report(&report).expect("read the report"))
}

/// `bake preview INPUT PNG [args]`.
fn preview_run(input: &Path, png: &Path, args: &[&str]) -> Run {
    let mut all: Vec<&std::ffi::OsStr> = vec!["preview".as_ref(), input.as_ref(), png.as_ref()];
    all.extend(args.iter().map(std::ffi::OsStr::new));
    bake(all)
}

fn read_png(path: &Path) -> RgbImage {
    preview::image::open(path)
        .expect("decode the PNG")
        .to_rgb8()
}

/// The camera `bake preview` uses for `input` with `options` (the library's own choice).
fn preview_camera(input: &Path, options: &preview::Options) -> Camera {
    let scene = preview::load(input, options.colors).expect("load the bake");
    preview::choose_camera(&scene, options).expect("a camera").0
}

/// An element's displayed colour: COLOR_0 = clamp(b × exposure, 0, 1), sRGB-encoded.
fn expected_srgb(b: [f64; 3], exposure: f64) -> [u8; 3] {
    b.map(|v| srgb8((v * exposure).clamp(0.0, 1.0)))
}

fn max_difference(a: [u8; 3], b: [u8; 3]) -> i32 {
    (0..3)
        .map(|k| (i32::from(a[k]) - i32::from(b[k])).abs())
        .max()
        .unwrap_or(0)
}

/// For every element facing the camera: the pixel at its projected centroid in `image`
/// against the element's sRGB colour. Returns (elements checked, largest difference).
fn check_element_pixels(
    image: &RgbImage,
    camera: &Camera,
    report: &Report,
    exposure: f64,
    what: &str,
) -> (usize, i32) {
    let mut checked = 0;
    let mut worst = 0;
    for (k, element) in report.elements.iter().enumerate() {
        let towards_eye: f64 = (0..3)
            .map(|a| (camera.eye[a] - element.centroid[a]) * element.normal[a])
            .sum();
        if towards_eye <= 0.0 {
            continue; // culled: seen from behind
        }
        let p = camera
            .project(element.centroid, image.width(), image.height())
            .expect("the element is in front of the camera");
        let (x, y) = (p[0].floor() as u32, p[1].floor() as u32);
        assert!(
            x < image.width() && y < image.height(),
            "{what}: element {k} off screen"
        );
        let got = image.get_pixel(x, y).0;
        let expected = expected_srgb(element.b, exposure);
        let difference = max_difference(got, expected);
        assert!(
            difference <= TOLERANCE,
            "{what}: element {k} at {:?}: pixel ({x}, {y}) = {got:?}, expected {expected:?}",
            element.centroid
        );
        worst = worst.max(difference);
        checked += 1;
    }
    (checked, worst)
}

// ---- bake preview ----

#[test]
fn preview_shows_every_element_with_its_colour() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (baked, report) = bake_cube(dir.path(), "flat.gltf", "flat");
    let png = dir.path().join("flat.png");
    let run = preview_run(&baked, &png, &["--view", "0,0,-1"]).success();
    assert!(run.stderr.contains("framing, view 0,0,-1"), "{run:#?}");
    let image = read_png(&png);
    assert_eq!(image.dimensions(), (SIZE, SIZE));
    let options = preview::Options {
        view: Some([0.0, 0.0, -1.0]),
        ..preview::Options::default()
    };
    let camera = preview_camera(&baked, &options);
    let (checked, worst) = check_element_pixels(&image, &camera, &report, 1.0, "flat");
    // Looking into the cube through its emitter wall (culled): 5 walls × 16 elements.
    assert_eq!(checked, (CUBE_WALLS.len() - 1) * 16);
    println!("preview: {checked} elements checked, largest difference {worst}/255");

    // --exposure shows _RADIOSITY × X instead of COLOR_0.
    let bright = dir.path().join("bright.png");
    preview_run(&baked, &bright, &["--exposure", "3", "-q"]).success();
    let (checked, worst) =
        check_element_pixels(&read_png(&bright), &camera, &report, 3.0, "exposure 3");
    println!("preview --exposure 3: {checked} elements checked, largest difference {worst}/255");
}

#[test]
fn flat_and_smooth_previews_differ_like_figures_6_and_8() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut images = Vec::new();
    for shading in ["flat", "smooth"] {
        let (baked, _) = bake_cube(dir.path(), &format!("{shading}.glb"), shading);
        let png = dir.path().join(format!("{shading}.png"));
        preview_run(&baked, &png, &["-q"]).success();
        images.push(read_png(&png));
    }
    let distinct = |image: &RgbImage| {
        let mut colours: Vec<[u8; 3]> = image.pixels().map(|p| p.0).collect();
        colours.sort_unstable();
        colours.dedup();
        colours.len()
    };
    let (flat, smooth) = (distinct(&images[0]), distinct(&images[1]));
    println!("distinct colours: flat {flat}, smooth {smooth}");
    // Flat: one colour per visible element, the background, and edges between them.
    assert!(flat <= 80 + 1, "flat shows {flat} colours");
    assert!(smooth > 4 * flat, "smooth shows {smooth} colours");
}

#[test]
fn previews_are_deterministic_across_containers_threads_and_runs() {
    let mut pngs = Vec::new();
    for (output, threads) in [("a.gltf", "1"), ("b.glb", "2"), ("c.glb", "1")] {
        let dir = tempfile::tempdir().expect("a temporary directory");
        bake_in(
            Some(dir.path()),
            [
                "--quiet",
                "--subdiv",
                "6",
                "--threads",
                threads,
                fixture("cube.gltf").to_str().expect("UTF-8"),
                output,
            ],
        )
        .success();
        for _ in 0..2 {
            preview_run(&dir.path().join(output), &dir.path().join("p.png"), &["-q"]).success();
            pngs.push(std::fs::read(dir.path().join("p.png")).expect("read the PNG"));
        }
    }
    assert!(pngs.iter().all(|png| png == &pngs[0]), "previews differ");
}

#[test]
fn preview_exit_codes_and_messages() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (baked, _) = bake_cube(dir.path(), "cube.glb", "flat");
    let out = tempfile::tempdir().expect("a temporary directory");
    let png = out.path().join("cube.png");

    let ok = preview_run(&baked, &png, &[]).success();
    let line = ok.stderr.trim();
    assert!(
        line.starts_with("bake: preview ")
            && line.contains("512×512")
            && line.contains("triangles"),
        "{line:?}"
    );
    assert_eq!(preview_run(&baked, &png, &["-q"]).success().stderr, "");
    std::fs::remove_file(&png).expect("remove the PNG");

    let expect = |run: Run, code: i32, says: &str| {
        assert_eq!(run.code, Some(code), "{run:#?}");
        assert!(run.stderr.contains(says), "{says:?} not in {run:#?}");
        assert_eq!(
            bake_testkit::file_names(out.path()),
            Vec::<String>::new(),
            "files left behind"
        );
    };
    // 1: bad input.
    let report = dir.path().join("cube.glb.json");
    expect(
        preview_run(&dir.path().join("absent.glb"), &png, &[]),
        1,
        "absent.glb",
    );
    expect(preview_run(&report, &png, &[]), 1, "cube.glb.json");
    expect(
        preview_run(&baked, &png, &["--view", "0,0,0"]),
        1,
        "cannot frame",
    );
    expect(
        preview_run(&baked, &png, &["--exposure", "-1"]),
        1,
        "--exposure",
    );
    // 2: usage.
    expect(bake(["preview"]), 2, "required");
    expect(preview_run(&baked, &png, &["--view", "1,2"]), 2, "--view");
    expect(preview_run(&baked, &png, &["--width", "0"]), 2, "--width");
    expect(
        preview_run(&baked, &png, &["--no-such-flag"]),
        2,
        "--no-such-flag",
    );
    // 3: output.
    expect(
        preview_run(&baked, &out.path().join("missing").join("x.png"), &[]),
        3,
        "missing",
    );
    expect(
        preview_run(&baked, &out.path().join("x.jpg"), &[]),
        3,
        "x.jpg",
    );

    let help = bake(["preview", "--help"]).success();
    for word in ["--width", "--height", "--exposure", "--view", "Exit codes"] {
        assert!(help.stdout.contains(word), "bake preview --help: {word}");
    }
    assert!(bake(["--help"]).success().stdout.contains("bake preview"));
}

// ---- the summary line ----

#[test]
fn a_bake_ends_with_a_one_line_summary() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let output = dir.path().join("cube.glb");
    let run = bake([
        "--subdiv".as_ref(),
        "4".as_ref(),
        fixture("cube.gltf").as_os_str(),
        output.as_os_str(),
    ])
    .success();
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{run:#?}");
    let line = lines[0];
    assert!(
        line.starts_with("bake: ") && line.contains("cube.glb"),
        "{line:?}"
    );
    assert!(line.contains(" 6 polygons, 96 elements, "), "{line:?}");
    let residual = line
        .split("residual ")
        .nth(1)
        .and_then(|rest| rest.split(',').next())
        .expect("a residual");
    let bands: Vec<f64> = residual
        .split('/')
        .map(|v| v.parse().expect("a number"))
        .collect();
    assert_eq!(bands.len(), 3, "{line:?}");
    assert!(bands.iter().all(|r| *r < 1e-12), "{line:?}");
    let seconds: f64 = line
        .strip_suffix(" s")
        .and_then(|rest| rest.rsplit(", ").next())
        .and_then(|t| t.parse().ok())
        .expect("the time in seconds at the end");
    assert!(seconds >= 0.0, "{line:?}");
}

// ---- real clients ----

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Prints a command's output and asserts it succeeded.
fn show(what: &str, output: &std::process::Output, started: Instant) -> String {
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("{stdout}{stderr}");
    println!("{what}: {:.1} s", started.elapsed().as_secs_f64());
    assert!(output.status.success(), "{what} failed:\n{stdout}{stderr}");
    stdout
}

#[test]
fn pyrender_renders_the_reported_colours() {
    let python = root().join("tests/python/.venv/bin/python");
    if !python.is_file() {
        skip(
            "BAKE_REQUIRE_CLIENTS",
            &format!("{} is missing (run tools/ci-clients)", python.display()),
        );
        return;
    }
    let started = Instant::now();
    let output = Command::new(&python)
        .arg(root().join("tests/python/test_render.py"))
        .env("BAKE_BIN", env!("CARGO_BIN_EXE_bake"))
        .env("PYOPENGL_PLATFORM", "osmesa")
        .output()
        .expect("run tests/python/test_render.py");
    let stdout = show("pyrender harness", &output, started);
    assert!(stdout.contains("cube: 96 elements"), "{stdout}");
    assert!(stdout.trim_end().ends_with("ok"), "{stdout}");
}

#[test]
fn blender_imports_the_baked_colours_and_renders_what_preview_renders() {
    if !blender_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (baked, report) = bake_cube(dir.path(), "flat.gltf", "flat");
    let rendered = dir.path().join("blender.png");
    let started = Instant::now();
    let output = Command::new(root().join("tools/blender-check"))
        .arg(&baked)
        .arg(&rendered)
        .arg("--json")
        .output()
        .expect("run tools/blender-check");
    let stdout = show("blender-check", &output, started);
    let json = stdout
        .lines()
        .find_map(|line| line.strip_prefix("BLENDER_CHECK_JSON "))
        .expect("blender-check's JSON line");
    let seen: serde_json::Value = serde_json::from_str(json).expect("JSON");

    // Six mesh objects named after the walls, each with one 8-bit colour attribute whose
    // range is the range of its wall's element colours (8-bit sRGB storage: within 0.01).
    let objects = seen["objects"].as_array().expect("objects");
    assert_eq!(objects.len(), CUBE_WALLS.len(), "{seen:#}");
    for (node, wall) in CUBE_WALLS.iter().enumerate() {
        let object = objects
            .iter()
            .find(|o| o["name"] == *wall)
            .unwrap_or_else(|| panic!("no object {wall}"));
        assert_eq!(object["type"], "MESH");
        assert_eq!(object["uv_maps"], serde_json::json!([]), "{wall}");
        let colours = object["color_attributes"].as_array().expect("colours");
        assert_eq!(colours.len(), 1, "{wall}");
        let elements: Vec<[f64; 3]> = report
            .elements
            .iter()
            .filter(|e| report.polygons[e.polygon as usize].node == node)
            .map(|e| e.b.map(|v| v.clamp(0.0, 1.0)))
            .collect();
        for band in 0..3 {
            let lo = elements
                .iter()
                .map(|b| b[band])
                .fold(f64::INFINITY, f64::min);
            let hi = elements.iter().map(|b| b[band]).fold(0.0, f64::max);
            let rgba = &colours[0]["rgba"];
            let got_lo = rgba["min"][band].as_f64().expect("min");
            let got_hi = rgba["max"][band].as_f64().expect("max");
            assert!(
                (got_lo - lo).abs() < 0.01,
                "{wall} band {band}: {got_lo} vs {lo}"
            );
            assert!(
                (got_hi - hi).abs() < 0.01,
                "{wall} band {band}: {got_hi} vs {hi}"
            );
        }
    }
    let materials = seen["materials"].as_array().expect("materials");
    assert_eq!(materials.len(), 1);
    let nodes = materials[0]["node_types"].to_string();
    // KHR_materials_unlit arrives as an emission-based node tree fed by the vertex colours.
    assert!(
        nodes.contains("ShaderNodeEmission") && nodes.contains("ShaderNodeVertexColor"),
        "{nodes}"
    );

    // Blender's render (same framing camera) shows each element's colour where the
    // preview does.
    let image = read_png(&rendered);
    let camera = preview_camera(&baked, &preview::Options::default());
    let (checked, worst) = check_element_pixels(&image, &camera, &report, 1.0, "blender");
    println!("blender render: {checked} elements checked, largest difference {worst}/255");
}
