//! `--target baked-texture`, end to end: the written glTF's unlit base-colour texture, read
//! through its own `TEXCOORD_1` at every element centre, shows the report's ρ × H + e (times
//! the exposure, sRGB-encoded, 8-bit) within 2/255; on a textured floor, the base-colour
//! texture's own texel at that point times H (the element's mean ρ is not what the surface
//! shows there). Flat shading, so that bilinear sampling at an element's centre reads the
//! element's own H.

use crate::common::{self, bake};
use crate::textures::{floor_scene, png, srgb_to_linear};
use bake_job::report::{ElementEntry, Report};
use bake_testkit::fixture;
use glam::{DMat4, DVec2, DVec3};
use std::path::{Path, PathBuf};

/// One triangle of the written glTF in world space, with its `TEXCOORD_1` and the image its
/// material's base-colour texture shows.
struct Triangle {
    p: [DVec3; 3],
    uv: [DVec2; 3],
    image: usize,
}

/// What a baked-texture glTF shows.
struct Written {
    triangles: Vec<Triangle>,
    images: Vec<gltf::image::Data>,
    exposure: f64,
}

/// Bakes `input` to `dir/out.gltf` with `--target baked-texture --shading flat` and `args`;
/// the report and the written files.
fn bake_baked(input: &Path, dir: &Path, args: &[&str]) -> (Report, PathBuf) {
    let out = dir.join("out.gltf");
    let report = dir.join("report.json");
    let mut all: Vec<&std::ffi::OsStr> = vec![
        "--quiet".as_ref(),
        "--target".as_ref(),
        "baked-texture".as_ref(),
        "--shading".as_ref(),
        "flat".as_ref(),
        input.as_os_str(),
        out.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
    ];
    all.extend(args.iter().map(std::ffi::OsStr::new));
    bake(all).success();
    (
        bake_job::report::read_report(&report).expect("the report"),
        out,
    )
}

fn read_written(path: &Path) -> Written {
    let (document, buffers, images) = gltf::import(path).expect("the baked glTF reads");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).expect("read the glTF")).expect("JSON");
    let extras = &json["extras"];
    let exposure = extras["bake_baked_texture"]["exposure"]
        .as_f64()
        .expect("the exposure in the extras");
    let mut triangles = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4)> = document
        .default_scene()
        .expect("a scene")
        .nodes()
        .map(|n| (n, DMat4::IDENTITY))
        .collect();
    while let Some((node, parent)) = stack.pop() {
        let local = node.transform().matrix().map(|c| c.map(f64::from));
        let world = parent * DMat4::from_cols_array_2d(&local);
        for child in node.children() {
            stack.push((child, world));
        }
        let Some(mesh) = node.mesh() else { continue };
        for primitive in mesh.primitives() {
            let material = primitive.material();
            assert!(material.unlit(), "every material is unlit");
            let pbr = material.pbr_metallic_roughness();
            assert_eq!(pbr.base_color_factor(), [1.0; 4]);
            let info = pbr.base_color_texture().expect("a base-colour texture");
            assert_eq!(info.tex_coord(), 1);
            let image = info.texture().source().index();
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<DVec3> = reader
                .read_positions()
                .expect("positions")
                .map(|p| world.transform_point3(DVec3::from_array(p.map(f64::from))))
                .collect();
            let uvs: Vec<DVec2> = reader
                .read_tex_coords(1)
                .expect("TEXCOORD_1")
                .into_f32()
                .map(|t| DVec2::new(f64::from(t[0]), f64::from(t[1])))
                .collect();
            assert!(
                reader.read_colors(0).is_none(),
                "no COLOR_0 on top of the bake"
            );
            let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
            for t in indices.chunks_exact(3) {
                let k = [t[0], t[1], t[2]].map(|i| i as usize);
                triangles.push(Triangle {
                    p: k.map(|i| positions[i]),
                    uv: k.map(|i| uvs[i]),
                    image,
                });
            }
        }
    }
    Written {
        triangles,
        images,
        exposure,
    }
}

