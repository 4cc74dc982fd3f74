//! Helpers shared by the CLI's end-to-end tests: running the `bake` binary and writing small
//! (often deliberately broken) glTF and OBJ inputs. What other packages' tests need too (the
//! glTF builder, base64, fixtures, skipping) is in `bake-testkit`.

#![allow(dead_code)]

use bake_testkit::{base64, data_uri, fixture, position_bytes};
use serde_json::{json, Value};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The paper's cube: six unit walls, one emitter (e = 1, ρ = 0), two coloured side walls.
pub const CUBE_WALLS: [&str; 6] = ["emitter", "back", "red", "blue", "floor", "ceiling"];

/// What one run of `bake` did.
#[derive(Debug)]
pub struct Run {
    /// The exit code (`None` when killed by a signal).
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

impl Run {
    /// stderr lines that are not warnings (trimmed, blank lines left out).
    pub fn error_lines(&self) -> Vec<&str> {
        self.stderr
            .trim()
            .lines()
            .map(str::trim)
            .filter(|line| !line.is_empty() && !line.starts_with("bake: warning:"))
            .collect()
    }

    /// stderr lines that are warnings.
    pub fn warning_lines(&self) -> Vec<&str> {
        self.stderr
            .lines()
            .filter(|line| line.starts_with("bake: warning:"))
            .collect()
    }

