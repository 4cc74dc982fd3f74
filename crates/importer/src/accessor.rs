//! Bounds-checked reading of glTF accessors (glTF 2.0, "Accessors": strides, sparse
//! accessors, normalized integers).
//!
//! This replaces the `gltf` crate's `Reader` for the two accessors the importer needs
//! (POSITION and indices): that reader panics on some invalid files a user may hand us
//! (`unreachable!` on a float index accessor, `count - 1` on an empty accessor, asserts on
//! short strides) and reads quantized integer positions as if they were floats.
//! Every offset here is computed with checked arithmetic and every slice taken with `get`.

use glam::DVec3;
use gltf::buffer::Data;
use gltf::json::accessor::{sparse, ComponentType, Type};
use gltf::json::validation::Checked;
use gltf::json::Root;

/// The most elements an accessor may have (a memory guard: a sparse accessor without a
/// buffer view needs no data for its `count`).
pub(crate) const MAX_COUNT: usize = 1 << 24;

/// Reads a VEC3 accessor (any component type; normalized integers are dequantized).
pub(crate) fn read_vec3(root: &Root, buffers: &[Data], index: usize) -> Result<Vec<DVec3>, String> {
    let values = read_components(root, buffers, index, Type::Vec3)?;
    Ok(values
        .chunks_exact(3)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect())
}

/// Reads a VEC2 accessor (texture coordinates: float, or normalized unsigned byte/short).
pub(crate) fn read_vec2(
    root: &Root,
    buffers: &[Data],
    index: usize,
) -> Result<Vec<glam::DVec2>, String> {
    let values = read_components(root, buffers, index, Type::Vec2)?;
    Ok(values
        .chunks_exact(2)
        .map(|c| glam::DVec2::new(c[0], c[1]))
        .collect())
}

/// Reads a colour accessor (`COLOR_n`): VEC3 or VEC4 (alpha dropped), float or normalized
/// unsigned byte/short, as linear RGB.
pub(crate) fn read_colors(
    root: &Root,
    buffers: &[Data],
    index: usize,
) -> Result<Vec<DVec3>, String> {
    let accessor = root
        .accessors
        .get(index)
        .ok_or_else(|| format!("accessor {index} does not exist"))?;
    let (ty, n) = match accessor.type_ {
        Checked::Valid(Type::Vec3) => (Type::Vec3, 3),
        Checked::Valid(Type::Vec4) => (Type::Vec4, 4),
        _ => return Err(format!("colour accessor {index} is not VEC3 or VEC4")),
    };
    let values = read_components(root, buffers, index, ty)?;
    Ok(values
        .chunks_exact(n)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect())
}

/// Reads an index accessor: SCALAR, unsigned byte/short/int, not normalized.
pub(crate) fn read_indices(
    root: &Root,
    buffers: &[Data],
    index: usize,
) -> Result<Vec<u32>, String> {
    let accessor = root
        .accessors
        .get(index)
        .ok_or_else(|| format!("accessor {index} does not exist"))?;
    let component = component_type(accessor, index)?;
    if !matches!(
        component,
        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
    ) || accessor.normalized
    {
        return Err(format!(
            "index accessor {index} has component type {component:?}; expected unsigned integers"
        ));
    }
    let values = read_components(root, buffers, index, Type::Scalar)?;
    // Unsigned integers of ≤ 32 bits are exact in f64.
    Ok(values.into_iter().map(|v| v as u32).collect())
}

/// How one element is stored.
#[derive(Clone, Copy)]
struct Element {
    component: ComponentType,
    components: usize,
    normalized: bool,
}

impl Element {
    fn size(self) -> usize {
        self.component.size() * self.components
    }
}

fn component_type(accessor: &gltf::json::Accessor, index: usize) -> Result<ComponentType, String> {
    match accessor.component_type {
        Checked::Valid(c) => Ok(c.0),
        Checked::Invalid => Err(format!("accessor {index} has an invalid component type")),
    }
}

/// Reads all components of an accessor of type `expected` as f64, applying sparse
/// substitution.
fn read_components(
    root: &Root,
    buffers: &[Data],
    index: usize,
    expected: Type,
) -> Result<Vec<f64>, String> {
    let accessor = root
        .accessors
        .get(index)
        .ok_or_else(|| format!("accessor {index} does not exist"))?;
    let ty = match accessor.type_ {
        Checked::Valid(t) if t == expected => t,
        Checked::Valid(t) => {
            return Err(format!(
                "accessor {index} has type {t:?}; expected {expected:?}"
            ))
        }
        Checked::Invalid => return Err(format!("accessor {index} has an invalid type")),
    };
    let element = Element {
        component: component_type(accessor, index)?,
        components: ty.multiplicity(),
        normalized: accessor.normalized,
    };
    let count = to_usize(accessor.count.0)?;
    if count > MAX_COUNT {
        return Err(format!(
            "accessor {index} has {count} elements, more than the importer's limit of {MAX_COUNT}"
        ));
    }
    let mut values = match (accessor.buffer_view, &accessor.sparse) {
        (Some(view), _) => {
            let (data, stride) = view_data(root, buffers, view.value(), element.size())?;
            let offset = to_usize(accessor.byte_offset.map_or(0, |o| o.0))?;
            read_strided(data, offset, stride, element, count)
                .map_err(|e| format!("accessor {index}: {e}"))?
        }
        // Zeros (glTF 2.0, "Accessors"), possibly with sparse values over them.
        (None, _) => vec![0.0; count * element.components],
    };
    if let Some(sparse) = &accessor.sparse {
        apply_sparse(root, buffers, sparse, element, count, &mut values)
            .map_err(|e| format!("accessor {index} (sparse): {e}"))?;
    }
    Ok(values)
}

