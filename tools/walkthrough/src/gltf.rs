//! glTF 2.0 writer for a [`Floor`] (an office floor or an atrium): `.gltf` + `.bin` beside
//! it, or a `.glb`, chosen by the extension (the approach of `tools/fixtures/src/gltf.rs`).
//! A floor with a sun gets a `KHR_lights_punctual` directional light of [`SUN_LUX`].
//!
//! One node and one mesh per room; one primitive per surface of the room (floor, walls, ceiling,
//! light panels, desk, cabinet) with its own material. Each primitive is indexed triangles
//! (u32; a quad is the fan (0, 1, 2), (0, 2, 3), counter-clockwise seen from the normal side),
//! POSITION (with min/max) and NORMAL (each face's own corners and normal). Materials are lit
//! and ideal diffuse: baseColorFactor = ρ, metallic 0, roughness 1; the panels' emission e is
//! emissiveFactor e / max(e) × `KHR_materials_emissive_strength` max(e).

use crate::office::{normal, Floor, Quad, Surface};
use anyhow::{Context, Result};
use serde_json::{json, Map, Value};
use std::path::Path;

const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const TRIANGLES: u32 = 4;
const EMISSIVE_STRENGTH: &str = "KHR_materials_emissive_strength";
const LIGHTS: &str = "KHR_lights_punctual";
/// The sun's illuminance (lux) of a scene with one ([`Floor::sun`]).
pub const SUN_LUX: f64 = 100.0;

/// The unit quaternion (x, y, z, w) that turns −Z onto the unit vector `d`.
fn rotation_to(d: [f64; 3]) -> [f64; 4] {
    let a = [0.0, 0.0, -1.0];
    let dot = a[2] * d[2];
    if dot < -1.0 + 1e-12 {
        // d = +Z: half a turn about y.
        return [0.0, 1.0, 0.0, 0.0];
    }
    // q = (a × d, 1 + a · d), normalised.
    let c = [
        a[1] * d[2] - a[2] * d[1],
        a[2] * d[0] - a[0] * d[2],
        a[0] * d[1] - a[1] * d[0],
    ];
    let q = [c[0], c[1], c[2], 1.0 + dot];
    let len = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| v / len)
}

/// The files of `floor` written as `out` (`.gltf` or `.glb`): (path, contents).
pub fn files(floor: &Floor, out: &Path) -> Result<Vec<(std::path::PathBuf, Vec<u8>)>> {
    let extension = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let bin = Binary::new(floor)?;
    match extension.as_deref() {
        Some("gltf") => {
            let stem = out
                .file_stem()
                .and_then(|s| s.to_str())
                .with_context(|| format!("{}: file name is not UTF-8", out.display()))?;
            let bin_name = format!("{stem}.bin");
            let doc = document(floor, &bin, Some(&bin_name));
            let mut text = serde_json::to_vec_pretty(&doc)?;
            text.push(b'\n');
            Ok(vec![
                (out.to_path_buf(), text),
                (out.with_file_name(&bin_name), bin.bytes),
            ])
        }
        Some("glb") => Ok(vec![(
            out.to_path_buf(),
            glb(&document(floor, &bin, None), &bin.bytes)?,
        )]),
        _ => anyhow::bail!("{}: the output must end in .gltf or .glb", out.display()),
    }
}

