//! Reads a scene (glTF 2.0 `.gltf`/`.glb`, or OBJ + MTL) into world-space polygons
//! with ideal-diffuse materials: the input of the radiosity method (Goral et al. 1984, §3,
//! "the first module reads a description of a polygonal environment").
//!
//! Public API: [`load`] → [`Scene`]. A [`Scene`] holds
//! - [`Polygon`]s in world space (every node transform applied, f64), each planar and convex,
//!   3 or 4 vertices counter-clockwise seen from the side it faces, tagged with its [`Origin`];
//! - [`Material`]s with reflectance ρ and emission e per colour band (RGB);
//! - a [`Layout`]: the input's node hierarchy, names and transforms, so the exporter can
//!   write the baked scene back with the same structure;
//! - punctual [`Light`]s (glTF `KHR_lights_punctual`: point, spot, directional) in world
//!   space; OBJ has no lights;
//! - the world origins of nodes marked as light probes (`"bake_probe": true` in a glTF
//!   node's `extras`, [`Scene::probe_points`]);
//! - [`ImportStats`] and human-readable warnings for everything that was dropped or changed.

use std::path::{Path, PathBuf};

mod accessor;
mod coincident;
mod compressed;
mod draco;
mod files;
mod gltf_in;
mod memory;
mod meshopt;
mod obj_in;
mod obj_texture;
mod polygon;
mod sky_map;
pub mod texture;

pub use files::MAX_FILE_BYTES;
/// The scene vocabulary lives in the `scene` crate; these names stay importable from here.
pub use scene::{
    authored_sets, bounds, AlphaMask, Authored, AuthoredTexture, EncodedImage, Image, ImportStats,
    Layout, Light, LightKind, Material, Mesh, Node, Origin, Polygon, PolygonUv, Primitive, Scene,
    SceneRoots, Side, Texture, TextureRef, Transform, UvTriangle, Wrap,
};
pub use sky_map::load_sky_map;

/// How [`load_with`] reads a scene's files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Options {
    /// Read buffer, image and `mtllib` references that are absolute paths, `file:` URIs or
    /// relative paths leading out of the scene file's folder (`..`, or a link inside it that
    /// points out). By default they are an error.
    pub allow_outside_paths: bool,
}

#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("unsupported file extension (expected .gltf, .glb or .obj)")]
    UnsupportedExtension,
    #[error("malformed glTF: {0}")]
    Gltf(String),
    #[error("malformed OBJ/MTL: {0}")]
    Obj(String),
    /// A value a user's file controls is out of range; names the mesh and polygon.
    #[error("{what}: {problem}")]
    InvalidValue { what: String, problem: String },
    #[error("nothing left to bake: the scene has no polygons with area")]
    Empty,
    /// A file the scene refers to may not be read: outside the scene's folder (see
    /// [`Options::allow_outside_paths`]).
    #[error("{0}")]
    Refused(String),
    /// The scene exceeds a fixed limit of the importer (the same on every machine).
    #[error("too large: {0}")]
    TooLarge(String),
    /// The scene needs more memory than this machine has available now (`MemAvailable`):
    /// it may bake on a larger one ([`ImportError::is_too_large`]).
    #[error("too large for this machine: {0}")]
    ExceedsMemory(String),
}

impl ImportError {
    /// Whether the file is refused only for the memory this machine has: the same file may
    /// import on a machine with more (the CLI's exit code 4).
    pub fn is_too_large(&self) -> bool {
        matches!(self, ImportError::ExceedsMemory(_))
    }
}

