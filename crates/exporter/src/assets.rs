//! The input's own materials, textures and images, copied into an output document so it
//! keeps the asset: images are embedded (a buffer view of the output's one buffer, so the
//! output is self-contained and needs no files beside it), samplers copied as written, and
//! texture indices rewritten to the output's.

use crate::document::{pad_to_four, DocumentWriter};
use crate::ExportError;
use gltf::json;
use gltf::json::validation::USize64;
use gltf::json::Index;
use scene::Authored;
use std::collections::HashMap;

pub(crate) const TEXTURE_TRANSFORM_EXTENSION: &str = "KHR_texture_transform";

/// Copies authored textures into one output document, each once.
pub(crate) struct Assets<'a> {
    authored: &'a Authored,
    textures: HashMap<usize, Index<json::Texture>>,
    images: HashMap<usize, Index<json::Image>>,
    /// Some copied texture reference carries `KHR_texture_transform`.
    pub(crate) uses_transform: bool,
}

impl<'a> Assets<'a> {
    pub(crate) fn new(authored: &'a Authored) -> Self {
        Assets {
            authored,
            textures: HashMap::new(),
            images: HashMap::new(),
            uses_transform: false,
        }
    }

    /// Authored material `m` with its texture indices pointing at the output's copies, or
    /// `None` when the input has no authored material for it. With `base_colour_only` the
    /// other texture slots are left out (and their textures not copied).
    pub(crate) fn material(
        &mut self,
        writer: &mut DocumentWriter,
        m: usize,
        base_colour_only: bool,
    ) -> Result<Option<json::Material>, ExportError> {
        let Some(value) = self.authored.materials.get(m).and_then(Option::as_ref) else {
            return Ok(None);
        };
        let mut material: json::Material = serde_json::from_value(value.clone())
            .map_err(|e| ExportError::InvalidData(format!("authored material {m}: {e}")))?;
        if base_colour_only {
            material.pbr_metallic_roughness.metallic_roughness_texture = None;
            material.normal_texture = None;
            material.emissive_texture = None;
        }
        let pbr = &mut material.pbr_metallic_roughness;
        for info in [
            pbr.base_color_texture.as_mut(),
            pbr.metallic_roughness_texture.as_mut(),
            material.emissive_texture.as_mut(),
        ]
        .into_iter()
        .flatten()
        {
            info.index = self.texture(writer, info.index.value())?;
            self.uses_transform |= has_transform(info);
            // `gltf` writes an absent transform `texCoord` as null, which is invalid: spell
            // out the set the reference reads.
            set_info_set(info, info_set(info));
        }
        if let Some(info) = material.normal_texture.as_mut() {
            info.index = self.texture(writer, info.index.value())?;
        }
        Ok(Some(material))
    }

    /// The output's copy of authored texture `k` (its image embedded, its sampler copied).
    fn texture(
        &mut self,
        writer: &mut DocumentWriter,
        k: usize,
    ) -> Result<Index<json::Texture>, ExportError> {
        if let Some(&index) = self.textures.get(&k) {
            return Ok(index);
        }
        let texture =
            self.authored.textures.get(k).ok_or_else(|| {
                ExportError::InvalidData(format!("authored texture {k} is missing"))
            })?;
        let image = self.image(writer, texture.image)?;
        let sampler = match &texture.sampler {
            None => None,
            Some(value) => {
                let sampler: json::texture::Sampler = serde_json::from_value(value.clone())
                    .map_err(|e| ExportError::InvalidData(format!("authored sampler: {e}")))?;
                Some(writer.root.push(sampler))
            }
        };
        let index = writer.root.push(json::Texture {
            name: texture.name.clone(),
            sampler,
            source: image,
            extensions: None,
            extras: Default::default(),
        });
        self.textures.insert(k, index);
        Ok(index)
    }

    /// Authored image `k`, embedded as a buffer view.
    fn image(
        &mut self,
        writer: &mut DocumentWriter,
        k: usize,
    ) -> Result<Index<json::Image>, ExportError> {
        if let Some(&index) = self.images.get(&k) {
            return Ok(index);
        }
        let image =
            self.authored.images.get(k).ok_or_else(|| {
                ExportError::InvalidData(format!("authored image {k} is missing"))
            })?;
        let view = embed(writer, &image.bytes);
        let index = writer.root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType(image.mime_type.into())),
            name: image.name.clone(),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        self.images.insert(k, index);
        Ok(index)
    }
}

/// Appends `bytes` (an image file) as a buffer view without a target.
pub(crate) fn embed(writer: &mut DocumentWriter, bytes: &[u8]) -> Index<json::buffer::View> {
    pad_to_four(&mut writer.bin);
    let offset = writer.bin.len();
    writer.bin.extend_from_slice(bytes);
    writer.root.push(json::buffer::View {
        buffer: Index::new(0),
        byte_length: USize64::from(bytes.len()),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: None,
        extensions: None,
        extras: Default::default(),
    })
}

fn has_transform(info: &json::texture::Info) -> bool {
    info.extensions
        .as_ref()
        .is_some_and(|e| e.texture_transform.is_some())
}

/// The TEXCOORD set a texture reference reads (after `KHR_texture_transform`'s override).
pub(crate) fn info_set(info: &json::texture::Info) -> u32 {
    info.extensions
        .as_ref()
        .and_then(|e| e.texture_transform.as_ref())
        .and_then(|t| t.tex_coord)
        .unwrap_or(info.tex_coord)
}

/// Points a texture reference at TEXCOORD set `set` (a transform's override too).
pub(crate) fn set_info_set(info: &mut json::texture::Info, set: u32) {
    info.tex_coord = set;
    if let Some(t) = info
        .extensions
        .as_mut()
        .and_then(|e| e.texture_transform.as_mut())
    {
        t.tex_coord = Some(set);
    }
}

/// Every texture reference of `material` with the TEXCOORD set it reads, for rewriting sets.
pub(crate) fn remap_sets(material: &mut json::Material, map: impl Fn(u32) -> u32) {
    let pbr = &mut material.pbr_metallic_roughness;
    for info in [
        pbr.base_color_texture.as_mut(),
        pbr.metallic_roughness_texture.as_mut(),
        material.emissive_texture.as_mut(),
    ]
    .into_iter()
    .flatten()
    {
        let set = map(info_set(info));
        set_info_set(info, set);
    }
    if let Some(info) = material.normal_texture.as_mut() {
        info.tex_coord = map(info.tex_coord);
    }
}

/// Whether some texture reference of `material` reads TEXCOORD set `set`.
pub(crate) fn reads_set(material: &json::Material, set: u32) -> bool {
    let pbr = &material.pbr_metallic_roughness;
    [
        pbr.base_color_texture.as_ref(),
        pbr.metallic_roughness_texture.as_ref(),
        material.emissive_texture.as_ref(),
    ]
    .into_iter()
    .flatten()
    .any(|info| info_set(info) == set)
        || material
            .normal_texture
            .as_ref()
            .is_some_and(|n| n.tex_coord == set)
}
