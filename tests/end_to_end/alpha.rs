//! Alpha cut-outs (`alphaMode` `MASK`): a 2 × 2 m grate whose base-colour texture is a
//! 16 × 16 alpha checkerboard (NEAREST) hangs 2 m under a point light and 2 m over a 4 × 4 m
//! floor that catches exactly its shadow. The floor is black and the grate's underside
//! sees only the floor, so the floor's irradiance is the light's direct light: its flux
//! π Σ H A must be I × the solid angle of
//! the grate's open cells (closed form, Van Oosterom–Strackee) within 2%, and the same grate
//! made `OPAQUE` passes nothing (but the rim the shadow rays' lift lets through, < 0.1%).
//! Each grate element's ρ is its opaque share (cut-out texels average in as 0). Under a sun
//! straight down the grate passes half its area's light within 2%.

use crate::common;

use bake_testkit::data_uri;
use common::{bake, write_json};
use glam::DVec3;
use serde_json::{json, Value};

const INTENSITY: f64 = 100.0;
const LIGHT: DVec3 = DVec3::new(0.0, 4.0, 0.0);
pub(crate) const CELLS: usize = 16;

/// Whether checker cell (column i, row j) of the grate's texture is open (alpha 0).
pub(crate) fn open(i: usize, j: usize) -> bool {
    (i + j).is_multiple_of(2)
}

fn checker_png() -> String {
    let image = image::RgbaImage::from_fn(CELLS as u32, CELLS as u32, |i, j| {
        let alpha = if open(i as usize, j as usize) { 0 } else { 255 };
        image::Rgba([255, 255, 255, alpha])
    });
    common::png_data_uri(image::DynamicImage::ImageRgba8(image))
}

/// The floor (y = 0, [−2, 2]², facing up) and the grate (y = 2, [−1, 1]², facing down,
/// TEXCOORD_0 u = (x + 1)/2, v = (z + 1)/2), two triangles each.
pub(crate) fn scene(alpha_mode: &str, sun: bool) -> Value {
    let quad = |y: f32, s: f32, up: bool| {
        let mut c = [[-s, y, -s], [s, y, -s], [s, y, s], [-s, y, s]];
        if up {
            c.reverse();
        }
        [0, 1, 2, 0, 2, 3].map(|k| c[k])
    };
    let floor = quad(0.0, 2.0, true);
    let grate = quad(2.0, 1.0, false);
    let positions: Vec<[f32; 3]> = floor.iter().chain(&grate).copied().collect();
    let uv: Vec<[f32; 2]> = positions
        .iter()
        .map(|p| [(p[0] + 1.0) / 2.0, (p[2] + 1.0) / 2.0])
        .collect();
    let mut bytes: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let offset = bytes.len();
    bytes.extend(uv.iter().flatten().flat_map(|v| v.to_le_bytes()));
    json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0, 1, 2] }],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            if sun {
                json!({ "type": "directional", "intensity": INTENSITY, "color": [1.0, 1.0, 1.0] })
            } else {
                json!({ "type": "point", "intensity": INTENSITY, "color": [1.0, 1.0, 1.0] })
            }
        ] } },
        "nodes": [
            { "name": "floor", "mesh": 0 },
            { "name": "grate", "mesh": 1 },
            // Shining along the node's −Z turned to −y: straight down.
            { "name": "lamp", "translation": [LIGHT.x, LIGHT.y, LIGHT.z],
              "rotation": [-std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2],
              "extensions": { "KHR_lights_punctual": { "light": 0 } } }
        ],
        "meshes": [
            { "name": "floor", "primitives": [{
                "attributes": { "POSITION": 0 }, "material": 0 }] },
            { "name": "grate", "primitives": [{
                "attributes": { "POSITION": 1, "TEXCOORD_0": 2 }, "material": 1 }] }
        ],
        "materials": [
            { "name": "black", "pbrMetallicRoughness": {
                "baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0 } },
            { "name": "grate", "alphaMode": alpha_mode, "alphaCutoff": 0.5,
              "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0,
                "baseColorTexture": { "index": 0 } } }
        ],
        "textures": [{ "source": 0, "sampler": 0 }],
        "samplers": [{ "magFilter": 9728, "minFilter": 9728 }],
        "images": [{ "uri": checker_png() }],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3",
              "min": [-2.0, 0.0, -2.0], "max": [2.0, 0.0, 2.0] },
            { "bufferView": 0, "byteOffset": 72, "componentType": 5126, "count": 6,
              "type": "VEC3", "min": [-1.0, 2.0, -1.0], "max": [1.0, 2.0, 1.0] },
            { "bufferView": 1, "byteOffset": 48, "componentType": 5126, "count": 6,
              "type": "VEC2" }
        ],
        "bufferViews": [
            { "buffer": 0, "byteLength": offset },
            { "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() - offset }
        ],
        "buffers": [{ "byteLength": bytes.len(), "uri": data_uri(&bytes) }]
    })
}

