//! The rasterizer on small hand-made glTF files: colours at projected points, depth test,
//! culling, node transforms, perspective-correct interpolation, near-plane clipping, camera
//! choice, determinism and errors.

use bake_preview::{
    load, render, render_file, render_scene, srgb8, write_png, CameraChoice, ColorSource, Options,
    PreviewError, BACKGROUND,
};
use serde_json::{json, Value};
use std::f64::consts::FRAC_1_SQRT_2;
use std::path::{Path, PathBuf};

// ---- building test files ----

/// One node with one non-indexed triangle-list mesh.
struct Node {
    positions: Vec<[f32; 3]>,
    colors: Option<Vec<[f32; 3]>>,
    double_sided: bool,
    /// glTF node properties merged in (translation, scale, matrix, …).
    transform: Value,
}

impl Node {
    /// Two triangles: the axis-aligned square [x0, x1] × [y0, y1] at depth z, counter-clockwise
    /// seen from +Z, in one colour.
    fn square(x0: f32, y0: f32, x1: f32, y1: f32, z: f32, color: [f32; 3]) -> Node {
        let positions = vec![
            [x0, y0, z],
            [x1, y0, z],
            [x1, y1, z],
            [x0, y0, z],
            [x1, y1, z],
            [x0, y1, z],
        ];
        Node {
            colors: Some(vec![color; positions.len()]),
            positions,
            double_sided: false,
            transform: json!({}),
        }
    }

    /// The same triangles wound the other way (their front faces −Z).
    fn reversed(mut self) -> Node {
        for t in self.positions.chunks_mut(3) {
            t.swap(1, 2);
        }
        self
    }

    fn with_transform(mut self, transform: Value) -> Node {
        self.transform = transform;
        self
    }

    fn double_sided(mut self) -> Node {
        self.double_sided = true;
        self
    }
}

/// Writes `<dir>/<name>.gltf` + `<name>.bin` with `nodes` (and an optional camera node, given
/// as node properties) and returns the .gltf path.
fn write_scene(dir: &Path, name: &str, nodes: &[Node], camera: Option<Value>) -> PathBuf {
    let mut bin: Vec<u8> = Vec::new();
    let mut accessors = Vec::new();
    let mut views = Vec::new();
    let mut meshes = Vec::new();
    let mut node_values = Vec::new();
    let mut materials = Vec::new();
    let mut push = |data: &[[f32; 3]], bounds: bool| -> usize {
        let offset = bin.len();
        for v in data.iter().flatten() {
            bin.extend(v.to_le_bytes());
        }
        views.push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": data.len() * 12 }));
        let mut accessor = json!({
            "bufferView": views.len() - 1, "componentType": 5126,
            "count": data.len(), "type": "VEC3"
        });
        if bounds {
            let min: Vec<f32> = (0..3)
                .map(|a| data.iter().map(|p| p[a]).fold(f32::INFINITY, f32::min))
                .collect();
            let max: Vec<f32> = (0..3)
                .map(|a| data.iter().map(|p| p[a]).fold(f32::NEG_INFINITY, f32::max))
                .collect();
            accessor["min"] = json!(min);
            accessor["max"] = json!(max);
        }
        accessors.push(accessor);
        accessors.len() - 1
    };
    for (k, node) in nodes.iter().enumerate() {
        let mut attributes = json!({ "POSITION": push(&node.positions, true) });
        if let Some(colors) = &node.colors {
            attributes["COLOR_0"] = json!(push(colors, false));
        }
        materials.push(json!({ "doubleSided": node.double_sided }));
        meshes.push(json!({ "primitives": [{ "attributes": attributes, "material": k }] }));
        let mut value = json!({ "name": format!("node{k}"), "mesh": k });
        if let (Some(target), Some(extra)) = (value.as_object_mut(), node.transform.as_object()) {
            target.extend(extra.clone());
        }
        node_values.push(value);
    }
    let mut root = json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len(), "uri": format!("{name}.bin") }],
    });
    if let Some(mut camera) = camera {
        camera["camera"] = json!(0);
        node_values.push(camera);
        root["cameras"] = json!([{
            "type": "perspective",
            "perspective": { "yfov": 0.8, "znear": 0.01 }
        }]);
    }
    let roots: Vec<usize> = (0..node_values.len()).collect();
    root["nodes"] = json!(node_values);
    root["scenes"] = json!([{ "nodes": roots }]);
    std::fs::write(dir.join(format!("{name}.bin")), &bin).expect("write the .bin");
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_vec_pretty(&root).expect("JSON")).expect("write");
    path
}

