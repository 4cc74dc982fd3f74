//! Subdivides each polygon into elements of constant radiosity (Goral et al. 1984, §3: "the
//! second module subdivides the polygonal surfaces of the environment into subpolygons called
//! elements"), and smooths element values to vertices for display (the paper's linear
//! interpolation, §4, Figure 8).
//!
//! Public API: [`mesh`] → [`ElementMesh`]; [`ElementMesh::smooth`].
//! A polygon's elements share one vertex grid ([`PatchGrid`]); grids are not shared between
//! polygons, so creases and material borders keep their own values.

use glam::DVec3;
use importer::Polygon;
use std::ops::Range;

/// How finely to subdivide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Subdivision {
    /// N×N elements per quad, N² per triangle.
    Count(u32),
    /// Elements no longer than this along any polygon edge direction (world units).
    MaxSize(f64),
}

/// One element: a planar convex triangle or quad of constant radiosity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    /// Index into the polygon list the mesh was built from.
    pub polygon: u32,
    /// Indices into [`ElementMesh::vertices`], counter-clockwise seen from the normal side.
    /// For a triangle the fourth entry repeats the third and `sides == 3`.
    pub corners: [u32; 4],
    pub sides: u8,
    pub area: f64,
    /// Area centroid.
    pub centroid: DVec3,
    /// Unit normal (the polygon's).
    pub normal: DVec3,
}

impl Element {
    /// Corner indices actually used (3 or 4).
    pub fn corner_indices(&self) -> &[u32] {
        &self.corners[..self.sides as usize]
    }
}

/// The vertex grid and elements of one polygon.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchGrid {
    pub vertices: Range<u32>,
    pub elements: Range<u32>,
}

/// Elements of a whole scene.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct ElementMesh {
    pub vertices: Vec<DVec3>,
    pub elements: Vec<Element>,
    /// One per input polygon, in polygon order.
    pub patches: Vec<PatchGrid>,
}
