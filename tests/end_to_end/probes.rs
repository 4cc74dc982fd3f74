//! `--probes`: the `BAKE_irradiance_probes` extension in both glTF outputs (validator clean),
//! and the paper's cube (the exact solution at subdiv 7): each probe's SH coefficients
//! against an independent brute force over directions (the ray's exit point from the unit
//! cube, its element found by the grid of the report's element centroids), the irradiance
//! the L2 coefficients reconstruct against the brute force's within the stated truncation
//! bound.

use crate::common::bake;
use bake_testkit::{fixture, validate_clean};
use serde_json::Value;
use std::f64::consts::PI;
use std::path::Path;

/// Subdivisions of each cube wall.
const N: usize = 7;

/// The extension of the first scene of the glTF at `path`, and its accessors' data (f32 or u8
/// as f64) read from the `.bin` beside it.
pub(crate) fn probes_of(path: &Path) -> (Value, Vec<f64>, Vec<f64>, Vec<f64>) {
    let text = std::fs::read_to_string(path).expect("read glTF");
    let doc: Value = serde_json::from_str(&text).expect("glTF JSON");
    let used = doc["extensionsUsed"].as_array().expect("extensionsUsed");
    assert!(used.iter().any(|e| e == "BAKE_irradiance_probes"));
    let required = doc["extensionsRequired"].as_array();
    assert!(required.is_none_or(|r| !r.iter().any(|e| e == "BAKE_irradiance_probes")));
    let ext = doc["scenes"][0]["extensions"]["BAKE_irradiance_probes"].clone();
    let uri = doc["buffers"][0]["uri"].as_str().expect("buffer uri");
    let bin = std::fs::read(path.with_file_name(uri)).expect("read .bin");
    let read = |key: &str| -> Vec<f64> {
        let accessor = &doc["accessors"][ext[key].as_u64().expect("accessor") as usize];
        let view = &doc["bufferViews"][accessor["bufferView"].as_u64().expect("view") as usize];
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let count = accessor["count"].as_u64().expect("count") as usize;
        let per = match accessor["type"].as_str() {
            Some("VEC3") => 3,
            _ => 1,
        };
        let data = &bin[start..];
        match accessor["componentType"].as_u64() {
            Some(5126) => (0..count * per)
                .map(|i| {
                    let b = [
                        data[4 * i],
                        data[4 * i + 1],
                        data[4 * i + 2],
                        data[4 * i + 3],
                    ];
                    f64::from(f32::from_le_bytes(b))
                })
                .collect(),
            Some(5121) => data[..count].iter().map(|&b| f64::from(b)).collect(),
            other => panic!("component type {other:?}"),
        }
    };
    let (positions, coefficients, valid) = (read("positions"), read("coefficients"), read("valid"));
    (ext, positions, coefficients, valid)
}

/// Per cube wall (axis, side), the b of its N × N elements, from the report's centroids.
fn wall_table(report: &bake_job::report::Report) -> Vec<[f64; 3]> {
    let mut table = vec![[f64::NAN; 3]; 6 * N * N];
    for e in &report.elements {
        let axis = (0..3).find(|&k| e.normal[k].abs() > 0.5).expect("an axis");
        // The wall at 0 faces +axis (inward), the wall at 1 faces −axis.
        let side = usize::from(e.normal[axis] < 0.0);
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let cell = |x: f64| ((x * N as f64).floor() as usize).min(N - 1);
        table[(axis * 2 + side) * N * N + cell(e.centroid[a]) * N + cell(e.centroid[b])] = e.b;
    }
    assert!(
        table.iter().all(|b| b[0].is_finite()),
        "every cell has an element"
    );
    table
}

/// The nine three.js SH basis functions.
fn basis(d: [f64; 3]) -> [f64; 9] {
    let (x, y, z) = (d[0], d[1], d[2]);
    [
        0.282_094_791_773_878_1,
        0.488_602_511_902_919_9 * y,
        0.488_602_511_902_919_9 * z,
        0.488_602_511_902_919_9 * x,
        1.092_548_430_592_079 * x * y,
        1.092_548_430_592_079 * y * z,
        0.315_391_565_252_520_05 * (3.0 * z * z - 1.0),
        1.092_548_430_592_079 * x * z,
        0.546_274_215_296_039_5 * (x * x - y * y),
    ]
}

