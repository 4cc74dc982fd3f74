//! Writes the baked-texture bake (`--target baked-texture`): the lightmap bake's polygons and
//! layout, but every material is `KHR_materials_unlit` with a white base colour whose
//! `baseColorTexture` (on `TEXCOORD_1`) is an atlas of what the surface shows, `ρ × H + e`
//! per texel with the base-colour texture multiplied in at texel resolution, times the
//! exposure, clamped to [0, 1], 8-bit sRGB (with an alpha channel holding the cut-out of any
//! `MASK` material, [`surface_alpha`]). Any glTF viewer shows it as baked, with no
//! set-up (Blender, Godot and Unity import the unlit extension; `MOZ_lightmap` they drop).
//!
//! One atlas set for the scene (the lightmap's): a material per input material and atlas,
//! each naming its atlas's PNG.

use crate::files::{self, OutputFormat, OutputSet};
use crate::lightmap_gltf::{
    add_meshes, add_texture, numbered, png_image, sibling, stage_document, start_document, UvNeeds,
};
use crate::ExportError;
use glam::DVec3;
use gltf::json;
use lightmap::Lightmap;
use rayon::prelude::*;
use scene::{AlphaMask, Scene, TextureRef};
use std::path::{Path, PathBuf};

const UNLIT_EXTENSION: &str = "KHR_materials_unlit";
/// The key of the root `extras` object that describes the baked texture.
pub const BAKED_TEXTURE_EXTRAS_KEY: &str = "bake_baked_texture";

/// Where the files of a baked-texture bake go: OUT, its `.bin` (`.gltf` only) and per atlas
/// k `<stem>.baked.png` (k = 0) or `<stem>.baked-k.png` (`.gltf` only; a `.glb` embeds them).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BakedTexturePaths {
    pub gltf: PathBuf,
    /// The first atlas's PNG.
    pub png: PathBuf,
}

impl BakedTexturePaths {
    pub fn new(output: &Path) -> Result<BakedTexturePaths, ExportError> {
        OutputFormat::from_path(output)?;
        Ok(BakedTexturePaths {
            gltf: output.to_path_buf(),
            png: sibling(output, "baked.png")?,
        })
    }

    /// Every file of a one-atlas bake: the PNG, `.bin` and `.gltf`, or the `.glb`.
    pub fn files(&self) -> Result<Vec<PathBuf>, ExportError> {
        Ok(match OutputFormat::from_path(&self.gltf)? {
            OutputFormat::Gltf => vec![
                self.png.clone(),
                files::bin_path_for(&self.gltf)?,
                self.gltf.clone(),
            ],
            OutputFormat::Glb => vec![self.gltf.clone()],
        })
    }

    /// The PNG of atlas `k` (written beside a `.gltf` only).
    pub fn atlas_png(&self, k: usize) -> Result<PathBuf, ExportError> {
        numbered(&self.png, k)
    }
}

/// Everything [`stage_baked_texture_gltf`] needs.
#[derive(Clone, Copy, Debug)]
pub struct BakedTextureBake<'a> {
    pub scene: &'a Scene,
    /// The lightmap of H: its layout and texels.
    pub lightmap: &'a Lightmap,
    /// Texel = clamp((ρ H + e) × exposure, 0, 1), as the vertex bake's `COLOR_0`.
    pub exposure: f64,
    /// The bake's reflectance ceiling `(at, to)`: a band of ρ at or above `at` is lowered to
    /// `to`, per texel as the bake did per element (`--max-reflectance`); `None`: kept.
    pub ceiling: Option<(f64, f64)>,
    /// Light probes, written as the `BAKE_irradiance_probes` extension on every scene.
    pub probes: Option<&'a crate::ProbeGrid<'a>>,
}