/// Writes `floor` as `out`; returns the paths written.
pub fn write(floor: &Floor, out: &Path) -> Result<Vec<std::path::PathBuf>> {
    let mut written = Vec::new();
    for (path, bytes) in files(floor, out)? {
        std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}

/// One primitive's place in the buffer.
struct Primitive {
    surface: Surface,
    corners: usize,
    /// Byte offsets into the VEC3 sections and the index section.
    vec3_offset: usize,
    index_offset: usize,
    min: [f32; 3],
    max: [f32; 3],
}

/// Every primitive's positions, then every primitive's normals, then every primitive's indices
/// (little-endian f32 / u32), each section 4-byte aligned.
struct Binary {
    bytes: Vec<u8>,
    positions: (usize, usize),
    normals: (usize, usize),
    indices: (usize, usize),
    /// Per room, its primitives.
    rooms: Vec<Vec<Primitive>>,
}

impl Binary {
    fn new(floor: &Floor) -> Result<Self> {
        let groups: Vec<&[(Surface, Vec<Quad>)]> =
            floor.room_list.iter().map(|r| r.faces.as_slice()).collect();
        let mut bytes = Vec::new();
        let start = bytes.len();
        let mut rooms = Vec::new();
        let (mut vec3_offset, mut index_offset) = (0, 0);
        for faces in &groups {
            let mut prims = Vec::new();
            for (surface, quads) in faces.iter() {
                let mut min = [f32::INFINITY; 3];
                let mut max = [f32::NEG_INFINITY; 3];
                for p in quads.iter().flatten() {
                    for k in 0..3 {
                        let x = p[k] as f32;
                        min[k] = min[k].min(x);
                        max[k] = max[k].max(x);
                        bytes.extend(x.to_le_bytes());
                    }
                }
                let corners = 4 * quads.len();
                if u32::try_from(corners).is_err() {
                    anyhow::bail!("a primitive has too many corners for u32 indices");
                }
                prims.push(Primitive {
                    surface: *surface,
                    corners,
                    vec3_offset,
                    index_offset,
                    min,
                    max,
                });
                vec3_offset += corners * 12;
                index_offset += quads.len() * 6 * 4;
            }
            rooms.push(prims);
        }
        let positions = (start, bytes.len() - start);
        let start = bytes.len();
        for faces in &groups {
            for (_, quads) in faces.iter() {
                for q in quads.iter() {
                    let n = normal(q).map(|x| x as f32);
                    for _ in q {
                        for x in n {
                            bytes.extend(x.to_le_bytes());
                        }
                    }
                }
            }
        }
        let normals = (start, bytes.len() - start);
        let start = bytes.len();
        for faces in &groups {
            for (_, quads) in faces.iter() {
                for k in 0..quads.len() as u32 {
                    let b = 4 * k;
                    for i in [b, b + 1, b + 2, b, b + 2, b + 3] {
                        bytes.extend(i.to_le_bytes());
                    }
                }
            }
        }
        let indices = (start, bytes.len() - start);
        Ok(Self {
            bytes,
            positions,
            normals,
            indices,
            rooms,
        })
    }
}

/// The glTF JSON. `uri` is the buffer's file name, or `None` for a .glb.
fn document(floor: &Floor, bin: &Binary, uri: Option<&str>) -> Value {
    let mut buffer = json!({ "byteLength": bin.bytes.len() });
    if let Some(uri) = uri {
        buffer["uri"] = json!(uri);
    }
    let view = |(offset, length): (usize, usize), target, stride: Option<usize>| {
        let mut v = json!({
            "buffer": 0, "byteOffset": offset, "byteLength": length, "target": target,
        });
        if let Some(stride) = stride {
            v["byteStride"] = json!(stride);
        }
        v
    };
    let buffer_views = vec![
        view(bin.positions, ARRAY_BUFFER, Some(12)),
        view(bin.normals, ARRAY_BUFFER, Some(12)),
        view(bin.indices, ELEMENT_ARRAY_BUFFER, None),
    ];
    let mut accessors = Vec::new();
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    for (r, (room, prims)) in floor.room_list.iter().zip(&bin.rooms).enumerate() {
        let mut primitives = Vec::new();
        for p in prims {
            let first = accessors.len();
            accessors.push(json!({
                "bufferView": 0, "byteOffset": p.vec3_offset, "componentType": FLOAT,
                "count": p.corners, "type": "VEC3", "min": p.min, "max": p.max,
            }));
            accessors.push(json!({
                "bufferView": 1, "byteOffset": p.vec3_offset, "componentType": FLOAT,
                "count": p.corners, "type": "VEC3",
            }));
            accessors.push(json!({
                "bufferView": 2, "byteOffset": p.index_offset,
                "componentType": UNSIGNED_INT, "count": p.corners / 4 * 6, "type": "SCALAR",
            }));
            let material = Surface::ALL
                .iter()
                .position(|s| *s == p.surface)
                .unwrap_or(0);
            primitives.push(json!({
                "attributes": { "POSITION": first, "NORMAL": first + 1 },
                "indices": first + 2,
                "material": material,
                "mode": TRIANGLES,
            }));
        }
        meshes.push(json!({ "name": room.name, "primitives": primitives }));
        nodes.push(json!({ "name": room.name, "mesh": r }));
    }
    let materials: Vec<Value> = Surface::ALL.iter().map(|s| material(*s)).collect();
    let (generator, scene_name) = match &floor.title {
        Some((what, name)) => (what.clone(), name.clone()),
        None => (
            format!(
                "office {} rooms of {} m × {} m × {} m",
                floor.rooms, floor.room_size, floor.room_size, floor.height
            ),
            format!("office-{}", floor.rooms),
        ),
    };
    let mut extensions_used = vec![EMISSIVE_STRENGTH];
    if let Some(d) = floor.sun {
        // A directional light shines along its node's −Z: the rotation taking −Z to `d`.
        nodes.push(json!({
            "name": "sun",
            "rotation": rotation_to(d),
            "extensions": { LIGHTS: { "light": 0 } },
        }));
        extensions_used.push(LIGHTS);
    }
    let mut root = json!({
        "asset": {
            "version": "2.0",
            "generator": format!("bake-walkthrough (tools/walkthrough): {generator}"),
        },
        "scene": 0,
        "scenes": [{ "name": scene_name, "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": buffer_views,
        "buffers": [buffer],
        "extensionsUsed": extensions_used,
    });
    if floor.sun.is_some() {
        root["extensions"] = json!({
            LIGHTS: { "lights": [{ "name": "sun", "type": "directional", "intensity": SUN_LUX }] }
        });
    }
    // Same key order whatever serde_json features other crates switch on.
    root.sort_all_objects();
    root
}

fn material(surface: Surface) -> Value {
    let [r, g, b] = surface.rho();
    let mut m = json!({
        "name": surface.name(),
        "pbrMetallicRoughness": {
            "baseColorFactor": [r, g, b, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0,
        },
    });
    let e = surface.emission();
    let max = e.iter().copied().fold(0.0, f64::max);
    if max > 1.0 {
        m["emissiveFactor"] = json!(e.map(|x| x / max));
        let mut ext = Map::new();
        ext.insert(EMISSIVE_STRENGTH.into(), json!({ "emissiveStrength": max }));
        m["extensions"] = Value::Object(ext);
    } else if max > 0.0 {
        m["emissiveFactor"] = json!(e);
    }
    m
}

/// A .glb: 12-byte header, then a JSON chunk padded with spaces and a BIN chunk padded with
/// zeros, both to 4 bytes (glTF 2.0 §4.4 "Binary glTF Layout").
fn glb(doc: &Value, bin: &[u8]) -> Result<Vec<u8>> {
    let mut json = serde_json::to_vec(doc)?;
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let u32_len = |n: usize| u32::try_from(n).context("glb larger than 4 GiB");
    let total = u32_len(12 + 8 + json.len() + 8 + bin.len())?;
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(total.to_le_bytes());
    for (kind, data) in [(b"JSON", &json), (b"BIN\0", &bin)] {
        out.extend(u32_len(data.len())?.to_le_bytes());
        out.extend(kind);
        out.extend(data.iter());
    }
    Ok(out)
}
