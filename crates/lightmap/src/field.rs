//! The smoothed field on one polygon: its element grid's vertex values, interpolated the way
//! the element mesh is built (bilinear over a quad's elements, linear over a triangle's), and
//! the weld that makes coplanar neighbours of the same material agree along shared edges.
//! A refined mesh (not the mesher's grids) is reconstructed from its elements instead:
//! linear over each element's conforming triangles (`ElementMesh::triangles`, the ones the
//! vertex bake writes), found through a bucket grid over the polygon's plane.

use crate::LightmapError;
use glam::{DVec2, DVec3};
use mesher::{ElementMesh, PatchGrid};
use scene::Polygon;

/// How a polygon's vertex grid is laid out (see `mesher::mesh`).
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Grid {
    /// A refined mesh: the polygon's element triangles.
    Elements(Box<Locator>),
    /// (nu+1)×(nv+1) vertices, row-major in t: vertex (i, j) is `base + j (nu+1) + i`, at the
    /// bilinear point P(i/nu, j/nv) of the quad v0 v1 v2 v3.
    Quad { base: u32, nu: u32, nv: u32 },
    /// Rows k = 0..=n of n−k+1 vertices: vertex (i, k) is at v0 + (i/n)(v1−v0) + (k/n)(v2−v0).
    Triangle { base: u32, n: u32 },
}

/// A polygon in its own plane frame plus its grid layout.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Field {
    origin: DVec3,
    e1: DVec3,
    e2: DVec3,
    /// The polygon's vertices in the plane frame (counter-clockwise).
    pub(crate) corners: Vec<DVec2>,
    pub(crate) grid: Grid,
    pub(crate) normal: DVec3,
}

impl Field {
    /// Reads the grid layout of polygon `index` from the mesh and checks that it is the one
    /// `mesher::mesh` builds (counts and corner positions).
    pub(crate) fn new(
        polygon: &Polygon,
        patch: &PatchGrid,
        mesh: &ElementMesh,
        index: usize,
    ) -> Result<Field, LightmapError> {
        let bad = |why: &str| LightmapError::InvalidData(format!("polygon {index}: {why}"));
        let v = &polygon.vertices;
        let base = patch.vertices.start;
        let vertex_count = patch.vertices.len() as u64;
        let element_count = patch.elements.len() as u64;
        if element_count == 0 || patch.vertices.end as usize > mesh.vertices.len() {
            return Err(bad("no elements or missing vertices"));
        }
        if !mesh.is_grid() {
            return Field::refined(polygon, patch, mesh, index);
        }
        let grid = match v.len() {
            4 => {
                let first = mesh
                    .elements
                    .get(patch.elements.start as usize)
                    .ok_or_else(|| bad("missing element"))?;
                let nu = u64::from(first.corners[3].wrapping_sub(base)).saturating_sub(1);
                if nu == 0 || !element_count.is_multiple_of(nu) {
                    return Err(bad("not a quad grid"));
                }
                let nv = element_count / nu;
                if (nu + 1) * (nv + 1) != vertex_count {
                    return Err(bad("not a quad grid"));
                }
                Grid::Quad {
                    base,
                    nu: nu as u32,
                    nv: nv as u32,
                }
            }
            3 => {
                let n = (element_count as f64).sqrt().round() as u64;
                if n == 0 || n * n != element_count || (n + 1) * (n + 2) / 2 != vertex_count {
                    return Err(bad("not a triangle grid"));
                }
                Grid::Triangle { base, n: n as u32 }
            }
            sides => return Err(bad(&format!("{sides} vertices"))),
        };
        let origin = v[0];
        let e1 = (v[1] - v[0])
            .try_normalize()
            .ok_or_else(|| bad("zero-length edge"))?;
        let e2 = polygon.normal.cross(e1);
        let mut field = Field {
            origin,
            e1,
            e2,
            corners: Vec::new(),
            grid,
            normal: polygon.normal,
        };
        field.corners = v.iter().map(|p| field.to_plane(*p)).collect();
        // The grid's corner vertices must be the polygon's corners.
        let size = v.iter().map(|p| p.distance(v[0])).fold(0.0, f64::max);
        let corner_ids: Vec<u32> = match field.grid {
            Grid::Elements(_) => Vec::new(),
            Grid::Quad { base, nu, nv } => vec![
                base,
                base + nu,
                base + nv * (nu + 1) + nu,
                base + nv * (nu + 1),
            ],
            Grid::Triangle { base, n } => vec![base, base + n, base + vertex_count as u32 - 1],
        };
        for (corner, id) in v.iter().zip(corner_ids) {
            if corner.distance(mesh.vertices[id as usize]) > 1e-9 * size {
                return Err(bad("the element grid does not match the polygon"));
            }
        }
        Ok(field)
    }

