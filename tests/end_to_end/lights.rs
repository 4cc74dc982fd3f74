//! Punctual lights (`KHR_lights_punctual`) end to end, against closed forms: a point light's
//! mean illuminance over a rectangle (the corner-sum solid angle, independent of the baker's
//! triangle fan), a spot inside and outside its cones, a sun's cos θ, a sun's exact shadow of a
//! square, and the energy balance of a closed box lit only by a point light.
//!
//! The issue asked for 0.5% (closed forms) and 0.02 × ρE/π (the sun's shadow); the baker is
//! exact there, so the bounds are 1e-6: what is left is the f32 rounding of the glTF's
//! positions and rotations (measured below 1e-7).

use crate::common;

use bake_job::report::{ElementEntry, Report};
use bake_testkit::{blender_or_skip, tools_dir, validator_or_skip, validator_output};
use common::{aim, bake, bake_json, lit_scene as scene, write_json};
use serde_json::{json, Value};
use std::f64::consts::PI;
use std::path::Path;

const RHO: [f64; 3] = [0.5, 0.4, 0.3];

/// Triangles (CCW about their normal) of the 10 × 10 m floor at y = 0, facing +y.
fn floor() -> Vec<[f32; 3]> {
    let (a, b, c, d) = (
        [-5.0, 0.0, -5.0],
        [-5.0, 0.0, 5.0],
        [5.0, 0.0, 5.0],
        [5.0, 0.0, -5.0],
    );
    vec![a, b, c, a, c, d]
}

/// A 2 × 2 m square at height 2 m facing down (−y), centred above the origin.
fn black_square() -> Vec<[f32; 3]> {
    let (a, b, c, d) = (
        [-1.0, 2.0, -1.0],
        [1.0, 2.0, -1.0],
        [1.0, 2.0, 1.0],
        [-1.0, 2.0, 1.0],
    );
    vec![a, b, c, a, c, d]
}

/// The floor's elements, with their square's x and z bounds.
fn floor_elements(report: &Report) -> Vec<(&ElementEntry, [f64; 4])> {
    report
        .elements
        .iter()
        .filter(|e| e.normal[1] > 0.5 && e.centroid[1].abs() < 1e-9)
        .map(|e| {
            let h = e.area.sqrt() / 2.0;
            let (x, z) = (e.centroid[0], e.centroid[2]);
            (e, [x - h, x + h, z - h, z + h])
        })
        .collect()
}

/// Solid angle of the rectangle [x0, x1] × [z0, z1] (coordinates relative to the foot of a
/// point at height h): corner sums of Ω(x, z) = atan(x z / (h √(x² + z² + h²))), the solid
/// angle of [0, x] × [0, z] seen from above its corner (odd in x and in z).
fn rectangle_solid_angle(r: [f64; 4], h: f64) -> f64 {
    let f = |x: f64, z: f64| (x * z / (h * (x * x + z * z + h * h).sqrt())).atan();
    f(r[1], r[3]) - f(r[0], r[3]) - f(r[1], r[2]) + f(r[0], r[2])
}

fn shifted(r: [f64; 4], x: f64, z: f64) -> [f64; 4] {
    [r[0] - x, r[1] - x, r[2] - z, r[3] - z]
}

fn assert_relative(b: [f64; 3], expected: [f64; 3], tolerance: f64, what: &str) {
    for c in 0..3 {
        let error = (b[c] - expected[c]).abs() / expected[c];
        assert!(
            error <= tolerance,
            "{what}: band {c}: b {} vs {} (relative error {error:.2e})",
            b[c],
            expected[c]
        );
    }
}

