//! Issue 34 ("Reliability, round 3"), item 5: bad input gives one line that names the
//! material, the buffer or its URI, and the container's actual problem.

use bake_importer::{load_bytes, load_obj_bytes, Format, ImportError};
use bake_testkit::{glb, GltfBuilder, GLB_BIN, GLB_JSON, TRIANGLES};
use serde_json::json;

const OBJ_QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nmtllib m.mtl\nusemtl hot\nf 1 2 3 4\n";

fn message(result: Result<bake_importer::Scene, ImportError>) -> (ImportError, String) {
    let error = result.expect_err("refused");
    let text = error.to_string();
    assert!(!text.contains('\n'), "{text}");
    (error, text)
}

#[test]
fn emission_past_f32_is_bad_input_naming_the_material() {
    let (error, text) = message(load_obj_bytes(
        OBJ_QUAD.as_bytes(),
        Some(b"newmtl hot\nKd 0.5 0.5 0.5\nKe 1e39 0 0\n"),
    ));
    assert!(
        matches!(error, ImportError::InvalidValue { .. }),
        "{error:?}"
    );
    assert!(
        text.contains("hot") && text.contains("emission 1e39"),
        "{text}"
    );
    // Below f32's largest value is still accepted.
    let mtl = b"newmtl hot\nKd 0.5 0.5 0.5\nKe 3e38 0 0\n";
    load_obj_bytes(OBJ_QUAD.as_bytes(), Some(mtl)).expect("3e38 fits f32");
    // glTF: an f32 factor times an f32 strength past f32's range.
    let mut b = GltfBuilder::wall(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        TRIANGLES,
        Some(json!({
            "name": "lamp",
            "emissiveFactor": [3e38, 0.0, 0.0],
            "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 10.0 } }
        })),
    );
    b.root["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
    let text = serde_json::to_vec(&b.json()).expect("json");
    let (error, text) = message(load_bytes(&text, Format::Gltf));
    assert!(
        matches!(error, ImportError::InvalidValue { .. }),
        "{error:?}"
    );
    assert!(text.contains("lamp"), "{text}");
}

fn triangle() -> GltfBuilder {
    GltfBuilder::wall(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        TRIANGLES,
        None,
    )
}

#[test]
fn a_glb_with_an_empty_json_chunk_says_so() {
    let json = serde_json::to_vec(&triangle().json()).expect("json");
    let bytes = glb(&[(GLB_JSON, b""), (GLB_BIN, &json)]);
    let (_, text) = message(load_bytes(&bytes, Format::Gltf));
    assert!(text.contains("JSON chunk is empty"), "{text}");
}

#[test]
fn a_byte_order_mark_before_the_json_is_accepted() {
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(serde_json::to_vec(&triangle().json()).expect("json"));
    let scene = load_bytes(&bytes, Format::Gltf).expect("a BOM is skipped");
    assert_eq!(scene.polygons.len(), 1);
}

#[test]
fn bad_embedded_buffers_name_the_buffer_and_its_uri() {
    for (uri, says) in [
        (
            "data:application/octet-stream;base64,!!!!",
            "data:application/octet-stream;base64,!!!!",
        ),
        ("http://example.com/a.bin", "http://example.com/a.bin"),
    ] {
        let mut root = triangle().json();
        root["buffers"][0]["uri"] = json!(uri);
        let text = serde_json::to_vec(&root).expect("json");
        let (_, text) = message(load_bytes(&text, Format::Gltf));
        assert!(text.contains("buffer 0") && text.contains(says), "{text}");
    }
    // A long data URI is cut in the line.
    let mut root = triangle().json();
    let long = format!(
        "data:application/octet-stream;base64,{}!",
        "A".repeat(10_000)
    );
    root["buffers"][0]["uri"] = json!(long);
    let text = serde_json::to_vec(&root).expect("json");
    let (_, text) = message(load_bytes(&text, Format::Gltf));
    assert!(text.contains("buffer 0") && text.len() < 400, "{text}");
}

/// Whether this system tells the memory available (the totals below are checked only then).
fn knows_available_memory() -> bool {
    std::fs::read_to_string("/proc/meminfo").is_ok_and(|m| m.contains("MemAvailable:"))
}

/// Item 4: accessors without a bufferView are zero-filled per primitive that reads them; 200
/// primitives over one such accessor of 2^24 − 1 VEC3 ask for 80 GB from a 30 KB file, and
/// are refused before any is read.
#[test]
fn zero_filled_accessors_are_totalled_before_reading() {
    let count = (1u64 << 24) - 1;
    let primitives: Vec<_> = (0..200)
        .map(|_| json!({ "attributes": { "POSITION": 0 }, "mode": TRIANGLES }))
        .collect();
    let root = json!({
        "asset": { "version": "2.0" },
        "accessors": [{
            "componentType": 5126, "type": "VEC3", "count": count,
            "min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.0]
        }],
        "meshes": [{ "primitives": primitives }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }],
        "scene": 0
    });
    let bytes = serde_json::to_vec(&root).expect("json");
    assert!(bytes.len() < 30_000);
    if !knows_available_memory() {
        bake_testkit::skip("BAKE_REQUIRE_MEMINFO", "no MemAvailable in /proc/meminfo");
        return;
    }
    let started = std::time::Instant::now();
    let (error, text) = message(load_bytes(&bytes, Format::Gltf));
    assert!(matches!(error, ImportError::ExceedsMemory(_)), "{error:?}");
    assert!(error.is_too_large());
    assert!(text.contains("200 zero-filled accessor reads"), "{text}");
    assert!(text.contains("MiB of memory available"), "{text}");
    assert!(started.elapsed().as_secs_f64() < 1.0);
}

