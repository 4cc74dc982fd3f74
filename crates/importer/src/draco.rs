//! `KHR_draco_mesh_compression` primitives, decoded into plain accessors.
//!
//! A primitive carrying the extension keeps its geometry in a Draco bitstream (the
//! extension's `bufferView`); its own accessors have no buffer view, only count, type and
//! bounds (KHR_draco_mesh_compression README, "Conformance"). The extension's `attributes`
//! maps each compressed glTF semantic to the Draco attribute's *unique id*, which is what
//! is looked up here (never the attribute order in the stream). Each primitive is decoded
//! with the pure-Rust `draco-core` decoder, and its attributes and indices are replaced by
//! new float (or u32 index) accessors over a fresh buffer, so the accessor readers see an
//! ordinary primitive.
//!
//! What this is not: an encoder, or a reader of Draco point clouds (POINTS primitives are
//! left as they are: the importer skips points anyway). Attributes the extension does not
//! list stay as uncompressed accessors (README: "attributes not in the extension").

use gltf::buffer::Data;
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::{Checked, USize64};
use gltf::json::{Accessor, Index, Root};
use serde_json::Value;

/// The extension's name.
pub(crate) const NAME: &str = "KHR_draco_mesh_compression";

/// The most points (and faces) a Draco stream may declare per byte of its own: a thousand
/// times what real meshes reach, so only a header that lies is refused.
const MAX_POINTS_PER_BYTE: u64 = 1024;

/// Streams of any size may declare this many points and faces.
const MIN_POINT_LIMIT: u64 = 65_536;

/// The most bytes a Draco stream may decode to per byte of its own (real meshes: about 4–10),
/// and what a stream of any size may decode to: draco-core applies this limit where it does
/// not check the point count (a sequential stream's values).
const MAX_DECODED_PER_BYTE: u64 = 4096;
const MIN_DECODED_LIMIT: u64 = 1 << 20;

/// Decodes every Draco-compressed triangle primitive of `root` (see the module doc). The
/// buffer views must already be plain (`EXT_meshopt_compression` decoded first).
pub(crate) fn decode_primitives(root: &mut Root, buffers: &mut Vec<Data>) -> Result<(), String> {
    for m in 0..root.meshes.len() {
        for p in 0..root.meshes[m].primitives.len() {
            let primitive = &root.meshes[m].primitives[p];
            let Some(extension) = primitive
                .extensions
                .as_ref()
                .and_then(|e| e.others.get(NAME))
                .cloned()
            else {
                continue;
            };
            if !matches!(
                primitive.mode,
                Checked::Valid(Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)
            ) {
                continue;
            }
            decode_primitive(root, buffers, m, p, &extension)
                .map_err(|e| format!("meshes[{m}].primitives[{p}] ({NAME}): {e}"))?;
        }
    }
    Ok(())
}

/// One decoded attribute or index stream, before it is given an accessor.
struct Stream {
    /// The semantic it replaces (`None`: the indices).
    semantic: Option<Checked<Semantic>>,
    /// The accessor it replaces (copied for name and bounds).
    old: Option<usize>,
    type_: Type,
    component: ComponentType,
    bytes: Vec<u8>,
    count: usize,
}

fn decode_primitive(
    root: &mut Root,
    buffers: &mut Vec<Data>,
    m: usize,
    p: usize,
    extension: &Value,
) -> Result<(), String> {
    let view = extension
        .get("bufferView")
        .and_then(Value::as_u64)
        .ok_or("`bufferView` is missing or not an index")?;
    let bytes = view_bytes(root, buffers, view)?;
    // A stream holds a few bytes per point (Google's encoder writes 2–6 at 14-bit
    // positions): one claiming far more points, or decoded bytes, than its size can encode
    // is refused from its header, before the decoder loops over them (fuzzing found a
    // 72-byte sequential stream declaring 1.98 M points, 194 MB of values, that kept it busy
    // 1.0–1.6 s before the importer refused it; it is now refused at once).
    let max = (MAX_POINTS_PER_BYTE * bytes.len() as u64 + MIN_POINT_LIMIT)
        .min(crate::accessor::MAX_COUNT as u64);
    let limits = draco_core::DecodeLimits::default()
        .with_max_points(max)
        .with_max_faces(max)
        .with_max_decoded_bytes(
            (MAX_DECODED_PER_BYTE * bytes.len() as u64 + MIN_DECODED_LIMIT).min(1 << 30),
        );
    let mut buffer = draco_core::DecoderBuffer::new(bytes).with_limits(limits);
    let mut mesh = draco_core::Mesh::new();
    draco_core::MeshDecoder::new()
        .decode(&mut buffer, &mut mesh)
        .map_err(|e| format!("the Draco bitstream cannot be decoded: {e}"))?;
    let points = mesh.num_points();
    if points > crate::accessor::MAX_COUNT || mesh.num_faces() > crate::accessor::MAX_COUNT {
        return Err(format!(
            "{points} points and {} faces, more than the importer's limit of {}",
            mesh.num_faces(),
            crate::accessor::MAX_COUNT
        ));
    }

    let attributes = extension
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or("`attributes` is missing or not an object")?;
    let primitive = &root.meshes[m].primitives[p];
    let mut streams = Vec::new();
    for (name, id) in attributes {
        let id = id
            .as_u64()
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| format!("attribute {name}: id {id} is not an unsigned integer"))?;
        let semantic: Checked<Semantic> = serde_json::from_value(Value::String(name.clone()))
            .map_err(|e| format!("attribute {name}: {e}"))?;
        let old = primitive.attributes.get(&semantic).map(|a| a.value());
        // The accessor the primitive lists gives the glTF type (VEC2/3/4); without one the
        // attribute is not part of the primitive and is not decoded.
        let Some(old) = old else { continue };
        let accessor = root
            .accessors
            .get(old)
            .ok_or_else(|| format!("attribute {name}: accessor {old} does not exist"))?;
        let Checked::Valid(type_) = accessor.type_ else {
            return Err(format!(
                "attribute {name}: accessor {old} has an invalid type"
            ));
        };
        let attribute = mesh.attribute_by_unique_id(id).ok_or_else(|| {
            format!("attribute {name}: the bitstream has no attribute with unique id {id}")
        })?;
        let components = type_.multiplicity();
        let mut values = attribute.read_f32s(points, components);
        // Normalized integers (e.g. COLOR_0 as bytes) are dequantized with the glTF 2.0
        // formulas; non-normalized ones keep their integer values (KHR_mesh_quantization).
        if attribute.normalized() || accessor.normalized {
            if let Some(scale) = normalization(attribute.data_type()) {
                for v in &mut values {
                    *v = (*v / scale).max(-1.0);
                }
            }
        }
        streams.push(Stream {
            semantic: Some(semantic),
            old: Some(old),
            type_,
            component: ComponentType::F32,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
            count: points,
        });
    }
    let indices: Vec<u8> = mesh
        .faces()
        .iter()
        .flatten()
        .flat_map(|i| i.0.to_le_bytes())
        .collect();
    streams.push(Stream {
        semantic: None,
        old: primitive.indices.map(|i| i.value()),
        type_: Type::Scalar,
        component: ComponentType::U32,
        count: mesh.num_faces() * 3,
        bytes: indices,
    });
    install(root, buffers, m, p, streams)
}

