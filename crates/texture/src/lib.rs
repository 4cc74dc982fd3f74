//! Exact means of a material's textures over mesh elements: the reflectance ρ of an element
//! is `baseColorFactor` × the mean of `baseColorTexture` over the element's surface, and its
//! emission likewise with `emissiveTexture` (glTF 2.0, "Metallic-Roughness Material").
//!
//! "Mean over the surface" is area-weighted on the surface, not in texture space, so UV stretch
//! does not bias it: the element is cut by the source triangles of its polygon (each maps
//! affinely to texture space, so within one triangle surface area and texture area are
//! proportional), and each piece's texture mean is integrated exactly over the texels it
//! covers — per texel cell for a `NEAREST` magnification filter (the texture is constant on
//! each cell), per cell between texel centres for the default linear filter (bilinear there;
//! integrated by the degree-2 edge-midpoint rule on a fan, exact for bilinear functions), with
//! the sampler's wrap modes. Mip levels are never used: they average more than the element.
//! A piece that covers more than [`MAX_CELLS`] cells is averaged from [`SAMPLES`] points
//! instead (bounded work for any UV extent, issue 34).
//! [`sample_alpha`] reads an image's alpha as the sampler filters it, for alpha cut-outs.
//!
//! It is not the importer (which decodes images to linear values) and knows no elements beyond
//! their corners.

use glam::{DVec2, DVec3};
use scene::{Image, PolygonUv, Texture, TextureRef, Wrap};

/// The mean linear RGB of `texture` (with `image`) over the planar convex element `corners`
/// (3 or 4, counter-clockwise about `normal`) lying on the polygon mapped by `uv`, through
/// `reference`'s TEXCOORD set and transform.
pub fn element_mean(
    uv: &PolygonUv,
    reference: &TextureRef,
    texture: &Texture,
    image: &Image,
    corners: &[DVec3],
    normal: DVec3,
) -> [f64; 3] {
    let set = (reference.tex_coord as usize).min(1);
    let mut total = [0.0; 3];
    let mut weight = 0.0;
    for_each_piece(uv, corners, normal, |triangle, p, piece, area| {
        let q = triangle.uv[set].map(|t| reference.apply(t));
        // The affine map of this triangle: X ↦ q0 + M (X − p0), M = [q1−q0 q2−q0][p1−p0 p2−p0]⁻¹.
        let in_uv: Vec<DVec2> = piece.iter().map(|&x| affine(p, q, x)).collect();
        let mean = polygon_mean(&in_uv, texture, image);
        for c in 0..3 {
            total[c] += area * mean[c];
        }
        weight += area;
    });
    if weight > 0.0 {
        return total.map(|t| t / weight);
    }
    // Outside every source triangle (rounding at a sliver): the texture at the centre of the
    // polygon's first source triangle.
    let centre = uv.triangles.first().map_or(DVec2::ZERO, |t| {
        reference.apply((t.uv[set][0] + t.uv[set][1] + t.uv[set][2]) / 3.0)
    });
    sample(texture, image, centre)
}

/// The mean of the input's `COLOR_0` over the element `corners` (as [`element_mean`]): on
/// each piece of the element inside one source triangle the colour is linear, so its mean
/// there is its value at the piece's centroid — exact. `None` when the polygon has no
/// colours.
pub fn element_colour_mean(uv: &PolygonUv, corners: &[DVec3], normal: DVec3) -> Option<[f64; 3]> {
    uv.triangles.first()?.color?;
    let mut total = DVec3::ZERO;
    let mut weight = 0.0;
    for_each_piece(uv, corners, normal, |triangle, p, piece, area| {
        let Some(color) = triangle.color else {
            return;
        };
        let centroid = clip::centroid(piece);
        // Barycentric coordinates of the centroid in the source triangle.
        let (a, b) = (p[1] - p[0], p[2] - p[0]);
        let det = a.perp_dot(b);
        let d = centroid - p[0];
        let (s, t) = (d.perp_dot(b) / det, a.perp_dot(d) / det);
        total += (color[0] + (color[1] - color[0]) * s + (color[2] - color[0]) * t) * area;
        weight += area;
    });
    if weight > 0.0 {
        return Some((total / weight).to_array());
    }
    let t = uv.triangles.first()?;
    t.color.map(|c| ((c[0] + c[1] + c[2]) / 3.0).to_array())
}