fn srgb(color: [f64; 3]) -> [u8; 3] {
    color.map(srgb8)
}

fn pixel_at(image: &image::RgbImage, p: [f64; 2]) -> [u8; 3] {
    image.get_pixel(p[0].floor() as u32, p[1].floor() as u32).0
}

const GREY: [f32; 3] = [0.2, 0.5, 0.8];
const RED: [f32; 3] = [0.9, 0.1, 0.1];
const GREEN: [f32; 3] = [0.1, 0.9, 0.1];

fn f64s(c: [f32; 3]) -> [f64; 3] {
    c.map(f64::from)
}

// ---- tests ----

#[test]
fn a_square_shows_its_colour_where_its_points_project() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = write_scene(
        dir.path(),
        "square",
        &[Node::square(0.0, 0.0, 1.0, 1.0, 0.0, GREY)],
        None,
    );
    let options = Options::default();
    let preview = render_file(&path, &options).expect("render");
    assert_eq!(
        preview.choice,
        CameraChoice::Framing {
            view: [0.0, 0.0, -1.0]
        }
    );
    assert_eq!(preview.image.dimensions(), (512, 512));
    assert_eq!(preview.stats.rasterized, 2);
    for x in [0.05, 0.3, 0.5, 0.9] {
        for y in [0.1, 0.5, 0.95] {
            let p = preview
                .camera
                .project([x, y, 0.0], 512, 512)
                .expect("in front of the camera");
            assert_eq!(pixel_at(&preview.image, p), srgb(f64s(GREY)), "({x}, {y})");
        }
    }
    // The framing camera leaves a margin: the image's corners are background.
    assert_eq!(preview.image.get_pixel(0, 0).0, srgb(BACKGROUND));
    assert_eq!(preview.image.get_pixel(511, 511).0, srgb(BACKGROUND));
    // ... and the square fills most of the frame (it is fitted, not lost in the middle).
    let covered = preview
        .image
        .pixels()
        .filter(|p| p.0 == srgb(f64s(GREY)))
        .count();
    assert!(covered > 512 * 512 * 8 / 10, "{covered} pixels");
}

#[test]
fn the_nearer_triangle_wins_in_either_order() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // Looking down −Z, z = 0.5 is nearer than z = 0.
    let far = || Node::square(0.0, 0.0, 1.0, 1.0, 0.0, RED);
    let near = || Node::square(0.25, 0.25, 0.75, 0.75, 0.5, GREEN);
    for (name, nodes) in [
        ("far-first", [far(), near()]),
        ("near-first", [near(), far()]),
    ] {
        let path = write_scene(dir.path(), name, &nodes, None);
        let preview = render_file(&path, &Options::default()).expect("render");
        let centre = preview
            .camera
            .project([0.5, 0.5, 0.5], 512, 512)
            .expect("visible");
        assert_eq!(
            pixel_at(&preview.image, centre),
            srgb(f64s(GREEN)),
            "{name}"
        );
        let edge = preview
            .camera
            .project([0.1, 0.1, 0.0], 512, 512)
            .expect("visible");
        assert_eq!(pixel_at(&preview.image, edge), srgb(f64s(RED)), "{name}");
    }
}

#[test]
fn back_faces_are_culled_unless_the_material_is_double_sided() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let away = write_scene(
        dir.path(),
        "away",
        &[Node::square(0.0, 0.0, 1.0, 1.0, 0.0, GREY).reversed()],
        None,
    );
    let preview = render_file(&away, &Options::default()).expect("render");
    assert_eq!(preview.stats.culled, 2);
    assert!(preview.image.pixels().all(|p| p.0 == srgb(BACKGROUND)));

    let both = write_scene(
        dir.path(),
        "both",
        &[Node::square(0.0, 0.0, 1.0, 1.0, 0.0, GREY)
            .reversed()
            .double_sided()],
        None,
    );
    let preview = render_file(&both, &Options::default()).expect("render");
    assert_eq!(preview.stats.culled, 0);
    let p = preview
        .camera
        .project([0.5, 0.5, 0.0], 512, 512)
        .expect("visible");
    assert_eq!(pixel_at(&preview.image, p), srgb(f64s(GREY)));
}