/// The texture coordinate and image at world point `x` on a surface facing `normal`: the
/// written triangle that holds it (barycentric, in its plane, facing the same way).
fn lookup(written: &Written, x: DVec3, normal: DVec3) -> Option<(DVec2, usize)> {
    written.triangles.iter().find_map(|t| {
        let n = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
        let area2 = n.length_squared();
        if area2 == 0.0 || n.normalize().dot(normal) < 0.99 {
            return None;
        }
        if (x - t.p[0]).dot(n.normalize()).abs() > 1e-5 {
            return None;
        }
        let w0 = (t.p[1] - x).cross(t.p[2] - x).dot(n) / area2;
        let w1 = (t.p[2] - x).cross(t.p[0] - x).dot(n) / area2;
        let w2 = 1.0 - w0 - w1;
        (w0 >= -1e-9 && w1 >= -1e-9 && w2 >= -1e-9)
            .then(|| (t.uv[0] * w0 + t.uv[1] * w1 + t.uv[2] * w2, t.image))
    })
}

/// The image's 8-bit texel values at `uv`, bilinear as a GPU samples level 0 (clamp to edge).
fn sample(image: &gltf::image::Data, uv: DVec2) -> [f64; 3] {
    let (w, h) = (i64::from(image.width), i64::from(image.height));
    let channels = match image.format {
        gltf::image::Format::R8G8B8 => 3,
        gltf::image::Format::R8G8B8A8 => 4,
        other => panic!("unexpected image format {other:?}"),
    };
    let at = |i: i64, j: i64| -> [f64; 3] {
        let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
        let k = (j * w + i) as usize * channels;
        [0, 1, 2].map(|c| f64::from(image.pixels[k + c]))
    };
    let (x, y) = (uv.x * w as f64 - 0.5, uv.y * h as f64 - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (i, j) = (x0 as i64, y0 as i64);
    let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
    std::array::from_fn(|k| {
        (1.0 - fy) * ((1.0 - fx) * a[k] + fx * b[k]) + fy * ((1.0 - fx) * c[k] + fx * d[k])
    })
}

/// The sRGB encoding (IEC 61966-2-1), written out independently of the exporter's.
fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The 8-bit level (unrounded) a linear displayed value should have.
fn level(value: f64, exposure: f64) -> f64 {
    linear_to_srgb((value * exposure).clamp(0.0, 1.0)) * 255.0
}

/// Element centres compared, those within 2/255, and the largest difference (levels), for
/// the expected linear value `expected(element)`.
fn compare(
    report: &Report,
    written: &Written,
    expected: impl Fn(&ElementEntry) -> [f64; 3],
) -> (usize, usize, f64) {
    let (mut compared, mut within, mut worst) = (0, 0, 0.0f64);
    for element in &report.elements {
        let centre = DVec3::from_array(element.centroid);
        let Some((uv, image)) = lookup(written, centre, DVec3::from_array(element.normal)) else {
            continue;
        };
        let shown = sample(&written.images[image], uv);
        let want = expected(element).map(|v| level(v, written.exposure));
        let diff = (0..3)
            .map(|c| (shown[c] - want[c]).abs())
            .fold(0.0, f64::max);
        compared += 1;
        worst = worst.max(diff);
        if diff <= 2.0 {
            within += 1;
        }
    }
    (compared, within, worst)
}

fn rho_h_plus_e(element: &ElementEntry) -> [f64; 3] {
    let h = element.h.expect("the report has H");
    std::array::from_fn(|c| element.rho[c] * h[c] + element.e[c])
}

#[test]
fn cornell_box_texels_show_rho_h_plus_e_at_element_centres() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (report, out) = bake_baked(&fixture("cornell.gltf"), dir.path(), &[]);
    assert_eq!(
        bake_testkit::file_names(dir.path()),
        ["out.baked.png", "out.bin", "out.gltf", "report.json"]
    );
    let written = read_written(&out);
    let (compared, within, worst) = compare(&report, &written, rho_h_plus_e);
    eprintln!(
        "cornell: {within} of {compared} element centres within 2/255 (of {} elements), \
         largest difference {worst:.2} levels, exposure {}",
        report.elements.len(),
        written.exposure
    );
    assert_eq!(
        compared,
        report.elements.len(),
        "every centre is on a chart"
    );
    assert!(within as f64 >= 0.99 * compared as f64);
    // Without ρ (H + e) the texels do not match: the test sees what it claims to.
    let (_, without_rho, _) = compare(&report, &written, |el| {
        let h = el.h.expect("H");
        std::array::from_fn(|c| h[c] + el.e[c])
    });
    assert!(
        (without_rho as f64) < 0.5 * compared as f64,
        "{without_rho} of {compared} centres match H + e"
    );
    if let Some(stdout) = bake_testkit::validate_clean(&[out]) {
        assert!(!stdout.contains("UNSUPPORTED_EXTENSION"), "{stdout}");
    }
}