/// The six axis directions: +x, −x, +y, −y, +z, −z.
fn axes() -> [[f64; 3]; 6] {
    std::array::from_fn(|m| {
        let mut d = [0.0; 3];
        d[m / 2] = if m % 2 == 0 { 1.0 } else { -1.0 };
        d
    })
}

/// Brute force at `p` inside the unit cube: n × 2n jittered strata of (cos θ, φ); each
/// direction leaves the cube through one wall cell. Returns the SH coefficients of b/π, ∫ L²
/// per band and the irradiance ∫ L max(n·ω, 0) for the six axes.
#[allow(clippy::type_complexity)]
fn brute_force(
    p: [f64; 3],
    table: &[[f64; 3]],
    n: usize,
) -> ([[f64; 3]; 9], [f64; 3], [[f64; 3]; 6]) {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let w = 4.0 * PI / (2 * n * n) as f64;
    let (mut sh, mut square, mut irradiance) = ([[0.0; 3]; 9], [0.0; 3], [[0.0; 3]; 6]);
    for i in 0..n {
        for j in 0..2 * n {
            let z = -1.0 + 2.0 * (i as f64 + next()) / n as f64;
            let phi = PI * (j as f64 + next()) / n as f64;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let d = [s * phi.cos(), s * phi.sin(), z];
            // The wall the ray leaves through: the smallest positive distance to a plane.
            let (mut t, mut wall) = (f64::INFINITY, 0);
            for axis in 0..3 {
                if d[axis] != 0.0 {
                    let (to, side) = if d[axis] > 0.0 { (1.0, 1) } else { (0.0, 0) };
                    let ta = (to - p[axis]) / d[axis];
                    if ta < t {
                        (t, wall) = (ta, axis * 2 + side);
                    }
                }
            }
            let axis = wall / 2;
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let cell = |x: f64| ((x * N as f64).floor().max(0.0) as usize).min(N - 1);
            let x = [p[0] + t * d[0], p[1] + t * d[1], p[2] + t * d[2]];
            let l = table[wall * N * N + cell(x[a]) * N + cell(x[b])].map(|v| v / PI);
            let y = basis(d);
            for (k, yk) in y.iter().enumerate() {
                for band in 0..3 {
                    sh[k][band] += l[band] * yk * w;
                }
            }
            for band in 0..3 {
                square[band] += l[band] * l[band] * w;
            }
            for (m, axis) in axes().iter().enumerate() {
                let c = (d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2]).max(0.0);
                for band in 0..3 {
                    irradiance[m][band] += l[band] * c * w;
                }
            }
        }
    }
    (sh, square, irradiance)
}

/// three.js's `shGetIrradianceAt`, exact constants: Σ Â_l c_lm Y_lm(n).
pub(crate) fn reconstruct(sh: &[[f64; 3]; 9], n: [f64; 3]) -> [f64; 3] {
    let kernel = [PI, 2.0 * PI / 3.0, 2.0 * PI / 3.0, 2.0 * PI / 3.0]
        .into_iter()
        .chain([PI / 4.0; 5]);
    let y = basis(n);
    let mut out = [0.0; 3];
    for ((c, a), yk) in sh.iter().zip(kernel).zip(y) {
        for band in 0..3 {
            out[band] += a * c[band] * yk;
        }
    }
    out
}