#[test]
fn point_light_over_a_floor_matches_the_solid_angle_closed_form() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (lx, lz, h, intensity) = (0.3, -0.2, 2.0, 100.0);
    let doc = scene(
        &[(floor(), RHO)],
        &[(
            json!({ "type": "point", "intensity": intensity }),
            json!({ "translation": [lx, h, lz] }),
        )],
    );
    let report = bake_json(dir.path(), "in", &doc, &[]);
    let elements = floor_elements(&report);
    assert!(elements.len() >= 100, "{} floor elements", elements.len());
    let mut delivered = 0.0;
    for (e, r) in &elements {
        let omega = rectangle_solid_angle(shifted(*r, lx, lz), h);
        let expected = RHO.map(|rho| rho * intensity * omega / (PI * e.area));
        assert_relative(e.b, expected, 1e-6, "point light");
        assert_relative(e.direct, expected, 5e-3, "point light, direct");
        delivered += intensity * omega / PI;
    }
    assert_eq!(report.lights.len(), 1);
    assert_eq!(report.lights[0].kind, "point");
    assert_eq!(
        report.lights[0].stats.rays_cast, 0,
        "nothing can shadow a lone floor"
    );
    let energy = report.energy.as_ref().expect("energy");
    assert!((energy.delivered[0] - delivered).abs() < 1e-6 * delivered);
    assert!(energy.imbalance.iter().all(|&x| x < 1e-12), "{energy:?}");
}

#[test]
fn spot_is_exact_inside_its_inner_cone_and_dark_outside_its_outer_cone() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (h, intensity) = (3.0, 200.0);
    let (inner, outer) = (20f64.to_radians(), 30f64.to_radians());
    let doc = scene(
        &[(floor(), RHO)],
        &[(
            json!({ "type": "spot", "intensity": intensity,
                    "spot": { "innerConeAngle": inner, "outerConeAngle": outer } }),
            json!({ "translation": [0.0, h, 0.0], "rotation": aim([0.0, -1.0, 0.0]) }),
        )],
    );
    let report = bake_json(dir.path(), "in", &doc, &["--max-element-size", "0.25"]);
    let (mut inside, mut outside, mut between) = (0, 0, 0);
    for (e, r) in floor_elements(&report) {
        let corners = [(r[0], r[2]), (r[1], r[2]), (r[1], r[3]), (r[0], r[3])];
        let farthest = corners
            .iter()
            .map(|(x, z)| (x * x + z * z).sqrt())
            .fold(0.0, f64::max);
        // The nearest point of the square to the foot of the light (the origin).
        let nx = 0f64.clamp(r[0], r[1]);
        let nz = 0f64.clamp(r[2], r[3]);
        let nearest = (nx * nx + nz * nz).sqrt();
        if (farthest / h).atan() < inner * (1.0 - 1e-6) {
            inside += 1;
            let omega = rectangle_solid_angle(r, h);
            let expected = RHO.map(|rho| rho * intensity * omega / (PI * e.area));
            assert_relative(e.b, expected, 1e-6, "inside the inner cone");
        } else if (nearest / h).atan() > outer * (1.0 + 1e-6) {
            outside += 1;
            assert_eq!(e.b, [0.0; 3], "outside the outer cone at {:?}", e.centroid);
        } else {
            between += 1;
            assert!(e.b[0] >= 0.0);
        }
    }
    assert!(
        inside > 30 && outside > 1000 && between > 50,
        "{inside} {outside} {between}"
    );
}

#[test]
fn sun_gives_every_element_rho_e_cos_over_pi() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let lux = 1000.0;
    let n = (0.5f64 * 0.5 + 1.0).sqrt();
    let d = [0.5 / n, -1.0 / n, 0.0];
    let doc = scene(
        &[(floor(), RHO)],
        &[(
            json!({ "type": "directional", "intensity": lux }),
            json!({ "rotation": aim(d), "translation": [40.0, 50.0, -7.0] }),
        )],
    );
    let report = bake_json(dir.path(), "in", &doc, &[]);
    let cos = -d[1];
    let expected = RHO.map(|rho| rho * lux * cos / PI);
    let elements = floor_elements(&report);
    assert!(elements.len() >= 100);
    for (e, _) in elements {
        assert_relative(e.b, expected, 1e-6, "sun");
    }
    assert_eq!(report.lights[0].kind, "directional");
}

