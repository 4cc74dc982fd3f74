//! Textured reflectance end to end: ρ of each element is `baseColorFactor` × the exact mean of
//! `baseColorTexture` over it (sRGB-decoded), checked against closed forms through the report.

use crate::common;

use bake_job::report::Report;
use bake_testkit::data_uri;
use common::{bake, bake_json, write_json};
use serde_json::{json, Value};

/// The IEC 61966-2-1 decoding, written out independently of the importer's.
pub(crate) fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// A PNG of `width` × `height` texels, `texel(x, y)` giving 8-bit sRGB.
pub(crate) fn png(width: u32, height: u32, texel: impl Fn(u32, u32) -> [u8; 3]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(width, height, |x, y| image::Rgb(texel(x, y)));
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)
        .expect("encode PNG");
    bytes.into_inner()
}

/// A 10 × 10 m floor (y = 0, facing +y) with TEXCOORD_0 = ((x + 5) / 10, (z + 5) / 10), a
/// point-less lit scene: an emissive panel above it lights it. `texture`: the PNG and whether
/// the sampler filters NEAREST; `None` for an untextured material.
pub(crate) fn floor_scene(factor: [f64; 3], texture: Option<(Vec<u8>, bool)>) -> Value {
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
            "images": [{ "uri": format!("data:image/png;base64,{}", bake_testkit::base64(&png)) }],
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

fn floor_of(report: &Report) -> Vec<&bake_job::report::ElementEntry> {
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

/// The floor of [`floor_scene`] textured with a 16 × 16 pattern (no black texels, so every
/// element reflects), `KHR_texture_transform` on its base colour, a normal map and an
/// occlusion texture (which the outputs must drop).
fn asset_scene() -> (Value, Vec<u8>) {
    let pattern = png(16, 16, |x, y| {
        [
            (60 + 12 * x) as u8,
            (250 - 9 * y) as u8,
            (90 + 5 * (x ^ y)) as u8,
        ]
    });
    let mut doc = floor_scene([0.9, 0.8, 0.7], Some((pattern.clone(), true)));
    let flat_normal = png(4, 4, |_, _| [128, 128, 255]);
    doc["images"].as_array_mut().expect("images").push(
        json!({ "uri": format!("data:image/png;base64,{}", bake_testkit::base64(&flat_normal)) }),
    );
    doc["textures"]
        .as_array_mut()
        .expect("textures")
        .push(json!({ "source": 1 }));
    let floor = &mut doc["materials"][0];
    floor["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = json!({
        "KHR_texture_transform": { "offset": [0.25, 0.0], "scale": [2.0, 2.0] } });
    floor["normalTexture"] = json!({ "index": 1 });
    floor["occlusionTexture"] = json!({ "index": 1 });
    doc["extensionsUsed"] = json!(["KHR_texture_transform"]);
    (doc, pattern)
}

/// The floor's TEXCOORD_0 at a point, from the scene's construction.
fn floor_uv(p: [f64; 3]) -> [f64; 2] {
    [(p[0] + 5.0) / 10.0, (p[2] + 5.0) / 10.0]
}

/// The floor element of `report` whose square holds `p` (floor elements are axis-aligned
/// squares).
fn element_holding(report: &Report, p: [f64; 3]) -> Option<&bake_job::report::ElementEntry> {
    floor_of(report).into_iter().find(|e| {
        let h = e.area.sqrt() / 2.0 + 1e-9;
        (p[0] - e.centroid[0]).abs() <= h && (p[2] - e.centroid[2]).abs() <= h
    })
}

/// A re-read primitive's POSITION and COLOR_0.
fn positions_and_colours<'a, 's, F>(
    reader: &gltf::mesh::Reader<'a, 's, F>,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>)
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    let positions = reader.read_positions().expect("POSITION").collect();
    let colours = reader
        .read_colors(0)
        .expect("COLOR_0")
        .into_rgb_f32()
        .collect();
    (positions, colours)
}

