//! Textures of the materials in use (glTF `baseColorTexture`, `emissiveTexture`): decoded with
//! the `image` crate (PNG, JPEG) from a buffer view, a `data:` URI or a file beside the input,
//! sRGB-decoded to linear, with their sampler's wrap modes and magnification filter and the
//! `KHR_texture_transform` of the material's reference.
//!
//! Read straight from the JSON with bounds-checked lookups: the importer's validation does not
//! check texture, image and sampler objects (it never needed them), so nothing here may trust
//! an index.

use crate::files::Files;
use crate::{ImportError, Material};
use gltf::json::validation::Checked;
use gltf::json::Root;
pub use scene::{
    authored_sets, Authored, AuthoredTexture, EncodedImage, Image, Texture, TextureRef, Wrap,
};
use std::collections::HashMap;

/// The texture references of glTF material `m` (JSON), before decoding: (base colour,
/// emissive) as (texture index in the file, TEXCOORD set, transform).
/// A material's reference to a texture of the file: its index, TEXCOORD set and transform.
type Reference = (usize, u32, [[f64; 3]; 2]);

pub(crate) fn references(root: &Root, m: usize) -> [Option<Reference>; 2] {
    let Some(material) = root.materials.get(m) else {
        return [None, None];
    };
    let info = |i: &gltf::json::texture::Info| {
        let transform = i
            .extensions
            .as_ref()
            .and_then(|e| e.texture_transform.as_ref());
        let (matrix, set) = match transform {
            Some(t) => {
                // KHR_texture_transform: T · R · S with R = [[cos, sin], [−sin, cos]].
                let [ox, oy] = t.offset.0.map(f64::from);
                let r = f64::from(t.rotation.0);
                let [sx, sy] = t.scale.0.map(f64::from);
                let (s, c) = r.sin_cos();
                (
                    [[c * sx, s * sy, ox], [-s * sx, c * sy, oy]],
                    t.tex_coord.unwrap_or(i.tex_coord),
                )
            }
            None => ([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], i.tex_coord),
        };
        (i.index.value(), set, matrix)
    };
    [
        material
            .pbr_metallic_roughness
            .base_color_texture
            .as_ref()
            .map(info),
        material.emissive_texture.as_ref().map(info),
    ]
}

/// What [`load`] found: decoded textures for ρ and e, the authored materials, and warnings
/// for kept slots that had to be dropped.
pub(crate) struct Loaded {
    pub(crate) textures: Vec<Texture>,
    pub(crate) images: Vec<Image>,
    pub(crate) authored: Authored,
    pub(crate) warnings: Vec<String>,
}

/// Decodes every texture the materials in use reference for ρ and e and fills in their
/// [`Material::base_color_texture`] / [`Material::emissive_texture`]; gathers the authored
/// materials with every texture they keep. `used[m]`: material m is used by a baked
/// primitive. A base-colour or emissive texture that cannot be read is an error naming it; a
/// metallic-roughness or normal texture that cannot be read is dropped from the outputs with
/// a warning (it does not change the bake).
pub(crate) fn load(
    root: &Root,
    buffers: &[gltf::buffer::Data],
    files: Option<&Files>,
    materials: &mut [Material],
    used: &[bool],
) -> Result<Loaded, ImportError> {
    let mut loader = Loader {
        root,
        buffers,
        files,
        textures: Vec::new(),
        images: Vec::new(),
        texture_of: HashMap::new(),
        image_of: HashMap::new(),
        authored: Authored {
            materials: vec![None; materials.len()],
            ..Default::default()
        },
        authored_texture_of: HashMap::new(),
        authored_image_of: HashMap::new(),
        warnings: Vec::new(),
    };
    loader.check_decoded_total(used)?;
    for (m, material) in materials.iter_mut().enumerate() {
        if !used.get(m).copied().unwrap_or(false) {
            continue;
        }
        let [base_color, emissive] = references(root, m);
        for (slot, reference) in [
            (&mut material.base_color_texture, base_color),
            (&mut material.emissive_texture, emissive),
        ] {
            let Some((t, tex_coord, transform)) = reference else {
                continue;
            };
            // A KTX2/WebP texture without a PNG/JPEG fallback: named with its material.
            if let Some(problem) = root
                .textures
                .get(t)
                .and_then(|json| crate::compressed::undecodable(root, json))
            {
                let material = crate::describe("material", material.name.as_deref(), m);
                return Err(ImportError::InvalidValue {
                    what: format!("{} used by {material}", loader.texture_name(t)),
                    problem,
                });
            }
            let texture = loader.decoded_texture(t)?;
            *slot = Some(TextureRef {
                texture,
                tex_coord,
                transform,
            });
        }
        if let Some(json) = root.materials.get(m) {
            loader.authored.materials[m] = Some(loader.authored_material(m, json)?);
        }
    }
    Ok(Loaded {
        textures: loader.textures,
        images: loader.images,
        authored: loader.authored,
        warnings: loader.warnings,
    })
}