#[test]
fn sun_shadow_of_a_black_square_is_its_exact_lit_share() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let lux = 1000.0;
    let doc = scene(
        &[(floor(), RHO), (black_square(), [0.0; 3])],
        &[(
            json!({ "type": "directional", "intensity": lux }),
            json!({ "rotation": aim([0.0, -1.0, 0.0]) }),
        )],
    );
    // Elements of 0.3 m: the square's edges at ±1 m cut through elements.
    let report = bake_json(dir.path(), "in", &doc, &["--max-element-size", "0.3"]);
    let full = RHO.map(|rho| rho * lux / PI);
    let (mut dark, mut partial, mut lit) = (0, 0, 0);
    for (e, r) in floor_elements(&report) {
        let overlap =
            (r[1].min(1.0) - r[0].max(-1.0)).max(0.0) * (r[3].min(1.0) - r[2].max(-1.0)).max(0.0);
        let share = 1.0 - overlap / ((r[1] - r[0]) * (r[3] - r[2]));
        for (b, full) in e.b.iter().zip(full) {
            let expected = full * share;
            assert!(
                (b - expected).abs() <= 1e-6 * full,
                "element at {:?}: b {b} vs {expected} (lit share {share})",
                e.centroid
            );
        }
        if share == 0.0 {
            dark += 1;
            assert_eq!(e.b, [0.0; 3], "wholly in shadow");
        } else if share == 1.0 {
            lit += 1;
        } else {
            partial += 1;
        }
    }
    assert!(
        dark > 10 && partial > 10 && lit > 100,
        "{dark} {partial} {lit}"
    );
    assert!(report.lights[0].stats.elements_clipped > 0);
    assert_eq!(
        report.lights[0].stats.rays_cast, 0,
        "directional shadows are clipped, not sampled"
    );
}

/// The 6 inward-facing faces of the box [0, 2] × [0, 1.5] × [0, 1] as triangles.
fn closed_box() -> Vec<[f32; 3]> {
    let (x, y, z) = (2.0f32, 1.5f32, 1.0f32);
    let p = |i: usize| {
        [
            if i & 1 == 1 { x } else { 0.0 },
            if i & 2 == 2 { y } else { 0.0 },
            if i & 4 == 4 { z } else { 0.0 },
        ]
    };
    // Quads (CCW seen from inside).
    let quads = [
        [0, 1, 3, 2], // z = 0, normal +z
        [4, 6, 7, 5], // z = 1, normal −z
        [0, 2, 6, 4], // x = 0, normal +x
        [1, 5, 7, 3], // x = 2, normal −x
        [0, 4, 5, 1], // y = 0, normal +y
        [2, 3, 7, 6], // y = 1.5, normal −y
    ];
    let mut out = Vec::new();
    for q in quads {
        out.extend([p(q[0]), p(q[1]), p(q[2]), p(q[0]), p(q[2]), p(q[3])]);
    }
    out
}

#[test]
fn closed_box_lit_by_a_point_light_balances_energy() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let doc = scene(
        &[(closed_box(), [0.7, 0.5, 0.2])],
        &[(
            json!({ "type": "point", "intensity": 50.0, "color": [1.0, 0.8, 0.6] }),
            json!({ "translation": [0.6, 1.1, 0.3] }),
        )],
    );
    // The dense transport (exact form factors, rows scaled to the closed scene's 1), then the
    // default, which `auto` gives the hierarchy (cheaper, refined to 4 000 elements).
    for (args, escape) in [(&["--transport", "dense"][..], 1e-5), (&[][..], 1e-3)] {
        let report = bake_json(dir.path(), "in", &doc, args);
        let energy = report.energy.as_ref().expect("energy");
        for c in 0..3 {
            assert!(energy.imbalance[c] < 1e-9, "band {c}: {energy:?}");
            // A closed box: everything that enters is absorbed, and the light delivers its
            // whole flux 4π I / π = 4 I per band (in b × area).
            let flux = 4.0 * 50.0 * f64::from([1.0f32, 0.8, 0.6][c]);
            assert!(
                (energy.delivered[c] - flux).abs() < 1e-9 * flux,
                "{energy:?}"
            );
            // Nothing escapes but the estimator's row-sum error (auto, 1e-3 per pair), which
            // the dense transport scales away; the hierarchy's links keep theirs (measured
            // 2.5e-4 of the flux at --max-error 1e-2; issue 31 holds the escape of the two
            // transports within 0.3% of each other).
            assert!(
                energy.escaped[c].abs() < escape * flux,
                "{args:?}: {energy:?}"
            );
        }
        assert!(report
            .elements
            .iter()
            .all(|e| e.b.iter().all(|v| v.is_finite() && *v > 0.0)));
    }
}

