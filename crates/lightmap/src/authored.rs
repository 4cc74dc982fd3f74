//! Authored lightmap UVs: the input's `TEXCOORD_1` kept as the chart layout
//! (`--lightmap-uv keep`, or `auto` when it is usable).
//!
//! A layout is usable when every polygon of every baked primitive instance has a
//! `TEXCOORD_1` inside [0, 1], continuous over the polygon (no seam across a merged quad),
//! with area on every triangle the outputs are drawn with (v0 vk vk+1), no material samples
//! it as a texture set, and no two such triangles overlap — within a primitive or across
//! primitives, since one atlas holds one layout (two instances of one mesh, or the two sides
//! of a double-sided face, would share texels). Touching is allowed: overlaps count above
//! 1e-6 of the smaller triangle's area (f32 rounding of shared edges is far below that).
//! When the whole layout is not usable, each primitive instance is judged on its own (its
//! own problems, overlaps within it): `keep` then gives each an atlas of its own when all
//! pass (exact TEXCOORD_1), `auto` a region of its own for those that pass (TEXCOORD_1
//! scaled and moved) and generated charts for the rest.
//!
//! The atlas is square, N texels a side, N from the texel size over the UV area:
//! `N = sqrt(world area / UV area) / texel size`, rounded up to even, at least 16, at most
//! the atlas limit (the texel size then grows, as for generated charts). Padding is the
//! distance between islands (triangles connected through shared TEXCOORD_1 vertices, equal
//! bit for bit); under [`MIN_PADDING`] texels gives a warning, since filtering then mixes
//! islands.

use crate::LightmapError;
use glam::DVec2;
use rayon::prelude::*;
use scene::{Polygon, Scene, Side};
use std::collections::{BTreeMap, HashMap};

/// Padding between authored islands (texels) below which the bake warns.
pub const MIN_PADDING: f64 = 2.0;

/// Where the lightmap's charts come from (`--lightmap-uv`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum UvMode {
    /// The input's `TEXCOORD_1` where the whole scene's is a usable layout; otherwise per
    /// primitive instance: one whose own `TEXCOORD_1` is usable (in [0, 1], no overlaps
    /// within it, not sampled by its material, one-sided) keeps its layout in its own atlas
    /// region (its `TEXCOORD_1` scaled and moved: an affine map of the input's), the others
    /// get generated charts. The decision per primitive is in
    /// [`crate::Lightmap::uv_decisions`].
    #[cfg_attr(
        feature = "clap",
        value(
            help = "The input's TEXCOORD_1 where usable (as a whole, else per primitive), generated charts elsewhere"
        )
    )]
    #[default]
    Auto,
    /// The input's `TEXCOORD_1` as it is, for the whole scene: one atlas when it is one
    /// usable layout; when primitives overlap each other but each one's own layout is usable,
    /// an atlas per primitive (at most `Options::max_atlases`), each primitive's
    /// `TEXCOORD_1` unchanged; an error otherwise.
    #[cfg_attr(
        feature = "clap",
        value(help = "The input's TEXCOORD_1 unchanged; an error where it is unusable")
    )]
    Keep,
    /// Charts made by the lightmap (one per polygon).
    Generate,
}

/// The input's `TEXCOORD_1` at every polygon vertex, or why a polygon has none usable.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AuthoredUv {
    /// Per polygon, in polygon order.
    pub polygons: Vec<Result<Vec<DVec2>, String>>,
}

impl AuthoredUv {
    /// No authored UVs at all (every polygon: no `TEXCOORD_1`).
    pub fn none(polygons: usize) -> AuthoredUv {
        AuthoredUv {
            polygons: vec![Err("no TEXCOORD_1".into()); polygons],
        }
    }

    /// Reads each polygon's `TEXCOORD_1` from the importer's source triangles.
    pub fn from_scene(scene: &Scene) -> AuthoredUv {
        let polygons = scene
            .polygons
            .iter()
            .enumerate()
            .map(|(k, polygon)| polygon_uv(scene, k, polygon))
            .collect();
        AuthoredUv { polygons }
    }
}

