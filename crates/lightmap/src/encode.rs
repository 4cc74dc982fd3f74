//! Image files for a lightmap: linear float EXR (exact) and 8-bit sRGB-encoded PNG with a
//! scale (for viewers: what `MOZ_lightmap` points at).

use crate::{AtlasRef, Lightmap, LightmapError, Texel};
use std::io::Cursor;

/// What the EXR's `comments` attribute says about its content.
pub const EXR_COMMENT: &str = "bake lightmap: irradiance H per texel, linear, in the bake's \
intensity units (the units of emission e and radiosity b: b = e + rho*H)";

/// An encoded PNG lightmap and the factor that turns its decoded values back into H.
#[derive(Clone, Debug, PartialEq)]
pub struct PngLightmap {
    pub bytes: Vec<u8>,
    /// `H = srgb_to_linear(value / 255) × scale` ([`png_scale`]; 1 when every texel is 0).
    /// This is `MOZ_lightmap.intensity`.
    pub scale: f64,
    /// Chart texels with a band above `scale`, written as 255 there (the EXR keeps them).
    pub clipped: u64,
    /// Chart texels ([`Texel::Chart`]) the scale was chosen from.
    pub covered: u64,
}

/// The share of chart texels (by their brightest band) that sets the PNG's scale: the
/// 99.9th percentile, nearest rank.
pub const PNG_PERCENTILE: f64 = 0.999;
/// How far above the [`PNG_PERCENTILE`] texel the scale may reach before the brightest
/// texels clip: a hot spot (a lamp's pool, a glint) up to twice the percentile keeps its
/// shape; one texel a hundred times brighter than the rest no longer blacks them out.
pub const PNG_HEADROOM: f64 = 2.0;

/// The PNG's scale for `atlas`, and how many chart texels clip at it and how many there
/// are: the brightest chart texel, or [`PNG_HEADROOM`] × the [`PNG_PERCENTILE`] texel when
/// that is lower (so at most 0.1% clip); 1 when every chart texel is 0.
pub fn png_scale(atlas: AtlasRef) -> (f64, u64, u64) {
    let mut brightest: Vec<f32> = atlas
        .texels
        .iter()
        .zip(atlas.coverage)
        .filter(|(_, c)| matches!(c, Texel::Chart(_)))
        .map(|(t, _)| t[0].max(t[1]).max(t[2]))
        .collect();
    let n = brightest.len();
    let max = brightest.iter().copied().fold(0.0f32, f32::max);
    if n == 0 || max <= 0.0 {
        return (1.0, 0, n as u64);
    }
    let rank = ((PNG_PERCENTILE * n as f64).ceil() as usize).clamp(1, n);
    let (_, &mut percentile, _) = brightest.select_nth_unstable_by(rank - 1, f32::total_cmp);
    let capped = PNG_HEADROOM * f64::from(percentile);
    let scale = if capped > 0.0 && capped < f64::from(max) {
        capped
    } else {
        f64::from(max)
    };
    let clipped = brightest.iter().filter(|&&b| f64::from(b) > scale).count();
    (scale, clipped as u64, n as u64)
}

/// The lightmap as an OpenEXR file: one layer, channels R, G, B as 32-bit floats (f16 would
/// lose ~1e-3 relative), lossless ZIP compression, written on one thread so the bytes never
/// depend on the thread count.
pub fn encode_exr(lightmap: &Lightmap) -> Result<Vec<u8>, LightmapError> {
    encode_exr_atlas(lightmap.atlas(0))
}

/// [`encode_exr`] of one atlas ([`Lightmap::atlas`]).
pub fn encode_exr_atlas(lightmap: AtlasRef) -> Result<Vec<u8>, LightmapError> {
    use exr::prelude::*;
    let width = lightmap.width as usize;
    let texels = lightmap.texels;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let t = texels[y * width + x];
        (t[0], t[1], t[2])
    });
    let mut image = Image::from_encoded_channels(
        (width, lightmap.height as usize),
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    image.layer_data.attributes.comments = Some(Text::from(EXR_COMMENT));
    let mut cursor = Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut cursor)
        .map_err(|e| LightmapError::Encode {
            what: "EXR",
            message: e.to_string(),
        })?;
    Ok(cursor.into_inner())
}

/// sRGB transfer function (IEC 61966-2-1), linear [0, 1] → encoded [0, 1].
pub fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse of [`linear_to_srgb`].
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The lightmap as an 8-bit RGB PNG: each texel is `H / scale`, sRGB-encoded (more of the
/// 256 levels go to the dark end, as for any colour texture; viewers must decode it as sRGB).
pub fn encode_png(lightmap: &Lightmap) -> Result<PngLightmap, LightmapError> {
    encode_png_atlas(lightmap.atlas(0))
}

/// [`encode_png`] of one atlas ([`Lightmap::atlas`]), at its own [`png_scale`].
pub fn encode_png_atlas(lightmap: AtlasRef) -> Result<PngLightmap, LightmapError> {
    let (scale, clipped, covered) = png_scale(lightmap);
    let png = encode_srgb_png(lightmap.width, lightmap.height, lightmap.texels, |v| {
        f64::from(v) / scale
    })?;
    Ok(PngLightmap {
        bytes: png,
        scale,
        clipped,
        covered,
    })
}

/// An 8-bit RGB PNG of linear `texels` (row-major from the top-left), each band mapped by
/// `to_unit` (a scale or an exposure), clamped to [0, 1] and sRGB-encoded
/// ([`linear_to_srgb`], rounded to the nearest level).
pub fn encode_srgb_png(
    width: u32,
    height: u32,
    texels: &[[f32; 3]],
    to_unit: impl Fn(f32) -> f64,
) -> Result<Vec<u8>, LightmapError> {
    encode_srgb_png_alpha(width, height, texels, None, to_unit)
}

/// [`encode_srgb_png`] with an alpha channel (linear, clamped to [0, 1], rounded to the
/// nearest of 256 levels) when `alpha` is given: an 8-bit RGBA PNG.
pub fn encode_srgb_png_alpha(
    width: u32,
    height: u32,
    texels: &[[f32; 3]],
    alpha: Option<&[f32]>,
    to_unit: impl Fn(f32) -> f64,
) -> Result<Vec<u8>, LightmapError> {
    use image::ImageEncoder;
    let level = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let colour = |t: &[f32; 3]| t.map(|v| level(linear_to_srgb(to_unit(v).clamp(0.0, 1.0))));
    let (bytes, kind): (Vec<u8>, _) = match alpha {
        None => (
            texels.iter().flat_map(colour).collect(),
            image::ExtendedColorType::Rgb8,
        ),
        Some(alpha) => (
            texels
                .iter()
                .zip(alpha.iter().chain(std::iter::repeat(&1.0)))
                .flat_map(|(t, a)| {
                    let [r, g, b] = colour(t);
                    [r, g, b, level(f64::from(*a))]
                })
                .collect(),
            image::ExtendedColorType::Rgba8,
        ),
    };
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&bytes, width, height, kind)
        .map_err(|e| LightmapError::Encode {
            what: "PNG",
            message: e.to_string(),
        })?;
    Ok(png)
}