    /// World point → plane coordinates.
    pub(crate) fn to_plane(&self, p: DVec3) -> DVec2 {
        let d = p - self.origin;
        DVec2::new(d.dot(self.e1), d.dot(self.e2))
    }

    /// Plane coordinates → world point.
    pub(crate) fn to_world(&self, q: DVec2) -> DVec3 {
        self.origin + self.e1 * q.x + self.e2 * q.y
    }

    /// The grid parameters of plane point `q`: (s, t) of the quad's bilinear map, or the
    /// triangle's (β, γ) with q = v0 + β(v1−v0) + γ(v2−v0). Points outside give parameters
    /// outside the unit square / triangle (extrapolation).
    pub(crate) fn params(&self, q: DVec2) -> DVec2 {
        let c = &self.corners;
        match self.grid {
            Grid::Elements(_) => q,
            Grid::Quad { .. } => inverse_bilinear(q, c[0], c[1], c[2], c[3]),
            Grid::Triangle { .. } => {
                let (b, g, h) = (c[1] - c[0], c[2] - c[0], q - c[0]);
                let det = cross(b, g);
                DVec2::new(cross(h, g) / det, cross(b, h) / det)
            }
        }
    }

    /// The field at grid parameters `p` (see [`Field::params`]), from per-mesh-vertex values.
    /// Outside the polygon the nearest element's interpolant is extended.
    pub(crate) fn value_at_params(&self, p: DVec2, values: &[[f64; 3]]) -> [f64; 3] {
        self.interpolate(p, values, false)
    }

    /// The field at plane point `q` of the polygon, bounded: the parameters are clamped into
    /// the polygon's grid and the cell's weights into [0, 1], and the result into the range
    /// of the vertex values it interpolates (each a weighted mean of the elements around it),
    /// so no rounding or sliver can leave that range.
    pub(crate) fn value_within(&self, q: DVec2, values: &[[f64; 3]]) -> [f64; 3] {
        self.interpolate(self.params(q), values, true)
    }

