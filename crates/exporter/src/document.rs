//! Builds a fresh glTF document (`gltf::json::Root`) and its binary buffer from the input's
//! layout and the baked primitives.

use crate::assets::{set_info_set, Assets, TEXTURE_TRANSFORM_EXTENSION};
use crate::geometry::{NodeMesh, PrimitiveData};
use crate::ExportError;
use gltf::json;
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::buffer::Target;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::{Checked, USize64};
use gltf::json::Index;
use scene::{Layout, Scene, Transform};
use std::collections::BTreeMap;

/// The name of the one material every baked primitive uses.
pub(crate) const MATERIAL_NAME: &str = "bake_unlit";
const UNLIT_EXTENSION: &str = "KHR_materials_unlit";
/// The unclamped radiosity attribute (an application-specific attribute: leading `_`).
pub(crate) const RADIOSITY_ATTRIBUTE: &str = "RADIOSITY";
/// The estimated error bound of b per band (`_ERROR`: `gltf` adds the leading `_`).
pub(crate) const ERROR_ATTRIBUTE: &str = "ERROR";

/// The document and the content of its one buffer (empty when nothing was baked). With
/// `bin_uri` the buffer refers to an external file (`.gltf`), without it is the GLB's
/// binary chunk.
pub(crate) fn build(
    scene: &Scene,
    node_meshes: &[NodeMesh],
    bin_uri: Option<String>,
    probes: Option<&crate::ProbeGrid>,
) -> Result<(json::Root, Vec<u8>), ExportError> {
    let layout = &scene.layout;
    check_layout(layout)?;
    let mut writer = DocumentWriter::default();
    writer.root.asset.generator = Some(format!("bake {}", env!("CARGO_PKG_VERSION")));
    writer.add_layout(layout);
    let mut assets = Assets::new(&scene.authored);
    let mut textured = BTreeMap::new();
    for node_mesh in node_meshes {
        writer.add_node_mesh(layout, node_mesh, &mut assets, &mut textured)?;
    }
    if assets.uses_transform {
        writer.use_extension(TEXTURE_TRANSFORM_EXTENSION);
    }
    if let Some(probes) = probes {
        crate::probes::add(&mut writer, probes)?;
    }
    Ok(writer.finish(bin_uri))
}

/// Every index in the layout must point at something, so the document is consistent.
pub(crate) fn check_layout(layout: &Layout) -> Result<(), ExportError> {
    let node_count = layout.nodes.len();
    if u32::try_from(node_count).is_err() || u32::try_from(layout.scenes.len()).is_err() {
        return Err(invalid("too many nodes or scenes for glTF".into()));
    }
    for (i, node) in layout.nodes.iter().enumerate() {
        if let Some(&child) = node.children.iter().find(|&&c| c >= node_count) {
            return Err(invalid(format!("node {i} has a missing child {child}")));
        }
        if let Some(mesh) = node.mesh.filter(|&m| m >= layout.meshes.len()) {
            return Err(invalid(format!("node {i} uses a missing mesh {mesh}")));
        }
    }
    for (i, scene) in layout.scenes.iter().enumerate() {
        if let Some(&node) = scene.nodes.iter().find(|&&n| n >= node_count) {
            return Err(invalid(format!("scene {i} has a missing node {node}")));
        }
    }
    if let Some(scene) = layout.scene.filter(|&s| s >= layout.scenes.len()) {
        return Err(invalid(format!("the default scene {scene} is missing")));
    }
    Ok(())
}

fn invalid(message: String) -> ExportError {
    ExportError::InvalidData(message)
}

#[derive(Default)]
pub(crate) struct DocumentWriter {
    pub(crate) root: json::Root,
    pub(crate) bin: Vec<u8>,
    material: Option<Index<json::Material>>,
}

