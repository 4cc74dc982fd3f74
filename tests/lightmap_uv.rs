//! `--lightmap-uv`: the input's authored `TEXCOORD_1` as the lightmap layout; and grouped
//! generated charts end to end.
//!
//! - A room from Blender (`tools/blender-lightmap-room`: Blender's own Lightmap Pack over all
//!   objects into one texture space) baked with `keep`: every vertex of the lightmap glTF has
//!   the input's TEXCOORD_1 within f32 rounding (read back from the input with `gltf`, not
//!   through the importer), and so does the point at each output triangle's centroid; the
//!   report says every primitive was kept; the output passes the Khronos validator; element
//!   centroids sampled through TEXCOORD_1 read the smoothed irradiance within 1%.
//! - Small written scenes: `keep` refuses overlaps (between primitives, and a double-sided
//!   face's two sides), UVs outside [0, 1] and a material that samples TEXCOORD_1, each
//!   naming the primitive and the reason, before the bake; `auto` generates charts for them
//!   and says why; islands closer than 2 texels warn.
//! - Grouped charts through the binary: a flat floor of 4 232 triangles under a point light
//!   (one grouped chart), validator clean, and each triangle centroid away from the edge,
//!   sampled from the written EXR through the written TEXCOORD_1, reads the closed form
//!   H = I cos θ / (π d²) within 1%.

mod common;

use common::{bake, blender_installed, data_uri, skip, tools_dir, validate_clean, write_json};
use glam::{DVec2, DVec3};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;

/// Two triangles per quad, non-indexed: a floor (y = 0, facing +y) and a ceiling (y = 1,
/// facing −y) of one unit square, with TEXCOORD_1 squares at `floor` and `ceiling` (corner,
/// side), one emissive material. `material` is merged into the material JSON.
fn two_quads(floor: ([f32; 2], f32), ceiling: ([f32; 2], f32), material: Value) -> Value {
    let quad = |y: f32, up: bool, (at, s): ([f32; 2], f32)| {
        // Corners (x, z) and their UV offsets, counter-clockwise seen from the normal side.
        let mut corners = [
            ([0.0, 0.0], [0.0, 0.0]),
            ([1.0, 0.0], [s, 0.0]),
            ([1.0, 1.0], [s, s]),
            ([0.0, 1.0], [0.0, s]),
        ];
        if up {
            corners.reverse();
        }
        let tri = [0, 1, 2, 0, 2, 3];
        let positions: Vec<[f32; 3]> = tri
            .iter()
            .map(|&k| [corners[k].0[0], y, corners[k].0[1]])
            .collect();
        let uv: Vec<[f32; 2]> = tri
            .iter()
            .map(|&k| [at[0] + corners[k].1[0], at[1] + corners[k].1[1]])
            .collect();
        (positions, uv)
    };
    let (mut positions, mut uv1) = quad(0.0, true, floor);
    let (p, u) = quad(1.0, false, ceiling);
    positions.extend(p);
    uv1.extend(u);
    let uv0 = uv1.clone();
    let mut bytes = Vec::new();
    for p in &positions {
        bytes.extend(p.iter().flat_map(|v| v.to_le_bytes()));
    }
    let uv_offset = bytes.len();
    for t in uv0.iter().chain(&uv1) {
        bytes.extend(t.iter().flat_map(|v| v.to_le_bytes()));
    }
    let n = positions.len();
    let mut m = json!({
        "name": "paint",
        "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0 },
        "emissiveFactor": [1.0, 1.0, 1.0]
    });
    if let (Some(m), Value::Object(extra)) = (m.as_object_mut(), material) {
        m.extend(extra);
    }
    json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "name": "room", "mesh": 0 }],
        "meshes": [{ "name": "room", "primitives": [{
            "attributes": { "POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2 }, "material": 0
        }] }],
        "materials": [m],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
              "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0] },
            { "bufferView": 1, "componentType": 5126, "count": n, "type": "VEC2" },
            { "bufferView": 1, "byteOffset": 8 * n, "componentType": 5126, "count": n, "type": "VEC2" }
        ],
        "bufferViews": [
            { "buffer": 0, "byteLength": uv_offset },
            { "buffer": 0, "byteOffset": uv_offset, "byteLength": bytes.len() - uv_offset }
        ],
        "buffers": [{ "byteLength": bytes.len(), "uri": data_uri(&bytes) }]
    })
}