/// The textured floor's 2 × 2 texture (8-bit sRGB, row-major) and base-colour factor.
const FLOOR_COLOURS: [[u8; 3]; 4] = [[230, 60, 40], [40, 200, 90], [70, 90, 220], [250, 240, 200]];
const FLOOR_FACTOR: [f64; 3] = [0.9, 0.8, 1.0];

/// `dir/floor.gltf`: the textures tests' lit floor with a 2 × 2 texture of [`FLOOR_COLOURS`]
/// (NEAREST when `nearest`: four colours, each constant over a quarter of the floor).
fn textured_floor(dir: &Path, nearest: bool) -> PathBuf {
    let texture = png(2, 2, |x, y| FLOOR_COLOURS[(y * 2 + x) as usize]);
    let input = dir.join("floor.gltf");
    common::write_json(&input, &floor_scene(FLOOR_FACTOR, Some((texture, nearest))));
    input
}

/// What the textured floor's surface shows at element `el`'s centre: ρ × H + e with ρ the
/// NEAREST texture's texel there (the floor's TEXCOORD_0 is ((x + 5) / 10, (z + 5) / 10))
/// times the factor; elsewhere the element's own ρ × H + e.
fn floor_surface(el: &ElementEntry) -> [f64; 3] {
    let h = el.h.expect("H");
    let on_floor = el.normal[1] > 0.5 && el.centroid[1].abs() < 1e-9;
    if !on_floor {
        return rho_h_plus_e(el);
    }
    let u = (el.centroid[0] + 5.0) / 10.0;
    let v = (el.centroid[2] + 5.0) / 10.0;
    let (x, y) = (
        ((u * 2.0).floor() as usize).min(1),
        ((v * 2.0).floor() as usize).min(1),
    );
    let texel = FLOOR_COLOURS[y * 2 + x];
    std::array::from_fn(|c| {
        FLOOR_FACTOR[c] * srgb_to_linear(f64::from(texel[c]) / 255.0) * h[c] + el.e[c]
    })
}

#[test]
fn a_textured_floor_shows_the_texture_texel_times_h() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = textured_floor(dir.path(), true);
    let factor = FLOOR_FACTOR;
    let (report, out) = bake_baked(&input, dir.path(), &["--exposure", "auto"]);
    let written = read_written(&out);
    let (compared, within, worst) = compare(&report, &written, floor_surface);
    eprintln!(
        "textured floor: {within} of {compared} element centres within 2/255 (of {}), \
         largest difference {worst:.2} levels, exposure {}",
        report.elements.len(),
        written.exposure
    );
    assert_eq!(compared, report.elements.len());
    assert!(within as f64 >= 0.99 * compared as f64);
    // Without the texture (the factor alone) the floor's texels do not match.
    let (_, factor_only, _) = compare(&report, &written, |el| {
        let h = el.h.expect("H");
        std::array::from_fn(|c| factor[c] * h[c] + el.e[c])
    });
    eprintln!("textured floor, the factor without the texture: {factor_only} of {compared}");
    assert!((factor_only as f64) < 0.5 * compared as f64);
    if let Some(files) = bake_testkit::validate_clean(&[out]) {
        assert!(!files.is_empty());
    }
}

#[test]
fn a_glb_embeds_every_atlas_and_several_atlases_get_their_own_png() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path().join("out.glb");
    bake([
        "--quiet".as_ref(),
        "--target".as_ref(),
        "baked-texture".as_ref(),
        fixture("cornell.gltf").as_os_str(),
        out.as_os_str(),
    ])
    .success();
    assert_eq!(bake_testkit::file_names(dir.path()), ["out.glb"]);
    let gltf_out = dir.path().join("many.gltf");
    bake([
        "--quiet",
        "--target",
        "baked-texture",
        "--lightmap-max",
        "256",
        fixture("cornell.gltf").to_str().expect("UTF-8 path"),
        gltf_out.to_str().expect("UTF-8 path"),
    ])
    .success();
    let names = bake_testkit::file_names(dir.path());
    assert!(names.contains(&"many.baked-1.png".to_string()), "{names:?}");
    let written = read_written(&gltf_out);
    assert!(written.images.len() > 1);
    bake_testkit::validate_clean(&[out, gltf_out]);
}