    /// [`Field::value_at_params`], or with `bounded` [`Field::value_within`]'s clamps.
    fn interpolate(&self, p: DVec2, values: &[[f64; 3]], bounded: bool) -> [f64; 3] {
        let at = |id: u32| values[id as usize];
        let unit = |f: f64| if bounded { f.clamp(0.0, 1.0) } else { f };
        match self.grid {
            Grid::Elements(ref locator) => locator.value_at(p, values, bounded),
            Grid::Quad { base, nu, nv } => {
                let p = if bounded {
                    p.clamp(DVec2::ZERO, DVec2::ONE)
                } else {
                    p
                };
                let (x, y) = (p.x * f64::from(nu), p.y * f64::from(nv));
                let i = clamp_cell(x, nu);
                let j = clamp_cell(y, nv);
                let (fx, fy) = (unit(x - f64::from(i)), unit(y - f64::from(j)));
                let id = |i: u32, j: u32| base + j * (nu + 1) + i;
                let (v00, v10, v11, v01) = (
                    at(id(i, j)),
                    at(id(i + 1, j)),
                    at(id(i + 1, j + 1)),
                    at(id(i, j + 1)),
                );
                let v = std::array::from_fn(|c| {
                    (1.0 - fy) * ((1.0 - fx) * v00[c] + fx * v10[c])
                        + fy * ((1.0 - fx) * v01[c] + fx * v11[c])
                });
                within(v, &[v00, v10, v11, v01], bounded)
            }
            Grid::Triangle { base, n } => {
                let p = if bounded { into_triangle(p) } else { p };
                let (x, y) = (p.x * f64::from(n), p.y * f64::from(n));
                let k = clamp_cell(y, n);
                let i = clamp_cell(x, n - k);
                let (fx, fy) = (unit(x - f64::from(i)), unit(y - f64::from(k)));
                let row_start = |k: u32| k * (n + 1) - k * k.saturating_sub(1) / 2;
                let id = |i: u32, k: u32| base + row_start(k) + i;
                let has_down = i + 1 < n - k;
                if fx + fy <= 1.0 || !has_down {
                    let (a, b, c) = (at(id(i, k)), at(id(i + 1, k)), at(id(i, k + 1)));
                    let v = std::array::from_fn(|m| a[m] + fx * (b[m] - a[m]) + fy * (c[m] - a[m]));
                    within(v, &[a, b, c], bounded)
                } else {
                    let (a, b, c) = (at(id(i + 1, k)), at(id(i + 1, k + 1)), at(id(i, k + 1)));
                    let v = std::array::from_fn(|m| {
                        b[m] + (1.0 - fy) * (a[m] - b[m]) + (1.0 - fx) * (c[m] - b[m])
                    });
                    within(v, &[a, b, c], bounded)
                }
            }
        }
    }

    /// The field at plane point `q`.
    pub(crate) fn value_at(&self, q: DVec2, values: &[[f64; 3]]) -> [f64; 3] {
        self.value_at_params(self.params(q), values)
    }

    /// Mesh vertex ids of the grid vertices on the polygon's boundary, in id order.
    pub(crate) fn boundary_vertices(&self) -> Vec<u32> {
        let mut ids = Vec::new();
        match self.grid {
            Grid::Elements(ref locator) => ids.clone_from(&locator.boundary),
            Grid::Quad { base, nu, nv } => {
                for j in 0..=nv {
                    for i in 0..=nu {
                        if i == 0 || j == 0 || i == nu || j == nv {
                            ids.push(base + j * (nu + 1) + i);
                        }
                    }
                }
            }
            Grid::Triangle { base, n } => {
                let mut id = base;
                for k in 0..=n {
                    for i in 0..=(n - k) {
                        if k == 0 || i == 0 || i == n - k {
                            ids.push(id);
                        }
                        id += 1;
                    }
                }
            }
        }
        ids
    }

    /// Whether plane point `q` lies in the closed polygon, with tolerance `tol` (distance).
    pub(crate) fn contains(&self, q: DVec2, tol: f64) -> bool {
        let c = &self.corners;
        (0..c.len()).all(|k| {
            let (a, b) = (c[k], c[(k + 1) % c.len()]);
            let edge = b - a;
            cross(edge, q - a) >= -tol * edge.length()
        })
    }
}

