//! glTF import: scenes written programmatically, results checked against hand-computed
//! numbers.

use bake_importer::{load, ImportError, Polygon, Scene, Side, Transform};
use bake_testkit::GltfBuilder;
use glam::{DMat4, DVec3};
use serde_json::{json, Value};

const TOL: f64 = 1e-9;

fn d(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < TOL
}

fn assert_vertices(polygon: &Polygon, expected: &[DVec3]) {
    assert_eq!(polygon.vertices.len(), expected.len(), "{polygon:?}");
    for (v, e) in polygon.vertices.iter().zip(expected) {
        assert!(close(*v, *e), "vertex {v} != {e} in {polygon:?}");
    }
}

/// Twice the signed area about the polygon's own normal (> 0 when counter-clockwise).
fn ccw_area(polygon: &Polygon) -> f64 {
    let v = &polygon.vertices;
    let n = v.len();
    (0..n)
        .map(|i| (v[i] - v[0]).cross(v[(i + 1) % n] - v[0]))
        .sum::<DVec3>()
        .dot(polygon.normal)
        / 2.0
}

fn write_and_load(builder: &GltfBuilder) -> Result<Scene, ImportError> {
    let dir = tempfile::tempdir().expect("tempdir");
    load(&builder.write_embedded(&dir.path().join("scene.gltf")))
}

const SQUARE: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
const TRIANGLE: [[f32; 3]; 3] = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]];

/// One mesh on one node in one scene.
fn single(
    points: &[[f32; 3]],
    indices: Option<&[u16]>,
    material: Option<serde_json::Value>,
) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let material = material.map(|m| b.material(m));
    let mesh = b.triangle_mesh("Mesh", points, indices, material);
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    b
}

#[test]
fn two_triangles_of_a_square_merge_into_one_quad() {
    let scene = write_and_load(&single(&SQUARE, Some(&[0, 1, 2, 0, 2, 3]), None)).unwrap();
    assert_eq!(scene.polygons.len(), 1);
    let quad = &scene.polygons[0];
    assert_vertices(
        quad,
        &[d(0., 0., 0.), d(1., 0., 0.), d(1., 1., 0.), d(0., 1., 0.)],
    );
    assert!(close(quad.normal, d(0., 0., 1.)));
    assert!((ccw_area(quad) - 1.0).abs() < TOL);
    assert_eq!(quad.origin.face, 0);
    assert_eq!(scene.stats.faces_read, 2);
    assert_eq!(scene.stats.quads_merged, 1);
    // No material: the glTF default one is appended.
    assert_eq!(scene.materials.len(), 1);
    assert_eq!(scene.materials[0].rho, [1.0; 3]);
    assert_eq!(scene.materials[0].emission, [0.0; 3]);
    assert!(!scene.materials[0].double_sided);
    assert_eq!(quad.material, 0);
}

#[test]
fn triangles_that_are_not_coplanar_stay_triangles() {
    // The square folded along its diagonal 0-2.
    let folded = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.5]];
    let scene = write_and_load(&single(&folded, Some(&[0, 1, 2, 0, 2, 3]), None)).unwrap();
    assert_eq!(scene.polygons.len(), 2);
    assert_eq!(scene.stats.quads_merged, 0);
    assert_eq!(scene.polygons[1].origin.face, 1);
}

