//! Subdivides each polygon into elements of constant radiosity (Goral et al. 1984, §3: "the
//! second module subdivides the polygonal surfaces of the environment into subpolygons called
//! elements"), and smooths element values to vertices for display (the paper's linear
//! interpolation, §4, Figure 8).
//!
//! Public API: [`mesh`] → [`ElementMesh`]; [`ElementMesh::smooth`]; [`ElementMesh::refine`]
//! (split chosen elements below the grid: quads 2 × 2 at their edge midpoints, triangles into
//! 4) and [`ElementMesh::split_at_discontinuities`] (one vertex copy per side of a detected
//! discontinuity, so smoothing does not blend across it); [`ElementMesh::triangles`], the
//! conforming triangulation of an element that uses the hanging vertices on its edges.
//! A polygon's elements share one vertex set ([`PatchGrid`]); vertex sets are not shared
//! between polygons, so creases and material borders keep their own values. It is not a
//! general remesher: elements stay planar convex triangles and quads of their polygon.

use glam::DVec3;
use scene::Polygon;
use std::ops::Range;

mod refine;
pub use refine::Refined;

/// How radiosity is shown across an element (`--shading`), in the vertex bake and the
/// lightmap alike.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Shading {
    /// Smoothed: vertex values are area-weighted averages of the elements around each vertex
    /// (the paper's linear smoothing, `ElementMesh::smooth`), interpolated across elements
    /// and, in the lightmap, over the element grid, so the light has no steps at element edges.
    #[cfg_attr(
        feature = "clap",
        value(help = "Area-weighted averages at vertices, interpolated across elements")
    )]
    #[default]
    Smooth,
    /// Each element constant: its vertices are duplicated per element; each lightmap texel
    /// holds the element its centre maps to (in the footprint's rim: the nearest element's),
    /// so bilinear sampling at least one texel inside an element reads exactly its H.
    #[cfg_attr(feature = "clap", value(help = "Each element its own constant value"))]
    Flat,
}

/// How finely to subdivide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Subdivision {
    /// N×N elements per quad, N² per triangle.
    Count(u32),
    /// Elements no longer than this along any polygon edge direction (world units).
    MaxSize(f64),
}

/// One element: a planar convex triangle or quad of constant radiosity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    /// Index into the polygon list the mesh was built from.
    pub polygon: u32,
    /// Indices into [`ElementMesh::vertices`], counter-clockwise seen from the normal side.
    /// For a triangle the fourth entry repeats the third and `sides == 3`.
    pub corners: [u32; 4],
    pub sides: u8,
    pub area: f64,
    /// Area centroid.
    pub centroid: DVec3,
    /// Unit normal (the polygon's).
    pub normal: DVec3,
}

impl ElementMesh {
    /// Element `i`'s corners and normal as a [`scene::Convex`].
    pub fn convex(&self, i: usize) -> scene::Convex {
        let e = &self.elements[i];
        scene::Convex {
            corners: e.corners.map(|k| self.vertices[k as usize]),
            sides: e.sides,
            normal: e.normal,
        }
    }
}

impl Element {
    /// Corner indices actually used (3 or 4).
    pub fn corner_indices(&self) -> &[u32] {
        &self.corners[..self.sides as usize]
    }
}

/// The vertex grid and elements of one polygon.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchGrid {
    pub vertices: Range<u32>,
    pub elements: Range<u32>,
}

/// Elements of a whole scene.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct ElementMesh {
    pub vertices: Vec<DVec3>,
    pub elements: Vec<Element>,
    /// One per input polygon, in polygon order.
    pub patches: Vec<PatchGrid>,
    /// Per element: how many times it was split below the mesher's grid ([`ElementMesh::refine`]);
    /// empty when nothing was (all 0).
    pub levels: Vec<u8>,
    /// Per element, when the mesh is no longer the mesher's regular grids (refined, or vertices
    /// split at discontinuities): its boundary loop, counter-clockwise from corner 0, with the
    /// hanging vertices neighbours' splits put on its edges. Empty for the grids (the loop is
    /// then the corners).
    pub outlines: Vec<Vec<u32>>,
    /// Edges (pairs of vertex positions' indices on one side) where smoothing was stopped
    /// because the light is discontinuous there ([`ElementMesh::split_at_discontinuities`]).
    pub discontinuities: Vec<[u32; 2]>,
}