impl Field {
    /// The field of polygon `index` on a refined mesh: its elements' triangles.
    fn refined(
        polygon: &Polygon,
        patch: &PatchGrid,
        mesh: &ElementMesh,
        index: usize,
    ) -> Result<Field, LightmapError> {
        let bad = |why: &str| LightmapError::InvalidData(format!("polygon {index}: {why}"));
        let v = &polygon.vertices;
        let e1 = (v[1] - v[0])
            .try_normalize()
            .ok_or_else(|| bad("zero-length edge"))?;
        let mut field = Field {
            origin: v[0],
            e1,
            e2: polygon.normal.cross(e1),
            corners: Vec::new(),
            grid: Grid::Triangle { base: 0, n: 1 },
            normal: polygon.normal,
        };
        field.corners = v.iter().map(|p| field.to_plane(*p)).collect();
        let base = patch.vertices.start;
        let points: Vec<DVec2> = patch
            .vertices
            .clone()
            .map(|k| field.to_plane(mesh.vertices[k as usize]))
            .collect();
        let inside = |k: u32| patch.vertices.contains(&k);
        let mut tris = Vec::new();
        let mut tri_elements = Vec::new();
        let mut scratch = Vec::new();
        for i in patch.elements.clone() {
            if i as usize >= mesh.elements.len() {
                return Err(bad("missing element"));
            }
            mesh.triangles(i as usize, &mut scratch);
            for t in &scratch {
                if !t.iter().all(|&k| inside(k)) {
                    return Err(bad(
                        "an element's vertex lies outside its polygon's vertices",
                    ));
                }
                tris.push((*t, t.map(|k| points[(k - base) as usize])));
                tri_elements.push(i - patch.elements.start);
            }
        }
        if tris.is_empty() {
            return Err(bad("no triangles"));
        }
        let size = v.iter().map(|p| p.distance(v[0])).fold(0.0, f64::max);
        let tol = 1e-9 * size;
        let corners = field.corners.clone();
        let boundary: Vec<u32> = (0..points.len())
            .filter(|&k| {
                let q = points[k];
                (0..corners.len()).any(|j| {
                    let (a, b) = (corners[j], corners[(j + 1) % corners.len()]);
                    let d = b - a;
                    cross(d, q - a).abs() <= tol * d.length()
                })
            })
            .map(|k| base + k as u32)
            .collect();
        field.grid = Grid::Elements(Box::new(Locator::new(
            base,
            points,
            tris,
            tri_elements,
            boundary,
        )));
        Ok(field)
    }
}

/// The triangles of a refined polygon and a bucket grid over them (plane coordinates).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Locator {
    /// The polygon's first mesh vertex.
    base: u32,
    /// Plane position of each of the polygon's mesh vertices (from `base`).
    points: Vec<DVec2>,
    /// Mesh vertex ids and plane positions of each triangle.
    tris: Vec<([u32; 3], [DVec2; 3])>,
    /// Each triangle's element, counted from the polygon's first.
    tri_elements: Vec<u32>,
    lo: DVec2,
    cell: DVec2,
    cells: [usize; 2],
    /// Per bucket (row-major), the triangles whose box meets it.
    buckets: Vec<Vec<u32>>,
    /// Mesh vertex ids on the polygon's boundary, in id order.
    boundary: Vec<u32>,
}