#[test]
fn unusable_lights_are_skipped_with_a_warning_and_obj_has_none() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let doc = scene(
        &[(floor(), RHO)],
        &[
            (
                json!({ "type": "point", "intensity": 10.0 }),
                json!({ "translation": [0.0, 1.0, 0.0], "scale": [0.0, 1.0, 1.0] }),
            ),
            (
                json!({ "type": "point", "intensity": -3.0 }),
                json!({ "translation": [0.0, 1.0, 0.0] }),
            ),
            (
                json!({ "type": "point", "intensity": 10.0 }),
                json!({ "translation": [0.0, 1.0, 0.0] }),
            ),
        ],
    );
    let report = bake_json(dir.path(), "in", &doc, &[]);
    assert_eq!(report.lights.len(), 1, "only the usable light");
    assert_eq!(report.lights[0].node, 3);
    let skipped: Vec<&String> = report
        .warnings
        .iter()
        .filter(|w| w.contains("skipped"))
        .collect();
    assert_eq!(skipped.len(), 2, "{:?}", report.warnings);
    assert!(skipped[0].contains("singular"), "{skipped:?}");
    assert!(skipped[1].contains("intensity"), "{skipped:?}");
}

// ---- a room made by Blender's own glTF exporter ----

/// `tools/blender-room` (walls, a table, a 500 W point light and an 800 W spot, exported with
/// `export_lights`) bakes with exit 0; the brightest floor element is within 1.2 m of the
/// spot's foot; `--exposure auto` keeps COLOR_0 out of saturation; the outputs are
/// validator-clean; the lightmap bake carries the lights only with `--keep-lights`.
#[test]
fn blender_room_with_point_and_spot_lights_bakes() {
    if !blender_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let room = dir.path().join("room.gltf");
    let made = std::process::Command::new(tools_dir().join("blender-room"))
        .arg(&room)
        .output()
        .expect("run tools/blender-room");
    let stdout = String::from_utf8_lossy(&made.stdout);
    assert!(made.status.success(), "blender-room failed:\n{stdout}");
    let facts: Value = stdout
        .lines()
        .find_map(|l| l.strip_prefix("BLENDER_ROOM "))
        .and_then(|l| serde_json::from_str(l).ok())
        .expect("a BLENDER_ROOM line");
    let foot: Vec<f64> = facts["spot_foot"]
        .as_array()
        .expect("spot_foot")
        .iter()
        .filter_map(Value::as_f64)
        .collect();

    let out = dir.path().join("out.gltf");
    let report_path = dir.path().join("report.json");
    let run = bake([
        room.as_os_str(),
        out.as_os_str(),
        "--exposure".as_ref(),
        "auto".as_ref(),
        "--report".as_ref(),
        report_path.as_os_str(),
    ])
    .success();
    assert!(run.stderr.contains("exposure auto"), "{}", run.stderr);
    let report = bake_job::report::read_report(&report_path).expect("the report");
    let kinds: Vec<&str> = report.lights.iter().map(|l| l.kind.as_str()).collect();
    assert_eq!(kinds, ["point", "spot"]);
    let floor = report
        .elements
        .iter()
        .filter(|e| e.normal[1] > 0.9 && e.centroid[1].abs() < 1e-6)
        .max_by(|a, b| a.b[0].total_cmp(&b.b[0]))
        .expect("floor elements");
    let distance =
        ((floor.centroid[0] - foot[0]).powi(2) + (floor.centroid[2] - foot[2]).powi(2)).sqrt();
    assert!(
        distance <= 1.2,
        "brightest floor element at {:?}, {distance:.2} m from the spot's foot {foot:?}",
        floor.centroid
    );
    // Emitted = absorbed + escaped to the solve's residual: ~1e-8 from GMRES on the
    // hierarchy (`auto` gives this small room with occluders the hierarchical transport).
    let energy = report.energy.as_ref().expect("energy");
    assert!(energy.imbalance.iter().all(|&x| x < 1e-6), "{energy:?}");

    // COLOR_0 under --exposure auto: at most ~1% of the vertices clipped, none black overall.
    let (document, buffers, _) = gltf::import(&out).expect("read the bake");
    let (mut vertices, mut saturated, mut brightest) = (0usize, 0usize, 0f32);
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let colors = reader.read_colors(0).expect("COLOR_0").into_rgb_f32();
            for c in colors {
                vertices += 1;
                saturated += usize::from(c.iter().any(|&v| v >= 1.0));
                brightest = brightest.max(c[0].max(c[1]).max(c[2]));
            }
        }
    }
    assert!(
        saturated * 50 <= vertices,
        "{saturated} of {vertices} vertices saturated"
    );
    assert!(brightest > 0.5, "brightest COLOR_0 {brightest}");

    // Lights in the lightmap bake only when asked for.
    let lights_in = |path: &Path| -> usize {
        let text = std::fs::read_to_string(path).expect("read glTF");
        let json: Value = serde_json::from_str(&text).expect("glTF JSON");
        json["extensions"]["KHR_lights_punctual"]["lights"]
            .as_array()
            .map_or(0, Vec::len)
    };
    let lightmap = dir.path().join("out.lightmap.gltf");
    assert_eq!(lights_in(&lightmap), 0);
    let kept = dir.path().join("kept.gltf");
    bake([
        "--quiet".as_ref(),
        "--target".as_ref(),
        "lightmap".as_ref(),
        "--keep-lights".as_ref(),
        room.as_os_str(),
        kept.as_os_str(),
    ])
    .success();
    assert_eq!(lights_in(&kept), 2);

    if !validator_or_skip() {
        return;
    }
    let files = [out, lightmap, kept];
    let output = validator_output(&files);
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "errors or warnings:\n{text}");
    let clean = text
        .lines()
        .filter(|l| l.contains(": 0 errors, 0 warnings, "))
        .count();
    assert_eq!(clean, files.len(), "{text}");
}