/// Calls `f(triangle, its corners in the element's plane, piece, piece area)` for each piece
/// of the element `corners` (planar convex, counter-clockwise about `normal`) inside one
/// source triangle of `uv` with positive area.
fn for_each_piece(
    uv: &PolygonUv,
    corners: &[DVec3],
    normal: DVec3,
    mut f: impl FnMut(&scene::UvTriangle, [DVec2; 3], &[DVec2], f64),
) {
    let origin = corners[0];
    let u_axis = (corners[1] - corners[0]).normalize_or_zero();
    let v_axis = normal.cross(u_axis);
    let to_2d = |p: DVec3| DVec2::new((p - origin).dot(u_axis), (p - origin).dot(v_axis));
    let element: Vec<DVec2> = corners.iter().map(|&p| to_2d(p)).collect();
    let (mut piece, mut scratch) = (Vec::new(), Vec::new());
    for triangle in &uv.triangles {
        let p = triangle.positions.map(to_2d);
        clip::clip_convex(&element, &p, &mut piece, &mut scratch);
        let area = clip::signed_area(&piece).abs();
        if piece.len() < 3 || area <= 0.0 || (p[1] - p[0]).perp_dot(p[2] - p[0]) == 0.0 {
            continue;
        }
        f(triangle, p, &piece, area);
    }
}

/// The affine map taking triangle `p` to `q`, at `x`.
fn affine(p: [DVec2; 3], q: [DVec2; 3], x: DVec2) -> DVec2 {
    let (a, b) = (p[1] - p[0], p[2] - p[0]);
    let det = a.perp_dot(b);
    let d = x - p[0];
    let s = d.perp_dot(b) / det;
    let t = a.perp_dot(d) / det;
    q[0] + (q[1] - q[0]) * s + (q[2] - q[0]) * t
}

/// The texture at one UV point (the filter and wrap modes applied).
pub fn sample(texture: &Texture, image: &Image, uv: DVec2) -> [f64; 3] {
    let (w, h) = (image.width as f64, image.height as f64);
    let (x, y) = (pixel(uv.x * w), pixel(uv.y * h));
    if texture.nearest {
        return texel(texture, image, x.floor() as i64, y.floor() as i64);
    }
    let (x, y) = (x - 0.5, y - 0.5);
    let (i, j) = (x.floor(), y.floor());
    bilinear(texture, image, i as i64, j as i64, x - i, y - j)
}

/// Beyond this many texels from the origin f64 has no fraction left (2⁵²): coordinates are
/// clamped to it, so that texel indices and their neighbours stay far inside i64.
const FAR: f64 = 4_503_599_627_370_496.0;

/// A pixel coordinate clamped to ±[`FAR`] (NaN to 0).
fn pixel(x: f64) -> f64 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(-FAR, FAR)
    }
}

/// The image's alpha at texture coordinate `uv`, filtered and wrapped as [`sample`] filters
/// colour (1 for an image without alpha): what a renderer compares with `alphaCutoff`.
pub fn sample_alpha(texture: &Texture, image: &Image, uv: DVec2) -> f64 {
    if image.alpha.is_empty() {
        return 1.0;
    }
    let at = |i: i64, j: i64| {
        let x = wrap(i, image.width as i64, texture.wrap[0]);
        let y = wrap(j, image.height as i64, texture.wrap[1]);
        image
            .alpha
            .get((y * image.width as i64 + x) as usize)
            .map_or(1.0, |&a| f64::from(a))
    };
    let (w, h) = (image.width as f64, image.height as f64);
    let (x, y) = (pixel(uv.x * w), pixel(uv.y * h));
    if texture.nearest {
        return at(x.floor() as i64, y.floor() as i64);
    }
    let (x, y) = (x - 0.5, y - 0.5);
    let (i, j) = (x.floor(), y.floor());
    let (s, t) = (x - i, y - j);
    let (i, j) = (i as i64, j as i64);
    (1.0 - t) * ((1.0 - s) * at(i, j) + s * at(i + 1, j))
        + t * ((1.0 - s) * at(i, j + 1) + s * at(i + 1, j + 1))
}