impl Locator {
    fn new(
        base: u32,
        points: Vec<DVec2>,
        tris: Vec<([u32; 3], [DVec2; 3])>,
        tri_elements: Vec<u32>,
        boundary: Vec<u32>,
    ) -> Locator {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for (_, p) in &tris {
            for q in p {
                lo = lo.min(*q);
                hi = hi.max(*q);
            }
        }
        let side = (tris.len() as f64).sqrt().ceil().clamp(1.0, 1024.0) as usize;
        let cells = [side, side];
        let cell = ((hi - lo) / side as f64).max(DVec2::splat(f64::MIN_POSITIVE));
        let mut buckets = vec![Vec::new(); side * side];
        let index = |q: DVec2| {
            let c = (q - lo) / cell;
            [
                (c.x.max(0.0) as usize).min(side - 1),
                (c.y.max(0.0) as usize).min(side - 1),
            ]
        };
        for (k, (_, p)) in tris.iter().enumerate() {
            let a = index(p[0].min(p[1]).min(p[2]));
            let b = index(p[0].max(p[1]).max(p[2]));
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    buckets[y * side + x].push(k as u32);
                }
            }
        }
        Locator {
            base,
            points,
            tris,
            tri_elements,
            lo,
            cell,
            cells,
            buckets,
            boundary,
        }
    }

    /// Barycentric coordinates of `q` in triangle `p`.
    fn barycentric(p: &[DVec2; 3], q: DVec2) -> [f64; 3] {
        let det = cross(p[1] - p[0], p[2] - p[0]);
        let b = cross(q - p[0], p[2] - p[0]) / det;
        let c = cross(p[1] - p[0], q - p[0]) / det;
        [1.0 - b - c, b, c]
    }

    /// The field at plane point `q`: linear over the triangle containing it (the one it is
    /// least outside of, in barycentric terms, for points outside the polygon).
    /// With `bounded`, negative weights (rounding at the polygon's edge) are clamped to 0
    /// and the result into the range of the triangle's vertex values.
    fn value_at(&self, q: DVec2, values: &[[f64; 3]], bounded: bool) -> [f64; 3] {
        let Some((k, mut w)) = self.locate(q) else {
            return [0.0; 3];
        };
        if bounded {
            let w0 = w.map(|x| x.max(0.0));
            let sum = w0[0] + w0[1] + w0[2];
            if sum > 0.0 {
                w = w0.map(|x| x / sum);
            }
        }
        let ids = self.tris[k].0;
        let v =
            std::array::from_fn(|band| (0..3).map(|j| w[j] * values[ids[j] as usize][band]).sum());
        within(v, &ids.map(|id| values[id as usize]), bounded)
    }

    /// The element (counted from the polygon's first) whose triangle holds `q`, or the
    /// nearest one's outside the polygon.
    fn element_at(&self, q: DVec2) -> u32 {
        self.locate(q).map_or(0, |(k, _)| self.tri_elements[k])
    }

    /// The triangle holding `q` (the one it is least outside of, outside the polygon) and
    /// `q`'s barycentric weights in it.
    fn locate(&self, q: DVec2) -> Option<(usize, [f64; 3])> {
        let c = (q - self.lo) / self.cell;
        let in_grid = c.x >= 0.0
            && c.y >= 0.0
            && (c.x as usize) < self.cells[0]
            && (c.y as usize) < self.cells[1];
        let best = |candidates: &mut dyn Iterator<Item = usize>| {
            let mut best: Option<(f64, usize, [f64; 3])> = None;
            for k in candidates {
                let w = Self::barycentric(&self.tris[k].1, q);
                let worst = w[0].min(w[1]).min(w[2]);
                if worst.is_finite() && best.is_none_or(|(b, _, _)| worst > b) {
                    best = Some((worst, k, w));
                }
            }
            best
        };
        let mut found = None;
        if in_grid {
            let bucket = &self.buckets[c.y as usize * self.cells[0] + c.x as usize];
            found = best(&mut bucket.iter().map(|&k| k as usize)).filter(|b| b.0 >= -1e-9);
        }
        if found.is_none() {
            found = best(&mut (0..self.tris.len()));
        }
        found.map(|(_, k, w)| (k, w))
    }
}

/// With `bounded`, `v` clamped per band into the range of `corners` (the vertex values it
/// interpolates; the first corner's when `v` is not a number); else `v` as it is.
fn within(v: [f64; 3], corners: &[[f64; 3]], bounded: bool) -> [f64; 3] {
    if !bounded {
        return v;
    }
    std::array::from_fn(|c| {
        let (lo, hi) = corners
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x[c]), hi.max(x[c]))
            });
        if v[c].is_nan() {
            corners[0][c]
        } else {
            v[c].clamp(lo, hi)
        }
    })
}

/// Triangle parameters (β, γ) moved into the triangle β, γ ≥ 0, β + γ ≤ 1 (a point of the
/// polygon gives such parameters up to rounding).
fn into_triangle(p: DVec2) -> DVec2 {
    let p = p.max(DVec2::ZERO);
    let sum = p.x + p.y;
    if sum > 1.0 {
        p / sum
    } else {
        p
    }
}

/// The cell index of grid coordinate `x` among `cells` cells, clamped so points outside use
/// the nearest cell.
fn clamp_cell(x: f64, cells: u32) -> u32 {
    if x.is_nan() || x < 0.0 {
        0
    } else {
        (x.floor() as u64).min(u64::from(cells.max(1) - 1)) as u32
    }
}

