//! `EXT_meshopt_compression` buffer views, decoded into plain bytes.
//!
//! A buffer view carrying the extension holds its data compressed in another buffer range
//! (the extension's `buffer`, `byteOffset`, `byteLength`); the view's own `buffer` is then
//! usually a fallback buffer without data (EXT_meshopt_compression README, "Fallback
//! buffers"). Each such view is decoded with meshoptimizer's reference decoder into a fresh
//! buffer, and the view is rewritten to point at it, so the accessor readers see an
//! ordinary view.
//!
//! What this is not: an encoder, or a reader of `KHR_meshopt_compression` (a later
//! extension with codec version 1 and more filters); the `COLOR` filter of that extension is
//! refused as an unknown filter.

use gltf::buffer::Data;
use gltf::json::validation::USize64;
use gltf::json::Root;
use serde_json::Value;

/// The extension's name.
pub(crate) const NAME: &str = "EXT_meshopt_compression";

/// The most bytes one decoded view may have (a memory guard: the header's `count` costs
/// the file nothing).
const MAX_DECODED_BYTES: usize = 1 << 30;

/// How the data was encoded (EXT_meshopt_compression README, "Compression modes").
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    Attributes,
    Triangles,
    Indices,
}

/// The post-decode transform (README, "Filters").
#[derive(Clone, Copy, Debug, PartialEq)]
enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
}

/// True when buffer `json` is a fallback buffer (README, "Fallback buffers": the buffer
/// carries the extension with `fallback: true`; it has no data a reader may use).
pub(crate) fn is_fallback(json: &gltf::json::Buffer) -> bool {
    json.extensions
        .as_ref()
        .and_then(|e| e.others.get(NAME))
        .and_then(|e| e.get("fallback"))
        .and_then(Value::as_bool)
        .unwrap_or(false)
}