#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("invalid subdivision: {0}")]
    InvalidSubdivision(String),
    #[error("polygon {polygon} has {sides} vertices; the mesher takes triangles and quads")]
    UnsupportedPolygon { polygon: usize, sides: usize },
    /// The count, or a lower bound of it (`at least 10^…`) when it does not fit in a u64.
    #[error("subdivision would create {0} elements, more than the mesher's limit of {max}", max = MAX_ELEMENTS)]
    TooManyElements(String),
}

/// Hard cap on the element count (indices are `u32`).
pub const MAX_ELEMENTS: u64 = 1 << 30;

/// Elements per scene-size unit of the default subdivision: the default element size is the
/// scene's bounding-box diagonal divided by this (the paper's cube: 10×10 elements per wall).
pub const DEFAULT_ELEMENTS_PER_DIAGONAL: f64 = 16.0;

/// The default `--max-element-size`: the scene's bounding-box diagonal / 16.
pub fn default_max_element_size(polygons: &[Polygon]) -> f64 {
    max_element_size(polygons, DEFAULT_ELEMENTS_PER_DIAGONAL)
}

/// An element size relative to the scene: its bounding-box diagonal / `per_diagonal`.
pub fn max_element_size(polygons: &[Polygon], per_diagonal: f64) -> f64 {
    let (lo, hi) = scene::bounds(polygons);
    (hi - lo).length() / per_diagonal
}

/// Subdivides every polygon into elements.
///
/// Quads (v0 v1 v2 v3, counter-clockwise) get an nu×nv bilinear grid, u along v0→v1 and v
/// along v0→v3; triangles get the n² regular split by lines parallel to their edges. With
/// [`Subdivision::Count`] n = nu = nv = N; with [`Subdivision::MaxSize`] each direction gets
/// the fewest divisions that keep every element edge ≤ L.
pub fn mesh(polygons: &[Polygon], subdivision: Subdivision) -> Result<ElementMesh, MeshError> {
    // Count first so a huge request fails before allocating.
    let (total, plan) = plan(polygons, subdivision)?;
    let mut out = ElementMesh::default();
    out.elements.reserve(total as usize);
    for (index, (p, &(nu, nv))) in polygons.iter().zip(&plan).enumerate() {
        let v0 = out.vertices.len() as u32;
        let e0 = out.elements.len() as u32;
        if p.vertices.len() == 4 {
            quad_grid(&mut out, p, index as u32, nu, nv);
        } else {
            triangle_grid(&mut out, p, index as u32, nu);
        }
        out.patches.push(PatchGrid {
            vertices: v0..out.vertices.len() as u32,
            elements: e0..out.elements.len() as u32,
        });
    }
    Ok(out)
}

/// How many elements [`mesh`] would create, computed from the polygons' edge lengths alone
/// (nothing is allocated): exact, in checked u64 arithmetic, or
/// [`MeshError::TooManyElements`] above [`MAX_ELEMENTS`].
pub fn element_count(polygons: &[Polygon], subdivision: Subdivision) -> Result<u64, MeshError> {
    Ok(plan(polygons, subdivision)?.0)
}