/// POSITION, COLOR_0 and indices of every primitive of a re-read vertex bake that has
/// TEXCOORD_0 (the textured ones).
type PrimitiveArrays = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>);

fn textured_primitives(path: &std::path::Path) -> Vec<PrimitiveArrays> {
    let (document, buffers, _) = gltf::import(path).expect("re-read the vertex bake");
    let mut out = Vec::new();
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
            if reader.read_tex_coords(0).is_none() {
                continue;
            }
            let (positions, colours) = positions_and_colours(&reader);
            let indices = reader.read_indices().expect("indices").into_u32().collect();
            out.push((positions, colours, indices));
        }
    }
    out
}

/// The bytes of image 0 of a re-read document.
fn image_bytes(document: &gltf::Document, buffers: &[gltf::buffer::Data], k: usize) -> Vec<u8> {
    let image = document.images().nth(k).expect("an image");
    let gltf::image::Source::View { view, mime_type } = image.source() else {
        panic!("image {k} is not embedded");
    };
    assert_eq!(mime_type, "image/png");
    let data = &buffers[view.buffer().index()];
    data[view.offset()..view.offset() + view.length()].to_vec()
}

/// Bakes `input` to `out` (`--target target`, flat shading, exposure 2) and returns the
/// report (written beside `out`).
fn bake_flat(input: &std::path::Path, out: &std::path::Path, target: &str) -> Report {
    let report = out.with_extension("report.json");
    bake([
        "--quiet".as_ref(),
        "--target".as_ref(),
        target.as_ref(),
        "--shading".as_ref(),
        "flat".as_ref(),
        "--exposure".as_ref(),
        "2".as_ref(),
        input.as_os_str(),
        out.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
    ])
    .success();
    bake_job::report::read_report(&report).expect("the report")
}