/// Bakes `doc` (`--target lightmap`, `--lightmap-uv mode`, a report): the run and the
/// report's `options.lightmap_layout`, if any.
fn bake_uv(dir: &Path, name: &str, doc: &Value, mode: &str) -> (common::Run, Value) {
    let input = dir.join(format!("{name}.gltf"));
    write_json(&input, doc);
    let out = dir.join(format!("{name}-out.gltf"));
    let report = dir.join(format!("{name}.json"));
    let run = bake([
        input.as_os_str(),
        out.as_os_str(),
        "--target".as_ref(),
        "lightmap".as_ref(),
        "--lightmap-uv".as_ref(),
        mode.as_ref(),
        "--quality".as_ref(),
        "draft".as_ref(),
        "--report".as_ref(),
        report.as_os_str(),
    ]);
    let layout = std::fs::read_to_string(&report)
        .ok()
        .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        .map_or(Value::Null, |r| r["options"]["lightmap_layout"].clone());
    (run, layout)
}

/// A 2×2 PNG as a data URI (for a texture that reads TEXCOORD_1).
fn png_uri() -> String {
    let image = image::RgbImage::from_pixel(2, 2, image::Rgb([200, 200, 200]));
    common::png_data_uri(image::DynamicImage::ImageRgb8(image))
}

#[test]
fn keep_uses_a_valid_layout_and_refuses_unusable_ones() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let apart = two_quads(
        ([0.0625, 0.0625], 0.375),
        ([0.5625, 0.0625], 0.375),
        json!({}),
    );
    let (run, layout) = bake_uv(d, "apart", &apart, "keep");
    let run = run.success();
    assert!(run.warning_lines().is_empty(), "{run:#?}");
    assert_eq!(layout[0]["uv"], "kept", "{layout}");
    // The output's TEXCOORD_1 is the input's, vertex by vertex (polygons in input order).
    let (document, buffers, _) = gltf::import(d.join("apart-out.gltf")).expect("re-read");
    let mut uv1 = Vec::new();
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
            uv1.extend(reader.read_tex_coords(1).expect("TEXCOORD_1").into_f32());
        }
    }
    // Two quads of four vertices; the input's corners, in the importer's vertex order, are
    // among the input UVs: compare as sets of corner UVs per quad.
    assert_eq!(uv1.len(), 8);
    let corners = |at: [f32; 2], s: f32| {
        let mut c = vec![
            at,
            [at[0] + s, at[1]],
            [at[0] + s, at[1] + s],
            [at[0], at[1] + s],
        ];
        c.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
        c
    };
    let mut got: Vec<Vec<[f32; 2]>> = uv1.chunks(4).map(<[_]>::to_vec).collect();
    for g in &mut got {
        g.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
    }
    got.sort_by(|a, b| a[0].partial_cmp(&b[0]).expect("finite"));
    assert_eq!(
        got,
        vec![
            corners([0.0625, 0.0625], 0.375),
            corners([0.5625, 0.0625], 0.375)
        ]
    );

    // Overlapping squares: refused by keep (exit 1, before the bake), generated by auto.
    let overlap = two_quads(([0.0625, 0.0625], 0.375), ([0.25, 0.25], 0.375), json!({}));
    let (run, _) = bake_uv(d, "overlap", &overlap, "keep");
    assert_eq!(run.code, Some(1), "{run:#?}");
    assert!(
        run.stderr.contains("node 0 mesh 0 primitive 0") && run.stderr.contains("overlaps itself"),
        "{}",
        run.stderr
    );
    let (run, layout) = bake_uv(d, "overlap-auto", &overlap, "auto");
    run.success();
    assert_eq!(layout[0]["uv"], "generated", "{layout}");
    assert!(
        layout[0]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("overlaps")),
        "{layout}"
    );

    // Outside [0, 1].
    let outside = two_quads(
        ([0.0625, 0.0625], 0.375),
        ([0.75, 0.0625], 0.375),
        json!({}),
    );
    let (run, _) = bake_uv(d, "outside", &outside, "keep");
    assert_eq!(run.code, Some(1), "{run:#?}");
    assert!(run.stderr.contains("leaves [0, 1]"), "{}", run.stderr);

    // Both sides of a double-sided face would share its texels.
    let two_sided = two_quads(
        ([0.0625, 0.0625], 0.375),
        ([0.5625, 0.0625], 0.375),
        json!({ "doubleSided": true }),
    );
    let (run, _) = bake_uv(d, "two-sided", &two_sided, "keep");
    assert_eq!(run.code, Some(1), "{run:#?}");
    assert!(run.stderr.contains("double-sided"), "{}", run.stderr);

    // A material that samples TEXCOORD_1 as a texture set.
    let mut sampled = two_quads(
        ([0.0625, 0.0625], 0.375),
        ([0.5625, 0.0625], 0.375),
        json!({ "pbrMetallicRoughness": {
            "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0,
            "baseColorTexture": { "index": 0, "texCoord": 1 }
        } }),
    );
    sampled["textures"] = json!([{ "source": 0 }]);
    sampled["images"] = json!([{ "uri": png_uri() }]);
    let (run, _) = bake_uv(d, "sampled", &sampled, "keep");
    assert_eq!(run.code, Some(1), "{run:#?}");
    assert!(run.stderr.contains("samples TEXCOORD_1"), "{}", run.stderr);
    let (run, layout) = bake_uv(d, "sampled-auto", &sampled, "auto");
    run.success();
    assert_eq!(layout[0]["uv"], "generated", "{layout}");

    // Islands 1/512 of the atlas apart: under 2 texels at any atlas under 1024 texels (this
    // one: 394).
    let close = two_quads(
        ([0.0625, 0.0625], 0.375),
        ([0.4375 + 1.0 / 512.0, 0.0625], 0.375),
        json!({}),
    );
    let (run, layout) = bake_uv(d, "close", &close, "keep");
    let run = run.success();
    assert_eq!(layout[0]["uv"], "kept");
    assert!(
        run.warning_lines()
            .iter()
            .any(|w| w.contains("texels apart")),
        "{run:#?}"
    );
}