#[test]
fn node_transforms_place_the_triangles_and_a_mirror_keeps_the_front() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = write_scene(
        dir.path(),
        "moved",
        &[
            Node::square(0.0, 0.0, 1.0, 1.0, 0.0, RED),
            Node::square(0.0, 0.0, 1.0, 1.0, 0.0, GREEN)
                .with_transform(json!({ "translation": [2.0, 0.0, 0.0] })),
            // Mirrored in x: the triangles land on [−2, −1] and, by glTF's rule, still face +Z.
            Node::square(1.0, 0.0, 2.0, 1.0, 0.0, GREY)
                .with_transform(json!({ "scale": [-1.0, 1.0, 1.0] })),
        ],
        None,
    );
    let preview = render_file(&path, &Options::default()).expect("render");
    assert_eq!(preview.stats.culled, 0);
    for (point, color) in [
        ([0.5, 0.5, 0.0], RED),
        ([2.5, 0.5, 0.0], GREEN),
        ([-1.5, 0.5, 0.0], GREY),
    ] {
        let p = preview.camera.project(point, 512, 512).expect("visible");
        assert_eq!(pixel_at(&preview.image, p), srgb(f64s(color)), "{point:?}");
    }
}

/// The world point seen through the centre of pixel (i, j), on the plane y = 0.
fn floor_point(camera: &bake_preview::Camera, i: u32, j: u32, size: u32) -> [f64; 3] {
    let tan_y = (camera.yfov / 2.0).tan();
    let tan_x = tan_y * camera.aspect;
    let ndc_x = (f64::from(i) + 0.5) / f64::from(size) * 2.0 - 1.0;
    let ndc_y = 1.0 - (f64::from(j) + 0.5) / f64::from(size) * 2.0;
    let ray: [f64; 3] = std::array::from_fn(|a| {
        camera.forward[a] + ndc_x * tan_x * camera.right[a] + ndc_y * tan_y * camera.up[a]
    });
    let t = -camera.eye[1] / ray[1];
    std::array::from_fn(|a| camera.eye[a] + t * ray[a])
}

#[test]
fn colours_are_interpolated_perspective_correctly() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // A floor (y = 0, facing +Y) from z = 0 to z = −4 whose red channel is −z / 4.
    let corners = |x: f32, z: f32| ([x, 0.0, z], [-z / 4.0, 0.5, 0.0]);
    let quad = [
        corners(0.0, 0.0),
        corners(1.0, 0.0),
        corners(1.0, -4.0),
        corners(0.0, 0.0),
        corners(1.0, -4.0),
        corners(0.0, -4.0),
    ];
    let node = Node {
        positions: quad.iter().map(|c| c.0).collect(),
        colors: Some(quad.iter().map(|c| c.1).collect()),
        double_sided: false,
        transform: json!({}),
    };
    let path = write_scene(dir.path(), "floor", &[node], None);
    let scene = load(&path, ColorSource::Color0).expect("load");
    let options = Options {
        view: Some([0.0, -1.0, -1.0]),
        ..Options::default()
    };
    let (camera, _) = bake_preview::choose_camera(&scene, &options).expect("a camera");
    let (frame, stats) = render(&scene, &camera, 512, 512, BACKGROUND);
    assert_eq!(stats.rasterized, 2);
    let mut checked = 0;
    for j in (0..512).step_by(7) {
        for i in (0..512).step_by(7) {
            let index = (j * 512 + i) as usize;
            if frame.depth[index].is_infinite() {
                continue;
            }
            let p = floor_point(&camera, i, j, 512);
            let expected = -p[2] / 4.0;
            let got = frame.pixels[index][0];
            assert!(
                (got - expected).abs() < 1e-9,
                "pixel ({i}, {j}) at {p:?}: {got} vs {expected}"
            );
            checked += 1;
        }
    }
    assert!(checked > 1000, "{checked} pixels checked");
}