/// Solid angle of triangle (a, b, c) seen from the origin (Van Oosterom & Strackee).
fn triangle_solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let numerator = a.dot(b.cross(c)).abs();
    let denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * numerator.atan2(denominator)
}

/// Solid angle, from the light, of the grate's cell (column i, row j): x from u, z from v.
fn cell_solid_angle(i: usize, j: usize) -> f64 {
    let step = 2.0 / CELLS as f64;
    let (x0, z0) = (-1.0 + step * i as f64, -1.0 + step * j as f64);
    let corner = |x: f64, z: f64| DVec3::new(x, 2.0, z) - LIGHT;
    let (a, b) = (corner(x0, z0), corner(x0 + step, z0));
    let (c, d) = (corner(x0 + step, z0 + step), corner(x0, z0 + step));
    triangle_solid_angle(a, b, c) + triangle_solid_angle(a, c, d)
}

/// The floor's flux π Σ H A from the report (the floor is black and the grate's white
/// underside sees only it, so H is the direct light), the warnings and the report.
fn floor_flux(alpha_mode: &str, sun: bool, subdiv: &str) -> (f64, Vec<String>, Value) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = dir.path().join("grate.gltf");
    write_json(&input, &scene(alpha_mode, sun));
    let out = dir.path().join("out.gltf");
    let report = dir.path().join("report.json");
    let run = bake([
        input.as_os_str(),
        out.as_os_str(),
        "--target".as_ref(),
        "vertex".as_ref(),
        "--quality".as_ref(),
        "high".as_ref(),
        "--subdiv".as_ref(),
        subdiv.as_ref(),
        "--light-samples".as_ref(),
        "900".as_ref(),
        "--report".as_ref(),
        report.as_os_str(),
    ])
    .success();
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("JSON");
    let mut flux = 0.0;
    let mut floor_area = 0.0;
    for e in report["elements"].as_array().expect("elements") {
        if e["centroid"][1].as_f64().expect("y").abs() > 1e-9 {
            continue;
        }
        let area = e["area"].as_f64().expect("area");
        floor_area += area;
        flux += std::f64::consts::PI * e["h"][0].as_f64().expect("h") * area;
    }
    assert!((floor_area - 16.0).abs() < 1e-9, "{floor_area}");
    let warnings = run.warning_lines().iter().map(|s| s.to_string()).collect();
    (flux, warnings, report)
}

/// The share of the square [x0, x1] × [z0, z1] (on the grate) covered by closed cells.
fn opaque_share(x0: f64, x1: f64, z0: f64, z1: f64) -> f64 {
    let step = 2.0 / CELLS as f64;
    let mut covered = 0.0;
    for i in 0..CELLS {
        for j in 0..CELLS {
            if open(i, j) {
                continue;
            }
            let (cx, cz) = (-1.0 + step * i as f64, -1.0 + step * j as f64);
            let w = (x1.min(cx + step) - x0.max(cx)).max(0.0);
            let h = (z1.min(cz + step) - z0.max(cz)).max(0.0);
            covered += w * h;
        }
    }
    covered / ((x1 - x0) * (z1 - z0))
}