#[test]
fn node_hierarchy_composes_trs_and_matrix() {
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    let (s, c) = (
        std::f32::consts::FRAC_1_SQRT_2,
        std::f32::consts::FRAC_1_SQRT_2,
    );
    // Child: a matrix translating by (5, 0, 0), column-major.
    let child = b.node(json!({
        "name": "child", "mesh": mesh,
        "matrix": [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 5., 0., 0., 1.]
    }));
    // Parent: T(1, 2, 3) · R(90° about z) · S(2).
    let parent = b.node(json!({
        "name": "parent", "children": [child],
        "translation": [1., 2., 3.], "rotation": [0., 0., s, c], "scale": [2., 2., 2.]
    }));
    b.scene(&[parent]);
    let scene = write_and_load(&b).unwrap();

    // p → T + R·2·(p + (5, 0, 0)), with R(x, y, z) = (−y, x, z).
    assert_eq!(scene.polygons.len(), 1);
    assert_vertices(
        &scene.polygons[0],
        &[d(1., 12., 3.), d(1., 14., 3.), d(-1., 12., 3.)],
    );
    assert!(close(scene.polygons[0].normal, d(0., 0., 1.)));
    assert_eq!(scene.polygons[0].origin.node, child);

    let nodes = &scene.layout.nodes;
    assert_eq!(nodes[parent].children, vec![child]);
    assert!(matches!(nodes[child].transform, Transform::Matrix(m) if m[12] == 5.0));
    assert!(matches!(
        nodes[parent].transform,
        Transform::Trs {
            scale: [2., 2., 2.],
            ..
        }
    ));
    let expected_child_world = DMat4::from_cols_array(&[
        0., 2., 0., 0., -2., 0., 0., 0., 0., 0., 2., 0., 1., 12., 3., 1.,
    ]);
    assert!(nodes[child].world.abs_diff_eq(expected_child_world, 1e-6));
}

#[test]
fn mirroring_node_keeps_the_normal_on_the_front_side() {
    // Mirror in x: the triangle still faces +z.
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    let mirror_x = b.node(json!({ "mesh": mesh, "scale": [-1., 1., 1.] }));
    let mirror_z =
        b.node(json!({ "mesh": mesh, "scale": [1., 1., -1.], "translation": [0., 0., 5.] }));
    b.scene(&[mirror_x, mirror_z]);
    let scene = write_and_load(&b).unwrap();
    assert_eq!(scene.polygons.len(), 2);

    let x = &scene.polygons[0];
    assert!(close(x.normal, d(0., 0., 1.)), "{x:?}");
    assert!((ccw_area(x) - 0.5).abs() < TOL);
    assert_vertices(x, &[d(0., 0., 0.), d(0., 1., 0.), d(-1., 0., 0.)]);

    // Mirror in z: the front now faces −z.
    let z = &scene.polygons[1];
    assert!(close(z.normal, d(0., 0., -1.)), "{z:?}");
    assert!((ccw_area(z) - 0.5).abs() < TOL);
}

#[test]
fn triangle_strip_decodes_and_merges_into_quads() {
    // Two unit squares side by side as one strip of 4 triangles.
    let strip = [
        [0., 1., 0.],
        [0., 0., 0.],
        [1., 1., 0.],
        [1., 0., 0.],
        [2., 1., 0.],
        [2., 0., 0.],
    ];
    let mut b = GltfBuilder::new();
    let primitive = b.primitive(&strip, None, None, 5);
    let mesh = b.mesh("Strip", vec![primitive]);
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    let scene = write_and_load(&b).unwrap();

    assert_eq!(scene.stats.faces_read, 4);
    assert_eq!(scene.stats.quads_merged, 2);
    assert_eq!(scene.polygons.len(), 2);
    for (polygon, face) in scene.polygons.iter().zip([0, 2]) {
        assert_eq!(polygon.vertices.len(), 4);
        assert_eq!(polygon.origin.face, face);
        assert!(close(polygon.normal, d(0., 0., 1.)));
        assert!((ccw_area(polygon) - 1.0).abs() < TOL);
    }
}

#[test]
fn triangle_fan_decodes_into_a_quad_and_a_triangle() {
    // Fan about the origin: triangles (1,2,0), (2,3,0), (3,4,0).
    let fan = [
        [0., 0., 0.],
        [1., 0., 0.],
        [1., 1., 0.],
        [0., 1., 0.],
        [-1., 0.5, 0.],
    ];
    let mut b = GltfBuilder::new();
    let primitive = b.primitive(&fan, Some(&[0, 1, 2, 3, 4]), None, 6);
    let mesh = b.mesh("Fan", vec![primitive]);
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    let scene = write_and_load(&b).unwrap();

    assert_eq!(scene.stats.faces_read, 3);
    assert_eq!(scene.stats.quads_merged, 1);
    assert_eq!(scene.polygons.len(), 2);
    let areas: Vec<f64> = scene.polygons.iter().map(ccw_area).collect();
    assert!(
        (areas[0] - 1.0).abs() < TOL && (areas[1] - 0.5).abs() < TOL,
        "{areas:?}"
    );
    assert_eq!(scene.polygons[1].origin.face, 2);
    assert_vertices(
        &scene.polygons[1],
        &[d(0., 1., 0.), d(-1., 0.5, 0.), d(0., 0., 0.)],
    );
}

