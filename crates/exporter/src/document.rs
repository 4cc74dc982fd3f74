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
    /// Nodes (same order), their transforms and children, and the scenes.
    pub(crate) fn add_layout(&mut self, layout: &Layout) {
        for node in &layout.nodes {
            let mut output = json::Node {
                name: node.name.clone(),
                children: children(&node.children),
                ..Default::default()
            };
            set_transform(&mut output, &node.transform);
            self.root.nodes.push(output);
        }
        for scene in &layout.scenes {
            self.root.scenes.push(json::Scene {
                extensions: None,
                extras: Default::default(),
                name: scene.name.clone(),
                nodes: scene.nodes.iter().map(|&n| index(n)).collect(),
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
        let bytes: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let view = self.add_view(&bytes, Target::ArrayBuffer);
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
        pad_to_four(&mut self.bin);
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: Some(Checked::Valid(target)),
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
            if *rotation != [0.0, 0.0, 0.0, 1.0] {
                output.rotation = Some(json::scene::UnitQuaternion(*rotation));
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