/// Decodes every compressed buffer view of `root` into a buffer of its own (appended to
/// `buffers` and `root.buffers`) and removes the extension from the view.
pub(crate) fn decode_views(root: &mut Root, buffers: &mut Vec<Data>) -> Result<(), String> {
    for v in 0..root.buffer_views.len() {
        let Some(extension) = root.buffer_views[v]
            .extensions
            .as_ref()
            .and_then(|e| e.others.get(NAME))
            .cloned()
        else {
            continue;
        };
        let decoded = decode_view(&extension, buffers)
            .map_err(|e| format!("buffer view {v} ({NAME}): {e}"))?;
        let length = decoded.len();
        let index = buffers.len();
        buffers.push(Data(decoded));
        root.buffers.push(gltf::json::Buffer {
            byte_length: USize64::from(length),
            name: Some(format!("decoded {NAME} view {v}")),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let view = &mut root.buffer_views[v];
        view.buffer = gltf::json::Index::new(
            u32::try_from(index).map_err(|_| "too many buffers".to_string())?,
        );
        view.byte_offset = Some(USize64(0));
        view.byte_length = USize64::from(length);
        if let Some(e) = view.extensions.as_mut() {
            e.others.remove(NAME);
        }
    }
    Ok(())
}

/// Reads one field of the extension object as an unsigned integer.
fn field(extension: &Value, name: &str) -> Result<Option<usize>, String> {
    match extension.get(name) {
        None => Ok(None),
        Some(v) => v
            .as_u64()
            .and_then(|n| usize::try_from(n).ok())
            .map(Some)
            .ok_or_else(|| format!("`{name}` is not a non-negative integer")),
    }
}

fn required(extension: &Value, name: &str) -> Result<usize, String> {
    field(extension, name)?.ok_or_else(|| format!("`{name}` is missing"))
}

/// One view's decoded bytes: `count` elements of `byteStride` bytes.
fn decode_view(extension: &Value, buffers: &[Data]) -> Result<Vec<u8>, String> {
    let buffer = required(extension, "buffer")?;
    let offset = field(extension, "byteOffset")?.unwrap_or(0);
    let length = required(extension, "byteLength")?;
    let stride = required(extension, "byteStride")?;
    let count = required(extension, "count")?;
    let mode = match extension.get("mode").and_then(Value::as_str) {
        Some("ATTRIBUTES") => Mode::Attributes,
        Some("TRIANGLES") => Mode::Triangles,
        Some("INDICES") => Mode::Indices,
        other => return Err(format!("unknown mode {other:?}")),
    };
    let filter = match extension.get("filter").map(Value::as_str) {
        None | Some(Some("NONE")) => Filter::None,
        Some(Some("OCTAHEDRAL")) => Filter::Octahedral,
        Some(Some("QUATERNION")) => Filter::Quaternion,
        Some(Some("EXPONENTIAL")) => Filter::Exponential,
        Some(other) => return Err(format!("unknown filter {other:?}")),
    };
    let data = buffers
        .get(buffer)
        .ok_or_else(|| format!("buffer {buffer} does not exist"))?;
    let encoded = offset
        .checked_add(length)
        .and_then(|end| data.get(offset..end))
        .ok_or_else(|| {
            format!(
                "bytes {offset}..+{length} lie outside buffer {buffer} (is it a fallback buffer?)"
            )
        })?;
    if count > crate::accessor::MAX_COUNT {
        return Err(format!(
            "{count} elements, more than the importer's limit of {}",
            crate::accessor::MAX_COUNT
        ));
    }
    let size = count
        .checked_mul(stride)
        .filter(|&n| n <= MAX_DECODED_BYTES)
        .ok_or_else(|| format!("{count} elements of {stride} bytes are too many to decode"))?;
    // README, "Compression modes" and "Filters": the constraints each mode and filter puts on
    // byteStride and count.
    let stride_ok = match (mode, filter) {
        (Mode::Attributes, Filter::None | Filter::Exponential) => {
            stride % 4 == 0 && (4..=256).contains(&stride)
        }
        (Mode::Attributes, Filter::Octahedral) => stride == 4 || stride == 8,
        (Mode::Attributes, Filter::Quaternion) => stride == 8,
        (_, Filter::None) => stride == 2 || stride == 4,
        (_, _) => return Err(format!("filter {filter:?} with mode {mode:?}")),
    };
    if !stride_ok {
        return Err(format!(
            "byteStride {stride} is not allowed for mode {mode:?} with filter {filter:?}"
        ));
    }
    let native = |e: ::meshopt::Error| format!("the compressed data is malformed ({e})");
    match mode {
        Mode::Attributes => {
            let mut out = vec![0u8; size];
            // SAFETY: `out` holds exactly `count * stride` bytes, which is what the decoder
            // writes (`vertex_count` elements of `vertex_size` bytes); it reads at most
            // `encoded.len()` bytes of `encoded`. meshoptimizer documents the decoder as
            // safe on untrusted input (it returns an error code instead of overrunning).
            // The crate's safe `decode_vertex_buffer` needs the element size as a type,
            // which varies per view here (4 to 256 bytes).
            let code = unsafe {
                ::meshopt::ffi::meshopt_decodeVertexBuffer(
                    out.as_mut_ptr().cast(),
                    count,
                    stride,
                    encoded.as_ptr(),
                    encoded.len(),
                )
            };
            if code != 0 {
                return Err(native(::meshopt::Error::Native(code)));
            }
            apply_filter(&mut out, stride, filter);
            Ok(out)
        }
        Mode::Triangles | Mode::Indices => {
            if mode == Mode::Triangles && count % 3 != 0 {
                return Err(format!(
                    "TRIANGLES with {count} indices (not a multiple of 3)"
                ));
            }
            let indices: Vec<u32> = if mode == Mode::Triangles {
                ::meshopt::decode_index_buffer(encoded, count).map_err(native)?
            } else {
                ::meshopt::decode_index_sequence(encoded, count).map_err(native)?
            };
            Ok(if stride == 2 {
                // The encoder wrote 16-bit indices; none exceeds u16 then.
                indices
                    .iter()
                    .flat_map(|&i| (i as u16).to_le_bytes())
                    .collect()
            } else {
                indices.iter().flat_map(|&i| i.to_le_bytes()).collect()
            })
        }
    }
}

/// Applies `filter` in place to decoded attribute bytes (little-endian elements of `stride`
/// bytes; the strides were checked against the filter).
fn apply_filter(out: &mut [u8], stride: usize, filter: Filter) {
    match (filter, stride) {
        (Filter::None, _) => {}
        (Filter::Octahedral, 4) => {
            let mut v: Vec<[i8; 4]> = out
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]].map(|b| b as i8))
                .collect();
            ::meshopt::decode_filter_oct(&mut v);
            for (dst, src) in out.chunks_exact_mut(4).zip(&v) {
                dst.copy_from_slice(&src.map(|x| x as u8));
            }
        }
        (Filter::Octahedral, _) => {
            let mut v = shorts(out);
            ::meshopt::decode_filter_oct(&mut v);
            write_shorts(out, &v);
        }
        (Filter::Quaternion, _) => {
            let mut v = shorts(out);
            ::meshopt::decode_filter_quat(&mut v);
            write_shorts(out, &v);
        }
        (Filter::Exponential, _) => {
            // Each 32-bit component decodes on its own (README, "Filters").
            let mut v: Vec<[u32; 1]> = out
                .chunks_exact(4)
                .map(|c| [u32::from_le_bytes([c[0], c[1], c[2], c[3]])])
                .collect();
            ::meshopt::decode_filter_exp(&mut v);
            for (dst, src) in out.chunks_exact_mut(4).zip(&v) {
                dst.copy_from_slice(&src[0].to_le_bytes());
            }
        }
    }
}

