//! Compressed and quantised glTF input (issue 29): the fixtures written with
//! `KHR_draco_mesh_compression` (by draco-core's encoder, inside the test) and with
//! `EXT_meshopt_compression` + `KHR_mesh_quantization` (by Debian's `gltfpack`, when
//! installed) load to the same polygons as the uncompressed files, within the quantisation
//! step.

mod draco_writer;

use bake_importer::{load, Scene};
use bake_testkit::{fixture, skip, tools_dir};
use draco_writer::float_attribute;
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;

/// Matches every polygon of `b` to a distinct polygon of `a` with an equal material (ρ and
/// emission) and
/// corner count whose corners are each within `tol` of one of the other's, and returns
/// the largest corner distance found. Panics when the scenes differ in polygon count or a
/// polygon has no match.
fn max_deviation(a: &Scene, b: &Scene, tol: f64) -> f64 {
    assert_eq!(a.polygons.len(), b.polygons.len(), "polygon counts differ");
    // gltfpack merges equal materials: polygons are matched by material values, not index.
    let look = |s: &Scene, m: usize| (s.materials[m].rho, s.materials[m].emission);
    let mut used = vec![false; a.polygons.len()];
    let mut worst: f64 = 0.0;
    for q in &b.polygons {
        let distance = |p: &bake_importer::Polygon| -> f64 {
            q.vertices
                .iter()
                .map(|v| {
                    p.vertices
                        .iter()
                        .map(|w| (*v - *w).length())
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(0.0, f64::max)
        };
        let best = a
            .polygons
            .iter()
            .enumerate()
            .filter(|(i, p)| {
                !used[*i]
                    && look(a, p.material) == look(b, q.material)
                    && p.vertices.len() == q.vertices.len()
            })
            .map(|(i, p)| (i, distance(p)))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        let Some((i, d)) = best else {
            panic!("no polygon matches {q:?}");
        };
        assert!(
            d <= tol,
            "polygon {q:?} is {d} from its match (tolerance {tol})"
        );
        used[i] = true;
        worst = worst.max(d);
    }
    worst
}

/// The largest extent of the scene's bounding box.
fn extent(scene: &Scene) -> f64 {
    let (lo, hi) = bake_importer::bounds(&scene.polygons);
    (hi - lo).max_element()
}

#[test]
fn draco_fixtures_decode_to_the_uncompressed_polygons() {
    for name in ["cube.gltf", "cornell.gltf", "two-rooms.gltf"] {
        let original = load(&fixture(name)).unwrap();
        let step = extent(&original) / f64::from((1 << 14) - 1);
        for speed in [10, 5] {
            let dir = tempfile::tempdir().unwrap();
            let path = draco_writer::write_draco(&fixture(name), dir.path(), 14, speed);
            let decoded = load(&path).unwrap_or_else(|e| panic!("{name} speed {speed}: {e}"));
            // Draco rounds each coordinate to the nearest of 2^14 levels over the box:
            // within half a step per axis.
            let worst = max_deviation(&original, &decoded, step * 0.5 * 3f64.sqrt());
            assert!(
                worst > 0.0 || name == "cube.gltf",
                "{name}: not quantised at all?"
            );
            eprintln!("{name} speed {speed}: max deviation {worst:.3e} (step {step:.3e})");
        }
    }
}

#[test]
fn draco_without_quantisation_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let original = load(&fixture("cornell.gltf")).unwrap();
    // 30 bits: below f32's own precision over the Cornell box's 559 units.
    let decoded = load(&draco_writer::write_draco(
        &fixture("cornell.gltf"),
        dir.path(),
        30,
        10,
    ))
    .unwrap();
    assert!(max_deviation(&original, &decoded, 1e-4) <= 1e-4);
}

#[test]
fn a_corrupt_draco_stream_is_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = draco_writer::write_draco(&fixture("cube.gltf"), dir.path(), 14, 10);
    let mut bytes = std::fs::read(dir.path().join("draco.bin")).unwrap();
    for b in bytes.iter_mut().skip(8) {
        *b = 0xff;
    }
    std::fs::write(dir.path().join("draco.bin"), bytes).unwrap();
    let error = load(&path).unwrap_err().to_string();
    assert!(error.contains("KHR_draco_mesh_compression"), "{error}");
    assert!(!error.contains('\n'), "{error}");
}

