//! Turns the element mesh into per-instance vertex and index arrays, in each node's local
//! space, ready to be stored as glTF primitives.

use crate::{Bake, ExportError, Shading};
use glam::{DMat3, DMat4, DVec3};
use importer::{Origin, Scene};
use mesher::ElementMesh;
use std::collections::{BTreeMap, HashMap};

/// The vertex and index data of one output primitive (f32, node-local space).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct PrimitiveData {
    pub(crate) positions: Vec<[f32; 3]>,
    /// Unit length.
    pub(crate) normals: Vec<[f32; 3]>,
    /// `clamp(value × exposure, 0, 1)`.
    pub(crate) colors: Vec<[f32; 3]>,
    /// Unclamped radiosity.
    pub(crate) radiosity: Vec<[f32; 3]>,
    /// Triangle list, counter-clockwise about the local normal.
    pub(crate) indices: Vec<u32>,
}

/// The primitives written for one node (its own, un-instanced mesh).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NodeMesh {
    pub(crate) node: usize,
    /// Index into the layout's meshes (for the name).
    pub(crate) mesh: usize,
    pub(crate) primitives: Vec<PrimitiveData>,
}

/// Builds every node's output primitives, in node order, then input primitive order.
pub(crate) fn build(bake: &Bake) -> Result<Vec<NodeMesh>, ExportError> {
    check_bake(bake)?;
    let groups = group_elements(bake.scene, bake.mesh);
    let smoothed = match bake.shading {
        // The paper's smoothing, welded across edges shared by coplanar polygons of one
        // material (a wall split into two polygons shows no seam), exactly as the lightmap's
        // vertex values are, so the vertex and lightmap bakes agree everywhere.
        Shading::Smooth => Some(
            lightmap::welded_vertex_values(&bake.scene.polygons, bake.mesh, bake.radiosity)
                .map_err(|e| invalid(e.to_string()))?,
        ),
        Shading::Flat => None,
    };
    let mut node_meshes: Vec<NodeMesh> = Vec::new();
    for (&(node, mesh, _primitive), elements) in &groups {
        let space = NodeSpace::new(&bake.scene.layout.nodes[node].world, node)?;
        let mut writer = PrimitiveWriter::new(bake, &space, smoothed.as_deref());
        for &element in elements {
            writer.add_element(element)?;
        }
        let data = writer.finish();
        match node_meshes.last_mut() {
            Some(last) if last.node == node => last.primitives.push(data),
            _ => node_meshes.push(NodeMesh {
                node,
                mesh,
                primitives: vec![data],
            }),
        }
    }
    Ok(node_meshes)
}

/// (node, mesh, primitive) → element indices, in element order.
type Groups = BTreeMap<(usize, usize, usize), Vec<usize>>;

fn group_elements(scene: &Scene, mesh: &ElementMesh) -> Groups {
    let mut groups = Groups::new();
    for (index, element) in mesh.elements.iter().enumerate() {
        let origin = scene.polygons[element.polygon as usize].origin;
        groups
            .entry((origin.node, origin.mesh, origin.primitive))
            .or_default()
            .push(index);
    }
    groups
}

/// Rejects a bake whose parts do not fit together, so the rest can index freely.
fn check_bake(bake: &Bake) -> Result<(), ExportError> {
    let mesh = bake.mesh;
    if bake.radiosity.len() != mesh.elements.len() {
        return Err(invalid(format!(
            "{} radiosity values for {} elements",
            bake.radiosity.len(),
            mesh.elements.len()
        )));
    }
    if !bake.exposure.is_finite() {
        return Err(invalid(format!("exposure {} is not finite", bake.exposure)));
    }
    for polygon in &bake.scene.polygons {
        check_origin(bake.scene, &polygon.origin)?;
    }
    for (i, element) in mesh.elements.iter().enumerate() {
        if element.polygon as usize >= bake.scene.polygons.len() {
            return Err(invalid(format!(
                "element {i} refers to polygon {} of {}",
                element.polygon,
                bake.scene.polygons.len()
            )));
        }
        let b = bake.radiosity[i];
        if !all_finite(&b) {
            return Err(ExportError::NonFinite {
                what: format!("{}: radiosity {b:?}", element_name(bake, i)),
            });
        }
        if element.sides != 3 && element.sides != 4 {
            return Err(invalid(format!("element {i} has {} sides", element.sides)));
        }
        if element
            .corner_indices()
            .iter()
            .any(|&c| c as usize >= mesh.vertices.len())
        {
            return Err(invalid(format!("element {i} refers to a missing vertex")));
        }
    }
    Ok(())
}

