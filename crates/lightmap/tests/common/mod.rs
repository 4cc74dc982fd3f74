//! Helpers the lightmap crate's integration tests share.

use glam::DVec3;
use importer::{Origin, Polygon, Side};

/// A polygon of `material` in node, mesh and primitive 0, facing by its winding.
pub fn polygon(vertices: Vec<DVec3>, material: usize) -> Polygon {
    let normal = (vertices[1] - vertices[0])
        .cross(vertices[2] - vertices[0])
        .normalize();
    let origin = Origin {
        node: 0,
        mesh: 0,
        primitive: 0,
        face: 0,
        side: Side::Front,
    };
    Polygon {
        vertices,
        normal,
        material,
        origin,
    }
}