#[test]
fn both_outputs_keep_the_textured_material_and_its_uvs() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (doc, pattern) = asset_scene();
    let input = dir.path().join("asset.gltf");
    write_json(&input, &doc);
    let exposure = 2.0;
    let mut files = Vec::new();
    for container in ["gltf", "glb"] {
        let out = dir.path().join(format!("out.{container}"));
        let report = bake_flat(&input, &out, "both");
        // H from the report is (b − e) / ρ, independently of how the bake computed it.
        for e in floor_of(&report) {
            let h = e.h.expect("the report's H");
            for c in 0..3 {
                let expected = (e.b[c] - e.e[c]) / e.rho[c];
                assert!(
                    (h[c] - expected).abs() <= 1e-9 * expected.abs(),
                    "{h:?} vs {expected}"
                );
            }
        }

        // The vertex bake.
        let (document, buffers, _) = gltf::import(&out).expect("re-read the vertex bake");
        let mut floor_vertices = 0;
        let mut panel_vertices = 0;
        for mesh in document.meshes() {
            for primitive in mesh.primitives() {
                let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
                let (positions, colours) = positions_and_colours(&reader);
                let material = primitive.material();
                assert!(material.unlit());
                let pbr = material.pbr_metallic_roughness();
                match reader.read_tex_coords(0) {
                    Some(uv) => {
                        // The floor: its material, texture and transform kept.
                        assert_eq!(pbr.base_color_factor(), [0.9, 0.8, 0.7, 1.0]);
                        let info = pbr.base_color_texture().expect("baseColorTexture");
                        assert_eq!(info.tex_coord(), 0);
                        let transform = info.texture_transform().expect("the transform");
                        assert_eq!(transform.offset(), [0.25, 0.0]);
                        assert_eq!(transform.scale(), [2.0, 2.0]);
                        let k = info.texture().source().index();
                        assert_eq!(image_bytes(&document, &buffers, k), pattern);
                        let uv: Vec<[f32; 2]> = uv.into_f32().collect();
                        for (p, uv) in positions.iter().zip(&uv) {
                            let p = p.map(f64::from);
                            let expected = floor_uv(p);
                            for a in 0..2 {
                                assert!((f64::from(uv[a]) - expected[a]).abs() < 1e-6);
                            }
                            floor_vertices += 1;
                        }
                        // Flat: each triangle is one element; its COLOR_0 is clamp(H × exposure).
                        let indices: Vec<u32> =
                            reader.read_indices().expect("indices").into_u32().collect();
                        for t in indices.chunks(3) {
                            let centre = (0..3)
                                .map(|a| {
                                    t.iter()
                                        .map(|&i| f64::from(positions[i as usize][a]))
                                        .sum::<f64>()
                                        / 3.0
                                })
                                .collect::<Vec<_>>();
                            let element =
                                element_holding(&report, [centre[0], centre[1], centre[2]])
                                    .expect("the element under a triangle");
                            for &i in t {
                                for (c, got) in colours[i as usize].iter().enumerate() {
                                    let h = (element.b[c] - element.e[c]) / element.rho[c];
                                    let expected = (h * exposure).clamp(0.0, 1.0);
                                    let got = f64::from(*got);
                                    assert!((got - expected).abs() <= 1e-6, "{got} vs {expected}");
                                }
                            }
                        }
                    }
                    None => {
                        // The untextured emitter: COLOR_0 = clamp(b × exposure), white.
                        assert_eq!(pbr.base_color_factor(), [1.0; 4]);
                        assert!(pbr.base_color_texture().is_none());
                        for colour in &colours {
                            assert_eq!(*colour, [1.0; 3], "e = 1 at exposure 2 saturates");
                        }
                        panel_vertices += positions.len();
                    }
                }
            }
        }
        assert!(floor_vertices > 100 && panel_vertices > 0);

        // The lightmap bake: the whole material, minus the occlusion texture.
        let side = dir.path().join(format!("out.lightmap.{container}"));
        let (document, buffers, _) = gltf::import(&side).expect("re-read the lightmap bake");
        let floor = document
            .materials()
            .find(|m| m.pbr_metallic_roughness().base_color_texture().is_some())
            .expect("the floor's material");
        assert!(!floor.unlit());
        assert!(floor.normal_texture().is_some(), "the normal map is kept");
        assert!(
            floor.occlusion_texture().is_none(),
            "occlusion would darken twice"
        );
        let info = floor
            .pbr_metallic_roughness()
            .base_color_texture()
            .expect("base colour");
        assert_eq!(info.tex_coord(), 0);
        assert_eq!(
            info.texture_transform().expect("transform").offset(),
            [0.25, 0.0]
        );
        let k = info.texture().source().index();
        assert_eq!(image_bytes(&document, &buffers, k), pattern);
        let mut checked = 0;
        for mesh in document.meshes() {
            for primitive in mesh.primitives() {
                if primitive.material().index() != Some(floor.index().expect("an index")) {
                    continue;
                }
                let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
                let positions: Vec<[f32; 3]> = reader.read_positions().expect("POSITION").collect();
                let uv0: Vec<[f32; 2]> = reader
                    .read_tex_coords(0)
                    .expect("TEXCOORD_0")
                    .into_f32()
                    .collect();
                assert!(
                    reader.read_tex_coords(1).is_some(),
                    "TEXCOORD_1: the lightmap"
                );
                for (p, uv) in positions.iter().zip(&uv0) {
                    let expected = floor_uv(p.map(f64::from));
                    for a in 0..2 {
                        assert!((f64::from(uv[a]) - expected[a]).abs() < 1e-6);
                    }
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 4, "the floor quad's corners");
        files.push(out);
        files.push(side);
    }
    if let Some(stdout) = bake_testkit::validate_clean(&files) {
        println!("{stdout}");
    }
}

/// [`asset_scene`]'s pattern texel at a floor point, linear: nearest filter, the transform
/// uv' = (2u + 0.25, 2v), repeat; with the distance (in texels) to the nearest texel border.
fn asset_texel(p: [f64; 3]) -> ([f64; 3], f64) {
    let [u, v] = floor_uv(p);
    let (x, y) = (
        (2.0 * u + 0.25).rem_euclid(1.0) * 16.0,
        (2.0 * v).rem_euclid(1.0) * 16.0,
    );
    let border = [x - x.floor(), x.ceil() - x, y - y.floor(), y.ceil() - y]
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    let (x, y) = (x.floor() as u32, y.floor() as u32);
    let srgb = [60 + 12 * x, 250 - 9 * y, 90 + 5 * (x ^ y)];
    (srgb.map(|c| srgb_to_linear(f64::from(c) / 255.0)), border)
}

#[test]
fn preview_shows_factor_times_texture_times_colour() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (doc, _) = asset_scene();
    let input = dir.path().join("asset.gltf");
    write_json(&input, &doc);
    let out = dir.path().join("out.gltf");
    let report = bake_flat(&input, &out, "vertex");
    let options = preview::Options {
        width: 400,
        height: 400,
        view: Some([0.0, -1.0, 0.0]),
        ..Default::default()
    };
    let picture = preview::render_file(&out, &options).expect("render the bake");
    let factor = [0.9, 0.8, 0.7];
    let mut checked = 0;
    for e in floor_of(&report) {
        let (texel, border) = asset_texel(e.centroid);
        // A pixel centre lies within a pixel (~0.03 m, 0.05 texel) of the centroid.
        if border < 0.2 {
            continue;
        }
        let [x, y] = picture
            .camera
            .project(e.centroid, options.width, options.height)
            .expect("the floor is in view");
        let pixel = picture.image.get_pixel(x as u32, y as u32).0;
        for c in 0..3 {
            let h = (e.b[c] - e.e[c]) / e.rho[c];
            let expected = factor[c] * texel[c] * (h * 2.0).clamp(0.0, 1.0);
            let expected = preview::srgb8(expected);
            assert!(
                pixel[c].abs_diff(expected) <= 1,
                "element at {:?}: pixel {pixel:?} vs {expected} in band {c}",
                e.centroid
            );
        }
        checked += 1;
    }
    assert!(checked > 30, "{checked} elements checked");
}

