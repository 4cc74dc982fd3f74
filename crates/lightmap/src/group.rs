//! Grouped charts, for meshes of many small polygons (any scene above [`GROUPED_ABOVE`] polygons),
//! where one chart per polygon would make every triangle pay its own gutter.
//!
//! A chart grows from its first polygon (in polygon order) across shared edges (both ends
//! equal bit for bit) to polygons of the same node and material whose unit normal lies within
//! [`CHART_CONE_DEGREES`] of the first polygon's; so every normal is within twice that of
//! the chart's area-weighted mean normal (the mean of vectors in a cone stays in it). The
//! chart is flattened by projecting onto the plane across its mean normal, turned so its
//! principal axis runs along x, scaled to texels; a chart whose projected triangles overlap
//! (a surface that folds over its own plane) is grown again inside itself with half the cone,
//! down to [`MIN_CONE_DEGREES`] and then one chart per polygon, each projected onto its own
//! plane, so no chart overlaps. Charts are packed as their bounding
//! rectangles with [`crate::PADDING`] texels around each (as per-polygon regions), with
//! `etagere`.

use crate::authored::check_layout;
use crate::chart::PADDING;
use glam::{DVec2, DVec3};
use scene::Polygon;
use std::collections::HashMap;

/// Scenes with more polygons than this get grouped charts when any polygons group (or there
/// are more polygons than one shelf-packed atlas takes; polygons alone in their group keep
/// the per-polygon layout); others keep one chart per polygon (each with its exact aspect,
/// stretched to its shelf, and no interior seams). 0: every scene (issue 32). It was 4 096,
/// which left a 1 152-triangle cylinder in 1 152 charts at 36.5 % occupancy (grouped: 13
/// charts, 78.1 %; `crates/lightmap/tests/seams.rs`); a scene of separate quads (the cube, the
/// Cornell box) groups nothing and keeps the per-polygon layout.
pub const GROUPED_ABOVE: usize = 0;
/// Every polygon of a chart has its normal within this angle of the chart's first polygon
/// (so within twice it of the chart's mean normal).
pub const CHART_CONE_DEGREES: f64 = 22.5;

/// A grouped chart: its polygons and each one's vertices in chart coordinates (world
/// units, origin at the chart's low corner).
pub(crate) struct Group {
    pub(crate) polygons: Vec<usize>,
    pub(crate) uv: Vec<Vec<DVec2>>,
    /// Width and height in world units.
    pub(crate) size: DVec2,
}

fn key(p: DVec3) -> [u64; 3] {
    [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits())
}

/// Undirected edges (both ends bit for bit) → the polygons that have them, in polygon order.
type Edges = HashMap<([u64; 3], [u64; 3]), Vec<u32>>;

/// The charts of `polygons`, in order of their first polygon.
pub(crate) fn groups(polygons: &[Polygon]) -> Vec<Group> {
    let mut edges: Edges = HashMap::new();
    for (k, p) in polygons.iter().enumerate() {
        let v = &p.vertices;
        for i in 0..v.len() {
            let (a, b) = (key(v[i]), key(v[(i + 1) % v.len()]));
            let e = if a <= b { (a, b) } else { (b, a) };
            edges.entry(e).or_default().push(k as u32);
        }
    }
    // Per polygon: 0 taken by a chart, else the token of the set it may still join.
    let mut free = vec![1u32; polygons.len()];
    let mut token = 1;
    let mut out = Vec::new();
    for seed in 0..polygons.len() {
        if free[seed] == 0 {
            continue;
        }
        let members = grow(polygons, &edges, seed, CHART_CONE_DEGREES, &mut free, 1);
        split(
            polygons,
            &edges,
            members,
            CHART_CONE_DEGREES,
            &mut free,
            &mut token,
            &mut out,
        );
    }
    out
}

/// The polygons reachable from `seed` across shared edges among those marked `token` in
/// `free`, of the seed's node and material, whose normals lie within `degrees` of the
/// seed's; marked taken (0) and returned in polygon order.
fn grow(
    polygons: &[Polygon],
    edges: &Edges,
    seed: usize,
    degrees: f64,
    free: &mut [u32],
    token: u32,
) -> Vec<usize> {
    let cone = degrees.to_radians().cos();
    let s = &polygons[seed];
    free[seed] = 0;
    let mut members = vec![seed];
    let mut next = 0;
    while next < members.len() {
        let p = members[next];
        next += 1;
        let v = &polygons[p].vertices;
        for i in 0..v.len() {
            let (a, b) = (key(v[i]), key(v[(i + 1) % v.len()]));
            let e = if a <= b { (a, b) } else { (b, a) };
            for &q in edges.get(&e).map_or(&[][..], Vec::as_slice) {
                let q = q as usize;
                let t = &polygons[q];
                if free[q] == token
                    && t.material == s.material
                    && t.origin.node == s.origin.node
                    && t.normal.dot(s.normal) >= cone
                {
                    free[q] = 0;
                    members.push(q);
                }
            }
        }
    }
    members.sort_unstable();
    members
}

