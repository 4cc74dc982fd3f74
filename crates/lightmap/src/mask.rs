//! A region's shape in 2×2 texel blocks (the first mip level's texels): the blocks whose
//! centre lies within [`REACH`] texels of one of its polygons. Every texel that bilinear
//! filtering reads for a point of the polygon, at full resolution and at the first mip
//! level, lies in those blocks; a region owns its blocks (its gutter is filled from its own
//! charts only, `raster::atlas_texels`), so regions whose masks share no block never read
//! each other's texels, and the packer ([`crate::pack::pack_masks`]) may fit one into the
//! corners of another's bounding rectangle.

use glam::DVec2;

/// A block is the region's when its centre lies within this Chebyshev distance (texels) of
/// one of its polygons. A mip-1 bilinear read at a point p averages the four blocks whose
/// centres lie within 2 texels of p on each axis (the mip-1 texels around p / 2); a
/// full-resolution read takes texels whose centres lie within 1 of p, whose blocks' centres
/// lie within 1.5. So every block read for a point of a polygon is within 2 of it.
pub(crate) const REACH: f64 = 2.0;
/// Texels added to [`REACH`] so that rounding never leaves out a block at the reach.
const SLACK: f64 = 1e-6;

/// Blocks a region needs, as per-column extents (a region's mask is what its polygons'
/// blocks cover; the packer keeps columns whole between their lowest and highest block, so
/// a mask is its columns' spans).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Mask {
    /// Width and height in blocks.
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// Per column: the first block used and one past the last (`(0, 0)`: none).
    pub(crate) columns: Vec<(u32, u32)>,
}

impl Mask {
    /// Blocks inside the column spans.
    pub(crate) fn blocks(&self) -> u64 {
        self.columns.iter().map(|&(a, b)| u64::from(b - a)).sum()
    }
}

/// The mask of a `width` × `height`-texel region (even sides) holding `charts` (texel
/// coordinates relative to the region's corner, at least [`crate::PADDING`] texels inside it).
pub(crate) fn mask(width: u32, height: u32, charts: &[(usize, Vec<DVec2>)]) -> Mask {
    let (w, h) = (width / 2, height / 2);
    let mut columns = vec![(u32::MAX, 0u32); w as usize];
    // A hair more: the packed charts' coordinates are these plus the region's corner,
    // rounded again, and a block at exactly the reach must stay in.
    let half = REACH + SLACK;
    // Blocks whose square of half-side `half` around their centre (2b + 1) meets a box.
    let first = |a: f64| (((a - half - 1.0) / 2.0).floor().max(0.0)) as u32;
    let last = |b: f64, n: u32| ((((b + half - 1.0) / 2.0).ceil().max(0.0)) as u32).min(n - 1);
    for (_, uv) in charts.iter().filter(|_| w > 0 && h > 0) {
        let (lo, hi) = uv.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        for bx in first(lo.x)..=last(hi.x, w) {
            let column = &mut columns[bx as usize];
            for by in first(lo.y)..=last(hi.y, h) {
                let c = DVec2::new(2.0 * f64::from(bx) + 1.0, 2.0 * f64::from(by) + 1.0);
                if crate::raster::meets_square(c, half, uv) {
                    column.0 = column.0.min(by);
                    column.1 = column.1.max(by + 1);
                }
            }
        }
    }
    for c in &mut columns {
        if c.0 == u32::MAX {
            *c = (0, 0);
        }
    }
    // Trimmed to the last column and row used.
    let width = columns.iter().rposition(|c| c.1 > c.0).map_or(0, |k| k + 1);
    columns.truncate(width);
    Mask {
        width: width as u32,
        height: columns.iter().map(|c| c.1).max().unwrap_or(0),
        columns,
    }
}