/// The element count and each polygon's divisions.
fn plan(
    polygons: &[Polygon],
    subdivision: Subdivision,
) -> Result<(u64, Vec<(u32, u32)>), MeshError> {
    match subdivision {
        Subdivision::Count(0) => {
            return Err(MeshError::InvalidSubdivision(
                "--subdiv must be at least 1".into(),
            ))
        }
        Subdivision::MaxSize(l) if !(l.is_finite() && l > 0.0) => {
            return Err(MeshError::InvalidSubdivision(format!(
                "--max-element-size must be a positive number, got {l}"
            )))
        }
        _ => {}
    }
    let too_many = |count: Option<u64>| {
        MeshError::TooManyElements(match count {
            Some(n) => n.to_string(),
            None => approximate_count(polygons, subdivision),
        })
    };
    let mut total: u64 = 0;
    let mut plan = Vec::with_capacity(polygons.len());
    for (index, p) in polygons.iter().enumerate() {
        let (nu, nv) = divisions(p, subdivision, index)?.ok_or_else(|| too_many(None))?;
        let here = if p.vertices.len() == 4 {
            nu.checked_mul(nv)
        } else {
            nu.checked_mul(nu)
        };
        total = here
            .and_then(|h| total.checked_add(h))
            .ok_or_else(|| too_many(None))?;
        if total > MAX_ELEMENTS {
            return Err(too_many(Some(total)));
        }
        // Both fit: each is at most the total, at most 2^30.
        plan.push((nu as u32, nv as u32));
    }
    Ok((total, plan))
}

/// A lower bound of the element count for a message when it does not fit in a u64: the
/// largest polygon's, as a power of ten (`at least 10^600`).
fn approximate_count(polygons: &[Polygon], subdivision: Subdivision) -> String {
    let l = match subdivision {
        Subdivision::MaxSize(l) => l,
        Subdivision::Count(n) => return format!("at least {}", u64::from(n) * u64::from(n)),
    };
    // Logarithms: the count itself overflows f64 for l = 1e-300.
    let log10_largest = polygons
        .iter()
        .map(|p| {
            let v = &p.vertices;
            let (a, b) = match v.len() {
                4 => (
                    v[0].distance(v[1]).max(v[3].distance(v[2])),
                    v[0].distance(v[3]).max(v[1].distance(v[2])),
                ),
                _ => {
                    let e = v[0].distance(v[1]).max(v[1].distance(v[2]));
                    (e, e)
                }
            };
            (a / l).max(1.0).log10() + (b / l).max(1.0).log10()
        })
        .fold(f64::NEG_INFINITY, f64::max);
    format!("at least 10^{}", log10_largest.max(0.0).floor())
}

/// Divisions along u and v; `None` when one alone exceeds [`MAX_ELEMENTS`].
fn divisions(p: &Polygon, s: Subdivision, index: usize) -> Result<Option<(u64, u64)>, MeshError> {
    let v = &p.vertices;
    // The ratio is checked as an f64 first: `1 / 1e-300` does not fit a u64.
    let steps = |len: f64, l: f64| {
        let ratio = (len / l).ceil();
        (ratio <= MAX_ELEMENTS as f64).then(|| (ratio as u64).max(1))
    };
    match (v.len(), s) {
        (3 | 4, Subdivision::Count(n)) => Ok(Some((n as u64, n as u64))),
        (4, Subdivision::MaxSize(l)) => {
            let u = v[0].distance(v[1]).max(v[3].distance(v[2]));
            let w = v[0].distance(v[3]).max(v[1].distance(v[2]));
            Ok(steps(u, l).zip(steps(w, l)))
        }
        (3, Subdivision::MaxSize(l)) => {
            let e = v[0]
                .distance(v[1])
                .max(v[1].distance(v[2]))
                .max(v[2].distance(v[0]));
            Ok(steps(e, l).map(|n| (n, n)))
        }
        (sides, _) => Err(MeshError::UnsupportedPolygon {
            polygon: index,
            sides,
        }),
    }
}

fn quad_grid(out: &mut ElementMesh, p: &Polygon, polygon: u32, nu: u32, nv: u32) {
    let [a, b, c, d] = [p.vertices[0], p.vertices[1], p.vertices[2], p.vertices[3]];
    let base = out.vertices.len() as u32;
    for j in 0..=nv {
        let t = j as f64 / nv as f64;
        for i in 0..=nu {
            let s = i as f64 / nu as f64;
            // Bilinear map of the unit square onto the quad; exact at the corners.
            let bottom = a.lerp(b, s);
            let top = d.lerp(c, s);
            out.vertices.push(bottom.lerp(top, t));
        }
    }
    let id = |i: u32, j: u32| base + j * (nu + 1) + i;
    for j in 0..nv {
        for i in 0..nu {
            let corners = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            out.elements
                .push(element(&out.vertices, polygon, corners, 4, p.normal));
        }
    }
}