#[test]
fn range_window_darkens_smoothly_and_ends_exactly_at_the_range() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (h, intensity, range) = (2.0, 100.0, 3.0);
    let doc = scene(
        &[(floor(), RHO)],
        &[(
            json!({ "type": "point", "intensity": intensity, "range": range }),
            json!({ "translation": [0.0, h, 0.0] }),
        )],
    );
    let report = bake_json(dir.path(), "in", &doc, &["--max-element-size", "0.25"]);
    let (mut beyond, mut within) = (0, 0);
    for (e, r) in floor_elements(&report) {
        let nx = 0f64.clamp(r[0], r[1]);
        let nz = 0f64.clamp(r[2], r[3]);
        let nearest = (nx * nx + nz * nz + h * h).sqrt();
        let unranged = RHO[0] * intensity * rectangle_solid_angle(r, h) / (PI * e.area);
        if nearest >= range {
            beyond += 1;
            assert_eq!(e.b, [0.0; 3], "beyond the range at {:?}", e.centroid);
            continue;
        }
        within += 1;
        // KHR_lights_punctual's window max(min(1 − (d/range)⁴, 1), 0) between the element's
        // nearest and farthest distances.
        let far = [(r[0], r[2]), (r[1], r[2]), (r[1], r[3]), (r[0], r[3])]
            .iter()
            .map(|(x, z)| (x * x + z * z + h * h).sqrt())
            .fold(0.0, f64::max);
        let window = |d: f64| (1.0 - (d / range).powi(4)).clamp(0.0, 1.0);
        let (lo, hi) = (window(far) * unranged, window(nearest) * unranged);
        assert!(
            e.b[0] >= lo * (1.0 - 1e-9) && e.b[0] <= hi * (1.0 + 1e-9),
            "b {} outside [{lo}, {hi}] at {:?}",
            e.b[0],
            e.centroid
        );
    }
    assert!(beyond > 100 && within > 100, "{beyond} {within}");
}

