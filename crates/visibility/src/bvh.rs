//! The obvhs CWBVH over the occluders' bounding boxes, used only to find candidates: every hit
//! is confirmed by the exact f64 test of [`Piece::hits_segment`], so the f32 tree only has to be
//! conservative, never exact.
//!
//! Conservative in f32:
//! - coordinates are stored relative to the scene's centre in units of its size, so every
//!   coordinate is ≤ 1 and f32 rounding is ~6e-8 of the scene whatever its size or position;
//! - every box is padded by [`PAD`] (≈ 1.7e3 f32 ulps of the unit scene), so flat boxes (a floor)
//!   have thickness and rounding in the slab test cannot drop a segment that touches a polygon;
//! - obvhs's node test ignores boxes the ray leaves before t = 1e-4 (a fixed epsilon in its
//!   `CwBvhNode::intersect_ray`); rays start [`BACKUP`] before the segment so that nothing on
//!   the segment is that close to the ray origin.

use crate::geometry::Piece;
use glam::{DVec3, UVec2, Vec3A};
use obvhs::cwbvh::node::{extract_byte64, CwBvhNode};
use obvhs::{aabb::Aabb, cwbvh::CwBvh, ray::Ray, Boundable, BvhBuildParams};
use std::time::Duration;

/// Box padding, in scene units.
const PAD: f32 = 1e-4;
/// How far before the segment's start each ray begins, in scene units (> obvhs's 1e-4).
const BACKUP: f64 = 4e-4;

/// An occluder's padded box, in scene units.
struct Boxed(Aabb);

