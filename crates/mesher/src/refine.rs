//! Below the grid: splitting chosen elements (quads 2 × 2 at their edge midpoints, triangles
//! into 4 by their edge midpoints), the hanging vertices those splits leave on neighbours'
//! edges, vertex copies at discontinuities, and the conforming triangulation of an element
//! that uses its hanging vertices (no T-junctions in a vertex bake).
//!
//! Midpoints are `(a + b) / 2` of the edge's end positions (addition commutes in IEEE
//! arithmetic, so both elements along an edge compute the same bits): a polygon's vertices are
//! keyed by their position bits, and an element's edge has a hanging vertex exactly where the
//! position of its midpoint is a vertex of the polygon (recursively, for deeper splits).

use crate::{element, ElementMesh, MeshError, PatchGrid, MAX_ELEMENTS};
use glam::DVec3;
use std::collections::HashMap;

/// A refined mesh and where its elements came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Refined {
    pub mesh: ElementMesh,
    /// Per element of the new mesh: the element of the old one it is, or is a quarter of.
    pub parent: Vec<u32>,
    /// How many elements were split.
    pub split: usize,
}

/// Position bits of a vertex (−0 and +0 are one position).
fn key(p: DVec3) -> [u64; 3] {
    p.to_array().map(|c| (c + 0.0).to_bits())
}

/// The vertex at the midpoint of `a` and `b`, pushed on first use.
fn midpoint(vertices: &mut Vec<DVec3>, at: &mut HashMap<[u64; 3], u32>, a: u32, b: u32) -> u32 {
    let p = (vertices[a as usize] + vertices[b as usize]) * 0.5;
    *at.entry(key(p)).or_insert_with(|| {
        vertices.push(p);
        (vertices.len() - 1) as u32
    })
}

impl ElementMesh {
    /// Whether the mesh is still the mesher's regular grids (nothing refined or split).
    pub fn is_grid(&self) -> bool {
        self.outlines.is_empty()
    }

    /// Element `i`'s boundary loop: its corners and, on a refined mesh, the hanging vertices
    /// on its edges, counter-clockwise from corner 0.
    pub fn outline(&self, i: usize) -> &[u32] {
        match self.outlines.get(i) {
            Some(o) => o,
            None => self.elements[i].corner_indices(),
        }
    }

    /// How many times element `i` was split below the grid.
    pub fn level(&self, i: usize) -> u8 {
        self.levels.get(i).copied().unwrap_or(0)
    }

    /// Element `i` as triangles (mesh vertex indices, counter-clockwise) that use every vertex
    /// of its outline, so neighbours share their edges (no T-junctions). Without hanging
    /// vertices that is the grid's split, (0, 1, 2) and (0, 2, 3); with them, ears are clipped
    /// at the first vertex (in outline order) where the remaining polygon turns strictly and
    /// keeps an area, so each triangle has an area and the hanging vertices are all used.
    pub fn triangles(&self, i: usize, out: &mut Vec<[u32; 3]>) {
        out.clear();
        let e = &self.elements[i];
        let o = self.outline(i);
        if o.len() == e.sides as usize {
            for k in 1..o.len() - 1 {
                out.push([o[0], o[k], o[k + 1]]);
            }
            return;
        }
        let p = |v: u32| self.vertices[v as usize];
        let n = e.normal;
        // Strictly to the left of the line a→b (relative to the lengths: hanging vertices are
        // collinear up to rounding).
        let left = |a: u32, b: u32, x: u32| {
            let (d, r) = (p(b) - p(a), p(x) - p(a));
            d.cross(r).dot(n) > 1e-9 * d.length() * r.length()
        };
        let mut poly: Vec<u32> = o.to_vec();
        while poly.len() > 3 {
            let m = poly.len();
            let ear = (0..m).find(|&k| {
                let (u, v, w) = (poly[(k + m - 1) % m], poly[k], poly[(k + 1) % m]);
                left(u, v, w)
                    && poly
                        .iter()
                        .any(|&x| x != u && x != v && x != w && left(u, w, x))
            });
            let Some(k) = ear else { break };
            out.push([poly[(k + m - 1) % m], poly[k], poly[(k + 1) % m]]);
            poly.remove(k);
        }
        if poly.len() == 3 && left(poly[0], poly[1], poly[2]) {
            out.push([poly[0], poly[1], poly[2]]);
        }
    }