#[test]
fn an_unknown_required_extension_is_still_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = draco_writer::write_draco(&fixture("cube.gltf"), dir.path(), 14, 10);
    let mut json: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    json["extensionsRequired"]
        .as_array_mut()
        .unwrap()
        .push(json!("EXT_made_up"));
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let error = load(&path).unwrap_err().to_string();
    assert!(error.contains("EXT_made_up"), "{error}");
    assert!(!error.contains("KHR_draco"), "{error}");
}

/// Runs gltfpack, or says why the test is skipped (a failure under BAKE_REQUIRE_ALL=1).
fn gltfpack(input: &Path, output: &Path, args: &[&str]) -> bool {
    let run = Command::new("gltfpack")
        .arg("-i")
        .arg(input)
        .arg("-o")
        .arg(output)
        .args(args)
        .output();
    match run {
        Ok(out) if out.status.success() => true,
        Ok(out) => panic!("gltfpack failed: {}", String::from_utf8_lossy(&out.stderr)),
        Err(e) => {
            skip(
                "BAKE_REQUIRE_GLTFPACK",
                &format!("gltfpack does not run ({e}; tools/ci-clients installs it)"),
            );
            false
        }
    }
}

#[test]
fn meshopt_fixtures_decode_to_the_uncompressed_polygons() {
    for name in ["cube.gltf", "cornell.gltf", "two-rooms.gltf"] {
        let original = load(&fixture(name)).unwrap();
        let dir = tempfile::tempdir().unwrap();
        // Meshopt without quantisation is lossless: the same f32 positions.
        let exact = dir.path().join("noq.glb");
        if !gltfpack(&fixture(name), &exact, &["-c", "-noq"]) {
            return;
        }
        let decoded = load(&exact).unwrap();
        assert_eq!(max_deviation(&original, &decoded, 0.0), 0.0, "{name}");

        // gltfpack's default quantisation: 14-bit positions over the mesh's box, the scale
        // in the node transform (KHR_mesh_quantization), plus meshopt; and quantisation
        // alone.
        let step = extent(&original) / f64::from((1 << 14) - 1);
        for (file, args) in [("cq.glb", &["-c"][..]), ("q.gltf", &[][..])] {
            let path = dir.path().join(file);
            assert!(gltfpack(&fixture(name), &path, args));
            let json = std::fs::read(&path).unwrap();
            let text = String::from_utf8_lossy(&json);
            assert!(text.contains("\"KHR_mesh_quantization\""), "{name} {file}");
            let decoded = load(&path).unwrap_or_else(|e| panic!("{name} {file}: {e}"));
            let worst = max_deviation(&original, &decoded, step * 3f64.sqrt());
            eprintln!("{name} {file}: max deviation {worst:.3e} (step {step:.3e})");
        }
    }
}

/// The textured square's texture coordinates (unlike its positions, so a reader that took
/// one attribute for the other would be caught).
const UVS: [[f32; 2]; 4] = [[0.1, 0.2], [0.9, 0.2], [0.9, 0.7], [0.1, 0.7]];

