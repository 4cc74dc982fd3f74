//! Writes the fixture as .gltf and .glb, reads it back with the `gltf` crate and checks the
//! numbers: structure, transforms, positions, normals, winding, colours and radiosity.

mod common;

use bake_exporter::{write_gltf, Bake, ExportError, Shading};
use bake_testkit::file_names;
use common::{expected_smoothed, sample_bake, Fixture, BAKED_NODES};
use glam::{DMat3, DMat4, DVec3};
use gltf::json::validation::Checked;
use gltf::mesh::Semantic;
use std::collections::HashMap;
use std::path::Path;

const EXPOSURE: f64 = 0.9;
const TOLERANCE: f64 = 1e-6;

fn bake(fixture: &Fixture, shading: Shading) -> Bake<'_> {
    Bake {
        scene: &fixture.scene,
        mesh: &fixture.mesh,
        radiosity: &fixture.radiosity,
        irradiance: None,
        error: None,
        shading,
        exposure: EXPOSURE,
        probes: None,
    }
}

struct Output {
    document: gltf::Document,
    buffers: Vec<gltf::buffer::Data>,
}

fn write_and_import(dir: &Path, name: &str, bake: &Bake) -> Output {
    let path = dir.join(name);
    write_gltf(&path, bake).expect("write the baked glTF");
    let (document, buffers, _images) = gltf::import(&path).expect("re-read the baked glTF");
    Output { document, buffers }
}

#[test]
fn gltf_and_glb_hold_the_bake_smooth_and_flat() {
    let fixture = sample_bake();
    for shading in [Shading::Smooth, Shading::Flat] {
        for name in ["baked.gltf", "baked.glb"] {
            let dir = tempfile::tempdir().expect("a temporary directory");
            let output = write_and_import(dir.path(), name, &bake(&fixture, shading));
            check_structure(&output.document, &fixture);
            check_transforms(&output.document, &fixture);
            check_material(&output.document);
            check_primitives(&output, &fixture, shading);
            let expected_files: Vec<String> = if name.ends_with(".gltf") {
                vec!["baked.bin".into(), "baked.gltf".into()]
            } else {
                vec!["baked.glb".into()]
            };
            assert_eq!(
                file_names(dir.path()),
                expected_files,
                "no temporaries left"
            );
        }
    }
}

/// Nodes, names, children and scenes as in the input; one output mesh per baked instance.
fn check_structure(document: &gltf::Document, fixture: &Fixture) {
    let layout = &fixture.scene.layout;
    let nodes: Vec<gltf::Node> = document.nodes().collect();
    assert_eq!(nodes.len(), layout.nodes.len());
    for (output, input) in nodes.iter().zip(&layout.nodes) {
        assert_eq!(output.name(), input.name.as_deref());
        let children: Vec<usize> = output.children().map(|c| c.index()).collect();
        assert_eq!(children, input.children);
    }
    assert_eq!(document.meshes().count(), 2, "one mesh per baked instance");
    let mesh_of = |node: usize| nodes[node].mesh().map(|m| m.index());
    assert_eq!(mesh_of(0), None);
    assert_eq!(
        mesh_of(3),
        None,
        "a mesh without baked primitives is dropped"
    );
    assert_ne!(mesh_of(1), mesh_of(2), "instances are written un-instanced");
    for node in BAKED_NODES {
        let mesh = nodes[node].mesh().expect("a baked node keeps a mesh");
        assert_eq!(mesh.name(), Some("shared"));
        assert_eq!(mesh.primitives().count(), 2);
    }
    let scenes: Vec<gltf::Scene> = document.scenes().collect();
    assert_eq!(scenes.len(), 1);
    assert_eq!(scenes[0].name(), Some("main"));
    let roots: Vec<usize> = scenes[0].nodes().map(|n| n.index()).collect();
    assert_eq!(roots, vec![0, 3]);
    assert_eq!(document.default_scene().map(|s| s.index()), Some(0));
    let generator = document
        .as_json()
        .asset
        .generator
        .clone()
        .unwrap_or_default();
    assert!(generator.starts_with("bake "), "generator {generator:?}");
}