fn polygon_uv(scene: &Scene, k: usize, polygon: &Polygon) -> Result<Vec<DVec2>, String> {
    let material = scene.materials.get(polygon.material);
    let decoded = material.is_some_and(|m| {
        [&m.base_color_texture, &m.emissive_texture]
            .iter()
            .any(|t| t.as_ref().is_some_and(|t| t.tex_coord == 1))
    });
    let authored = scene
        .authored
        .materials
        .get(polygon.material)
        .and_then(Option::as_ref)
        .is_some_and(|m| scene::authored_sets(m)[1]);
    if decoded || authored {
        return Err("its material samples TEXCOORD_1 as a texture set".into());
    }
    let Some(uv) = scene
        .uvs
        .get(k)
        .and_then(Option::as_ref)
        .filter(|uv| uv.sets[1])
    else {
        return Err("no TEXCOORD_1".into());
    };
    let v = &polygon.vertices;
    let size = v.iter().map(|p| p.distance(v[0])).fold(0.0, f64::max);
    let mut out = Vec::with_capacity(v.len());
    for (i, p) in v.iter().enumerate() {
        let t = uv
            .at(1, *p)
            .ok_or_else(|| format!("vertex {i} has no TEXCOORD_1"))?;
        if !(t.x.is_finite() && t.y.is_finite()) {
            return Err(format!("TEXCOORD_1 of vertex {i} is not finite"));
        }
        if !(0.0..=1.0).contains(&t.x) || !(0.0..=1.0).contains(&t.y) {
            return Err(format!(
                "TEXCOORD_1 ({}, {}) of vertex {i} leaves [0, 1]",
                t.x, t.y
            ));
        }
        out.push(t);
    }
    // A quad merged from two source triangles: both must give its shared corners the same
    // TEXCOORD_1 (no seam along the diagonal).
    for t in &uv.triangles {
        for (corner, position) in t.positions.iter().enumerate() {
            let Some(i) = v.iter().position(|p| p.distance(*position) <= 1e-9 * size) else {
                continue;
            };
            if (t.uv[1][corner] - out[i]).abs().max_element() > 1e-6 {
                return Err("TEXCOORD_1 has a seam inside one polygon".into());
            }
        }
    }
    Ok(out)
}

/// What the lightmap did with one primitive instance's charts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UvDecision {
    pub node: usize,
    pub mesh: usize,
    pub primitive: usize,
    pub polygons: usize,
    /// Its `TEXCOORD_1` is the layout.
    pub kept: bool,
    /// Why it was generated; for a primitive kept in its own atlas region, that (empty when
    /// the whole scene's layout is kept as it is).
    pub reason: String,
    /// Kept in its own atlas region: `TEXCOORD_1` is the input's scaled and moved.
    pub own_region: bool,
}

/// The [`UvDecision::reason`] of a primitive kept exactly in an atlas of its own (`keep`).
pub const OWN_ATLAS: &str =
    "kept as authored in an atlas of its own (primitives' TEXCOORD_1 overlap each other)";

/// The [`UvDecision::reason`] of a primitive kept in its own region.
pub const OWN_REGION: &str =
    "kept in its own atlas region (the input's TEXCOORD_1 scaled and moved: the whole scene's is not one usable layout)";

/// The primitive instances of `polygons` in (node, mesh, primitive) order, each with its
/// polygons.
fn primitives(polygons: &[Polygon]) -> BTreeMap<(usize, usize, usize), Vec<usize>> {
    let mut groups: BTreeMap<(usize, usize, usize), Vec<usize>> = BTreeMap::new();
    for (k, p) in polygons.iter().enumerate() {
        let o = p.origin;
        groups
            .entry((o.node, o.mesh, o.primitive))
            .or_default()
            .push(k);
    }
    groups
}

/// The decision: keep the authored layout (per-polygon texel-space charts and the atlas
/// side) or generate.
pub(crate) struct Plan {
    pub(crate) decisions: Vec<UvDecision>,
    /// Some when the authored layout is kept: the atlas side N.
    pub(crate) kept: Option<Kept>,
    /// When the whole layout is not kept: the primitives kept in their own regions (`Auto`)
    /// or, `exact`, atlases (`Keep`: every primitive's own layout is usable, they overlap
    /// each other).
    pub(crate) own: Vec<Own>,
    pub(crate) exact: bool,
}