#[test]
fn cube_probes_match_a_brute_force_and_both_outputs_carry_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("cube.gltf");
    let report_path = dir.path().join("report.json");
    let run = bake([
        fixture("cube.gltf").as_os_str(),
        out.as_os_str(),
        "--subdiv".as_ref(),
        "7".as_ref(),
        "--probes".as_ref(),
        "grid:0.25".as_ref(),
        "--target".as_ref(),
        "both".as_ref(),
        "--report".as_ref(),
        report_path.as_os_str(),
        "--quiet".as_ref(),
    ])
    .success();
    assert!(run.error_lines().is_empty(), "{run:?}");
    let report = bake_job::report::read_report(&report_path).expect("report");
    let summary = report.probes.expect("a probes summary");
    assert_eq!((summary.count, summary.valid, summary.moved), (64, 64, 0));
    let lightmap = dir.path().join("cube.lightmap.gltf");
    validate_clean(&[out.clone(), lightmap.clone()]);

    let (ext, positions, coefficients, valid) = probes_of(&out);
    assert_eq!(ext["count"], 64);
    assert_eq!(ext["grid"]["counts"], serde_json::json!([4, 4, 4]));
    assert_eq!(ext["grid"]["spacing"], 0.25);
    assert!(valid.iter().all(|&v| v == 1.0));
    // The lightmap glTF carries the same probes.
    let (ext_l, positions_l, coefficients_l, _) = probes_of(&lightmap);
    assert_eq!(
        (ext_l["count"].clone(), positions_l),
        (ext["count"].clone(), positions.clone())
    );
    assert_eq!(coefficients_l, coefficients);

    let table = wall_table(&report);
    let t = ::probes::sh::truncation_factor();
    // A corner cell's probe, one nearer the middle, one by the light (z = 1).
    for probe in [0usize, 21, 4 + 16 * 3 + 1] {
        let p = [0, 1, 2].map(|k| positions[3 * probe + k]);
        let got: [[f64; 3]; 9] =
            std::array::from_fn(|k| [0, 1, 2].map(|b| coefficients[27 * probe + 3 * k + b]));
        let (want, square, exact) = brute_force(p, &table, 1200);
        for band in 0..3 {
            let c0 = want[0][band];
            for k in 0..9 {
                let diff = (got[k][band] - want[k][band]).abs();
                assert!(
                    diff < 1e-3 * c0,
                    "probe {p:?} band {band} c{k}: {} vs {} ({:.1e} of c0)",
                    got[k][band],
                    want[k][band],
                    diff / c0
                );
            }
            let kept: f64 = got.iter().map(|c| c[band] * c[band]).sum();
            let bound = t * (square[band] - kept).max(0.0).sqrt();
            for (m, axis) in axes().iter().enumerate() {
                let e = reconstruct(&got, *axis)[band];
                let err = (e - exact[m][band]).abs();
                eprintln!(
                    "probe {p:?} {axis:?} band {band}: L2 {e:.5}, brute force {:.5}, \
                     truncation {:.2}% (bound {:.2}%)",
                    exact[m][band],
                    100.0 * err / exact[m][band],
                    100.0 * bound / exact[m][band]
                );
                assert!(err <= bound, "probe {p:?} axis {axis:?} band {band}");
            }
        }
    }
}

/// Bakes fixture `name` into `out` with `args` (quietly); the run.
fn bake_fixture(name: &str, out: &Path, args: &[&str]) -> crate::common::Run {
    let mut all = vec![fixture(name).into_os_string(), out.as_os_str().to_owned()];
    all.extend(args.iter().map(std::ffi::OsString::from));
    bake(all)
}

#[test]
fn probes_off_writes_no_extension() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("cube.gltf");
    bake_fixture("cube.gltf", &out, &["--subdiv", "3", "--quiet"]).success();
    let text = std::fs::read_to_string(&out).expect("read glTF");
    assert!(!text.contains("BAKE_irradiance_probes"));
}

#[test]
fn bad_probe_options_are_refused() {
    for bad in ["grid:0", "grid:-1", "grid:x", "on"] {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("cube.gltf");
        let run = bake_fixture("cube.gltf", &out, &["--probes", bad]);
        assert_eq!(run.code, Some(2), "{bad}: {run:?}");
        assert!(!out.exists());
    }
}