/// Adds COLOR_0 to [`floor_scene`]'s floor: red (x + 5) / 10, green 1, blue 0.5 (linear in
/// x, so its mean over any element is its value at the element's centroid).
fn with_floor_colours(doc: Value) -> Value {
    with_colours(
        doc,
        [
            [0.0, 1.0, 0.5],
            [0.0, 1.0, 0.5],
            [1.0, 1.0, 0.5],
            [1.0, 1.0, 0.5],
        ],
    )
}

/// [`floor_scene`]'s floor with COLOR_0 = `colours` at its four corners.
fn with_colours(mut doc: Value, colours: [[f32; 3]; 4]) -> Value {
    let bytes = bake_testkit::position_bytes(&colours);
    doc["buffers"]
        .as_array_mut()
        .expect("buffers")
        .push(json!({ "byteLength": bytes.len(), "uri": data_uri(&bytes) }));
    doc["bufferViews"]
        .as_array_mut()
        .expect("views")
        .push(json!({ "buffer": 1, "byteLength": bytes.len() }));
    let view = doc["bufferViews"].as_array().map_or(0, Vec::len) - 1;
    doc["accessors"]
        .as_array_mut()
        .expect("accessors")
        .push(json!({ "bufferView": view, "componentType": 5126, "count": 4, "type": "VEC3" }));
    let accessor = doc["accessors"].as_array().map_or(0, Vec::len) - 1;
    doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(accessor);
    doc
}