/// TRS stays TRS, a matrix stays a matrix, and the composed world matrices are the input's.
fn check_transforms(document: &gltf::Document, fixture: &Fixture) {
    let nodes: Vec<gltf::Node> = document.nodes().collect();
    match nodes[1].transform() {
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            assert_eq!(translation, common::TURNED_TRANSLATION);
            assert_eq!(rotation, common::TURNED_ROTATION);
            assert_eq!(scale, [1.0; 3]);
        }
        other => panic!("node 1 should stay TRS, got {other:?}"),
    }
    match nodes[2].transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            assert_eq!(matrix.concat(), common::MIRRORED_MATRIX.to_vec());
        }
        other => panic!("node 2 should stay a matrix, got {other:?}"),
    }
    for node in BAKED_NODES {
        let world = output_world(document, node);
        let expected = fixture.scene.layout.nodes[node].world;
        assert!(
            world.abs_diff_eq(expected, TOLERANCE),
            "node {node}: {world} vs {expected}"
        );
    }
}

/// The node's world matrix composed from the written transforms.
fn output_world(document: &gltf::Document, node: usize) -> DMat4 {
    let mut parent_of = HashMap::new();
    for parent in document.nodes() {
        for child in parent.children() {
            parent_of.insert(child.index(), parent.index());
        }
    }
    let nodes: Vec<gltf::Node> = document.nodes().collect();
    let mut world = DMat4::IDENTITY;
    let mut current = Some(node);
    while let Some(index) = current {
        let local = nodes[index].transform().matrix();
        world = DMat4::from_cols_array_2d(&local.map(|c| c.map(f64::from))) * world;
        current = parent_of.get(&index).copied();
    }
    world
}

/// One shared unlit material, declared in extensionsUsed.
fn check_material(document: &gltf::Document) {
    let materials: Vec<gltf::Material> = document.materials().collect();
    assert_eq!(materials.len(), 1);
    let material = &materials[0];
    assert_eq!(material.name(), Some("bake_unlit"));
    assert!(material.unlit());
    assert!(!material.double_sided());
    assert_eq!(
        material.pbr_metallic_roughness().base_color_factor(),
        [1.0; 4]
    );
    assert_eq!(material.emissive_strength(), None);
    let used: Vec<&str> = document.extensions_used().collect();
    assert_eq!(used, vec!["KHR_materials_unlit"]);
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            assert_eq!(primitive.material().index(), Some(0));
        }
    }
}

/// The attributes read back from one primitive.
struct Attributes {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 3]>,
    radiosity: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

fn read_attributes(primitive: &gltf::Primitive, buffers: &[gltf::buffer::Data]) -> Attributes {
    let get = |buffer: gltf::Buffer| buffers.get(buffer.index()).map(|data| &data[..]);
    let reader = primitive.reader(get);
    let radiosity = primitive
        .get(&Semantic::Extras("RADIOSITY".into()))
        .expect("a _RADIOSITY attribute");
    Attributes {
        positions: reader.read_positions().expect("POSITION").collect(),
        normals: reader.read_normals().expect("NORMAL").collect(),
        colors: reader
            .read_colors(0)
            .expect("COLOR_0")
            .into_rgb_f32()
            .collect(),
        radiosity: gltf::accessor::Iter::<[f32; 3]>::new(radiosity, get)
            .expect("_RADIOSITY data")
            .collect(),
        indices: reader.read_indices().expect("indices").into_u32().collect(),
    }
}

fn check_primitives(output: &Output, fixture: &Fixture, shading: Shading) {
    let smoothed = expected_smoothed(&fixture.mesh, &fixture.radiosity);
    for node in BAKED_NODES {
        let mesh = output
            .document
            .nodes()
            .nth(node)
            .and_then(|n| n.mesh())
            .expect("a mesh on a baked node");
        for (input_primitive, primitive) in mesh.primitives().enumerate() {
            assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles);
            let attributes = read_attributes(&primitive, &output.buffers);
            check_bounds(&primitive, &attributes);
            let check = PrimitiveCheck {
                fixture,
                node,
                world: fixture.scene.layout.nodes[node].world,
                elements: elements_of(fixture, node, input_primitive),
                smoothed: match shading {
                    Shading::Smooth => Some(&smoothed),
                    Shading::Flat => None,
                },
            };
            check.vertex_count(&attributes);
            check.triangles(&attributes);
        }
    }
}