    /// Splits every element `split` marks: a quad into four at its edge midpoints and the
    /// mean of its corners (the quad's bimedians cross there), a triangle into four at its
    /// edge midpoints. Other elements are kept as they are; midpoints shared with a neighbour
    /// become hanging vertices on its edge ([`ElementMesh::outline`]). Each polygon keeps a
    /// contiguous vertex and element range (its old vertices first, in order).
    pub fn refine(&self, split: &[bool]) -> Result<Refined, MeshError> {
        let count = split.iter().filter(|&&s| s).count();
        let total = self.elements.len() as u64 + 3 * count as u64;
        if total > MAX_ELEMENTS {
            return Err(MeshError::TooManyElements(total.to_string()));
        }
        let mut out = ElementMesh::default();
        let mut parent = Vec::with_capacity(total as usize);
        let mut levels = Vec::with_capacity(total as usize);
        for patch in &self.patches {
            let v0 = out.vertices.len() as u32;
            let e0 = out.elements.len() as u32;
            let mut at: HashMap<[u64; 3], u32> = HashMap::new();
            for v in patch.vertices.clone() {
                let p = self.vertices[v as usize];
                at.insert(key(p), out.vertices.len() as u32);
                out.vertices.push(p);
            }
            let remap = |v: u32| {
                patch
                    .vertices
                    .contains(&v)
                    .then(|| v - patch.vertices.start + v0)
                    .ok_or_else(|| {
                        MeshError::InvalidSubdivision(format!(
                            "vertex {v} lies outside its polygon's vertex range"
                        ))
                    })
            };
            for i in patch.elements.clone() {
                let e = &self.elements[i as usize];
                let sides = e.sides as usize;
                let mut c = [0u32; 4];
                for (slot, &corner) in c.iter_mut().zip(&e.corners) {
                    *slot = remap(corner)?;
                }
                let level = self.level(i as usize);
                if !split.get(i as usize).copied().unwrap_or(false) {
                    out.elements.push(crate::Element { corners: c, ..*e });
                    parent.push(i);
                    levels.push(level);
                    continue;
                }
                let v = &mut out.vertices;
                let m: Vec<u32> = (0..sides)
                    .map(|k| midpoint(v, &mut at, c[k], c[(k + 1) % sides]))
                    .collect();
                let children: Vec<([u32; 4], u8)> = if sides == 4 {
                    let centre =
                        (v[c[0] as usize] + v[c[1] as usize] + v[c[2] as usize] + v[c[3] as usize])
                            * 0.25;
                    let mid = *at.entry(key(centre)).or_insert_with(|| {
                        v.push(centre);
                        (v.len() - 1) as u32
                    });
                    vec![
                        ([c[0], m[0], mid, m[3]], 4),
                        ([m[0], c[1], m[1], mid], 4),
                        ([mid, m[1], c[2], m[2]], 4),
                        ([m[3], mid, m[2], c[3]], 4),
                    ]
                } else {
                    vec![
                        ([c[0], m[0], m[2], m[2]], 3),
                        ([m[0], c[1], m[1], m[1]], 3),
                        ([m[2], m[1], c[2], c[2]], 3),
                        ([m[0], m[1], m[2], m[2]], 3),
                    ]
                };
                for (corners, sides) in children {
                    out.elements
                        .push(element(&out.vertices, e.polygon, corners, sides, e.normal));
                    parent.push(i);
                    levels.push(level.saturating_add(1));
                }
            }
            out.patches.push(PatchGrid {
                vertices: v0..out.vertices.len() as u32,
                elements: e0..out.elements.len() as u32,
            });
        }
        out.levels = levels;
        if count > 0 || !self.is_grid() {
            out.outlines = outlines(&out);
        }
        Ok(Refined {
            mesh: out,
            parent,
            split: count,
        })
    }

