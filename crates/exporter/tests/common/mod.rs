//! A small hand-built bake shared by the exporter's tests.
//!
//! Layout: node 0 "root" (translation, children 1 and 2); node 1 "turned" (translation +
//! oblique rotation, TRS) and node 2 "mirrored" (matrix with scale (-1, 2, 1): negative
//! determinant) both instance mesh 0 "shared"; node 3 "unbaked" uses mesh 1 whose only
//! primitive was not baked. Scene 0 "main" holds nodes 0 and 3.
//!
//! Mesh 0, primitive 0 (single-sided): quad A (y = 0, normal +y) subdivided into 2×2 quad
//! elements, and triangle B (tilted: local normal along (0, 1, 1), so a wrong normal
//! transform shows under the non-uniform scale) as one element. Primitive 1 (doubleSided):
//! quad C (x = 3, normal +x) and its back side D, one element each. Per instance that is
//! polygons A, B, C, D and 7 elements; 14 elements in all.

#![allow(dead_code)]

use glam::{DMat4, DQuat, DVec3};
use importer::{
    ImportStats, Layout, Material, Mesh, Node, Origin, Polygon, Primitive, Scene, SceneRoots, Side,
    Transform,
};
use mesher::{Element, ElementMesh, PatchGrid};

pub const ROOT_TRANSLATION: [f32; 3] = [0.0, 1.0, 0.0];
pub const TURNED_TRANSLATION: [f32; 3] = [1.0, 2.0, 3.0];
/// 60° about (1, 2, 2)/3.
pub const TURNED_ROTATION: [f32; 4] = [1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 0.866_025_4];
pub const MIRRORED_MATRIX: [f32; 16] = [
    -1.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -5.0, 1.0,
];
/// The nodes whose instances were baked.
pub const BAKED_NODES: [usize; 2] = [1, 2];

pub struct Fixture {
    pub scene: Scene,
    pub mesh: ElementMesh,
    pub radiosity: Vec<[f64; 3]>,
}

pub fn sample_bake() -> Fixture {
    let layout = layout();
    let mut polygons = Vec::new();
    for node in BAKED_NODES {
        polygons.extend(instance_polygons(node, &layout.nodes[node].world));
    }
    let mesh = element_mesh(&polygons);
    let radiosity = (0..mesh.elements.len())
        .map(|k| {
            let k = k as f64;
            [0.2 + 0.15 * k, 1.5 - 0.1 * k, 0.05 * k * k]
        })
        .collect();
    let polygon_count = polygons.len();
    let scene = Scene {
        polygons,
        materials: materials(),
        lights: Vec::new(),
        probe_points: Vec::new(),
        textures: Vec::new(),
        images: Vec::new(),
        uvs: vec![None; polygon_count],
        authored: Default::default(),
        alpha_masks: vec![None; 8],
        layout,
        stats: ImportStats {
            faces_read: 12,
            quads_merged: 4,
            degenerate_dropped: 1,
            primitives_skipped: 1,
            ngons_split: 0,
            duplicates_dropped: 2,
            against_winding: 3,
            coincident_dropped: 0,
            material_libraries_missing: 0,
        },
        warnings: vec!["mesh \"lines\": primitive 0 skipped (mode LINES)".into()],
        input_files: Vec::new(),
    };
    Fixture {
        scene,
        mesh,
        radiosity,
    }
}

fn materials() -> Vec<Material> {
    vec![
        Material {
            name: Some("wall".into()),
            rho: [0.8, 0.5, 0.3],
            emission: [0.0; 3],
            double_sided: false,
            base_color_texture: None,
            emissive_texture: None,
            transmission: 0.0,
        },
        Material {
            name: Some("panel".into()),
            rho: [0.5; 3],
            emission: [1.0, 0.9, 0.8],
            double_sided: true,
            base_color_texture: None,
            emissive_texture: None,
            transmission: 0.0,
        },
    ]
}

