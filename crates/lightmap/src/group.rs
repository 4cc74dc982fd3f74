//! Grouped charts: connected polygons laid out as one flat piece, so that a mesh of many
//! small polygons does not make every polygon pay its own gutter (on every mesh; a scene of
//! separate quads groups nothing and keeps one chart per polygon).
//!
//! Charts grown by unfolding: each polygon joins its chart by turning it about the edge it
//! shares with a polygon already there, into the chart's plane (the way a paper model is
//! unfolded). Every polygon keeps its exact shape, so texel density is the same everywhere
//! (no projection stretch) and a developable surface — a cylinder, a cone, an extrusion, a
//! folded strip — lays out as one flat piece whatever its curvature.
//!
//! Rules (`grow`): a polygon joins across an edge (both ends equal bit for bit) from a
//! polygon of the chart when it has the same node and material, the two normals are within
//! [`CREASE_DEGREES`] (a steeper edge is a crease, where the field itself jumps and a seam
//! costs nothing), its normal is within [`CHART_CONE_DEGREES`] of the chart's first polygon's
//! (a tube becomes strips of a half-turn at most), its unfolded shape overlaps no polygon of
//! the chart, and the chart stays within an atlas side (`largest`). A vertex unfolded within [`SNAP`] × its edge of where the chart
//! already has it is put there (a doubly curved surface closes up to its small angle defect);
//! further away the chart keeps a cut there (a cylinder unrolled to a strip).
//!
//! The chart is then turned to its smallest bounding rectangle and packed by its mask
//! (`crate::mask`) with [`crate::PADDING`] texels around it.

use crate::chart::PADDING;
use glam::{DVec2, DVec3};
use scene::Polygon;
use std::collections::HashMap;

/// Scenes with more polygons than this get grouped charts when any polygons group (or there
/// are more polygons than one shelf-packed atlas takes); others keep one chart per polygon
/// (each with its exact aspect, stretched to its shelf, and no interior seams). 0: every scene (issue 32). It was 4 096,
/// which left a 1 152-triangle cylinder in 1 152 charts at 36.5 % occupancy (grouped: 13
/// charts, 78.1 %; `crates/lightmap/tests/seams.rs`); a scene of separate quads (the cube, the
/// Cornell box) groups nothing and keeps the per-polygon layout.
pub const GROUPED_ABOVE: usize = 0;
/// A grouped chart: its polygons and each one's vertices in chart coordinates (world
/// units, origin at the chart's low corner).
pub(crate) struct Group {
    pub(crate) polygons: Vec<usize>,
    pub(crate) uv: Vec<Vec<DVec2>>,
    /// Width and height in world units.
    pub(crate) size: DVec2,
}

/// Largest angle between the normals of two polygons across an inner edge of a chart.
pub const CREASE_DEGREES: f64 = 45.0;
/// Every polygon of a chart has its normal within this angle of the chart's first one's, so
/// a closed surface (a tube, a sphere) is cut into pieces of at most a half-turn.
pub const CHART_CONE_DEGREES: f64 = 90.0;
/// A vertex unfolded within this fraction of the edge it hangs from of the chart's own
/// position of it is snapped there.
const SNAP: f64 = 0.02;

fn key(p: DVec3) -> [u64; 3] {
    [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits())
}

type EdgeKey = ([u64; 3], [u64; 3]);

fn edge_key(a: DVec3, b: DVec3) -> EdgeKey {
    let (a, b) = (key(a), key(b));
    if a <= b {
        (a, b)
    } else {
        (b, a)
    }
}

/// The longest side a chart's rectangle may have (world units): one atlas side at the
/// requested texel size, padding aside. A larger surface is cut into several charts rather
/// than making every texel of the bake coarser.
pub(crate) fn largest(options: &crate::Options) -> f64 {
    let side = f64::from(options.max_size.saturating_sub(2 * PADDING + 2).max(1));
    side * options.texel_size
}

/// Directions (in a chart's plane) along which its extent is tracked while it grows: a chart
/// stays within [`largest`] on both axes of at least one of them.
const DIRECTIONS: usize = 8;