/// Texel cells (of the piece's bounding box in pixel space) beyond which a piece's mean is
/// estimated from [`SAMPLES`] points instead of integrated cell by cell: the exact sum visits
/// every cell, and a UV extent of 10⁷ periods (a `KHR_texture_transform` scale, a stray
/// `vt 1e30 0`) or a 512² texture tiled 40 times over a floor would visit billions (issue 34:
/// past 120 s and 31 s). 262 144 cells (a whole 512² texture) cost a few ms.
pub const MAX_CELLS: f64 = 262_144.0;

/// Points of the estimate past [`MAX_CELLS`]: the R2 low-discrepancy sequence (Roberts 2018),
/// whose irrational steps never alias with a texture's integer period, mapped area-uniformly
/// onto the piece's fan triangles. A piece past the cap covers more than 262 144 texels, which
/// its mean averages away; the estimate's error is that of a quasi-Monte Carlo rule over 4 096
/// points, about 1/64 of the texels' spread for an irregular texture and far less for a
/// periodic pattern (the tests: a ramp over 10⁷ periods within 0.5 % of its range).
pub const SAMPLES: usize = 4_096;

/// The mean of the texture over the convex polygon `uv` (texture coordinates).
fn polygon_mean(uv: &[DVec2], texture: &Texture, image: &Image) -> [f64; 3] {
    let (w, h) = (image.width as f64, image.height as f64);
    // Pixel space; for the linear filter, shifted so cells run between texel centres.
    let shift = if texture.nearest { 0.0 } else { 0.5 };
    let poly: Vec<DVec2> = uv
        .iter()
        .map(|t| DVec2::new(t.x * w - shift, t.y * h - shift))
        .collect();
    let area = clip::signed_area(&poly).abs();
    if !(area > 0.0 && area.is_finite()) {
        let c = uv.iter().copied().sum::<DVec2>() / uv.len() as f64;
        return sample(texture, image, c);
    }
    let (lo, hi) = poly.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let cells = (hi.x.ceil() - lo.x.floor()) * (hi.y.ceil() - lo.y.floor());
    let far = lo.min_element() < -FAR || hi.max_element() > FAR;
    // NaN cells (an infinite extent) take the estimate too.
    if cells.is_nan() || cells > MAX_CELLS || far {
        return sampled_mean(uv, texture, image);
    }
    let mut sum = [0.0; 3];
    let (mut strip, mut cell, mut tmp) = (Vec::new(), Vec::new(), Vec::new());
    for j in lo.y.floor() as i64..hi.y.ceil() as i64 {
        let (y0, y1) = (j as f64, j as f64 + 1.0);
        clip::clip_half_plane(&poly, DVec2::Y, y0, &mut tmp);
        clip::clip_half_plane(&tmp, DVec2::NEG_Y, -y1, &mut strip);
        if strip.len() < 3 {
            continue;
        }
        let (xl, xr) = strip
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, r), p| {
                (l.min(p.x), r.max(p.x))
            });
        // Cells wholly inside the strip: between the inner ends of its bottom and top
        // cross-sections (a convex polygon's left side is convex, its right side concave).
        let inner = match (cross_section(&strip, y0), cross_section(&strip, y1)) {
            (Some((l0, r0)), Some((l1, r1))) => Some((l0.max(l1), r0.min(r1))),
            _ => None,
        };
        for i in xl.floor() as i64..xr.ceil() as i64 {
            let (x0, x1) = (i as f64, i as f64 + 1.0);
            let full = inner.is_some_and(|(l, r)| x0 >= l && x1 <= r);
            let add = if full {
                cell_mean(texture, image, i, j)
            } else {
                clip::clip_half_plane(&strip, DVec2::X, x0, &mut tmp);
                clip::clip_half_plane(&tmp, DVec2::NEG_X, -x1, &mut cell);
                if cell.len() < 3 {
                    continue;
                }
                cell_integral(texture, image, i, j, &cell)
            };
            for c in 0..3 {
                sum[c] += add[c];
            }
        }
    }
    sum.map(|s| s / area)
}

