//! The per-polygon trees of the hierarchy (HSA91: each polygon the root of a tree whose
//! leaves are its elements): nodes, child lists, and per-node ranges of element values.

use super::*;

/// A node of a polygon's tree.
#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    pub(super) surface: Surface,
    pub(super) polygon: u32,
    /// Children: `children[first..first + count]`; no children for a leaf.
    pub(super) first: u32,
    pub(super) count: u32,
}

pub(super) fn patch(node: &Node) -> Patch {
    let s = &node.surface;
    // Sides are 3 or 4 by construction.
    Patch::new(s.corners(), s.normal, node.polygon as usize)
        .unwrap_or_else(|| unreachable!("hierarchy nodes are triangles or quads"))
}

pub(super) fn max3(v: [f64; BANDS]) -> f64 {
    v[0].max(v[1]).max(v[2])
}

/// Per node: the largest of `values` (one per element) over its elements, and that maximum
/// minus the smallest.
pub(super) fn node_range(
    nodes: &[Node],
    children: &[u32],
    n: usize,
    values: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let mut hi = vec![0.0; nodes.len()];
    let mut lo = vec![0.0; nodes.len()];
    hi[..n].copy_from_slice(&values[..n]);
    lo[..n].copy_from_slice(&values[..n]);
    for u in n..nodes.len() {
        let node = &nodes[u];
        let (mut h, mut l) = (f64::NEG_INFINITY, f64::INFINITY);
        for &c in &children[node.first as usize..(node.first + node.count) as usize] {
            h = h.max(hi[c as usize]);
            l = l.min(lo[c as usize]);
        }
        (hi[u], lo[u]) = if h >= l { (h, l) } else { (0.0, 0.0) };
    }
    let spread = hi.iter().zip(&lo).map(|(h, l)| h - l).collect();
    (hi, spread)
}

/// Per node: how many elements (leaves) lie below it.
pub(super) fn leaf_counts(nodes: &[Node], children: &[u32], n: usize) -> Vec<u64> {
    let mut out = vec![1u64; nodes.len()];
    for u in n..nodes.len() {
        let node = &nodes[u];
        out[u] = children[node.first as usize..(node.first + node.count) as usize]
            .iter()
            .map(|&c| out[c as usize])
            .sum();
    }
    out
}

/// Per node: the largest band of `values` (per element), maxed over each node's leaves.
pub(super) fn node_max(
    nodes: &[Node],
    children: &[u32],
    n: usize,
    values: &[[f64; BANDS]],
) -> Vec<f64> {
    let mut out = vec![0.0; nodes.len()];
    for (o, v) in out.iter_mut().zip(values).take(n) {
        *o = max3(*v);
    }
    for u in n..nodes.len() {
        let node = &nodes[u];
        let mut m = 0.0f64;
        for &c in &children[node.first as usize..(node.first + node.count) as usize] {
            m = m.max(out[c as usize]);
        }
        out[u] = m;
    }
    out
}

/// Nodes, child lists and per-polygon roots.
pub(super) type Trees = (Vec<Node>, Vec<u32>, Vec<u32>);

/// The trees: nodes (elements first, then interior nodes, each after its children), the
/// child lists, and each polygon's root.
pub(super) fn build_trees(polygons: &[Polygon], mesh: &ElementMesh) -> Result<Trees, LinkError> {
    let n = mesh.elements.len();
    let mut nodes: Vec<Node> = (0..n)
        .map(|i| Node {
            surface: Surface::element(mesh, i),
            polygon: mesh.elements[i].polygon,
            first: 0,
            count: 0,
        })
        .collect();
    let mut children = Vec::new();
    let mut roots = Vec::with_capacity(polygons.len());
    for (k, (polygon, grid)) in polygons.iter().zip(&mesh.patches).enumerate() {
        if grid.elements.is_empty() {
            return Err(LinkError::Mesh(k));
        }
        let mut tree = Tree {
            mesh,
            nodes: &mut nodes,
            children: &mut children,
            polygon: k as u32,
            normal: polygon.normal,
            e0: grid.elements.start,
            v0: grid.vertices.start,
            cells: Vec::new(),
        };
        // A refined mesh: each grid element is its own subtree of quarters.
        if !mesh.levels.is_empty() {
            tree.refined_cells(grid.elements.clone())?;
        }
        let count = tree.cell_count(grid.elements.len() as u32);
        let root = if polygon.vertices.len() == 4 {
            // Row-major nu × nv grid: element k < nu of the first row starts at vertex k, the
            // first element of the second row at vertex nu + 1 (on a refined mesh: the first
            // quarter of grid element k starts at its corner 0).
            let nu = (0..count)
                .find(|&k| {
                    mesh.elements[tree.first_element(k) as usize].corners[0]
                        != grid.vertices.start + k
                })
                .unwrap_or(count);
            let nv = count / nu;
            let (lu, lv) = (
                polygon.vertices[0].distance(polygon.vertices[1]),
                polygon.vertices[0].distance(polygon.vertices[3]),
            );
            tree.quad(nu, [0, nu, 0, nv], lu / nu as f64, lv / nv as f64)
        } else {
            let side = (count as f64).sqrt().round() as u32;
            tree.up(side, 0, 0, side)
        };
        roots.push(root);
    }
    Ok((nodes, children, roots))
}

