//! Texel reconstruction: every texel that bilinear filtering reads for some point of a chart
//! (its footprint) holds the field at the surface point the texel's centre maps to; every
//! other texel of the region copies its nearest footprint texel (the gutter).

use crate::chart::Region;
use crate::field::{cross, Field};
use crate::Texel;
use glam::DVec2;

/// Gutter texels further than this (texels) from every footprint texel of their region stay
/// unused: only the empty half of a lone triangle's rectangle is that far, and no filter
/// reaches it.
pub const DILATION_RADIUS: i64 = 8;

/// One region's texels, row-major over the region.
pub(crate) struct RegionTexels {
    pub(crate) values: Vec<[f32; 3]>,
    pub(crate) coverage: Vec<Texel>,
}

/// Whether the closed square of half-side 1 around `c` meets the convex polygon `uv`: the
/// texel at `c` is read by bilinear filtering for some point of the polygon.
pub(crate) fn in_footprint(c: DVec2, uv: &[DVec2]) -> bool {
    meets_square(c, 1.0, uv)
}

/// Whether the closed square of half-side `half` around `c` meets the convex polygon `uv`.
pub(crate) fn meets_square(c: DVec2, half: f64, uv: &[DVec2]) -> bool {
    let (lo, hi) = uv.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    if lo.x > c.x + half || hi.x < c.x - half || lo.y > c.y + half || hi.y < c.y - half {
        return false;
    }
    // Separating axes: the polygon's edge normals.
    for k in 0..uv.len() {
        let edge = uv[(k + 1) % uv.len()] - uv[k];
        let normal = DVec2::new(-edge.y, edge.x);
        let (min, max) = uv
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                let d = p.dot(normal);
                (a.min(d), b.max(d))
            });
        let centre = c.dot(normal);
        let reach = half * (normal.x.abs() + normal.y.abs());
        if centre - reach > max + 1e-9 * reach || centre + reach < min - 1e-9 * reach {
            return false;
        }
    }
    true
}

/// Whether `c` lies in the closed convex polygon `uv` (either winding).
pub(crate) fn inside(c: DVec2, uv: &[DVec2]) -> bool {
    let n = uv.len();
    let sides: Vec<f64> = (0..n)
        .map(|k| cross(uv[(k + 1) % n] - uv[k], c - uv[k]))
        .collect();
    sides.iter().all(|&s| s >= 0.0) || sides.iter().all(|&s| s <= 0.0)
}

/// What a chart's texels are reconstructed from ([`crate::Shading`]).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Source<'a> {
    /// Smoothed, welded values per mesh vertex, interpolated over the element grid.
    Smooth(&'a [[f64; 3]]),
    /// Each element's own value; `first[p]` is polygon p's first element.
    Flat {
        elements: &'a [[f64; 3]],
        first: &'a [u32],
    },
}

impl Source<'_> {
    /// The value at plane point `q` of polygon `polygon` (its field `field`).
    pub(crate) fn at(&self, polygon: usize, field: &Field, q: DVec2) -> [f64; 3] {
        match *self {
            Source::Smooth(values) => field.value_at(q, values),
            Source::Flat { elements, first } => {
                let local = field.element_at_params(field.params(q));
                elements[(first[polygon] + local) as usize]
            }
        }
    }

    /// [`Source::at`] for a point `q` inside the polygon, bounded: the smooth field never
    /// leaves the range of the vertex values it interpolates ([`Field::value_within`]).
    pub(crate) fn at_within(&self, polygon: usize, field: &Field, q: DVec2) -> [f64; 3] {
        match *self {
            Source::Smooth(values) => field.value_within(q, values),
            Source::Flat { .. } => self.at(polygon, field, q),
        }
    }
}

