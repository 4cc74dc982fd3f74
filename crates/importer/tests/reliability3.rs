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