fn shorts(bytes: &[u8]) -> Vec<[i16; 4]> {
    bytes
        .chunks_exact(8)
        .map(|c| {
            let s = |k: usize| i16::from_le_bytes([c[2 * k], c[2 * k + 1]]);
            [s(0), s(1), s(2), s(3)]
        })
        .collect()
}

fn write_shorts(bytes: &mut [u8], values: &[[i16; 4]]) {
    for (dst, src) in bytes.chunks_exact_mut(8).zip(values) {
        for (k, s) in src.iter().enumerate() {
            dst[2 * k..2 * k + 2].copy_from_slice(&s.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn view(stride: usize, count: usize, mode: &str, filter: &str, len: usize) -> Value {
        json!({"buffer": 0, "byteOffset": 0, "byteLength": len, "byteStride": stride,
               "count": count, "mode": mode, "filter": filter})
    }

    #[test]
    fn vertex_buffer_round_trips_exactly() {
        let vertices: Vec<[f32; 3]> = (0..50)
            .map(|i| [i as f32 * 0.25, (i * i) as f32 - 3.5, -(i as f32)])
            .collect();
        let encoded = ::meshopt::encode_vertex_buffer(&vertices).unwrap();
        let ext = view(12, 50, "ATTRIBUTES", "NONE", encoded.len());
        let out = decode_view(&ext, &[Data(encoded)]).unwrap();
        let expected: Vec<u8> = vertices
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        assert_eq!(out, expected);
    }

    #[test]
    fn triangles_decode_to_16_bit_indices() {
        let indices: Vec<u32> = vec![0, 1, 2, 2, 1, 3, 3, 1, 4];
        let encoded = ::meshopt::encode_index_buffer(&indices, 5).unwrap();
        let ext = view(2, 9, "TRIANGLES", "NONE", encoded.len());
        let out = decode_view(&ext, &[Data(encoded)]).unwrap();
        let got: Vec<u16> = out
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        // The codec may rotate a triangle's corners but keeps each triangle and its winding.
        assert_eq!(got.len(), 9);
        for (t, want) in got.chunks_exact(3).zip(indices.chunks_exact(3)) {
            let w: Vec<u16> = want.iter().map(|&i| i as u16).collect();
            let rotations = [[w[0], w[1], w[2]], [w[1], w[2], w[0]], [w[2], w[0], w[1]]];
            assert!(rotations.iter().any(|r| r == t), "{t:?} vs {w:?}");
        }
    }

    #[test]
    fn exponential_and_octahedral_filters_are_applied() {
        // EXPONENTIAL (README, "Filters"): positions as 2^e·m with 15-bit mantissas.
        let positions: Vec<[f32; 3]> = (0..20)
            .map(|i| [i as f32 * 13.7, -(i as f32) * 0.031, 559.2 - i as f32])
            .collect();
        let filtered =
            ::meshopt::encode_filter_exp(&positions, 15, ::meshopt::EncodeExpMode::Separate);
        let encoded = ::meshopt::encode_vertex_buffer(&filtered).unwrap();
        let ext = view(12, 20, "ATTRIBUTES", "EXPONENTIAL", encoded.len());
        let out = decode_view(&ext, &[Data(encoded)]).unwrap();
        for (p, c) in positions.iter().flatten().zip(out.chunks_exact(4)) {
            let got = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            assert!(
                (got - p).abs() <= p.abs() * 2f32.powi(-14) + 1e-6,
                "{got} vs {p}"
            );
        }
        // OCTAHEDRAL: unit normals as 8-bit snorm.
        let normals: Vec<[f32; 4]> = vec![[0.0, 1.0, 0.0, 0.0], [0.6, 0.0, -0.8, 0.0]];
        let filtered: Vec<[i8; 4]> = ::meshopt::encode_filter_oct(&normals, 8);
        let encoded = ::meshopt::encode_vertex_buffer(&filtered).unwrap();
        let ext = view(4, 2, "ATTRIBUTES", "OCTAHEDRAL", encoded.len());
        let out = decode_view(&ext, &[Data(encoded)]).unwrap();
        for (n, c) in normals.iter().zip(out.chunks_exact(4)) {
            for k in 0..3 {
                let got = f32::from(c[k] as i8) / 127.0;
                assert!((got - n[k]).abs() < 0.03, "{got} vs {}", n[k]);
            }
        }
    }

    #[test]
    fn mutated_streams_decode_or_fail_without_panicking() {
        let vertices: Vec<[f32; 3]> = (0..40).map(|i| [i as f32, 1.5, -(i as f32)]).collect();
        let indices: Vec<u32> = (0..38).flat_map(|i| [i, i + 1, i + 2]).collect();
        let streams = [
            (
                ::meshopt::encode_vertex_buffer(&vertices).unwrap(),
                12,
                40,
                "ATTRIBUTES",
            ),
            (
                ::meshopt::encode_index_buffer(&indices, 40).unwrap(),
                4,
                114,
                "TRIANGLES",
            ),
            (
                ::meshopt::encode_index_sequence(&indices, 40).unwrap(),
                4,
                114,
                "INDICES",
            ),
        ];
        for (encoded, stride, count, mode) in streams {
            for at in 0..encoded.len() {
                for value in [0x00, 0x5a, 0xff] {
                    let mut bytes = encoded.clone();
                    bytes[at] = value;
                    let ext = view(stride, count, mode, "NONE", bytes.len());
                    let _ = decode_view(&ext, &[Data(bytes)]);
                }
            }
        }
    }

    #[test]
    fn malformed_and_oversized_views_are_errors_not_panics() {
        let ext = view(12, 10, "ATTRIBUTES", "NONE", 4);
        assert!(decode_view(&ext, &[Data(vec![0xa0, 1, 2, 3])]).is_err());
        // Stride not a multiple of 4, a range past the buffer, a huge count.
        assert!(decode_view(&view(6, 1, "ATTRIBUTES", "NONE", 4), &[Data(vec![0; 4])]).is_err());
        assert!(decode_view(&view(4, 1, "ATTRIBUTES", "NONE", 99), &[Data(vec![0; 4])]).is_err());
        assert!(decode_view(
            &view(256, 1 << 24, "ATTRIBUTES", "NONE", 4),
            &[Data(vec![0; 4])]
        )
        .is_err());
        assert!(decode_view(
            &view(4, 3, "TRIANGLES", "OCTAHEDRAL", 4),
            &[Data(vec![0; 4])]
        )
        .is_err());
    }
}