/// A primitive instance whose own `TEXCOORD_1` is kept in its own atlas region.
pub(crate) struct Own {
    /// Its polygons, and each one's TEXCOORD_1 (in [0, 1]).
    pub(crate) polygons: Vec<usize>,
    pub(crate) uv: Vec<Vec<DVec2>>,
    /// World area over UV area.
    pub(crate) world_per_uv: f64,
    /// "node N mesh M primitive P", for warnings.
    pub(crate) label: String,
}

pub(crate) struct Kept {
    pub(crate) side: u32,
    pub(crate) texel_size: f64,
    pub(crate) reductions: u32,
    /// Per polygon: its vertices' TEXCOORD_1 × N (texel space).
    pub(crate) charts: Vec<Vec<DVec2>>,
    /// The smallest distance between two islands, in texels, when under [`MIN_PADDING`].
    pub(crate) padding: Option<f64>,
}

/// Decides whether the authored layout is kept; `Keep` refuses a layout that is not usable.
pub(crate) fn plan(
    polygons: &[Polygon],
    authored: &AuthoredUv,
    mode: UvMode,
    texel_size: f64,
    max_size: u32,
) -> Result<Plan, LightmapError> {
    let groups = primitives(polygons);
    let mut decisions: Vec<UvDecision> = groups
        .iter()
        .map(|(&(node, mesh, primitive), members)| UvDecision {
            node,
            mesh,
            primitive,
            polygons: members.len(),
            kept: false,
            reason: String::new(),
            own_region: false,
        })
        .collect();
    if mode == UvMode::Generate {
        for d in &mut decisions {
            d.reason = "--lightmap-uv generate".into();
        }
        return Ok(Plan {
            decisions,
            kept: None,
            own: Vec::new(),
            exact: false,
        });
    }
    if authored.polygons.len() != polygons.len() {
        return Err(LightmapError::InvalidData(format!(
            "{} authored UV entries for {} polygons",
            authored.polygons.len(),
            polygons.len()
        )));
    }
    // Per primitive: its own problems first.
    let mut reasons: Vec<Option<String>> = vec![None; decisions.len()];
    for (g, members) in groups.values().enumerate() {
        for &k in members {
            if polygons[k].origin.side == Side::Back {
                reasons[g] = Some(
                    "double-sided: both sides of a face would share its TEXCOORD_1 texels".into(),
                );
                break;
            }
            if let Err(why) = &authored.polygons[k] {
                reasons[g] = Some(format!("polygon {k}: {why}"));
                break;
            }
        }
    }
    let own_reasons = reasons.clone();
    let usable = reasons.iter().all(Option::is_none);
    let mut kept = None;
    if usable {
        let uv: Vec<&[DVec2]> = authored
            .polygons
            .iter()
            .map(|r| r.as_deref().unwrap_or(&[]))
            .collect();
        let (world, uv_area) = polygons.iter().zip(&uv).fold((0.0, 0.0), |(w, u), (p, t)| {
            (w + crate::polygon_area(p), u + fan_area(t))
        });
        let (side, used, reduced) = square_side((world / uv_area).sqrt(), texel_size, max_size);
        let reductions = u32::from(reduced);
        let group_of: Vec<usize> = {
            let mut g = vec![0; polygons.len()];
            for (i, members) in groups.values().enumerate() {
                for &k in members {
                    g[k] = i;
                }
            }
            g
        };
        let check = check_layout(&uv, Some(f64::from(side)));
        if let Some((a, b)) = check.overlap {
            let (ga, gb) = (group_of[a], group_of[b]);
            let name = |g: usize| {
                let d = &decisions[g];
                format!("node {} mesh {} primitive {}", d.node, d.mesh, d.primitive)
            };
            if ga == gb {
                reasons[ga] = Some(format!("TEXCOORD_1 overlaps itself (polygons {a} and {b})"));
            } else {
                let why = format!(
                    "TEXCOORD_1 of polygon {a} overlaps polygon {b} of {} (one atlas holds one layout)",
                    name(gb)
                );
                reasons[ga] = Some(why);
                reasons[gb] = Some(format!(
                    "TEXCOORD_1 of polygon {b} overlaps polygon {a} of {} (one atlas holds one layout)",
                    name(ga)
                ));
            }
        } else {
            let n = f64::from(side);
            kept = Some(Kept {
                side,
                texel_size: used,
                reductions,
                charts: uv
                    .iter()
                    .map(|t| t.iter().map(|p| *p * n).collect())
                    .collect(),
                padding: check.padding,
            });
        }
    }
    if kept.is_none() {
        // Each primitive on its own — its own problems, then overlaps within it.
        let exact = mode == UvMode::Keep;
        let mut own = Vec::new();
        let mut first_problem = None;
        for ((d, members), r) in decisions.iter_mut().zip(groups.values()).zip(&own_reasons) {
            let uv = members.iter().map(|&k| authored.polygons[k].as_deref());
            let own_uv: Option<Vec<&[DVec2]>> = if r.is_none() {
                uv.collect::<Result<_, _>>().ok()
            } else {
                None
            };
            let problem = match (r, &own_uv) {
                (Some(r), _) => r.clone(),
                (None, None) => "no usable TEXCOORD_1".into(),
                (None, Some(uv)) => match check_layout(uv, None).overlap {
                    Some((a, b)) => format!(
                        "TEXCOORD_1 overlaps itself (polygons {} and {})",
                        members[a], members[b]
                    ),
                    None => {
                        let (world, area) =
                            members.iter().zip(uv).fold((0.0, 0.0), |(w, u), (&k, t)| {
                                (w + crate::polygon_area(&polygons[k]), u + fan_area(t))
                            });
                        d.kept = true;
                        d.own_region = !exact;
                        d.reason = if exact { OWN_ATLAS } else { OWN_REGION }.into();
                        own.push(Own {
                            polygons: members.clone(),
                            uv: uv.iter().map(|t| t.to_vec()).collect(),
                            world_per_uv: world / area,
                            label: format!(
                                "node {} mesh {} primitive {}",
                                d.node, d.mesh, d.primitive
                            ),
                        });
                        continue;
                    }
                },
            };
            if first_problem.is_none() {
                first_problem = Some(format!(
                    "node {} mesh {} primitive {}: {problem}",
                    d.node, d.mesh, d.primitive
                ));
            }
            d.reason = problem;
        }
        if let (true, Some(why)) = (exact, first_problem) {
            return Err(LightmapError::AuthoredUv(why));
        }
        return Ok(Plan {
            decisions,
            kept: None,
            own,
            exact,
        });
    } else {
        for d in &mut decisions {
            d.kept = true;
        }
    }
    Ok(Plan {
        decisions,
        kept,
        own: Vec::new(),
        exact: false,
    })
}