#[test]
fn a_masked_grate_passes_its_open_share_of_a_point_lights_flux() {
    let total: f64 = (0..CELLS)
        .flat_map(|i| (0..CELLS).map(move |j| cell_solid_angle(i, j)))
        .sum();
    let open_angle: f64 = (0..CELLS)
        .flat_map(|i| (0..CELLS).map(move |j| (i, j)))
        .filter(|&(i, j)| open(i, j))
        .map(|(i, j)| cell_solid_angle(i, j))
        .sum();
    let want = INTENSITY * open_angle;
    let (got, warnings, report) = floor_flux("MASK", false, "12");
    println!(
        "masked grate: floor flux {got:.4}, I × open solid angle {want:.4} (open share {:.4}), \
         relative {:.2e}",
        open_angle / total,
        (got - want).abs() / want
    );
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!((got - want).abs() <= 0.02 * want, "{got} vs {want}");
    // The grate's elements reflect with ρ = 0.8 × their opaque share (the texture's mean
    // over the element with cut-out texels 0): 12 × 12 elements over 16 × 16 cells.
    let half = 1.0 / 12.0;
    let mut grate = 0;
    for e in report["elements"].as_array().expect("elements") {
        let c = &e["centroid"];
        if (c[1].as_f64().expect("y") - 2.0).abs() > 1e-9 {
            continue;
        }
        let (x, z) = (c[0].as_f64().expect("x"), c[2].as_f64().expect("z"));
        let share = opaque_share(x - half, x + half, z - half, z + half);
        let rho = e["rho"][0].as_f64().expect("rho");
        let want_rho = f64::from(0.8f32) * share;
        assert!(
            (rho - want_rho).abs() < 1e-9,
            "element at ({x}, {z}): ρ {rho}, 0.8 × share {share}"
        );
        grate += 1;
    }
    assert_eq!(grate, 144);
    // Opaque, the same grate casts a full shadow on the floor it exactly covers (up to the
    // shadow rays' lift off the floor, which lets a sliver at the rim see past the edge).
    let (closed, _, _) = floor_flux("OPAQUE", false, "12");
    assert!(closed <= 1e-3 * want, "{closed}");
}

/// The same grate under a sun shining straight down (E = INTENSITY lux): the floor outside
/// the grate's shadow gets E × 12 m² exactly, and through the grate it gets its open share
/// (1/2 of the grate's 4 m², orthographic) within 2%: the sun's exact shadow clipping gives
/// way to shadow rays where an occluder has cut-outs.
#[test]
fn a_masked_grate_passes_its_open_share_of_sunlight() {
    // 10 × 10 floor elements: their ray strata do not line up with the checker's cells.
    let (masked, warnings, report) = floor_flux("MASK", true, "10");
    // The grate's cut-outs turned its shadow from exact clipping into rays.
    let light = &report["lights"][0];
    assert!(
        light["rays_cast"].as_u64().is_some_and(|r| r > 0),
        "{light}"
    );
    assert_eq!(light["elements_clipped"], 0, "{light}");
    let (solid, _, _) = floor_flux("OPAQUE", true, "10");
    assert!(warnings.is_empty(), "{warnings:?}");
    let outside = INTENSITY * 12.0;
    assert!(
        (solid - outside).abs() <= 1e-9 * outside,
        "{solid} vs {outside}"
    );
    let passed = masked - outside;
    let want = INTENSITY * 4.0 * 0.5;
    println!("sun: through the grate {passed:.8}, open share × E × 4 m² = {want:.4}");
    assert!((passed - want).abs() <= 0.02 * want, "{passed} vs {want}");
}

#[test]
fn a_white_texture_on_a_white_factor_is_rho_one_not_more() {
    // The texture's mean over an element is a sum of per-piece means weighted by area: in
    // floating point it can round above 1 for an all-white texture, and ρ > 1 is refused.
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = dir.path().join("white.gltf");
    let mut doc = scene("OPAQUE", false);
    doc["materials"][1]["pbrMetallicRoughness"]["baseColorFactor"] = json!([1.0, 1.0, 1.0, 1.0]);
    write_json(&input, &doc);
    let report = dir.path().join("report.json");
    for subdiv in ["5", "7", "12"] {
        let run = bake([
            input.as_os_str(),
            dir.path().join("out.gltf").as_os_str(),
            "--target".as_ref(),
            "vertex".as_ref(),
            "--subdiv".as_ref(),
            subdiv.as_ref(),
            "--report".as_ref(),
            report.as_os_str(),
        ]);
        assert_eq!(run.code, Some(0), "--subdiv {subdiv}: {}", run.stderr);
        let report: Value =
            serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("JSON");
        for e in report["elements"].as_array().expect("elements") {
            let rho = e["rho"][0].as_f64().expect("rho");
            assert!(rho <= 1.0, "--subdiv {subdiv}: rho {rho}");
        }
    }
}