/// Accessor min/max are exactly the stored extremes.
fn check_bounds(primitive: &gltf::Primitive, attributes: &Attributes) {
    let bounds = primitive.bounding_box();
    for axis in 0..3 {
        let values = attributes.positions.iter().map(|p| p[axis]);
        let min = values.clone().fold(f32::INFINITY, f32::min);
        let max = values.fold(f32::NEG_INFINITY, f32::max);
        assert_eq!(bounds.min[axis], min);
        assert_eq!(bounds.max[axis], max);
    }
}

/// Indices of the elements of (node, mesh 0, primitive).
fn elements_of(fixture: &Fixture, node: usize, primitive: usize) -> Vec<usize> {
    (0..fixture.mesh.elements.len())
        .filter(|&e| {
            let polygon = fixture.mesh.elements[e].polygon as usize;
            let origin = fixture.scene.polygons[polygon].origin;
            origin.node == node && origin.primitive == primitive
        })
        .collect()
}

struct PrimitiveCheck<'a> {
    fixture: &'a Fixture,
    node: usize,
    world: DMat4,
    elements: Vec<usize>,
    smoothed: Option<&'a Vec<[f64; 3]>>,
}

impl PrimitiveCheck<'_> {
    /// Smooth: a polygon's elements share vertices. Flat: every element has its own.
    fn vertex_count(&self, attributes: &Attributes) {
        let expected = match self.smoothed {
            Some(_) => {
                let mut used: Vec<u32> = self
                    .elements
                    .iter()
                    .flat_map(|&e| self.fixture.mesh.elements[e].corner_indices().to_vec())
                    .collect();
                used.sort();
                used.dedup();
                used.len()
            }
            None => self
                .elements
                .iter()
                .map(|&e| usize::from(self.fixture.mesh.elements[e].sides))
                .sum(),
        };
        assert_eq!(attributes.positions.len(), expected, "node {}", self.node);
        assert_eq!(attributes.normals.len(), expected);
        assert_eq!(attributes.colors.len(), expected);
        assert_eq!(attributes.radiosity.len(), expected);
    }

    /// Every triangle lies on one element, faces the right way, and carries that element's
    /// values; the triangles cover every element exactly.
    fn triangles(&self, attributes: &Attributes) {
        assert_eq!(attributes.indices.len() % 3, 0);
        let mut covered: HashMap<usize, f64> = HashMap::new();
        for triangle in attributes.indices.chunks(3) {
            let corners = [0, 1, 2].map(|i| triangle[i] as usize);
            let element = self.triangle(attributes, corners);
            let world = corners.map(|c| self.world_position(attributes, c));
            let area = 0.5 * (world[1] - world[0]).cross(world[2] - world[0]).length();
            *covered.entry(element).or_default() += area;
        }
        for &e in &self.elements {
            let area = self.fixture.mesh.elements[e].area;
            let got = covered.get(&e).copied().unwrap_or(0.0);
            assert!(
                (got - area).abs() < TOLERANCE,
                "element {e}: {got} vs {area}"
            );
        }
    }

    /// Checks one triangle and returns the element it belongs to.
    fn triangle(&self, attributes: &Attributes, corners: [usize; 3]) -> usize {
        let local_normal = vec3(attributes.normals[corners[0]]);
        for &c in &corners {
            let normal = vec3(attributes.normals[c]);
            assert!((normal.length() - 1.0).abs() < TOLERANCE, "unit normal");
            assert!(normal.abs_diff_eq(local_normal, 1e-12), "flat normal");
        }
        let world_normal = self.world_normal(local_normal);
        let world = corners.map(|c| self.world_position(attributes, c));
        let element = self.find_element(&world, world_normal);
        let expected_normal = self.fixture.mesh.elements[element].normal;
        assert!(
            world_normal.abs_diff_eq(expected_normal, TOLERANCE),
            "normal {world_normal} vs {expected_normal}"
        );

        // glTF: counter-clockwise about the local normal is the front face; with a negative
        // determinant that is clockwise about the world normal.
        let local = corners.map(|c| vec3(attributes.positions[c]));
        let local_turn = (local[1] - local[0])
            .cross(local[2] - local[0])
            .dot(local_normal);
        assert!(local_turn > 0.0, "CCW in local space");
        let world_turn = (world[1] - world[0])
            .cross(world[2] - world[0])
            .dot(expected_normal);
        if self.world.determinant() < 0.0 {
            assert!(world_turn < 0.0, "mirrored node: CW in world space");
        } else {
            assert!(world_turn > 0.0, "CCW in world space");
        }

        for (c, position) in corners.iter().zip(world) {
            self.check_values(attributes, *c, element, position);
        }
        element
    }

    /// The element of this primitive whose normal is `normal` and whose corners include
    /// all three points.
    fn find_element(&self, points: &[DVec3; 3], normal: DVec3) -> usize {
        let matches: Vec<usize> = self
            .elements
            .iter()
            .copied()
            .filter(|&e| {
                let element = &self.fixture.mesh.elements[e];
                element.normal.dot(normal) > 0.99
                    && points.iter().all(|p| self.corner_at(e, *p).is_some())
            })
            .collect();
        assert_eq!(matches.len(), 1, "triangle {points:?} on one element");
        matches[0]
    }

    /// The mesh vertex of element `e` at `point`.
    fn corner_at(&self, e: usize, point: DVec3) -> Option<u32> {
        let mesh = &self.fixture.mesh;
        mesh.elements[e]
            .corner_indices()
            .iter()
            .copied()
            .find(|&v| mesh.vertices[v as usize].abs_diff_eq(point, TOLERANCE))
    }

    /// `_RADIOSITY` is the smoothed vertex value (Smooth) or the element's b (Flat);
    /// `COLOR_0` is that value × exposure clamped to [0, 1].
    fn check_values(&self, attributes: &Attributes, vertex: usize, element: usize, at: DVec3) {
        let expected = match self.smoothed {
            Some(smoothed) => {
                let corner = self.corner_at(element, at).expect("a corner");
                smoothed[corner as usize]
            }
            None => self.fixture.radiosity[element],
        };
        let radiosity = attributes.radiosity[vertex];
        let color = attributes.colors[vertex];
        for band in 0..3 {
            let value = f64::from(radiosity[band]);
            assert!(
                (value - expected[band]).abs() <= TOLERANCE * expected[band].abs().max(1.0),
                "radiosity {value} vs {}",
                expected[band]
            );
            let clamped = (expected[band] * EXPOSURE).clamp(0.0, 1.0);
            assert!((f64::from(color[band]) - clamped).abs() < TOLERANCE);
            assert!((0.0..=1.0).contains(&color[band]));
        }
    }

    fn world_position(&self, attributes: &Attributes, vertex: usize) -> DVec3 {
        self.world
            .transform_point3(vec3(attributes.positions[vertex]))
    }

    /// Normals go to world space through the inverse-transpose of the linear part.
    fn world_normal(&self, local: DVec3) -> DVec3 {
        let linear = DMat3::from_mat4(self.world);
        (linear.inverse().transpose() * local).normalize()
    }
}

