//! Turns the element mesh into per-instance vertex and index arrays, in each node's local
//! space, ready to be stored as glTF primitives.

use crate::{Bake, ExportError, Shading};
use glam::{DMat3, DMat4, DVec3};
use mesher::ElementMesh;
use scene::{Origin, Scene};
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
    /// The estimated error of b (`_ERROR`); empty when the bake has none.
    pub(crate) error: Vec<[f32; 3]>,
    /// Textured materials: the base-colour texture's TEXCOORD set at each vertex (written as
    /// `TEXCOORD_0`).
    pub(crate) texcoords: Option<Vec<[f32; 2]>>,
    /// Textured materials: the scene material whose base-colour texture the output keeps
    /// (`COLOR_0` then holds the irradiance H); `None`: the shared white material (`COLOR_0`
    /// holds b).
    pub(crate) textured_material: Option<usize>,
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
    let textured: Vec<Option<u32>> = (0..bake.scene.materials.len())
        .map(|m| textured_set(bake.scene, m))
        .collect();
    let irradiance = match bake.irradiance {
        Some(h) => Some(h),
        None if textured.iter().any(Option::is_some) => {
            return Err(invalid(
                "a textured material needs the irradiance H for COLOR_0".into(),
            ))
        }
        None => None,
    };
    // The paper's smoothing, welded across edges shared by coplanar polygons of one
    // material (a wall split into two polygons shows no seam), exactly as the lightmap's
    // vertex values are, so the vertex and lightmap bakes agree everywhere.
    let smooth = |values: &[[f64; 3]]| {
        lightmap::welded_vertex_values(&bake.scene.polygons, bake.mesh, values)
            .map_err(|e| invalid(e.to_string()))
    };
    let (smoothed, smoothed_h) = match bake.shading {
        Shading::Smooth => (
            Some(smooth(bake.radiosity)?),
            irradiance.map(smooth).transpose()?,
        ),
        Shading::Flat => (None, None),
    };
    // Smooth: each mesh vertex gets the largest error of the elements around it.
    let vertex_error = match (bake.error, bake.shading) {
        (Some(error), Shading::Smooth) => Some(vertex_maxima(bake.mesh, error)),
        _ => None,
    };
    let mut node_meshes: Vec<NodeMesh> = Vec::new();
    for (&(node, mesh, primitive), elements) in &groups {
        let space = NodeSpace::new(&bake.scene.layout.nodes[node].world, node)?;
        let material = bake.scene.layout.meshes[mesh].primitives[primitive].material;
        let colour = match (textured.get(material).copied().flatten(), irradiance) {
            (Some(set), Some(h)) => ColourSource::Irradiance {
                material,
                set: set as usize,
                element: h,
                smoothed: smoothed_h.as_deref(),
            },
            _ => ColourSource::Radiosity,
        };
        let mut writer = PrimitiveWriter::new(bake, &space, smoothed.as_deref(), colour);
        writer.vertex_error = vertex_error.as_deref();
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

/// The TEXCOORD set of scene material `m`'s base-colour texture when the vertex bake keeps
/// that texture: the material has one, an authored material to copy it from, and no emission
/// (an unlit material shows no emission: emitters keep `COLOR_0` = b and the white material).
pub(crate) fn textured_set(scene: &Scene, m: usize) -> Option<u32> {
    let material = scene.materials.get(m)?;
    let reference = material.base_color_texture.as_ref()?;
    let authored = scene.authored.materials.get(m)?.as_ref()?;
    let emits = material.emission.iter().any(|&e| e != 0.0);
    let kept = authored["pbrMetallicRoughness"]["baseColorTexture"].is_object();
    (kept && !emits).then_some(reference.tex_coord)
}

/// What `COLOR_0` of a primitive holds.
#[derive(Clone, Copy)]
enum ColourSource<'a> {
    /// The radiosity b (untextured materials and emitters).
    Radiosity,
    /// The irradiance H (per element, and per mesh vertex when smooth), with the base-colour
    /// texture's TEXCOORD `set` of scene material `material` at each vertex.
    Irradiance {
        material: usize,
        set: usize,
        element: &'a [[f64; 3]],
        smoothed: Option<&'a [[f64; 3]]>,
    },
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

/// Per mesh vertex: the band-wise maximum of `values` over the elements that have it as a
/// corner.
fn vertex_maxima(mesh: &ElementMesh, values: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0f64; 3]; mesh.vertices.len()];
    for (i, value) in values.iter().enumerate().take(mesh.elements.len()) {
        for &v in mesh.outline(i) {
            if let Some(slot) = out.get_mut(v as usize) {
                for c in 0..3 {
                    slot[c] = slot[c].max(value[c]);
                }
            }
        }
    }
    out
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
    if let Some(h) = bake.irradiance {
        if h.len() != mesh.elements.len() {
            return Err(invalid(format!(
                "{} irradiance values for {} elements",
                h.len(),
                mesh.elements.len()
            )));
        }
        if let Some(i) = h.iter().position(|h| !all_finite(h)) {
            return Err(ExportError::NonFinite {
                what: format!("{}: irradiance {:?}", element_name(bake, i), h[i]),
            });
        }
    }
    if let Some(error) = bake.error {
        if error.len() != mesh.elements.len() {
            return Err(invalid(format!(
                "{} error values for {} elements",
                error.len(),
                mesh.elements.len()
            )));
        }
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
            .chain(mesh.outline(i))
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
        scene::Side::Front => "front",
        scene::Side::Back => "back",
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
    colour: ColourSource<'a>,
    /// Smooth shading: (polygon, mesh vertex) → output vertex, so a polygon's elements share
    /// vertices.
    shared: HashMap<(u32, u32), u32>,
    /// Smooth shading with an error estimate: the largest error around each mesh vertex.
    vertex_error: Option<&'a [[f64; 3]]>,
    /// One element's triangles (reused).
    triangles: Vec<[u32; 3]>,
    data: PrimitiveData,
}