fn check_origin(scene: &Scene, origin: &Origin) -> Result<(), ExportError> {
    let layout = &scene.layout;
    let node = layout
        .nodes
        .get(origin.node)
        .ok_or_else(|| invalid(format!("polygon origin {origin:?}: no such node")))?;
    if node.mesh != Some(origin.mesh) {
        return Err(invalid(format!(
            "polygon origin {origin:?}: node {} does not use mesh {}",
            origin.node, origin.mesh
        )));
    }
    let mesh = layout
        .meshes
        .get(origin.mesh)
        .ok_or_else(|| invalid(format!("polygon origin {origin:?}: no such mesh")))?;
    if origin.primitive >= mesh.primitives.len() {
        return Err(invalid(format!(
            "polygon origin {origin:?}: no such primitive"
        )));
    }
    Ok(())
}

fn invalid(message: String) -> ExportError {
    ExportError::InvalidData(message)
}

/// `element 3 (polygon 1: node 0, mesh 0, primitive 0, face 2, front)`, for messages.
/// The element and its polygon exist (checked by `check_bake`).
fn element_name(bake: &Bake, index: usize) -> String {
    let polygon = bake.mesh.elements[index].polygon;
    let origin = bake.scene.polygons[polygon as usize].origin;
    let side = match origin.side {
        importer::Side::Front => "front",
        importer::Side::Back => "back",
    };
    format!(
        "element {index} (polygon {polygon}: node {}, mesh {}, primitive {}, face {}, {side})",
        origin.node, origin.mesh, origin.primitive, origin.face
    )
}

fn all_finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

/// Maps world-space geometry into one node's local space.
struct NodeSpace {
    world_to_local: DMat4,
    /// Transpose of the linear part of the local-to-world matrix: takes world normals to
    /// local normals (the inverse-transpose of the world-to-local map).
    normal_to_local: DMat3,
    /// The world matrix mirrors (negative determinant): glTF then treats clockwise
    /// triangles as front faces, so the winding is reversed.
    mirrored: bool,
}

impl NodeSpace {
    fn new(world: &DMat4, node: usize) -> Result<Self, ExportError> {
        let determinant = world.determinant();
        if determinant == 0.0 || !determinant.is_finite() {
            return Err(invalid(format!(
                "node {node} has a singular world transform"
            )));
        }
        Ok(NodeSpace {
            world_to_local: world.inverse(),
            normal_to_local: DMat3::from_mat4(*world).transpose(),
            mirrored: determinant < 0.0,
        })
    }

    fn position(&self, world: DVec3) -> DVec3 {
        self.world_to_local.transform_point3(world)
    }

    fn normal(&self, world: DVec3) -> Option<DVec3> {
        (self.normal_to_local * world).try_normalize()
    }
}

/// Accumulates the vertices and triangles of one output primitive.
struct PrimitiveWriter<'a> {
    bake: &'a Bake<'a>,
    space: &'a NodeSpace,
    /// Smooth shading: one value per mesh vertex. Flat: `None`.
    smoothed: Option<&'a [[f64; 3]]>,
    /// Smooth shading: (polygon, mesh vertex) → output vertex, so a polygon's elements share
    /// vertices.
    shared: HashMap<(u32, u32), u32>,
    data: PrimitiveData,
}

