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

    /// The box lo–hi (world units) in the tree's frame, padded.
    fn query_box(&self, lo: DVec3, hi: DVec3) -> Aabb {
        Aabb::new(
            ((lo - self.centre) / self.scale).as_vec3a() - PAD,
            ((hi - self.centre) / self.scale).as_vec3a() + PAD,
        )
    }

    /// Whether `pred(piece)` holds for some piece whose padded box overlaps the box lo–hi (world
    /// units). Stops at the first (the answer does not depend on the traversal order).
    pub fn any_in_box(&self, lo: DVec3, hi: DVec3, mut pred: impl FnMut(usize) -> bool) -> bool {
        let query = self.query_box(lo, hi);
        let bvh = &self.bvh;
        let mut state = bvh.new_traversal(Vec3A::ONE);
        let mut node;
        let mut found = false;
        obvhs::traverse!(
            bvh,
            node,
            state,
            // Once found, no node is entered again: the traversal only drains its stack.
            if found {
                0
            } else {
                node.intersect_aabb(&query, state.oct_inv4)
            },
            {
                if !found && pred(bvh.primitive_indices[state.primitive_id as usize] as usize) {
                    found = true;
                    state.primitive_group.y = 0;
                }
            }
        );
        found
    }

    /// Calls `f(piece)` for every piece whose padded box overlaps the box lo–hi (world units).
    pub fn for_each_in_box(&self, lo: DVec3, hi: DVec3, mut f: impl FnMut(usize)) {
        let query = self.query_box(lo, hi);
        let bvh = &self.bvh;
        let mut state = bvh.new_traversal(Vec3A::ONE);
        let mut node;
        obvhs::traverse!(
            bvh,
            node,
            state,
            node.intersect_aabb(&query, state.oct_inv4),
            {
                f(bvh.primitive_indices[state.primitive_id as usize] as usize);
            }
        );
    }
}
