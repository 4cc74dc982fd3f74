//! Input cases that need a decision: duplicate coincident faces, winding that disagrees
//! across shared edges, zero-filled accessors, and reading scenes from memory.

use bake_importer::{
    load, load_bytes, load_obj_bytes, load_with, Format, ImportError, Options, Scene,
};
use bake_testkit::GltfBuilder;
use glam::DVec3;
use serde_json::json;

fn write_and_load(builder: &GltfBuilder) -> Result<Scene, ImportError> {
    let dir = tempfile::tempdir().expect("tempdir");
    load(&builder.write_embedded(&dir.path().join("scene.gltf")))
}

/// One mesh of indexed triangles on one node, with an optional material.
fn mesh(points: &[[f32; 3]], indices: &[u16], material: Option<serde_json::Value>) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let material = material.map(|m| b.material(m));
    let mesh = b.triangle_mesh("Mesh", points, Some(indices), material);
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    b
}

fn warnings_with(scene: &Scene, text: &str) -> Vec<String> {
    scene
        .warnings
        .iter()
        .filter(|w| w.contains(text))
        .cloned()
        .collect()
}

const SQUARE: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];

/// Unit cube corners: index x + 2y + 4z.
const CUBE: [[f32; 3]; 8] = [
    [0., 0., 0.],
    [1., 0., 0.],
    [0., 1., 0.],
    [1., 1., 0.],
    [0., 0., 1.],
    [1., 0., 1.],
    [0., 1., 1.],
    [1., 1., 1.],
];

/// The cube's six faces as quads, counter-clockwise seen from outside; the top (+z) last.
const CUBE_QUADS: [[u16; 4]; 6] = [
    [0, 2, 3, 1],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 4, 6, 2],
    [1, 3, 7, 5],
    [4, 5, 7, 6],
];

/// The cube as 12 triangles; the quads listed in `flipped` are wound inwards.
fn cube_indices(flipped: &[usize]) -> Vec<u16> {
    let mut indices = Vec::new();
    for (q, &[a, b, c, d]) in CUBE_QUADS.iter().enumerate() {
        if flipped.contains(&q) {
            indices.extend([a, c, b, a, d, c]);
        } else {
            indices.extend([a, b, c, a, c, d]);
        }
    }
    indices
}

#[test]
fn duplicate_faces_are_dropped_with_one_warning() {
    // The square's two triangles, then both again: one from another starting vertex.
    let scene =
        write_and_load(&mesh(&SQUARE, &[0, 1, 2, 0, 2, 3, 1, 2, 0, 0, 2, 3], None)).expect("loads");
    assert_eq!(scene.polygons.len(), 1, "one quad: {:?}", scene.polygons);
    assert_eq!(scene.stats.duplicates_dropped, 2);
    assert_eq!(scene.stats.faces_read, 4);
    assert_eq!(scene.stats.against_winding, 0);
    let warnings = warnings_with(&scene, "duplicate");
    assert_eq!(warnings.len(), 1, "{:?}", scene.warnings);
    assert!(
        warnings[0].contains("dropped 2 duplicate face(s)"),
        "{warnings:?}"
    );
    assert!(warnings[0].contains("mesh \"Mesh\""), "{warnings:?}");
    let area: f64 = scene.polygons.iter().map(|p| area(&p.vertices)).sum();
    assert!((area - 1.0).abs() < 1e-12, "area counted once: {area}");
}

#[test]
fn duplicate_vertices_at_the_same_position_are_the_same_face() {
    // An unwelded copy of the triangle's vertices (as exporters write for split normals).
    let points = [
        SQUARE[0], SQUARE[1], SQUARE[2], SQUARE[0], SQUARE[1], SQUARE[2],
    ];
    let scene = write_and_load(&mesh(&points, &[0, 1, 2, 3, 4, 5], None)).expect("loads");
    assert_eq!(scene.polygons.len(), 1);
    assert_eq!(scene.stats.duplicates_dropped, 1);
}