struct Loader<'a> {
    root: &'a Root,
    buffers: &'a [gltf::buffer::Data],
    files: Option<&'a Files>,
    textures: Vec<Texture>,
    images: Vec<Image>,
    /// File texture → decoded texture; file image → decoded image.
    texture_of: HashMap<usize, usize>,
    image_of: HashMap<usize, usize>,
    authored: Authored,
    /// File texture → authored texture (or why it cannot be kept); file image likewise.
    authored_texture_of: HashMap<usize, Result<usize, String>>,
    authored_image_of: HashMap<usize, Result<usize, String>>,
    warnings: Vec<String>,
}

impl Loader<'_> {
    fn texture_name(&self, t: usize) -> String {
        let name = self.root.textures.get(t).and_then(|x| x.name.as_deref());
        crate::describe("texture", name, t)
    }

    /// Every image the materials in use read is decoded and kept: their decoded size (from
    /// each file's header) is totalled against the memory available before any is decoded
    /// (each is within `MAX_TEXELS`, but a few small PNGs can name gigabytes). An image
    /// that cannot be read or sized here is left to [`Loader::decoded_texture`] to name.
    fn check_decoded_total(&mut self, used: &[bool]) -> Result<(), ImportError> {
        let mut sources = Vec::new();
        let in_use = (0..self.root.materials.len()).filter(|&m| used.get(m) == Some(&true));
        for m in in_use {
            for (t, _, _) in references(self.root, m).into_iter().flatten() {
                let source = self
                    .root
                    .textures
                    .get(t)
                    .and_then(|json| crate::compressed::texture_source(self.root, json).ok());
                if let Some(source) = source.filter(|s| !sources.contains(s)) {
                    sources.push(source);
                }
            }
        }
        let mut total: u64 = 0;
        for &source in &sources {
            let Ok(encoded) = self.authored_image(source) else {
                continue;
            };
            if let Some((w, h)) = dimensions(&self.authored.images[encoded].bytes) {
                total = total.saturating_add(crate::memory::decoded_image_bytes(w, h));
            }
        }
        crate::memory::check(
            &format!("the {} images the materials use, decoded,", sources.len()),
            total,
            crate::memory::available(),
        )
    }

    /// Texture `t` of the file, decoded (sRGB → linear) with its sampler's filter and wraps.
    fn decoded_texture(&mut self, t: usize) -> Result<usize, ImportError> {
        if let Some(&k) = self.texture_of.get(&t) {
            return Ok(k);
        }
        let json = self
            .root
            .textures
            .get(t)
            .ok_or_else(|| ImportError::Gltf(format!("texture {t} does not exist")))?;
        let name = self.texture_name(t);
        let fail = |problem: String| ImportError::InvalidValue {
            what: name.clone(),
            problem,
        };
        let (wrap, nearest) = match json.sampler.map(|s| s.value()) {
            None => ([Wrap::Repeat; 2], false),
            Some(s) => {
                let sampler = self
                    .root
                    .samplers
                    .get(s)
                    .ok_or_else(|| fail(format!("sampler {s} does not exist")))?;
                let wrap = |w: &Checked<gltf::json::texture::WrappingMode>| {
                    use gltf::json::texture::WrappingMode as W;
                    match w {
                        Checked::Valid(W::ClampToEdge) => Wrap::ClampToEdge,
                        Checked::Valid(W::MirroredRepeat) => Wrap::MirroredRepeat,
                        _ => Wrap::Repeat,
                    }
                };
                let nearest = matches!(
                    sampler.mag_filter,
                    Some(Checked::Valid(gltf::json::texture::MagFilter::Nearest))
                );
                ([wrap(&sampler.wrap_s), wrap(&sampler.wrap_t)], nearest)
            }
        };
        let source = crate::compressed::texture_source(self.root, json).map_err(&fail)?;
        let image = match self.image_of.get(&source) {
            Some(&k) => k,
            None => {
                let encoded = self.authored_image(source).map_err(&fail)?;
                let bytes = &self.authored.images[encoded].bytes;
                let decoded = decode_image(bytes, source).map_err(&fail)?;
                self.images.push(decoded);
                self.image_of.insert(source, self.images.len() - 1);
                self.images.len() - 1
            }
        };
        self.textures.push(Texture {
            name,
            image,
            wrap,
            nearest,
        });
        self.texture_of.insert(t, self.textures.len() - 1);
        Ok(self.textures.len() - 1)
    }

    /// File image `source` as an [`EncodedImage`] of [`Authored::images`] (read once).
    fn authored_image(&mut self, source: usize) -> Result<usize, String> {
        if let Some(known) = self.authored_image_of.get(&source) {
            return known.clone();
        }
        let made = image_bytes(self.root, self.buffers, self.files, source).and_then(|bytes| {
            let mime_type = mime_type(&bytes, &format!("image {source}"))?;
            let name = self.root.images.get(source).and_then(|i| i.name.clone());
            self.authored.images.push(EncodedImage {
                name,
                mime_type,
                bytes,
            });
            Ok(self.authored.images.len() - 1)
        });
        self.authored_image_of.insert(source, made.clone());
        made
    }

    /// File texture `t` as an [`AuthoredTexture`] (its sampler copied, its image read).
    fn authored_texture(&mut self, t: usize) -> Result<usize, String> {
        if let Some(known) = self.authored_texture_of.get(&t) {
            return known.clone();
        }
        let made = match self.root.textures.get(t) {
            None => Err(format!("texture {t} does not exist")),
            Some(json) => {
                let sampler = match json.sampler.map(|s| s.value()) {
                    None => Ok(None),
                    Some(s) => self
                        .root
                        .samplers
                        .get(s)
                        .ok_or_else(|| format!("sampler {s} does not exist"))
                        .and_then(|x| serde_json::to_value(x).map_err(|e| e.to_string()))
                        .map(Some),
                };
                let name = json.name.clone();
                let source = crate::compressed::texture_source(self.root, json);
                sampler.and_then(|sampler| {
                    let source = source?;
                    let image = self.authored_image(source)?;
                    self.authored.textures.push(AuthoredTexture {
                        name,
                        sampler,
                        image,
                    });
                    Ok(self.authored.textures.len() - 1)
                })
            }
        };
        self.authored_texture_of.insert(t, made.clone());
        made
    }

    /// Material `m` as written, its kept texture slots pointing into [`Authored::textures`].
    fn authored_material(
        &mut self,
        m: usize,
        json: &gltf::json::Material,
    ) -> Result<serde_json::Value, ImportError> {
        let mut material = json.clone();
        material.occlusion_texture = None;
        material.extensions = json.extensions.as_ref().and_then(|e| {
            e.emissive_strength
                .as_ref()
                .map(|s| gltf::json::extensions::material::Material {
                    emissive_strength: Some(s.clone()),
                    ..Default::default()
                })
        });
        let name = crate::describe("material", json.name.as_deref(), m);
        let mut keep = |slot: &str, index: &mut gltf::json::Index<gltf::json::Texture>| {
            let t = index.value();
            match self.authored_texture(t) {
                Ok(k) => {
                    *index = gltf::json::Index::new(k as u32);
                    true
                }
                Err(why) => {
                    let texture = self.texture_name(t);
                    self.warnings.push(format!(
                        "{name}: its {slot} {texture} is left out of the outputs ({why})"
                    ));
                    false
                }
            }
        };
        let pbr = &mut material.pbr_metallic_roughness;
        if let Some(info) = pbr.base_color_texture.as_mut() {
            if !keep("baseColorTexture", &mut info.index) {
                pbr.base_color_texture = None;
            }
        }
        if let Some(info) = pbr.metallic_roughness_texture.as_mut() {
            if !keep("metallicRoughnessTexture", &mut info.index) {
                pbr.metallic_roughness_texture = None;
            }
        }
        if let Some(info) = material.normal_texture.as_mut() {
            if !keep("normalTexture", &mut info.index) {
                material.normal_texture = None;
            }
        }
        if let Some(info) = material.emissive_texture.as_mut() {
            if !keep("emissiveTexture", &mut info.index) {
                material.emissive_texture = None;
            }
        }
        serde_json::to_value(&material).map_err(|e| ImportError::Gltf(format!("{name}: {e}")))
    }
}