/// The divisor of a normalized integer type (glTF 2.0, "Animations"/"Accessors").
fn normalization(data_type: draco_core::DataType) -> Option<f32> {
    use draco_core::DataType as D;
    match data_type {
        D::Int8 => Some(127.0),
        D::Uint8 => Some(255.0),
        D::Int16 => Some(32767.0),
        D::Uint16 => Some(65535.0),
        _ => None,
    }
}

/// The bytes of buffer view `view`, bounds-checked.
fn view_bytes<'a>(root: &Root, buffers: &'a [Data], view: u64) -> Result<&'a [u8], String> {
    let json = usize::try_from(view)
        .ok()
        .and_then(|v| root.buffer_views.get(v))
        .ok_or_else(|| format!("buffer view {view} does not exist"))?;
    let data = buffers
        .get(json.buffer.value())
        .ok_or_else(|| format!("buffer {} does not exist", json.buffer.value()))?;
    let start = usize::try_from(json.byte_offset.map_or(0, |o| o.0)).ok();
    let length = usize::try_from(json.byte_length.0).ok();
    start
        .zip(length)
        .and_then(|(s, l)| data.get(s..s.checked_add(l)?))
        .ok_or_else(|| format!("buffer view {view} lies outside its buffer"))
}

/// Puts `streams` in one new buffer (a view each) and points the primitive at new accessors
/// over them; the primitive becomes an indexed triangle list without the extension.
fn install(
    root: &mut Root,
    buffers: &mut Vec<Data>,
    m: usize,
    p: usize,
    streams: Vec<Stream>,
) -> Result<(), String> {
    let too_many = || "too many buffers, views or accessors".to_string();
    let buffer_index = u32::try_from(buffers.len()).map_err(|_| too_many())?;
    let mut data = Vec::new();
    for stream in streams {
        let view_index = u32::try_from(root.buffer_views.len()).map_err(|_| too_many())?;
        root.buffer_views.push(gltf::json::buffer::View {
            buffer: Index::new(buffer_index),
            byte_length: USize64::from(stream.bytes.len()),
            byte_offset: Some(USize64::from(data.len())),
            byte_stride: None,
            name: None,
            target: None,
            extensions: None,
            extras: Default::default(),
        });
        data.extend_from_slice(&stream.bytes);
        let old = stream.old.and_then(|a| root.accessors.get(a));
        let accessor = Accessor {
            buffer_view: Some(Index::new(view_index)),
            byte_offset: Some(USize64(0)),
            count: USize64::from(stream.count),
            component_type: Checked::Valid(GenericComponentType(stream.component)),
            extensions: None,
            extras: Default::default(),
            type_: Checked::Valid(stream.type_),
            // Bounds in the old accessor's terms are kept only for float data.
            min: old.filter(|a| !a.normalized).and_then(|a| a.min.clone()),
            max: old.filter(|a| !a.normalized).and_then(|a| a.max.clone()),
            name: old.and_then(|a| a.name.clone()),
            normalized: false,
            sparse: None,
        };
        let accessor_index = u32::try_from(root.accessors.len()).map_err(|_| too_many())?;
        root.accessors.push(accessor);
        let primitive = &mut root.meshes[m].primitives[p];
        match stream.semantic {
            Some(semantic) => {
                primitive
                    .attributes
                    .insert(semantic, Index::new(accessor_index));
            }
            None => primitive.indices = Some(Index::new(accessor_index)),
        }
    }
    let primitive = &mut root.meshes[m].primitives[p];
    // The decoded faces are triangles whatever the strip/fan mode said.
    primitive.mode = Checked::Valid(Mode::Triangles);
    if let Some(e) = primitive.extensions.as_mut() {
        e.others.remove(NAME);
    }
    root.buffers.push(gltf::json::Buffer {
        byte_length: USize64::from(data.len()),
        name: Some(format!("decoded {NAME} meshes[{m}].primitives[{p}]")),
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    buffers.push(Data(data));
    Ok(())
}