/// A textured unit square whose base colour texture carries `extension` (KTX2 or WebP image
/// 1), with `fallback` a PNG `source` (image 0) or none; the extension is required.
fn textured_square(extension: &str, fallback: bool) -> bake_testkit::GltfBuilder {
    let mut b = bake_testkit::GltfBuilder::new();
    let square = [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let position = b.positions(&square);
    let uv: Vec<u8> = UVS.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
    let uv = b.accessor(&uv, bake_testkit::FLOAT, "VEC2", 4, json!({}));
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let material = b.material(json!({
        "name": "Painted",
        "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } }
    }));
    let mesh = b.mesh(
        "Square",
        vec![json!({
            "attributes": { "POSITION": position, "TEXCOORD_0": uv },
            "indices": indices, "material": material
        })],
    );
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    let mut png = Vec::new();
    image::DynamicImage::ImageRgb8(image::RgbImage::from_pixel(2, 2, image::Rgb([200, 30, 30])))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let png = format!("data:image/png;base64,{}", bake_testkit::base64(&png));
    b.root["images"] = json!([{ "uri": png }, { "uri": "data:image/ktx2;base64,AAAA" }]);
    let mut texture = json!({ "name": "Paint", "extensions": { extension: { "source": 1 } } });
    if fallback {
        texture["source"] = json!(0);
    }
    b.root["textures"] = json!([texture]);
    b.root["extensionsUsed"] = json!([extension]);
    b.root["extensionsRequired"] = json!([extension]);
    b
}

#[test]
fn a_texture_without_a_png_or_jpeg_fallback_is_refused_by_extension() {
    for extension in ["KHR_texture_basisu", "EXT_texture_webp"] {
        let dir = tempfile::tempdir().unwrap();
        let path = textured_square(extension, false).write_embedded(&dir.path().join("s.gltf"));
        let started = std::time::Instant::now();
        let error = load(&path).unwrap_err().to_string();
        assert!(started.elapsed().as_secs_f64() < 0.5);
        eprintln!("{error}");
        assert!(error.contains(extension), "{error}");
        assert!(error.contains("texture \"Paint\""), "{error}");
        assert!(error.contains("material \"Painted\""), "{error}");
        assert!(!error.contains('\n'), "{error}");
    }
}

#[test]
fn a_texture_with_a_png_fallback_uses_it() {
    for extension in ["KHR_texture_basisu", "EXT_texture_webp"] {
        let dir = tempfile::tempdir().unwrap();
        let path = textured_square(extension, true).write_embedded(&dir.path().join("s.gltf"));
        let scene = load(&path).unwrap_or_else(|e| panic!("{extension}: {e}"));
        assert_eq!(scene.polygons.len(), 1);
        assert_eq!(scene.textures.len(), 1);
        assert!(scene.materials[0].base_color_texture.is_some());
        assert_eq!(scene.authored.images.len(), 1);
        assert_eq!(scene.authored.images[0].mime_type, "image/png");
    }
}

#[test]
fn mutated_draco_streams_fail_without_panicking() {
    // Every byte of a Draco stream overwritten in turn with three values: each load
    // returns (Ok or a one-line error); none panics or hangs.
    let dir = tempfile::tempdir().unwrap();
    let path = draco_writer::write_draco(&fixture("cornell.gltf"), dir.path(), 14, 5);
    let bin = dir.path().join("draco.bin");
    let original = std::fs::read(&bin).unwrap();
    let mut errors = 0;
    for at in (0..original.len()).step_by(3) {
        for value in [0x00, 0x7f, 0xff] {
            let mut bytes = original.clone();
            bytes[at] = value;
            std::fs::write(&bin, &bytes).unwrap();
            if let Err(e) = load(&path) {
                assert!(!e.to_string().contains('\n'), "{e}");
                errors += 1;
            }
        }
    }
    assert!(errors > 0);
}

#[test]
fn draco_texture_coordinates_come_from_the_attribute_the_extension_names() {
    use draco_core::{
        EncoderBuffer, EncoderOptions, GeometryAttributeType, Mesh, MeshEncoder, PointIndex,
    };
    let dir = tempfile::tempdir().unwrap();
    let b = textured_square("KHR_texture_basisu", true);
    let plain = load(&b.write_embedded(&dir.path().join("plain.gltf"))).unwrap();

    // The same square, Draco-compressed: TEXCOORD_0 is attribute 0 and POSITION attribute
    // 1 in the stream, with 12-bit texture coordinates.
    let square = [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let mut mesh = Mesh::new();
    let uv_id = mesh.add_attribute(float_attribute(GeometryAttributeType::TexCoord, &UVS));
    let position_id = mesh.add_attribute(float_attribute(GeometryAttributeType::Position, &square));
    for t in [[0, 1, 2], [0, 2, 3]] {
        mesh.add_face(t.map(PointIndex));
    }
    let mut options = EncoderOptions::new();
    options.set_attribute_int(position_id, "quantization_bits", 14);
    options.set_attribute_int(uv_id, "quantization_bits", 12);
    options.set_global_int("encoding_speed", 10);
    let mut encoder = MeshEncoder::new();
    encoder.set_mesh(mesh);
    let mut out = EncoderBuffer::new();
    encoder.encode(&options, &mut out).unwrap();

    let mut b = b;
    let view = b.view(out.data());
    let accessors = b.root["accessors"].as_array_mut().unwrap();
    accessors.push(json!({"componentType": 5126, "count": 4, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]}));
    accessors.push(json!({"componentType": 5126, "count": 4, "type": "VEC2"}));
    accessors.push(json!({"componentType": 5125, "count": 6, "type": "SCALAR"}));
    let n = accessors.len();
    let primitive = &mut b.root["meshes"][0]["primitives"][0];
    primitive["attributes"] = json!({ "POSITION": n - 3, "TEXCOORD_0": n - 2 });
    primitive["indices"] = json!(n - 1);
    primitive["extensions"] = json!({ "KHR_draco_mesh_compression": {
        "bufferView": view, "attributes": { "POSITION": 1, "TEXCOORD_0": 0 }
    }});
    b.root["extensionsRequired"] = json!(["KHR_texture_basisu", "KHR_draco_mesh_compression"]);
    let draco = load(&b.write_embedded(&dir.path().join("draco.gltf"))).unwrap();

    assert_eq!(max_deviation(&plain, &draco, 1e-4), 0.0);
    let corners = |s: &Scene| -> Vec<(glam::DVec3, glam::DVec2)> {
        let mut v: Vec<_> = s.uvs[0]
            .as_ref()
            .expect("a textured polygon")
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(|k| (t.positions[k], t.uv[0][k])))
            .collect();
        v.sort_by(|a, b| a.0.to_array().partial_cmp(&b.0.to_array()).unwrap());
        v
    };
    let (a, b) = (corners(&plain), corners(&draco));
    assert_eq!(a.len(), 6);
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.0, y.0);
        // Each position has one texture coordinate here; 12 bits over the UVs' range.
        assert!(
            (x.1 - y.1).abs().max_element() <= 0.5 / 4095.0,
            "{x:?} vs {y:?}"
        );
    }
}