/// The side N of a square atlas for a layout of `scale` = sqrt(world area / UV area), from
/// the texel size: `ceil(scale / texel)`, even, 16 to `max`; the texel size used, and
/// whether the atlas limit made it coarser than asked.
pub(crate) fn square_side(scale: f64, texel_size: f64, max: u32) -> (u32, f64, bool) {
    let wanted = (scale / texel_size).ceil();
    let mut side = if wanted.is_finite() {
        wanted.clamp(16.0, f64::from(max)) as u32
    } else {
        16
    };
    side += side % 2;
    side = side.min(max - max % 2);
    let used = scale / f64::from(side);
    (
        side,
        used,
        used > texel_size * (1.0 + 1e-12) && wanted > f64::from(side),
    )
}

/// The area of the fan triangles (v0 vk vk+1) of a polygon's UVs (sum of absolute areas).
fn fan_area(uv: &[DVec2]) -> f64 {
    (1..uv.len().saturating_sub(1))
        .map(|k| triangle_area(uv[0], uv[k], uv[k + 1]).abs())
        .sum()
}

fn triangle_area(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    0.5 * (b - a).perp_dot(c - a)
}

/// What [`check_layout`] found.
#[derive(Debug, PartialEq)]
pub(crate) struct LayoutCheck {
    /// The first overlapping pair of polygons (by index), if any.
    pub(crate) overlap: Option<(usize, usize)>,
    /// The smallest gap between islands in texels, when under [`MIN_PADDING`].
    pub(crate) padding: Option<f64>,
}

/// One fan triangle of a polygon's UVs.
struct Tri {
    polygon: usize,
    corners: [DVec2; 3],
    area: f64,
    island: usize,
    lo: DVec2,
    hi: DVec2,
}