#[test]
fn geometry_behind_a_camera_node_is_clipped() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // A long floor at y = −1 under a camera at the origin looking down −Z: part of it is
    // behind the camera.
    let floor = Node::square(-5.0, -5.0, 5.0, 5.0, 0.0, GREY).with_transform(json!({
        "rotation": [-FRAC_1_SQRT_2, 0.0, 0.0, FRAC_1_SQRT_2],
        "translation": [0.0, -1.0, 0.0]
    }));
    let path = write_scene(
        dir.path(),
        "inside",
        &[floor],
        Some(json!({ "name": "eye" })),
    );
    let preview = render_file(&path, &Options::default()).expect("render");
    assert_eq!(
        preview.choice,
        CameraChoice::Node {
            name: Some("eye".into())
        }
    );
    assert_eq!(preview.camera.eye, [0.0; 3]);
    // Bottom half: floor; top half: background.
    assert_eq!(preview.image.get_pixel(256, 500).0, srgb(f64s(GREY)));
    assert_eq!(preview.image.get_pixel(256, 10).0, srgb(BACKGROUND));
    let p = preview
        .camera
        .project([0.0, -1.0, -3.0], 512, 512)
        .expect("visible");
    assert_eq!(pixel_at(&preview.image, p), srgb(f64s(GREY)));

    // --view overrides the camera node: the framing camera sees the whole floor.
    let options = Options {
        view: Some([0.0, -1.0, 0.0]),
        ..Options::default()
    };
    let framed = render_file(&path, &options).expect("render");
    assert!(matches!(framed.choice, CameraChoice::Framing { .. }));
    assert_eq!(framed.image.get_pixel(256, 256).0, srgb(f64s(GREY)));
}

#[test]
fn radiosity_source_scales_and_clamps() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = write_scene(
        dir.path(),
        "exposed",
        &[Node::square(0.0, 0.0, 1.0, 1.0, 0.0, [0.1, 0.3, 0.6])],
        None,
    );
    // No _RADIOSITY: COLOR_0 × exposure, clamped.
    let options = Options {
        colors: ColorSource::Radiosity { exposure: 2.0 },
        ..Options::default()
    };
    let preview = render_file(&path, &options).expect("render");
    let p = preview
        .camera
        .project([0.5, 0.5, 0.0], 512, 512)
        .expect("visible");
    assert_eq!(
        pixel_at(&preview.image, p),
        srgb([f64::from(0.1f32) * 2.0, f64::from(0.3f32) * 2.0, 1.0])
    );
}

#[test]
fn renders_and_pngs_are_deterministic() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = write_scene(
        dir.path(),
        "two",
        &[
            Node::square(0.0, 0.0, 1.0, 1.0, 0.0, RED),
            Node::square(0.2, 0.1, 0.9, 0.7, 0.3, GREEN),
        ],
        None,
    );
    let scene = load(&path, ColorSource::Color0).expect("load");
    let options = Options {
        width: 300,
        height: 200,
        view: Some([0.3, -0.2, -1.0]),
        ..Options::default()
    };
    let a = render_scene(&scene, &options).expect("render");
    let b = render_scene(&scene, &options).expect("render");
    assert_eq!(a.image, b.image);
    let (pa, pb) = (dir.path().join("a.png"), dir.path().join("b.png"));
    write_png(&pa, &a.image).expect("write");
    write_png(&pb, &b.image).expect("write");
    let bytes = std::fs::read(&pa).expect("read");
    assert_eq!(bytes, std::fs::read(&pb).expect("read"));
    assert_eq!(&bytes[1..4], b"PNG");
    let decoded = image::load_from_memory(&bytes).expect("decode").to_rgb8();
    assert_eq!(decoded, a.image);
}

