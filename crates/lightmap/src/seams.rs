//! How far a lightmap jumps across its seams (issue 32), measured against the field it was
//! reconstructed from: a measurement for tests and tools, not a build step.
//!
//! A *seam* is an edge two polygons share (both endpoints, within a weld tolerance of the
//! scene's size) whose two sides lie apart in the atlas (different charts, or a grouped
//! chart cut there). A viewer samples each side's texels bilinearly, so at a point x of the
//! edge the two sides show the atlas at two places; the *jump* is the larger band's
//! difference. What the jump may be is the field's own variation there: every texel a
//! bilinear sample at x reads holds the reconstructed field ([`crate::Lightmap::irradiance_at`])
//! at a chart point within about a texel and a half of x, so a lightmap without seam errors
//! (a wrong gutter, a chart placed off its polygon, a weld that does not match) jumps by at
//! most the range of that field over the surface within [`FOOTPRINT`] texels of x: the
//! polygons reached from the edge's two through shared vertices while they come that close,
//! each sampled on a 7 × 7 grid of its plane around x (every grid point taken to its nearest
//! point of the polygon, so a sliver thinner than the grid counts) and at its corners within
//! reach; a polygon wholly within reach at its corners and centre. At a
//! crease (different planes or materials, not welded) the sides' fields differ, and that
//! difference is part of the range.

use crate::Lightmap;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use scene::Polygon;
use std::collections::HashMap;

/// Points measured along every seam edge.
pub const POINTS_PER_EDGE: usize = 8;

/// Radius (texels) of the footprint whose field range bounds a point's jump: a bilinear sample
/// reads texel centres within √2 texels of it, each reconstructed at its chart's point nearest
/// its centre (≤ √2/2 further), so within 1.5√2 ≈ 2.12 texels in the chart; grouped charts are
/// unfolded, each polygon in its own shape, so a chart distance is a path on the surface of the
/// same length (and no part of a chart lies nearer another in the chart than on the surface,
/// `group`): 3 texels leave room for the snapping of a doubly curved chart's vertices.
pub const FOOTPRINT: f64 = 3.0;

/// Relative slack of the bound: the texels are stored as `f32`.
const STORAGE: f64 = 1e-6;

/// The most polygons one footprint gathers (a vertex shared by thousands of slivers).
const MAX_FOOTPRINT_POLYGONS: usize = 512;

/// What [`Lightmap::seams`] measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Seams {
    /// Edges two polygons share.
    pub shared_edges: usize,
    /// Shared edges whose sides lie apart in the atlas.
    pub seam_edges: usize,
    /// Points measured (seam edges × points per edge).
    pub points: usize,
    /// The largest jump, relative to the larger of the two sides' values there.
    pub worst_jump: f64,
    /// The largest jump over its bound (the field's range over the footprint, plus the
    /// storage slack): at most 1 on a seam without errors.
    pub worst_ratio: f64,
    /// Points whose jump passes its bound.
    pub over: usize,
    /// Where the worst ratio is: the two polygons and the point.
    pub worst_at: Option<(usize, usize, DVec3)>,
}

impl Lightmap {
    /// The seams of this lightmap of `polygons` (the ones it was built from), measured as the
    /// module docs say at [`POINTS_PER_EDGE`] points of every seam edge.
    pub fn seams(&self, polygons: &[Polygon]) -> Seams {
        self.seams_at(polygons, POINTS_PER_EDGE)
    }

    /// [`Lightmap::seams`] at `points` points of every seam edge (at least 1).
    pub fn seams_at(&self, polygons: &[Polygon], points: usize) -> Seams {
        let points = points.max(1);
        let (edges, around) = shared_edges(polygons);
        let around = &around;
        let seam: Vec<SharedEdge> = edges
            .iter()
            .copied()
            .filter(|&(p, a, b, q, c, d)| {
                let apart = |(p, i): (usize, usize), (q, j): (usize, usize)| {
                    let (s, t) = (&self.charts[p], &self.charts[q]);
                    s.atlas != t.atlas || DVec2::from(s.uv[i]).distance(DVec2::from(t.uv[j])) > 1e-6
                };
                apart((p, a), (q, c)) || apart((p, b), (q, d))
            })
            .collect();
        let texel = self.texel_size;
        let per_point: Vec<(f64, f64, (usize, usize, DVec3))> = seam
            .par_iter()
            .flat_map_iter(|&(p, a, b, q, _, _)| {
                let (x0, x1) = (polygons[p].vertices[a], polygons[p].vertices[b]);
                (0..points).map(move |k| {
                    let x = x0.lerp(x1, (k as f64 + 0.5) / points as f64);
                    let (jump, ratio) = self.jump_at(polygons, around, (p, q), x, texel);
                    (jump, ratio, (p, q, x))
                })
            })
            .collect();
        let mut out = Seams {
            shared_edges: edges.len(),
            seam_edges: seam.len(),
            points: per_point.len(),
            ..Seams::default()
        };
        for (jump, ratio, at) in per_point {
            out.worst_jump = out.worst_jump.max(jump);
            if ratio > out.worst_ratio {
                out.worst_ratio = ratio;
                out.worst_at = Some(at);
            }
            out.over += usize::from(ratio > 1.0);
        }
        out
    }

