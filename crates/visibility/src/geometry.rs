//! Small fixed-size convex polygons in f64 and the plane tests the occlusion queries are built
//! from: signed distances, the exact segment–polygon hit, and the separating-plane tests of the
//! conservative "can anything come between these two patches" check.

use glam::DVec3;
use scene::Convex;

/// A planar convex patch (an element or a scene polygon: a [`Convex`], which it derefs to)
/// tagged with the scene polygon it lies on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    shape: Convex,
    polygon: u32,
}

impl std::ops::Deref for Patch {
    type Target = Convex;

    fn deref(&self) -> &Convex {
        &self.shape
    }
}

impl Patch {
    /// A patch from 3 or 4 corners (counter-clockwise about `normal`, a unit vector) on scene
    /// polygon `polygon` (the index given to [`crate::Occluders::new`]; it is never counted as an
    /// occluder of this patch). `None` for any other corner count.
    pub fn new(corners: &[DVec3], normal: DVec3, polygon: usize) -> Option<Patch> {
        Convex::new(corners, normal).map(|shape| Patch {
            shape,
            polygon: polygon as u32,
        })
    }

    /// Element `index` of `mesh` as a patch (its corners, normal and polygon).
    pub fn element(mesh: &mesher::ElementMesh, index: usize) -> Patch {
        Patch {
            shape: mesh.convex(index),
            polygon: mesh.elements[index].polygon,
        }
    }

    pub fn normal(&self) -> DVec3 {
        self.shape.normal
    }

    /// The scene polygon this patch lies on.
    pub fn polygon(&self) -> usize {
        self.polygon as usize
    }

    /// Signed distance of `p` from the patch's plane (positive on the normal side).
    #[inline]
    pub(crate) fn height(&self, p: DVec3) -> f64 {
        (p - self.corners[0]).dot(self.normal)
    }

    /// Axis-aligned bounds (min, max).
    pub(crate) fn bounds(&self) -> (DVec3, DVec3) {
        let c = self.corners();
        c.iter()
            .fold((c[0], c[0]), |(lo, hi), &p| (lo.min(p), hi.max(p)))
    }

    /// Bilinear (quad) or area-uniform (triangle) map of the unit square onto the patch, and the
    /// relative area density there (constant 1 for a triangle; |∂P/∂u × ∂P/∂v| for a quad,
    /// constant for a parallelogram).
    #[inline]
    pub(crate) fn point(&self, u: f64, v: f64) -> (DVec3, f64) {
        let [c0, c1, c2, c3] = self.corners;
        if self.sides == 3 {
            // (1 − √u, √u (1 − v), √u v): uniform over the triangle, continuous, so strata of
            // the square stay compact on the triangle (Shirley & Chiu's square-to-triangle map).
            let s = u.sqrt();
            (c0 * (1.0 - s) + c1 * (s * (1.0 - v)) + c2 * (s * v), 1.0)
        } else {
            let bottom = c0.lerp(c1, u);
            let top = c3.lerp(c2, u);
            let du = (c1 - c0).lerp(c2 - c3, v);
            let dv = top - bottom;
            (bottom.lerp(top, v), du.cross(dv).dot(self.normal).abs())
        }
    }
}

