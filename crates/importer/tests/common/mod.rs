//! A minimal glTF 2.0 writer for tests: one binary buffer, written as a data URI, an
//! external `.bin`, or a `.glb` container.
#![allow(dead_code)]

use serde_json::{json, Value};
use std::path::{Path, PathBuf};

pub const FLOAT: u32 = 5126;
pub const UNSIGNED_SHORT: u32 = 5123;
pub const UNSIGNED_INT: u32 = 5125;

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
    /// points: JSON has no NaN).
    pub fn positions(&mut self, points: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = points
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let mut min = [f32::INFINITY; 3];
        let mut max = [f32::NEG_INFINITY; 3];
        for p in points.iter().filter(|p| p.iter().all(|f| f.is_finite())) {
            for k in 0..3 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        self.accessor(
            &bytes,
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
        let primitive = self.primitive(points, indices, material, 4);
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

    fn root_with_buffer(&self, uri: Option<String>) -> Value {
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

    /// `.gltf` with the buffer as a base64 data URI.
    pub fn write_embedded(&self, path: &Path) -> PathBuf {
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        let text = serde_json::to_string_pretty(&self.root_with_buffer(Some(uri))).expect("json");
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
            serde_json::to_string_pretty(&self.root_with_buffer(Some(bin_name))).expect("json");
        std::fs::write(path, text).expect("write gltf");
        path.to_owned()
    }

    /// `.glb`: 12-byte header, JSON chunk padded with spaces, BIN chunk padded with zeros.
    pub fn write_glb(&self, path: &Path) -> PathBuf {
        let mut json = serde_json::to_vec(&self.root_with_buffer(None)).expect("json");
        while json.len() % 4 != 0 {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
        out.extend_from_slice(&bin);
        std::fs::write(path, out).expect("write glb");
        path.to_owned()
    }
}

/// Standard base64 with padding (RFC 4648 §4).
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k)) as usize & 63] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}