#[test]
fn errors_name_the_problem_and_leave_no_files() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let missing = render_file(&dir.path().join("absent.gltf"), &Options::default());
    let error = missing.expect_err("a missing file");
    assert!(error.is_input_error());
    assert!(error.to_string().contains("absent.gltf"), "{error}");

    let square = write_scene(
        dir.path(),
        "square",
        &[Node::square(0.0, 0.0, 1.0, 1.0, 0.0, GREY)],
        None,
    );
    for options in [
        Options {
            view: Some([0.0; 3]),
            ..Options::default()
        },
        Options {
            width: 0,
            ..Options::default()
        },
        Options {
            height: bake_preview::MAX_SIZE + 1,
            ..Options::default()
        },
    ] {
        let error = render_file(&square, &options).expect_err("bad options");
        assert!(matches!(error, PreviewError::Options(_)), "{error}");
    }

    let empty = dir.path().join("empty.gltf");
    std::fs::write(
        &empty,
        r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[]}]}"#,
    )
    .expect("write");
    let error = render_file(&empty, &Options::default()).expect_err("nothing to draw");
    assert!(error.to_string().contains("no triangles"), "{error}");

    // A node that is its own child: refused, not followed forever.
    let cycle = write_scene(
        dir.path(),
        "cycle",
        &[Node::square(0.0, 0.0, 1.0, 1.0, 0.0, GREY).with_transform(json!({ "children": [0] }))],
        None,
    );
    let error = render_file(&cycle, &Options::default()).expect_err("a cycle");
    assert!(error.is_input_error());
    assert!(error.to_string().contains("appears twice"), "{error}");

    let preview = render_file(&square, &Options::default()).expect("render");
    let out = tempfile::tempdir().expect("a temporary directory");
    let error = write_png(
        &out.path().join("no-such-dir").join("x.png"),
        &preview.image,
    )
    .expect_err("a missing directory");
    assert!(!error.is_input_error());
    assert_eq!(std::fs::read_dir(out.path()).expect("list").count(), 0);
}

#[test]
fn srgb_encoding() {
    assert_eq!(srgb8(0.0), 0);
    assert_eq!(srgb8(1.0), 255);
    assert_eq!(srgb8(2.0), 255);
    assert_eq!(srgb8(-1.0), 0);
    assert_eq!(srgb8(f64::NAN), 0);
    assert_eq!(srgb8(0.5), 188);
    assert_eq!(srgb8(0.2159), 128);
    assert_eq!(srgb8(0.002), 7);
}

#[test]
fn shared_edges_leave_no_gaps() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // A 9×9 grid of squares (each its own two triangles, as a flat bake writes them), seen
    // obliquely so that edges cross pixel centres at odd slopes.
    let n = 9;
    let mut nodes = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x0, y0) = (i as f32 / n as f32, j as f32 / n as f32);
            let (x1, y1) = ((i + 1) as f32 / n as f32, (j + 1) as f32 / n as f32);
            let shade = (i * n + j) as f32 / (n * n) as f32;
            nodes.push(Node::square(x0, y0, x1, y1, 0.0, [shade, 1.0 - shade, 0.5]));
        }
    }
    let path = write_scene(dir.path(), "grid", &nodes, None);
    for view in [[0.3, -0.2, -1.0], [-0.7, 0.4, -1.0], [0.0, 0.0, -1.0]] {
        let options = Options {
            width: 257,
            height: 193,
            view: Some(view),
            ..Options::default()
        };
        let preview = render_file(&path, &options).expect("render");
        let corners = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]].map(|[x, y]| {
            preview
                .camera
                .project([x, y, 0.0], 257, 193)
                .expect("visible")
        });
        let mut inside = 0;
        for (x, y, pixel) in preview.image.enumerate_pixels() {
            let p = [f64::from(x) + 0.5, f64::from(y) + 0.5];
            // At least 1.5 px inside every edge of the projected square (clockwise on screen).
            let well_inside = (0..4).all(|k| {
                let (a, b) = (corners[k], corners[(k + 1) % 4]);
                let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
                let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
                -cross / length > 1.5
            });
            if well_inside {
                inside += 1;
                assert_ne!(pixel.0, srgb(BACKGROUND), "{view:?}: gap at ({x}, {y})");
            }
        }
        assert!(inside > 10_000, "{view:?}: {inside} pixels inside");
    }
}