// ---- Blender ----

/// Per node name: the input's triangles (node-local positions, TEXCOORD_1), read with
/// `gltf` straight from the file.
type Triangles = Vec<([DVec3; 3], [DVec2; 3])>;

fn triangles_by_node(path: &Path, set: u32) -> std::collections::BTreeMap<String, Triangles> {
    let (document, buffers, _) = gltf::import(path).expect("read a glTF");
    let mut out = std::collections::BTreeMap::new();
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let mut tris = Vec::new();
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
            let positions: Vec<DVec3> = reader
                .read_positions()
                .expect("POSITION")
                .map(|p| DVec3::from_array(p.map(f64::from)))
                .collect();
            let uv: Vec<DVec2> = reader
                .read_tex_coords(set)
                .expect("TEXCOORD")
                .into_f32()
                .map(|t| DVec2::from_array(t.map(f64::from)))
                .collect();
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            for t in indices.chunks_exact(3) {
                let k = [t[0], t[1], t[2]].map(|i| i as usize);
                tris.push((k.map(|i| positions[i]), k.map(|i| uv[i])));
            }
        }
        out.insert(node.name().unwrap_or_default().to_owned(), tris);
    }
    out
}

/// TEXCOORD of `point` on the input triangles: the triangle holding it (largest smallest
/// barycentric coordinate, lying in its plane).
fn uv_at(tris: &Triangles, point: DVec3) -> Option<DVec2> {
    let mut best: Option<(f64, DVec2)> = None;
    for (p, t) in tris {
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let area = n.length_squared();
        if area == 0.0 || ((point - p[0]).dot(n)).abs() > 1e-6 * area.sqrt() {
            continue;
        }
        let la = (p[1] - point).cross(p[2] - point).dot(n) / area;
        let lb = (p[2] - point).cross(p[0] - point).dot(n) / area;
        let lc = 1.0 - la - lb;
        let worst = la.min(lb).min(lc);
        if worst > -1e-6 && best.is_none_or(|(w, _)| worst > w) {
            best = Some((worst, t[0] * la + t[1] * lb + t[2] * lc));
        }
    }
    best.map(|b| b.1)
}

