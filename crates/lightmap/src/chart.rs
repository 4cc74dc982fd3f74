//! Charts: every polygon is laid out flat in texel space. A quad becomes a rectangle with its
//! true aspect (edge lengths rounded up to whole texels); a triangle becomes a right triangle
//! of the same area with its longest edge kept, so two similar triangles share one rectangle
//! (the second turned half a turn, [`PAIR_GAP`] texels away along the diagonal).
//!
//! Each chart sits in a region (the rectangle the packer places) with [`PADDING`] texels
//! around its polygon; region sizes are even so that regions start on even texels and every
//! 2×2 block of the first mip level belongs to one region.

use glam::{DVec2, DVec3};
use scene::Polygon;

/// Texels between a polygon's bounding box and its region's edge: bilinear filtering at the
/// first mip level reads level-0 texels up to 2.5 texels outside the polygon.
pub const PADDING: u32 = 3;
/// Chebyshev distance, in texels, between the two triangles that share a region: each reads
/// up to 2.5 texels beyond itself at mip 1 and the texels between them must be nearer to the
/// one they serve.
pub const PAIR_GAP: u32 = 8;

/// Charts that the packer places as one rectangle.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Region {
    /// Even sizes, in texels.
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// (polygon, its vertices' texel coordinates relative to the region's corner).
    pub(crate) charts: Vec<(usize, Vec<DVec2>)>,
}

/// Whole texels for a length in texels (at least 1), or `None` when it does not fit in u32.
fn texels(length: f64) -> Option<u32> {
    let n = (length - 1e-9).ceil().max(1.0);
    (n.is_finite() && n <= f64::from(u32::MAX / 4)).then_some(n as u32)
}

fn even(n: u32) -> u32 {
    n + n % 2
}

/// The height etagere gives the shelf of a `height`-texel region: it rounds shelf heights
/// (in its units, 2-texel blocks here) up to multiples of 8, 16, 32 or 64 blocks by size.
/// Charts are stretched to fill that height, so the rounding buys texels instead of waste.
fn shelf_height(height: u32) -> u32 {
    let blocks = even(height) / 2;
    let alignment = match blocks {
        0..=31 => 8,
        32..=127 => 16,
        128..=511 => 32,
        _ => 64,
    };
    2 * blocks.div_ceil(alignment) * alignment
}

/// The regions for `polygons` at `texels_per_unit`; `None` when a chart would not fit in u32.
pub(crate) fn layout(polygons: &[Polygon], texels_per_unit: f64) -> Option<Vec<Region>> {
    let mut regions = Vec::new();
    let mut triangles = Vec::new();
    for (index, polygon) in polygons.iter().enumerate() {
        let v = &polygon.vertices;
        if v.len() == 4 {
            regions.push(quad_region(index, v, texels_per_unit)?);
        } else {
            triangles.push(Triangle::new(index, v, texels_per_unit)?);
        }
    }
    // Similar triangles next to each other; pair neighbours when that saves texels.
    triangles.sort_by_key(|t| {
        (
            std::cmp::Reverse(t.height),
            std::cmp::Reverse(t.base),
            t.polygon,
        )
    });
    let mut k = 0;
    while k < triangles.len() {
        let first = &triangles[k];
        if let Some(second) = triangles.get(k + 1) {
            let pair = pair_region(first, second);
            let alone = |t: &Triangle| {
                let r = lone_region(t);
                u64::from(r.width) * u64::from(r.height)
            };
            let pair_area = u64::from(pair.width) * u64::from(pair.height);
            if pair_area < alone(first) + alone(second) {
                regions.push(pair);
                k += 2;
                continue;
            }
        }
        regions.push(lone_region(first));
        k += 1;
    }
    Some(regions)
}