    /// Gives each vertex one copy per class of the elements around it (`class`, one per
    /// element: elements of one class may be smoothed together, e.g. lit alike by every
    /// light), so that smoothing and the lightmap's reconstruction never blend across a
    /// discontinuity. The copies are at the same position: the mesh stays conforming. The
    /// outline segments whose two ends were copied are recorded in
    /// [`ElementMesh::discontinuities`] (as the first copies' indices). Returns the mesh
    /// unchanged when every vertex has one class.
    pub fn split_at_discontinuities(&self, class: &[u64]) -> ElementMesh {
        let n = self.elements.len();
        let class_of = |i: usize| class.get(i).copied().unwrap_or(0);
        // The first class (in element order) that touches each vertex keeps it.
        let mut first: Vec<Option<u64>> = vec![None; self.vertices.len()];
        let mut multi = vec![false; self.vertices.len()];
        for i in 0..n {
            for &v in self.outline(i) {
                let slot = &mut first[v as usize];
                match slot {
                    None => *slot = Some(class_of(i)),
                    Some(c) if *c != class_of(i) => multi[v as usize] = true,
                    _ => {}
                }
            }
        }
        if !multi.iter().any(|&m| m) {
            return self.clone();
        }
        let mut out = ElementMesh {
            levels: self.levels.clone(),
            ..ElementMesh::default()
        };
        let mut outlines = Vec::with_capacity(n);
        let mut elements = Vec::with_capacity(n);
        let mut discontinuities = std::collections::BTreeSet::new();
        for patch in &self.patches {
            let v0 = out.vertices.len() as u32;
            let local = |v: u32| v.wrapping_sub(patch.vertices.start).wrapping_add(v0);
            out.vertices
                .extend(patch.vertices.clone().map(|v| self.vertices[v as usize]));
            let mut copies: HashMap<(u32, u64), u32> = HashMap::new();
            for i in patch.elements.clone() {
                let i = i as usize;
                let c = class_of(i);
                let mut copy = |v: u32| -> u32 {
                    if first[v as usize] == Some(c) {
                        return local(v);
                    }
                    *copies.entry((v, c)).or_insert_with(|| {
                        out.vertices.push(self.vertices[v as usize]);
                        (out.vertices.len() - 1) as u32
                    })
                };
                let o: Vec<u32> = self.outline(i).iter().map(|&v| copy(v)).collect();
                let e = &self.elements[i];
                let mut corners = e.corners;
                for k in corners.iter_mut() {
                    *k = copy(*k);
                }
                elements.push(crate::Element { corners, ..*e });
                let raw = self.outline(i);
                for k in 0..raw.len() {
                    let (a, b) = (raw[k], raw[(k + 1) % raw.len()]);
                    if multi[a as usize] && multi[b as usize] {
                        discontinuities.insert([local(a.min(b)), local(a.max(b))]);
                    }
                }
                outlines.push(o);
            }
            out.patches.push(PatchGrid {
                vertices: v0..out.vertices.len() as u32,
                elements: patch.elements.clone(),
            });
        }
        out.elements = elements;
        out.outlines = outlines;
        out.discontinuities = discontinuities.into_iter().collect();
        out
    }
}

/// Every element's outline: its corners with the hanging vertices on each edge between them.
fn outlines(mesh: &ElementMesh) -> Vec<Vec<u32>> {
    let mut all = Vec::with_capacity(mesh.elements.len());
    for patch in &mesh.patches {
        let at: HashMap<[u64; 3], u32> = patch
            .vertices
            .clone()
            .map(|v| (key(mesh.vertices[v as usize]), v))
            .collect();
        for i in patch.elements.clone() {
            let e = &mesh.elements[i as usize];
            let c = e.corner_indices();
            let mut o = Vec::with_capacity(c.len());
            for k in 0..c.len() {
                o.push(c[k]);
                hanging(&mesh.vertices, &at, c[k], c[(k + 1) % c.len()], &mut o, 0);
            }
            all.push(o);
        }
    }
    all
}