impl DocumentWriter {
    /// Nodes (same order), their transforms and children, and the scenes, valid even where
    /// the input was not: a node listed as the child of several nodes stays under the first
    /// only, and each scene lists root nodes only, each once (a listed node that is a child
    /// is replaced by its topmost ancestor, which brings it along).
    pub(crate) fn add_layout(&mut self, layout: &Layout) {
        let parents = first_parents(layout);
        for (i, node) in layout.nodes.iter().enumerate() {
            let own: Vec<usize> = node
                .children
                .iter()
                .copied()
                .filter(|&c| parents[c] == Some(i))
                .collect();
            let mut output = json::Node {
                name: node.name.clone(),
                children: children(&own),
                ..Default::default()
            };
            set_transform(&mut output, &node.transform);
            self.root.nodes.push(output);
        }
        for scene in &layout.scenes {
            let mut listed = vec![false; layout.nodes.len()];
            let mut roots = Vec::new();
            for &node in &scene.nodes {
                let top = topmost(&parents, node);
                if !std::mem::replace(&mut listed[top], true) {
                    roots.push(index(top));
                }
            }
            self.root.scenes.push(json::Scene {
                extensions: None,
                extras: Default::default(),
                name: scene.name.clone(),
                nodes: roots,
            });
        }
        self.root.scene = layout.scene.map(index);
        if layout.scenes.is_empty() && !layout.nodes.is_empty() {
            self.add_default_scene(layout);
        }
    }