#[test]
fn input_vertex_colours_multiply_rho_exactly() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // 0.5 is exact in the file's f32.
    let factor = 0.5;
    let colour = |p: [f64; 3]| [(p[0] + 5.0) / 10.0, 1.0, 0.5];
    for textured in [false, true] {
        let texture = textured.then(|| (png(4, 4, |_, _| [255; 3]), true));
        let doc = with_floor_colours(floor_scene([factor; 3], texture));
        let input = dir.path().join(format!("colours-{textured}.gltf"));
        write_json(&input, &doc);
        let out = dir.path().join(format!("colours-{textured}.gltf-out.gltf"));
        let report = bake_flat(&input, &out, "both");
        let floor = floor_of(&report);
        assert!(floor.len() > 50);
        for e in &floor {
            for (k, c) in colour(e.centroid).iter().enumerate() {
                let expected = factor * c;
                assert!(
                    (e.rho[k] - expected).abs() <= 1e-9,
                    "element at {:?}: ρ {:?} vs {expected}",
                    e.centroid,
                    e.rho
                );
            }
        }
        if textured {
            // The vertex bake's COLOR_0 is H × the input colour at each vertex, so a viewer's
            // factor × texture × COLOR_0 still carries the colour.
            let mut checked = 0;
            for (positions, colours, indices) in textured_primitives(&out) {
                for t in indices.chunks(3) {
                    let centre: Vec<f64> = (0..3)
                        .map(|a| {
                            t.iter()
                                .map(|&i| f64::from(positions[i as usize][a]))
                                .sum::<f64>()
                                / 3.0
                        })
                        .collect();
                    let e = element_holding(&report, [centre[0], centre[1], centre[2]])
                        .expect("an element");
                    for &i in t {
                        let c = colour(positions[i as usize].map(f64::from));
                        for k in 0..3 {
                            let h = (e.b[k] - e.e[k]) / e.rho[k].max(1e-300);
                            let h = if e.rho[k] > 0.0 {
                                h
                            } else {
                                e.h.expect("H")[k]
                            };
                            let expected = (h * 2.0 * c[k]).clamp(0.0, 1.0);
                            let got = f64::from(colours[i as usize][k]);
                            assert!((got - expected).abs() <= 1e-6, "{got} vs {expected}");
                        }
                    }
                    checked += 1;
                }
            }
            assert!(checked > 50);
        }
        let side = out.with_file_name(format!("colours-{textured}.gltf-out.lightmap.gltf"));
        let (document, _, _) = gltf::import(&side).expect("re-read the lightmap bake");
        let floor_primitives = document
            .meshes()
            .flat_map(|m| m.primitives().collect::<Vec<_>>())
            .filter(|p| p.get(&gltf::Semantic::Colors(0)).is_some())
            .count();
        assert_eq!(
            floor_primitives, 1,
            "the lightmap bake keeps the floor's COLOR_0"
        );
        bake_testkit::validate_clean(&[out, side]);
    }
}

#[test]
fn vertex_colours_outside_zero_one_are_refused() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let doc = with_colours(floor_scene([0.5; 3], None), [[1.5, 0.0, 0.0]; 4]);
    let input = dir.path().join("bright.gltf");
    write_json(&input, &doc);
    let run = bake([input.as_os_str(), dir.path().join("o.gltf").as_os_str()]);
    assert_eq!(run.code, Some(1), "{run:?}");
    assert!(run.stderr.contains("COLOR_0"), "{}", run.stderr);
}