fn directions() -> [DVec2; DIRECTIONS] {
    std::array::from_fn(|k| {
        let a = std::f64::consts::PI * k as f64 / DIRECTIONS as f64;
        DVec2::new(a.cos(), a.sin())
    })
}

/// The extents of `points` along each of [`directions`] and across it.
type Extents = [(f64, f64); DIRECTIONS];

fn extend(extents: &mut Extents, points: &[DVec2]) {
    for (e, d) in extents.iter_mut().zip(directions()) {
        for q in points {
            let t = q.dot(d);
            *e = (e.0.min(t), e.1.max(t));
        }
    }
}

/// Whether some tracked direction has the chart within `largest` on both axes.
fn fits(extents: &Extents, largest: f64) -> bool {
    let half = DIRECTIONS / 2;
    (0..half).any(|k| {
        let (a, b) = (extents[k], extents[k + half]);
        a.1 - a.0 <= largest && b.1 - b.0 <= largest
    })
}

/// The charts of `polygons`, in order of their first polygon; each polygon in exactly one;
/// each fits a `largest` square in some direction.
pub(crate) fn groups(polygons: &[Polygon], largest: f64, reach: f64) -> Vec<Group> {
    let mut edges: HashMap<EdgeKey, Vec<u32>> = HashMap::new();
    for (k, p) in polygons.iter().enumerate() {
        let v = &p.vertices;
        for i in 0..v.len() {
            edges
                .entry(edge_key(v[i], v[(i + 1) % v.len()]))
                .or_default()
                .push(k as u32);
        }
    }
    let mut taken = vec![false; polygons.len()];
    let mut out = Vec::new();
    let mut chart = Chart {
        members: Vec::new(),
        uv: Vec::new(),
        at: HashMap::new(),
        grid: HashMap::new(),
        big: Vec::new(),
        cell: 1.0,
        reach,
        centres: Vec::new(),
        extents: [(f64::INFINITY, f64::NEG_INFINITY); DIRECTIONS],
        near: Vec::new(),
        clipped: Vec::new(),
        scratch: Vec::new(),
    };
    for seed in 0..polygons.len() {
        if taken[seed] {
            continue;
        }
        chart.grow(polygons, &edges, seed, largest, &mut taken);
        let members = std::mem::take(&mut chart.members);
        out.push(oriented(members, std::mem::take(&mut chart.uv), largest));
    }
    out
}

/// One chart while it grows; reused (cleared) for the next.
struct Chart {
    members: Vec<usize>,
    /// Per member, its vertices' chart coordinates (world units).
    uv: Vec<Vec<DVec2>>,
    /// Vertex → the chart positions it has (more than one where the chart is cut).
    at: HashMap<[u64; 3], Vec<DVec2>>,
    /// Uniform grid over the chart plane: cell → members whose bounding box meets it.
    grid: HashMap<(i64, i64), Vec<u32>>,
    /// Members whose box spans more than [`MAX_CELLS`] cells: tested against every query.
    big: Vec<u32>,
    cell: f64,
    /// How far apart in the chart (world units) two polygons must be unless they are as near
    /// on the surface: a bilinear read's footprint, [`crate::FOOTPRINT`] texels.
    reach: f64,
    /// Per member: its centroid in space and in the chart, and its radius in the chart.
    centres: Vec<(DVec3, DVec2, f64)>,
    /// The chart's extents along the tracked directions.
    extents: Extents,
    near: Vec<u32>,
    clipped: Vec<DVec2>,
    scratch: Vec<DVec2>,
}

/// Cells a member's box may span before it is kept in the list every query tests.
const MAX_CELLS: i64 = 256;

fn spans(x0: i64, y0: i64, x1: i64, y1: i64) -> i64 {
    (x1 - x0 + 1).saturating_mul(y1 - y0 + 1)
}

/// A polygon's vertex mean in space and in the chart, and its radius in the chart.
fn centres(vertices: &[DVec3], uv: &[DVec2]) -> (DVec3, DVec2, f64) {
    let n = vertices.len().max(1) as f64;
    let space = vertices.iter().sum::<DVec3>() / n;
    let chart = uv.iter().sum::<DVec2>() / n;
    let radius = uv.iter().map(|q| q.distance(chart)).fold(0.0, f64::max);
    (space, chart, radius)
}