fn vec3(v: [f32; 3]) -> DVec3 {
    DVec3::from(v.map(f64::from))
}

#[test]
fn smoothed_centre_of_the_split_quad_is_the_mean_of_its_four_elements() {
    let fixture = sample_bake();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let output = write_and_import(dir.path(), "smooth.glb", &bake(&fixture, Shading::Smooth));
    // Quad A of node 1 is polygon 0: elements 0..4, vertex grid 0..9 with the centre at 4.
    let centre = fixture.mesh.vertices[4];
    let expected: Vec<f64> = (0..3)
        .map(|band| (0..4).map(|e| fixture.radiosity[e][band]).sum::<f64>() / 4.0)
        .collect();
    let world = fixture.scene.layout.nodes[1].world;
    let primitive = output
        .document
        .nodes()
        .nth(1)
        .and_then(|n| n.mesh())
        .and_then(|m| m.primitives().next())
        .expect("primitive 0 of node 1");
    let attributes = read_attributes(&primitive, &output.buffers);
    let found = attributes
        .positions
        .iter()
        .position(|&p| {
            world
                .transform_point3(vec3(p))
                .abs_diff_eq(centre, TOLERANCE)
        })
        .expect("the centre vertex is written once");
    for (got, expected) in attributes.radiosity[found].iter().zip(expected) {
        let got = f64::from(*got);
        assert!((got - expected).abs() < 1e-6, "{got} vs {expected}");
    }
}