/// Builds one polygon's tree.
pub(super) struct Tree<'a> {
    pub(super) mesh: &'a ElementMesh,
    pub(super) nodes: &'a mut Vec<Node>,
    pub(super) children: &'a mut Vec<u32>,
    pub(super) polygon: u32,
    pub(super) normal: DVec3,
    pub(super) e0: u32,
    pub(super) v0: u32,
    /// On a refined mesh, per grid element (in grid order): its node (the element itself, or
    /// the root of the quarters it was split into) and its first element. Empty on the grids,
    /// where grid element k is element `e0 + k`.
    pub(super) cells: Vec<(u32, u32)>,
}

impl Tree<'_> {
    /// How many grid elements the polygon has (`elements` on the grids).
    pub(super) fn cell_count(&self, elements: u32) -> u32 {
        if self.cells.is_empty() {
            elements
        } else {
            self.cells.len() as u32
        }
    }

    /// The node of grid element k.
    pub(super) fn cell(&self, k: u32) -> u32 {
        self.cells.get(k as usize).map_or(self.e0 + k, |c| c.0)
    }

    /// The first element of grid element k.
    pub(super) fn first_element(&self, k: u32) -> u32 {
        self.cells.get(k as usize).map_or(self.e0 + k, |c| c.1)
    }

    /// The subtrees of a refined polygon's elements `range`: `ElementMesh::refine` keeps each
    /// element in place or replaces it by its four quarters (corner k of the parent is corner
    /// k of quarter k), so the elements are the grid's in order, each followed depth-first by
    /// its quarters, and their levels are enough to rebuild the splits.
    pub(super) fn refined_cells(&mut self, range: std::ops::Range<u32>) -> Result<(), LinkError> {
        let mut at = range.start;
        while at < range.end {
            let first = at;
            let node = self.quarters(&mut at, range.end, 0)?;
            self.cells.push((node, first));
        }
        Ok(())
    }

    /// The node of the element, or split element, at `at` of level `depth`.
    pub(super) fn quarters(&mut self, at: &mut u32, end: u32, depth: u8) -> Result<u32, LinkError> {
        let i = *at;
        let malformed = LinkError::Refinement(self.polygon as usize);
        if i >= end {
            return Err(malformed);
        }
        let level = self.mesh.level(i as usize);
        if level == depth {
            *at += 1;
            return Ok(i);
        }
        if level < depth || depth >= u8::MAX - 1 {
            return Err(malformed);
        }
        let sides = usize::from(self.mesh.elements[i as usize].sides);
        let mut kids = [0u32; 4];
        for kid in &mut kids {
            *kid = self.quarters(at, end, depth + 1)?;
        }
        // Corner k of the split element is corner k of its k-th quarter.
        let corners: Vec<DVec3> = (0..sides)
            .map(|k| self.nodes[kids[k] as usize].surface.corners[k])
            .collect();
        Ok(self.interior(&corners, &kids))
    }

    pub(super) fn vertex(&self, k: u32) -> DVec3 {
        self.mesh.vertices[(self.v0 + k) as usize]
    }

    /// An interior node over `kids` with these corners (area = the children's sum).
    pub(super) fn interior(&mut self, corners: &[DVec3], kids: &[u32]) -> u32 {
        let area: f64 = kids
            .iter()
            .map(|&c| self.nodes[c as usize].surface.area)
            .sum();
        let mut surface = Surface::new(corners, self.normal).unwrap_or_else(|| {
            // A sliver whose fan area rounds to 0: keep the children's area and centroid.
            let c = self.nodes[kids[0] as usize].surface;
            Surface { area, ..c }
        });
        surface.area = area;
        // The children's area-weighted centroid (equal to the corners' up to rounding), so that
        // pushing a linear function to the children keeps its mean exactly.
        surface.centroid = kids
            .iter()
            .map(|&c| {
                let s = &self.nodes[c as usize].surface;
                s.centroid * s.area
            })
            .sum::<DVec3>()
            / area;
        let first = self.children.len() as u32;
        self.children.extend_from_slice(kids);
        self.nodes.push(Node {
            surface,
            polygon: self.polygon,
            first,
            count: kids.len() as u32,
        });
        (self.nodes.len() - 1) as u32
    }

    /// Elements `[i0, i1) × [j0, j1)` of an nu-column quad grid, halved along the longer side
    /// (world lengths `du`, `dv` per column and row).
    pub(super) fn quad(&mut self, nu: u32, [i0, i1, j0, j1]: [u32; 4], du: f64, dv: f64) -> u32 {
        if i1 - i0 == 1 && j1 - j0 == 1 {
            return self.cell(j0 * nu + i0);
        }
        let split_i =
            j1 - j0 == 1 || (i1 - i0 > 1 && (i1 - i0) as f64 * du >= (j1 - j0) as f64 * dv);
        let (a, b) = if split_i {
            let m = (i0 + i1) / 2;
            (
                self.quad(nu, [i0, m, j0, j1], du, dv),
                self.quad(nu, [m, i1, j0, j1], du, dv),
            )
        } else {
            let m = (j0 + j1) / 2;
            (
                self.quad(nu, [i0, i1, j0, m], du, dv),
                self.quad(nu, [i0, i1, m, j1], du, dv),
            )
        };
        let id = |i: u32, j: u32| j * (nu + 1) + i;
        let corners = [
            self.vertex(id(i0, j0)),
            self.vertex(id(i1, j0)),
            self.vertex(id(i1, j1)),
            self.vertex(id(i0, j1)),
        ];
        self.interior(&corners, &[a, b])
    }

    /// Vertex (i, k) of an n-split triangle grid (row k holds n − k + 1 vertices).
    pub(super) fn tri_vertex(&self, n: u32, i: u32, k: u32) -> DVec3 {
        let row = k * (n + 1) - k * (k.saturating_sub(1)) / 2;
        // Σ_{k' < k} (n − k' + 1) = k (n + 1) − k (k − 1) / 2.
        self.vertex(row + i)
    }

    /// Element index of the upward (`down = false`) or downward triangle of cell (i, k).
    pub(super) fn tri_element(&self, n: u32, i: u32, k: u32, down: bool) -> u32 {
        // Row k holds 2 (n − k) − 1 elements: Σ_{k' < k} = 2 n k − k².
        self.cell(2 * n * k - k * k + 2 * i + u32::from(down))
    }

    /// The upward triangle of side m with corner cell (i0, k0).
    pub(super) fn up(&mut self, n: u32, i0: u32, k0: u32, m: u32) -> u32 {
        if m == 1 {
            return self.tri_element(n, i0, k0, false);
        }
        let kids = if m.is_multiple_of(2) {
            let h = m / 2;
            vec![
                self.up(n, i0, k0, h),
                self.up(n, i0 + h, k0, h),
                self.up(n, i0, k0 + h, h),
                self.down(n, i0, k0, h),
            ]
        } else {
            let mut kids = Vec::with_capacity((m * m) as usize);
            for r in 0..m {
                let k = k0 + r;
                for i in i0..i0 + (m - r) {
                    kids.push(self.tri_element(n, i, k, false));
                    if i + 1 < i0 + (m - r) {
                        kids.push(self.tri_element(n, i, k, true));
                    }
                }
            }
            kids
        };
        let corners = [
            self.tri_vertex(n, i0, k0),
            self.tri_vertex(n, i0 + m, k0),
            self.tri_vertex(n, i0, k0 + m),
        ];
        self.interior(&corners, &kids)
    }

    /// The downward triangle of side m with corners (i0 + m, k0), (i0 + m, k0 + m),
    /// (i0, k0 + m) in vertex coordinates.
    pub(super) fn down(&mut self, n: u32, i0: u32, k0: u32, m: u32) -> u32 {
        if m == 1 {
            return self.tri_element(n, i0, k0, true);
        }
        let kids = if m.is_multiple_of(2) {
            let h = m / 2;
            vec![
                self.down(n, i0 + h, k0, h),
                self.down(n, i0, k0 + h, h),
                self.down(n, i0 + h, k0 + h, h),
                self.up(n, i0 + h, k0 + h, h),
            ]
        } else {
            let mut kids = Vec::with_capacity((m * m) as usize);
            for r in 0..m {
                let k = k0 + r;
                // r + 1 downward cells ending at column i0 + m − 1, r upward ones between.
                for i in (i0 + m - 1 - r)..(i0 + m) {
                    kids.push(self.tri_element(n, i, k, true));
                    if i + 1 < i0 + m {
                        kids.push(self.tri_element(n, i + 1, k, false));
                    }
                }
            }
            kids
        };
        let corners = [
            self.tri_vertex(n, i0 + m, k0),
            self.tri_vertex(n, i0 + m, k0 + m),
            self.tri_vertex(n, i0, k0 + m),
        ];
        self.interior(&corners, &kids)
    }
}