    /// At point `x` of the edge polygons p and q share: the jump relative to the larger side,
    /// and the jump over its bound (`around`: per polygon, the polygons sharing a vertex).
    fn jump_at(
        &self,
        polygons: &[Polygon],
        around: &[Vec<u32>],
        (p, q): (usize, usize),
        x: DVec3,
        texel: f64,
    ) -> (f64, f64) {
        let (Some(a), Some(b)) = (
            self.viewed_at(polygons, p, x),
            self.viewed_at(polygons, q, x),
        ) else {
            return (0.0, 0.0);
        };
        let r = FOOTPRINT * texel;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut take = |v: [f64; 3]| {
            for c in 0..3 {
                lo[c] = lo[c].min(v[c]);
                hi[c] = hi[c].max(v[c]);
            }
        };
        // The polygons within r of x on the surface: from p and q through shared vertices.
        let mut seen = vec![p as u32, q as u32];
        let mut next = 0;
        while next < seen.len() {
            let s = seen[next] as usize;
            next += 1;
            let poly = &polygons[s];
            let field = &self.fields[s];
            // The field at the points of s within r of x: a 7 × 7 grid of its plane around
            // x's projection, each point taken into s (its nearest point of s: a sliver thinner
            // than the grid's spacing is still sampled), and its corners. A polygon whose
            // nearest point is out of reach is neither sampled nor gone through (p and q hold
            // x itself).
            let centre = field.to_plane(x);
            let near = field.to_world(nearest_in(&field.corners, centre));
            if near.distance(x) > r {
                continue;
            }
            // A polygon wholly within reach: its corners (taken below) and centre bound its
            // field (linear between its vertex values); else the grid.
            let grid = if poly.vertices.iter().all(|v| v.distance(x) <= r) {
                0
            } else {
                3
            };
            if grid == 0 {
                let c = poly.vertices.iter().copied().sum::<DVec3>() / poly.vertices.len() as f64;
                take(self.irradiance_at(s, c));
            }
            for i in -grid..=grid {
                for j in -grid..=grid {
                    let d = glam::DVec2::new(i as f64, j as f64) * (r / 3.0);
                    let y = nearest_in(&field.corners, centre + d);
                    let world = field.to_world(y);
                    if world.distance(x) <= r {
                        take(self.irradiance_at(s, world));
                    }
                }
            }
            for &v in &poly.vertices {
                if v.distance(x) <= r {
                    take(self.irradiance_at(s, v));
                }
            }
            for &t in &around[s] {
                if !seen.contains(&t) && seen.len() < MAX_FOOTPRINT_POLYGONS {
                    seen.push(t);
                }
            }
        }
        let (mut jump, mut ratio) = (0.0f64, 0.0f64);
        for c in 0..3 {
            let d = (a[c] - b[c]).abs();
            let scale = a[c].abs().max(b[c].abs());
            let range = if hi[c] >= lo[c] { hi[c] - lo[c] } else { 0.0 };
            let bound = range + STORAGE * scale + 1e-30;
            if scale > 0.0 {
                jump = jump.max(d / scale);
            }
            ratio = ratio.max(d / bound);
        }
        (jump, ratio)
    }

