//! Scenes shared by the visibility tests.
#![allow(dead_code)]

use bake_testkit::fixture;
use glam::DVec3;
use importer::{Origin, Polygon, Side};

/// A polygon from counter-clockwise corners (normal from the first three).
pub fn polygon(corners: &[DVec3], index: usize) -> Polygon {
    let normal = (corners[1] - corners[0])
        .cross(corners[2] - corners[0])
        .normalize();
    Polygon {
        vertices: corners.to_vec(),
        normal,
        material: 0,
        origin: Origin {
            node: index,
            mesh: index,
            primitive: 0,
            face: 0,
            side: Side::Front,
        },
    }
}

/// The axis-aligned rectangle x0..x1 × y0..y1 at height z, facing +z (`up`) or −z.
pub fn rect_z(x: [f64; 2], y: [f64; 2], z: f64, up: bool, index: usize) -> Polygon {
    let mut c = vec![
        DVec3::new(x[0], y[0], z),
        DVec3::new(x[1], y[0], z),
        DVec3::new(x[1], y[1], z),
        DVec3::new(x[0], y[1], z),
    ];
    if !up {
        c.reverse();
    }
    polygon(&c, index)
}

/// The paper's cube: the unit cube's six walls, facing inward.
pub fn cube() -> Vec<Polygon> {
    reference::unit_cube_walls()
        .iter()
        .enumerate()
        .map(|(k, c)| polygon(c, k))
        .collect()
}

/// The Cornell box fixture, and the mesh name of every polygon.
pub fn cornell() -> (Vec<Polygon>, Vec<String>) {
    let scene = importer::load(&fixture("cornell.gltf")).expect("fixtures/cornell.gltf");
    let names = scene
        .polygons
        .iter()
        .map(|p| {
            scene.layout.meshes[p.origin.mesh]
                .name
                .clone()
                .unwrap_or_default()
        })
        .collect();
    (scene.polygons, names)
}