#[test]
fn points_primitive_is_skipped_with_a_warning() {
    let mut b = GltfBuilder::new();
    let points = b.primitive(&TRIANGLE, None, None, 0);
    let triangles = b.primitive(&TRIANGLE, None, None, 4);
    let mesh = b.mesh("Mixed", vec![points, triangles]);
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    let scene = write_and_load(&b).unwrap();

    assert_eq!(scene.polygons.len(), 1);
    assert_eq!(scene.polygons[0].origin.primitive, 1);
    assert_eq!(scene.stats.primitives_skipped, 1);
    assert_eq!(scene.warnings.len(), 1);
    assert!(
        scene.warnings[0].contains("mesh \"Mixed\" (0), primitive 0"),
        "{:?}",
        scene.warnings
    );
    let primitives = &scene.layout.meshes[0].primitives;
    assert!(!primitives[0].baked);
    assert!(primitives[1].baked);
}

#[test]
fn mesh_used_by_two_nodes_is_baked_twice() {
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    let a = b.node(json!({ "mesh": mesh }));
    let c = b.node(json!({ "mesh": mesh, "translation": [10., 0., 0.] }));
    b.scene(&[a, c]);
    let scene = write_and_load(&b).unwrap();

    assert_eq!(scene.polygons.len(), 2);
    assert_eq!(scene.polygons[0].origin.node, a);
    assert_eq!(scene.polygons[1].origin.node, c);
    assert_eq!(scene.polygons[0].origin.mesh, scene.polygons[1].origin.mesh);
    assert_vertices(
        &scene.polygons[1],
        &[d(10., 0., 0.), d(11., 0., 0.), d(10., 1., 0.)],
    );
    assert_eq!(scene.stats.faces_read, 2);
}

#[test]
fn double_sided_material_gives_front_and_back_polygons() {
    let material = json!({ "name": "Paper", "doubleSided": true });
    let scene = write_and_load(&single(&TRIANGLE, None, Some(material))).unwrap();

    assert_eq!(scene.polygons.len(), 2);
    let (front, back) = (&scene.polygons[0], &scene.polygons[1]);
    assert_eq!(front.origin.side, Side::Front);
    assert_eq!(back.origin.side, Side::Back);
    assert_eq!(front.origin.face, back.origin.face);
    assert_eq!(front.material, back.material);
    assert!(close(front.normal, d(0., 0., 1.)));
    assert!(close(back.normal, d(0., 0., -1.)));
    let reversed: Vec<DVec3> = front.vertices.iter().rev().copied().collect();
    assert_eq!(back.vertices, reversed);
    assert!((ccw_area(back) - 0.5).abs() < TOL);
    assert!(scene.materials[0].double_sided);
}

#[test]
fn emissive_strength_multiplies_the_emissive_factor() {
    let material = json!({
        "name": "Lamp",
        "pbrMetallicRoughness": { "baseColorFactor": [0.2, 0.4, 0.6, 1.0] },
        "emissiveFactor": [1.0, 0.5, 0.25],
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 4.0 } }
    });
    let mut b = single(&TRIANGLE, None, Some(material));
    b.root["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
    let scene = write_and_load(&b).unwrap();

    let m = &scene.materials[0];
    assert_eq!(m.name.as_deref(), Some("Lamp"));
    assert_eq!(m.emission, [4.0, 2.0, 1.0]);
    for (got, want) in m.rho.iter().zip([0.2, 0.4, 0.6]) {
        assert!((got - want).abs() < 1e-7);
    }
    assert_eq!(scene.materials.len(), 1, "no default material needed");
}