    /// What a viewer shows of polygon `polygon` (of the `polygons` this lightmap was built
    /// from) at its point `point`: `TEXCOORD_1` interpolated over the glTF fan triangle
    /// (v0 vk vk+1) nearest to holding it, the atlas sampled bilinearly there (H, as a GPU
    /// samples level 0). `None` for a polygon it has no chart of.
    pub fn viewed_at(
        &self,
        polygons: &[Polygon],
        polygon: usize,
        point: DVec3,
    ) -> Option<[f64; 3]> {
        let c = &polygons.get(polygon)?.vertices;
        let chart = self.charts.get(polygon)?;
        let mut best: Option<(f64, DVec2)> = None;
        for k in 1..c.len().saturating_sub(1) {
            let l = barycentric(c[0], c[k], c[k + 1], point);
            let outside = -l.iter().copied().fold(f64::INFINITY, f64::min);
            if best.is_some_and(|b| b.0 <= outside) {
                continue;
            }
            let uv = [0, k, k + 1]
                .iter()
                .zip(l)
                .map(|(&v, w)| DVec2::from_array(self.texcoord(polygon, v).map(f64::from)) * w)
                .sum();
            best = Some((outside, uv));
        }
        let (_, uv) = best?;
        let atlas = self.atlas(chart.atlas as usize);
        Some(crate::sample_bilinear(
            atlas.texels,
            atlas.width,
            atlas.height,
            uv.to_array(),
        ))
    }
}

/// One shared edge: polygon p's edge from vertex a to b meets polygon q's from c to d at the
/// same two points (c at a's).
type SharedEdge = (usize, usize, usize, usize, usize, usize);

/// Every edge two polygons share, once, within a weld tolerance of 1e-9 of the scene's
/// bounding box (an edge three or more polygons share gives each pair with the first); and
/// per polygon, the polygons sharing a vertex with it.
fn shared_edges(polygons: &[Polygon]) -> (Vec<SharedEdge>, Vec<Vec<u32>>) {
    let (lo, hi) = polygons
        .iter()
        .flat_map(|p| p.vertices.iter())
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let tol = (hi - lo).length().max(1e-300) * 1e-9;
    let key = |v: DVec3| (v / tol).round().to_array().map(|x| x as i64);
    // Per edge (its two welded end points): the first polygon with it, and its two vertices.
    type Key = [i64; 3];
    let mut first: HashMap<(Key, Key), (usize, usize, usize)> = HashMap::new();
    let mut at_vertex: HashMap<Key, Vec<u32>> = HashMap::new();
    let mut out = Vec::new();
    for (p, poly) in polygons.iter().enumerate() {
        let n = poly.vertices.len();
        for a in 0..n {
            let b = (a + 1) % n;
            let (ka, kb) = (key(poly.vertices[a]), key(poly.vertices[b]));
            at_vertex.entry(ka).or_default().push(p as u32);
            if ka == kb {
                continue;
            }
            let edge = if ka < kb { (ka, kb) } else { (kb, ka) };
            match first.get(&edge) {
                None => {
                    first.insert(edge, (p, a, b));
                }
                Some(&(q, c, d)) if q != p => {
                    // Orient q's edge as p's: c at a's point.
                    let (c, d) = if key(polygons[q].vertices[c]) == ka {
                        (c, d)
                    } else {
                        (d, c)
                    };
                    out.push((p, a, b, q, c, d));
                }
                Some(_) => {}
            }
        }
    }
    let around = polygons
        .iter()
        .enumerate()
        .map(|(p, poly)| {
            let mut near: Vec<u32> = poly
                .vertices
                .iter()
                .flat_map(|&v| at_vertex.get(&key(v)).into_iter().flatten().copied())
                .filter(|&t| t as usize != p)
                .collect();
            near.sort_unstable();
            near.dedup();
            near
        })
        .collect();
    (out, around)
}

/// The point of the convex polygon `corners` (counter-clockwise, plane coordinates) nearest
/// to `y`: `y` itself inside, else the nearest point of its boundary.
fn nearest_in(corners: &[DVec2], y: DVec2) -> DVec2 {
    let n = corners.len();
    let inside = (0..n).all(|k| {
        let (a, b) = (corners[k], corners[(k + 1) % n]);
        (b - a).perp_dot(y - a) >= 0.0
    });
    if inside || n < 2 {
        return y;
    }
    (0..n)
        .map(|k| {
            let (a, b) = (corners[k], corners[(k + 1) % n]);
            let e = b - a;
            let t = if e.length_squared() > 0.0 {
                ((y - a).dot(e) / e.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            a + e * t
        })
        .min_by(|p, q| p.distance_squared(y).total_cmp(&q.distance_squared(y)))
        .unwrap_or(y)
}

/// Barycentric coordinates of `x` projected onto the plane of triangle (a, b, c).
fn barycentric(a: DVec3, b: DVec3, c: DVec3, x: DVec3) -> [f64; 3] {
    let (e1, e2) = (b - a, c - a);
    let n = e1.cross(e2);
    let nn = n.length_squared();
    if nn <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let q = x - a;
    let l1 = q.cross(e2).dot(n) / nn;
    let l2 = e1.cross(q).dot(n) / nn;
    [1.0 - l1 - l2, l1, l2]
}