impl<'a> PrimitiveWriter<'a> {
    fn new(
        bake: &'a Bake<'a>,
        space: &'a NodeSpace,
        smoothed: Option<&'a [[f64; 3]]>,
        colour: ColourSource<'a>,
    ) -> Self {
        let mut data = PrimitiveData::default();
        if let ColourSource::Irradiance { material, .. } = colour {
            data.texcoords = Some(Vec::new());
            data.textured_material = Some(material);
        }
        PrimitiveWriter {
            bake,
            space,
            smoothed,
            colour,
            shared: HashMap::new(),
            vertex_error: None,
            triangles: Vec::new(),
            data,
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
        // The element's outline: its corners and, on a refined mesh, the hanging vertices
        // its neighbours' splits put on its edges, so that the triangles conform.
        let mesh = self.bake.mesh;
        let outline = mesh.outline(index);
        let mut output = Vec::with_capacity(outline.len());
        for &vertex in outline {
            let out = match self.smoothed {
                Some(values) => self.shared_vertex(index, vertex, normal, values[vertex as usize]),
                None => self.push_vertex(index, vertex, normal, self.bake.radiosity[index]),
            }?;
            output.push((vertex, out));
        }
        let at = |v: u32| output.iter().find(|(k, _)| *k == v).map(|&(_, o)| o);
        mesh.triangles(index, &mut self.triangles);
        for k in 0..self.triangles.len() {
            let [a, b, c] = self.triangles[k];
            if let (Some(a), Some(b), Some(c)) = (at(a), at(b), at(c)) {
                self.push_triangle(a, b, c);
            }
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
        let shown = match self.colour {
            ColourSource::Radiosity => value,
            ColourSource::Irradiance {
                element: h,
                smoothed,
                ..
            } => match smoothed {
                Some(values) => values[vertex as usize],
                None => h[element],
            },
        };
        if let ColourSource::Irradiance { set, .. } = self.colour {
            let polygon = self.bake.mesh.elements[element].polygon as usize;
            let uv = self
                .bake
                .scene
                .uvs
                .get(polygon)
                .and_then(Option::as_ref)
                .and_then(|uv| uv.at(set, world))
                .ok_or_else(|| {
                    invalid(format!(
                        "{}: its material is textured but it has no TEXCOORD_{set}",
                        element_name(self.bake, element)
                    ))
                })?;
            let uv = [uv.x as f32, uv.y as f32];
            if !all_finite_f32(&uv) {
                return Err(ExportError::NonFinite {
                    what: format!(
                        "{}: TEXCOORD {uv:?} of mesh vertex {vertex} (as f32)",
                        element_name(self.bake, element)
                    ),
                });
            }
            if let Some(texcoords) = self.data.texcoords.as_mut() {
                texcoords.push(uv);
            }
        }
        // A viewer multiplies the texture by COLOR_0 only: the input's own vertex colour
        // (part of ρ) goes into it with H.
        let shown = match (self.colour, self.input_colour(element, world)) {
            (ColourSource::Irradiance { .. }, Some(c)) => [0, 1, 2].map(|k| shown[k] * c[k]),
            _ => shown,
        };
        let attributes = [
            ("POSITION", to_f32(self.space.position(world).to_array())),
            ("NORMAL", to_f32(normal.to_array())),
            (
                "COLOR_0",
                to_f32(shown.map(|v| (v * exposure).clamp(0.0, 1.0))),
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
        if let Some(per_element) = self.bake.error {
            let error = match self.vertex_error {
                Some(per_vertex) => per_vertex[vertex as usize],
                None => per_element[element],
            };
            let stored = to_f32(error);
            if !all_finite_f32(&stored) {
                return Err(ExportError::NonFinite {
                    what: format!(
                        "{}: _ERROR {stored:?} of mesh vertex {vertex} (as f32)",
                        element_name(self.bake, element)
                    ),
                });
            }
            self.data.error.push(stored);
        }
        let [position, normal, color, radiosity] = attributes.map(|(_, stored)| stored);
        self.data.positions.push(position);
        self.data.normals.push(normal);
        self.data.colors.push(color);
        self.data.radiosity.push(radiosity);
        Ok(output)
    }

    /// The input's `COLOR_0` at a point of `element`'s polygon, if it had one.
    fn input_colour(&self, element: usize, world: DVec3) -> Option<DVec3> {
        let polygon = self.bake.mesh.elements[element].polygon as usize;
        self.bake
            .scene
            .uvs
            .get(polygon)
            .and_then(Option::as_ref)
            .and_then(|uv| uv.color_at(world))
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