/// Two rooms joined by a doorway in a 0.2 m partition (x 3.9–4.1; the doorway z 1.5–2.5,
/// y < 2), probes every 8/17 m, so that a column of grid points (x = 4) lies inside the
/// partition: those, and points too near the floor, are moved or invalid, and no valid
/// probe is inside the partition or nearer a surface than a quarter spacing (checked here on the fixture's stated geometry, not with the
/// probes' rays).
#[test]
fn probes_in_or_near_walls_are_moved_or_invalid() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("rooms.gltf");
    let report_path = dir.path().join("report.json");
    let report_arg = report_path.to_str().expect("a UTF-8 temporary path");
    bake_fixture(
        "two-rooms.gltf",
        &out,
        &[
            "--subdiv",
            "2",
            "--probes",
            "grid:0.4706",
            "--target",
            "vertex",
            "--report",
            report_arg,
            "--quiet",
        ],
    )
    .success();
    let summary = bake_job::report::read_report(&report_path)
        .expect("report")
        .probes
        .expect("probes");
    let (ext, positions, _, valid) = probes_of(&out);
    assert_eq!(ext["grid"]["counts"], serde_json::json!([17, 6, 9]));
    assert_eq!(summary.count, 918);
    assert!(summary.moved > 100, "{summary:?}");
    let origin = [0, 1, 2].map(|k| ext["grid"]["origin"][k].as_f64().expect("origin"));
    let mut inside = 0;
    for i in (0..918).filter(|i| i % 17 == 8) {
        let grid = [
            origin[0] + 8.0 * 0.4706,
            origin[1] + (i / 17 % 6) as f64 * 0.4706,
        ];
        let z = origin[2] + (i / 102) as f64 * 0.4706;
        assert!((grid[0] - 4.0).abs() < 1e-9, "{grid:?}");
        if grid[1] < 2.0 && (1.5..=2.5).contains(&z) {
            continue;
        }
        inside += 1;
        let moved = (positions[3 * i] - 4.0).abs() > 1e-6;
        assert!(valid[i] == 0.0 || moved, "probe {i} stays in the partition");
    }
    assert!(inside > 30, "{inside}");
    // A quarter spacing along the check's 64 rays: at least 0.9 of it straight to the
    // surface (the rays' directions are up to ~25° from its normal).
    let clearance = 0.9 * 0.4706 / 4.0;
    for (i, &v) in valid.iter().enumerate() {
        if v == 0.0 {
            continue;
        }
        let p = [0, 1, 2].map(|k| positions[3 * i + k]);
        // In the doorway's cross-section, how far from its jambs and lintel.
        let opening = (p[1] < 2.0 && (1.5..=2.5).contains(&p[2]))
            .then(|| (p[2] - 1.5).min(2.5 - p[2]).min(2.0 - p[1]));
        let slab = (p[0] - 4.1).max(3.9 - p[0]);
        let to_partition = match opening {
            Some(edge) if slab <= 0.0 => edge,
            Some(edge) => slab.hypot(edge),
            None => slab,
        };
        let to_room = [p[0], 8.0 - p[0], p[1], 2.5 - p[1], p[2], 4.0 - p[2]]
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        assert!(
            to_partition >= clearance && to_room >= clearance,
            "valid probe {i} at {p:?}: {to_partition} from the partition, {to_room} from the room"
        );
    }
}

/// The paper's cube with probe nodes marked in `extras`: a parent moved by (0.1, 0.1, 0.1)
/// holding a marked child at (0.15, 0.15, 0.15) (world (0.25, 0.25, 0.25), grid probe 0's
/// point at `grid:0.5`) and a marked root node at (0.3, 0.6, 0.4); two nodes whose
/// `bake_probe` is `false` or a string mark nothing.
fn cube_with_marked_probes(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(fixture("cube-embedded.gltf")).expect("read the cube");
    let mut doc: Value = serde_json::from_str(&text).expect("glTF JSON");
    let nodes = doc["nodes"].as_array_mut().expect("nodes");
    let first = nodes.len();
    nodes.extend([
        serde_json::json!({"name": "parent", "translation": [0.1, 0.1, 0.1], "children": [first + 1]}),
        serde_json::json!({"name": "marked child", "translation": [0.15, 0.15, 0.15],
                           "extras": {"bake_probe": true}}),
        serde_json::json!({"name": "marked", "translation": [0.3, 0.6, 0.4],
                           "extras": {"bake_probe": true, "note": "kept"}}),
        serde_json::json!({"name": "not marked", "translation": [0.5, 0.5, 0.5],
                           "extras": {"bake_probe": false}}),
        serde_json::json!({"name": "not marked either", "translation": [0.5, 0.5, 0.5],
                           "extras": {"bake_probe": "true"}}),
    ]);
    let roots = doc["scenes"][0]["nodes"]
        .as_array_mut()
        .expect("scene nodes");
    roots.extend([first, first + 2, first + 3, first + 4].map(|n| serde_json::json!(n)));
    let input = dir.join("marked.gltf");
    crate::common::write_json(&input, &doc);
    input
}