fn area(p: &[DVec2]) -> f64 {
    clip::signed_area(p).abs()
}

impl Chart {
    fn grow(
        &mut self,
        polygons: &[Polygon],
        edges: &HashMap<EdgeKey, Vec<u32>>,
        seed: usize,
        largest: f64,
        taken: &mut [bool],
    ) {
        self.members.clear();
        self.uv.clear();
        self.centres.clear();
        self.at.clear();
        self.grid.clear();
        self.big.clear();
        let s = &polygons[seed];
        let longest = s
            .vertices
            .iter()
            .zip(s.vertices.iter().cycle().skip(1))
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        self.cell = (2.0 * longest).max(self.reach).max(f64::MIN_POSITIVE);
        // The seed in its own plane.
        let e1 = s.normal.any_orthonormal_vector();
        let e2 = s.normal.cross(e1);
        let o = s.vertices[0];
        let uv: Vec<DVec2> = s
            .vertices
            .iter()
            .map(|&q| DVec2::new((q - o).dot(e1), (q - o).dot(e2)))
            .collect();
        taken[seed] = true;
        self.extents = [(f64::INFINITY, f64::NEG_INFINITY); DIRECTIONS];
        self.add(seed, &s.vertices, uv);
        let crease = CREASE_DEGREES.to_radians().cos();
        let cone = CHART_CONE_DEGREES.to_radians().cos();
        let mut next = 0;
        while next < self.members.len() {
            let p = self.members[next];
            let pu = self.uv[next].clone();
            next += 1;
            let pv = &polygons[p].vertices;
            for i in 0..pv.len() {
                let j = (i + 1) % pv.len();
                let Some(across) = edges.get(&edge_key(pv[i], pv[j])) else {
                    continue;
                };
                for &q in across {
                    let q = q as usize;
                    let t = &polygons[q];
                    if taken[q]
                        || t.material != s.material
                        || t.origin.node != s.origin.node
                        || t.normal.dot(polygons[p].normal) < crease
                        || t.normal.dot(s.normal) < cone
                    {
                        continue;
                    }
                    let Some(uv) = self.unfold(t, (pv[i], pu[i]), (pv[j], pu[j]), &pu) else {
                        continue;
                    };
                    let mut extents = self.extents;
                    extend(&mut extents, &uv);
                    if !fits(&extents, largest) {
                        continue;
                    }
                    taken[q] = true;
                    self.add(q, &t.vertices, uv);
                }
            }
        }
    }

    /// The grid cells the box of `uv`, grown by `grow`, meets.
    fn cells(&self, uv: &[DVec2], grow: f64) -> (i64, i64, i64, i64) {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for q in uv {
            lo = lo.min(*q - grow);
            hi = hi.max(*q + grow);
        }
        let c = |x: f64| (x / self.cell).floor().clamp(-1e15, 1e15) as i64;
        (c(lo.x), c(lo.y), c(hi.x), c(hi.y))
    }

