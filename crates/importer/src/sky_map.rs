//! Sky maps (`--sky map:FILE`): an equirectangular Radiance `.hdr` (RGBE) or OpenEXR `.exr`
//! (its first RGB(A) layer) decoded to linear RGB radiance, row 0 at the top. Only the file
//! format is here; what the texels mean (directions, sampling) is `bake-direct`'s
//! `envmap`.

use crate::ImportError;
use scene::{SkyImage, MAX_SKY_MAP_TEXELS};
use std::path::Path;

/// Reads the sky map at `path`: refused (naming the file) when it cannot be read, is not
/// `.hdr` or `.exr`, or has more than [`MAX_SKY_MAP_TEXELS`] texels (checked before it is
/// decoded).
pub fn load_sky_map(path: &Path) -> Result<SkyImage, ImportError> {
    let file = path.display().to_string();
    let unreadable = |message: String| ImportError::InvalidValue {
        what: format!("the sky map {file}"),
        problem: message,
    };
    let too_large = |w: u64, h: u64| {
        ImportError::TooLarge(format!(
            "the sky map {file} is {w} × {h}: more than {MAX_SKY_MAP_TEXELS} texels"
        ))
    };
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("hdr") => {
            let open = || {
                image::ImageReader::open(path)
                    .map_err(|e| ImportError::Io {
                        path: path.to_path_buf(),
                        source: e,
                    })?
                    .with_guessed_format()
                    .map_err(|e| ImportError::Io {
                        path: path.to_path_buf(),
                        source: e,
                    })
            };
            let (w, h) = open()?
                .into_dimensions()
                .map_err(|e| unreadable(e.to_string()))?;
            if u64::from(w) * u64::from(h) > MAX_SKY_MAP_TEXELS {
                return Err(too_large(u64::from(w), u64::from(h)));
            }
            let image = open()?
                .decode()
                .map_err(|e| unreadable(e.to_string()))?
                .to_rgb32f();
            Ok(SkyImage {
                width: w as usize,
                height: h as usize,
                texels: image.pixels().map(|p| p.0).collect(),
            })
        }
        Some("exr") => {
            use exr::prelude::*;
            let image = read_first_rgba_layer_from_file(
                path,
                |size: Vec2<usize>, _: &RgbaChannels| {
                    let texels = if (size.0 as u64) * (size.1 as u64) <= MAX_SKY_MAP_TEXELS {
                        vec![[0f32; 3]; size.0 * size.1]
                    } else {
                        Vec::new()
                    };
                    (size.0, size.1, texels)
                },
                |(w, _, texels): &mut (usize, usize, Vec<[f32; 3]>),
                 at: Vec2<usize>,
                 (r, g, b, _): (f32, f32, f32, f32)| {
                    if let Some(t) = texels.get_mut(at.1 * *w + at.0) {
                        *t = [r, g, b];
                    }
                },
            )
            .map_err(|e| unreadable(e.to_string()))?;
            let (width, height, texels) = image.layer_data.channel_data.pixels;
            if (width as u64) * (height as u64) > MAX_SKY_MAP_TEXELS {
                return Err(too_large(width as u64, height as u64));
            }
            Ok(SkyImage {
                width,
                height,
                texels,
            })
        }
        _ => Err(ImportError::InvalidValue {
            what: format!("the sky map {file}"),
            problem: "not a .hdr or .exr file".to_string(),
        }),
    }
}