/// Appends the vertices strictly inside edge a→b, in order from a.
fn hanging(
    vertices: &[DVec3],
    at: &HashMap<[u64; 3], u32>,
    a: u32,
    b: u32,
    out: &mut Vec<u32>,
    depth: u32,
) {
    // 2^-60 of an edge is below f64 resolution: no split goes deeper.
    if depth > 60 {
        return;
    }
    let m = (vertices[a as usize] + vertices[b as usize]) * 0.5;
    if let Some(&k) = at.get(&key(m)) {
        if k != a && k != b {
            hanging(vertices, at, a, k, out, depth + 1);
            out.push(k);
            hanging(vertices, at, k, b, out, depth + 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::tests::polygon;
    use crate::{mesh, ElementMesh, Subdivision};
    use glam::DVec3;
    use scene::Polygon;
    use std::collections::HashMap;

    fn shapes() -> Vec<Polygon> {
        vec![
            polygon(vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(1.5, 1.0, 0.0),
                DVec3::new(0.5, 1.0, 0.0),
            ]),
            polygon(vec![
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(3.0, 0.0, 1.0),
                DVec3::new(0.0, 2.0, 1.0),
            ]),
        ]
    }

    /// The triangles of every element of a polygon, as position-keyed edges: each interior
    /// edge must be used exactly twice (once each way), each boundary edge once.
    fn check_conforming(m: &ElementMesh, polygons: &[Polygon]) {
        let mut tris = Vec::new();
        for (p, patch) in m.patches.iter().enumerate() {
            let mut edges: HashMap<([u64; 3], [u64; 3]), i32> = HashMap::new();
            let mut area = 0.0;
            let k = |v: u32| m.vertices[v as usize].to_array().map(f64::to_bits);
            for i in patch.elements.clone() {
                m.triangles(i as usize, &mut tris);
                for t in &tris {
                    let [a, b, c] = t.map(|v| m.vertices[v as usize]);
                    let ta = (b - a).cross(c - a).dot(polygons[p].normal) / 2.0;
                    assert!(ta > 0.0, "degenerate or flipped triangle {t:?}");
                    area += ta;
                    for e in 0..3 {
                        let (u, v) = (t[e], t[(e + 1) % 3]);
                        *edges.entry((k(u), k(v))).or_default() += 1;
                    }
                }
            }
            let want: f64 = m.elements[patch.elements.start as usize..patch.elements.end as usize]
                .iter()
                .map(|e| e.area)
                .sum();
            assert!((area - want).abs() < 1e-12 * want);
            for (&(u, v), &count) in &edges {
                let back = edges.get(&(v, u)).copied().unwrap_or(0);
                assert_eq!(count, 1, "edge used {count} times one way");
                if back == 0 {
                    // On the polygon's boundary.
                    let (pu, pv) = (
                        DVec3::from_array(u.map(f64::from_bits)),
                        DVec3::from_array(v.map(f64::from_bits)),
                    );
                    let on = polygons[p].vertices.iter().enumerate().any(|(j, &a)| {
                        let b = polygons[p].vertices[(j + 1) % polygons[p].vertices.len()];
                        let d = (b - a).normalize();
                        (pu - a).cross(d).length() < 1e-12 && (pv - a).cross(d).length() < 1e-12
                    });
                    assert!(on, "open edge inside polygon {p}: {pu} {pv}");
                }
            }
        }
    }

    #[test]
    fn refining_splits_and_keeps_areas_and_conformity() {
        let polygons = shapes();
        let m = mesh(&polygons, Subdivision::Count(3)).unwrap();
        assert!(m.is_grid());
        check_conforming(&m, &polygons);
        // Split one element per polygon, then one child of it again: hanging vertices two
        // levels deep on the neighbours.
        let mut split = vec![false; m.elements.len()];
        split[4] = true;
        split[9 + 4] = true;
        let r = m.refine(&split).unwrap();
        assert_eq!(r.split, 2);
        assert_eq!(r.mesh.elements.len(), m.elements.len() + 6);
        assert!(!r.mesh.is_grid());
        check_conforming(&r.mesh, &polygons);
        let mut again = vec![false; r.mesh.elements.len()];
        again[5] = true; // a child of element 4 (children follow the kept elements 0..4)
        let kid_of_triangle = r.mesh.patches[1].elements.start as usize + 5;
        again[kid_of_triangle] = true;
        let r2 = r.mesh.refine(&again).unwrap();
        assert_eq!(r2.mesh.level(6), 2);
        check_conforming(&r2.mesh, &polygons);
        for (p, patch) in r2.mesh.patches.iter().enumerate() {
            let area: f64 = r2.mesh.elements
                [patch.elements.start as usize..patch.elements.end as usize]
                .iter()
                .map(|e| e.area)
                .sum();
            let want = [1.5, 3.0][p];
            assert!((area - want).abs() < 1e-12, "{area}");
        }
        // Some neighbour has hanging vertices.
        assert!(r2.mesh.outlines.iter().any(|o| o.len() > 4));
        // The grid's triangles are unchanged where nothing was split.
        let mut t = Vec::new();
        m.triangles(0, &mut t);
        let c = m.elements[0].corners;
        assert_eq!(t, vec![[c[0], c[1], c[2]], [c[0], c[2], c[3]]]);
    }

    #[test]
    fn smoothing_on_a_refined_mesh_reproduces_a_linear_field_at_grid_vertices() {
        // Constant light: every vertex, hanging ones included, gets exactly the constant.
        let polygons = shapes();
        let m = mesh(&polygons, Subdivision::Count(2)).unwrap();
        let mut split = vec![false; m.elements.len()];
        split[0] = true;
        let r = m.refine(&split).unwrap().mesh;
        let values = vec![[2.5, 1.0, 0.0]; r.elements.len()];
        for v in r.smooth(&values) {
            assert_eq!(v, [2.5, 1.0, 0.0]);
        }
    }

    #[test]
    fn discontinuities_get_one_vertex_copy_per_side() {
        let polygons = shapes();
        let m = mesh(&polygons[..1], Subdivision::Count(2)).unwrap();
        // Left column lit (class 1), right column dark (class 0).
        let class: Vec<u64> = m
            .elements
            .iter()
            .map(|e| u64::from(e.centroid.x < 1.0))
            .collect();
        let values: Vec<[f64; 3]> = class.iter().map(|&c| [c as f64 * 10.0; 3]).collect();
        let s = m.split_at_discontinuities(&class);
        // The middle column of 3 vertices is duplicated.
        assert_eq!(s.vertices.len(), m.vertices.len() + 3);
        assert_eq!(s.discontinuities.len(), 2);
        let smoothed = s.smooth(&values);
        for (i, e) in s.elements.iter().enumerate() {
            for &v in s.outline(i) {
                assert_eq!(
                    smoothed[v as usize], values[i],
                    "element {i} at {}",
                    e.centroid
                );
            }
        }
        check_conforming(&s, &polygons[..1]);
        // One class: unchanged.
        assert_eq!(m.split_at_discontinuities(&vec![7; m.elements.len()]), m);
    }
}