/// Reads `path` (`.gltf`, `.glb` or `.obj`, by extension, case-insensitive).
///
/// - glTF: the nodes of the default scene (else scene 0, else every root node) are baked,
///   each mesh once per node that uses it. ρ = `baseColorFactor` rgb, e = `emissiveFactor`
///   × `KHR_materials_emissive_strength`; glass: transmission t = 1 − (1 − T) α from
///   `KHR_materials_transmission`'s factor T and, under `alphaMode` `BLEND`, the base
///   colour's alpha α, with ρ lowered to (1 − t) ρ (docs/input-handling.md, "Glass"; the
///   transmission texture and a BLEND texture's alpha are warned about and not read); the
///   `baseColorTexture` and `emissiveTexture` of
///   materials in use are decoded ([`texture`]; averaged per element by `bake-texture`);
///   `COLOR_0` (VEC3/VEC4, float or normalized integers, within [0, 1]) multiplies ρ, per
///   element its exact mean (`bake-texture`). The materials in use are also kept as authored
///   ([`Scene::authored`]) with the textures and images they use. A
///   primitive without a material uses the glTF default material (ρ = 1, e = 0,
///   single-sided), appended after the file's materials when some primitive needs it.
///   A node whose world matrix is singular (a scale of 0) is skipped with a warning: its
///   bake could not be written back in its local space.
///   `KHR_lights_punctual` lights on baked nodes become [`Light`]s; a light that cannot be
///   used (a singular node transform, a non-finite or negative intensity or colour, a
///   non-positive range, spot cones outside 0 ≤ inner < outer ≤ π/2) is skipped with a
///   warning naming it.
/// - OBJ: one mesh (and one identity node) per `tobj` model, all in one scene. ρ = `Kd`
///   (× the mean of `map_Kd`, PNG or JPEG beside the OBJ, over each element, as a glTF
///   `baseColorTexture` with the default sampler), e = `Ke`, single-sided. A face without a material (no `usemtl`, a missing MTL file or
///   an unknown name) uses a neutral grey default: ρ = 0.8, e = 0, appended after the MTL
///   materials when used.
///
/// Faces are cleaned per primitive instance, in world space (f64; "scene size" is the
/// diagonal of the bounding box of all vertices):
/// 1. a non-finite position is an [`ImportError::InvalidValue`] naming mesh, primitive,
///    face and node; so are non-finite colours, ρ outside [0, 1] and negative emission of
///    a material in use;
/// 2. consecutive repeated vertices (closer than 1e-9 × scene size) are removed; faces
///    left with < 3 vertices or area ≤ 1e-12 × scene size² are dropped
///    ([`ImportStats::degenerate_dropped`], one warning per instance);
/// 3. a face with the same vertices (exact positions) in the same cyclic order as an
///    earlier face of the same primitive instance is dropped
///    ([`ImportStats::duplicates_dropped`], one warning per instance); for a double-sided
///    material the reverse order is a duplicate too. Two coincident single-sided faces of
///    opposite orientation are a thin two-sided sheet and both kept. Winding is taken as
///    authored (it defines the front side); faces that traverse a shared edge in the same
///    direction as their neighbour are counted against the majority of their connected
///    surface ([`ImportStats::against_winding`], one warning per instance; not checked for
///    double-sided materials, whose sides are both surfaces);
/// 4. consecutive source triangles t, t+1 sharing an edge (opposite directions), facing
///    the same way, coplanar (every vertex within 1e-6 × the quad's size of its mean
///    plane) and forming a strictly convex quad are merged ([`ImportStats::quads_merged`]);
/// 5. OBJ polygons with > 4 vertices are ear-clipped (a fan from vertex 0 when convex) and
///    their triangles merged pairwise into quads where planar and convex
///    ([`ImportStats::ngons_split`]); a concave quad is cut along the diagonal from its
///    reflex corner; a non-planar quad (same 1e-6 rule) is cut into two triangles with a
///    warning;
/// 6. a node whose world matrix mirrors (negative determinant) has its faces' vertex
///    order reversed, so every polygon is counter-clockwise about its Newell normal,
///    which points to the front;
/// 7. a double-sided material adds, right after each front polygon, a [`Side::Back`]
///    polygon with reversed vertices and negated normal;
/// 8. across the whole scene, a polygon with the same corners (within 1e-9 × scene size) in
///    the same cyclic order as an earlier polygon of another primitive or node (coincident
///    and facing the same way: both would be seen in full, counting their light twice) is
///    dropped, the first kept ([`ImportStats::coincident_dropped`], one warning).
///
/// No polygon left is [`ImportError::Empty`].
///
/// Files are read as [`load_with`] reads them with the default [`Options`]: only regular
/// files of at most [`MAX_FILE_BYTES`], only inside the scene file's folder.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    load_with(path, &Options::default())
}

/// [`load`] with `options`. Every file (the scene, its buffers, images and material
/// libraries) must be a regular file (checked before it is opened: a FIFO, device or
/// directory is refused without blocking) of at most [`MAX_FILE_BYTES`]; references are
/// resolved in the scene file's folder and must stay inside it unless
/// [`Options::allow_outside_paths`]. An OBJ's faces are counted before it is parsed.
pub fn load_with(path: &Path, options: &Options) -> Result<Scene, ImportError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let files = files::Files::new(path, options.allow_outside_paths);
    let mut scene = match extension.as_deref() {
        Some("gltf" | "glb") => gltf_in::load(path, &files),
        Some("obj") => obj_in::load(path, &files),
        _ => Err(ImportError::UnsupportedExtension),
    }?;
    coincident::drop_coincident(&mut scene);
    scene.input_files = files.into_read();
    Ok(scene)
}