#[test]
fn blended_materials_transmit_what_their_alpha_does_not_cover_and_masks_are_kept() {
    // (mode, transmission t = 1 − α under BLEND, else 0)
    for (mode, t) in [("OPAQUE", 0.0), ("MASK", 0.0), ("BLEND", 0.25)] {
        let material = json!({
            "name": "Grate", "alphaMode": mode, "alphaCutoff": 0.25,
            "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.5, 0.5, 0.75] }
        });
        let b = single(&TRIANGLE, None, Some(material));
        let scene = write_and_load(&b).unwrap();
        let m = &scene.materials[0];
        assert_eq!(m.transmission, t, "{mode}");
        // ρ_eff = (1 − t) ρ: BLEND reflects α ρ.
        assert_eq!(m.rho, [0.5 * (1.0 - t); 3], "{mode}");
        assert!(
            !scene.warnings.iter().any(|w| w.contains("Grate")),
            "{mode}: {:?}",
            scene.warnings
        );
        let mask = scene.alpha_masks[0];
        if mode == "MASK" {
            assert_eq!(
                mask,
                Some(bake_importer::AlphaMask {
                    cutoff: 0.25,
                    factor: 0.75
                })
            );
        } else {
            assert_eq!(mask, None);
        }
    }
}

#[test]
fn transmission_factor_makes_glass_and_combines_with_blend() {
    let glass = |factor: Value, blend: bool| {
        let mut material = json!({
            "name": "Pane",
            "pbrMetallicRoughness": { "baseColorFactor": [0.8, 0.6, 0.4, 0.5] },
            "extensions": { "KHR_materials_transmission": factor }
        });
        if blend {
            material["alphaMode"] = json!("BLEND");
        }
        let mut b = single(&TRIANGLE, None, Some(material));
        b.root["extensionsUsed"] = json!(["KHR_materials_transmission"]);
        write_and_load(&b)
    };
    // T = 0.75 (exact in f32): t = 0.75, ρ = 0.25 × base.
    let scene = glass(json!({ "transmissionFactor": 0.75 }), false).unwrap();
    assert_eq!(scene.materials[0].transmission, 0.75);
    let base = [0.8f32, 0.6, 0.4].map(f64::from);
    assert_eq!(scene.materials[0].rho, base.map(|r| r * 0.25));
    // With BLEND α = 0.5: t = 1 − (1 − 0.75) 0.5 = 0.875.
    let scene = glass(json!({ "transmissionFactor": 0.75 }), true).unwrap();
    assert_eq!(scene.materials[0].transmission, 0.875);
    // A factor above 1 is refused like ρ > 1.
    let refused = glass(json!({ "transmissionFactor": 1.5 }), false);
    assert!(
        refused
            .as_ref()
            .is_err_and(|e| e.to_string().contains("transmission")),
        "{:?}",
        refused.map(|s| s.materials)
    );
}

#[test]
fn degenerate_triangles_are_dropped_with_one_warning() {
    let points = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [2., 0., 0.]];
    // Face 1 repeats a vertex; face 2 is collinear (zero area).
    let scene = write_and_load(&single(&points, Some(&[0, 1, 2, 0, 0, 1, 0, 1, 3]), None)).unwrap();

    assert_eq!(scene.polygons.len(), 1);
    assert_eq!(scene.stats.faces_read, 3);
    assert_eq!(scene.stats.degenerate_dropped, 2);
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(
        scene.warnings[0].contains("dropped 2 degenerate"),
        "{:?}",
        scene.warnings
    );
}

#[test]
fn nan_position_is_an_error_naming_mesh_and_face() {
    let points = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [f32::NAN, 0., 0.]];
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Broken", &points, Some(&[0, 1, 2, 0, 1, 3]), None);
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    match write_and_load(&b) {
        Err(ImportError::InvalidValue { what, problem }) => {
            assert!(
                what.starts_with("mesh \"Broken\" (0), primitive 0, face 1"),
                "{what}"
            );
            assert!(problem.contains("not finite"), "{problem}");
        }
        other => panic!("expected InvalidValue, got {other:?}"),
    }
}