/// An occluder: one scene polygon (3 or 4 corners) with its plane and bounds.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Piece {
    pub patch: Patch,
    /// `normal · x = offset` on the plane.
    pub offset: f64,
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Piece {
    pub fn new(patch: Patch) -> Piece {
        let (lo, hi) = patch.bounds();
        let offset = patch.normal.dot(patch.corners[0]);
        Piece {
            patch,
            offset,
            lo,
            hi,
        }
    }

    /// Whether the closed segment p–q meets the polygon (edges included, widened by `edge_tol`,
    /// so a segment through the seam between two adjacent polygons hits at least one of them).
    /// A segment lying in the polygon's plane does not hit it: coplanar surfaces never shadow.
    #[inline]
    pub fn hits_segment(&self, p: DVec3, q: DVec3, edge_tol: f64) -> bool {
        let n = self.patch.normal;
        let sp = n.dot(p) - self.offset;
        let sq = n.dot(q) - self.offset;
        if (sp > 0.0 && sq > 0.0) || (sp < 0.0 && sq < 0.0) || (sp == 0.0 && sq == 0.0) {
            return false;
        }
        let x = p + (q - p) * (sp / (sp - sq));
        let c = self.patch.corners();
        (0..c.len()).all(|k| {
            let (a, b) = (c[k], c[(k + 1) % c.len()]);
            let edge = b - a;
            // Distance of x inside the edge's line, times |edge|.
            edge.cross(x - a).dot(n) >= -edge_tol * edge.length()
        })
    }
}

/// Up to 8 points (a convex polygon clipped by one plane has at most one more corner).
#[derive(Clone, Copy)]
struct Points {
    p: [DVec3; 8],
    n: usize,
}

/// The part of the polygon `c` where `height(x) ≥ level` (Sutherland–Hodgman, one plane).
fn clip_above(c: &[DVec3], height: impl Fn(DVec3) -> f64, level: f64) -> Points {
    let mut out = Points {
        p: [DVec3::ZERO; 8],
        n: 0,
    };
    for k in 0..c.len() {
        let (a, b) = (c[k], c[(k + 1) % c.len()]);
        let (ha, hb) = (height(a) - level, height(b) - level);
        if ha >= 0.0 {
            out.p[out.n] = a;
            out.n += 1;
        }
        if (ha >= 0.0) != (hb >= 0.0) {
            out.p[out.n] = a + (b - a) * (ha / (ha - hb));
            out.n += 1;
        }
    }
    out
}

/// Whether `a` and `b` can exchange light at all: some corner of each is more than `tol` in
/// front of the other's plane.
pub(crate) fn facing(a: &Patch, b: &Patch, tol: f64) -> bool {
    b.corners().iter().any(|&p| a.height(p) > tol) && a.corners().iter().any(|&p| b.height(p) > tol)
}

/// Conservative test: can the polygon `k` block some segment between a point of `a` and a point
/// of `b`? `false` only when a plane separates `k` from the convex hull of `a ∪ b` (the union of
/// all those segments), or `k` has no part more than `tol` in front of both patches' planes.
///
/// Tests, cheapest first:
/// 1. bounding boxes: `k`'s box must overlap the box of `a ∪ b`;
/// 2. `k`'s own plane: if every corner of `a ∪ b` is on one closed side of it (within `tol`),
///    `k` lies in a supporting plane of the hull and can only touch it; this is why no wall of
///    a convex enclosure ever occludes;
/// 3. `a`'s and `b`'s planes: `k` clipped to the part more than `tol` in front of `a` must still
///    reach more than `tol` in front of `b` (coplanar neighbours and the patches' own solids
///    fail here);
/// 4. the hull's side faces: planes through an edge of one patch and a corner of the other
///    that have all of `a ∪ b` on one side; `k` wholly on the other side cannot enter the hull.
pub(crate) fn may_block(k: &Piece, a: &Patch, b: &Patch, tol: f64) -> bool {
    let (alo, ahi) = a.bounds();
    let (blo, bhi) = b.bounds();
    let (lo, hi) = (alo.min(blo) - tol, ahi.max(bhi) + tol);
    if k.lo.cmpgt(hi).any() || k.hi.cmplt(lo).any() {
        return false;
    }
    let both = || a.corners().iter().chain(b.corners());
    let kh = |p: &DVec3| k.patch.height(*p);
    if both().all(|p| kh(p) >= -tol) || both().all(|p| kh(p) <= tol) {
        return false;
    }
    let front = clip_above(k.patch.corners(), |x| a.height(x), tol);
    if !front.p[..front.n].iter().any(|&x| b.height(x) > tol) {
        return false;
    }
    !separated_by_hull_side(k, a, b, tol) && !separated_by_hull_side(k, b, a, tol)
}