#[test]
fn obj_map_kd_is_a_base_colour_texture() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // Image rows 0..32 (the top half, OBJ v > 0.5) black, the rest white.
    let texture = png(64, 64, |_, y| if y < 32 { [0; 3] } else { [255; 3] });
    std::fs::write(dir.path().join("half.png"), &texture).expect("write the PNG");
    common::write_text(
        &dir.path().join("room.mtl"),
        "newmtl floor\nKd 0.5 0.5 0.5\nmap_Kd half.png\nnewmtl light\nKd 0 0 0\nKe 1 1 1\n",
    );
    let obj = dir.path().join("room.obj");
    common::write_text(
        &obj,
        "mtllib room.mtl\no floor\nusemtl floor\n\
         v -5 0 -5\nv -5 0 5\nv 5 0 5\nv 5 0 -5\n\
         vt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\n\
         f 1/1 2/2 3/3 4/4\n\
         o light\nusemtl light\nv -1 3 -1\nv 1 3 -1\nv 1 3 1\nv -1 3 1\nf 5 6 7 8\n",
    );
    let out = dir.path().join("room-out.gltf");
    let report = bake_flat(&obj, &out, "both");
    let (mut black, mut white) = (0, 0);
    for e in floor_of(&report) {
        let half = e.area.sqrt() / 2.0;
        // OBJ v = (z + 5) / 10; v > 0.5 (z > 0) is black. The linear filter blurs one texel
        // (10 / 64 m) around the edge, and at z = ±5 with the other side (repeat wraps).
        if e.centroid[2] + half > 4.8 || e.centroid[2] - half < -4.8 {
            continue;
        }
        if e.centroid[2] - half > 0.2 {
            assert!(e.rho[0].abs() < 1e-12, "{:?} at {:?}", e.rho, e.centroid);
            black += 1;
        } else if e.centroid[2] + half < -0.2 {
            assert!(
                (e.rho[0] - 0.5).abs() < 1e-6,
                "{:?} at {:?}",
                e.rho,
                e.centroid
            );
            white += 1;
        }
    }
    assert!(black > 20 && white > 20, "{black} black, {white} white");
    let side = dir.path().join("room-out.lightmap.gltf");
    for path in [&out, &side] {
        let (document, _, images) = gltf::import(path).expect("re-read");
        assert_eq!(images.len(), if path == &out { 1 } else { 2 });
        assert!(document
            .materials()
            .any(|m| m.pbr_metallic_roughness().base_color_texture().is_some()));
    }
    bake_testkit::validate_clean(&[out, side]);
}

#[test]
fn smooth_textured_bake_averages_h_to_vertices() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (doc, _) = asset_scene();
    let input = dir.path().join("asset.gltf");
    write_json(&input, &doc);
    let out = dir.path().join("smooth.gltf");
    let report_path = dir.path().join("smooth.json");
    bake([
        "--quiet".as_ref(),
        "--exposure".as_ref(),
        "2".as_ref(),
        input.as_os_str(),
        out.as_os_str(),
        "--report".as_ref(),
        report_path.as_os_str(),
    ])
    .success();
    let report = bake_job::report::read_report(&report_path).expect("the report");
    // A smoothed vertex value is an area-weighted mean of the floor elements' H: within
    // their range, band by band.
    let floor = floor_of(&report);
    let range: Vec<(f64, f64)> = (0..3)
        .map(|c| {
            let h = floor.iter().map(|e| e.h.expect("H")[c] * 2.0);
            (
                h.clone().fold(f64::INFINITY, f64::min),
                h.fold(0.0, f64::max),
            )
        })
        .collect();
    let mut vertices = 0;
    for (_, colours, _) in textured_primitives(&out) {
        for colour in colours {
            for (c, (lo, hi)) in range.iter().enumerate() {
                let v = f64::from(colour[c]);
                assert!(
                    v >= lo.min(1.0) - 1e-6 && v <= hi.min(1.0) + 1e-6,
                    "{v} vs {lo}..{hi}"
                );
            }
            vertices += 1;
        }
    }
    assert!(vertices > 100);
    let side = dir.path().join("smooth.lightmap.gltf");
    bake_testkit::validate_clean(&[out, side]);
}

/// The first material with a base-colour texture, and the TEXCOORD set that texture reads.
fn textured_material<'a>(document: &'a gltf::Document) -> (gltf::Material<'a>, u32) {
    let material = document
        .materials()
        .find(|m| m.pbr_metallic_roughness().base_color_texture().is_some())
        .expect("a textured material");
    let set = material
        .pbr_metallic_roughness()
        .base_color_texture()
        .map_or(u32::MAX, |info| info.tex_coord());
    (material, set)
}

