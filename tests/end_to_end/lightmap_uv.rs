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
//! - `auto` per primitive: two primitives whose TEXCOORD_1 overlap each other (not
//!   themselves) each keep theirs in an atlas region of their own (output = input under one
//!   scale and a shift, checked at every vertex), a third that overlaps itself is generated;
//!   flat texels at element centroids are the elements' H; validator clean.
//! - Grouped charts through the binary: a flat floor of 4 232 triangles under a point light
//!   (one grouped chart), validator clean, and each triangle centroid away from the edge,
//!   sampled from the written EXR through the written TEXCOORD_1, reads the closed form
//!   H = I cos θ / (π d²) within 1%.

use crate::common;

use bake_testkit::{blender_or_skip, data_uri, tools_dir, validate_clean};
use common::{bake, write_json};
use glam::{DVec2, DVec3};
use lightmap::UvMode::{Auto, Generate};
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
    if !blender_or_skip() {
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
    let (scene, baked, h) = bake_in_process(&room);
    let options = lightmap::Options {
        texel_size: lightmap::default_texel_size(&scene.polygons),
        max_size: lightmap::DEFAULT_MAX_SIZE,
        shading: lightmap::Shading::Smooth,
        max_atlases: lightmap::DEFAULT_MAX_ATLASES,
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

/// The CLI's default bake of `path` in-process, with H.
fn bake_in_process(path: &Path) -> (importer::Scene, bake_core::Bake, Vec<[f64; 3]>) {
    let scene = importer::load(path).expect("load");
    let request = bake_core::Request {
        irradiance: true,
        // The uniform mesh these tests are about.
        refine: Some(false),
        ..bake_core::Request::default()
    };
    let settings = bake_core::Settings::resolve(&request, &scene.polygons).expect("settings");
    let mut baked = bake_core::run(&scene, &settings, &bake_core::Silent).expect("bake");
    let h = baked.irradiance.take().expect("irradiance");
    (scene, baked, h)
}

/// The flat lightmap of an in-process bake with the scene's authored TEXCOORD_1 under
/// `mode`, at (texel size, atlas side, most atlases).
fn flat_lightmap(
    scene: &importer::Scene,
    baked: &bake_core::Bake,
    irradiance: &[[f64; 3]],
    (texel_size, max_size, max_atlases): (f64, u32, u32),
    mode: lightmap::UvMode,
) -> lightmap::Lightmap {
    let options = lightmap::Options {
        texel_size,
        max_size,
        shading: lightmap::Shading::Flat,
        max_atlases,
    };
    lightmap::build_with(
        &scene.polygons,
        &baked.mesh,
        irradiance,
        &options,
        &lightmap::AuthoredUv::from_scene(scene),
        mode,
    )
    .expect("build the lightmap")
}

/// The largest difference, relative to the peak H, between each element's H and the EXR
/// of its polygon's atlas (`exrs`, by atlas) sampled at its centroid through `map`'s
/// TEXCOORD_1.
fn flat_error(
    scene: &importer::Scene,
    baked: &bake_core::Bake,
    irradiance: &[[f64; 3]],
    map: &lightmap::Lightmap,
    exrs: &[(u32, u32, Vec<[f32; 3]>)],
) -> f64 {
    let peak = irradiance.iter().flatten().fold(0.0f64, |m, v| m.max(*v));
    let mut worst = 0.0f64;
    for (i, element) in baked.mesh.elements.iter().enumerate() {
        let p = element.polygon as usize;
        let polygon = &scene.polygons[p];
        let uv: Vec<DVec2> = (0..polygon.vertices.len())
            .map(|v| DVec2::from_array(map.texcoord(p, v).map(f64::from)))
            .collect();
        let at = texcoord_at(polygon, &uv, element.centroid);
        let (w, h, texels) = &exrs[map.charts[p].atlas as usize];
        let got = lightmap::sample_bilinear(texels, *w, *h, at.to_array());
        for c in 0..3 {
            worst = worst.max((got[c] - irradiance[i][c]).abs() / peak);
        }
    }
    worst
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

/// A flat 10 × 10 m floor (y = 0, facing +y) of 66 × 66 cells, two triangles each, written
/// all first triangles then all second ones (the importer pairs them back into 4 356 quads
/// across their shared edges: above `lightmap::GROUPED_ABOVE`), lit by a 50 cd point light
/// 3 m above (1, 0.5).
fn flat_floor() -> Value {
    let n = 66u32;
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

// ---- auto, per primitive ----

/// A TEXCOORD_1 square: corner and side.
type Square = ([f32; 2], f32);

/// One node per entry, 2 apart along x, each its own mesh from [`two_quads`] with TEXCOORD_1
/// squares (floor, ceiling); node names "p0", "p1", …
fn primitives_scene(squares: &[(Square, Square)]) -> Value {
    let mut doc = json!({
        "asset": { "version": "2.0" }, "scene": 0, "scenes": [{ "nodes": [] }],
        "nodes": [], "meshes": [], "materials": [], "accessors": [], "bufferViews": [],
        "buffers": []
    });
    let push = |doc: &mut Value, key: &str, v: Value| {
        let list = doc[key].as_array_mut().expect("a list");
        list.push(v);
        list.len() - 1
    };
    for (k, &(floor, ceiling)) in squares.iter().enumerate() {
        let one = two_quads(floor, ceiling, json!({}));
        let buffer = push(&mut doc, "buffers", one["buffers"][0].clone());
        let views = doc["bufferViews"].as_array().map_or(0, Vec::len);
        for mut view in one["bufferViews"].as_array().cloned().unwrap_or_default() {
            view["buffer"] = json!(buffer);
            push(&mut doc, "bufferViews", view);
        }
        let accessors = doc["accessors"].as_array().map_or(0, Vec::len);
        for mut a in one["accessors"].as_array().cloned().unwrap_or_default() {
            a["bufferView"] = json!(a["bufferView"].as_u64().unwrap_or(0) as usize + views);
            push(&mut doc, "accessors", a);
        }
        let material = push(&mut doc, "materials", one["materials"][0].clone());
        let mut primitive = one["meshes"][0]["primitives"][0].clone();
        for set in ["POSITION", "TEXCOORD_0", "TEXCOORD_1"] {
            let a = primitive["attributes"][set].as_u64().unwrap_or(0) as usize;
            primitive["attributes"][set] = json!(a + accessors);
        }
        primitive["material"] = json!(material);
        let mesh = push(
            &mut doc,
            "meshes",
            json!({ "name": format!("p{k}"), "primitives": [primitive] }),
        );
        let node = push(
            &mut doc,
            "nodes",
            json!({ "name": format!("p{k}"), "mesh": mesh, "translation": [2.0 * k as f64, 0.0, 0.0] }),
        );
        doc["scenes"][0]["nodes"]
            .as_array_mut()
            .expect("nodes")
            .push(json!(node));
    }
    doc
}

/// `auto` decides per primitive: two primitives whose TEXCOORD_1 each fill the same part of
/// [0, 1] (as Blender's per-object UV maps do) overlap each other, so the whole layout cannot
/// be kept, but each keeps its own in its own atlas region — its output TEXCOORD_1 is the
/// input's under one scale (the same in texels along u and v) and a shift; a third primitive
/// whose TEXCOORD_1 overlaps itself gets generated charts. `keep` refuses the scene for that
/// third one; for the first two alone it gives each an atlas of its own, TEXCOORD_1
/// unchanged. The
/// texels (`--shading flat`) at element centroids, sampled through the written TEXCOORD_1,
/// are the elements' H; the output is validator clean.
#[test]
fn auto_keeps_each_usable_primitive_in_its_own_region() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let good = (([0.0625, 0.0625], 0.375), ([0.5625, 0.0625], 0.375));
    let folded = (([0.0625, 0.0625], 0.375), ([0.25, 0.25], 0.375));
    let doc = primitives_scene(&[good, good, folded]);
    // `keep` refuses the primitive that overlaps itself, naming it.
    let (run, _) = bake_uv(d, "keep", &doc, "keep");
    assert_eq!(run.code, Some(1), "{run:#?}");
    assert!(
        run.stderr.contains("node 2 mesh 2 primitive 0") && run.stderr.contains("overlaps itself"),
        "{}",
        run.stderr
    );
    // Without it, `keep` gives each primitive an atlas of its own, its TEXCOORD_1 unchanged
    // (every output vertex's is the input's there, within f32 rounding).
    let pair = primitives_scene(&[good, good]);
    let (run, layout) = bake_uv(d, "exact", &pair, "keep");
    run.success();
    for k in 0..2 {
        assert_eq!(layout[k]["uv"], "kept", "{layout}");
        assert_eq!(layout[k]["own_region"], false, "{layout}");
    }
    let (inputs, outputs) = (
        triangles_by_node(&d.join("exact.gltf"), 1),
        triangles_by_node(&d.join("exact-out.gltf"), 1),
    );
    for (name, tris) in &outputs {
        for (p, t) in tris {
            for k in 0..3 {
                let want = uv_at(&inputs[name], p[k]).expect("an input triangle there");
                assert!(
                    (want - t[k]).abs().max_element() <= f64::from(f32::EPSILON),
                    "{name}: {} vs the input's {want}",
                    t[k]
                );
            }
        }
    }
    let (document, _, images) = gltf::import(d.join("exact-out.gltf")).expect("re-read");
    assert_eq!((document.images().count(), images.len()), (2, 2));
    // More atlases than allowed: refused before the bake.
    let refused = bake([
        d.join("exact.gltf").as_os_str(),
        d.join("exact-one.gltf").as_os_str(),
        "--lightmap-uv".as_ref(),
        "keep".as_ref(),
        "--lightmap-atlases".as_ref(),
        "1".as_ref(),
    ]);
    assert_eq!(refused.code, Some(1), "{refused:#?}");
    assert!(
        refused.stderr.contains("more than --lightmap-atlases 1"),
        "{}",
        refused.stderr
    );
    assert!(!d.join("exact-one.gltf").exists());
    if let Some(summary) = validate_clean(&[d.join("exact-out.gltf")]) {
        eprintln!("{summary}");
    }

    let input = d.join("mixed.gltf");
    write_json(&input, &doc);
    let out = d.join("mixed-out.gltf");
    let report = d.join("mixed.json");
    bake([
        input.as_os_str(),
        out.as_os_str(),
        "--target".as_ref(),
        "lightmap".as_ref(),
        "--shading".as_ref(),
        "flat".as_ref(),
        "--report".as_ref(),
        report.as_os_str(),
    ])
    .success();
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("JSON");
    let layout = &report["options"]["lightmap_layout"];
    assert_eq!(layout.as_array().map(Vec::len), Some(3), "{layout}");
    for k in 0..2 {
        assert_eq!(layout[k]["uv"], "kept", "{layout}");
        assert_eq!(layout[k]["own_region"], true, "{layout}");
    }
    assert_eq!(layout[2]["uv"], "generated", "{layout}");
    assert!(
        layout[2]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("overlaps itself")),
        "{layout}"
    );

    // Kept primitives: output = input × (a_u, a_v) + (b_u, b_v), with a_u W = a_v H (one
    // scale in texels), fitted on the extremes and checked at every vertex.
    let (inputs, outputs) = (triangles_by_node(&input, 1), triangles_by_node(&out, 1));
    let (document, _, images) = gltf::import(&out).expect("re-read");
    let png = document
        .images()
        .next()
        .expect("the lightmap image")
        .index();
    let (w, h) = (f64::from(images[png].width), f64::from(images[png].height));
    let mut boxes = Vec::new();
    for name in ["p0", "p1"] {
        let mut pairs = Vec::new();
        for (p, t) in &outputs[name] {
            for k in 0..3 {
                let want = uv_at(&inputs[name], p[k]).expect("an input triangle there");
                pairs.push((want, t[k]));
            }
        }
        let (lo_in, hi_in, lo_out, hi_out) = pairs.iter().fold(
            (
                DVec2::INFINITY,
                DVec2::NEG_INFINITY,
                DVec2::INFINITY,
                DVec2::NEG_INFINITY,
            ),
            |(a, b, c, e), (i, o)| (a.min(*i), b.max(*i), c.min(*o), e.max(*o)),
        );
        let scale = (hi_out - lo_out) / (hi_in - lo_in);
        let texels = scale * DVec2::new(w, h);
        assert!(
            (texels.x - texels.y).abs() <= 1e-5 * texels.x,
            "{name}: {texels}"
        );
        for (i, o) in &pairs {
            let mapped = lo_out + (*i - lo_in) * scale;
            assert!(
                (mapped - *o).abs().max_element() <= 4.0 * f64::from(f32::EPSILON),
                "{name}: {i} → {o}, affine {mapped}"
            );
            assert!(o.min_element() >= 0.0 && o.max_element() <= 1.0, "{o}");
        }
        boxes.push((lo_out, hi_out));
    }
    let (a, b) = (boxes[0], boxes[1]);
    assert!(
        a.1.x <= b.0.x || b.1.x <= a.0.x || a.1.y <= b.0.y || b.1.y <= a.0.y,
        "the two kept primitives' regions overlap: {boxes:?}"
    );
    if let Some(summary) = validate_clean(std::slice::from_ref(&out)) {
        eprintln!("{summary}");
    }

    // The same lightmap in-process: the CLI's EXR, and H at element centroids.
    let (scene, baked, irradiance) = bake_in_process(&input);
    let texel = lightmap::default_texel_size(&scene.polygons);
    let map = flat_lightmap(&scene, &baked, &irradiance, (texel, 4096, 16), Auto);
    let exr = read_exr(&d.join("mixed-out.lightmap.exr"));
    assert_eq!((exr.0, exr.1), (map.width, map.height));
    assert!(exr.2 == map.texels, "the CLI's texels");
    let worst = flat_error(&scene, &baked, &irradiance, &map, &[exr]);
    println!(
        "{} elements, atlas {}×{}, flat texels at centroids vs H: {worst:.2e} of the peak",
        baked.mesh.elements.len(),
        map.width,
        map.height
    );
    assert!(worst <= 1e-6, "{worst}");
}

// ---- several atlases ----

/// Three primitives (each keeping its own TEXCOORD_1 in a region of 100 × 46 texels at 40
/// texels per metre) under `--lightmap-max 128`: one atlas cannot hold them at that texel
/// size, so they go into two atlases (whole primitives per atlas) instead of coarser texels.
/// Each atlas is its own PNG and EXR, each primitive's material points at the lightmap of its
/// atlas and its TEXCOORD_1 lies in [0, 1]; validator clean; the flat texels at element
/// centroids, sampled in the polygon's own atlas, are the elements' H. With
/// `--lightmap-atlases 1` the texel size grows instead, as before.
#[test]
fn charts_that_need_several_atlases_get_them() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let good = (([0.0625, 0.0625], 0.375), ([0.5625, 0.0625], 0.375));
    let doc = primitives_scene(&[good, good, good]);
    let input = d.join("three.gltf");
    write_json(&input, &doc);
    let run = |atlases: &str, name: &str| {
        let out = d.join(format!("{name}.gltf"));
        let report = d.join(format!("{name}.json"));
        let run = bake([
            input.as_os_str(),
            out.as_os_str(),
            "--target".as_ref(),
            "lightmap".as_ref(),
            "--shading".as_ref(),
            "flat".as_ref(),
            "--lightmap-texel".as_ref(),
            "0.025".as_ref(),
            "--lightmap-max".as_ref(),
            "128".as_ref(),
            "--lightmap-atlases".as_ref(),
            atlases.as_ref(),
            "--report".as_ref(),
            report.as_os_str(),
        ])
        .success();
        (out, run)
    };
    let (out, several) = run("16", "several");
    assert!(
        !several.stderr.contains("texel size raised"),
        "{}",
        several.stderr
    );
    let (_, one) = run("1", "one");
    assert!(one.stderr.contains("texel size raised"), "{}", one.stderr);
    // An input texture where the second atlas's PNG would go: refused (exit 2), untouched.
    let mut textured = doc.clone();
    textured["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    textured["textures"] = json!([{ "source": 0 }]);
    textured["images"] = json!([{ "uri": "clash.lightmap-1.png" }]);
    let png = image::RgbImage::from_pixel(2, 2, image::Rgb([200, 200, 200]));
    png.save(d.join("clash.lightmap-1.png"))
        .expect("write the texture");
    let before = std::fs::read(d.join("clash.lightmap-1.png")).expect("read");
    let clash_in = d.join("clash-in.gltf");
    write_json(&clash_in, &textured);
    let refused = bake([
        clash_in.as_os_str(),
        d.join("clash.gltf").as_os_str(),
        "--target".as_ref(),
        "lightmap".as_ref(),
        "--lightmap-texel".as_ref(),
        "0.025".as_ref(),
        "--lightmap-max".as_ref(),
        "128".as_ref(),
    ]);
    assert_eq!(refused.code, Some(2), "{refused:#?}");
    assert!(
        refused.stderr.contains("overwrite an input"),
        "{}",
        refused.stderr
    );
    assert_eq!(
        std::fs::read(d.join("clash.lightmap-1.png")).expect("read"),
        before
    );

    // A .glb embeds every atlas's PNG; the EXRs lie beside it.
    let glb = d.join("both.glb");
    bake([
        input.as_os_str(),
        glb.as_os_str(),
        "--lightmap-texel".as_ref(),
        "0.025".as_ref(),
        "--lightmap-max".as_ref(),
        "128".as_ref(),
    ])
    .success();
    let side = d.join("both.lightmap.glb");
    let (document, _, images) = gltf::import(&side).expect("re-read the .glb");
    assert_eq!((document.images().count(), images.len()), (2, 2));
    for name in ["both.lightmap.exr", "both.lightmap-1.exr"] {
        assert!(d.join(name).is_file(), "{name}");
    }
    assert!(!d.join("both.lightmap.png").exists());
    if let Some(summary) = validate_clean(&[glb.clone(), side.clone()]) {
        eprintln!("{summary}");
    }

    let (scene, baked, irradiance) = bake_in_process(&input);
    let map = flat_lightmap(&scene, &baked, &irradiance, (0.025, 128, 16), Auto);
    let atlases = map.atlases();
    assert_eq!(atlases.len(), 2, "{:?}", map.stats);
    assert_eq!((map.stats.reductions, map.texel_size), (0, 0.025));
    // At 80 texels per metre one primitive alone (≈ 200 × 92 texels) exceeds 128: the texel
    // size grows, to just what fits, and the atlases stay within 128.
    let fine = flat_lightmap(&scene, &baked, &irradiance, (0.0125, 128, 16), Auto);
    assert!(fine.stats.reductions > 0, "{:?}", fine.stats);
    assert!(
        fine.texel_size > 0.0125 && fine.texel_size < 0.0125 * 1.7,
        "{}",
        fine.texel_size
    );
    assert!(fine
        .atlases()
        .iter()
        .all(|a| a.width <= 128 && a.height <= 128));
    // Generated charts (one per polygon) split the same way.
    let generated = flat_lightmap(&scene, &baked, &irradiance, (0.025, 128, 16), Generate);
    assert!(generated.atlases().len() >= 2, "{:?}", generated.stats);
    assert_eq!(generated.stats.reductions, 0);
    for (p, chart) in generated.charts.iter().enumerate() {
        let o = scene.polygons[p].origin;
        let same = scene.polygons.iter().zip(&generated.charts).all(|(q, c)| {
            (q.origin.node, q.origin.primitive) != (o.node, o.primitive) || c.atlas == chart.atlas
        });
        assert!(same, "polygon {p}: its primitive is split across atlases");
    }
    println!(
        "atlases {:?}, occupancy {:.3}",
        atlases
            .iter()
            .map(|a| (a.width, a.height))
            .collect::<Vec<_>>(),
        map.stats.occupancy
    );
    // Each atlas's EXR is the in-process atlas; its PNG is beside it.
    let mut exrs = Vec::new();
    for (k, atlas) in atlases.iter().enumerate() {
        let suffix = if k == 0 {
            String::new()
        } else {
            format!("-{k}")
        };
        let (w, h, texels) = read_exr(&d.join(format!("several.lightmap{suffix}.exr")));
        assert_eq!((w, h), (atlas.width, atlas.height));
        assert!(w <= 128 && h <= 128);
        assert!(texels == atlas.texels, "atlas {k}: the CLI's texels");
        assert!(d.join(format!("several.lightmap{suffix}.png")).is_file());
        exrs.push((w, h, texels));
    }
    // The output: each primitive's lightmap texture is its atlas's PNG; TEXCOORD_1 in [0, 1].
    let (document, buffers, _) = gltf::import(&out).expect("re-read");
    assert_eq!(document.images().count(), 2);
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let polygon = scene
            .polygons
            .iter()
            .position(|p| p.origin.node == node.index())
            .expect("the node's polygons");
        let atlas = map.charts[polygon].atlas as usize;
        let suffix = if atlas == 0 {
            String::new()
        } else {
            format!("-{atlas}")
        };
        for primitive in mesh.primitives() {
            let material = primitive.material().index().expect("a material");
            let json = document.as_json();
            let extension = json.materials[material]
                .extensions
                .as_ref()
                .and_then(|e| e.others.get("MOZ_lightmap"))
                .expect("MOZ_lightmap");
            let texture = extension["index"].as_u64().expect("index") as usize;
            let image = json.textures[texture].source.value();
            assert_eq!(
                json.images[image].uri.as_deref(),
                Some(format!("several.lightmap{suffix}.png").as_str()),
                "node {}",
                node.index()
            );
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
            for uv in reader.read_tex_coords(1).expect("TEXCOORD_1").into_f32() {
                assert!(uv.iter().all(|c| (0.0..=1.0).contains(c)), "{uv:?}");
            }
        }
    }
    if let Some(summary) = validate_clean(std::slice::from_ref(&out)) {
        eprintln!("{summary}");
    }
    // Flat texels at element centroids, in each polygon's own atlas.
    let worst = flat_error(&scene, &baked, &irradiance, &map, &exrs);
    assert!(worst <= 1e-6, "{worst}");
}