/// [`SAMPLES`] points of the convex polygon `uv` (see there), split over its fan triangles by
/// area, averaged through [`sample`] (filter and wrap modes applied).
fn sampled_mean(uv: &[DVec2], texture: &Texture, image: &Image) -> [f64; 3] {
    // R2: the steps 1/φ₂ and 1/φ₂², φ₂ the plastic number.
    const STEP: [f64; 2] = [0.754_877_666_246_692_7, 0.569_840_290_998_053_2];
    let fan: Vec<[DVec2; 3]> = (1..uv.len().saturating_sub(1))
        .map(|k| [uv[0], uv[k], uv[k + 1]])
        .collect();
    let areas: Vec<f64> = fan
        .iter()
        .map(|t| (t[1] - t[0]).perp_dot(t[2] - t[0]).abs() / 2.0)
        .collect();
    let total: f64 = areas.iter().sum();
    let mut sum = [0.0; 3];
    let mut weight = 0.0;
    for (t, &area) in fan.iter().zip(&areas) {
        if !(area > 0.0 && total > 0.0) {
            continue;
        }
        let n = ((SAMPLES as f64 * area / total).round() as usize).max(1);
        let mut acc = [0.0; 3];
        for k in 0..n {
            let u = (0.5 + STEP[0] * k as f64).fract();
            let v = (0.5 + STEP[1] * k as f64).fract();
            // Shirley & Chiu's square-to-triangle map: area-uniform.
            let r = u.sqrt();
            let p = t[0] * (1.0 - r) + t[1] * (r * (1.0 - v)) + t[2] * (r * v);
            let c = sample(texture, image, p);
            for (a, c) in acc.iter_mut().zip(c) {
                *a += c;
            }
        }
        for (s, a) in sum.iter_mut().zip(acc) {
            *s += area * a / n as f64;
        }
        weight += area;
    }
    if weight > 0.0 {
        sum.map(|s| s / weight)
    } else {
        sample(texture, image, uv[0])
    }
}

/// The x-range of the convex polygon at height y, if it reaches that height.
fn cross_section(poly: &[DVec2], y: f64) -> Option<(f64, f64)> {
    let mut range: Option<(f64, f64)> = None;
    let mut extend = |x: f64| {
        range = Some(range.map_or((x, x), |(l, r)| (l.min(x), r.max(x))));
    };
    for k in 0..poly.len() {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        if a.y == y {
            extend(a.x);
        }
        if (a.y - y) * (b.y - y) < 0.0 {
            extend(a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y));
        }
    }
    range
}

/// The integral of the texture over the whole unit cell (i, j) of pixel space.
fn cell_mean(texture: &Texture, image: &Image, i: i64, j: i64) -> [f64; 3] {
    if texture.nearest {
        return texel(texture, image, i, j);
    }
    // Bilinear over the cell: the mean of its four corners.
    let c = [
        texel(texture, image, i, j),
        texel(texture, image, i + 1, j),
        texel(texture, image, i, j + 1),
        texel(texture, image, i + 1, j + 1),
    ];
    [0, 1, 2].map(|k| 0.25 * (c[0][k] + c[1][k] + c[2][k] + c[3][k]))
}