/// A PNG's signature, header (`width` × `height`, 16-bit RGBA) and the start of its data:
/// enough for its size to be read, nothing to decode.
fn png_header(width: u32, height: u32) -> Vec<u8> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend((data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend(data);
        out.extend(&body);
        out.extend(crc32(&body).to_be_bytes());
    }
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = width.to_be_bytes().to_vec();
    ihdr.extend(height.to_be_bytes());
    ihdr.extend([16, 6, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(&mut png, b"IDAT", b"\x78\x9c");
    png
}

/// Item 4: each image is within the per-image limits (2^28 texels, the decoder's 512 MB),
/// but 40 of them would take 72 GB decoded (a 100-byte header each): refused, naming the
/// total, before any is decoded.
#[test]
fn decoded_images_are_totalled_before_decoding() {
    if !knows_available_memory() {
        bake_testkit::skip("BAKE_REQUIRE_MEMINFO", "no MemAvailable in /proc/meminfo");
        return;
    }
    let png = bake_testkit::data_uri(&png_header(8000, 8000));
    let png = png.replacen("application/octet-stream", "image/png", 1);
    let n = 40;
    let mut b = GltfBuilder::new();
    let uv: Vec<u8> = [[0.0f32, 0.0], [1.0, 0.0], [0.0, 1.0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let mut nodes = Vec::new();
    for k in 0..n {
        let material = b.material(json!({
            "pbrMetallicRoughness": { "baseColorTexture": { "index": k } }
        }));
        let z = k as f32;
        let mut primitive = b.primitive(
            &[[0.0, 0.0, z], [1.0, 0.0, z], [0.0, 1.0, z]],
            None,
            Some(material),
            TRIANGLES,
        );
        let uv = b.accessor(&uv, bake_testkit::FLOAT, "VEC2", 3, json!({}));
        primitive["attributes"]["TEXCOORD_0"] = json!(uv);
        let mesh = b.mesh("m", vec![primitive]);
        nodes.push(b.node(json!({ "mesh": mesh })));
    }
    let scene = b.scene(&nodes);
    b.root["scene"] = json!(scene);
    b.root["images"] = json!((0..n).map(|_| json!({ "uri": png })).collect::<Vec<_>>());
    b.root["textures"] = json!((0..n).map(|k| json!({ "source": k })).collect::<Vec<_>>());
    let bytes = serde_json::to_vec(&b.json()).expect("json");
    let started = std::time::Instant::now();
    let (_, text) = message(load_bytes(&bytes, Format::Gltf));
    assert!(
        text.contains("the 40 images the materials use, decoded, need"),
        "{text}"
    );
    assert!(text.contains("MiB of memory available"), "{text}");
    assert!(started.elapsed().as_secs_f64() < 2.0);
}