fn triangle_grid(out: &mut ElementMesh, p: &Polygon, polygon: u32, n: u32) {
    let [a, b, c] = [p.vertices[0], p.vertices[1], p.vertices[2]];
    let base = out.vertices.len() as u32;
    // Row k (0..=n) holds n-k+1 vertices a + (i/n)(b-a) + (k/n)(c-a).
    let mut row_start = Vec::with_capacity(n as usize + 1);
    for k in 0..=n {
        row_start.push(out.vertices.len() as u32 - base);
        for i in 0..=(n - k) {
            let (s, t) = (i as f64 / n as f64, k as f64 / n as f64);
            out.vertices.push(a + (b - a) * s + (c - a) * t);
        }
    }
    let id = |i: u32, k: u32| base + row_start[k as usize] + i;
    for k in 0..n {
        for i in 0..(n - k) {
            let up = [id(i, k), id(i + 1, k), id(i, k + 1), id(i, k + 1)];
            out.elements
                .push(element(&out.vertices, polygon, up, 3, p.normal));
            if i + 1 < n - k {
                let down = [id(i + 1, k), id(i + 1, k + 1), id(i, k + 1), id(i, k + 1)];
                out.elements
                    .push(element(&out.vertices, polygon, down, 3, p.normal));
            }
        }
    }
}

/// Area and area centroid of a planar convex polygon by a fan of triangles.
fn element(
    vertices: &[DVec3],
    polygon: u32,
    corners: [u32; 4],
    sides: u8,
    normal: DVec3,
) -> Element {
    let v = |k: usize| vertices[corners[k] as usize];
    let mut area = 0.0;
    let mut moment = DVec3::ZERO;
    for k in 1..sides as usize - 1 {
        let a = (v(k) - v(0)).cross(v(k + 1) - v(0)).dot(normal) * 0.5;
        area += a;
        moment += (v(0) + v(k) + v(k + 1)) * (a / 3.0);
    }
    Element {
        polygon,
        corners,
        sides,
        area,
        centroid: moment / area,
        normal,
    }
}