fn layout() -> Layout {
    let root_world = trs_world(ROOT_TRANSLATION, [0.0, 0.0, 0.0, 1.0], [1.0; 3]);
    let turned_world = root_world * trs_world(TURNED_TRANSLATION, TURNED_ROTATION, [1.0; 3]);
    let mirrored_world = root_world * DMat4::from_cols_array(&MIRRORED_MATRIX.map(f64::from));
    let nodes = vec![
        Node {
            name: Some("root".into()),
            transform: Transform::Trs {
                translation: ROOT_TRANSLATION,
                rotation: [0.0, 0.0, 0.0, 1.0],
                scale: [1.0; 3],
            },
            children: vec![1, 2],
            mesh: None,
            world: root_world,
        },
        Node {
            name: Some("turned".into()),
            transform: Transform::Trs {
                translation: TURNED_TRANSLATION,
                rotation: TURNED_ROTATION,
                scale: [1.0; 3],
            },
            children: vec![],
            mesh: Some(0),
            world: turned_world,
        },
        Node {
            name: Some("mirrored".into()),
            transform: Transform::Matrix(MIRRORED_MATRIX),
            children: vec![],
            mesh: Some(0),
            world: mirrored_world,
        },
        Node {
            name: Some("unbaked".into()),
            transform: Transform::Trs {
                translation: [0.0; 3],
                rotation: [0.0, 0.0, 0.0, 1.0],
                scale: [1.0; 3],
            },
            children: vec![],
            mesh: Some(1),
            world: DMat4::IDENTITY,
        },
    ];
    let meshes = vec![
        Mesh {
            name: Some("shared".into()),
            primitives: vec![
                Primitive {
                    material: 0,
                    baked: true,
                },
                Primitive {
                    material: 1,
                    baked: true,
                },
            ],
        },
        Mesh {
            name: Some("lines".into()),
            primitives: vec![Primitive {
                material: 0,
                baked: false,
            }],
        },
    ];
    Layout {
        nodes,
        meshes,
        scenes: vec![SceneRoots {
            name: Some("main".into()),
            nodes: vec![0, 3],
        }],
        scene: Some(0),
    }
}

pub fn trs_world(translation: [f32; 3], rotation: [f32; 4], scale: [f32; 3]) -> DMat4 {
    DMat4::from_scale_rotation_translation(
        DVec3::from(scale.map(f64::from)),
        DQuat::from_array(rotation.map(f64::from)),
        DVec3::from(translation.map(f64::from)),
    )
}

/// Polygons A, B, C (front) and D (back of C) of mesh 0 placed by `world`, counter-clockwise
/// about their world normals, as the importer produces them.
fn instance_polygons(node: usize, world: &DMat4) -> Vec<Polygon> {
    let quad_a = [
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 2.0],
        [2.0, 0.0, 2.0],
        [2.0, 0.0, 0.0],
    ];
    let triangle_b = [[0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 1.0, -2.0]];
    let quad_c = [
        [3.0, 0.0, 0.0],
        [3.0, 1.0, 0.0],
        [3.0, 1.0, 1.0],
        [3.0, 0.0, 1.0],
    ];
    let origin = |primitive, face, side| Origin {
        node,
        mesh: 0,
        primitive,
        face,
        side,
    };
    let front_c = world_polygon(&quad_c, world, 1, origin(1, 0, Side::Front));
    let mut back_d = front_c.clone();
    back_d.vertices.reverse();
    back_d.normal = -front_c.normal;
    back_d.origin.side = Side::Back;
    vec![
        world_polygon(&quad_a, world, 0, origin(0, 0, Side::Front)),
        world_polygon(&triangle_b, world, 0, origin(0, 2, Side::Front)),
        front_c,
        back_d,
    ]
}

fn world_polygon(local: &[[f64; 3]], world: &DMat4, material: usize, origin: Origin) -> Polygon {
    let mut vertices: Vec<DVec3> = local
        .iter()
        .map(|&v| world.transform_point3(DVec3::from(v)))
        .collect();
    if world.determinant() < 0.0 {
        vertices.reverse();
    }
    let normal = (vertices[1] - vertices[0])
        .cross(vertices[2] - vertices[0])
        .normalize();
    Polygon {
        vertices,
        normal,
        material,
        origin,
    }
}