/// Runs a `tools/` check on the baked-texture bake `out` (its report beside it) with `extra`
/// arguments and asserts that it succeeded, compared at least `at_least` element centres
/// and found none past 2 levels; its last `PREFIX {...}` line as JSON.
fn run_check(
    tool: &str,
    out: &Path,
    extra: &[&std::ffi::OsStr],
    prefix: &str,
    at_least: u64,
) -> serde_json::Value {
    let report = out.with_file_name("report.json");
    let checked = std::process::Command::new(bake_testkit::tools_dir().join(tool))
        .args([out.as_os_str(), report.as_os_str()])
        .args(extra)
        .output()
        .expect("run a tools/ check");
    let stdout = String::from_utf8_lossy(&checked.stdout);
    let result: serde_json::Value = stdout
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix(prefix))
        .and_then(|l| serde_json::from_str(l).ok())
        .unwrap_or(serde_json::Value::Null);
    println!("{tool}: {result}");
    assert!(checked.status.success(), "{stdout}");
    assert!(
        result["compared"].as_u64().unwrap_or(0) >= at_least,
        "{result}"
    );
    assert!(
        result["max_levels"].as_f64().unwrap_or(f64::MAX) <= 2.0,
        "{result}"
    );
    result
}

/// [`run_check`] on a flat baked-texture bake of the Cornell box.
fn check_with_tool(tool: &str, extra: &[&str], prefix: &str, at_least: u64) -> serde_json::Value {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (_, out) = bake_baked(&fixture("cornell.gltf"), dir.path(), &[]);
    let extra: Vec<&std::ffi::OsStr> = extra.iter().map(|a| a.as_ref()).collect();
    run_check(tool, &out, &extra, prefix, at_least)
}

/// Blender's own import of the baked-texture bake (its `KHR_materials_unlit` set-up, nothing
/// changed), rendered by Cycles from above: the floor's and the blocks' tops show
/// (ρ × H + e) × exposure within 2/255 at element centres (`tools/blender-cycles-check
/// --baked-texture`; measured 101 centres, at most 1.49 levels). Skipped when Blender is
/// missing, unless `BAKE_REQUIRE_BLENDER=1`.
#[test]
fn blender_shows_the_baked_texture_as_the_report_says() {
    if !bake_testkit::blender_or_skip() {
        return;
    }
    check_with_tool(
        "blender-cycles-check",
        &["--baked-texture"],
        "CYCLES_CHECK ",
        50,
    );
}

/// Blender's own import of the baked-texture bake of the textured floor (a 2 × 2 NEAREST
/// texture under a factor), rendered by Cycles from above: at the centre of every floor
/// element at least 5 cm from the texture cells' borders, the pixel shows factor × the
/// texture's texel × H (+ e) × exposure within 2/255 — the values computed here from the
/// input's texture (`tools/blender-cycles-check --baked-texture --expected`). Skipped when
/// Blender is missing, unless `BAKE_REQUIRE_BLENDER=1`.
#[test]
fn blender_shows_a_textured_baked_texture_as_the_texture_says() {
    if !bake_testkit::blender_or_skip() {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = textured_floor(dir.path(), true);
    let (report, out) = bake_baked(&input, dir.path(), &["--exposure", "auto"]);
    let exposure = read_written(&out).exposure;
    let mut expected = serde_json::Map::new();
    for (k, el) in report.elements.iter().enumerate() {
        let on_floor = el.normal[1] > 0.5 && el.centroid[1].abs() < 1e-9;
        let near_border = el.centroid[0].abs() < 0.05 || el.centroid[2].abs() < 0.05;
        if on_floor && !near_border {
            let value = floor_surface(el).map(|v| v * exposure);
            expected.insert(k.to_string(), serde_json::json!(value));
        }
    }
    assert!(expected.len() >= 50, "{} floor elements", expected.len());
    let expected_path = dir.path().join("expected.json");
    common::write_json(&expected_path, &serde_json::Value::Object(expected));
    run_check(
        "blender-cycles-check",
        &out,
        &[
            "--baked-texture".as_ref(),
            "--expected".as_ref(),
            expected_path.as_os_str(),
        ],
        "CYCLES_CHECK ",
        50,
    );
}

/// three.js' stock GLTFLoader in headless Chromium (`tools/threejs-check`: software WebGL,
/// no tone mapping, sRGB output, nothing else set up) shows (ρ × H + e) × exposure within
/// 2/255 at every element centre, each seen from 1 mm in front along its normal. Skipped
/// when Chromium is missing, unless `BAKE_REQUIRE_THREEJS=1` (or `BAKE_REQUIRE_ALL=1`).
#[test]
fn threejs_shows_the_baked_texture_as_the_report_says() {
    if !bake_testkit::chromium_or_skip() {
        return;
    }
    let result = check_with_tool("threejs-check", &[], "THREEJS_CHECK ", 900);
    assert_eq!(
        result["materials"],
        serde_json::json!(["MeshBasicMaterial"])
    );
}

/// The same bytes whatever the thread count (the texels are computed in parallel).
#[test]
fn baked_textures_are_the_same_bytes_for_any_thread_count() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = textured_floor(dir.path(), false);
    common::assert_same_bytes_for_thread_counts(
        dir.path(),
        &input,
        &["1", "2", "3"],
        &["--target", "baked-texture"],
        &["gltf", "bin", "baked.png"],
    );
}