impl<'a> PrimitiveWriter<'a> {
    fn new(bake: &'a Bake<'a>, space: &'a NodeSpace, smoothed: Option<&'a [[f64; 3]]>) -> Self {
        PrimitiveWriter {
            bake,
            space,
            smoothed,
            shared: HashMap::new(),
            data: PrimitiveData::default(),
        }
    }

    fn add_element(&mut self, index: usize) -> Result<(), ExportError> {
        let element = &self.bake.mesh.elements[index];
        let normal = self.space.normal(element.normal).ok_or_else(|| {
            let what = format!(
                "{}: normal {}",
                element_name(self.bake, index),
                element.normal
            );
            if element.normal.is_finite() {
                invalid(format!("{what} cannot be normalized"))
            } else {
                ExportError::NonFinite { what }
            }
        })?;
        let mut corners = Vec::with_capacity(4);
        for &vertex in element.corner_indices() {
            let output = match self.smoothed {
                Some(values) => self.shared_vertex(index, vertex, normal, values[vertex as usize]),
                None => self.push_vertex(index, vertex, normal, self.bake.radiosity[index]),
            }?;
            corners.push(output);
        }
        self.push_triangle(corners[0], corners[1], corners[2]);
        if corners.len() == 4 {
            self.push_triangle(corners[0], corners[2], corners[3]);
        }
        Ok(())
    }

    /// The output vertex of `vertex` in the polygon of `element`, pushed on first use.
    fn shared_vertex(
        &mut self,
        element: usize,
        vertex: u32,
        normal: DVec3,
        value: [f64; 3],
    ) -> Result<u32, ExportError> {
        let polygon = self.bake.mesh.elements[element].polygon;
        if let Some(&output) = self.shared.get(&(polygon, vertex)) {
            return Ok(output);
        }
        let output = self.push_vertex(element, vertex, normal, value)?;
        self.shared.insert((polygon, vertex), output);
        Ok(output)
    }

    /// Appends one output vertex of `element`, after checking that every value stored for
    /// it is finite as f32.
    fn push_vertex(
        &mut self,
        element: usize,
        vertex: u32,
        normal: DVec3,
        value: [f64; 3],
    ) -> Result<u32, ExportError> {
        let output = u32::try_from(self.data.positions.len())
            .map_err(|_| invalid("more than 2^32 vertices in one primitive".into()))?;
        let world = self.bake.mesh.vertices[vertex as usize];
        let exposure = self.bake.exposure;
        let attributes = [
            ("POSITION", to_f32(self.space.position(world).to_array())),
            ("NORMAL", to_f32(normal.to_array())),
            (
                "COLOR_0",
                to_f32(value.map(|v| (v * exposure).clamp(0.0, 1.0))),
            ),
            ("_RADIOSITY", to_f32(value)),
        ];
        for (name, stored) in &attributes {
            if !all_finite_f32(stored) {
                return Err(ExportError::NonFinite {
                    what: format!(
                        "{}: {name} {stored:?} of mesh vertex {vertex} (as f32)",
                        element_name(self.bake, element)
                    ),
                });
            }
        }
        let [position, normal, color, radiosity] = attributes.map(|(_, stored)| stored);
        self.data.positions.push(position);
        self.data.normals.push(normal);
        self.data.colors.push(color);
        self.data.radiosity.push(radiosity);
        Ok(output)
    }

    fn push_triangle(&mut self, a: u32, b: u32, c: u32) {
        if self.space.mirrored {
            self.data.indices.extend([a, c, b]);
        } else {
            self.data.indices.extend([a, b, c]);
        }
    }

    fn finish(self) -> PrimitiveData {
        self.data
    }
}

fn to_f32(values: [f64; 3]) -> [f32; 3] {
    values.map(|v| v as f32)
}

fn all_finite_f32(values: &[f32]) -> bool {
    values.iter().all(|v| v.is_finite())
}