/// Overlaps between the fan triangles of `uv` (UV space, [0, 1]²) and, given `side`
/// (texels per unit), the smallest gap between islands. A grid of cells over [0, 1]², each triangle in
/// every cell its box (grown by the padding) meets; a pair is tested in the first cell both
/// boxes share, so once. A degenerate triangle (no UV area) counts as overlapping itself.
pub(crate) fn check_layout(uv: &[&[DVec2]], side: Option<f64>) -> LayoutCheck {
    let islands = islands(uv);
    let pad = side.map_or(0.0, |side| MIN_PADDING / side);
    let mut tris = Vec::new();
    for (p, t) in uv.iter().enumerate() {
        for k in 1..t.len().saturating_sub(1) {
            let corners = [t[0], t[k], t[k + 1]];
            let lo = corners[0].min(corners[1]).min(corners[2]);
            let hi = corners[0].max(corners[1]).max(corners[2]);
            tris.push(Tri {
                polygon: p,
                corners,
                area: triangle_area(corners[0], corners[1], corners[2]).abs(),
                island: islands[p],
                lo,
                hi,
            });
        }
    }
    if let Some(t) = tris.iter().find(|t| t.area <= 1e-15) {
        return LayoutCheck {
            overlap: Some((t.polygon, t.polygon)),
            padding: None,
        };
    }
    let cells = ((tris.len() as f64).sqrt().ceil() as usize).clamp(1, 1024);
    let cell_of = |x: f64| ((x * cells as f64).floor().max(0.0) as usize).min(cells - 1);
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); cells * cells];
    for (i, t) in tris.iter().enumerate() {
        let (lo, hi) = (t.lo - pad, t.hi + pad);
        for cy in cell_of(lo.y)..=cell_of(hi.y) {
            for cx in cell_of(lo.x)..=cell_of(hi.x) {
                grid[cy * cells + cx].push(i as u32);
            }
        }
    }
    // Per cell: the first overlap (as polygon pair) and the smallest island gap.
    let found: Vec<(Option<(usize, usize)>, f64)> = grid
        .par_iter()
        .enumerate()
        .map(|(cell, members)| {
            let (cx, cy) = (cell % cells, cell / cells);
            let mut overlap: Option<(usize, usize)> = None;
            let mut gap = f64::INFINITY;
            let mut out = Vec::new();
            let mut scratch = Vec::new();
            for (n, &i) in members.iter().enumerate() {
                let a = &tris[i as usize];
                for &j in &members[n + 1..] {
                    let b = &tris[j as usize];
                    let (lo, hi) = ((a.lo - pad).max(b.lo - pad), (a.hi + pad).min(b.hi + pad));
                    if lo.x > hi.x || lo.y > hi.y {
                        continue;
                    }
                    // Tested once: in the cell holding the shared box's low corner.
                    if (cell_of(lo.x), cell_of(lo.y)) != (cx, cy) {
                        continue;
                    }
                    let touch = a.lo.x <= b.hi.x
                        && b.lo.x <= a.hi.x
                        && a.lo.y <= b.hi.y
                        && b.lo.y <= a.hi.y;
                    if touch {
                        clip::clip_convex(&a.corners, &b.corners, &mut out, &mut scratch);
                        let shared = clip::signed_area(&out).abs();
                        if shared > 1e-6 * a.area.min(b.area) {
                            let pair = (a.polygon.min(b.polygon), a.polygon.max(b.polygon));
                            if overlap.is_none_or(|o| pair < o) {
                                overlap = Some(pair);
                            }
                            continue;
                        }
                    }
                    if side.is_some() && a.island != b.island {
                        gap = gap.min(triangle_distance(&a.corners, &b.corners));
                    }
                }
            }
            (overlap, gap)
        })
        .collect();
    let overlap = found.iter().filter_map(|f| f.0).min();
    let gap = found.iter().map(|f| f.1).fold(f64::INFINITY, f64::min) * side.unwrap_or(0.0);
    LayoutCheck {
        overlap,
        padding: (gap < MIN_PADDING).then_some(gap),
    }
}

