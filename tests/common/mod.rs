//! Helpers shared by the CLI's end-to-end tests: running the `bake` binary, listing output
//! directories, and writing small (often deliberately broken) glTF and OBJ inputs.

#![allow(dead_code)]

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
/// counts, closed forms per element); `tests/refine.rs` bakes with the defaults through
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

/// `fixtures/<name>` in the workspace.
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// The names of everything in `dir` (hidden files included), sorted.
pub fn file_names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("list the directory")
        .map(|entry| {
            entry
                .expect("a directory entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    names.sort();
    names
}

/// A bake report with `timings` and `peak_rss_mib` (the only parts that may change between
/// runs) removed.
pub fn report_without_timings(path: &Path) -> exporter::report::Report {
    let mut report = exporter::report::read_report(path).expect("read the bake report");
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

/// Standard base64 with padding (RFC 4648), for `data:` URIs.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

pub fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64(bytes))
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

/// Little-endian f32 bytes of the positions.
pub fn position_bytes(positions: &[[f32; 3]]) -> Vec<u8> {
    positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// Component-wise min and max over the finite values (glTF requires POSITION bounds; a
/// NaN can't be written in JSON, so the bounds of a poisoned buffer skip it).
fn finite_bounds(positions: &[[f32; 3]]) -> (Value, Value) {
    let mut min = [0.0f32; 3];
    let mut max = [0.0f32; 3];
    for axis in 0..3 {
        let finite = positions.iter().map(|p| p[axis]).filter(|v| v.is_finite());
        min[axis] = finite.clone().fold(f32::INFINITY, f32::min);
        max[axis] = finite.fold(f32::NEG_INFINITY, f32::max);
    }
    (json!(min), json!(max))
}

/// A one-mesh glTF: node "wall" → mesh "wall" with one non-indexed primitive of `mode`
/// (4 = TRIANGLES, 0 = POINTS) over `positions`, stored in buffer 0 as a data URI. With
/// `material`, it becomes material 0 and the primitive uses it.
pub struct GltfBuilder {
    pub positions: Vec<[f32; 3]>,
    pub mode: u32,
    pub material: Option<Value>,
}

impl GltfBuilder {
    pub fn triangles(positions: &[[f32; 3]]) -> Self {
        GltfBuilder {
            positions: positions.to_vec(),
            mode: 4,
            material: None,
        }
    }

    pub fn mode(mut self, mode: u32) -> Self {
        self.mode = mode;
        self
    }

    pub fn material(mut self, material: Value) -> Self {
        self.material = Some(material);
        self
    }

    /// The document, with the buffer stored at `uri`.
    pub fn json_with_buffer_uri(&self, uri: &str) -> Value {
        let bytes = position_bytes(&self.positions);
        let (min, max) = finite_bounds(&self.positions);
        let mut primitive = json!({ "attributes": { "POSITION": 0 }, "mode": self.mode });
        let mut root = json!({
            "asset": { "version": "2.0" },
            "scene": 0,
            "scenes": [{ "nodes": [0] }],
            "nodes": [{ "name": "wall", "mesh": 0 }],
            "accessors": [{
                "bufferView": 0, "componentType": 5126, "count": self.positions.len(),
                "type": "VEC3", "min": min, "max": max
            }],
            "bufferViews": [{ "buffer": 0, "byteLength": bytes.len() }],
            "buffers": [{ "byteLength": bytes.len(), "uri": uri }],
        });
        if let Some(material) = &self.material {
            primitive["material"] = json!(0);
            root["materials"] = json!([material]);
        }
        root["meshes"] = json!([{ "name": "wall", "primitives": [primitive] }]);
        root
    }

    /// The document with its buffer embedded as a data URI.
    pub fn json(&self) -> Value {
        self.json_with_buffer_uri(&data_uri(&position_bytes(&self.positions)))
    }

    /// Writes `path` with an embedded buffer.
    pub fn write(&self, path: &Path) {
        write_json(path, &self.json());
    }
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

/// Writes `doc` as `dir/NAME.gltf`, bakes it (`--target vertex`, a report, `--quiet`, then
/// `args`), asserts exit 0 and returns the report.
pub fn bake_json(dir: &Path, name: &str, doc: &Value, args: &[&str]) -> exporter::report::Report {
    bake_json_with(dir, name, doc, args, false)
}

/// [`bake_json`] with the bake's own defaults (refinement on unless `args` say otherwise).
pub fn bake_json_default(
    dir: &Path,
    name: &str,
    doc: &Value,
    args: &[&str],
) -> exporter::report::Report {
    bake_json_with(dir, name, doc, args, true)
}

fn bake_json_with(
    dir: &Path,
    name: &str,
    doc: &Value,
    args: &[&str],
    defaults: bool,
) -> exporter::report::Report {
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
    exporter::report::read_report(&report).expect("read the report")
}

/// The repository's `tools/` directory.
pub fn tools_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tools")
}

/// Whether `node` runs and `tools/install-validator` has installed the Khronos validator.
pub fn validator_available() -> bool {
    let installed = tools_dir()
        .join(".validator/node_modules/gltf-validator/package.json")
        .is_file();
    let node_runs = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|output| output.status.success());
    installed && node_runs
}

/// Whether the test that needs what `variable` names must run: `variable=1`, or
/// `BAKE_REQUIRE_ALL=1` (as `.ci/run` sets).
pub fn required(variable: &str) -> bool {
    let set = |name: &str| std::env::var(name).is_ok_and(|v| v == "1");
    set(variable) || set("BAKE_REQUIRE_ALL")
}

/// A test that cannot run here because `why` (e.g. "the validator is not installed"): fails
/// when [`required`]`(variable)`, else says `skipped: …` on stderr. Written straight to the
/// process's stderr, past libtest's capture of `print!`/`eprint!`, so `cargo test` shows
/// it even when the test passes.
pub fn skip(variable: &str, why: &str) {
    assert!(
        !required(variable),
        "{variable}=1 (or BAKE_REQUIRE_ALL=1) but {why}"
    );
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr(),
        "skipped: {} ({why}; {variable}=1 makes it fail)",
        std::thread::current().name().unwrap_or("a test")
    );
}

/// Whether `blender` runs.
pub fn blender_installed() -> bool {
    Command::new("blender")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs the Khronos validator (`node tools/validate.mjs`) on `files` and returns its output,
/// asserting that every file has 0 errors and 0 warnings. `None` (with a message) when the
/// validator is not installed, unless `BAKE_REQUIRE_VALIDATOR=1`.
pub fn validate_clean(files: &[PathBuf]) -> Option<String> {
    if !validator_available() {
        let required = std::env::var("BAKE_REQUIRE_VALIDATOR").is_ok_and(|v| v == "1");
        assert!(
            !required,
            "BAKE_REQUIRE_VALIDATOR=1 but the validator is not installed"
        );
        eprintln!("skipped the validator: not installed (run tools/install-validator)");
        return None;
    }
    let output = Command::new("node")
        .arg(tools_dir().join("validate.mjs"))
        .args(files)
        .output()
        .expect("run node tools/validate.mjs");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let summaries: Vec<&str> = stdout.lines().filter(|l| !l.starts_with(' ')).collect();
    assert_eq!(summaries.len(), files.len(), "{stdout}");
    for line in &summaries {
        assert!(line.contains(": 0 errors, 0 warnings, "), "{stdout}");
    }
    assert!(output.status.success(), "{stdout}");
    Some(stdout)
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

/// Files under `dir` (recursively) whose extension, lower-cased, is one of `extensions`,
/// sorted (for the corpus tests).
pub fn files_with_extensions(dir: &Path, extensions: &[&str]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for path in entries.flatten().map(|e| e.path()) {
            if path.is_dir() {
                stack.push(path);
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| extensions.contains(&e.to_ascii_lowercase().as_str()))
            {
                found.push(path);
            }
        }
    }
    found.sort();
    found
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