    /// Asserts exit 0 and returns self.
    pub fn success(self) -> Run {
        assert_eq!(self.code, Some(0), "bake failed: {self:#?}");
        self
    }
}

/// Runs the `bake` binary with `args` in the current directory.
pub fn bake<I, S>(args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    bake_in(None, args)
}

/// Runs the `bake` binary with `args`, in `dir` when given. A bake that does not say
/// `--refine` gets `--refine off`: these tests check the uniform mesh they ask for (element
/// counts, closed forms per element); `tests/end_to_end/refine.rs` bakes with the defaults through
/// [`bake_default_in`].
pub fn bake_in<I, S>(dir: Option<&Path>, args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let mut args: Vec<std::ffi::OsString> = args
        .into_iter()
        .map(|a| a.as_ref().to_os_string())
        .collect();
    let says = |flags: &[&str]| args.iter().any(|a| flags.iter().any(|f| a == f));
    let preview = args.first().is_some_and(|a| a == "preview");
    if !preview && !says(&["--refine", "--help", "-h", "--version", "-V"]) {
        args.extend(["--refine".into(), "off".into()]);
    }
    bake_default_in(dir, args)
}

/// Runs the `bake` binary with exactly `args` (the bake's own defaults), in `dir` when given.
pub fn bake_default_in<I, S>(dir: Option<&Path>, args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let mut command = Command::new(env!("CARGO_BIN_EXE_bake"));
    command.args(args);
    if let Some(dir) = dir {
        command.current_dir(dir);
    }
    let output = command.output().expect("run the bake binary");
    Run {
        code: output.status.code(),
        stdout: String::from_utf8_lossy(&output.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
    }
}

/// A bake report with `timings` and `peak_rss_mib` (the only parts that may change between
/// runs) removed.
pub fn report_without_timings(path: &Path) -> bake_job::report::Report {
    let mut report = bake_job::report::read_report(path).expect("read the bake report");
    report.timings.clear();
    report.peak_rss_mib.clear();
    report
}

pub fn write_text(path: &Path, text: &str) {
    std::fs::write(path, text).expect("write a test input");
}

pub fn write_json(path: &Path, value: &Value) {
    let text = serde_json::to_string_pretty(value).expect("encode JSON");
    write_text(path, &text);
}

/// `image` encoded as a PNG data URI (for textures embedded in written glTF).
pub fn png_data_uri(image: image::DynamicImage) -> String {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .expect("encode a PNG");
    format!("data:image/png;base64,{}", base64(&bytes))
}

/// A unit right triangle in z = 0, counter-clockwise about +z.
pub const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// An OBJ "wall" (one triangle, positions given as text so `nan` can be written) using
/// material "paint" from `<stem>.mtl`, whose body is `mtl_body`.
pub fn write_obj_with_material(dir: &Path, stem: &str, mtl_body: &str) -> PathBuf {
    let obj = dir.join(format!("{stem}.obj"));
    write_text(
        &obj,
        &format!("mtllib {stem}.mtl\no wall\nusemtl paint\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
    );
    write_text(
        &dir.join(format!("{stem}.mtl")),
        &format!("newmtl paint\n{mtl_body}\n"),
    );
    obj
}

/// The fixture `cube-embedded.gltf` with one more node, "sliver", whose mesh "sliver" is a
/// single zero-area triangle (three collinear points inside the cube), appended to the scene.
pub fn cube_with_sliver_json() -> Value {
    let text = std::fs::read_to_string(fixture("cube-embedded.gltf")).expect("read the fixture");
    let mut root: Value = serde_json::from_str(&text).expect("the fixture is JSON");
    let sliver: [[f32; 3]; 3] = [[0.25, 0.25, 0.25], [0.5, 0.5, 0.5], [0.75, 0.75, 0.75]];
    let bytes = position_bytes(&sliver);
    let buffer = push(
        &mut root["buffers"],
        json!({ "byteLength": bytes.len(), "uri": data_uri(&bytes) }),
    );
    let view = push(
        &mut root["bufferViews"],
        json!({ "buffer": buffer, "byteLength": bytes.len() }),
    );
    let accessor = push(
        &mut root["accessors"],
        json!({
            "bufferView": view, "componentType": 5126, "count": 3, "type": "VEC3",
            "min": [0.25, 0.25, 0.25], "max": [0.75, 0.75, 0.75]
        }),
    );
    let mesh = push(
        &mut root["meshes"],
        json!({ "name": "sliver", "primitives": [{ "attributes": { "POSITION": accessor }, "material": 1 }] }),
    );
    let node = push(
        &mut root["nodes"],
        json!({ "name": "sliver", "mesh": mesh }),
    );
    let scene = root["scene"].as_u64().unwrap_or(0) as usize;
    push(&mut root["scenes"][scene]["nodes"], json!(node));
    root
}

/// Appends `value` to the JSON array `array` and returns its index.
fn push(array: &mut Value, value: Value) -> usize {
    let array = array.as_array_mut().expect("a JSON array");
    array.push(value);
    array.len() - 1
}

/// Bakes `input` once per thread count (`--quiet --threads N`, then `args`) into
/// `dir/threads-N/out.gltf` (the same file name each time: a glTF names its buffer file) and
/// asserts that the outputs with the extensions `exts` are the same bytes every time.
pub fn assert_same_bytes_for_thread_counts(
    dir: &Path,
    input: &Path,
    threads: &[&str],
    args: &[&str],
    exts: &[&str],
) {
    let outputs: Vec<Vec<Vec<u8>>> = threads
        .iter()
        .map(|threads| {
            let folder = dir.join(format!("threads-{threads}"));
            std::fs::create_dir(&folder).expect("a folder");
            let out = folder.join("out.gltf");
            let mut all: Vec<&OsStr> = vec!["--quiet".as_ref(), "--threads".as_ref()];
            all.push(OsStr::new(threads));
            all.extend(args.iter().map(OsStr::new));
            all.extend([input.as_os_str(), out.as_os_str()]);
            bake(all).success();
            exts.iter()
                .map(|ext| std::fs::read(out.with_extension(ext)).expect("an output"))
                .collect()
        })
        .collect();
    assert!(
        outputs.iter().all(|o| o == &outputs[0]),
        "the outputs differ between thread counts {threads:?}"
    );
}

/// Writes `doc` as `dir/NAME.gltf`, bakes it (`--target vertex`, a report, `--quiet`, then
/// `args`), asserts exit 0 and returns the report.
pub fn bake_json(dir: &Path, name: &str, doc: &Value, args: &[&str]) -> bake_job::report::Report {
    bake_json_with(dir, name, doc, args, false)
}

/// [`bake_json`] with the bake's own defaults (refinement on unless `args` say otherwise).
pub fn bake_json_default(
    dir: &Path,
    name: &str,
    doc: &Value,
    args: &[&str],
) -> bake_job::report::Report {
    bake_json_with(dir, name, doc, args, true)
}

fn bake_json_with(
    dir: &Path,
    name: &str,
    doc: &Value,
    args: &[&str],
    defaults: bool,
) -> bake_job::report::Report {
    let input = dir.join(format!("{name}.gltf"));
    write_json(&input, doc);
    let out = dir.join(format!("{name}-out.gltf"));
    let report = dir.join(format!("{name}.json"));
    let mut all: Vec<&OsStr> = vec![
        "--quiet".as_ref(),
        "--target".as_ref(),
        "vertex".as_ref(),
        input.as_os_str(),
        out.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
    ];
    all.extend(args.iter().map(OsStr::new));
    if defaults {
        bake_default_in(None, all).success();
    } else {
        bake(all).success();
    }
    bake_job::report::read_report(&report).expect("read the report")
}

/// A glTF scene: one mesh per (triangles, baseColor) and one light node per light
/// `(light json, node json without the extension)`.
pub fn lit_scene(meshes: &[(Vec<[f32; 3]>, [f64; 3])], lights: &[(Value, Value)]) -> Value {
    let mut bytes = Vec::new();
    let mut accessors = Vec::new();
    let mut views = Vec::new();
    let mut gltf_meshes = Vec::new();
    let mut materials = Vec::new();
    let mut nodes = Vec::new();
    for (k, (positions, rho)) in meshes.iter().enumerate() {
        let offset = bytes.len();
        for p in positions {
            for v in p {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        let mut min = [f32::INFINITY; 3];
        let mut max = [f32::NEG_INFINITY; 3];
        for p in positions {
            for a in 0..3 {
                min[a] = min[a].min(p[a]);
                max[a] = max[a].max(p[a]);
            }
        }
        views
            .push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": positions.len() * 12 }));
        accessors.push(
            json!({ "bufferView": k, "componentType": 5126, "count": positions.len(),
                               "type": "VEC3", "min": min, "max": max }),
        );
        materials.push(json!({ "pbrMetallicRoughness": {
            "baseColorFactor": [rho[0], rho[1], rho[2], 1.0], "metallicFactor": 0.0 } }));
        gltf_meshes
            .push(json!({ "primitives": [{ "attributes": { "POSITION": k }, "material": k }] }));
        nodes.push(json!({ "name": format!("mesh{k}"), "mesh": k }));
    }
    let mut light_defs = Vec::new();
    for (k, (light, node)) in lights.iter().enumerate() {
        let mut node = node.clone();
        node["name"] = json!(format!("light{k}"));
        node["extensions"] = json!({ "KHR_lights_punctual": { "light": k } });
        nodes.push(node);
        light_defs.push(light.clone());
    }
    let roots: Vec<usize> = (0..nodes.len()).collect();
    json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensionsRequired": ["KHR_lights_punctual"],
        "extensions": { "KHR_lights_punctual": { "lights": light_defs } },
        "scene": 0,
        "scenes": [{ "nodes": roots }],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bytes.len(), "uri": data_uri(&bytes) }],
    })
}

/// Rotation (x, y, z, w) taking the light's local −Z to the unit vector `d`.
pub fn aim(d: [f64; 3]) -> [f64; 4] {
    // q = normalize(a × d, 1 + a · d) with a = (0, 0, −1).
    let (x, y, z, w) = (d[1], -d[0], 0.0, 1.0 - d[2]);
    let n = (x * x + y * y + z * z + w * w).sqrt();
    [x / n, y / n, z / n, w / n]
}

/// How a run under [`run_limited`] ended.
pub struct Limited {
    /// `None` when it ran past the limit and was killed.
    pub status: Option<std::process::ExitStatus>,
    pub stderr: String,
    pub seconds: f64,
}

/// Runs `command` (stdin and stdout null, stderr captured on a thread so a chatty child never
/// blocks on a full pipe), killing it past `limit`.
pub fn run_limited(
    mut command: Command,
    limit: std::time::Duration,
) -> Result<Limited, std::io::Error> {
    use std::process::Stdio;
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()?;
    let stderr = child.stderr.take();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        if let Some(mut stderr) = stderr {
            let _ = std::io::Read::read_to_string(&mut stderr, &mut text);
        }
        text
    });
    let started = std::time::Instant::now();
    let status = loop {
        match child.try_wait()? {
            Some(status) => break Some(status),
            None if started.elapsed() > limit => {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            None => std::thread::sleep(std::time::Duration::from_millis(10)),
        }
    };
    let seconds = started.elapsed().as_secs_f64();
    Ok(Limited {
        status,
        stderr: reader.join().unwrap_or_default(),
        seconds,
    })
}