#[test]
fn reference_encoder_draco_files_decode_to_the_uncompressed_polygons() {
    // Files from Google's encoder (draco3dgltf 1.5.7 through glTF-Transform, as
    // tools/install-draco-encoder installs): 14-bit positions, NORMAL as attribute 0 and
    // POSITION as attribute 1.
    let tools = tools_dir();
    let installed = tools
        .join(".draco/node_modules/draco3dgltf/package.json")
        .is_file();
    if !installed {
        skip(
            "BAKE_REQUIRE_DRACO_ENCODER",
            "the reference Draco encoder is not installed (tools/install-draco-encoder)",
        );
        return;
    }
    // Edgebreaker reorders faces, and the importer merges a quad only from consecutive
    // triangles: on two-rooms it leaves 2 quads as 4 triangles, so that one is compared
    // with sequential coding only.
    let cases = [
        ("cube.gltf", "edgebreaker"),
        ("cornell.gltf", "edgebreaker"),
        ("cornell.gltf", "sequential"),
        ("two-rooms.gltf", "sequential"),
    ];
    for (name, method) in cases {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("draco.glb");
        let run = Command::new("node")
            .arg(tools.join("draco-encode.mjs"))
            .arg(fixture(name))
            .arg(&out)
            .arg(method)
            .output()
            .expect("run node");
        assert!(run.status.success(), "{run:?}");
        let original = load(&fixture(name)).unwrap();
        let step = extent(&original) / f64::from((1 << 14) - 1);
        let decoded = load(&out).unwrap_or_else(|e| panic!("{name} {method}: {e}"));
        let worst = max_deviation(&original, &decoded, step * 0.5 * 3f64.sqrt());
        eprintln!("{name} {method}: max deviation {worst:.3e} (step {step:.3e})");
    }
}