/// The integral of the texture over `piece`, a convex part of cell (i, j).
fn cell_integral(texture: &Texture, image: &Image, i: i64, j: i64, piece: &[DVec2]) -> [f64; 3] {
    let area = clip::signed_area(piece).abs();
    if texture.nearest {
        return texel(texture, image, i, j).map(|v| v * area);
    }
    // Degree-2 rule on each fan triangle: the mean of the values at its edge midpoints.
    let (fi, fj) = (i as f64, j as f64);
    let value = |p: DVec2| bilinear(texture, image, i, j, p.x - fi, p.y - fj);
    let mut sum = [0.0; 3];
    for k in 1..piece.len() - 1 {
        let (a, b, c) = (piece[0], piece[k], piece[k + 1]);
        let t = ((b - a).perp_dot(c - a) * 0.5).abs();
        let m = [
            value((a + b) * 0.5),
            value((b + c) * 0.5),
            value((c + a) * 0.5),
        ];
        for band in 0..3 {
            sum[band] += t * (m[0][band] + m[1][band] + m[2][band]) / 3.0;
        }
    }
    sum
}

/// The bilinear blend of texels (i, j) … (i + 1, j + 1) at fractions (s, t).
fn bilinear(texture: &Texture, image: &Image, i: i64, j: i64, s: f64, t: f64) -> [f64; 3] {
    let c00 = texel(texture, image, i, j);
    let c10 = texel(texture, image, i + 1, j);
    let c01 = texel(texture, image, i, j + 1);
    let c11 = texel(texture, image, i + 1, j + 1);
    [0, 1, 2].map(|k| {
        (1.0 - t) * ((1.0 - s) * c00[k] + s * c10[k]) + t * ((1.0 - s) * c01[k] + s * c11[k])
    })
}

/// Texel (i, j), wrapped by the sampler's modes.
fn texel(texture: &Texture, image: &Image, i: i64, j: i64) -> [f64; 3] {
    let x = wrap(i, image.width as i64, texture.wrap[0]);
    let y = wrap(j, image.height as i64, texture.wrap[1]);
    image
        .texels
        .get((y * image.width as i64 + x) as usize)
        .map_or([0.0; 3], |t| t.map(f64::from))
}