/// Barycentric weights of the point of triangle (a, b, d) nearest to `c` (all in [0, 1],
/// summing to 1; distances in texel space, where texels are square), and that distance
/// squared. A degenerate triangle gives its first corner's weights when nothing better is
/// defined.
fn nearest_in_triangle(c: DVec2, a: DVec2, b: DVec2, d: DVec2) -> ([f64; 3], f64) {
    // Ericson, Real-Time Collision Detection, 5.1.5, in 2D.
    let (ab, ad, ac) = (b - a, d - a, c - a);
    let at = |w: [f64; 3]| {
        let p = a * w[0] + b * w[1] + d * w[2];
        (w, p.distance_squared(c))
    };
    let (d1, d2) = (ab.dot(ac), ad.dot(ac));
    if d1 <= 0.0 && d2 <= 0.0 {
        return at([1.0, 0.0, 0.0]);
    }
    let bc = c - b;
    let (d3, d4) = (ab.dot(bc), ad.dot(bc));
    if d3 >= 0.0 && d4 <= d3 {
        return at([0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return at([1.0 - t, t, 0.0]);
    }
    let dc = c - d;
    let (d5, d6) = (ab.dot(dc), ad.dot(dc));
    if d6 >= 0.0 && d5 <= d6 {
        return at([0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return at([1.0 - t, 0.0, t]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return at([0.0, 1.0 - t, t]);
    }
    let sum = va + vb + vc;
    let (v, w) = (vb / sum, vc / sum);
    if !(v.is_finite() && w.is_finite()) {
        return at([1.0, 0.0, 0.0]);
    }
    at([1.0 - v - w, v, w])
}

/// The field at texel-space point `c` of a chart: through the glTF triangles (v0 v1 v2) and
/// (v0 v2 v3) — the ones a renderer interpolates TEXCOORD_1 over — to the surface point, then
/// the grid. A point outside the chart (a footprint texel's centre past the edge) takes the
/// chart's nearest point: nothing is extrapolated, so a sliver's texels hold values of the
/// sliver's own edge and every texel lies within the range of the element values around
/// the point it reads ([`Field::value_within`]). Clamped to ≥ 0.
pub(crate) fn chart_value(
    c: DVec2,
    uv: &[DVec2],
    polygon: usize,
    fields: &[Field],
    source: Source,
) -> [f64; 3] {
    let field = &fields[polygon];
    let w = chart_weights(c, uv);
    let point = field
        .corners
        .iter()
        .zip(w)
        .fold(DVec2::ZERO, |sum, (&corner, w)| sum + corner * w);
    source.at_within(polygon, field, point).map(|v| v.max(0.0))
}

/// The weights of a chart's corners (3 or 4; a triangle's fourth is 0) at the chart point
/// nearest texel-space point `c`, through the glTF triangles (v0 v1 v2) and (v0 v2 v3): the
/// same corner weights give the surface point, in any space the polygon's corners are in.
pub(crate) fn chart_weights(c: DVec2, uv: &[DVec2]) -> [f64; 4] {
    let (first, d1) = nearest_in_triangle(c, uv[0], uv[1], uv[2]);
    if uv.len() == 4 {
        let (second, d2) = nearest_in_triangle(c, uv[0], uv[2], uv[3]);
        if d2 < d1 {
            return [second[0], 0.0, second[1], second[2]];
        }
    }
    [first[0], first[1], first[2], 0.0]
}

/// Reconstructs one region: footprints first, then the gutter by nearest footprint texel
/// (squared distance between centres; ties go to the first in row-major order).
pub(crate) fn region_texels(region: &Region, fields: &[Field], source: Source) -> RegionTexels {
    let (w, h) = (region.width as usize, region.height as usize);
    let mut out = RegionTexels {
        values: vec![[0.0; 3]; w * h],
        coverage: vec![Texel::Unused; w * h],
    };
    for y in 0..h {
        for x in 0..w {
            let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            for (polygon, uv) in &region.charts {
                if in_footprint(c, uv) {
                    let v = chart_value(c, uv, *polygon, fields, source);
                    out.values[y * w + x] = v.map(|v| v as f32);
                    out.coverage[y * w + x] = Texel::Chart(*polygon as u32);
                    break;
                }
            }
        }
    }
    let footprint: Vec<bool> = out
        .coverage
        .iter()
        .map(|t| matches!(t, Texel::Chart(_)))
        .collect();
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            if footprint[y as usize * w + x as usize] {
                continue;
            }
            let mut best: Option<(i64, usize)> = None;
            for dy in -DILATION_RADIUS..=DILATION_RADIUS {
                let sy = y + dy;
                if sy < 0 || sy >= h as i64 {
                    continue;
                }
                for dx in -DILATION_RADIUS..=DILATION_RADIUS {
                    let sx = x + dx;
                    if sx < 0 || sx >= w as i64 {
                        continue;
                    }
                    let k = sy as usize * w + sx as usize;
                    let d = dx * dx + dy * dy;
                    if footprint[k] && best.is_none_or(|(bd, bk)| (d, k) < (bd, bk)) {
                        best = Some((d, k));
                    }
                }
            }
            if let Some((_, k)) = best {
                let here = y as usize * w + x as usize;
                out.values[here] = out.values[k];
                if let Texel::Chart(p) = out.coverage[k] {
                    out.coverage[here] = Texel::Gutter(p);
                }
            }
        }
    }
    out
}

/// Reconstructs a whole atlas laid out by per-polygon charts (texel space; authored, or
/// grouped charts), which may share texels with their neighbours in one island or chart: a footprint texel belongs to
/// the chart nearest its centre (0 inside; ties to the lower polygon), the gutter grows from
/// the footprints in [`DILATION_RADIUS`] rings, each texel taking the nearest footprint
/// texel among its 8 neighbours' sources (ties to the lower index).
pub(crate) fn atlas_texels(
    width: u32,
    height: u32,
    charts: &[Vec<DVec2>],
    fields: &[Field],
    source: Source,
    ownership: Option<(&[u32], &[u32])>,
) -> RegionTexels {
    use rayon::prelude::*;
    let (n, rows) = (width as usize, height as usize);
    // The region owning texel k's block, and polygon p's region (both 0 without ownership).
    let owner =
        |k: usize| ownership.map_or(0, |(blocks, _)| blocks[(k / n / 2) * (n / 2) + (k % n) / 2]);
    let region = |p: u32| ownership.map_or(0, |(_, item_of)| item_of[p as usize]);
    let mut claim: Vec<(f64, u32)> = vec![(f64::INFINITY, u32::MAX); n * rows];
    for (p, uv) in charts.iter().enumerate() {
        if uv.is_empty() {
            continue; // in another atlas
        }
        let (lo, hi) = uv.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), q| (lo.min(*q), hi.max(*q)),
        );
        let range = |a: f64, b: f64, n: usize| {
            let first = (a - 1.5).floor().max(0.0) as usize;
            let last = ((b + 1.5).ceil().max(0.0) as usize).min(n);
            first..last
        };
        for y in range(lo.y, hi.y, rows) {
            for x in range(lo.x, hi.x, n) {
                let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                if !in_footprint(c, uv) || owner(y * n + x) != region(p as u32) {
                    continue;
                }
                let d = crate::authored::polygon_distance(c, uv);
                let slot = &mut claim[y * n + x];
                if (d, p as u32) < *slot {
                    *slot = (d, p as u32);
                }
            }
        }
    }
    let mut out = RegionTexels {
        values: vec![[0.0; 3]; n * rows],
        coverage: vec![Texel::Unused; n * rows],
    };
    out.values
        .par_chunks_mut(n)
        .zip(out.coverage.par_chunks_mut(n))
        .enumerate()
        .for_each(|(y, (row, cover))| {
            for x in 0..n {
                let (_, p) = claim[y * n + x];
                if p == u32::MAX {
                    continue;
                }
                let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let v = chart_value(c, &charts[p as usize], p as usize, fields, source);
                row[x] = v.map(|v| v as f32);
                cover[x] = Texel::Chart(p);
            }
        });
    // The gutter, ring by ring: `source` is the footprint texel a texel copies.
    let mut source: Vec<u32> = claim
        .iter()
        .enumerate()
        .map(|(k, c)| if c.1 == u32::MAX { u32::MAX } else { k as u32 })
        .collect();
    for _ in 0..DILATION_RADIUS {
        let next: Vec<u32> = (0..n * rows)
            .into_par_iter()
            .map(|k| {
                if source[k] != u32::MAX {
                    return source[k];
                }
                let (x, y) = ((k % n) as i64, (k / n) as i64);
                let mine = owner(k);
                let mut best: Option<(i64, u32)> = None;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (sx, sy) = (x + dx, y + dy);
                        if sx < 0 || sy < 0 || sx >= n as i64 || sy >= rows as i64 {
                            continue;
                        }
                        let s = source[sy as usize * n + sx as usize];
                        if s == u32::MAX || region(claim[s as usize].1) != mine {
                            continue;
                        }
                        let (fx, fy) = ((s as usize % n) as i64, (s as usize / n) as i64);
                        let d = (fx - x).pow(2) + (fy - y).pow(2);
                        if best.is_none_or(|b| (d, s) < b) {
                            best = Some((d, s));
                        }
                    }
                }
                best.map_or(u32::MAX, |b| b.1)
            })
            .collect();
        source = next;
    }
    for (k, &s) in source.iter().enumerate() {
        if s == u32::MAX || claim[k].1 != u32::MAX {
            continue;
        }
        out.values[k] = out.values[s as usize];
        out.coverage[k] = Texel::Gutter(claim[s as usize].1);
    }
    out
}
