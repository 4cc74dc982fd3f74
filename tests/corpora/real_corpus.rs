//! Real models as they come (issue 29): every glTF 2.0 model of Debian's `assimp-testmodels`
//! (`/usr/share/assimp/models/glTF2`, installed by `tools/ci-clients`) is baked with
//! `--quality draft`, with a sun added where the model has no light (a scene without light
//! bakes to zeros and would test nothing). Each must bake (exit 0, OUT written) or be refused
//! with exactly one `bake: error:` line (exit 1, nothing written) within the time limit:
//! never a panic, a signal or a kill. The time, elements and peak memory of each are
//! printed; they are measured, not asserted (see docs/real-assets.md for the table).
//!
//! Without the package the test says `skipped: …` and passes, or fails with
//! `BAKE_REQUIRE_CORPUS=1` or `BAKE_REQUIRE_ALL=1` (as `.ci/run` sets).

use crate::common;

use bake_testkit::{files_with_extensions, glb, glb_chunks, skip, tools_dir};
use common::run_limited;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

const MODELS: &str = "/usr/share/assimp/models/glTF2";
/// Models baked without the added sun, and why: the lit bake is measured in
/// docs/real-assets.md, not run here.
const UNLIT: &[(&str, &str)] = &[
    (
        "2CylinderEngine.gltf",
        "the Draco copy of the 85 k-polygon engine below (decoded: KHR_draco_mesh_compression)",
    ),
    (
        "2CylinderEngine.glb",
        "an open 76 k-polygon engine: with a sun its draft bake takes 93 s on 2 cores, 80 s of \
     it linking (9.9 M links, 128 per element, where every part sees every other: issue 33's \
     cluster links), past the 60 s budget",
    ),
];
/// Wall-clock limit per model (the budget); the run is killed past it.
const TIME_LIMIT: Duration = Duration::from_secs(60);

/// Adds a directional light (a sun from above, slanted) to a glTF document that has no
/// `KHR_lights_punctual` light, as a node of its default scene. `false` when the document
/// has a light already or no scene to add it to.
fn add_sun(doc: &mut Value) -> bool {
    let has_lights = doc["extensions"]["KHR_lights_punctual"]["lights"]
        .as_array()
        .is_some_and(|l| !l.is_empty());
    if has_lights {
        return false;
    }
    let scene = doc["scene"].as_u64().unwrap_or(0) as usize;
    let Some(node_count) = doc["nodes"].as_array().map(Vec::len) else {
        return false;
    };
    if !doc["scenes"][scene]["nodes"].is_array() {
        return false;
    }
    let Some(root) = doc.as_object_mut() else {
        return false;
    };
    let used = root.entry("extensionsUsed").or_insert_with(|| json!([]));
    if let Some(used) = used.as_array_mut() {
        used.push(json!("KHR_lights_punctual"));
    }
    let extensions = root.entry("extensions").or_insert_with(|| json!({}));
    extensions["KHR_lights_punctual"] =
        json!({ "lights": [{ "type": "directional", "intensity": 1000.0, "name": "sun" }] });
    // Local −Z turned to (0.3, −1, 0.2) normalised.
    let rotation = common::aim([0.2792, -0.9307, 0.1861]);
    doc["nodes"].as_array_mut().expect("nodes").push(json!({
        "name": "sun",
        "rotation": rotation,
        "extensions": { "KHR_lights_punctual": { "light": 0 } }
    }));
    doc["scenes"][scene]["nodes"]
        .as_array_mut()
        .expect("scene nodes")
        .push(json!(node_count));
    true
}

/// The model's bytes with a sun added ([`add_sun`]), or `None` to bake it as it is (not
/// JSON, already lit, no scene).
fn with_sun(bytes: &[u8]) -> Option<Vec<u8>> {
    if bytes.starts_with(b"glTF") {
        // GLB: 12-byte header, JSON chunk, optional BIN chunk (glTF 2.0 "GLB File Format").
        let mut chunks = glb_chunks(bytes)?;
        let mut doc: Value = serde_json::from_slice(chunks.first()?.1).ok()?;
        if !add_sun(&mut doc) {
            return None;
        }
        let json = serde_json::to_vec(&doc).ok()?;
        chunks[0].1 = &json;
        Some(glb(&chunks))
    } else {
        let mut doc: Value = serde_json::from_slice(bytes).ok()?;
        add_sun(&mut doc).then(|| serde_json::to_vec_pretty(&doc).ok())?
    }
}

