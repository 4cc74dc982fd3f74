//! Compressed and quantised glTF input: which extensions the importer decodes or accepts,
//! and the pass that turns a compressed document into a plain one before any accessor is
//! read.
//!
//! - `KHR_mesh_quantization`: nothing to decode; integer positions and texture coordinates
//!   are read by [`crate::accessor`] (normalized ones dequantized, others as their integer
//!   values, the scale being in the node transform).
//! - `EXT_meshopt_compression`: buffer views decoded by [`crate::meshopt`].
//! - `KHR_draco_mesh_compression`: primitives decoded by [`crate::draco`].
//! - `KHR_texture_basisu`, `EXT_texture_webp`: accepted as required when each texture that
//!   the bake needs has a PNG or JPEG fallback `source` (see [`texture_source`]); textures
//!   are never decoded from KTX2 or WebP.
//!
//! What this is not: a writer. The outputs are built afresh from the decoded geometry, so
//! they carry none of these extensions.

use gltf::buffer::Data;
use gltf::json::Root;

/// The required extensions this module makes readable (glTF 2.0, "Specifying
/// Extensions": a reader must refuse a file requiring any other extension it lacks).
pub(crate) const HANDLED: [&str; 5] = [
    "KHR_mesh_quantization",
    crate::meshopt::NAME,
    crate::draco::NAME,
    BASISU,
    WEBP,
];

const BASISU: &str = "KHR_texture_basisu";
const WEBP: &str = "EXT_texture_webp";

/// True when a validation error is the `gltf` crate refusing one of [`HANDLED`] in
/// `extensionsRequired` (its path reads `extensionsRequired[i] = "NAME"`).
pub(crate) fn handled_requirement(path: &str, error: gltf::json::validation::Error) -> bool {
    error == gltf::json::validation::Error::Unsupported
        && path.starts_with("extensionsRequired")
        && HANDLED
            .iter()
            .any(|name| path.ends_with(&format!("= \"{name}\"")))
}

/// Decodes the compressed buffer views, then the Draco primitives (a Draco bitstream may
/// itself sit in a meshopt-compressed view only in theory; the order makes that work).
pub(crate) fn decode(root: &mut Root, buffers: &mut Vec<Data>) -> Result<(), String> {
    crate::meshopt::decode_views(root, buffers)?;
    crate::draco::decode_primitives(root, buffers)
}

/// The image a texture samples: its `source` when that image exists (for a texture with
/// `KHR_texture_basisu` or `EXT_texture_webp`, that is the PNG/JPEG fallback); otherwise an
/// error naming the extension whose image the importer cannot decode.
pub(crate) fn texture_source(root: &Root, texture: &gltf::json::Texture) -> Result<usize, String> {
    match undecodable(root, texture) {
        Some(problem) => Err(problem),
        None => Ok(texture.source.value()),
    }
}

/// Why a texture cannot be sampled, when that is because its only image is KTX2 or WebP
/// (no `source`, or one that does not exist); `None` otherwise (a missing image without
/// either extension is reported where the image is read).
pub(crate) fn undecodable(root: &Root, texture: &gltf::json::Texture) -> Option<String> {
    if texture.source.value() < root.images.len() {
        return None;
    }
    let extensions = texture.extensions.as_ref().map(|e| &e.others);
    [(BASISU, "KTX2/Basis Universal"), (WEBP, "WebP")]
        .into_iter()
        .find(|(name, _)| extensions.is_some_and(|e| e.contains_key(*name)))
        .map(|(name, what)| {
            format!(
                "its image is {what} ({name}), which bake cannot decode, and it has no PNG or \
                 JPEG fallback `source`"
            )
        })
}