/// An alpha cut-out keeps its cut-out in the baked-texture bake: the grate of `alpha.rs` (a
/// 16 × 16 alpha checkerboard, `MASK`, cutoff 0.5) gets an unlit `MASK` material at the
/// same cutoff and an RGBA atlas whose alpha, read through the grate's own `TEXCOORD_1` at
/// the centre of every checker cell, is 0 where the cell is open and 255 where it is not;
/// the floor's material stays `OPAQUE` and its texels' alpha 255.
#[test]
fn an_alpha_cut_out_keeps_its_cut_out() {
    use crate::alpha::{open, scene, CELLS};
    let dir = tempfile::tempdir().expect("a temporary directory");
    let input = dir.path().join("grate.gltf");
    common::write_json(&input, &scene("MASK", false));
    let (_, out) = bake_baked(&input, dir.path(), &[]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).expect("read the glTF")).expect("JSON");
    let modes: Vec<(String, Option<f64>)> = json["materials"]
        .as_array()
        .expect("materials")
        .iter()
        .map(|m| {
            (
                m["alphaMode"].as_str().unwrap_or("OPAQUE").to_string(),
                m["alphaCutoff"].as_f64(),
            )
        })
        .collect();
    assert!(
        modes.contains(&("MASK".to_string(), Some(0.5))),
        "{modes:?}"
    );
    assert!(modes.contains(&("OPAQUE".to_string(), None)), "{modes:?}");
    let written = read_written(&out);
    let alpha = |image: &gltf::image::Data, uv: DVec2| {
        assert_eq!(image.format, gltf::image::Format::R8G8B8A8);
        let x = ((uv.x * f64::from(image.width)) as usize).min(image.width as usize - 1);
        let y = ((uv.y * f64::from(image.height)) as usize).min(image.height as usize - 1);
        image.pixels[4 * (y * image.width as usize + x) + 3]
    };
    let (mut open_cells, mut closed_cells) = (0, 0);
    for j in 0..CELLS {
        for i in 0..CELLS {
            // TEXCOORD_0 u = (x + 1)/2, v = (z + 1)/2 on the grate (y = 2, facing down).
            let u = (i as f64 + 0.5) / CELLS as f64;
            let v = (j as f64 + 0.5) / CELLS as f64;
            let point = DVec3::new(2.0 * u - 1.0, 2.0, 2.0 * v - 1.0);
            let (uv, image) = lookup(&written, point, DVec3::NEG_Y).expect("a grate point");
            let a = alpha(&written.images[image], uv);
            if open(i, j) {
                assert_eq!(a, 0, "cell ({i}, {j})");
                open_cells += 1;
            } else {
                assert_eq!(a, 255, "cell ({i}, {j})");
                closed_cells += 1;
            }
        }
    }
    assert_eq!((open_cells, closed_cells), (128, 128));
    let (uv, image) = lookup(&written, DVec3::new(1.5, 0.0, 1.5), DVec3::Y).expect("the floor");
    assert_eq!(alpha(&written.images[image], uv), 255);
    bake_testkit::validate_clean(&[out]);
}