impl Boundable for Boxed {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// A CWBVH over the pieces' boxes, in the scene frame `(x − centre) / scale`.
pub(crate) struct Tree {
    bvh: CwBvh,
    centre: DVec3,
    scale: f64,
}

impl Tree {
    /// `None` when there is nothing to put in the tree.
    pub fn new(pieces: &[Piece], centre: DVec3, scale: f64) -> Option<Tree> {
        if pieces.is_empty() {
            return None;
        }
        let boxes: Vec<Boxed> = pieces
            .iter()
            .map(|p| {
                let lo = ((p.lo - centre) / scale).as_vec3a() - PAD;
                let hi = ((p.hi - centre) / scale).as_vec3a() + PAD;
                Boxed(Aabb::new(lo, hi))
            })
            .collect();
        let bvh = obvhs::cwbvh::builder::build_cwbvh(
            &boxes,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        Some(Tree { bvh, centre, scale })
    }

    /// Whether `hit(piece)` is true for some piece whose box the segment p–q may cross. Stops at
    /// the first. The answer does not depend on the tree's shape or traversal order.
    #[inline]
    pub fn any_on_segment(&self, p: DVec3, q: DVec3, mut hit: impl FnMut(usize) -> bool) -> bool {
        let d = q - p;
        let len = d.length() / self.scale;
        if len.is_nan() || len <= 0.0 {
            return false;
        }
        let dir = d / (len * self.scale);
        let origin = (p - self.centre) / self.scale - dir * BACKUP;
        let ray = Ray::new(
            origin.as_vec3a(),
            dir.as_vec3a(),
            0.0,
            (len + 2.0 * BACKUP) as f32,
        );
        let indices = &self.bvh.primitive_indices;
        !self.bvh.ray_traverse_miss(ray, |_, id| {
            if hit(indices[id] as usize) {
                0.0
            } else {
                f32::INFINITY
            }
        })
    }

    /// Calls `visit(piece)` for every piece whose box the segment p–q may cross (in no
    /// particular order: callers that want the nearest compare distances themselves).
    pub fn each_on_segment(&self, p: DVec3, q: DVec3, mut visit: impl FnMut(usize)) {
        self.any_on_segment(p, q, |k| {
            visit(k);
            false
        });
    }

    /// The box lo–hi (world units) in the tree's frame, padded.
    fn query_box(&self, lo: DVec3, hi: DVec3) -> Aabb {
        Aabb::new(
            ((lo - self.centre) / self.scale).as_vec3a() - PAD,
            ((hi - self.centre) / self.scale).as_vec3a() + PAD,
        )
    }

    /// Whether `pred(piece)` holds for some piece whose padded box overlaps the box lo–hi (world
    /// units). Stops at the first (the answer does not depend on the traversal order).
    pub fn any_in_box(&self, lo: DVec3, hi: DVec3, pred: impl FnMut(usize) -> bool) -> bool {
        let query = self.query_box(lo, hi);
        self.any_where(|node, oct| node.intersect_aabb(&query, oct), pred)
    }

    /// Whether `pred(piece)` holds for some piece whose padded box may overlap `hull` (see
    /// [`Slabs`]). Stops at the first (the answer does not depend on the traversal order).
    pub fn any_in_slabs(&self, hull: &Slabs, pred: impl FnMut(usize) -> bool) -> bool {
        let local = hull.local(self);
        self.any_where(|node, oct| local.hit_mask(node, oct), pred)
    }

    /// Whether `pred(piece)` holds for some piece whose padded box may reach the half-space
    /// `n · x > d` (world units; `n` a unit vector). Stops at the first.
    pub fn any_in_front(&self, n: DVec3, d: f64, pred: impl FnMut(usize) -> bool) -> bool {
        // The frame's scale is uniform: n is unchanged, d moves with the centre.
        let local = Vec3A::from(n.as_vec3());
        let level = ((d - n.dot(self.centre)) / self.scale) as f32 - PAD;
        self.any_where(
            |node, oct| {
                child_mask(node, oct, |centre, half| {
                    local.dot(centre) + local.abs().dot(half) > level
                })
            },
            pred,
        )
    }

    /// Calls `f(piece)` for every piece whose padded box overlaps the box lo–hi (world units).
    pub fn for_each_in_box(&self, lo: DVec3, hi: DVec3, f: impl FnMut(usize)) {
        let query = self.query_box(lo, hi);
        self.for_each_where(|node, oct| node.intersect_aabb(&query, oct), f);
    }

    /// Calls `f(piece)` for every piece whose padded box may overlap `hull` (see [`Slabs`]).
    pub fn for_each_in_slabs(&self, hull: &Slabs, f: impl FnMut(usize)) {
        let local = hull.local(self);
        self.for_each_where(|node, oct| local.hit_mask(node, oct), f);
    }

    /// Whether `pred(piece)` holds for some piece in a leaf that `test` (obvhs's child hit mask
    /// of a node, given the traversal's `oct_inv4`) reaches. Stops at the first.
    #[inline]
    fn any_where(
        &self,
        test: impl Fn(&CwBvhNode, u32) -> u32,
        mut pred: impl FnMut(usize) -> bool,
    ) -> bool {
        let bvh = &self.bvh;
        let mut state = bvh.new_traversal(Vec3A::ONE);
        let mut node;
        let mut found = false;
        obvhs::traverse!(
            bvh,
            node,
            state,
            // Once found, no node is entered again: the traversal only drains its stack.
            if found { 0 } else { test(node, state.oct_inv4) },
            {
                if !found && pred(bvh.primitive_indices[state.primitive_id as usize] as usize) {
                    found = true;
                    state.primitive_group.y = 0;
                }
            }
        );
        found
    }

    /// Calls `f(piece)` for every piece in a leaf that `test` reaches (see [`Tree::any_where`]).
    #[inline]
    fn for_each_where(&self, test: impl Fn(&CwBvhNode, u32) -> u32, mut f: impl FnMut(usize)) {
        let bvh = &self.bvh;
        let mut state = bvh.new_traversal(Vec3A::ONE);
        let mut node;
        obvhs::traverse!(bvh, node, state, test(node, state.oct_inv4), {
            f(bvh.primitive_indices[state.primitive_id as usize] as usize);
        });
    }
}

/// Most axes a [`Slabs`] holds: x, y, z, the receiver's normal, one per receiver edge.
const MAX_AXES: usize = 8;

/// A convex region (world units) as the intervals of its points' projections on a few axes.
/// A box is kept from a query when no axis separates it from the region: the separating-axis
/// theorem with a subset of the axes, so the query is conservative (never drops a box that
/// meets the region) and exact for the region's own face normals. Used for the volume a
/// receiver's light segments sweep: its bounding box alone is most of the scene for a slanted
/// sun (issue 29: a sun's candidate search was 46% of an 85 k-polygon bake).
pub(crate) struct Slabs {
    axes: [DVec3; MAX_AXES],
    lo: [f64; MAX_AXES],
    hi: [f64; MAX_AXES],
    count: usize,
}

impl Slabs {
    /// The convex hull of `points` tested along x, y, z and the given `axes` (at most
    /// `MAX_AXES − 3`; zero and non-finite ones are skipped).
    pub fn new(points: &[DVec3], axes: &[DVec3]) -> Slabs {
        let mut slabs = Slabs {
            axes: [DVec3::ZERO; MAX_AXES],
            lo: [f64::INFINITY; MAX_AXES],
            hi: [f64::NEG_INFINITY; MAX_AXES],
            count: 0,
        };
        for &a in [DVec3::X, DVec3::Y, DVec3::Z].iter().chain(axes) {
            let a = a.normalize_or_zero();
            if a == DVec3::ZERO || slabs.count == MAX_AXES {
                continue;
            }
            let k = slabs.count;
            slabs.axes[k] = a;
            for p in points {
                let h = a.dot(*p);
                slabs.lo[k] = slabs.lo[k].min(h);
                slabs.hi[k] = slabs.hi[k].max(h);
            }
            slabs.count += 1;
        }
        slabs
    }