/// Test 4 of [`may_block`]: a plane through an edge of `a` and a corner of `b` with all of
/// `a ∪ b` on one side and `k` on the other.
fn separated_by_hull_side(k: &Piece, a: &Patch, b: &Patch, tol: f64) -> bool {
    let mut hull = [DVec3::ZERO; 8];
    let n = a.corners().len() + b.corners().len();
    for (slot, &p) in hull.iter_mut().zip(a.corners().iter().chain(b.corners())) {
        *slot = p;
    }
    separated_by_side(k, a.corners(), b.corners(), &hull[..n], tol)
}

/// A plane through an edge of the polygon `ring` and one of the `apexes`, with every point of
/// `hull` on one closed side (within `tol`) and `k` wholly on the other.
fn separated_by_side(
    k: &Piece,
    ring: &[DVec3],
    apexes: &[DVec3],
    hull: &[DVec3],
    tol: f64,
) -> bool {
    for e in 0..ring.len() {
        let (p, q) = (ring[e], ring[(e + 1) % ring.len()]);
        for &w in apexes {
            let n = (q - p).cross(w - p);
            let len = n.length();
            if len <= f64::MIN_POSITIVE {
                continue;
            }
            let n = n / len;
            let h = |x: &DVec3| (*x - p).dot(n);
            let side = if hull.iter().all(|x| h(x) >= -tol) {
                1.0
            } else if hull.iter().all(|x| h(x) <= tol) {
                -1.0
            } else {
                continue;
            };
            if k.patch.corners().iter().all(|x| side * h(x) <= tol) {
                return true;
            }
        }
    }
    false
}

