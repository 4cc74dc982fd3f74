//! The rasterizer: near-plane clipping, back-face culling, edge functions with a tie rule (no
//! pixel drawn twice or missed along a shared edge), a z-buffer, and perspective-correct
//! interpolation of vertex colours. Everything in f64, one sample at each pixel centre,
//! triangles in file order: the same input gives the same pixels on every machine.

use crate::camera::Camera;
use crate::math::Vec3;
use crate::scene::{Lightmap, Scene};
use crate::texture::Texture;

/// A rendered image: linear RGB per pixel, row by row from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
    /// View-space depth per pixel (`f64::INFINITY` where nothing was drawn).
    pub depth: Vec<f64>,
}

/// What [`render`] drew.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Triangles that covered at least one pixel centre (visible or not).
    pub rasterized: usize,
    /// Single-sided triangles seen from the back.
    pub culled: usize,
    /// Triangles wholly nearer than the near plane, or of zero area on screen.
    pub discarded: usize,
}

/// A vertex in view space with its colour.
#[derive(Clone, Copy, Debug)]
struct ClipVertex {
    view: Vec3,
    color: Vec3,
    uv: [f64; 2],
    uv1: [f64; 2],
}

/// Renders `scene` through `camera` into a `width` × `height` frame over `background`
/// (linear RGB).
pub fn render(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    background: Vec3,
) -> (Frame, RenderStats) {
    let count = width as usize * height as usize;
    let mut frame = Frame {
        width,
        height,
        pixels: vec![background; count],
        depth: vec![f64::INFINITY; count],
    };
    let mut stats = RenderStats::default();
    for triangle in &scene.triangles {
        let corners = triangle.vertices.map(|v| ClipVertex {
            view: camera.to_view(v.position),
            color: v.color,
            uv: v.uv,
            uv1: v.uv1,
        });
        let shade = Shade {
            texture: triangle.texture.and_then(|k| scene.textures.get(k)),
            lightmap: triangle.lightmap.and_then(|k| scene.lightmaps.get(k)),
            emissive: triangle.emissive,
        };
        let polygon = clip_near(&corners, camera.znear);
        if polygon.len() < 3 {
            stats.discarded += 1;
            continue;
        }
        let screen: Vec<Projected> = polygon
            .iter()
            .map(|v| Projected {
                pixel: camera.view_to_pixel(v.view, width, height),
                inverse_depth: 1.0 / v.view[2],
                color: v.color,
                uv: v.uv,
                uv1: v.uv1,
            })
            .collect();
        // The clipped polygon is convex and keeps the triangle's orientation: its signed area
        // decides the facing. Counter-clockwise on screen with y up is clockwise with y down,
        // i.e. a negative `area` here is the front.
        let area = polygon_area(&screen);
        if area == 0.0 || !area.is_finite() {
            stats.discarded += 1;
            continue;
        }
        if area > 0.0 && !triangle.double_sided {
            stats.culled += 1;
            continue;
        }
        let mut covered = false;
        for k in 1..screen.len() - 1 {
            covered |= draw(&mut frame, [screen[0], screen[k], screen[k + 1]], &shade);
        }
        stats.rasterized += usize::from(covered);
    }
    (frame, stats)
}

/// A vertex on screen: pixel position, 1/z and colour.
#[derive(Clone, Copy, Debug)]
struct Projected {
    pixel: [f64; 2],
    inverse_depth: f64,
    color: Vec3,
    uv: [f64; 2],
    uv1: [f64; 2],
}

/// What a triangle's pixels show besides its interpolated colour.
struct Shade<'a> {
    /// The base-colour texture at `uv`.
    texture: Option<&'a Texture>,
    /// A lightmap at `uv1` (× its intensity), `emissive` added, the sum clamped to [0, 1].
    lightmap: Option<&'a Lightmap>,
    emissive: Vec3,
}

/// Sutherland–Hodgman against the plane z = `znear`: the part of the triangle at z ≥ `znear`
/// (0, 3 or 4 vertices, in the triangle's order).
fn clip_near(corners: &[ClipVertex; 3], znear: f64) -> Vec<ClipVertex> {
    let inside = |v: &ClipVertex| v.view[2] >= znear;
    if corners.iter().all(inside) {
        return corners.to_vec();
    }
    let mut out = Vec::with_capacity(4);
    for k in 0..3 {
        let a = corners[k];
        let b = corners[(k + 1) % 3];
        if inside(&a) {
            out.push(a);
        }
        if inside(&a) != inside(&b) {
            let t = (znear - a.view[2]) / (b.view[2] - a.view[2]);
            let lerp =
                |x: Vec3, y: Vec3| -> Vec3 { std::array::from_fn(|i| x[i] + t * (y[i] - x[i])) };
            let mut view = lerp(a.view, b.view);
            view[2] = znear;
            out.push(ClipVertex {
                view,
                color: lerp(a.color, b.color),
                uv: std::array::from_fn(|i| a.uv[i] + t * (b.uv[i] - a.uv[i])),
                uv1: std::array::from_fn(|i| a.uv1[i] + t * (b.uv1[i] - a.uv1[i])),
            });
        }
    }
    out
}

