//! Base-colour textures as a viewer samples them: the image sRGB-decoded to linear, the
//! reference's `KHR_texture_transform`, the sampler's wrap modes and magnification filter
//! (`NEAREST`, else bilinear between texel centres). No mip levels: a preview pixel is one
//! sample, and the check it serves compares pixels with the texture at their UV.

use crate::math::Vec3;

/// How coordinates outside [0, 1] wrap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

/// A material's base-colour texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    /// Linear RGB, row-major from the top row (glTF's v = 0).
    pub texels: Vec<Vec3>,
    pub nearest: bool,
    pub wrap: [Wrap; 2],
    /// `KHR_texture_transform` as uv' = M (u, v, 1).
    pub transform: [[f64; 3]; 2],
}

impl Texture {
    /// The texture's linear colour at `uv` (the transform, filter and wraps applied).
    pub fn sample(&self, uv: [f64; 2]) -> Vec3 {
        let m = &self.transform;
        let u = m[0][0] * uv[0] + m[0][1] * uv[1] + m[0][2];
        let v = m[1][0] * uv[0] + m[1][1] * uv[1] + m[1][2];
        let (x, y) = (u * f64::from(self.width), v * f64::from(self.height));
        if self.nearest {
            return self.texel(x.floor() as i64, y.floor() as i64);
        }
        let (x, y) = (x - 0.5, y - 0.5);
        let (i, j) = (x.floor(), y.floor());
        let (s, t) = (x - i, y - j);
        let (i, j) = (i as i64, j as i64);
        let [a, b, c, d] = [
            self.texel(i, j),
            self.texel(i + 1, j),
            self.texel(i, j + 1),
            self.texel(i + 1, j + 1),
        ];
        std::array::from_fn(|k| {
            (1.0 - t) * ((1.0 - s) * a[k] + s * b[k]) + t * ((1.0 - s) * c[k] + s * d[k])
        })
    }

    fn texel(&self, i: i64, j: i64) -> Vec3 {
        let x = wrap(i, i64::from(self.width), self.wrap[0]);
        let y = wrap(j, i64::from(self.height), self.wrap[1]);
        self.texels
            .get((y * i64::from(self.width) + x) as usize)
            .copied()
            .unwrap_or([1.0; 3])
    }
}

fn wrap(i: i64, n: i64, mode: Wrap) -> i64 {
    match mode {
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::MirroredRepeat => {
            let k = i.rem_euclid(2 * n);
            if k < n {
                k
            } else {
                2 * n - 1 - k
            }
        }
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The base-colour texture of `material`, decoded, or `None` when it has none. `base` is the
/// file's directory (for images beside it).
pub(crate) fn base_colour(
    material: &gltf::Material,
    buffers: &[gltf::buffer::Data],
    base: Option<&std::path::Path>,
) -> Result<Option<(Texture, u32)>, String> {
    let Some(info) = material.pbr_metallic_roughness().base_color_texture() else {
        return Ok(None);
    };
    let (transform, set) = match info.texture_transform() {
        Some(t) => {
            let [ox, oy] = t.offset().map(f64::from);
            let r = f64::from(t.rotation());
            let [sx, sy] = t.scale().map(f64::from);
            let (s, c) = r.sin_cos();
            (
                [[c * sx, s * sy, ox], [-s * sx, c * sy, oy]],
                t.tex_coord().unwrap_or(info.tex_coord()),
            )
        }
        None => (IDENTITY_TRANSFORM, info.tex_coord()),
    };
    let texture = decode(&info.texture(), "base-colour texture", buffers, base)?;
    Ok(Some((
        Texture {
            transform,
            ..texture
        },
        set,
    )))
}

/// No `KHR_texture_transform`: uv' = uv.
const IDENTITY_TRANSFORM: [[f64; 3]; 2] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// Texture `texture` decoded to linear RGB (sRGB-decoded 8-bit texels) with its sampler, no
/// transform; `what` names it in errors.
pub(crate) fn decode(
    texture: &gltf::Texture,
    what: &str,
    buffers: &[gltf::buffer::Data],
    base: Option<&std::path::Path>,
) -> Result<Texture, String> {
    let data = gltf::image::Data::from_source(texture.source().source(), base, buffers)
        .map_err(|e| format!("{what} {}: {e}", texture.index()))?;
    let channels = match data.format {
        gltf::image::Format::R8G8B8 => 3,
        gltf::image::Format::R8G8B8A8 => 4,
        gltf::image::Format::R8 => 1,
        gltf::image::Format::R8G8 => 2,
        other => {
            return Err(format!(
                "{what} {}: {other:?} images are not drawn",
                texture.index()
            ))
        }
    };
    let table: Vec<f64> = (0..256)
        .map(|v| srgb_to_linear(f64::from(v as u8) / 255.0))
        .collect();
    let texels = data
        .pixels
        .chunks_exact(channels)
        .map(|p| match channels {
            1 | 2 => [table[p[0] as usize]; 3],
            _ => [
                table[p[0] as usize],
                table[p[1] as usize],
                table[p[2] as usize],
            ],
        })
        .collect();
    let sampler = texture.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    };
    Ok(Texture {
        width: data.width,
        height: data.height,
        texels,
        nearest: sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest),
        wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
        transform: IDENTITY_TRANSFORM,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker(nearest: bool) -> Texture {
        Texture {
            width: 2,
            height: 2,
            texels: vec![[0.0; 3], [1.0; 3], [1.0; 3], [0.0; 3]],
            nearest,
            wrap: [Wrap::Repeat; 2],
            transform: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        }
    }

    #[test]
    fn nearest_and_bilinear_samples() {
        let t = checker(true);
        assert_eq!(t.sample([0.25, 0.25]), [0.0; 3]);
        assert_eq!(t.sample([0.75, 0.25]), [1.0; 3]);
        assert_eq!(t.sample([1.25, 0.25]), [0.0; 3], "repeat");
        // Bilinear: halfway between the centres of texels (0,0) and (1,0).
        assert_eq!(checker(false).sample([0.5, 0.25]), [0.5; 3]);
        assert_eq!(checker(false).sample([0.25, 0.25]), [0.0; 3]);
    }
}
