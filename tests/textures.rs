//! Textured reflectance end to end: ρ of each element is `baseColorFactor` × the exact mean of
//! `baseColorTexture` over it (sRGB-decoded), checked against closed forms through the report.

mod common;

use common::{bake, bake_json, data_uri, write_json};
use exporter::report::Report;
use serde_json::{json, Value};

/// The IEC 61966-2-1 decoding, written out independently of the importer's.
fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// A PNG of `width` × `height` texels, `texel(x, y)` giving 8-bit sRGB.
fn png(width: u32, height: u32, texel: impl Fn(u32, u32) -> [u8; 3]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(width, height, |x, y| image::Rgb(texel(x, y)));
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)
        .expect("encode PNG");
    bytes.into_inner()
}

/// A 10 × 10 m floor (y = 0, facing +y) with TEXCOORD_0 = ((x + 5) / 10, (z + 5) / 10), a
/// point-less lit scene: an emissive panel above it lights it. `texture`: the PNG and whether
/// the sampler filters NEAREST; `None` for an untextured material.
fn floor_scene(factor: [f64; 3], texture: Option<(Vec<u8>, bool)>) -> Value {
    let floor = [
        [-5.0f32, 0.0, -5.0],
        [-5.0, 0.0, 5.0],
        [5.0, 0.0, 5.0],
        [5.0, 0.0, -5.0],
    ];
    let panel = [
        [-1.0f32, 3.0, -1.0],
        [1.0, 3.0, -1.0],
        [1.0, 3.0, 1.0],
        [-1.0, 3.0, 1.0],
    ];
    let mut bytes = Vec::new();
    for p in floor.iter().chain(&panel) {
        for v in p {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    for p in &floor {
        for v in [(p[0] + 5.0) / 10.0, (p[2] + 5.0) / 10.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    let mut floor_material = json!({ "pbrMetallicRoughness": {
        "baseColorFactor": [factor[0], factor[1], factor[2], 1.0], "metallicFactor": 0.0 } });
    let mut extra = json!({});
    if let Some((png, nearest)) = texture {
        floor_material["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
        let sampler = if nearest {
            json!({ "magFilter": 9728, "minFilter": 9728 })
        } else {
            json!({})
        };
        extra = json!({
            "textures": [{ "source": 0, "sampler": 0 }],
            "samplers": [sampler],
            "images": [{ "uri": format!("data:image/png;base64,{}", common::base64(&png)) }],
        });
    }
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0, 1] }],
        "nodes": [{ "mesh": 0 }, { "mesh": 1 }],
        "materials": [floor_material, {
            "pbrMetallicRoughness": { "baseColorFactor": [0.0, 0.0, 0.0, 1.0] },
            "emissiveFactor": [1.0, 1.0, 1.0] }],
        "meshes": [
            { "primitives": [{ "attributes": { "POSITION": 0, "TEXCOORD_0": 2 },
                               "indices": 3, "material": 0 }] },
            { "primitives": [{ "attributes": { "POSITION": 1 }, "indices": 3,
                               "material": 1 }] }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
              "min": [-5.0, 0.0, -5.0], "max": [5.0, 0.0, 5.0] },
            { "bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
              "min": [-1.0, 3.0, -1.0], "max": [1.0, 3.0, 1.0] },
            { "bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2" },
            { "bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR" }
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 48 },
            { "buffer": 0, "byteOffset": 48, "byteLength": 48 },
            { "buffer": 0, "byteOffset": 96, "byteLength": 32 },
            { "buffer": 0, "byteOffset": 128, "byteLength": 12 }
        ],
        "buffers": [{ "byteLength": bytes.len(), "uri": data_uri(&bytes) }],
    });
    if let (Some(d), Some(e)) = (doc.as_object_mut(), extra.as_object()) {
        for (k, v) in e {
            d.insert(k.clone(), v.clone());
        }
    }
    doc
}

fn floor_of(report: &Report) -> Vec<&exporter::report::ElementEntry> {
    report
        .elements
        .iter()
        .filter(|e| e.normal[1] > 0.5 && e.centroid[1].abs() < 1e-9)
        .collect()
}

#[test]
fn uniform_texture_gives_factor_times_its_linear_value() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let srgb = [200u8, 100, 50];
    let factor = [0.9, 0.8, 0.5];
    let doc = floor_scene(factor, Some((png(8, 8, |_, _| srgb), false)));
    let report = bake_json(dir.path(), "uniform", &doc, &[]);
    let expected: Vec<f64> = (0..3)
        .map(|c| factor[c] * srgb_to_linear(f64::from(srgb[c]) / 255.0))
        .collect();
    let floor = floor_of(&report);
    assert!(floor.len() > 50);
    for e in floor {
        for (rho, expected) in e.rho.iter().zip(&expected) {
            assert!((rho - expected).abs() <= 2e-6, "ρ {rho} vs {expected}");
        }
    }
}