fn to_usize(n: u64) -> Result<usize, String> {
    usize::try_from(n).map_err(|_| format!("size {n} does not fit in memory"))
}

/// The bytes of a buffer view, and its stride (the element size when none is given).
fn view_data<'a>(
    root: &Root,
    buffers: &'a [Data],
    view_index: usize,
    element_size: usize,
) -> Result<(&'a [u8], usize), String> {
    let view = root
        .buffer_views
        .get(view_index)
        .ok_or_else(|| format!("buffer view {view_index} does not exist"))?;
    let buffer = buffers
        .get(view.buffer.value())
        .ok_or_else(|| format!("buffer {} does not exist", view.buffer.value()))?;
    let start = to_usize(view.byte_offset.map_or(0, |o| o.0))?;
    let length = to_usize(view.byte_length.0)?;
    let data = start
        .checked_add(length)
        .and_then(|end| buffer.get(start..end))
        .ok_or_else(|| format!("buffer view {view_index} lies outside its buffer"))?;
    let stride = view.byte_stride.map_or(element_size, |s| s.0);
    if stride < element_size {
        return Err(format!(
            "buffer view {view_index} has stride {stride}, \
             less than the element size {element_size}"
        ));
    }
    Ok((data, stride))
}

/// Reads `count` elements, `stride` bytes apart, from `offset` in `data`; the range is
/// checked before anything is allocated.
fn read_strided(
    data: &[u8],
    offset: usize,
    stride: usize,
    element: Element,
    count: usize,
) -> Result<Vec<f64>, String> {
    if count == 0 {
        return Ok(Vec::new());
    }
    let end = stride
        .checked_mul(count - 1)
        .and_then(|n| n.checked_add(offset))
        .and_then(|n| n.checked_add(element.size()));
    if end.is_none_or(|end| end > data.len()) {
        return Err(format!(
            "{count} elements from byte {offset} do not fit in the buffer view ({} bytes)",
            data.len()
        ));
    }
    let mut values = vec![0.0; count * element.components];
    for (i, out) in values.chunks_exact_mut(element.components).enumerate() {
        read_element(data, offset + i * stride, element, out)?;
    }
    Ok(values)
}

/// Decodes one element starting at byte `at` into `out`.
fn read_element(data: &[u8], at: usize, element: Element, out: &mut [f64]) -> Result<(), String> {
    let size = element.component.size();
    for (c, value) in out.iter_mut().enumerate() {
        let start = at + c * size;
        let bytes = data
            .get(start..start + size)
            .ok_or_else(|| format!("byte {start} is outside the buffer view"))?;
        *value = decode(bytes, element.component, element.normalized);
    }
    Ok(())
}

/// One little-endian component; normalized integers map to [0, 1] or [-1, 1] with the
/// glTF 2.0 formulas (e.g. `max(c / 127, -1)` for signed bytes).
fn decode(bytes: &[u8], component: ComponentType, normalized: bool) -> f64 {
    let mut b = [0u8; 4];
    for (dst, src) in b.iter_mut().zip(bytes) {
        *dst = *src;
    }
    let (value, scale) = match component {
        ComponentType::F32 => return f64::from(f32::from_le_bytes(b)),
        ComponentType::I8 => (f64::from(b[0] as i8), 127.0),
        ComponentType::U8 => (f64::from(b[0]), 255.0),
        ComponentType::I16 => (f64::from(i16::from_le_bytes([b[0], b[1]])), 32767.0),
        ComponentType::U16 => (f64::from(u16::from_le_bytes([b[0], b[1]])), 65535.0),
        ComponentType::U32 => (f64::from(u32::from_le_bytes(b)), 4294967295.0),
    };
    if normalized {
        (value / scale).max(-1.0)
    } else {
        value
    }
}

/// Sparse substitution: `sparse.count` indices (strictly below `count`) and as many
/// tightly packed replacement elements.
fn apply_sparse(
    root: &Root,
    buffers: &[Data],
    sparse: &sparse::Sparse,
    element: Element,
    count: usize,
    values: &mut [f64],
) -> Result<(), String> {
    let n = to_usize(sparse.count.0)?;
    if n > count {
        return Err(format!("{n} substitutions for {count} elements"));
    }
    let index_type = match sparse.indices.component_type {
        Checked::Valid(t) => t.0,
        Checked::Invalid => return Err("invalid index component type".into()),
    };
    let index_element = Element {
        component: index_type,
        components: 1,
        normalized: false,
    };
    let (data, _) = view_data(
        root,
        buffers,
        sparse.indices.buffer_view.value(),
        index_element.size(),
    )?;
    let offset = to_usize(sparse.indices.byte_offset.0)?;
    let indices = read_strided(data, offset, index_element.size(), index_element, n)?;

    let (data, _) = view_data(
        root,
        buffers,
        sparse.values.buffer_view.value(),
        element.size(),
    )?;
    let offset = to_usize(sparse.values.byte_offset.0)?;
    let replacements = read_strided(data, offset, element.size(), element, n)?;

    for (k, (&i, replacement)) in indices
        .iter()
        .zip(replacements.chunks_exact(element.components))
        .enumerate()
    {
        let start = (i as usize).saturating_mul(element.components);
        let slot = values
            .get_mut(start..start.saturating_add(element.components))
            .ok_or_else(|| format!("sparse index {k} is out of range ({count} elements)"))?;
        slot.copy_from_slice(replacement);
    }
    Ok(())
}