/// Quad A is split 2×2, everything else is one element.
fn element_mesh(polygons: &[Polygon]) -> ElementMesh {
    let mut mesh = ElementMesh::default();
    for (index, polygon) in polygons.iter().enumerate() {
        let first_vertex = mesh.vertices.len() as u32;
        let first_element = mesh.elements.len() as u32;
        if polygon.vertices.len() == 4 {
            let n = if index % 4 == 0 { 2 } else { 1 };
            add_quad_grid(&mut mesh, polygon, index as u32, n);
        } else {
            add_triangle(&mut mesh, polygon, index as u32);
        }
        mesh.patches.push(PatchGrid {
            vertices: first_vertex..mesh.vertices.len() as u32,
            elements: first_element..mesh.elements.len() as u32,
        });
    }
    mesh
}

fn add_quad_grid(mesh: &mut ElementMesh, polygon: &Polygon, index: u32, n: u32) {
    let [p0, p1, p2, p3] = [0, 1, 2, 3].map(|i| polygon.vertices[i]);
    let base = mesh.vertices.len() as u32;
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (f64::from(i) / f64::from(n), f64::from(j) / f64::from(n));
            let a = p0 + (p1 - p0) * u;
            let b = p3 + (p2 - p3) * u;
            mesh.vertices.push(a + (b - a) * v);
        }
    }
    let at = |i: u32, j: u32| base + j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            let corners = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            mesh.elements
                .push(element(mesh, index, corners, 4, polygon.normal));
        }
    }
}

fn add_triangle(mesh: &mut ElementMesh, polygon: &Polygon, index: u32) {
    let base = mesh.vertices.len() as u32;
    mesh.vertices.extend(&polygon.vertices);
    let corners = [base, base + 1, base + 2, base + 2];
    mesh.elements
        .push(element(mesh, index, corners, 3, polygon.normal));
}

fn element(
    mesh: &ElementMesh,
    polygon: u32,
    corners: [u32; 4],
    sides: u8,
    normal: DVec3,
) -> Element {
    let p = corners.map(|c| mesh.vertices[c as usize]);
    let first = triangle_area_centroid(p[0], p[1], p[2]);
    let (area, centroid) = if sides == 4 {
        let second = triangle_area_centroid(p[0], p[2], p[3]);
        let area = first.0 + second.0;
        (area, (first.1 * first.0 + second.1 * second.0) / area)
    } else {
        first
    };
    Element {
        polygon,
        corners,
        sides,
        area,
        centroid,
        normal,
    }
}

fn triangle_area_centroid(a: DVec3, b: DVec3, c: DVec3) -> (f64, DVec3) {
    (0.5 * (b - a).cross(c - a).length(), (a + b + c) / 3.0)
}

/// The expected smoothed value per mesh vertex, computed here independently of the crate:
/// the area-weighted mean of the values of the elements that use the vertex.
pub fn expected_smoothed(mesh: &ElementMesh, values: &[[f64; 3]]) -> Vec<[f64; 3]> {
    (0..mesh.vertices.len() as u32)
        .map(|vertex| {
            let mut sum = DVec3::ZERO;
            let mut weight = 0.0;
            for (element, value) in mesh.elements.iter().zip(values) {
                if element.corner_indices().contains(&vertex) {
                    sum += DVec3::from(*value) * element.area;
                    weight += element.area;
                }
            }
            (sum / weight).to_array()
        })
        .collect()
}

/// An element of node 2's instance of quad A (polygon 4).
pub const ELEMENT: usize = 8;

/// The error's message, asserting it is a one-line `NonFinite` (the including test file names
/// the exporter's `ExportError`: the crate is `bake_exporter` in its own tests, `exporter`
/// in the job's).
pub fn non_finite(result: Result<(), super::ExportError>) -> String {
    let error = result.expect_err("a non-finite value is refused");
    assert!(
        matches!(error, super::ExportError::NonFinite { .. }),
        "{error:?}"
    );
    let message = error.to_string();
    assert!(!message.contains('\n'), "{message}");
    message
}