fn wrap(i: i64, n: i64, mode: Wrap) -> i64 {
    if n <= 0 {
        return 0;
    }
    match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
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

#[cfg(test)]
mod tests {
    use super::*;
    use scene::UvTriangle;

    fn square_uv(uv_scale: f64) -> PolygonUv {
        let p = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let t = |a: usize, b: usize, c: usize| UvTriangle {
            positions: [p[a], p[b], p[c]],
            uv: [[a, b, c].map(|k| DVec2::new(p[k].x, p[k].y) * uv_scale); 2],
            color: None,
        };
        PolygonUv {
            triangles: vec![t(0, 1, 2), t(0, 2, 3)],
            sets: [true; 2],
        }
    }

    fn identity(set: u32) -> TextureRef {
        TextureRef {
            texture: 0,
            tex_coord: set,
            transform: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        }
    }

    #[test]
    fn pieces_past_the_cell_cap_are_sampled_to_the_periodic_mean() {
        // The unit square mapped onto 10⁷ × 10⁷ periods of a 4 × 1 ramp (4 · 10¹⁴ cells: the
        // exact sum would not end): the sampled mean is the ramp's mean 1.5, for both
        // filters, and so is the exact one below the cap (64 × 64 periods, 16 384 cells).
        for nearest in [true, false] {
            let (texture, image) = ramp(nearest, Wrap::Repeat);
            let uv = square_uv(1e7);
            let mean = element_mean(&uv, &identity(0), &texture, &image, &corners(), DVec3::Z);
            assert!(
                mean.iter().all(|m| (m - 1.5).abs() < 0.015),
                // 0.5 % of the ramp's range 0…3.
                "nearest {nearest}: {mean:?}"
            );
            // At 10³⁰ f64 cannot tell texels apart (its spacing there is ~10¹⁴ periods): the
            // answer is some texel's value, but it comes at once and is one of the texture's.
            let uv = square_uv(1e30);
            let mean = element_mean(&uv, &identity(0), &texture, &image, &corners(), DVec3::Z);
            assert!(mean.iter().all(|m| (0.0..=3.0).contains(m)), "{mean:?}");
            // Far off the origin (a `vt 1e30 0`): no index overflows.
            let far = DVec2::new(1e30, -1e30);
            assert!(sample(&texture, &image, far)
                .iter()
                .all(|m| (0.0..=3.0).contains(m)));
            let uv = square_uv(64.0);
            let exact = element_mean(&uv, &identity(0), &texture, &image, &corners(), DVec3::Z);
            assert!(
                exact.iter().all(|m| (m - 1.5).abs() < 1e-9),
                "nearest {nearest}: {exact:?}"
            );
        }
    }

    /// The corners of [`square_uv`]'s unit square.
    fn corners() -> [DVec3; 4] {
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]
    }

    /// A 4 × 1 texture: texel x has value x.
    fn ramp(nearest: bool, wrap: Wrap) -> (Texture, Image) {
        (
            Texture {
                name: "ramp".into(),
                image: 0,
                wrap: [wrap; 2],
                nearest,
            },
            Image {
                width: 4,
                height: 1,
                texels: (0..4).map(|x| [x as f32; 3]).collect(),
                alpha: Vec::new(),
            },
        )
    }

    #[test]
    fn nearest_means_are_exact_texel_shares() {
        let (texture, image) = ramp(true, Wrap::Repeat);
        let uv = square_uv(1.0);
        // The element x ∈ [0.1, 0.6]: texel 0 over 0.15, texel 1 over 0.25, texel 2 over 0.1.
        let corners = [
            DVec3::new(0.1, 0.0, 0.0),
            DVec3::new(0.6, 0.0, 0.0),
            DVec3::new(0.6, 1.0, 0.0),
            DVec3::new(0.1, 1.0, 0.0),
        ];
        let m = element_mean(&uv, &identity(0), &texture, &image, &corners, DVec3::Z);
        let expected = (0.0 * 0.15 + 1.0 * 0.25 + 2.0 * 0.1) / 0.5;
        assert!((m[0] - expected).abs() < 1e-12, "{m:?} vs {expected}");
    }

    #[test]
    fn linear_means_integrate_the_bilinear_ramp() {
        // Clamped ramp: value(x_pixel) = clamp(x − 0.5, 0, 3) for pixel coordinate x ∈ [0, 4].
        let (texture, image) = ramp(false, Wrap::ClampToEdge);
        let uv = square_uv(1.0);
        let corners = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let m = element_mean(&uv, &identity(0), &texture, &image, &corners, DVec3::Z);
        // ∫₀⁴ clamp(x − 0.5, 0, 3) dx / 4 = (0 + 4.5 + 1.5) / 4 = 1.5.
        assert!((m[0] - 1.5).abs() < 1e-12, "{m:?}");
        // Repeating (u from 0 to 2): the same mean as one period of the wrapped ramp,
        // ∫ over a period of the periodic bilinear interpolation = mean of the texels = 1.5.
        let (texture, image) = ramp(false, Wrap::Repeat);
        let m = element_mean(
            &square_uv(2.0),
            &identity(0),
            &texture,
            &image,
            &corners,
            DVec3::Z,
        );
        assert!((m[0] - 1.5).abs() < 1e-12, "{m:?}");
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(
            [-1, 0, 3, 4, 5].map(|i| wrap(i, 4, Wrap::Repeat)),
            [3, 0, 3, 0, 1]
        );
        assert_eq!(
            [-1, 0, 3, 4].map(|i| wrap(i, 4, Wrap::ClampToEdge)),
            [0, 0, 3, 3]
        );
        assert_eq!(
            [-1, 0, 3, 4, 7, 8].map(|i| wrap(i, 4, Wrap::MirroredRepeat)),
            [0, 0, 3, 3, 0, 0]
        );
    }
}