/// Island of each polygon: polygons connected through TEXCOORD_1 vertices equal bit for bit.
fn islands(uv: &[&[DVec2]]) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..uv.len()).collect();
    fn root(parent: &mut [usize], mut k: usize) -> usize {
        while parent[k] != k {
            parent[k] = parent[parent[k]];
            k = parent[k];
        }
        k
    }
    let mut first: HashMap<(u64, u64), usize> = HashMap::new();
    for (p, t) in uv.iter().enumerate() {
        for q in t.iter() {
            let key = ((q.x + 0.0).to_bits(), (q.y + 0.0).to_bits());
            let other = *first.entry(key).or_insert(p);
            let (a, b) = (root(&mut parent, p), root(&mut parent, other));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    (0..uv.len()).map(|k| root(&mut parent, k)).collect()
}

/// The distance between two triangles (0 when they meet).
fn triangle_distance(a: &[DVec2; 3], b: &[DVec2; 3]) -> f64 {
    let inside = |p: DVec2, t: &[DVec2; 3]| crate::raster::inside(p, t);
    if a.iter().any(|p| inside(*p, b)) || b.iter().any(|p| inside(*p, a)) {
        return 0.0;
    }
    let mut best = f64::INFINITY;
    for i in 0..3 {
        for j in 0..3 {
            best = best.min(segment_distance(a[i], a[(i + 1) % 3], b[j], b[(j + 1) % 3]));
        }
    }
    best
}

fn point_segment(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let d = b - a;
    let len2 = d.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(d) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + d * t)
}

fn segment_distance(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> f64 {
    let o = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    let (d1, d2, d3, d4) = (o(a, b, c), o(a, b, d), o(c, d, a), o(c, d, b));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    point_segment(a, c, d)
        .min(point_segment(b, c, d))
        .min(point_segment(c, a, b))
        .min(point_segment(d, a, b))
}

/// The distance from `p` to the convex polygon `uv` (0 inside).
pub(crate) fn polygon_distance(p: DVec2, uv: &[DVec2]) -> f64 {
    if crate::raster::inside(p, uv) {
        return 0.0;
    }
    (0..uv.len())
        .map(|k| point_segment(p, uv[k], uv[(k + 1) % uv.len()]))
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x: f64, y: f64, s: f64) -> Vec<DVec2> {
        vec![
            DVec2::new(x, y),
            DVec2::new(x + s, y),
            DVec2::new(x + s, y + s),
            DVec2::new(x, y + s),
        ]
    }

    #[test]
    fn overlaps_are_found_and_touching_islands_are_not_overlaps() {
        let a = square(0.125, 0.125, 0.25);
        let b = square(0.25, 0.25, 0.25);
        let uv = [a.as_slice(), b.as_slice()];
        let check = check_layout(&uv, Some(100.0));
        assert_eq!(check.overlap, Some((0, 1)));
        // Side by side: no overlap, the gap is 0.01 × 100 = 1 texel.
        let c = square(0.385, 0.125, 0.25);
        let uv = [a.as_slice(), c.as_slice()];
        let check = check_layout(&uv, Some(100.0));
        assert_eq!(check.overlap, None);
        let gap = check.padding.expect("under 2 texels");
        assert!((gap - 1.0).abs() < 1e-9, "{gap}");
        // Sharing an edge's vertices (bit for bit): one island, touching is fine, no padding needed.
        let d = square(0.375, 0.125, 0.25);
        let uv = [a.as_slice(), d.as_slice()];
        assert_eq!(
            check_layout(&uv, Some(100.0)),
            LayoutCheck {
                overlap: None,
                padding: None
            }
        );
        // Far apart at this resolution: no warning.
        let e = square(0.625, 0.625, 0.25);
        let uv = [a.as_slice(), e.as_slice()];
        assert_eq!(check_layout(&uv, Some(100.0)).padding, None);
    }

    #[test]
    fn a_folded_quad_overlaps_itself() {
        // The fan triangles (v0 v1 v2) and (v0 v2 v3) of a bow-tie cover each other.
        let q = vec![
            DVec2::new(0.1, 0.1),
            DVec2::new(0.5, 0.1),
            DVec2::new(0.2, 0.5),
            DVec2::new(0.45, 0.4),
        ];
        let uv = [q.as_slice()];
        assert_eq!(check_layout(&uv, Some(64.0)).overlap, Some((0, 0)));
    }
}
