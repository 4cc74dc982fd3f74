//! A minimal glTF 2.0 writer for tests: one binary buffer, written as a data URI, an
//! external `.bin`, or a `.glb` container.

use crate::encode::{data_uri, glb, GLB_BIN, GLB_JSON};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Accessor component types.
pub const FLOAT: u32 = 5126;
pub const UNSIGNED_SHORT: u32 = 5123;
pub const UNSIGNED_INT: u32 = 5125;

/// Primitive modes.
pub const POINTS: u32 = 0;
pub const TRIANGLES: u32 = 4;

/// Little-endian f32 bytes of the positions.
pub fn position_bytes(positions: &[[f32; 3]]) -> Vec<u8> {
    positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// Component-wise min and max over the finite values (glTF requires POSITION bounds; a NaN
/// cannot be written in JSON, so the bounds of a poisoned buffer leave it out).
fn finite_bounds(positions: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut min = [0.0f32; 3];
    let mut max = [0.0f32; 3];
    for axis in 0..3 {
        let finite = positions.iter().map(|p| p[axis]).filter(|v| v.is_finite());
        min[axis] = finite.clone().fold(f32::INFINITY, f32::min);
        max[axis] = finite.fold(f32::NEG_INFINITY, f32::max);
    }
    (min, max)
}

/// A glTF document under construction: `root` is its JSON without `buffers`, `bin` the one
/// buffer's bytes. Empty top-level arrays are left out when it is written.
pub struct GltfBuilder {
    pub root: Value,
    pub bin: Vec<u8>,
}

impl Default for GltfBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl GltfBuilder {
    pub fn new() -> Self {
        Self {
            root: json!({
                "asset": { "version": "2.0" },
                "accessors": [], "bufferViews": [], "meshes": [], "nodes": [],
                "materials": [], "scenes": []
            }),
            bin: Vec::new(),
        }
    }

    /// A one-mesh document: scene 0 holds node "wall" → mesh "wall", one non-indexed
    /// primitive of `mode` ([`TRIANGLES`], [`POINTS`], …) over `positions`; with `material`,
    /// that is material 0 and the primitive uses it.
    pub fn wall(positions: &[[f32; 3]], mode: u32, material: Option<Value>) -> Self {
        let mut b = Self::new();
        let material = material.map(|m| b.material(m));
        let primitive = b.primitive(positions, None, material, mode);
        let mesh = b.mesh("wall", vec![primitive]);
        let node = b.node(json!({ "name": "wall", "mesh": mesh }));
        let scene = b.scene(&[node]);
        b.root["scene"] = json!(scene);
        b
    }

    fn push(&mut self, key: &str, value: Value) -> usize {
        let list = self.root[key].as_array_mut().expect("array");
        list.push(value);
        list.len() - 1
    }

    /// Appends bytes (4-byte aligned) as a new buffer view; returns its index.
    pub fn view(&mut self, bytes: &[u8]) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.push(
            "bufferViews",
            json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() }),
        )
    }

    /// A raw accessor over a new view; `extra` is merged into its JSON.
    pub fn accessor(
        &mut self,
        bytes: &[u8],
        component: u32,
        ty: &str,
        count: usize,
        extra: Value,
    ) -> usize {
        let view = self.view(bytes);
        let mut accessor = json!({
            "bufferView": view, "componentType": component, "type": ty, "count": count
        });
        if let (Some(a), Some(e)) = (accessor.as_object_mut(), extra.as_object()) {
            for (k, v) in e {
                a.insert(k.clone(), v.clone());
            }
        }
        self.push("accessors", accessor)
    }

    /// A float VEC3 POSITION accessor with the min/max the spec requires (over the finite
    /// values: JSON has no NaN).
    pub fn positions(&mut self, points: &[[f32; 3]]) -> usize {
        let (min, max) = finite_bounds(points);
        self.accessor(
            &position_bytes(points),
            FLOAT,
            "VEC3",
            points.len(),
            json!({ "min": min, "max": max }),
        )
    }

    pub fn indices(&mut self, indices: &[u16]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        self.accessor(&bytes, UNSIGNED_SHORT, "SCALAR", indices.len(), json!({}))
    }

    pub fn material(&mut self, material: Value) -> usize {
        self.push("materials", material)
    }

    /// A mesh from primitive JSON objects.
    pub fn mesh(&mut self, name: &str, primitives: Vec<Value>) -> usize {
        self.push("meshes", json!({ "name": name, "primitives": primitives }))
    }

    /// A one-primitive triangle mesh: positions, optional indices, optional material.
    pub fn triangle_mesh(
        &mut self,
        name: &str,
        points: &[[f32; 3]],
        indices: Option<&[u16]>,
        material: Option<usize>,
    ) -> usize {
        let primitive = self.primitive(points, indices, material, TRIANGLES);
        self.mesh(name, vec![primitive])
    }

    /// Primitive JSON with the given mode.
    pub fn primitive(
        &mut self,
        points: &[[f32; 3]],
        indices: Option<&[u16]>,
        material: Option<usize>,
        mode: u32,
    ) -> Value {
        let position = self.positions(points);
        let mut primitive = json!({ "attributes": { "POSITION": position }, "mode": mode });
        if let Some(indices) = indices {
            primitive["indices"] = json!(self.indices(indices));
        }
        if let Some(material) = material {
            primitive["material"] = json!(material);
        }
        primitive
    }

    pub fn node(&mut self, node: Value) -> usize {
        self.push("nodes", node)
    }

    pub fn scene(&mut self, nodes: &[usize]) -> usize {
        self.push("scenes", json!({ "nodes": nodes }))
    }

    /// The document with the buffer at `uri` (none: the GLB's BIN chunk).
    fn root_with_buffer(&self, uri: Option<&str>) -> Value {
        let mut root = self.root.clone();
        let mut buffer = json!({ "byteLength": self.bin.len() });
        if let Some(uri) = uri {
            buffer["uri"] = json!(uri);
        }
        root["buffers"] = json!([buffer]);
        // Empty arrays are invalid glTF: drop them.
        if let Some(object) = root.as_object_mut() {
            object.retain(|_, v| v.as_array().is_none_or(|a| !a.is_empty()));
        }
        root
    }

    /// The document, with the buffer stored at `uri`.
    pub fn json_with_buffer_uri(&self, uri: &str) -> Value {
        self.root_with_buffer(Some(uri))
    }

    /// The document with its buffer embedded as a base64 data URI.
    pub fn json(&self) -> Value {
        self.json_with_buffer_uri(&data_uri(&self.bin))
    }

    /// `.gltf` with the buffer as a base64 data URI.
    pub fn write_embedded(&self, path: &Path) -> PathBuf {
        let text = serde_json::to_string_pretty(&self.json()).expect("json");
        std::fs::write(path, text).expect("write gltf");
        path.to_owned()
    }

    /// `.gltf` next to an external `.bin` file.
    pub fn write_external(&self, path: &Path) -> PathBuf {
        let bin_name = format!(
            "{}.bin",
            path.file_stem().and_then(|s| s.to_str()).expect("stem")
        );
        std::fs::write(path.with_file_name(&bin_name), &self.bin).expect("write bin");
        let text =
            serde_json::to_string_pretty(&self.json_with_buffer_uri(&bin_name)).expect("json");
        std::fs::write(path, text).expect("write gltf");
        path.to_owned()
    }

    /// `.glb`: the JSON chunk and the BIN chunk (written even when the buffer is empty).
    pub fn write_glb(&self, path: &Path) -> PathBuf {
        let json = serde_json::to_vec(&self.root_with_buffer(None)).expect("json");
        std::fs::write(path, glb(&[(GLB_JSON, &json), (GLB_BIN, &self.bin)])).expect("write glb");
        path.to_owned()
    }
}