#[test]
fn json_layout_views_are_aligned_and_targeted() {
    let fixture = sample_bake();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("layout.gltf");
    write_gltf(&path, &bake(&fixture, Shading::Flat)).expect("write");
    let text = std::fs::read_to_string(&path).expect("read the JSON back");
    let root: gltf::json::Root = serde_json::from_str(&text).expect("parse the JSON");
    assert_eq!(root.buffers.len(), 1);
    assert_eq!(root.buffers[0].uri.as_deref(), Some("layout.bin"));
    let bin_length = std::fs::metadata(dir.path().join("layout.bin"))
        .expect("the .bin exists")
        .len();
    assert_eq!(root.buffers[0].byte_length.0, bin_length);
    assert_eq!(bin_length % 4, 0);
    for view in &root.buffer_views {
        assert_eq!(view.byte_offset.map(|o| o.0).unwrap_or(0) % 4, 0);
        assert!(view.target.is_some());
    }
    for mesh in &root.meshes {
        for primitive in &mesh.primitives {
            let indices = primitive.indices.expect("indexed triangles").value();
            let view = root.accessors[indices].buffer_view.expect("a view").value();
            assert!(matches!(
                root.buffer_views[view].target,
                Some(Checked::Valid(
                    gltf::json::buffer::Target::ElementArrayBuffer
                ))
            ));
            for accessor in primitive.attributes.values() {
                let view = root.accessors[accessor.value()]
                    .buffer_view
                    .expect("a view")
                    .value();
                assert!(matches!(
                    root.buffer_views[view].target,
                    Some(Checked::Valid(gltf::json::buffer::Target::ArrayBuffer))
                ));
            }
        }
    }
    // The extension object is written as `{}` and listed as used.
    let value: serde_json::Value = serde_json::from_str(&text).expect("parse as a value");
    assert_eq!(
        value["materials"][0]["extensions"]["KHR_materials_unlit"],
        serde_json::json!({})
    );
    assert_eq!(
        value["extensionsUsed"],
        serde_json::json!(["KHR_materials_unlit"])
    );
}

#[test]
fn writing_again_replaces_the_output() {
    let fixture = sample_bake();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("twice.gltf");
    write_gltf(&path, &bake(&fixture, Shading::Smooth)).expect("first write");
    write_gltf(&path, &bake(&fixture, Shading::Flat)).expect("second write");
    assert_eq!(file_names(dir.path()), vec!["twice.bin", "twice.gltf"]);
    let (document, _, _) = gltf::import(&path).expect("re-read");
    let vertices: usize = document
        .meshes()
        .flat_map(|m| m.primitives().collect::<Vec<_>>())
        .filter_map(|p| p.get(&Semantic::Positions).map(|a| a.count()))
        .sum();
    assert_eq!(
        vertices,
        2 * (19 + 8),
        "flat vertex counts of the second write"
    );
}

#[test]
fn failing_writes_leave_nothing() {
    let fixture = sample_bake();
    let dir = tempfile::tempdir().expect("a temporary directory");
    for name in ["missing/out.gltf", "missing/out.glb"] {
        let result = write_gltf(&dir.path().join(name), &bake(&fixture, Shading::Smooth));
        assert!(matches!(result, Err(ExportError::Io { .. })), "{result:?}");
    }
    let result = write_gltf(
        &dir.path().join("out.obj"),
        &bake(&fixture, Shading::Smooth),
    );
    assert!(matches!(result, Err(ExportError::UnsupportedExtension(_))));

    let short = &fixture.radiosity[1..];
    let mismatched = Bake {
        radiosity: short,
        ..bake(&fixture, Shading::Flat)
    };
    let result = write_gltf(&dir.path().join("out.glb"), &mismatched);
    assert!(
        matches!(result, Err(ExportError::InvalidData(_))),
        "{result:?}"
    );

    let mut not_finite = fixture.radiosity.clone();
    not_finite[3][1] = f64::NAN;
    let nan = Bake {
        radiosity: &not_finite,
        ..bake(&fixture, Shading::Smooth)
    };
    let result = write_gltf(&dir.path().join("out.gltf"), &nan);
    assert!(
        matches!(result, Err(ExportError::NonFinite { .. })),
        "{result:?}"
    );

    assert!(file_names(dir.path()).is_empty(), "nothing written");
}