/// Nodes marked `"bake_probe": true` are probes at their world origins, after the grid's, in
/// the order the scene is walked, not moved; the one at grid probe 0's point has its
/// coefficients. With `--probes off` they are not baked, and a warning says so.
#[test]
fn marked_nodes_are_probes_after_the_grid() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = cube_with_marked_probes(dir.path());
    let out = dir.path().join("out.gltf");
    let run = bake([
        input.as_os_str(),
        out.as_os_str(),
        "--subdiv".as_ref(),
        "3".as_ref(),
        "--probes".as_ref(),
        "grid:0.5".as_ref(),
        "--quiet".as_ref(),
    ])
    .success();
    assert!(run.warning_lines().is_empty(), "{run:?}");
    let (ext, positions, coefficients, valid) = probes_of(&out);
    assert_eq!(ext["grid"]["counts"], serde_json::json!([2, 2, 2]));
    assert_eq!(ext["count"], 10);
    assert_eq!(valid, vec![1.0; 10]);
    let at = |i: usize| [0, 1, 2].map(|k| positions[3 * i + k]);
    let near = |p: [f64; 3], q: [f64; 3]| (0..3).all(|k| (p[k] - q[k]).abs() < 1e-6);
    assert!(near(at(0), [0.25, 0.25, 0.25]), "{:?}", at(0));
    assert!(near(at(8), [0.25, 0.25, 0.25]), "{:?}", at(8));
    assert!(near(at(9), [0.3, 0.6, 0.4]), "{:?}", at(9));
    for k in 0..27 {
        let (grid, marked) = (coefficients[k], coefficients[27 * 8 + k]);
        assert!(
            (grid - marked).abs() <= 1e-6 * coefficients[0],
            "{k}: {grid} vs {marked}"
        );
    }

    let off = dir.path().join("off.gltf");
    let run = bake([
        input.as_os_str(),
        off.as_os_str(),
        "--subdiv".as_ref(),
        "3".as_ref(),
    ])
    .success();
    let warnings = run.warning_lines().join("\n");
    assert!(
        warnings.contains("2 node(s) marked \"bake_probe\" not baked"),
        "{run:?}"
    );
    let doc: Value =
        serde_json::from_str(&std::fs::read_to_string(&off).expect("read")).expect("JSON");
    assert!(doc["scenes"][0].get("extensions").is_none(), "{doc}");
}

/// `--target baked-texture` carries the probes too (validator clean): the same grid and
/// arrays as the vertex bake of the same scene.
#[test]
fn the_baked_texture_output_carries_the_probes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut read = Vec::new();
    for target in ["vertex", "baked-texture"] {
        let out = dir.path().join(format!("{target}.gltf"));
        bake_fixture(
            "cube.gltf",
            &out,
            &[
                "--subdiv", "3", "--probes", "grid:0.5", "--target", target, "--quiet",
            ],
        )
        .success();
        validate_clean(std::slice::from_ref(&out));
        read.push(probes_of(&out));
    }
    let (vertex, baked) = (&read[0], &read[1]);
    assert_eq!(baked.0["count"], 8);
    assert_eq!(baked.0["grid"], vertex.0["grid"]);
    assert_eq!(baked.0["exposure"], vertex.0["exposure"]);
    assert_eq!(
        (&baked.1, &baked.2, &baked.3),
        (&vertex.1, &vertex.2, &vertex.3)
    );
    assert!(baked.2[0] > 0.0);
}