/// `image/png` or `image/jpeg` for the bytes of `what`, or why they are neither.
pub(crate) fn mime_type(bytes: &[u8], what: &str) -> Result<&'static str, String> {
    match image::guess_format(bytes) {
        Ok(image::ImageFormat::Png) => Ok("image/png"),
        Ok(image::ImageFormat::Jpeg) => Ok("image/jpeg"),
        Ok(format) => Err(format!(
            "{what} is {format:?}: only PNG and JPEG textures are supported"
        )),
        Err(_) => Err(format!(
            "{what}: not a PNG or JPEG file (KTX2, WebP and others are not supported)"
        )),
    }
}

/// The largest image accepted (texels): a memory guard against a hostile header.
const MAX_TEXELS: u64 = 1 << 28;

fn image_bytes(
    root: &Root,
    buffers: &[gltf::buffer::Data],
    files: Option<&Files>,
    source: usize,
) -> Result<Vec<u8>, String> {
    let json = root
        .images
        .get(source)
        .ok_or_else(|| format!("image {source} does not exist"))?;
    let owned;
    let bytes: &[u8] = match (&json.buffer_view, &json.uri) {
        (Some(view), _) => {
            let view = root
                .buffer_views
                .get(view.value())
                .ok_or_else(|| format!("image {source}: its buffer view does not exist"))?;
            let buffer = buffers
                .get(view.buffer.value())
                .ok_or_else(|| format!("image {source}: its buffer does not exist"))?;
            let start = view.byte_offset.map_or(0, |o| o.0 as usize);
            let end = start
                .checked_add(view.byte_length.0 as usize)
                .ok_or_else(|| format!("image {source}: buffer view out of range"))?;
            buffer
                .get(start..end)
                .ok_or_else(|| format!("image {source}: buffer view out of range"))?
        }
        (None, Some(uri)) => {
            if let Some(data) = uri.strip_prefix("data:") {
                let (_, payload) = data
                    .split_once(";base64,")
                    .ok_or_else(|| format!("image {source}: a data URI that is not base64"))?;
                owned = base64_decode(payload)
                    .ok_or_else(|| format!("image {source}: invalid base64 in its data URI"))?;
                &owned
            } else {
                let files = files.ok_or_else(|| {
                    format!(
                        "image {source}: external file {uri:?} but the scene was read from memory"
                    )
                })?;
                let path = if uri.starts_with("file:") {
                    files.file_uri(uri)
                } else {
                    files.resolve(&crate::gltf_in::percent_decoded_path(uri))
                }
                .map_err(|e| format!("image {source}: {e}"))?;
                owned = files
                    .read(&path)
                    .map_err(|e| format!("cannot read image file {}: {e}", path.display()))?;
                &owned
            }
        }
        (None, None) => {
            return Err(format!(
                "image {source} has neither a buffer view nor a URI"
            ))
        }
    };
    Ok(bytes.to_vec())
}