    /// An input without scenes gets one holding its root nodes, so viewers show something.
    fn add_default_scene(&mut self, layout: &Layout) {
        let mut is_child = vec![false; layout.nodes.len()];
        for node in &layout.nodes {
            for &child in &node.children {
                if let Some(flag) = is_child.get_mut(child) {
                    *flag = true;
                }
            }
        }
        let roots = (0..layout.nodes.len()).filter(|&n| !is_child[n]).map(index);
        self.root.scenes.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: None,
            nodes: roots.collect(),
        });
        self.root.scene = Some(index(0));
    }

    /// One node's mesh; `textured` caches the unlit material made for each textured scene
    /// material.
    fn add_node_mesh(
        &mut self,
        layout: &Layout,
        node_mesh: &NodeMesh,
        assets: &mut Assets,
        textured: &mut BTreeMap<usize, Index<json::Material>>,
    ) -> Result<(), ExportError> {
        let mut primitives = Vec::with_capacity(node_mesh.primitives.len());
        for data in &node_mesh.primitives {
            let material = match data.textured_material {
                None => self.material(),
                Some(m) => match textured.get(&m) {
                    Some(&index) => index,
                    None => {
                        let index = self.textured_material(assets, m)?;
                        textured.insert(m, index);
                        index
                    }
                },
            };
            primitives.push(self.add_primitive(data, material));
        }
        let mesh = self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: layout.meshes[node_mesh.mesh].name.clone(),
            primitives,
            weights: None,
        });
        self.root.nodes[node_mesh.node].mesh = Some(mesh);
        Ok(())
    }

    /// An unlit material keeping authored material `m`'s base colour (factor, texture on
    /// `TEXCOORD_0`, its transform), alpha mode and name.
    fn textured_material(
        &mut self,
        assets: &mut Assets,
        m: usize,
    ) -> Result<Index<json::Material>, ExportError> {
        let authored = assets
            .material(self, m, true)?
            .ok_or_else(|| invalid(format!("material {m} has no authored form")))?;
        let mut base_color_texture = authored.pbr_metallic_roughness.base_color_texture;
        if let Some(info) = base_color_texture.as_mut() {
            set_info_set(info, 0);
        }
        let mut material = unlit_material();
        material.name = authored
            .name
            .or_else(|| Some(format!("{MATERIAL_NAME}_{m}")));
        material.pbr_metallic_roughness.base_color_factor =
            authored.pbr_metallic_roughness.base_color_factor;
        material.pbr_metallic_roughness.base_color_texture = base_color_texture;
        material.alpha_mode = authored.alpha_mode;
        material.alpha_cutoff = authored.alpha_cutoff;
        self.use_extension(UNLIT_EXTENSION);
        Ok(self.root.push(material))
    }

    fn add_primitive(
        &mut self,
        data: &PrimitiveData,
        material: Index<json::Material>,
    ) -> json::mesh::Primitive {
        let mut attributes = BTreeMap::new();
        let position = self.add_vec3(&data.positions, true);
        attributes.insert(Checked::Valid(Semantic::Positions), position);
        let normal = self.add_vec3(&data.normals, false);
        attributes.insert(Checked::Valid(Semantic::Normals), normal);
        let color = self.add_vec3(&data.colors, false);
        attributes.insert(Checked::Valid(Semantic::Colors(0)), color);
        let radiosity = self.add_vec3(&data.radiosity, false);
        attributes.insert(
            Checked::Valid(Semantic::Extras(RADIOSITY_ATTRIBUTE.into())),
            radiosity,
        );
        if !data.error.is_empty() {
            let error = self.add_vec3(&data.error, false);
            attributes.insert(
                Checked::Valid(Semantic::Extras(ERROR_ATTRIBUTE.into())),
                error,
            );
        }
        if let Some(texcoords) = &data.texcoords {
            let uv = self.add_vec2(texcoords);
            attributes.insert(Checked::Valid(Semantic::TexCoords(0)), uv);
        }
        let indices = self.add_indices(&data.indices, data.positions.len());
        json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices: Some(indices),
            material: Some(material),
            mode: Checked::Valid(Mode::Triangles),
            targets: None,
        }
    }

    /// The shared unlit material, created on first use.
    fn material(&mut self) -> Index<json::Material> {
        if let Some(material) = self.material {
            return material;
        }
        let material = self.root.push(unlit_material());
        self.use_extension(UNLIT_EXTENSION);
        self.material = Some(material);
        material
    }

    /// A float VEC3 attribute; `with_bounds` adds the exact min/max (required for POSITION).
    pub(crate) fn add_vec3(
        &mut self,
        values: &[[f32; 3]],
        with_bounds: bool,
    ) -> Index<json::Accessor> {
        self.add_vec3_on(values, with_bounds, Some(Target::ArrayBuffer))
    }

    /// [`DocumentWriter::add_vec3`] on a view with this target (`None`: data that is no
    /// vertex attribute).
    pub(crate) fn add_vec3_on(
        &mut self,
        values: &[[f32; 3]],
        with_bounds: bool,
        target: Option<Target>,
    ) -> Index<json::Accessor> {
        let bytes: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let view = self.push_view(&bytes, target);
        let (min, max) = if with_bounds {
            let (min, max) = bounds(values);
            (Some(json_vec3(min)), Some(json_vec3(max)))
        } else {
            (None, None)
        };
        self.root.push(accessor(
            view,
            values.len(),
            ComponentType::F32,
            Type::Vec3,
            min,
            max,
        ))
    }

    /// Lists `name` in `extensionsUsed` (once).
    pub(crate) fn use_extension(&mut self, name: &str) {
        if !self.root.extensions_used.iter().any(|e| e == name) {
            self.root.extensions_used.push(name.into());
        }
    }

    /// A float VEC2 attribute (texture coordinates).
    pub(crate) fn add_vec2(&mut self, values: &[[f32; 2]]) -> Index<json::Accessor> {
        self.add_floats(values.as_flattened(), values.len(), Type::Vec2)
    }

    /// A float VEC4 attribute (tangents).
    pub(crate) fn add_vec4(&mut self, values: &[[f32; 4]]) -> Index<json::Accessor> {
        self.add_floats(values.as_flattened(), values.len(), Type::Vec4)
    }

    fn add_floats(&mut self, flat: &[f32], count: usize, type_: Type) -> Index<json::Accessor> {
        let bytes: Vec<u8> = flat.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.add_view(&bytes, Target::ArrayBuffer);
        self.root
            .push(accessor(view, count, ComponentType::F32, type_, None, None))
    }

    /// Triangle indices: u16 when every index fits below the u16 primitive-restart value.
    pub(crate) fn add_indices(
        &mut self,
        indices: &[u32],
        vertex_count: usize,
    ) -> Index<json::Accessor> {
        let (bytes, component_type) = if vertex_count <= usize::from(u16::MAX) {
            let bytes: Vec<u8> = indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect();
            (bytes, ComponentType::U16)
        } else {
            let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
            (bytes, ComponentType::U32)
        };
        let view = self.add_view(&bytes, Target::ElementArrayBuffer);
        self.root.push(accessor(
            view,
            indices.len(),
            component_type,
            Type::Scalar,
            None,
            None,
        ))
    }

    /// Appends `bytes` at a 4-byte aligned offset as a new buffer view of buffer 0.
    pub(crate) fn add_view(&mut self, bytes: &[u8], target: Target) -> Index<json::buffer::View> {
        self.push_view(bytes, Some(target))
    }

    /// [`DocumentWriter::add_view`], the target optional (`None`: data that is no vertex
    /// attribute or index).
    pub(crate) fn push_view(
        &mut self,
        bytes: &[u8],
        target: Option<Target>,
    ) -> Index<json::buffer::View> {
        pad_to_four(&mut self.bin);
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Checked::Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    pub(crate) fn finish(mut self, bin_uri: Option<String>) -> (json::Root, Vec<u8>) {
        pad_to_four(&mut self.bin);
        if !self.bin.is_empty() {
            self.root.push(json::Buffer {
                byte_length: USize64::from(self.bin.len()),
                name: None,
                uri: bin_uri,
                extensions: None,
                extras: Default::default(),
            });
        }
        (self.root, self.bin)
    }
}