/// Twice the signed area of a screen polygon (pixel coordinates, y down).
fn polygon_area(points: &[Projected]) -> f64 {
    let n = points.len();
    (0..n)
        .map(|k| {
            let a = points[k].pixel;
            let b = points[(k + 1) % n].pixel;
            a[0] * b[1] - b[0] * a[1]
        })
        .sum()
}

/// `(b − a) × (p − a)`: positive when `p` is on the left of a → b (pixel coordinates).
///
/// Computed from the lesser endpoint (lexicographically) and negated when the edge runs the
/// other way, so the two triangles that share an edge get exactly opposite values at every
/// sample (in floating point too) and the tie rule of [`owns_edge`] leaves no gaps.
fn edge(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    let cross =
        |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    if (a[0], a[1]) <= (b[0], b[1]) {
        cross(a, b)
    } else {
        -cross(b, a)
    }
}

/// Whether a sample exactly on edge a → b belongs to this triangle. Two triangles sharing an
/// edge (with the same orientation) run along it in opposite directions, so exactly one of
/// them takes the samples on it.
fn owns_edge(a: [f64; 2], b: [f64; 2]) -> bool {
    let dx = b[0] - a[0];
    let dy = b[1] - a[1];
    dy > 0.0 || (dy == 0.0 && dx < 0.0)
}

/// Rasterizes one triangle with depth test, its colour times the texture at the interpolated
/// UV (and under a lightmap, times H at UV1 plus the emission, clamped); returns whether it
/// covered any pixel centre.
fn draw(frame: &mut Frame, mut t: [Projected; 3], shade: &Shade) -> bool {
    let mut area = edge(t[0].pixel, t[1].pixel, t[2].pixel);
    if area < 0.0 {
        t.swap(1, 2);
        area = -area;
    }
    if area <= 0.0 || !area.is_finite() {
        return false;
    }
    let (w, h) = (f64::from(frame.width), f64::from(frame.height));
    let min_x = t.iter().map(|v| v.pixel[0]).fold(f64::INFINITY, f64::min);
    let max_x = t
        .iter()
        .map(|v| v.pixel[0])
        .fold(f64::NEG_INFINITY, f64::max);
    let min_y = t.iter().map(|v| v.pixel[1]).fold(f64::INFINITY, f64::min);
    let max_y = t
        .iter()
        .map(|v| v.pixel[1])
        .fold(f64::NEG_INFINITY, f64::max);
    // Pixel i's centre is i + 0.5: the columns whose centres may be inside.
    let x0 = (min_x - 0.5).ceil().clamp(0.0, w) as usize;
    let x1 = ((max_x - 0.5).floor() + 1.0).clamp(0.0, w) as usize;
    let y0 = (min_y - 0.5).ceil().clamp(0.0, h) as usize;
    let y1 = ((max_y - 0.5).floor() + 1.0).clamp(0.0, h) as usize;
    let edges = [(1, 2), (2, 0), (0, 1)];
    let owned = edges.map(|(a, b)| owns_edge(t[a].pixel, t[b].pixel));
    let mut covered = false;
    for y in y0..y1 {
        for x in x0..x1 {
            let p = [x as f64 + 0.5, y as f64 + 0.5];
            let mut weights = [0.0; 3];
            let mut inside = true;
            for (k, &(a, b)) in edges.iter().enumerate() {
                let e = edge(t[a].pixel, t[b].pixel, p);
                if e < 0.0 || (e == 0.0 && !owned[k]) {
                    inside = false;
                    break;
                }
                weights[k] = e / area;
            }
            if !inside {
                continue;
            }
            covered = true;
            // Perspective-correct: 1/z and colour/z are affine on screen.
            let inverse_depth: f64 = (0..3).map(|k| weights[k] * t[k].inverse_depth).sum();
            let depth = 1.0 / inverse_depth;
            let index = y * frame.width as usize + x;
            if depth.is_nan() || depth >= frame.depth[index] {
                continue;
            }
            frame.depth[index] = depth;
            let interpolate = |value: &dyn Fn(&Projected) -> f64| {
                (0..3)
                    .map(|k| weights[k] * t[k].inverse_depth * value(&t[k]))
                    .sum::<f64>()
                    * depth
            };
            let texel = match shade.texture {
                Some(texture) => {
                    texture.sample([interpolate(&|v| v.uv[0]), interpolate(&|v| v.uv[1])])
                }
                None => [1.0; 3],
            };
            let color: Vec3 =
                std::array::from_fn(|band| interpolate(&|v| v.color[band]) * texel[band]);
            frame.pixels[index] = match shade.lightmap {
                Some(lightmap) => {
                    let uv1 = [interpolate(&|v| v.uv1[0]), interpolate(&|v| v.uv1[1])];
                    let h = lightmap.texture.sample(uv1);
                    std::array::from_fn(|band| {
                        (color[band] * h[band] * lightmap.intensity + shade.emissive[band])
                            .clamp(0.0, 1.0)
                    })
                }
                None => color,
            };
        }
    }
    covered
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value, clamped to [0, 1].
pub fn srgb_encode(linear: f64) -> f64 {
    let c = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// A linear value as an 8-bit sRGB code (rounded to nearest).
pub fn srgb8(linear: f64) -> u8 {
    (srgb_encode(linear) * 255.0).round() as u8
}
