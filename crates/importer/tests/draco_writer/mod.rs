//! Writes Draco-compressed (`KHR_draco_mesh_compression`) copies of glTF fixtures with
//! draco-core's encoder, for the importer's and the CLI's compressed-input tests (shared
//! by `#[path]`; no external tool needed).

#![allow(dead_code)]

use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A Float32 Draco point attribute of `kind` holding `values`, one `N`-component value per
/// point (the encoder's input for positions, normals and texture coordinates).
pub fn float_attribute<const N: usize>(
    kind: draco_core::GeometryAttributeType,
    values: &[[f32; N]],
) -> draco_core::PointAttribute {
    let mut attribute = draco_core::PointAttribute::new();
    let components = u8::try_from(N).expect("at most 255 components");
    attribute.init(
        kind,
        components,
        draco_core::DataType::Float32,
        false,
        values.len(),
    );
    for (i, v) in values.iter().enumerate() {
        attribute
            .buffer_mut()
            .write(i * 4 * N, &v.map(f32::to_le_bytes).concat());
    }
    attribute
}

/// Writes the glTF file `source` (geometry in external .bin files) into `dir` with every
/// triangle primitive's POSITION and indices Draco-compressed (positions quantised to
/// `bits` bits; `speed` 10 is sequential coding, lower speeds edgebreaker). The Draco
/// attribute of the positions is given unique id 1 (a NORMAL is attribute 0), so a reader
/// that went by attribute order would read the normals.
pub fn write_draco(source: &Path, dir: &Path, bits: i32, speed: i32) -> PathBuf {
    use draco_core::{
        EncoderBuffer, EncoderOptions, GeometryAttributeType, Mesh, MeshEncoder, PointIndex,
    };
    let (document, buffers, _) = gltf::import(source).expect("fixture loads");
    let mut json: Value =
        serde_json::from_slice(&std::fs::read(source).unwrap()).expect("fixture JSON");
    for b in json["buffers"].as_array().unwrap() {
        let uri = b["uri"].as_str().expect("external buffer");
        std::fs::copy(source.with_file_name(uri), dir.join(uri)).unwrap();
    }
    let draco_buffer = json["buffers"].as_array().unwrap().len();
    let mut blob: Vec<u8> = Vec::new();
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            let n = positions.len();
            let mut draco = Mesh::new();
            let normals = vec![[0.0f32, 0.0, 1.0]; n];
            let normal_id =
                draco.add_attribute(float_attribute(GeometryAttributeType::Normal, &normals));
            let position_id =
                draco.add_attribute(float_attribute(GeometryAttributeType::Position, &positions));
            for t in indices.chunks_exact(3) {
                draco.add_face([PointIndex(t[0]), PointIndex(t[1]), PointIndex(t[2])]);
            }
            let unique = |id: i32| draco.attribute(id).unique_id();
            let (normal_unique, position_unique) = (unique(normal_id), unique(position_id));
            assert_eq!((normal_unique, position_unique), (0, 1));
            let mut options = EncoderOptions::new();
            options.set_attribute_int(position_id, "quantization_bits", bits);
            options.set_global_int("encoding_speed", speed);
            options.set_global_int("decoding_speed", speed);
            let mut encoder = MeshEncoder::new();
            encoder.set_mesh(draco);
            let mut out = EncoderBuffer::new();
            encoder.encode(&options, &mut out).expect("Draco encode");

            let view = json["bufferViews"].as_array().unwrap().len();
            json["bufferViews"].as_array_mut().unwrap().push(json!({
                "buffer": draco_buffer, "byteOffset": blob.len(), "byteLength": out.data().len()
            }));
            blob.extend_from_slice(out.data());
            blob.resize(blob.len().next_multiple_of(4), 0);
            // The primitive's own accessors keep count, type and bounds only.
            let old =
                &json["accessors"][primitive.get(&gltf::Semantic::Positions).unwrap().index()];
            let position_accessor = json!({
                "componentType": 5126, "count": n, "type": "VEC3",
                "min": old["min"].clone(), "max": old["max"].clone()
            });
            let accessors = json["accessors"].as_array_mut().unwrap();
            accessors.push(position_accessor);
            accessors
                .push(json!({"componentType": 5125, "count": indices.len(), "type": "SCALAR"}));
            let count = accessors.len();
            let p = &mut json["meshes"][mesh.index()]["primitives"][primitive.index()];
            p["attributes"] = json!({ "POSITION": count - 2 });
            p["indices"] = json!(count - 1);
            p["extensions"] = json!({ "KHR_draco_mesh_compression": {
                "bufferView": view,
                "attributes": { "POSITION": position_unique }
            }});
        }
    }
    std::fs::write(dir.join("draco.bin"), &blob).unwrap();
    json["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({"uri": "draco.bin", "byteLength": blob.len()}));
    for key in ["extensionsUsed", "extensionsRequired"] {
        let list = json[key].as_array().cloned().unwrap_or_default();
        let mut list: Vec<Value> = list;
        list.push(json!("KHR_draco_mesh_compression"));
        json[key] = Value::Array(list);
    }
    let name = source.file_name().expect("a file name").to_string_lossy();
    let path = dir.join(format!("draco-{name}"));
    std::fs::write(&path, serde_json::to_vec_pretty(&json).unwrap()).unwrap();
    path
}