fn unlit_material() -> json::Material {
    let extensions = json::extensions::material::Material {
        unlit: Some(json::extensions::material::Unlit {}),
        ..Default::default()
    };
    json::Material {
        name: Some(MATERIAL_NAME.into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([1.0, 1.0, 1.0, 1.0]),
            ..Default::default()
        },
        double_sided: false,
        extensions: Some(extensions),
        ..Default::default()
    }
}

pub(crate) fn accessor(
    view: Index<json::buffer::View>,
    count: usize,
    component_type: ComponentType,
    type_: Type,
    min: Option<json::Value>,
    max: Option<json::Value>,
) -> json::Accessor {
    json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Checked::Valid(GenericComponentType(component_type)),
        extensions: None,
        extras: Default::default(),
        type_: Checked::Valid(type_),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    }
}

/// Component-wise min and max of the values exactly as stored.
fn bounds(values: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for value in values {
        for axis in 0..3 {
            min[axis] = min[axis].min(value[axis]);
            max[axis] = max[axis].max(value[axis]);
        }
    }
    (min, max)
}

/// f32 → f64 is exact, so readers get the stored values back.
fn json_vec3(values: [f32; 3]) -> json::Value {
    json::Value::from(values.map(f64::from).to_vec())
}

/// Each node's parent: the first node (in index order) listing it as a child, once.
fn first_parents(layout: &Layout) -> Vec<Option<usize>> {
    let mut parents = vec![None; layout.nodes.len()];
    for (i, node) in layout.nodes.iter().enumerate() {
        for &child in &node.children {
            if let Some(slot @ None) = parents.get_mut(child) {
                if child != i {
                    *slot = Some(i);
                }
            }
        }
    }
    parents
}

/// The root above `node` (itself when it has no parent). At most as many steps as there
/// are nodes: a cycle (which the importer refuses) ends there rather than looping.
fn topmost(parents: &[Option<usize>], node: usize) -> usize {
    let mut top = node;
    for _ in 0..parents.len() {
        match parents.get(top).copied().flatten() {
            Some(parent) => top = parent,
            None => break,
        }
    }
    top
}

/// `rotation` scaled to unit length (in f64), as glTF requires of a node's rotation; the
/// importer used it normalised (and refused one of length 0 or not finite: identity then).
/// One within [`UNIT_TOLERANCE`] of unit length is written as the input gave it (the same
/// bytes as before for every valid input).
fn unit_quaternion(rotation: [f32; 4]) -> [f32; 4] {
    let q = rotation.map(f64::from);
    let length = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (length - 1.0).abs() <= UNIT_TOLERANCE {
        return rotation;
    }
    if !(length.is_finite() && length > 0.0) {
        return [0.0, 0.0, 0.0, 1.0];
    }
    q.map(|c| (c / length) as f32)
}