/// A scene format, for [`load_bytes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// glTF 2.0: JSON (`.gltf`) or a GLB container (`.glb`), told apart by the GLB magic.
    Gltf,
    /// Wavefront OBJ, without a material library (see [`load_obj_bytes`]).
    Obj,
}

/// Reads a scene from memory, as [`load`] reads a file, except that nothing outside
/// `bytes` is read: a glTF buffer must be embedded (a `data:` URI or the GLB's BIN chunk;
/// an external one is an [`ImportError::Gltf`]), and an OBJ's `mtllib` is missing (its
/// faces use the default grey, with a warning).
pub fn load_bytes(bytes: &[u8], format: Format) -> Result<Scene, ImportError> {
    let mut scene = match format {
        Format::Gltf => gltf_in::load_bytes(bytes, None),
        Format::Obj => obj_in::load_bytes(bytes, None),
    }?;
    coincident::drop_coincident(&mut scene);
    Ok(scene)
}

/// Reads OBJ text from memory with one material library: every `mtllib` line reads `mtl`.
pub fn load_obj_bytes(obj: &[u8], mtl: Option<&[u8]>) -> Result<Scene, ImportError> {
    let mut scene = obj_in::load_bytes(obj, mtl)?;
    coincident::drop_coincident(&mut scene);
    Ok(scene)
}

/// The fuzz targets' harnesses (`fuzz/`), here so that the regression test replays a
/// saved input exactly as the fuzzer ran it. Not part of the API.
#[doc(hidden)]
pub mod fuzzing {
    use crate::{load_bytes, load_obj_bytes, Format};

    /// glTF bytes as given (JSON, or GLB by its magic), then, unless they already are a
    /// GLB, split at the first NUL into the JSON and BIN chunks of a well-formed GLB so
    /// that mutations reach binary files' JSON without breaking the container first.
    pub fn gltf(data: &[u8]) {
        let _ = load_bytes(data, Format::Gltf);
        if !data.starts_with(b"glTF") {
            let (json, bin) = split_at_nul(data);
            let _ = load_bytes(&glb(json, bin), Format::Gltf);
        }
    }

    /// OBJ text before the first NUL, and the MTL every `mtllib` reads after it (none
    /// without a NUL).
    pub fn obj(data: &[u8]) {
        let (obj, mtl) = split_at_nul(data);
        let _ = load_obj_bytes(obj, mtl);
    }

    /// A PNG or JPEG texture's bytes, decoded as an embedded image is (the `image` crate's
    /// decoders behind the importer's size check).
    pub fn image(data: &[u8]) {
        let _ = crate::texture::decode_image(data, 0);
    }

    /// A `KHR_draco_mesh_compression` bitstream: the input is the BIN chunk of a GLB whose
    /// one triangle primitive points the extension at all of it, so every input reaches the
    /// Draco decoder.
    pub fn draco(data: &[u8]) {
        let _ = load_bytes(&draco_glb(data), Format::Gltf);
    }