#[test]
fn blender_lightmap_pack_is_kept_as_authored() {
    if !blender_installed() {
        skip(
            "BAKE_REQUIRE_BLENDER",
            "blender is not installed (tools/ci-clients --blender)",
        );
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let room = dir.path().join("room.gltf");
    let made = Command::new(tools_dir().join("blender-lightmap-room"))
        .arg(&room)
        .output()
        .expect("run tools/blender-lightmap-room");
    assert!(
        made.status.success(),
        "{}",
        String::from_utf8_lossy(&made.stderr)
    );
    let out = dir.path().join("room-lightmap.gltf");
    let report = dir.path().join("room.json");
    bake([
        room.as_os_str(),
        out.as_os_str(),
        "--target".as_ref(),
        "lightmap".as_ref(),
        "--lightmap-uv".as_ref(),
        "keep".as_ref(),
        "--report".as_ref(),
        report.as_os_str(),
    ])
    .success();
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("JSON");
    let layout = report["options"]["lightmap_layout"]
        .as_array()
        .expect("layout");
    assert_eq!(layout.len(), 4, "{layout:?}");
    assert!(layout.iter().all(|d| d["uv"] == "kept"), "{layout:?}");

    let input = triangles_by_node(&room, 1);
    let output = triangles_by_node(&out, 1);
    assert_eq!(
        input.keys().collect::<Vec<_>>(),
        output.keys().collect::<Vec<_>>()
    );
    let rounding = f64::from(f32::EPSILON);
    let mut vertices = 0;
    for (name, tris) in &output {
        let source = &input[name];
        for (p, t) in tris {
            // Every vertex, and the triangle's centroid (no seam moved inside a polygon).
            let centroid = (p[0] + p[1] + p[2]) / 3.0;
            let points = [
                (p[0], t[0]),
                (p[1], t[1]),
                (p[2], t[2]),
                (centroid, (t[0] + t[1] + t[2]) / 3.0),
            ];
            for (point, got) in points {
                // A vertex on a seam has several input UVs: it must match one of them.
                let matches = source.iter().any(|(q, s)| {
                    (0..3).any(|k| {
                        q[k].distance(point) < 1e-6 && (s[k] - got).abs().max_element() <= rounding
                    })
                });
                let inside = uv_at(source, point)
                    .is_some_and(|want| (want - got).abs().max_element() <= 4.0 * rounding);
                assert!(
                    matches || inside,
                    "{name}: TEXCOORD_1 {got} at {point} is not the input's"
                );
                vertices += 1;
            }
        }
    }
    assert!(vertices >= 4 * 2 * 28, "{vertices}");
    if let Some(summary) = validate_clean(std::slice::from_ref(&out)) {
        eprintln!("{summary}");
    }
    // The texels under the kept layout hold the irradiance: element centroids, looked up
    // through TEXCOORD_1 and sampled, read the smoothed H within 1% (in-process bake).
    let scene = importer::load(&room).expect("load");
    let request = bake_core::Request {
        irradiance: true,
        // The uniform mesh this test is about.
        refine: Some(false),
        ..bake_core::Request::default()
    };
    let settings = bake_core::Settings::resolve(&request, &scene.polygons).expect("settings");
    let baked = bake_core::run(&scene, &settings, &bake_core::Silent).expect("bake");
    let h = baked.irradiance.expect("irradiance");
    let options = lightmap::Options {
        texel_size: lightmap::default_texel_size(&scene.polygons),
        max_size: lightmap::DEFAULT_MAX_SIZE,
    };
    let authored = lightmap::AuthoredUv::from_scene(&scene);
    let map = lightmap::build_with(
        &scene.polygons,
        &baked.mesh,
        &h,
        &options,
        &authored,
        lightmap::UvMode::Keep,
    )
    .expect("keep");
    let (mut checked, mut worst) = (0, 0.0f64);
    for element in &baked.mesh.elements {
        let p = element.polygon as usize;
        let uv = authored.polygons[p].as_ref().expect("kept");
        let polygon = &scene.polygons[p];
        let at = texcoord_at(polygon, uv, element.centroid);
        // Only where the bilinear sample reads this polygon's own texels.
        let (x, y) = (
            at.x * f64::from(map.width) - 0.5,
            at.y * f64::from(map.height) - 0.5,
        );
        let own = (0..4).all(|k| {
            let (i, j) = (x.floor() as i64 + (k & 1), y.floor() as i64 + (k >> 1));
            let w = i64::from(map.width);
            (0..w).contains(&i)
                && (0..w).contains(&j)
                && matches!(map.coverage[(j * w + i) as usize],
                    lightmap::Texel::Chart(q) | lightmap::Texel::Gutter(q) if q as usize == p)
        });
        if !own {
            continue;
        }
        let got = map.sample(at.to_array());
        let want = map.irradiance_at(p, element.centroid);
        let scale = want.iter().cloned().fold(0.0, f64::max).max(1e-9);
        for c in 0..3 {
            worst = worst.max((got[c] - want[c]).abs() / scale);
        }
        checked += 1;
    }
    assert!(checked * 2 > baked.mesh.elements.len(), "{checked} checked");
    assert!(worst < 0.01, "worst {worst}");
}

/// TEXCOORD_1 at `point` of `polygon`, over the fan triangle (v0 vk vk+1) holding it.
fn texcoord_at(polygon: &importer::Polygon, uv: &[DVec2], point: DVec3) -> DVec2 {
    let v = &polygon.vertices;
    let n = polygon.normal;
    let mut best = (f64::NEG_INFINITY, DVec2::ZERO);
    for k in 1..v.len() - 1 {
        let (a, b, c) = (v[0], v[k], v[k + 1]);
        let area = (b - a).cross(c - a).dot(n);
        let l1 = (point - a).cross(c - a).dot(n) / area;
        let l2 = (b - a).cross(point - a).dot(n) / area;
        let l = [1.0 - l1 - l2, l1, l2];
        let worst = l[0].min(l[1]).min(l[2]);
        if worst > best.0 {
            best = (worst, uv[0] * l[0] + uv[k] * l[1] + uv[k + 1] * l[2]);
        }
    }
    best.1
}

// ---- grouped charts through the binary ----

/// A flat 10 × 10 m floor (y = 0, facing +y) of 46 × 46 cells, two triangles each, written
/// all first triangles then all second ones so none merge into quads (4 232 polygons: above
/// `lightmap::GROUPED_ABOVE`), lit by a 50 cd point light 3 m above (1, 0.5).
fn flat_floor() -> Value {
    let n = 46u32;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (
                10.0 * i as f32 / n as f32 - 5.0,
                10.0 * j as f32 / n as f32 - 5.0,
            );
            positions.push([x, 0.0, z]);
        }
    }
    let (mut first, mut second) = (Vec::new(), Vec::new());
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
            first.extend([a, d, c]);
            second.extend([a, c, b]);
        }
    }
    let indices: Vec<u32> = first.into_iter().chain(second).collect();
    let mut bytes: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let offset = bytes.len();
    bytes.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0, 1] }],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "type": "point", "intensity": 50.0, "color": [1.0, 1.0, 1.0] }
        ] } },
        "nodes": [
            { "name": "floor", "mesh": 0 },
            { "name": "lamp", "translation": [1.0, 3.0, 0.5],
              "extensions": { "KHR_lights_punctual": { "light": 0 } } }
        ],
        "meshes": [{ "name": "floor", "primitives": [{
            "attributes": { "POSITION": 0 }, "indices": 1, "material": 0
        }] }],
        "materials": [{ "name": "grey", "pbrMetallicRoughness": {
            "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0
        } }],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3",
              "min": [-5.0, 0.0, -5.0], "max": [5.0, 0.0, 5.0] },
            { "bufferView": 1, "componentType": 5125, "count": indices.len(), "type": "SCALAR" }
        ],
        "bufferViews": [
            { "buffer": 0, "byteLength": offset },
            { "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() - offset }
        ],
        "buffers": [{ "byteLength": bytes.len(), "uri": data_uri(&bytes) }]
    })
}