    fn add(&mut self, polygon: usize, vertices: &[DVec3], uv: Vec<DVec2>) {
        let index = self.members.len() as u32;
        extend(&mut self.extents, &uv);
        self.centres.push(centres(vertices, &uv));
        let (x0, y0, x1, y1) = self.cells(&uv, 0.0);
        if spans(x0, y0, x1, y1) > MAX_CELLS {
            self.big.push(index);
        } else {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    self.grid.entry((x, y)).or_default().push(index);
                }
            }
        }
        for (v, q) in vertices.iter().zip(&uv) {
            let spots = self.at.entry(key(*v)).or_default();
            if !spots.contains(q) {
                spots.push(*q);
            }
        }
        self.members.push(polygon);
        self.uv.push(uv);
    }

    /// `t` turned about its edge (a, b) into the chart plane, on the other side of the edge
    /// from `from` (the chart polygon it is unfolded from), vertices snapped to the chart's
    /// own positions within [`SNAP`]; `None` when it would overlap the chart or is degenerate.
    fn unfold(
        &mut self,
        t: &Polygon,
        (a3, a): (DVec3, DVec2),
        (b3, b): (DVec3, DVec2),
        from: &[DVec2],
    ) -> Option<Vec<DVec2>> {
        let length = a3.distance(b3);
        let e = (b3 - a3).try_normalize()?;
        let f = t.normal.cross(e).try_normalize()?;
        let ue = (b - a).try_normalize()?;
        let scale = a.distance(b) / length;
        let place = |q: DVec3, side: f64| {
            let d = q - a3;
            a + ue * (d.dot(e) * scale) + ue.perp() * (d.dot(f) * side)
        };
        // The side away from `from`.
        let away = |uv: &[DVec2]| ue.perp_dot(clip::centroid(uv) - a);
        let mut uv: Vec<DVec2> = t.vertices.iter().map(|&q| place(q, 1.0)).collect();
        if away(&uv) * away(from) > 0.0 {
            uv = t.vertices.iter().map(|&q| place(q, -1.0)).collect();
        }
        let snap = SNAP * length;
        for (v, q) in t.vertices.iter().zip(uv.iter_mut()) {
            if *v == a3 {
                *q = a;
            } else if *v == b3 {
                *q = b;
            } else if let Some(spots) = self.at.get(&key(*v)) {
                if let Some(s) = spots
                    .iter()
                    .filter(|s| s.distance(*q) <= snap)
                    .min_by(|x, y| x.distance(*q).total_cmp(&y.distance(*q)))
                {
                    *q = *s;
                }
            }
        }
        let own = area(&uv);
        if own <= 1e-12 * length * length {
            return None;
        }
        // Members within reach: none may overlap, and none may be nearer in the chart than
        // on the surface (the far side of a gap, where filtering would read another part of
        // the surface): its centroid no further in space than in the chart, give or take a
        // third of the reach.
        let (x0, y0, x1, y1) = self.cells(&uv, self.reach);
        let mut near: Vec<u32> = std::mem::take(&mut self.near);
        near.clear();
        near.extend_from_slice(&self.big);
        if spans(x0, y0, x1, y1) > MAX_CELLS {
            near.extend(0..self.members.len() as u32);
        } else {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    near.extend(self.grid.get(&(x, y)).into_iter().flatten());
                }
            }
        }
        let (space, chart, radius) = centres(&t.vertices, &uv);
        let mut refused = false;
        for &m in &near {
            let (m_space, m_chart, m_radius) = self.centres[m as usize];
            let apart = chart.distance(m_chart);
            if apart <= self.reach + radius + m_radius
                && space.distance(m_space) > apart + self.reach / 3.0
            {
                refused = true;
                break;
            }
            // Overlap only where the boxes meet.
            let other = &self.uv[m as usize];
            if apart > radius + m_radius {
                continue;
            }
            clip::clip_convex(&uv, other, &mut self.clipped, &mut self.scratch);
            if area(&self.clipped) > 1e-6 * own.min(area(other)) {
                refused = true;
                break;
            }
        }
        self.near = near;
        if refused {
            return None;
        }
        Some(uv)
    }
}

/// The chart of `members` laid out at `uv` (world units) turned to its smallest bounding
/// rectangle whose sides are within `largest` (the smallest rectangle of any sides when none
/// is), its low corner at the origin.
pub(crate) fn oriented(members: Vec<usize>, mut uv: Vec<Vec<DVec2>>, largest: f64) -> Group {
    // The smallest bounding rectangle lies along an edge of the convex hull; the tracked
    // directions are tried too, since the chart fits `largest` along one of them.
    let points: Vec<DVec2> = uv.iter().flatten().copied().collect();
    let hull = convex_hull(&points);
    let mut best = (true, f64::INFINITY, DVec2::X);
    let edges =
        (0..hull.len()).filter_map(|k| (hull[(k + 1) % hull.len()] - hull[k]).try_normalize());
    for d in edges.chain(directions()) {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for q in &hull {
            let r = DVec2::new(q.dot(d), d.perp_dot(*q));
            lo = lo.min(r);
            hi = hi.max(r);
        }
        let size = hi - lo;
        let candidate = (size.max_element() > largest, size.x * size.y, d);
        if (candidate.0, candidate.1) < (best.0, best.1) {
            best = candidate;
        }
    }
    let d = best.2;
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
    Group {
        polygons: members,
        uv,
        size: hi - lo,
    }
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