pub(crate) fn cross(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// (s, t) with q = (1−t)((1−s)a + s b) + t((1−s)d + s c), the root nearest the unit square.
pub(crate) fn inverse_bilinear(q: DVec2, a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> DVec2 {
    let (e, f, g, h) = (b - a, d - a, a - b + c - d, q - a);
    let k2 = cross(g, f);
    let k1 = cross(e, f) + cross(h, g);
    let k0 = cross(h, e);
    let s_for = |t: f64| {
        let axis = e + g * t;
        (h - f * t).dot(axis) / axis.length_squared()
    };
    let distance = |p: DVec2| (-p.x).max(p.x - 1.0).max(0.0) + (-p.y).max(p.y - 1.0).max(0.0);
    let mut candidates = Vec::with_capacity(2);
    if k2 == 0.0 {
        candidates.push(-k0 / k1);
    } else {
        let w = (k1 * k1 - 4.0 * k0 * k2).max(0.0).sqrt();
        let q = -0.5 * (k1 + k1.signum() * w);
        if q == 0.0 {
            candidates.push(0.0);
        } else {
            candidates.push(k0 / q);
            candidates.push(q / k2);
        }
    }
    let mut best = DVec2::new(f64::NAN, f64::NAN);
    let mut best_distance = f64::INFINITY;
    for t in candidates {
        if !t.is_finite() {
            continue;
        }
        let p = DVec2::new(s_for(t), t);
        let dist = distance(p);
        if p.x.is_finite() && dist < best_distance {
            best = p;
            best_distance = dist;
        }
    }
    best
}

/// Averages, at every boundary grid vertex, the fields of all coplanar polygons of the same
/// material (same facing) whose closed area contains it, so that such neighbours agree along
/// shared edges. Reads the unwelded `values`; returns the welded values and how many vertices
/// changed. Exact agreement where the two grids' vertices coincide along the edge; elsewhere
/// (T-junctions, different subdivisions) each side moves half-way towards the other.
pub(crate) fn weld(
    polygons: &[Polygon],
    fields: &[Field],
    values: &[[f64; 3]],
    tol: f64,
) -> (Vec<[f64; 3]>, usize) {
    let candidates = coplanar_neighbours(polygons, fields, tol);
    let mut welded = values.to_vec();
    let mut count = 0;
    for (a, neighbours) in candidates.iter().enumerate() {
        if neighbours.is_empty() {
            continue;
        }
        for id in fields[a].boundary_vertices() {
            let world = fields[a].to_world(fields[a].vertex_point(id));
            let mut sum = values[id as usize];
            let mut n = 1.0;
            for &b in neighbours {
                let q = fields[b].to_plane(world);
                if fields[b].contains(q, tol) {
                    let v = fields[b].value_at(q, values);
                    for c in 0..3 {
                        sum[c] += v[c];
                    }
                    n += 1.0;
                }
            }
            if n > 1.0 {
                welded[id as usize] = sum.map(|s| s / n);
                count += 1;
            }
        }
    }
    (welded, count)
}

impl Field {
    /// The plane position of grid vertex `id` (recomputed from the grid parameters so it does
    /// not depend on the mesh's rounding).
    pub(crate) fn vertex_point(&self, id: u32) -> DVec2 {
        let c = &self.corners;
        match self.grid {
            Grid::Elements(ref locator) => locator.points[(id - locator.base) as usize],
            Grid::Quad { base, nu, nv } => {
                let local = id - base;
                let (i, j) = (local % (nu + 1), local / (nu + 1));
                let (s, t) = (f64::from(i) / f64::from(nu), f64::from(j) / f64::from(nv));
                let bottom = c[0].lerp(c[1], s);
                let top = c[3].lerp(c[2], s);
                bottom.lerp(top, t)
            }
            Grid::Triangle { base, n } => {
                let mut local = id - base;
                let mut k = 0;
                while local > n - k {
                    local -= n - k + 1;
                    k += 1;
                }
                let (s, t) = (f64::from(local) / f64::from(n), f64::from(k) / f64::from(n));
                c[0] + (c[1] - c[0]) * s + (c[2] - c[0]) * t
            }
        }
    }
}

impl Field {
    /// Flat reconstruction (`Shading::Flat`): which of the polygon's own elements, counted
    /// from its first in the mesher's order, holds grid parameters `p` (see
    /// [`Field::params`]); outside the polygon, the nearest cell's, as
    /// [`Field::value_at_params`] extends. Quads: row-major cells. Triangles: per row k the
    /// "up" triangle of cell i, then its "down" neighbour (row k starts at n² − (n − k)²).
    pub(crate) fn element_at_params(&self, p: DVec2) -> u32 {
        match self.grid {
            // Refined: the parameters are plane coordinates.
            Grid::Elements(ref locator) => locator.element_at(p),
            Grid::Quad { nu, nv, .. } => {
                let i = clamp_cell(p.x * f64::from(nu), nu);
                let j = clamp_cell(p.y * f64::from(nv), nv);
                j * nu + i
            }
            Grid::Triangle { n, .. } => {
                let (x, y) = (p.x * f64::from(n), p.y * f64::from(n));
                let k = clamp_cell(y, n);
                let i = clamp_cell(x, n - k);
                let (fx, fy) = (x - f64::from(i), y - f64::from(k));
                let down = fx + fy > 1.0 && i + 1 < n - k;
                n * n - (n - k) * (n - k) + 2 * i + u32::from(down)
            }
        }
    }
}

/// For each polygon, the other polygons that are coplanar with it (same facing, within
/// `tol`), of the same material, and whose bounding boxes touch its own (sweep over x).
fn coplanar_neighbours(polygons: &[Polygon], fields: &[Field], tol: f64) -> Vec<Vec<usize>> {
    let boxes: Vec<(DVec3, DVec3)> = polygons
        .iter()
        .map(|p| {
            let lo = p.vertices.iter().fold(DVec3::INFINITY, |m, v| m.min(*v));
            let hi = p
                .vertices
                .iter()
                .fold(DVec3::NEG_INFINITY, |m, v| m.max(*v));
            (lo - DVec3::splat(tol), hi + DVec3::splat(tol))
        })
        .collect();
    let mut order: Vec<usize> = (0..polygons.len()).collect();
    order.sort_by(|&a, &b| boxes[a].0.x.total_cmp(&boxes[b].0.x).then(a.cmp(&b)));
    let mut out = vec![Vec::new(); polygons.len()];
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            if boxes[b].0.x > boxes[a].1.x {
                break;
            }
            let overlap = (0..3).all(|axis| {
                boxes[a].0[axis] <= boxes[b].1[axis] && boxes[b].0[axis] <= boxes[a].1[axis]
            });
            if overlap && coplanar(&polygons[a], &polygons[b], &fields[a], tol) {
                out[a].push(b);
                out[b].push(a);
            }
        }
    }
    for list in &mut out {
        list.sort_unstable();
    }
    out
}