    /// The same region in the tree's frame, in f32, each interval padded by [`PAD`] (the
    /// frame's rounding is ~6e-8; the axes are unit vectors, unchanged by the frame's uniform
    /// scale).
    fn local(&self, tree: &Tree) -> LocalSlabs {
        let mut out = LocalSlabs {
            axes: [Vec3A::ZERO; MAX_AXES],
            lo: [0.0; MAX_AXES],
            hi: [0.0; MAX_AXES],
            count: self.count,
        };
        for k in 0..self.count {
            let a = self.axes[k];
            let shift = a.dot(tree.centre);
            out.axes[k] = a.as_vec3a();
            out.lo[k] = ((self.lo[k] - shift) / tree.scale) as f32 - PAD;
            out.hi[k] = ((self.hi[k] - shift) / tree.scale) as f32 + PAD;
        }
        out
    }
}

/// [`Slabs`] in a tree's frame.
struct LocalSlabs {
    axes: [Vec3A; MAX_AXES],
    lo: [f32; MAX_AXES],
    hi: [f32; MAX_AXES],
    count: usize,
}

impl LocalSlabs {
    /// obvhs's hit mask of the node's children whose boxes no axis separates from the region
    /// (built as `CwBvhNode::intersect_aabb` builds it).
    #[inline]
    fn hit_mask(&self, node: &CwBvhNode, oct_inv4: u32) -> u32 {
        child_mask(node, oct_inv4, |centre, half| {
            !(0..self.count).any(|k| {
                let a = self.axes[k];
                let c = a.dot(centre);
                let r = a.abs().dot(half);
                c + r < self.lo[k] || c - r > self.hi[k]
            })
        })
    }
}

/// obvhs's hit mask of the node's children whose boxes (centre, half size) `keep` keeps
/// (built as `CwBvhNode::intersect_aabb` builds it).
#[inline]
fn child_mask(node: &CwBvhNode, oct_inv4: u32, keep: impl Fn(Vec3A, Vec3A) -> bool) -> u32 {
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut mask = 0;
    for child in 0..8 {
        let b = node.child_aabb(child);
        if keep((b.min + b.max) * 0.5, (b.max - b.min) * 0.5) {
            mask |= extract_byte64(child_bits8, child) << extract_byte64(bit_index8, child);
        }
    }
    mask
}