#[test]
fn opposite_coincident_faces_are_a_two_sided_sheet() {
    let scene = write_and_load(&mesh(&SQUARE, &[0, 1, 2, 0, 2, 1], None)).expect("loads");
    assert_eq!(scene.polygons.len(), 2, "both sides kept");
    let normals: Vec<DVec3> = scene.polygons.iter().map(|p| p.normal).collect();
    assert!((normals[0] - DVec3::Z).length() < 1e-12, "{normals:?}");
    assert!((normals[1] + DVec3::Z).length() < 1e-12, "{normals:?}");
    assert_eq!(scene.stats.duplicates_dropped, 0);
    assert_eq!(scene.stats.against_winding, 0);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

#[test]
fn reversed_copy_under_a_double_sided_material_is_a_duplicate() {
    let material = json!({ "doubleSided": true });
    let scene = write_and_load(&mesh(&SQUARE, &[0, 1, 2, 0, 2, 1], Some(material))).expect("loads");
    // The first face's front and back; the reversed copy would repeat both.
    assert_eq!(scene.polygons.len(), 2);
    assert_eq!(scene.stats.duplicates_dropped, 1);
    assert_eq!(warnings_with(&scene, "duplicate").len(), 1);
}

#[test]
fn consistently_wound_closed_mesh_gives_no_warning() {
    let scene = write_and_load(&mesh(&CUBE, &cube_indices(&[]), None)).expect("loads");
    assert_eq!(scene.polygons.len(), 6, "12 triangles merge into 6 quads");
    assert_eq!(scene.stats.against_winding, 0);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let centre = DVec3::splat(0.5);
    for p in &scene.polygons {
        assert!(
            (p.vertices[0] - centre).dot(p.normal) > 0.0,
            "faces out: {p:?}"
        );
    }
}

#[test]
fn faces_wound_against_their_neighbours_are_kept_with_one_warning() {
    // The top quad (two triangles) is wound inwards.
    let scene = write_and_load(&mesh(&CUBE, &cube_indices(&[5]), None)).expect("loads");
    assert_eq!(scene.stats.against_winding, 2);
    let warnings = warnings_with(&scene, "wound opposite");
    assert_eq!(warnings.len(), 1, "{:?}", scene.warnings);
    assert!(warnings[0].contains("2 face(s)"), "{warnings:?}");
    // Kept as authored: the top faces down, into the cube.
    let top: Vec<_> = scene
        .polygons
        .iter()
        .filter(|p| p.vertices.iter().all(|v| v.z == 1.0))
        .collect();
    assert!(!top.is_empty());
    for p in top {
        assert!((p.normal + DVec3::Z).length() < 1e-12, "{p:?}");
    }
    // The minority is counted: flipping five of six quads gives the same count.
    let scene = write_and_load(&mesh(&CUBE, &cube_indices(&[0, 1, 2, 3, 4]), None)).expect("loads");
    assert_eq!(scene.stats.against_winding, 2);
}

#[test]
fn a_flipped_triangle_in_an_open_sheet_is_counted() {
    // Two squares side by side; the last triangle is wound clockwise.
    let points = [
        [0., 0., 0.],
        [1., 0., 0.],
        [2., 0., 0.],
        [0., 1., 0.],
        [1., 1., 0.],
        [2., 1., 0.],
    ];
    let scene =
        write_and_load(&mesh(&points, &[0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 4, 5], None)).expect("loads");
    assert_eq!(scene.stats.against_winding, 1);
    assert_eq!(warnings_with(&scene, "wound opposite").len(), 1);
}

#[test]
fn winding_is_not_checked_for_double_sided_materials() {
    let material = json!({ "doubleSided": true });
    let scene = write_and_load(&mesh(&CUBE, &cube_indices(&[5]), Some(material))).expect("loads");
    assert_eq!(scene.stats.against_winding, 0);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

#[test]
fn obj_duplicate_faces_and_winding() {
    let obj = "\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0
v 2 1 0
f 1 2 3 4
f 3 4 1 2
f 2 6 5
f 2 5 6
f 2 3 6
";
    let scene = load_obj_bytes(obj.as_bytes(), None).expect("loads");
    // `f 3 4 1 2` repeats `f 1 2 3 4`; `f 2 6 5` and `f 2 5 6` are a two-sided sheet;
    // `f 2 3 6` shares edge 2-3 with the quad in the same direction.
    assert_eq!(scene.stats.duplicates_dropped, 1);
    assert_eq!(scene.polygons.len(), 4);
    assert_eq!(scene.stats.against_winding, 1, "{:?}", scene.stats);
}

#[test]
fn accessor_without_buffer_view_is_zeros() {
    // Valid glTF 2.0: an accessor without a buffer view holds zeros. Its triangle has no
    // area; the square beside it bakes.
    let mut b = GltfBuilder::new();
    let square = b.primitive(&SQUARE, Some(&[0, 1, 2, 0, 2, 3]), None, 4);
    let zeros = b.positions(&[[0.; 3]; 3]);
    b.root["accessors"][zeros]
        .as_object_mut()
        .expect("object")
        .remove("bufferView");
    let mesh = b.mesh(
        "Mesh",
        vec![square, json!({ "attributes": { "POSITION": zeros } })],
    );
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    let scene = write_and_load(&b).expect("loads");
    assert_eq!(scene.polygons.len(), 1);
    assert_eq!(scene.stats.degenerate_dropped, 1);
}

#[test]
fn load_bytes_reads_gltf_glb_and_obj_from_memory() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = mesh(&SQUARE, &[0, 1, 2, 0, 2, 3], None);
    let embedded = b.write_embedded(&dir.path().join("a.gltf"));
    let glb = b.write_glb(&dir.path().join("a.glb"));
    let from_file = load(&embedded).expect("loads");
    for path in [&embedded, &glb] {
        let bytes = std::fs::read(path).expect("read");
        let scene = load_bytes(&bytes, Format::Gltf).expect("loads from memory");
        assert_eq!(scene.polygons, from_file.polygons);
    }

    // An external buffer cannot be read from memory: a one-line error.
    let external = b.write_external(&dir.path().join("b.gltf"));
    let bytes = std::fs::read(&external).expect("read");
    let error = load_bytes(&bytes, Format::Gltf).expect_err("external buffer");
    assert!(matches!(error, ImportError::Gltf(_)), "{error}");
    assert!(error.to_string().contains("external"), "{error}");
    assert!(!error.to_string().contains('\n'));

    let obj = "mtllib any.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\n";
    let mtl = "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 2 3\n";
    let scene = load_obj_bytes(obj.as_bytes(), Some(mtl.as_bytes())).expect("loads");
    assert_eq!(scene.materials[0].emission, [1.0, 2.0, 3.0]);
    let scene = load_bytes(obj.as_bytes(), Format::Obj).expect("loads without the MTL");
    assert_eq!(
        scene.materials[scene.polygons[0].material].emission,
        [0.0; 3]
    );
    assert_eq!(warnings_with(&scene, "material library").len(), 1);
}

#[cfg(unix)]
#[test]
fn buffer_or_material_library_that_is_not_a_regular_file_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = mesh(&SQUARE, &[0, 1, 2, 0, 2, 3], None);
    let path = b.write_external(&dir.path().join("c.gltf"));
    let text = std::fs::read_to_string(&path).expect("read");
    std::fs::write(&path, text.replace("\"c.bin\"", "\"file:///dev/zero\"")).expect("write");
    // Outside the scene's folder: refused unless allowed, then refused as no regular file.
    let error = load(&path).expect_err("outside the folder");
    assert!(
        error.to_string().contains("--allow-outside-paths"),
        "{error}"
    );
    let allow = Options {
        allow_outside_paths: true,
    };
    let error = load_with(&path, &allow).expect_err("not a regular file");
    assert!(error.to_string().contains("not a regular file"), "{error}");
    // Inside the folder, through a link.
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("z.bin")).expect("symlink");
    std::fs::write(&path, text.replace("\"c.bin\"", "\"z.bin\"")).expect("write");
    let error = load_with(&path, &allow).expect_err("not a regular file");
    assert!(error.to_string().contains("not a regular file"), "{error}");

    let obj = dir.path().join("d.obj");
    std::fs::write(
        &obj,
        "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .expect("write");
    let error = load(&obj).expect_err("outside the folder");
    assert!(
        error.to_string().contains("--allow-outside-paths"),
        "{error}"
    );
    let scene = load_with(&obj, &allow).expect("loads with the default material");
    assert_eq!(warnings_with(&scene, "not a regular file").len(), 1);
    // The files read, in order: the OBJ only (the library was not).
    assert_eq!(scene.input_files, vec![obj.clone()]);
}