    /// The GLB [`draco`] loads: one triangle (three points, three indices) whose primitive
    /// takes POSITION from Draco attribute 0 of `data`.
    pub fn draco_glb(data: &[u8]) -> Vec<u8> {
        let n = data.len();
        let json = format!(
            r#"{{"asset":{{"version":"2.0"}},
"extensionsUsed":["KHR_draco_mesh_compression"],
"extensionsRequired":["KHR_draco_mesh_compression"],
"buffers":[{{"byteLength":{n}}}],
"bufferViews":[{{"buffer":0,"byteLength":{n}}}],
"accessors":[
 {{"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}},
 {{"componentType":5125,"count":3,"type":"SCALAR"}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,
 "extensions":{{"KHR_draco_mesh_compression":{{"bufferView":0,"attributes":{{"POSITION":0}}}}}}}}]}}],
"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
        );
        glb(json.as_bytes(), Some(data))
    }

    /// An `EXT_meshopt_compression` buffer view: the first byte picks the mode (attributes,
    /// triangles, indices) and the stride, the next two the element count (1 … 65 536), the
    /// rest is the compressed stream, in the BIN chunk of a GLB whose one view points the
    /// extension at it (with a fallback buffer of the decoded size).
    pub fn meshopt(data: &[u8]) {
        let _ = load_bytes(&meshopt_glb(data), Format::Gltf);
    }

    /// The GLB [`meshopt`] loads (see there).
    pub fn meshopt_glb(data: &[u8]) -> Vec<u8> {
        let (head, stream) = data.split_at(data.len().min(3));
        let pick = head.first().copied().unwrap_or(0);
        let count = match head {
            [_, a, b] => usize::from(u16::from_le_bytes([*a, *b])) + 1,
            _ => 1,
        };
        let (mode, strides): (&str, &[usize]) = match pick % 3 {
            0 => ("ATTRIBUTES", &[4, 8, 12, 16, 20, 24, 32, 64]),
            1 => ("TRIANGLES", &[2, 4]),
            _ => ("INDICES", &[2, 4]),
        };
        let stride = strides[usize::from(pick / 3) % strides.len()];
        let count = if mode == "TRIANGLES" {
            count.div_ceil(3) * 3
        } else {
            count
        };
        let (n, decoded) = (stream.len(), stride * count);
        // glTF: only vertex attribute views have a byteStride (the extension has its own).
        let view_stride = if mode == "ATTRIBUTES" {
            format!(r#""byteStride":{stride},"#)
        } else {
            String::new()
        };
        let json = format!(
            r#"{{"asset":{{"version":"2.0"}},
"extensionsUsed":["EXT_meshopt_compression"],
"buffers":[{{"byteLength":{n}}},
 {{"byteLength":{decoded},"extensions":{{"EXT_meshopt_compression":{{"fallback":true}}}}}}],
"bufferViews":[{{"buffer":1,"byteLength":{decoded},{view_stride}
 "extensions":{{"EXT_meshopt_compression":{{"buffer":0,"byteLength":{n},
 "byteStride":{stride},"count":{count},"mode":"{mode}"}}}}}}]}}"#
        );
        glb(json.as_bytes(), Some(stream))
    }

    fn split_at_nul(data: &[u8]) -> (&[u8], Option<&[u8]>) {
        match data.iter().position(|&b| b == 0) {
            Some(at) => (&data[..at], Some(&data[at + 1..])),
            None => (data, None),
        }
    }

    /// A GLB container (glTF 2.0, "GLB File Format") holding `json` and maybe `bin`.
    fn glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
        let pad = |bytes: &[u8], with: u8| {
            let mut padded = bytes.to_vec();
            padded.resize(bytes.len().next_multiple_of(4), with);
            padded
        };
        let json = pad(json, b' ');
        let bin = bin.map(|b| pad(b, 0));
        let total = 12 + 8 + json.len() + bin.as_ref().map_or(0, |b| 8 + b.len());
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        if let Some(bin) = bin {
            out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&bin);
        }
        out
    }
}

/// `kind "name" (index)`, or `kind index` when unnamed: how messages name things.
pub(crate) fn describe(kind: &str, name: Option<&str>, index: usize) -> String {
    match name {
        Some(name) => format!("{kind} {name:?} ({index})"),
        None => format!("{kind} {index}"),
    }
}

/// A material's values must be finite, with ρ in [0, 1] and e ≥ 0; `what` names the
/// material and the mesh using it.
/// The diffuse reflectance of a surface that transmits t of the light: `(1 − t) ρ` (glTF's
/// PBR model blends the diffuse lobe by 1 − transmission). An authored ρ outside [0, 1] is
/// kept as it is for [`check_material`] to refuse.
pub(crate) fn reflected(rho: [f64; 3], transmission: f64) -> [f64; 3] {
    if transmission > 0.0 && transmission <= 1.0 && rho.iter().all(|r| (0.0..=1.0).contains(r)) {
        rho.map(|r| r * (1.0 - transmission))
    } else {
        rho
    }
}

pub(crate) fn check_material(material: &Material, what: &str) -> Result<(), ImportError> {
    let invalid = |problem: String| ImportError::InvalidValue {
        what: what.to_owned(),
        problem,
    };
    if !material
        .rho
        .iter()
        .chain(&material.emission)
        .all(|v| v.is_finite())
    {
        return Err(invalid(format!(
            "colour is not finite (ρ {:?}, e {:?})",
            material.rho, material.emission
        )));
    }
    // Radiosity b ≥ e is written as f32: an emission past f32's range is bad input here,
    // not a failed output after the whole bake.
    if let Some(e) = material.emission.iter().find(|e| **e > f64::from(f32::MAX)) {
        return Err(invalid(format!(
            "emission {e:e} exceeds the largest value glTF can hold (f32, {:e})",
            f32::MAX
        )));
    }
    if material.rho.iter().any(|r| !(0.0..=1.0).contains(r)) {
        return Err(invalid(format!(
            "reflectance ρ {:?} is outside [0, 1]",
            material.rho
        )));
    }
    if !(0.0..=1.0).contains(&material.transmission) {
        return Err(invalid(format!(
            "transmission {} is outside [0, 1]",
            material.transmission
        )));
    }
    if material.emission.iter().any(|e| *e < 0.0) {
        return Err(invalid(format!(
            "emission {:?} is negative",
            material.emission
        )));
    }
    Ok(())
}