#[test]
fn a_texture_on_the_second_uv_set_moves_to_texcoord_2_in_the_lightmap_bake() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (mut doc, _) = asset_scene();
    // The same UVs as set 1 too; the base colour reads set 1 (its transform keeps none).
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_1"] = json!(2);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = json!(1);
    let input = dir.path().join("second.gltf");
    write_json(&input, &doc);
    let out = dir.path().join("second-out.gltf");
    bake_flat(&input, &out, "both");
    let side = dir.path().join("second-out.lightmap.gltf");
    let (document, _, _) = gltf::import(&side).expect("re-read");
    let (floor, set) = textured_material(&document);
    assert_eq!(set, 2, "set 1 is the lightmap's");
    assert_eq!(floor.normal_texture().map(|n| n.tex_coord()), Some(0));
    let textured = document
        .meshes()
        .flat_map(|m| m.primitives().collect::<Vec<_>>())
        .find(|p| p.material().index() == floor.index())
        .expect("the floor primitive");
    assert!(textured.get(&gltf::Semantic::TexCoords(2)).is_some());
    let (document, _, _) = gltf::import(&out).expect("re-read the vertex bake");
    assert_eq!(textured_material(&document).1, 0);
    bake_testkit::validate_clean(&[out, side]);
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

#[test]
fn a_white_texture_on_a_white_factor_is_lowered_to_the_ceiling_with_a_warning() {
    // ρ = 1 × white texels = 1: lowered to --max-reflectance (0.98 by default), one warning
    // naming the material; a grey texture stays as authored.
    let dir = tempfile::tempdir().expect("tempdir");
    let white = png(4, 4, |_, _| [255, 255, 255]);
    let doc = floor_scene([1.0, 1.0, 1.0], Some((white, true)));
    let report = common::bake_json(dir.path(), "white", &doc, &[]);
    let floor: Vec<_> = report
        .elements
        .iter()
        .filter(|e| e.normal[1] > 0.5)
        .collect();
    assert!(!floor.is_empty());
    for e in &floor {
        assert_eq!(e.rho, [0.98; 3], "{e:?}");
    }
    let warned: Vec<&String> = report
        .warnings
        .iter()
        .filter(|w| w.contains("--max-reflectance 0.98") && w.contains("material 0"))
        .collect();
    assert_eq!(warned.len(), 1, "{:?}", report.warnings);

    let grey = png(4, 4, |_, _| [188, 188, 188]);
    let doc = floor_scene([1.0, 1.0, 1.0], Some((grey, true)));
    let report = common::bake_json(dir.path(), "grey", &doc, &[]);
    assert!(
        report
            .warnings
            .iter()
            .all(|w| !w.contains("--max-reflectance")),
        "{:?}",
        report.warnings
    );
    for e in report.elements.iter().filter(|e| e.normal[1] > 0.5) {
        assert!(e.rho[0] < 0.98 && e.rho[0] > 0.4, "{e:?}");
    }
}

#[test]
fn an_emissive_texture_that_is_the_base_colour_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let texture = png(4, 4, |x, _| {
        if x < 2 {
            [200, 100, 50]
        } else {
            [50, 100, 200]
        }
    });
    let mut doc = floor_scene([0.8, 0.8, 0.8], Some((texture, true)));
    doc["materials"][0]["emissiveTexture"] = json!({ "index": 0 });
    doc["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    doc["materials"][0]["name"] = json!("screen");
    let report = common::bake_json(dir.path(), "in", &doc, &[]);
    let named: Vec<&String> = report
        .warnings
        .iter()
        .filter(|w| w.contains("material \"screen\"") && w.contains("emissive texture"))
        .collect();
    assert_eq!(named.len(), 1, "{:?}", report.warnings);
    // The same picture only as base colour: no warning.
    let texture = png(4, 4, |x, _| {
        if x < 2 {
            [200, 100, 50]
        } else {
            [50, 100, 200]
        }
    });
    let doc = floor_scene([0.8, 0.8, 0.8], Some((texture, true)));
    let report = common::bake_json(dir.path(), "plain", &doc, &[]);
    assert!(
        report
            .warnings
            .iter()
            .all(|w| !w.contains("emissive texture")),
        "{:?}",
        report.warnings
    );
}