/// Twice-area / 2 of a planar polygon (Newell).
fn area(v: &[DVec3]) -> f64 {
    let n = v.len();
    (0..n)
        .map(|i| (v[i] - v[0]).cross(v[(i + 1) % n] - v[0]))
        .sum::<DVec3>()
        .length()
        / 2.0
}

#[test]
fn node_flattened_by_a_zero_scale_is_skipped_with_a_warning() {
    // The square lies in z = 0, so scale z = 0 keeps its area, but the node's transform
    // cannot be inverted to write the bake back: the node is skipped.
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Mesh", &SQUARE, Some(&[0, 1, 2, 0, 2, 3]), None);
    let kept = b.node(json!({ "mesh": mesh }));
    let flat = b.node(json!({ "name": "Flat", "mesh": mesh, "scale": [1., 1., 0.] }));
    b.scene(&[kept, flat]);
    let scene = write_and_load(&b).expect("loads");
    assert_eq!(scene.polygons.len(), 1);
    assert!(scene.polygons.iter().all(|p| p.origin.node == kept));
    let warnings = warnings_with(&scene, "singular");
    assert_eq!(warnings.len(), 1, "{:?}", scene.warnings);
    assert!(warnings[0].contains("node \"Flat\" (1)"), "{warnings:?}");
}

#[test]
fn a_scene_with_too_many_faces_in_all_instances_is_refused() {
    // 2^20 zero indices (an accessor without a buffer view) make 349,525 triangles; 16
    // nodes using the mesh make 5.6 million faces, more than the importer's 2^22.
    let mut b = GltfBuilder::new();
    let position = b.positions(&SQUARE);
    let indices = b.accessor(
        &[],
        bake_testkit::UNSIGNED_INT,
        "SCALAR",
        1 << 20,
        json!({}),
    );
    b.root["accessors"][indices]
        .as_object_mut()
        .expect("object")
        .remove("bufferView");
    let mesh = b.mesh(
        "Many",
        vec![json!({ "attributes": { "POSITION": position }, "indices": indices })],
    );
    let nodes: Vec<usize> = (0..16).map(|_| b.node(json!({ "mesh": mesh }))).collect();
    b.scene(&nodes);
    let error = write_and_load(&b).expect_err("too many faces");
    assert!(matches!(error, ImportError::TooLarge(_)), "{error}");
    // A fixed limit, not this machine's memory: the same on every machine.
    assert!(!error.is_too_large());
    assert!(error.to_string().contains("4194304"), "{error}");
}