impl ElementMesh {
    /// Area-weighted average, at each vertex, of the values of the elements of the same
    /// polygon that touch it: the paper's linear smoothing of element intensities (§3, §4).
    /// On a refined mesh an element touches the hanging vertices on its edges too (its
    /// outline), so a hanging vertex averages both sides consistently; across a split
    /// discontinuity each side has its own vertex copy and so its own average.
    /// Returns one value per entry of [`ElementMesh::vertices`].
    pub fn smooth(&self, element_values: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut sum = vec![[0.0f64; 3]; self.vertices.len()];
        let mut weight = vec![0.0f64; self.vertices.len()];
        for (i, (e, value)) in self.elements.iter().zip(element_values).enumerate() {
            for &c in self.outline(i) {
                let c = c as usize;
                weight[c] += e.area;
                for band in 0..3 {
                    sum[c][band] += e.area * value[band];
                }
            }
        }
        sum.iter()
            .zip(&weight)
            .map(|(s, &w)| {
                if w > 0.0 {
                    [s[0] / w, s[1] / w, s[2] / w]
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::{Origin, Side};

    pub(crate) fn polygon(vertices: Vec<DVec3>) -> Polygon {
        let n = (vertices[1] - vertices[0])
            .cross(vertices[2] - vertices[0])
            .normalize();
        let origin = Origin {
            node: 0,
            mesh: 0,
            primitive: 0,
            face: 0,
            side: Side::Front,
        };
        Polygon {
            vertices,
            normal: n,
            material: 0,
            origin,
        }
    }

    fn quad() -> Polygon {
        // A non-rectangular convex quad (trapezoid), area 1.5 in the plane z = 0.
        polygon(vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.5, 1.0, 0.0),
            DVec3::new(0.5, 1.0, 0.0),
        ])
    }

    fn triangle() -> Polygon {
        polygon(vec![
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(3.0, 0.0, 1.0),
            DVec3::new(0.0, 2.0, 1.0),
        ])
    }

    #[test]
    fn counts_and_areas_add_up() {
        for n in 1..=7 {
            let m = mesh(&[quad(), triangle()], Subdivision::Count(n)).unwrap();
            let n = n as usize;
            assert_eq!(m.patches[0].elements.len(), n * n);
            assert_eq!(m.patches[1].elements.len(), n * n);
            assert_eq!(m.patches[0].vertices.len(), (n + 1) * (n + 1));
            assert_eq!(m.patches[1].vertices.len(), (n + 1) * (n + 2) / 2);
            let area = |r: Range<u32>| -> f64 {
                m.elements[r.start as usize..r.end as usize]
                    .iter()
                    .map(|e| e.area)
                    .sum()
            };
            assert!((area(m.patches[0].elements.clone()) - 1.5).abs() < 1e-12);
            assert!((area(m.patches[1].elements.clone()) - 3.0).abs() < 1e-12);
            assert!(m.elements.iter().all(|e| e.area > 0.0));
        }
    }

    #[test]
    fn centroids_are_area_centroids() {
        let m = mesh(&[quad()], Subdivision::Count(1)).unwrap();
        // Trapezoid with parallel sides 2 (y=0) and 1 (y=1): centroid y = (2·1 + 1)/(3·3) ... = h(a+2b)/(3(a+b)).
        let y = 1.0 * (2.0 + 2.0 * 1.0) / (3.0 * 3.0);
        assert!((m.elements[0].centroid - DVec3::new(1.0, y, 0.0)).length() < 1e-12);
    }

    #[test]
    fn max_size_bounds_every_edge() {
        let m = mesh(&[quad(), triangle()], Subdivision::MaxSize(0.3)).unwrap();
        for e in &m.elements {
            let c = e.corner_indices();
            for k in 0..c.len() {
                let (a, b) = (
                    m.vertices[c[k] as usize],
                    m.vertices[c[(k + 1) % c.len()] as usize],
                );
                assert!(a.distance(b) <= 0.3 + 1e-12);
            }
        }
        assert_eq!(m.patches[0].elements.len(), 7 * 4);
    }

    #[test]
    fn smoothing_is_the_area_weighted_average() {
        let m = mesh(&[quad()], Subdivision::Count(2)).unwrap();
        let values: Vec<[f64; 3]> = (0..4).map(|k| [k as f64, 1.0, 0.0]).collect();
        let s = m.smooth(&values);
        // Centre vertex (1,1) of the 3×3 grid touches all four elements.
        let a: Vec<f64> = m.elements.iter().map(|e| e.area).collect();
        let expect = (0..4).map(|k| a[k] * k as f64).sum::<f64>() / a.iter().sum::<f64>();
        assert!((s[4][0] - expect).abs() < 1e-12);
        assert!((s[4][1] - 1.0).abs() < 1e-12);
        // A corner vertex touches one element only.
        assert_eq!(s[0][0], 0.0);
        assert_eq!(s[8][0], 3.0);
    }

    #[test]
    fn rejects_bad_requests() {
        assert!(mesh(&[quad()], Subdivision::Count(0)).is_err());
        assert!(mesh(&[quad()], Subdivision::MaxSize(f64::NAN)).is_err());
        assert!(matches!(
            mesh(&[quad()], Subdivision::MaxSize(1e-9)),
            Err(MeshError::TooManyElements(_))
        ));
        // 1 / 1e-300 overflows u64 (it used to wrap past the check).
        assert!(matches!(
            element_count(&[quad()], Subdivision::MaxSize(1e-300)),
            Err(MeshError::TooManyElements(_))
        ));
        // 131072 × 73272 (ceil(√1.25 × 65536)): over the limit, counted exactly.
        let over = element_count(&[quad()], Subdivision::MaxSize(1.0 / 65536.0));
        assert!(
            matches!(&over, Err(MeshError::TooManyElements(n)) if *n == (131_072u64 * 73_272).to_string()),
            "{over:?}"
        );
        assert_eq!(
            element_count(&[quad()], Subdivision::Count(3)).ok(),
            Some(9)
        );
    }
}