/// Charts narrower than this cone are not split further: their polygons become charts of
/// their own.
const MIN_CONE_DEGREES: f64 = 1.0;

/// `members` as one chart, or where its projection folds over itself, charts grown again
/// inside it with half the cone (a cylinder's band becomes narrower bands, not one chart per
/// triangle), down to [`MIN_CONE_DEGREES`], then one chart per polygon.
fn split(
    polygons: &[Polygon],
    edges: &Edges,
    members: Vec<usize>,
    degrees: f64,
    free: &mut [u32],
    token: &mut u32,
    out: &mut Vec<Group>,
) {
    if let Some(g) = flatten(polygons, &members) {
        out.push(g);
        return;
    }
    let half = degrees / 2.0;
    if half < MIN_CONE_DEGREES {
        for &p in &members {
            out.extend(flatten(polygons, &[p]));
        }
        return;
    }
    *token += 1;
    let mine = *token;
    for &p in &members {
        free[p] = mine;
    }
    for &seed in &members {
        if free[seed] != mine {
            continue;
        }
        let sub = grow(polygons, edges, seed, half, free, mine);
        split(polygons, edges, sub, half, free, token, out);
    }
}

/// Projects `members` onto the plane across their mean normal, principal axis along x;
/// `None` when the projection overlaps itself.
fn flatten(polygons: &[Polygon], members: &[usize]) -> Option<Group> {
    let mut normal = DVec3::ZERO;
    for &p in members {
        normal += polygons[p].normal * crate::polygon_area(&polygons[p]);
    }
    let normal = normal
        .try_normalize()
        .unwrap_or(polygons[members[0]].normal);
    let e1 = normal.any_orthonormal_vector();
    let e2 = normal.cross(e1);
    let origin = polygons[members[0]].vertices[0];
    let project = |q: DVec3| {
        let d = q - origin;
        DVec2::new(d.dot(e1), d.dot(e2))
    };
    let mut uv: Vec<Vec<DVec2>> = members
        .iter()
        .map(|&p| polygons[p].vertices.iter().map(|&q| project(q)).collect())
        .collect();
    // The smallest bounding rectangle lies along an edge of the convex hull: turn that
    // edge to x.
    let points: Vec<DVec2> = uv.iter().flatten().copied().collect();
    let hull = convex_hull(&points);
    let mut best = (f64::INFINITY, DVec2::X);
    for k in 0..hull.len() {
        let Some(d) = (hull[(k + 1) % hull.len()] - hull[k]).try_normalize() else {
            continue;
        };
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for q in &hull {
            let r = DVec2::new(q.dot(d), d.perp_dot(*q));
            lo = lo.min(r);
            hi = hi.max(r);
        }
        let area = (hi - lo).x * (hi - lo).y;
        if area < best.0 {
            best = (area, d);
        }
    }
    let d = best.1;
    let turn = |q: DVec2| DVec2::new(q.dot(d), d.perp_dot(q));
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for q in uv.iter_mut().flatten() {
        *q = turn(*q);
        lo = lo.min(*q);
        hi = hi.max(*q);
    }
    for q in uv.iter_mut().flatten() {
        *q -= lo;
    }
    let size = hi - lo;
    if members.len() > 1 {
        // Overlap test in a unit square (its tolerances are relative to triangle areas).
        let scale = size.max_element().max(f64::MIN_POSITIVE);
        let unit: Vec<Vec<DVec2>> = uv
            .iter()
            .map(|t| t.iter().map(|q| *q / scale).collect())
            .collect();
        let refs: Vec<&[DVec2]> = unit.iter().map(Vec::as_slice).collect();
        if check_layout(&refs, None).overlap.is_some() {
            return None;
        }
    }
    Some(Group {
        polygons: members.to_vec(),
        uv,
        size,
    })
}

/// The region size (even texels, padding included) of a group at `texels_per_unit`, and
/// its polygons' texel coordinates inside the region; `None` when it does not fit in u32.
pub(crate) fn region(group: &Group, texels_per_unit: f64) -> Option<(u32, u32, Vec<Vec<DVec2>>)> {
    let w = (group.size.x * texels_per_unit).ceil().max(1.0);
    let h = (group.size.y * texels_per_unit).ceil().max(1.0);
    if !(w.is_finite() && h.is_finite())
        || w > f64::from(u32::MAX / 4)
        || h > f64::from(u32::MAX / 4)
    {
        return None;
    }
    let even = |n: u32| n + n % 2;
    let (w, h) = (w as u32, h as u32);
    let p = DVec2::splat(f64::from(PADDING));
    let uv = group
        .uv
        .iter()
        .map(|t| t.iter().map(|q| *q * texels_per_unit + p).collect())
        .collect();
    Some((even(w + 2 * PADDING), even(h + 2 * PADDING), uv))
}

/// The convex hull of `points` (Andrew's monotone chain), counter-clockwise, collinear
/// points left out.
fn convex_hull(points: &[DVec2]) -> Vec<DVec2> {
    let mut p: Vec<DVec2> = points.to_vec();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let mut hull: Vec<DVec2> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2 {
                let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
                if (b - a).perp_dot(q - a) <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}