#[test]
fn reflectance_above_one_is_an_error() {
    let material = json!({
        "name": "Hot",
        "pbrMetallicRoughness": { "baseColorFactor": [1.5, 0.5, 0.5, 1.0] }
    });
    match write_and_load(&single(&TRIANGLE, None, Some(material))) {
        Err(ImportError::InvalidValue { what, problem }) => {
            assert!(what.contains("material \"Hot\" (0)"), "{what}");
            assert!(what.contains("mesh \"Mesh\" (0)"), "{what}");
            assert!(problem.contains("outside [0, 1]"), "{problem}");
        }
        other => panic!("expected InvalidValue, got {other:?}"),
    }
}

#[test]
fn negative_emission_is_an_error() {
    let material = json!({
        "name": "Dark",
        "emissiveFactor": [1.0, 1.0, 1.0],
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": -2.0 } }
    });
    match write_and_load(&single(&TRIANGLE, None, Some(material))) {
        Err(ImportError::InvalidValue { what, problem }) => {
            assert!(what.contains("material \"Dark\" (0)"), "{what}");
            assert!(problem.contains("negative"), "{problem}");
        }
        other => panic!("expected InvalidValue, got {other:?}"),
    }
}

#[test]
fn glb_and_external_buffer_equal_embedded_gltf() {
    let material = json!({ "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.5, 0.5, 1.0] } });
    let b = single(&SQUARE, Some(&[0, 1, 2, 0, 2, 3]), Some(material));
    let dir = tempfile::tempdir().unwrap();
    let mut embedded = load(&b.write_embedded(&dir.path().join("a.gltf"))).unwrap();
    let mut external = load(&b.write_external(&dir.path().join("b.gltf"))).unwrap();
    let mut binary = load(&b.write_glb(&dir.path().join("c.GLB"))).unwrap();
    // The files each read: the scene, and the external buffer beside it.
    assert_eq!(embedded.input_files, vec![dir.path().join("a.gltf")]);
    assert_eq!(
        external.input_files,
        vec![dir.path().join("b.gltf"), dir.path().join("b.bin")]
    );
    assert_eq!(binary.input_files, vec![dir.path().join("c.GLB")]);
    for scene in [&mut embedded, &mut external, &mut binary] {
        scene.input_files.clear();
    }
    assert_eq!(embedded, external);
    assert_eq!(embedded, binary);
    assert_eq!(binary.polygons.len(), 1);
}

#[test]
fn node_cycle_and_two_parents_are_errors() {
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    b.node(json!({ "mesh": mesh, "children": [1] }));
    b.node(json!({ "children": [0] }));
    b.node(json!({}));
    b.scene(&[2]);
    match write_and_load(&b) {
        Err(ImportError::Gltf(message)) => assert!(message.contains("cycle"), "{message}"),
        other => panic!("expected a cycle error, got {other:?}"),
    }

    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    let shared = b.node(json!({ "mesh": mesh }));
    let p = b.node(json!({ "children": [shared] }));
    let q = b.node(json!({ "children": [shared] }));
    b.scene(&[p, q]);
    match write_and_load(&b) {
        Err(ImportError::Gltf(message)) => assert!(message.contains("two parents"), "{message}"),
        other => panic!("expected a two-parents error, got {other:?}"),
    }
}

#[test]
fn default_scene_is_baked_and_layout_keeps_everything() {
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    let unused_mesh = b.triangle_mesh("Unused", &SQUARE, Some(&[0, 1, 2]), None);
    let a = b.node(json!({ "name": "A", "mesh": mesh }));
    let c = b.node(json!({ "name": "C", "mesh": unused_mesh, "translation": [0., 0., 3.] }));
    b.scene(&[a]);
    b.scene(&[c]);
    b.root["scene"] = json!(1);
    let scene = write_and_load(&b).unwrap();

    assert_eq!(scene.polygons.len(), 1);
    assert_eq!(scene.polygons[0].origin.node, c);
    assert!((scene.polygons[0].vertices[0].z - 3.0).abs() < TOL);
    assert_eq!(scene.layout.scene, Some(1));
    assert_eq!(scene.layout.scenes.len(), 2);
    assert_eq!(scene.layout.nodes.len(), 2);
    assert_eq!(scene.layout.meshes.len(), 2);
    assert!(!scene.layout.meshes[mesh].primitives[0].baked);
    assert!(scene.layout.meshes[unused_mesh].primitives[0].baked);
}

#[test]
fn without_scenes_every_root_node_is_baked() {
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    let child = b.node(json!({ "mesh": mesh, "translation": [0., 0., 1.] }));
    b.node(json!({ "mesh": mesh, "children": [child] }));
    b.node(json!({ "mesh": mesh, "translation": [0., 0., 7.] }));
    let scene = write_and_load(&b).unwrap();
    let mut zs: Vec<f64> = scene.polygons.iter().map(|p| p.vertices[0].z).collect();
    zs.sort_by(f64::total_cmp);
    assert_eq!(zs, vec![0.0, 1.0, 7.0]);
    assert_eq!(scene.layout.scene, None);
}

#[test]
fn index_out_of_range_is_an_error() {
    match write_and_load(&single(&TRIANGLE, Some(&[0, 1, 3]), None)) {
        Err(ImportError::Gltf(message)) => {
            assert!(
                message.contains("index 2 of the index list is out of range"),
                "{message}"
            );
            // Where, not the value read from the buffer.
            assert!(!message.contains("index 3"), "{message}")
        }
        other => panic!("expected a glTF error, got {other:?}"),
    }
}

#[test]
fn float_indices_are_an_error_not_a_panic() {
    let mut b = GltfBuilder::new();
    let position = b.positions(&TRIANGLE);
    let bytes: Vec<u8> = [0f32, 1., 2.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let indices = b.accessor(&bytes, bake_testkit::FLOAT, "SCALAR", 3, json!({}));
    let mesh = b.mesh(
        "Tri",
        vec![json!({ "attributes": { "POSITION": position }, "indices": indices })],
    );
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    assert!(matches!(write_and_load(&b), Err(ImportError::Gltf(_))));
}

#[test]
fn normalized_integer_and_sparse_positions_are_read() {
    let mut b = GltfBuilder::new();
    // Quantized positions (KHR_mesh_quantization): unsigned shorts, normalized.
    let shorts: Vec<u8> = [0u16, 0, 0, 65535, 0, 0, 0, 65535, 0, 0, 0, 0]
        .iter()
        .flat_map(|s| s.to_le_bytes())
        .collect();
    let quantized = b.accessor(
        &shorts,
        bake_testkit::UNSIGNED_SHORT,
        "VEC3",
        3,
        json!({ "normalized": true, "min": [0, 0, 0], "max": [65535, 65535, 0] }),
    );
    // Sparse: a zero base of 3 vertices with vertices 1 and 2 replaced.
    let sparse_indices = b.view(
        &[1u16, 2]
            .iter()
            .flat_map(|s| s.to_le_bytes())
            .collect::<Vec<u8>>(),
    );
    let sparse_values = b.view(
        &[2f32, 0., 0., 0., 2., 0.]
            .iter()
            .flat_map(|f| f.to_le_bytes())
            .collect::<Vec<u8>>(),
    );
    let sparse = b.root["accessors"].as_array().unwrap().len();
    b.root["accessors"].as_array_mut().unwrap().push(json!({
        "componentType": bake_testkit::FLOAT, "type": "VEC3", "count": 3,
        "min": [0, 0, 0], "max": [2, 2, 0],
        "sparse": {
            "count": 2,
            "indices": { "bufferView": sparse_indices, "componentType": bake_testkit::UNSIGNED_SHORT },
            "values": { "bufferView": sparse_values }
        }
    }));
    let mesh = b.mesh(
        "Packed",
        vec![
            json!({ "attributes": { "POSITION": quantized } }),
            json!({ "attributes": { "POSITION": sparse } }),
        ],
    );
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    b.root["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    let scene = write_and_load(&b).unwrap();

    assert_eq!(scene.polygons.len(), 2);
    assert_vertices(
        &scene.polygons[0],
        &[d(0., 0., 0.), d(1., 0., 0.), d(0., 1., 0.)],
    );
    assert_vertices(
        &scene.polygons[1],
        &[d(0., 0., 0.), d(2., 0., 0.), d(0., 2., 0.)],
    );
}

#[test]
fn scene_with_only_points_is_empty() {
    // (A primitive without POSITION is refused by the gltf crate's validation already.)
    let mut b = GltfBuilder::new();
    let points = b.primitive(&TRIANGLE, None, None, 0);
    let mesh = b.mesh("Dots", vec![points]);
    let node = b.node(json!({ "mesh": mesh }));
    b.scene(&[node]);
    let result = write_and_load(&b);
    assert!(matches!(result, Err(ImportError::Empty)), "{result:?}");
}

#[test]
fn skinned_and_morphed_meshes_are_named_as_baked_in_their_bind_pose() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = GltfBuilder::new();
    let triangle = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let still = b.triangle_mesh("still", &triangle, None, None);
    let moved = [[2.0f32, 0.0, 0.0], [3.0, 0.0, 0.0], [2.0, 1.0, 0.0]];
    let mut primitive = b.primitive(&moved, None, None, 4);
    let offsets = b.positions(&[[0.0f32, 0.0, 0.1]; 3]);
    primitive["targets"] = json!([{ "POSITION": offsets }]);
    let morphed = b.mesh("blob", vec![primitive]);
    let n0 = b.node(json!({ "mesh": still, "name": "plain" }));
    let n1 = b.node(json!({ "mesh": morphed, "name": "face" }));
    b.scene(&[n0, n1]);
    let scene = load(&b.write_embedded(&dir.path().join("m.gltf"))).expect("loads");
    let named: Vec<&String> = scene
        .warnings
        .iter()
        .filter(|w| w.contains("bind pose"))
        .collect();
    assert_eq!(named.len(), 1, "{:?}", scene.warnings);
    assert!(
        named[0].contains("mesh \"blob\"") && named[0].contains("morph targets"),
        "{named:?}"
    );
}

/// Nodes marked `"bake_probe": true` in their extras become probe points at their world
/// origins, in the order the baked scene is walked (depth first from its roots, as the baking
/// of meshes), only in the baked scene; other extras (false, a string, not an object) mark
/// nothing.
#[test]
fn marked_nodes_are_probe_points_at_their_world_origins() {
    let mut b = GltfBuilder::new();
    let mesh = b.triangle_mesh("Tri", &TRIANGLE, None, None);
    let floor = b.node(json!({ "mesh": mesh }));
    // Written before the child below, walked after it.
    let root_marked =
        b.node(json!({ "translation": [0.5, 0.25, -1.0], "extras": { "bake_probe": true } }));
    let child = b.node(json!({ "translation": [0.0, 1.0, 0.0], "extras": { "bake_probe": true } }));
    let parent = b.node(json!({
        "translation": [2.0, 0.0, 0.0], "scale": [2.0, 2.0, 2.0], "children": [child]
    }));
    let not_true = b.node(json!({ "extras": { "bake_probe": "true" } }));
    let not_object = b.node(json!({ "extras": [1, 2] }));
    let other_scene =
        b.node(json!({ "translation": [9.0, 9.0, 9.0], "extras": { "bake_probe": true } }));
    b.scene(&[floor, parent, root_marked, not_true, not_object]);
    b.scene(&[other_scene]);
    b.root["scene"] = json!(0);
    let scene = write_and_load(&b).expect("loads");
    assert_eq!(scene.probe_points.len(), 2, "{:?}", scene.probe_points);
    assert!(
        close(scene.probe_points[0], d(2.0, 2.0, 0.0)),
        "{:?}",
        scene.probe_points
    );
    assert!(
        close(scene.probe_points[1], d(0.5, 0.25, -1.0)),
        "{:?}",
        scene.probe_points
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}