fn coplanar(a: &Polygon, b: &Polygon, field_a: &Field, tol: f64) -> bool {
    a.material == b.material
        && a.normal.dot(b.normal) > 1.0 - 1e-9
        && b.vertices
            .iter()
            .all(|v| (*v - a.vertices[0]).dot(field_a.normal).abs() <= tol)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_bilinear_recovers_parameters() {
        let (a, b, c, d) = (
            DVec2::new(0.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(1.5, 1.0),
            DVec2::new(0.5, 1.0),
        );
        for &(s, t) in &[(0.0, 0.0), (0.3, 0.7), (1.0, 1.0), (0.5, 0.5), (-0.1, 1.05)] {
            let q = (a.lerp(b, s)).lerp(d.lerp(c, s), t);
            let p = inverse_bilinear(q, a, b, c, d);
            assert!((p - DVec2::new(s, t)).length() < 1e-12, "{s} {t}: {p}");
        }
        // A rectangle (k2 = 0).
        let r = [
            DVec2::new(1.0, 1.0),
            DVec2::new(4.0, 1.0),
            DVec2::new(4.0, 3.0),
            DVec2::new(1.0, 3.0),
        ];
        let p = inverse_bilinear(DVec2::new(2.5, 2.5), r[0], r[1], r[2], r[3]);
        assert!((p - DVec2::new(0.5, 0.75)).length() < 1e-12);
    }
}