/// Stages the baked-texture bake in `set`: per atlas its PNG (`.gltf`), then the `.bin` and
/// the glTF, or the `.glb`. Returns the files in that order.
pub fn stage_baked_texture_gltf(
    set: &mut OutputSet,
    paths: &BakedTexturePaths,
    bake: &BakedTextureBake,
) -> Result<Vec<PathBuf>, ExportError> {
    let format = OutputFormat::from_path(&paths.gltf)?;
    let (scene, lightmap) = (bake.scene, bake.lightmap);
    let mut writer = start_document(scene, lightmap)?;
    let atlases = lightmap.atlases().len();
    let mut pngs = Vec::with_capacity(atlases);
    let mut png_paths = Vec::with_capacity(atlases);
    let mut textures = Vec::with_capacity(atlases);
    for k in 0..atlases {
        let atlas = lightmap.atlas(k);
        let texels = surface_texels(bake, k)?;
        let exposure = bake.exposure;
        let alpha = surface_alpha(bake, k);
        let png = lightmap::encode_srgb_png_alpha(
            atlas.width,
            atlas.height,
            &texels,
            alpha.as_deref(),
            |v| f64::from(v) * exposure,
        )
        .map_err(|e| ExportError::Encode {
            what: "baked texture",
            message: e.to_string(),
        })?;
        let path = paths.atlas_png(k)?;
        let name = if k == 0 {
            "baked".to_string()
        } else {
            format!("baked-{k}")
        };
        let image = png_image(&mut writer, format, name, &png, &path);
        textures.push(add_texture(&mut writer.root, image));
        pngs.push(png);
        png_paths.push(path);
    }
    add_meshes(&mut writer, scene, lightmap, true, |writer, m, atlas| {
        let source = scene
            .materials
            .get(m)
            .ok_or_else(|| ExportError::InvalidData(format!("missing material {m}")))?;
        let mask = scene.alpha_masks.get(m).copied().flatten();
        let material = unlit_material(source.name.clone(), textures[atlas as usize], mask);
        Ok((writer.root.push(material), UvNeeds::default()))
    })?;
    writer.use_extension(UNLIT_EXTENSION);
    if let Some(probes) = bake.probes {
        crate::probes::add(&mut writer, probes)?;
    }
    let extras = serde_json::json!({
        BAKED_TEXTURE_EXTRAS_KEY: {
            "quantity": "radiosity b = rho * H + e, the base-colour texture multiplied in per texel",
            "encoding": "8-bit sRGB of clamp(b * exposure, 0, 1)",
            "texcoord": 1,
            "exposure": bake.exposure,
            "texel_size": lightmap.texel_size,
            "atlases": lightmap.atlases().iter().map(|a| [a.width, a.height]).collect::<Vec<_>>(),
        }
    })
    .to_string();
    writer.root.extras = Some(
        serde_json::value::RawValue::from_string(extras).map_err(|e| ExportError::Encode {
            what: "glTF extras",
            message: e.to_string(),
        })?,
    );
    let mut staged: Vec<(&Path, &[u8])> = Vec::new();
    if format == OutputFormat::Gltf {
        for (path, png) in png_paths.iter().zip(&pngs) {
            staged.push((path.as_path(), png));
        }
    }
    stage_document(set, &paths.gltf, format, writer, staged)
}