/// Copies `dir` (a model's folder: its buffers and images) into `to`, one level deep.
fn copy_folder(dir: &Path, to: &Path) {
    for entry in std::fs::read_dir(dir)
        .expect("list the model folder")
        .flatten()
    {
        let path = entry.path();
        if path.is_file() {
            std::fs::copy(&path, to.join(entry.file_name())).expect("copy a model file");
        }
    }
}

#[derive(Debug)]
enum Outcome {
    Baked { seconds: f64, summary: String },
    Refused { seconds: f64, line: String },
    Failed(String),
}

fn bake(input: &Path, out: &Path, report: &Path, options: &[&str], limit: Duration) -> Outcome {
    let mut command = Command::new(env!("CARGO_BIN_EXE_bake"));
    command
        .arg(input)
        .arg(out)
        .args(options)
        .arg("--report")
        .arg(report);
    let run = match run_limited(command, limit) {
        Ok(run) => run,
        Err(e) => return Outcome::Failed(format!("cannot run: {e}")),
    };
    let (seconds, stderr) = (run.seconds, run.stderr);
    let Some(status) = run.status else {
        return Outcome::Failed(format!("still running after {limit:?}: killed"));
    };
    let errors: Vec<&str> = stderr
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with("bake: warning:"))
        .collect();
    match status.code() {
        Some(0) if out.is_file() => {
            let summary = match bake_job::report::read_report(report) {
                Ok(r) => format!(
                    "{} elements, {} transport, peak {:.0} MiB, {} warnings",
                    r.counts.elements,
                    r.transport.kind.name(),
                    r.peak_rss_mib.values().copied().fold(0.0f64, f64::max),
                    r.warnings.len()
                ),
                Err(e) => format!("no report: {e}"),
            };
            Outcome::Baked { seconds, summary }
        }
        Some(1) if !out.exists() => match errors.as_slice() {
            [line] if line.starts_with("bake: error: ") => Outcome::Refused {
                seconds,
                line: line.to_string(),
            },
            _ => Outcome::Failed(format!("exit 1 without exactly one error line: {stderr:?}")),
        },
        code => Outcome::Failed(format!(
            "exit {code:?}, output written: {}: {stderr:?}",
            out.exists()
        )),
    }
}

#[test]
fn every_assimp_gltf2_model_bakes_or_is_refused_in_one_line() {
    let _alone = crate::one_at_a_time();
    corpus(&["--quality", "draft"], TIME_LIMIT, true);
}

/// The same models with default options (`--quality normal`), uncompressed, 10 minutes
/// each: the benchmark of docs/real-assets.md, run by hand with
/// `cargo test --release --test corpora -- --ignored --nocapture real_corpus::`.
#[test]
#[ignore]
fn default_options_benchmark() {
    let _alone = crate::one_at_a_time();
    corpus(&[], Duration::from_secs(600), false);
}