#[test]
fn shadowed_lights_give_the_same_bytes_for_one_and_two_threads() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // The closed box with a black square hanging between a point light, a spot and the floor.
    let mut square = black_square();
    for p in &mut square {
        *p = [p[0] * 0.2 + 1.0, 0.8, p[2] * 0.2 + 0.5];
    }
    let doc = scene(
        &[(closed_box(), [0.7, 0.5, 0.2]), (square, [0.0; 3])],
        &[
            (
                json!({ "type": "point", "intensity": 50.0 }),
                json!({ "translation": [1.0, 1.3, 0.5] }),
            ),
            (
                json!({ "type": "spot", "intensity": 80.0,
                        "spot": { "innerConeAngle": 0.3, "outerConeAngle": 0.6 } }),
                json!({ "translation": [0.9, 1.4, 0.4], "rotation": aim([0.0, -1.0, 0.0]) }),
            ),
        ],
    );
    let input = dir.path().join("in.gltf");
    write_json(&input, &doc);
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("out{threads}.glb"));
        let report = dir.path().join(format!("r{threads}.json"));
        bake([
            "--quiet".as_ref(),
            "--threads".as_ref(),
            threads.as_ref(),
            input.as_os_str(),
            out.as_os_str(),
            "--report".as_ref(),
            report.as_os_str(),
        ])
        .success();
        let report = common::report_without_timings(&report);
        outputs.push((std::fs::read(&out).expect("read the bake"), report));
    }
    assert!(
        outputs[0].1.lights.iter().all(|l| l.stats.rays_cast > 0),
        "rays were cast"
    );
    assert_eq!(outputs[0].0, outputs[1].0, "same bytes");
    assert_eq!(outputs[0].1.elements, outputs[1].1.elements);
    assert_eq!(outputs[0].1.lights, outputs[1].1.lights);
}

#[test]
fn a_light_behind_every_surface_is_named_and_one_in_front_is_not() {
    // Under the floor (it faces +y) the point light reaches no surface facing it; 2 m above,
    // the 10 × 10 m floor subtends 2.2 sr of its 4π (17.6%): no warning.
    for (h, warned) in [(-1.0, true), (2.0, false)] {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let doc = scene(
            &[(floor(), RHO)],
            &[(
                json!({ "type": "point", "intensity": 100.0, "name": "bulb" }),
                json!({ "translation": [0.0, h, 0.0] }),
            )],
        );
        let report = bake_json(dir.path(), "in", &doc, &[]);
        let named: Vec<&String> = report
            .warnings
            .iter()
            .filter(|w| w.contains("point light \"bulb\"") && w.contains("inside or behind"))
            .collect();
        assert_eq!(named.len(), usize::from(warned), "{:?}", report.warnings);
        if warned {
            assert!(named[0].contains("node \"light0\""), "{named:?}");
            assert!(named[0].contains("0.00% of its light"), "{named:?}");
        }
    }
}

#[test]
fn the_default_material_under_a_lamp_bakes_at_the_reflectance_ceiling() {
    // glTF's default material (no pbrMetallicRoughness) is ρ = 1: lowered to 0.98 with one
    // warning; on an open floor every element's b is then 0.98 × its direct irradiance E/π.
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut doc = scene(
        &[(floor(), RHO)],
        &[(
            json!({ "type": "point", "intensity": 100.0 }),
            json!({ "translation": [0.0, 2.0, 0.0] }),
        )],
    );
    doc["materials"][0] = json!({});
    let report = bake_json(dir.path(), "in", &doc, &[]);
    let warned = report
        .warnings
        .iter()
        .filter(|w| w.contains("--max-reflectance 0.98") && w.contains("material 0"))
        .count();
    assert_eq!(warned, 1, "{:?}", report.warnings);
    for e in &report.elements {
        assert_eq!(e.rho, [0.98; 3]);
        for c in 0..3 {
            let expect = e.direct[c];
            assert!((e.b[c] - expect).abs() <= 1e-12 * expect.max(1.0), "{e:?}");
            assert!(e.direct[c] > 0.0);
        }
    }
}