/// How far from 1 a quaternion's length may be and count as unit: the Khronos validator
/// allows 5e-6 (`ROTATION_NON_UNIT`); f32 rounding of a unit quaternion is far below 1e-6.
const UNIT_TOLERANCE: f64 = 1e-6;

fn set_transform(output: &mut json::Node, transform: &Transform) {
    match transform {
        Transform::Matrix(matrix) => {
            if *matrix != IDENTITY_MATRIX {
                output.matrix = Some(*matrix);
            }
        }
        Transform::Trs {
            translation,
            rotation,
            scale,
        } => {
            if *translation != [0.0; 3] {
                output.translation = Some(*translation);
            }
            let rotation = unit_quaternion(*rotation);
            if rotation != [0.0, 0.0, 0.0, 1.0] {
                output.rotation = Some(json::scene::UnitQuaternion(rotation));
            }
            if *scale != [1.0; 3] {
                output.scale = Some(*scale);
            }
        }
    }
}

const IDENTITY_MATRIX: [f32; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

fn children(children: &[usize]) -> Option<Vec<Index<json::Node>>> {
    if children.is_empty() {
        None
    } else {
        Some(children.iter().map(|&c| index(c)).collect())
    }
}

/// A glTF index. Layout indices were checked against counts that fit in u32, and pushes of
/// new objects panic in `Root::push` only beyond u32::MAX objects.
fn index<T>(i: usize) -> Index<T> {
    Index::new(i as u32)
}

pub(crate) fn pad_to_four(bytes: &mut Vec<u8>) {
    let padding = (4 - bytes.len() % 4) % 4;
    bytes.resize(bytes.len() + padding, 0);
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat4;
    use scene::{Node, SceneRoots};

    fn node(children: Vec<usize>, transform: Transform) -> Node {
        Node {
            name: None,
            transform,
            children,
            mesh: None,
            world: DMat4::IDENTITY,
        }
    }

    fn trs(rotation: [f32; 4]) -> Transform {
        Transform::Trs {
            translation: [0.0; 3],
            rotation,
            scale: [1.0; 3],
        }
    }

    /// Invalid glTF in, valid out: a 1e30 quaternion is written at unit length; a node that
    /// is a scene root twice, or a root while the child of another, or the child of two
    /// nodes, ends with one parent or one root entry; a matrix that is no TRS (a shear) is
    /// kept as `matrix`, not decomposed.
    #[test]
    fn nodes_and_scenes_are_written_valid_from_invalid_input() {
        let shear = [
            1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        let unit = [0.0, 0.0, 0.6, 0.8];
        let layout = Layout {
            nodes: vec![
                node(vec![1, 2], trs([1e30, 0.0, 0.0, 1e30])),
                node(vec![2], trs(unit)),
                node(vec![], Transform::Matrix(shear)),
                node(vec![], trs([0.0, 0.0, 0.0, 1.0])),
            ],
            meshes: Vec::new(),
            scenes: vec![SceneRoots {
                name: None,
                nodes: vec![0, 0, 2, 3, 1, 3],
            }],
            scene: Some(0),
        };
        let mut writer = DocumentWriter::default();
        writer.add_layout(&layout);
        let root = writer.root;
        let half = std::f32::consts::FRAC_1_SQRT_2;
        assert_eq!(
            root.nodes[0].rotation.map(|q| q.0),
            Some([half, 0.0, 0.0, half])
        );
        // A valid rotation keeps its bytes.
        assert_eq!(root.nodes[1].rotation.map(|q| q.0), Some(unit));
        assert_eq!(root.nodes[2].matrix, Some(shear));
        assert!(root.nodes[2].rotation.is_none());
        let children: Vec<Vec<u32>> = root
            .nodes
            .iter()
            .map(|n| {
                n.children
                    .iter()
                    .flatten()
                    .map(|c| c.value() as u32)
                    .collect()
            })
            .collect();
        assert_eq!(children, vec![vec![1, 2], vec![], vec![], vec![]]);
        let roots: Vec<usize> = root.scenes[0].nodes.iter().map(|n| n.value()).collect();
        assert_eq!(roots, vec![0, 3]);
    }
}