#[test]
fn nothing_baked_gives_nodes_without_meshes_or_buffers() {
    let mut fixture = sample_bake();
    fixture.scene.polygons.clear();
    fixture.mesh = mesher::ElementMesh::default();
    fixture.radiosity.clear();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("empty.gltf");
    write_gltf(&path, &bake(&fixture, Shading::Smooth)).expect("write");
    assert_eq!(
        file_names(dir.path()),
        vec!["empty.gltf"],
        "no .bin without data"
    );
    let (document, buffers, _) = gltf::import(&path).expect("re-read");
    assert_eq!(document.nodes().count(), 4);
    assert_eq!(document.meshes().count(), 0);
    assert_eq!(document.materials().count(), 0);
    assert_eq!(document.extensions_used().count(), 0);
    assert!(buffers.is_empty());
}

/// `_ERROR` holds each element's error estimate (flat) or, per vertex, the largest of the
/// elements around it (smooth), unclamped; without estimates there is no `_ERROR`.
#[test]
fn error_attribute_is_the_largest_estimate_around_each_vertex() {
    let fixture = sample_bake();
    let n = fixture.mesh.elements.len();
    // Distinct per element and band, some above 1 (unclamped).
    let error: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let x = (i as f64 * 0.37).sin().abs() * 3.0;
            [x, x * 0.5, x * 0.25 + 1e-3]
        })
        .collect();
    let mesh = &fixture.mesh;
    let mut around = vec![[0.0f64; 3]; mesh.vertices.len()];
    for (e, v) in mesh.elements.iter().zip(&error) {
        for &k in e.corner_indices() {
            for c in 0..3 {
                around[k as usize][c] = around[k as usize][c].max(v[c]);
            }
        }
    }
    let used: std::collections::BTreeSet<u32> = mesh
        .elements
        .iter()
        .flat_map(|e| e.corner_indices().iter().copied())
        .collect();
    let sorted = |mut v: Vec<[f32; 3]>| {
        v.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
        v
    };
    let f32s = |v: [f64; 3]| v.map(|x| x as f32);
    for shading in [Shading::Smooth, Shading::Flat] {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let with = Bake {
            error: Some(&error),
            ..bake(&fixture, shading)
        };
        let output = write_and_import(dir.path(), "baked.glb", &with);
        let get = |buffer: gltf::Buffer| output.buffers.get(buffer.index()).map(|d| &d[..]);
        let mut written = Vec::new();
        for mesh in output.document.meshes() {
            for primitive in mesh.primitives() {
                let accessor = primitive
                    .get(&Semantic::Extras("ERROR".into()))
                    .expect("an _ERROR attribute");
                written.extend(
                    gltf::accessor::Iter::<[f32; 3]>::new(accessor, get).expect("_ERROR data"),
                );
            }
        }
        let expected: Vec<[f32; 3]> = match shading {
            Shading::Smooth => used.iter().map(|&k| f32s(around[k as usize])).collect(),
            Shading::Flat => mesh
                .elements
                .iter()
                .zip(&error)
                .flat_map(|(e, v)| std::iter::repeat_n(f32s(*v), e.sides as usize))
                .collect(),
        };
        assert_eq!(sorted(written), sorted(expected), "{shading:?}");
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let output = write_and_import(dir.path(), "plain.glb", &bake(&fixture, Shading::Smooth));
    for mesh in output.document.meshes() {
        for primitive in mesh.primitives() {
            assert!(primitive.get(&Semantic::Extras("ERROR".into())).is_none());
        }
    }
}