/// Conservative test for light from outside the scene's surfaces: can the polygon `k` block
/// some segment from a point of `receiver` to one of the `far` points (a point light: one
/// point; a directional light: the receiver's corners moved toward the light past the scene)?
/// The segments fill the convex hull of `receiver ∪ far`; `false` only when a plane separates
/// `k` from it. The same tests as [`may_block`], with the far points in place of a patch:
/// 1. bounding boxes; 2. `k`'s own plane has the whole hull on one closed side; 3. `k` has no
///    part more than `tol` in front of the receiver (the segments lie in front of it);
/// 4. a plane through a receiver edge and a far point with the hull on one side, `k` on the
///    other.
pub(crate) fn may_block_light(k: &Piece, receiver: &Patch, far: &[DVec3], tol: f64) -> bool {
    let (mut lo, mut hi) = receiver.bounds();
    for &p in far {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    if k.lo.cmpgt(hi + tol).any() || k.hi.cmplt(lo - tol).any() {
        return false;
    }
    let all = || receiver.corners().iter().chain(far);
    let kh = |p: &DVec3| k.patch.height(*p);
    if all().all(|p| kh(p) >= -tol) || all().all(|p| kh(p) <= tol) {
        return false;
    }
    if !k.patch.corners().iter().any(|&x| receiver.height(x) > tol) {
        return false;
    }
    let mut hull = [DVec3::ZERO; 8];
    let n = receiver.corners().len() + far.len().min(4);
    for (slot, &p) in hull.iter_mut().zip(all()) {
        *slot = p;
    }
    !separated_by_side(k, receiver.corners(), far, &hull[..n], tol)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f64, size: f64, up: bool, polygon: usize) -> Patch {
        let h = size / 2.0;
        let mut c = vec![
            DVec3::new(-h, -h, z),
            DVec3::new(h, -h, z),
            DVec3::new(h, h, z),
            DVec3::new(-h, h, z),
        ];
        let mut n = DVec3::Z;
        if !up {
            c.reverse();
            n = -n;
        }
        Patch::new(&c, n, polygon).unwrap()
    }

    #[test]
    fn segment_hits_inside_and_on_edges_only() {
        let k = Piece::new(square(0.5, 1.0, true, 0));
        let hit = |x: f64| k.hits_segment(DVec3::new(x, 0.0, 0.0), DVec3::new(x, 0.0, 1.0), 1e-12);
        assert!(hit(0.0));
        assert!(hit(0.5));
        assert!(!hit(0.5 + 1e-9));
        // Both sides, either direction.
        assert!(k.hits_segment(DVec3::new(0.0, 0.0, 1.0), DVec3::ZERO, 0.0));
        // Not reaching the plane, or lying in it.
        assert!(!k.hits_segment(DVec3::ZERO, DVec3::new(0.0, 0.0, 0.4), 0.0));
        assert!(!k.hits_segment(DVec3::new(-0.2, 0.0, 0.5), DVec3::new(0.2, 0.0, 0.5), 0.0));
    }

    #[test]
    fn occluder_between_parallel_squares_may_block_and_walls_beside_do_not() {
        let a = square(0.0, 1.0, true, 0);
        let b = square(1.0, 1.0, false, 1);
        assert!(facing(&a, &b, 1e-9));
        let mid = Piece::new(square(0.5, 2.0, true, 2));
        assert!(may_block(&mid, &a, &b, 1e-9));
        // A square beside the pair's hull, in the plane x = 2.
        let c = [
            DVec3::new(2.0, -1.0, 0.2),
            DVec3::new(2.0, 1.0, 0.2),
            DVec3::new(2.0, 1.0, 0.8),
            DVec3::new(2.0, -1.0, 0.8),
        ];
        let side = Piece::new(Patch::new(&c, -DVec3::X, 3).unwrap());
        assert!(!may_block(&side, &a, &b, 1e-9));
        // Coplanar with a.
        let beside = Piece::new(square(0.0, 3.0, true, 4));
        assert!(!may_block(&beside, &a, &b, 1e-9));
    }

    #[test]
    fn light_segments_are_blocked_only_by_polygons_in_their_hull() {
        let floor = square(0.0, 2.0, true, 0);
        let light = [DVec3::new(0.0, 0.0, 2.0)];
        let tol = 1e-9;
        // Between the light and the floor.
        assert!(may_block_light(
            &Piece::new(square(1.0, 0.5, false, 1)),
            &floor,
            &light,
            tol
        ));
        // Above the light, or off to the side of the pyramid, or on the floor's plane.
        assert!(!may_block_light(
            &Piece::new(square(3.0, 5.0, false, 2)),
            &floor,
            &light,
            tol
        ));
        let mut side = [DVec3::ZERO; 4];
        for (k, c) in square(0.0, 0.5, true, 3).corners().iter().enumerate() {
            side[k] = *c + DVec3::new(2.0, 0.0, 1.5);
        }
        let side = Piece::new(Patch::new(&side, DVec3::Z, 3).unwrap());
        assert!(!may_block_light(&side, &floor, &light, tol));
        assert!(!may_block_light(
            &Piece::new(square(0.0, 9.0, true, 4)),
            &floor,
            &light,
            tol
        ));
        // A directional light straight down: far points above each corner.
        let far: Vec<DVec3> = floor
            .corners()
            .iter()
            .map(|c| *c + DVec3::Z * 10.0)
            .collect();
        assert!(may_block_light(
            &Piece::new(square(5.0, 0.5, false, 5)),
            &floor,
            &far,
            tol
        ));
        assert!(!may_block_light(&side, &floor, &far, tol));
    }

    #[test]
    fn quad_map_density_is_its_area_for_a_parallelogram() {
        let p = square(0.0, 2.0, true, 0);
        let (x, j) = p.point(0.5, 0.5);
        assert!(x.length() < 1e-15);
        assert!((j - 4.0).abs() < 1e-12);
    }
}