/// A PNG's or JPEG's width and height, from its header.
fn dimensions(bytes: &[u8]) -> Option<(u32, u32)> {
    let format = image::guess_format(bytes).ok()?;
    image::ImageReader::with_format(std::io::Cursor::new(bytes), format)
        .into_dimensions()
        .ok()
}

/// Decodes PNG or JPEG `bytes` (checked by [`Loader::authored_image`]) of file image
/// `source` to linear texels.
pub(crate) fn decode_image(bytes: &[u8], source: usize) -> Result<Image, String> {
    let format = image::guess_format(bytes)
        .map_err(|_| format!("image {source}: not a PNG or JPEG file"))?;
    let reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| format!("image {source}: {e}"))?;
    if u64::from(w) * u64::from(h) > MAX_TEXELS {
        return Err(format!(
            "image {source} is {w}×{h}: larger than {MAX_TEXELS} texels"
        ));
    }
    let decoded = image::load_from_memory_with_format(bytes, format)
        .map_err(|e| format!("image {source} cannot be decoded: {e}"))?;
    let has_alpha = decoded.color().has_alpha();
    let decoded = decoded.to_rgba8();
    // glTF: base-colour and emissive textures are sRGB-encoded.
    let table: Vec<f32> = (0..256)
        .map(|v| srgb_to_linear(f64::from(v as u8) / 255.0) as f32)
        .collect();
    let texels = decoded
        .pixels()
        .map(|p| {
            [
                table[p[0] as usize],
                table[p[1] as usize],
                table[p[2] as usize],
            ]
        })
        .collect();
    // glTF: alpha is linear.
    let alpha = if has_alpha {
        decoded.pixels().map(|p| f32::from(p[3]) / 255.0).collect()
    } else {
        Vec::new()
    };
    Ok(Image {
        width: decoded.width(),
        height: decoded.height(),
        texels,
        alpha,
    })
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Standard base64 (RFC 4648, padding optional); `None` on any other character.
fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let bytes: Vec<u8> = text.bytes().filter(|c| !c.is_ascii_whitespace()).collect();
    let trimmed = bytes
        .strip_suffix(b"==")
        .or_else(|| bytes.strip_suffix(b"="))
        .unwrap_or(&bytes);
    let mut out = Vec::with_capacity(trimmed.len() * 3 / 4);
    for chunk in trimmed.chunks(4) {
        let mut n = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            n |= value(c)? << (18 - 6 * k);
        }
        let produced = match chunk.len() {
            4 => 3,
            3 => 2,
            2 => 1,
            _ => return None,
        };
        for k in 0..produced {
            out.push((n >> (16 - 8 * k)) as u8);
        }
    }
    Some(out)
}