/// The `draco` fuzz target's GLB (`bake_importer::fuzzing::draco_glb`) takes a valid stream to
/// the decoder and through it: a triangle encoded by draco-core loads as one polygon (so the
/// fuzzer's inputs reach the Draco decoder, not a JSON error before it).
#[test]
fn the_draco_fuzz_harness_reaches_the_decoder() {
    use draco_core::{
        EncoderBuffer, EncoderOptions, GeometryAttributeType, Mesh, MeshEncoder, PointIndex,
    };
    let mut mesh = Mesh::new();
    let triangle = [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]];
    let id = mesh.add_attribute(float_attribute(GeometryAttributeType::Position, &triangle));
    mesh.add_face([0, 1, 2].map(PointIndex));
    let mut options = EncoderOptions::new();
    options.set_attribute_int(id, "quantization_bits", 14);
    let mut encoder = MeshEncoder::new();
    encoder.set_mesh(mesh);
    let mut out = EncoderBuffer::new();
    encoder.encode(&options, &mut out).unwrap();

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("draco.glb");
    std::fs::write(&path, bake_importer::fuzzing::draco_glb(out.data())).unwrap();
    let scene = load(&path).expect("the harness's GLB with a valid stream loads");
    assert_eq!(scene.polygons.len(), 1);
    // And a corrupt one is an error, not a panic.
    bake_importer::fuzzing::draco(&out.data()[..out.data().len() / 2]);
}

/// The `meshopt` fuzz target's GLB (`bake_importer::fuzzing::meshopt_glb`) takes its input to
/// the meshopt decoder: a stream that is not one is refused by the decoder (its error names
/// the extension and the view), not by the JSON before it, in each of the three modes.
#[test]
fn the_meshopt_fuzz_harness_reaches_the_decoder() {
    let dir = tempfile::tempdir().unwrap();
    for pick in [0u8, 1, 2] {
        let mut input = vec![pick, 5, 0];
        input.extend_from_slice(&[0x55; 40]);
        let path = dir.path().join(format!("meshopt{pick}.glb"));
        std::fs::write(&path, bake_importer::fuzzing::meshopt_glb(&input)).unwrap();
        let error = load(&path).expect_err("not a meshopt stream").to_string();
        assert!(
            error.contains("buffer view 0 (EXT_meshopt_compression)"),
            "mode {pick}: {error}"
        );
        bake_importer::fuzzing::meshopt(&input);
    }
}

/// A 72-byte Draco stream (found by `tools/fuzz draco`) declaring 1.98 M points, 194 MB of
/// sequential values: the decoder took 1.0–1.6 s over it before the importer refused it.
/// Now the limits scale with the stream's size and refuse it from its header.
#[test]
fn a_tiny_draco_stream_declaring_millions_of_points_is_refused_from_its_header() {
    let bytes = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/regressions/draco-many-points-1.draco-bytes"
    ))
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("draco.glb");
    std::fs::write(&path, bake_importer::fuzzing::draco_glb(&bytes)).unwrap();
    let error = load(&path).expect_err("refused").to_string();
    assert!(error.contains("Decode limit exceeded"), "{error}");
    assert!(!error.contains('\n'), "{error}");
}