/// The EXR's texels (RGB, row-major from the top) and size.
fn read_exr(path: &Path) -> (u32, u32, Vec<[f32; 3]>) {
    let image = image::open(path).expect("read the EXR").to_rgb32f();
    (
        image.width(),
        image.height(),
        image.pixels().map(|p| p.0).collect(),
    )
}

#[test]
fn grouped_charts_carry_a_point_lights_closed_form_through_the_files() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (run, layout) = bake_uv(dir.path(), "floor", &flat_floor(), "auto");
    run.success();
    assert_eq!(layout[0]["uv"], "generated", "{layout}");
    let out = dir.path().join("floor-out.gltf");
    if let Some(summary) = validate_clean(std::slice::from_ref(&out)) {
        eprintln!("{summary}");
    }
    let (width, height, texels) = read_exr(&dir.path().join("floor-out.lightmap.exr"));
    // Every output triangle's centroid (TEXCOORD_1 interpolated there) more than two
    // elements from the floor's edge reads the point light's H = I cos θ / (π d²) within 1%:
    // the smoothed element means, through the grouped chart.
    let light = DVec3::new(1.0, 3.0, 0.5);
    let (mut checked, mut worst) = (0, 0.0f64);
    for (p, t) in triangles_by_node(&out, 1).values().flatten() {
        let point = (p[0] + p[1] + p[2]) / 3.0;
        // Away from the floor's edge, where smoothing is one-sided (first order).
        if point.x.abs().max(point.z.abs()) > 4.5 {
            continue;
        }
        let at = (t[0] + t[1] + t[2]) / 3.0;
        let got = lightmap::sample_bilinear(&texels, width, height, at.to_array());
        let d = light.distance(point);
        let want = 50.0 * (light.y - point.y) / (std::f64::consts::PI * d * d * d);
        worst = got
            .iter()
            .fold(worst, |w, g| w.max((g - want).abs() / want));
        checked += 1;
    }
    assert!(checked > 3000, "{checked}");
    println!("{checked} triangle centroids: worst relative error {worst:.2e}");
    assert!(worst < 0.01, "worst {worst}");
}