/// Bakes every model (with a sun where it has none) with `options` within `limit`, and with
/// `compressed` its meshopt and Draco copies; fails if any run neither bakes nor is refused
/// in one line.
fn corpus(options: &[&str], limit: Duration, compressed: bool) {
    let root = Path::new(MODELS);
    if !root.is_dir() {
        skip(
            "BAKE_REQUIRE_CORPUS",
            &format!("{MODELS} is not there (Debian's assimp-testmodels)"),
        );
        return;
    }
    let inputs = files_with_extensions(root, &["gltf", "glb"]);
    assert!(inputs.len() >= 40, "{} models", inputs.len());
    let mut failures = Vec::new();
    let (mut baked, mut refused) = (0, 0);
    for (k, input) in inputs.iter().enumerate() {
        let work = tempfile::tempdir().expect("tempdir");
        let folder = input.parent().expect("a folder");
        copy_folder(folder, work.path());
        let name = input.file_name().expect("a name");
        let copy = work.path().join(name);
        let bytes = std::fs::read(&copy).expect("read the model");
        let unlit = UNLIT.iter().find(|(file, _)| name.to_str() == Some(*file));
        if let Some((_, why)) = unlit {
            eprintln!("no sun for {}: {why}", name.to_string_lossy());
        }
        let sun = match with_sun(&bytes).filter(|_| unlit.is_none()) {
            Some(lit) => {
                std::fs::write(&copy, lit).expect("write the lit model");
                " (+sun)"
            }
            None => "",
        };
        let out = work.path().join(format!("baked-{k}.glb"));
        let report = work.path().join(format!("report-{k}.json"));
        let outcome = bake(&copy, &out, &report, options, limit);
        let shown = input
            .strip_prefix(root)
            .unwrap_or(input)
            .display()
            .to_string();
        let mut outcomes = vec![(shown.clone(), outcome)];
        // What web pipelines make of a model that reads: meshopt + quantised (gltfpack -c)
        // and Draco (Google's encoder through glTF-Transform), baked by the same rules.
        if compressed && matches!(outcomes[0].1, Outcome::Baked { .. }) {
            for (variant, encoded) in compressed_variants(&copy, work.path(), k) {
                let out = work.path().join(format!("baked-{k}-{variant}.glb"));
                let report = work.path().join(format!("report-{k}-{variant}.json"));
                let outcome = bake(&encoded, &out, &report, options, limit);
                outcomes.push((format!("{shown} [{variant}]"), outcome));
            }
        }
        for (shown, outcome) in outcomes {
            match &outcome {
                Outcome::Baked { seconds, summary } => {
                    baked += 1;
                    eprintln!("baked   {seconds:6.2} s {shown}{sun}: {summary}");
                }
                Outcome::Refused { seconds, line } => {
                    refused += 1;
                    eprintln!("refused {seconds:6.2} s {shown}{sun}: {line}");
                }
                Outcome::Failed(why) => failures.push(format!("{shown}{sun}: {why}")),
            }
        }
    }
    eprintln!(
        "{} models and their compressed copies: {baked} baked, {refused} refused, {} failed",
        inputs.len(),
        failures.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The compressed copies of `model` that the encoders here make: `meshopt` (Debian's gltfpack
/// `-c`: EXT_meshopt_compression + KHR_mesh_quantization) and `draco` (tools/draco-encode.mjs,
/// installed by tools/test). A missing encoder is skipped with a note (failing with
/// `BAKE_REQUIRE_ALL=1`); an encoder that cannot read the model makes no copy.
fn compressed_variants(model: &Path, dir: &Path, k: usize) -> Vec<(&'static str, PathBuf)> {
    let mut made = Vec::new();
    let packed = dir.join(format!("meshopt-{k}.glb"));
    match Command::new("gltfpack")
        .arg("-i")
        .arg(model)
        .arg("-o")
        .arg(&packed)
        .arg("-c")
        .output()
    {
        Ok(out) if out.status.success() && packed.is_file() => made.push(("meshopt", packed)),
        Ok(_) => eprintln!("gltfpack cannot read {}", model.display()),
        Err(e) => skip(
            "BAKE_REQUIRE_CORPUS",
            &format!("gltfpack does not run ({e}; tools/ci-clients installs it)"),
        ),
    }
    let tools = tools_dir();
    if tools.join(".draco/node_modules/draco3dgltf").is_dir() {
        let draco = dir.join(format!("draco-{k}.glb"));
        match Command::new("node")
            .arg(tools.join("draco-encode.mjs"))
            .arg(model)
            .arg(&draco)
            .output()
        {
            Ok(out) if out.status.success() && draco.is_file() => made.push(("draco", draco)),
            _ => eprintln!("the Draco encoder cannot read {}", model.display()),
        }
    } else {
        skip(
            "BAKE_REQUIRE_CORPUS",
            "Google's Draco encoder is not installed (tools/install-draco-encoder)",
        );
    }
    made
}