/// A quad as a w × h rectangle, w and h its longer opposite edges (the mesher's element
/// directions), turned so the longer side runs along x.
fn quad_region(index: usize, v: &[DVec3], texels_per_unit: f64) -> Option<Region> {
    let mut w = texels(v[0].distance(v[1]).max(v[3].distance(v[2])) * texels_per_unit)?;
    let mut h = texels(v[0].distance(v[3]).max(v[1].distance(v[2])) * texels_per_unit)?;
    // The shorter side runs along y: stretch it to fill its shelf.
    if w >= h {
        h = shelf_height(h + 2 * PADDING) - 2 * PADDING;
    } else {
        w = shelf_height(w + 2 * PADDING) - 2 * PADDING;
    }
    let p = f64::from(PADDING);
    let (fw, fh) = (f64::from(w), f64::from(h));
    let uv = if w >= h {
        vec![
            DVec2::new(p, p),
            DVec2::new(p + fw, p),
            DVec2::new(p + fw, p + fh),
            DVec2::new(p, p + fh),
        ]
    } else {
        // Mirrored along the diagonal: (s, t) → (t, s). Lightmap UVs carry no handedness.
        vec![
            DVec2::new(p, p),
            DVec2::new(p, p + fw),
            DVec2::new(p + fh, p + fw),
            DVec2::new(p + fh, p),
        ]
    };
    Some(Region {
        width: even(w.max(h) + 2 * PADDING),
        height: even(w.min(h) + 2 * PADDING),
        charts: vec![(index, uv)],
    })
}

/// A triangle laid out as a right triangle: the longest edge (from vertex `first`) along x
/// with its true length, the opposite vertex straight above the first at the triangle's
/// height, so the area is kept.
struct Triangle {
    polygon: usize,
    /// Index of the vertex where the longest edge starts.
    first: usize,
    /// Texels along x (the longest edge) and y (the height onto it).
    base: u32,
    height: u32,
}

impl Triangle {
    fn new(polygon: usize, v: &[DVec3], texels_per_unit: f64) -> Option<Triangle> {
        let lengths: Vec<f64> = (0..3).map(|k| v[k].distance(v[(k + 1) % 3])).collect();
        let mut first = 0;
        for k in 1..3 {
            if lengths[k] > lengths[first] {
                first = k;
            }
        }
        let area2 = (v[1] - v[0]).cross(v[2] - v[0]).length();
        let base = lengths[first];
        Some(Triangle {
            polygon,
            first,
            base: texels(base * texels_per_unit)?,
            height: texels(area2 / base * texels_per_unit)?,
        })
    }

    /// Texel coordinates of the polygon's vertices, in polygon order, given where the right
    /// angle, the end of the base and the apex go.
    fn uv(&self, corner: DVec2, base_end: DVec2, apex: DVec2) -> Vec<DVec2> {
        let mut uv = vec![DVec2::ZERO; 3];
        uv[self.first] = corner;
        uv[(self.first + 1) % 3] = base_end;
        uv[(self.first + 2) % 3] = apex;
        uv
    }
}

fn lone_region(t: &Triangle) -> Region {
    let p = f64::from(PADDING);
    let height = shelf_height(t.height + 2 * PADDING);
    let (b, h) = (f64::from(t.base), f64::from(height - 2 * PADDING));
    Region {
        width: even(t.base + 2 * PADDING),
        height,
        charts: vec![(
            t.polygon,
            t.uv(DVec2::new(p, p), DVec2::new(p + b, p), DVec2::new(p, p + h)),
        )],
    }
}

/// Two triangles in one rectangle: the first's right angle at the top-left, the second's at
/// the bottom-right, their hypotenuses parallel and [`PAIR_GAP`] texels apart (Chebyshev).
fn pair_region(first: &Triangle, second: &Triangle) -> Region {
    let w = first.base.max(second.base);
    let height = shelf_height(first.height.max(second.height) + PAIR_GAP + 2 * PADDING);
    let h = height - PAIR_GAP - 2 * PADDING;
    let (p, g) = (f64::from(PADDING), f64::from(PAIR_GAP));
    let (fw, fh) = (f64::from(w), f64::from(h));
    let one = first.uv(
        DVec2::new(p, p),
        DVec2::new(p + fw, p),
        DVec2::new(p, p + fh),
    );
    let far = DVec2::new(p + g + fw, p + g + fh);
    let two = second.uv(
        far,
        DVec2::new(p + g, p + g + fh),
        DVec2::new(p + g + fw, p + g),
    );
    Region {
        width: even(w + PAIR_GAP + 2 * PADDING),
        height,
        charts: vec![(first.polygon, one), (second.polygon, two)],
    }
}