#[test]
fn half_black_nearest_texture_gives_each_element_its_white_share() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let factor = [0.7, 0.7, 0.7];
    // 64 × 64, black for u < 0.5 (texels 0..32), white elsewhere: the edge on a texel border,
    // at x = 0 on the floor.
    let texture = png(64, 64, |x, _| if x < 32 { [0; 3] } else { [255; 3] });
    let doc = floor_scene(factor, Some((texture, true)));
    // 0.3 m elements: 34 per side, so some straddle x = 0.
    let report = bake_json(dir.path(), "half", &doc, &["--max-element-size", "0.3"]);
    let mut straddling = 0;
    for e in floor_of(&report) {
        let h = e.area.sqrt() / 2.0;
        let (x0, x1) = (e.centroid[0] - h, e.centroid[0] + h);
        let white = ((x1.max(0.0) - x0.max(0.0)) / (x1 - x0)).clamp(0.0, 1.0);
        straddling += usize::from(white > 0.0 && white < 1.0);
        for (rho, factor) in e.rho.iter().zip(factor) {
            let expected = factor * white;
            assert!(
                (rho - expected).abs() <= 2e-3,
                "element at {:?}: ρ {rho} vs {expected}",
                e.centroid
            );
        }
    }
    assert!(straddling > 10, "{straddling} elements straddle the edge");
}

#[test]
fn white_texture_is_the_factor_alone() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let factor = [0.6, 0.6, 0.6];
    let plain = bake_json(dir.path(), "plain", &floor_scene(factor, None), &[]);
    for nearest in [true, false] {
        let doc = floor_scene(factor, Some((png(16, 16, |_, _| [255; 3]), nearest)));
        let textured = bake_json(dir.path(), "white", &doc, &[]);
        assert_eq!(plain.elements.len(), textured.elements.len());
        for (a, b) in plain.elements.iter().zip(&textured.elements) {
            for c in 0..3 {
                assert!(
                    (a.rho[c] - b.rho[c]).abs() <= 1e-12,
                    "{:?} vs {:?}",
                    a.rho,
                    b.rho
                );
                assert!(
                    (a.b[c] - b.b[c]).abs() <= 1e-12 * a.b[c].abs().max(1e-300),
                    "{:?} vs {:?}",
                    a.b,
                    b.b
                );
            }
        }
    }
}

#[test]
fn unsupported_or_missing_textures_are_refused_naming_the_texture() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut doc = floor_scene([0.5; 3], Some((png(2, 2, |_, _| [9; 3]), false)));
    // Not a PNG or JPEG (a WebP/KTX2 file would be refused the same way).
    doc["images"][0]["uri"] = json!(data_uri(b"RIFF\0\0\0\0WEBPVP8 "));
    let input = dir.path().join("bad.gltf");
    write_json(&input, &doc);
    let run = bake([input.as_os_str(), dir.path().join("o.gltf").as_os_str()]);
    assert_eq!(run.code, Some(1), "{run:?}");
    assert!(run.stderr.contains("texture 0"), "{}", run.stderr);
    doc["images"][0]["uri"] = json!("missing.png");
    write_json(&input, &doc);
    let run = bake([input.as_os_str(), dir.path().join("o.gltf").as_os_str()]);
    assert_eq!(run.code, Some(1), "{run:?}");
    assert!(run.stderr.contains("missing.png"), "{}", run.stderr);
}

#[test]
fn grey_texture_on_a_grey_factor_is_still_one_band() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // A grey checker: every texel has r = g = b, so every element's ρ does too.
    let texture = png(8, 8, |x, y| [if (x + y) % 2 == 0 { 60 } else { 200 }; 3]);
    let doc = floor_scene([0.5; 3], Some((texture, false)));
    let report = bake_json(dir.path(), "grey", &doc, &[]);
    assert!(report
        .elements
        .iter()
        .all(|e| e.rho[0] == e.rho[1] && e.rho[1] == e.rho[2]));
    assert_eq!(
        report.solver.factorizations, 1,
        "one LU for the three bands"
    );
}

/// An image file is read like a buffer: inside the scene's folder (else refused unless
/// `--allow-outside-paths`), and it is one of the inputs no output may overwrite.
#[test]
fn an_external_texture_is_read_inside_the_folder_only_and_never_overwritten() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let scenes = dir.path().join("scenes");
    std::fs::create_dir(&scenes).expect("mkdir");
    let texture = png(4, 4, |_, _| [128; 3]);
    std::fs::write(scenes.join("t.png"), &texture).expect("write");
    std::fs::write(dir.path().join("up.png"), &texture).expect("write");
    let mut doc = floor_scene([0.5; 3], Some((texture.clone(), false)));
    doc["images"][0]["uri"] = json!("t.png");
    let input = scenes.join("floor.gltf");
    write_json(&input, &doc);
    let out = scenes.join("o.gltf");
    bake(["--quiet".as_ref(), input.as_os_str(), out.as_os_str()]).success();

    let report = scenes.join("t.png");
    let run = bake([
        input.as_os_str(),
        out.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
    ]);
    assert_eq!(run.code, Some(2), "{run:?}");
    assert!(run.stderr.contains("same file"), "{}", run.stderr);
    assert_eq!(std::fs::read(&report).expect("read"), texture);

    doc["images"][0]["uri"] = json!("../up.png");
    write_json(&input, &doc);
    let run = bake([input.as_os_str(), out.as_os_str()]);
    assert_eq!(run.code, Some(1), "{run:?}");
    assert!(
        run.stderr.contains("../up.png") && run.stderr.contains("--allow-outside-paths"),
        "{}",
        run.stderr
    );
    bake([
        "--allow-outside-paths".as_ref(),
        "--quiet".as_ref(),
        input.as_os_str(),
        out.as_os_str(),
    ])
    .success();
}