/// An unlit material showing `texture` on `TEXCOORD_1` under a white factor; with an alpha
/// cut-out, `MASK` at its cutoff (the atlas's alpha holds the cut-out, [`surface_alpha`]).
fn unlit_material(
    name: Option<String>,
    texture: json::Index<json::Texture>,
    mask: Option<AlphaMask>,
) -> json::Material {
    json::Material {
        name,
        alpha_mode: json::validation::Checked::Valid(if mask.is_some() {
            json::material::AlphaMode::Mask
        } else {
            json::material::AlphaMode::Opaque
        }),
        alpha_cutoff: mask.map(|m| json::material::AlphaCutoff(m.cutoff as f32)),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([1.0, 1.0, 1.0, 1.0]),
            base_color_texture: Some(json::texture::Info {
                index: texture,
                tex_coord: 1,
                extensions: None,
                extras: Default::default(),
            }),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(1.0),
            ..Default::default()
        },
        double_sided: false,
        extensions: Some(json::extensions::material::Material {
            unlit: Some(json::extensions::material::Unlit {}),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// Atlas `k`'s texels of linear `ρ × H + e` (before exposure): H the lightmap's texel, ρ and
/// e the material's at the surface point the texel shows ([`Lightmap::texel_point`]).
/// Unused texels are 0. Rows are computed in parallel, each texel on its own: the same
/// values for any thread count.
pub fn surface_texels(bake: &BakedTextureBake, k: usize) -> Result<Vec<[f32; 3]>, ExportError> {
    let (scene, lightmap) = (bake.scene, bake.lightmap);
    let atlas = lightmap.atlas(k);
    let values: Vec<Result<[f32; 3], ExportError>> = atlas
        .texels
        .par_iter()
        .enumerate()
        .map(|(index, h)| {
            let Some((p, weights)) = lightmap.texel_point(k, index) else {
                return Ok([0.0; 3]);
            };
            let polygon = scene.polygons.get(p).ok_or_else(|| {
                ExportError::InvalidData(format!("lightmap texel of missing polygon {p}"))
            })?;
            let point = at_weights(polygon, weights);
            let (rho, e) = surface_at(bake, p, point);
            let value: [f32; 3] = std::array::from_fn(|c| (rho[c] * f64::from(h[c]) + e[c]) as f32);
            if !value.iter().all(|v| v.is_finite()) {
                return Err(ExportError::NonFinite {
                    what: format!("the baked texel {index} of atlas {k} (polygon {p})"),
                });
            }
            Ok(value)
        })
        .collect();
    values.into_iter().collect()
}

/// Atlas `k`'s alpha where a material of the scene is cut out (`alphaMode` `MASK`): per
/// texel, `baseColorFactor`'s alpha × the base-colour texture's alpha at the surface point the
/// texel shows (the input's cut-out, resampled at the lightmap's texels; 1 elsewhere);
/// `None` when no material is cut out. The same values for any thread count.
pub fn surface_alpha(bake: &BakedTextureBake, k: usize) -> Option<Vec<f32>> {
    let scene = bake.scene;
    if scene.alpha_masks.iter().all(Option::is_none) {
        return None;
    }
    let lightmap = bake.lightmap;
    let atlas = lightmap.atlas(k);
    Some(
        (0..atlas.texels.len())
            .into_par_iter()
            .map(|index| {
                let Some((p, weights)) = lightmap.texel_point(k, index) else {
                    return 1.0;
                };
                let Some(polygon) = scene.polygons.get(p) else {
                    return 1.0;
                };
                let material = polygon.material;
                let Some(mask) = scene.alpha_masks.get(material).copied().flatten() else {
                    return 1.0;
                };
                let point = at_weights(polygon, weights);
                let texture = scene.materials[material]
                    .base_color_texture
                    .as_ref()
                    .and_then(|reference| texture_at(scene, p, reference, point))
                    .map_or(1.0, |(texture, image, at)| {
                        texture::sample_alpha(texture, image, at)
                    });
                (mask.factor * texture).clamp(0.0, 1.0) as f32
            })
            .collect(),
    )
}

/// The world point of `polygon` at its corners' `weights` ([`Lightmap::texel_point`]).
fn at_weights(polygon: &scene::Polygon, weights: [f64; 4]) -> DVec3 {
    polygon
        .vertices
        .iter()
        .zip(weights)
        .fold(DVec3::ZERO, |sum, (&v, w)| sum + v * w)
}

/// The texture `reference` names and the texture coordinate it is sampled at, for world
/// point `point` of polygon `p` (its `TEXCOORD_0` or `_1` there, the reference's transform
/// applied); `None` where the polygon has no such coordinates or the texture is missing.
fn texture_at<'a>(
    scene: &'a Scene,
    p: usize,
    reference: &TextureRef,
    point: DVec3,
) -> Option<(&'a scene::Texture, &'a scene::Image, glam::DVec2)> {
    let uv = scene.uvs.get(p).and_then(Option::as_ref)?;
    let at = uv.at((reference.tex_coord as usize).min(1), point)?;
    let texture = scene.textures.get(reference.texture)?;
    let image = scene.images.get(texture.image)?;
    Some((texture, image, reference.apply(at)))
}

/// ρ and e of polygon `p`'s material at world point `point`: the factors times the textures
/// (and ρ times the input's `COLOR_0`) there, as the bake averages them per element
/// (`bake_core::element_values`), ρ lowered as the bake lowers it.
fn surface_at(bake: &BakedTextureBake, p: usize, point: DVec3) -> ([f64; 3], [f64; 3]) {
    let scene = bake.scene;
    let material = &scene.materials[scene.polygons[p].material];
    let uv = scene.uvs.get(p).and_then(Option::as_ref);
    let textured = |factor: [f64; 3], reference: &Option<TextureRef>| {
        let Some((texture, image, at)) = reference
            .as_ref()
            .and_then(|reference| texture_at(scene, p, reference, point))
        else {
            return factor;
        };
        let value = texture::sample(texture, image, at);
        std::array::from_fn(|c| factor[c] * value[c].clamp(0.0, 1.0))
    };
    let mut rho = textured(material.rho, &material.base_color_texture);
    if let Some(colour) = uv.and_then(|uv| uv.color_at(point)) {
        let colour = colour.to_array();
        rho = std::array::from_fn(|c| rho[c] * colour[c].clamp(0.0, 1.0));
    }
    if let Some((at, to)) = bake.ceiling {
        for r in rho.iter_mut().filter(|r| **r >= at) {
            *r = to;
        }
    }
    let e = textured(material.emission, &material.emissive_texture);
    (rho, e)
}
