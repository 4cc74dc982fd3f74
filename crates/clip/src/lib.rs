//! 2D convex clipping and the exact area of a union of convex polygons.
//!
//! This is the geometry behind exact shadows from a directional light: a receiver element
//! (a convex polygon in its plane's 2D coordinates) is shadowed by occluders whose
//! projections along the light direction onto that plane are convex polygons, and its lit
//! share is `1 − area(element ∩ ∪ projections) / area(element)`. [`clip_convex`] cuts each
//! projection down to the element, and [`union_area`] measures the union of the pieces
//! exactly (no sampling), however they overlap. The same clipping cuts an element's image in
//! texture space into texel cells for exact texture averages (`bake-texture`).
//!
//! It is not a general polygon boolean library: clip polygons must be convex, the union is
//! measured, never built as a polygon, and nothing here knows about 3D, lights or
//! projection (the caller projects the occluders and picks the plane's coordinates).

use glam::DVec2;

/// Polygons whose |area| is below this are treated as empty: it is far below any area the
/// bake can care about, yet keeps a true zero (collinear or repeated vertices) out.
const DEGENERATE_AREA: f64 = 1e-300;

/// Whether a signed area is big enough to count. A NaN area (not reachable from finite input
/// short of overflow) does not count either: there would be no orientation to trust.
fn has_area(area: f64) -> bool {
    area.abs() >= DEGENERATE_AREA
}

/// The area centroid of a simple polygon (fan triangles about the first vertex, each
/// weighted by its signed area); the vertex mean when the area is zero.
pub fn centroid(polygon: &[DVec2]) -> DVec2 {
    let Some((&origin, rest)) = polygon.split_first() else {
        return DVec2::ZERO;
    };
    let mut sum = DVec2::ZERO;
    let mut twice = 0.0;
    for pair in rest.windows(2) {
        let (a, b) = (pair[0] - origin, pair[1] - origin);
        let w = a.perp_dot(b);
        sum += (a + b) * w / 3.0;
        twice += w;
    }
    if twice == 0.0 {
        let mean = polygon.iter().copied().sum::<DVec2>() / polygon.len() as f64;
        return mean;
    }
    origin + sum / twice
}

/// Signed area (shoelace), positive for counter-clockwise.
///
/// Fewer than three vertices give zero.
pub fn signed_area(polygon: &[DVec2]) -> f64 {
    let Some((&origin, rest)) = polygon.split_first() else {
        return 0.0;
    };
    // Relative to the first vertex: the terms are then products of the polygon's own
    // extents, not of absolute coordinates, so a small polygon far from the origin loses no
    // digits to cancellation. The two edges at `origin` contribute zero and are skipped.
    let twice: f64 = rest
        .windows(2)
        .map(|pair| (pair[0] - origin).perp_dot(pair[1] - origin))
        .sum();
    0.5 * twice
}

/// The part of `subject` (any simple polygon; convex in our use) inside the convex polygon
/// `clip`, by Sutherland–Hodgman.
///
/// `clip` may be either orientation: it is detected from the sign of its area. The result
/// keeps the subject's orientation (counter-clockwise if the subject was); it is empty if
/// nothing of positive area is left, if the subject has fewer than three vertices, or if
/// `clip` is degenerate (fewer than three vertices or |area| below 1e-300). Points on the
/// clip boundary count as inside.
///
/// The result is written into `out` (cleared first); `scratch` holds the intermediate
/// polygons, so a caller in a hot loop can reuse both and allocate nothing per call.
pub fn clip_convex(
    subject: &[DVec2],
    clip: &[DVec2],
    out: &mut Vec<DVec2>,
    scratch: &mut Vec<DVec2>,
) {
    out.clear();
    let clip_area = signed_area(clip);
    if clip.len() < 3 || subject.len() < 3 || !has_area(clip_area) {
        return;
    }
    let orientation = clip_area.signum();
    scratch.clear();
    scratch.extend_from_slice(subject);
    let Some(&clip_last) = clip.last() else {
        return;
    };
    let mut a = clip_last;
    for &b in clip {
        let edge = b - a;
        // The cross product of the edge with the point's offset from the edge's start: zero
        // exactly on the edge's line, and made positive inside by the orientation. Measuring
        // from `a` (not `n · x − c` with absolute coordinates) keeps it accurate far from the
        // origin. A repeated clip vertex gives a zero edge, which keeps everything.
        clip_by(scratch, |x| orientation * edge.perp_dot(x - a), out);
        std::mem::swap(out, scratch);
        if scratch.len() < 3 {
            break;
        }
        a = b;
    }
    std::mem::swap(out, scratch);
    drop_degenerate(out);
}

/// The part of `subject` on the side of the half-plane `n · x ≥ c`, by one Sutherland–Hodgman
/// step; same conventions as [`clip_convex`]: the subject's orientation is kept, points on
/// the line count as inside, and the result (in `out`, cleared first) is empty if nothing of
/// positive area is left. A zero `n` with `c ≤ 0` keeps everything; with `c > 0`, nothing.
pub fn clip_half_plane(subject: &[DVec2], n: DVec2, c: f64, out: &mut Vec<DVec2>) {
    clip_by(subject, |x| n.dot(x) - c, out);
    drop_degenerate(out);
}

/// One Sutherland–Hodgman step: the part of `subject` where `distance ≥ 0`, into `out`.
fn clip_by(subject: &[DVec2], distance: impl Fn(DVec2) -> f64, out: &mut Vec<DVec2>) {
    out.clear();
    let Some(&last) = subject.last() else {
        return;
    };
    let (mut p, mut dp) = (last, distance(last));
    for &q in subject {
        let dq = distance(q);
        // A crossing only where the ends are strictly on opposite sides: an end on the line
        // is itself emitted (as `q` of this edge or the next), so emitting a crossing there
        // too would duplicate it. Strict opposite signs also make |dp − dq| = |dp| + |dq| > 0,
        // so the division is safe and `t` lies in (0, 1].
        if (dp > 0.0 && dq < 0.0) || (dp < 0.0 && dq > 0.0) {
            let t = dp / (dp - dq);
            out.push(p + (q - p) * t);
        }
        if dq >= 0.0 {
            out.push(q);
        }
        (p, dp) = (q, dq);
    }
}

/// Empties a clipped polygon with nothing left in it (fewer than three vertices, or the
/// vertices all on one line as when the subject only touches the clip boundary), so that
/// "empty" means the same thing to every caller.
fn drop_degenerate(polygon: &mut Vec<DVec2>) {
    if polygon.len() < 3 || !has_area(signed_area(polygon)) {
        polygon.clear();
    }
}

/// Exact area of the union of convex polygons, by a vertical slab sweep.
///
/// Each polygon may be either orientation; degenerate ones (fewer than three vertices or
/// |area| below 1e-300) are ignored. One polygon is answered by its |area| directly.
///
/// The answer is exact up to rounding and the event tolerance: the error is a small multiple
/// of ε × width × height of the polygons' common bounding box, plus 1e-12 of that box's
/// area, wherever the polygons lie. It is relative to the box, not to the union, so a union
/// of slivers has only that absolute accuracy (as has the shoelace of a sliver).
///
/// The cost is O(E²) for the events (E edges in all) plus O(S·P·V) for the slabs (S slabs,
/// P polygons of V vertices); the only memory that can grow faster than the input is the
/// event list. It is meant for up to about a hundred polygons.
pub fn union_area(polygons: &[&[DVec2]]) -> f64 {
    let kept: Vec<&[DVec2]> = polygons
        .iter()
        .copied()
        .filter(|p| p.len() >= 3 && has_area(signed_area(p)))
        .collect();
    match kept.as_slice() {
        [] => return 0.0,
        [only] => return signed_area(only).abs(),
        _ => {}
    }
    // Work relative to the centre of everything: the cross-sections' lengths are differences
    // of y's, and y's of the order of the distance to the origin would cost that many digits
    // of the lengths (a far-away element would get its area only to ε × distance × extent).
    // For a cluster far from the origin the subtraction is exact (Sterbenz).
    let (low, high) = kept.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(low, high), p| {
            let (min, max) = bounding_box(p);
            (low.min(min), high.max(max))
        },
    );
    let centre = 0.5 * low + 0.5 * high;
    let vertices: Vec<DVec2> = kept
        .iter()
        .flat_map(|p| p.iter().map(|&v| v - centre))
        .collect();
    let mut shifted: Vec<&[DVec2]> = Vec::with_capacity(kept.len());
    let mut rest = vertices.as_slice();
    for p in &kept {
        let (this, others) = rest.split_at(p.len());
        shifted.push(this);
        rest = others;
    }
    let kept = shifted;
    let boxes: Vec<(DVec2, DVec2)> = kept.iter().map(|p| bounding_box(p)).collect();

    // Why the sweep is exact. Events are every vertex's x and every x where an edge of one
    // polygon crosses an edge of another. Between two consecutive events (a slab), the
    // vertical line at x meets each convex polygon in one interval (or not at all), and each
    // end of that interval runs along one fixed edge, so it is linear in x. No two ends of
    // different polygons cross inside the slab (a crossing of ends is a crossing of edges,
    // hence an event), so the ends keep one order, the union of the intervals is made of the
    // same ends throughout, and its length is linear in x. The integral of a linear
    // function over a slab is its width times its value at the midpoint: the midpoint rule
    // per slab is exact, and only rounding is left. Extra events are harmless (they only
    // split a slab into slabs that are exact too), which is why the crossing test below is
    // generous.
    let mut events: Vec<f64> = kept.iter().flat_map(|p| p.iter().map(|v| v.x)).collect();
    for i in 0..kept.len() {
        for j in (i + 1)..kept.len() {
            if !boxes_overlap(boxes[i], boxes[j]) {
                continue;
            }
            push_crossings(kept[i], kept[j], &mut events);
        }
    }
    events.sort_unstable_by(f64::total_cmp);

    // Events closer than this are one event, so no slab is narrower: each merge moves a
    // slab's end by at most this, which costs at most 1e-12 of the bounding box's area,
    // while slabs of rounding noise would only add rounding.
    let tolerance = 1e-12 * (high.x - low.x);
    // `dedup_by` compares each event with the last one kept, so a run of close events
    // collapses onto its first one and every slab left is wider than `tolerance`.
    events.dedup_by(|x, kept_x| *x - *kept_x <= tolerance);

    let mut intervals: Vec<(f64, f64)> = Vec::with_capacity(kept.len());
    let mut total = 0.0;
    for slab in events.windows(2) {
        let (x0, x1) = (slab[0], slab[1]);
        let mid = x0 + 0.5 * (x1 - x0);
        intervals.clear();
        for (polygon, (min, max)) in kept.iter().zip(&boxes) {
            // Strictly inside the x range: at its ends the cross-section has zero length.
            if mid > min.x && mid < max.x {
                if let Some(interval) = cross_section(polygon, mid) {
                    intervals.push(interval);
                }
            }
        }
        total += (x1 - x0) * union_length(&mut intervals);
    }
    total
}

/// The polygon's axis-aligned bounding box, as (min, max).
fn bounding_box(polygon: &[DVec2]) -> (DVec2, DVec2) {
    polygon.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(min, max), &v| (min.min(v), max.max(v)),
    )
}

/// Whether two closed boxes share a point (touching counts: touching edges can still cross).
fn boxes_overlap(a: (DVec2, DVec2), b: (DVec2, DVec2)) -> bool {
    a.0.x <= b.1.x && b.0.x <= a.1.x && a.0.y <= b.1.y && b.0.y <= a.1.y
}

/// Appends to `events` the x of every crossing between an edge of `a` and an edge of `b`.
fn push_crossings(a: &[DVec2], b: &[DVec2], events: &mut Vec<f64>) {
    let (Some(&a_last), Some(&b_last)) = (a.last(), b.last()) else {
        return;
    };
    let mut p0 = a_last;
    for &p1 in a {
        let (p_min, p_max) = (p0.min(p1), p0.max(p1));
        let mut q0 = b_last;
        for &q1 in b {
            let disjoint = p_max.x < q0.x.min(q1.x)
                || q0.x.max(q1.x) < p_min.x
                || p_max.y < q0.y.min(q1.y)
                || q0.y.max(q1.y) < p_min.y;
            if !disjoint {
                if let Some(x) = crossing_x(p0, p1, q0, q1) {
                    events.push(x);
                }
            }
            q0 = q1;
        }
        p0 = p1;
    }
}

/// The x where segments `p0p1` and `q0q1` cross, if they do (give or take a little slack).
fn crossing_x(p0: DVec2, p1: DVec2, q0: DVec2, q1: DVec2) -> Option<f64> {
    let (r, s) = (p1 - p0, q1 - q0);
    // A vertical segment can only be crossed at its own x, a vertex and so an event already.
    if r.x == 0.0 || s.x == 0.0 {
        return None;
    }
    let denominator = r.perp_dot(s);
    // Parallel segments (collinear overlaps included) never swap the order of the ends
    // they carry: no event needed.
    if denominator == 0.0 {
        return None;
    }
    let w = q0 - p0;
    // p0 + t r = q0 + u s. A tiny denominator can overflow these to ±∞, which the range test
    // below rejects; 0/0 cannot happen, so there is no NaN.
    let t = w.perp_dot(s) / denominator;
    let u = w.perp_dot(r) / denominator;
    // Slack, because a spurious event is harmless while a crossing rounded just out of range
    // would be lost (it is near an end, so near a vertex event, but not necessarily on it).
    const SLACK: f64 = 1e-9;
    let in_range = |v: f64| (-SLACK..=1.0 + SLACK).contains(&v);
    if !(in_range(t) && in_range(u)) {
        return None;
    }
    Some(p0.x + t.clamp(0.0, 1.0) * r.x)
}

/// The interval (min y, max y) where the vertical line at `x` meets the convex `polygon`,
/// or `None` if it misses.
fn cross_section(polygon: &[DVec2], x: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut previous = *polygon.last()?;
    for &vertex in polygon {
        // Each edge taken left to right, so an edge shared by two polygons (in either
        // direction) gives both the same y, bit for bit.
        let (left, right) = if previous.x <= vertex.x {
            (previous, vertex)
        } else {
            (vertex, previous)
        };
        previous = vertex;
        // Vertical edges are skipped: their ends belong to the neighbouring edges too.
        if left.x == right.x || x < left.x || x > right.x {
            continue;
        }
        // The parameter rather than the slope: `t` is in [0, 1] (rounding is monotone), so
        // nothing overflows however steep the edge is; the clamp is belt and braces.
        let t = ((x - left.x) / (right.x - left.x)).clamp(0.0, 1.0);
        let y = left.y + t * (right.y - left.y);
        lo = lo.min(y);
        hi = hi.max(y);
    }
    (lo <= hi).then_some((lo, hi))
}

/// Total length of the union of closed intervals (sorted in place by their lower ends).
fn union_length(intervals: &mut [(f64, f64)]) -> f64 {
    intervals.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let Some((&(first_lo, first_hi), rest)) = intervals.split_first() else {
        return 0.0;
    };
    let (mut lo, mut hi) = (first_lo, first_hi);
    let mut length = 0.0;
    for &(next_lo, next_hi) in rest {
        if next_lo > hi {
            length += hi - lo;
            (lo, hi) = (next_lo, next_hi);
        } else {
            hi = hi.max(next_hi);
        }
    }
    length + (hi - lo)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centroid_of_a_trapezoid() {
        // (0,0) (4,0) (3,2) (1,2): area 6, centroid x = 2, y = 2·(2·2+4)/(3·(4+2)) = 8/9.
        let p = [
            DVec2::new(0.0, 0.0),
            DVec2::new(4.0, 0.0),
            DVec2::new(3.0, 2.0),
            DVec2::new(1.0, 2.0),
        ];
        let c = centroid(&p);
        assert!((c - DVec2::new(2.0, 8.0 / 9.0)).length() < 1e-15, "{c}");
    }
    use proptest::prelude::*;
    use std::f64::consts::{SQRT_2, TAU};

    fn v(x: f64, y: f64) -> DVec2 {
        DVec2::new(x, y)
    }

    /// The axis rectangle [x0, x1] × [y0, y1], counter-clockwise.
    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
        vec![v(x0, y0), v(x1, y0), v(x1, y1), v(x0, y1)]
    }

    fn reversed(p: &[DVec2]) -> Vec<DVec2> {
        p.iter().rev().copied().collect()
    }

    fn union(polygons: &[&Vec<DVec2>]) -> f64 {
        let slices: Vec<&[DVec2]> = polygons.iter().map(|p| p.as_slice()).collect();
        union_area(&slices)
    }

    fn intersection(a: &[DVec2], b: &[DVec2]) -> Vec<DVec2> {
        let (mut out, mut scratch) = (Vec::new(), Vec::new());
        clip_convex(a, b, &mut out, &mut scratch);
        out
    }

    fn intersection_area(polygons: &[&[DVec2]]) -> f64 {
        let mut piece = polygons[0].to_vec();
        for p in &polygons[1..] {
            piece = intersection(&piece, p);
        }
        signed_area(&piece).abs()
    }

    fn assert_close(got: f64, want: f64, tolerance: f64) {
        assert!(
            (got - want).abs() <= tolerance,
            "got {got}, want {want} (difference {})",
            got - want
        );
    }

    #[test]
    fn signed_area_sign_and_far_from_origin() {
        let square = rect(0.0, 0.0, 1.0, 1.0);
        assert_eq!(signed_area(&square), 1.0);
        assert_eq!(signed_area(&reversed(&square)), -1.0);
        assert_eq!(signed_area(&square[..2]), 0.0);
        assert_eq!(signed_area(&[]), 0.0);
        // A 1e-3 square at 1e6 (its side is what 1e6 + 1e-3 rounds to, less 1e6, exactly):
        // the shoelace on absolute coordinates would lose ~12 digits of its ~1e-6.
        let side = (1e6 + 1e-3) - 1e6;
        let far = rect(1e6, -1e6, 1e6 + 1e-3, -1e6 + 1e-3);
        assert_close(signed_area(&far), side * side, 1e-22);
    }

    #[test]
    fn union_of_disjoint_squares_is_the_sum() {
        let a = rect(0.0, 0.0, 1.0, 1.0);
        let b = rect(2.0, 0.5, 3.0, 1.5);
        let c = rect(-3.0, -3.0, -2.0, -2.0);
        assert_close(union(&[&a, &b, &c]), 3.0, 1e-14);
    }

    #[test]
    fn union_of_nested_squares_is_the_larger() {
        let outer = rect(0.0, 0.0, 2.0, 2.0);
        let inner = reversed(&rect(0.5, 0.5, 1.5, 1.5));
        assert_close(union(&[&outer, &inner]), 4.0, 1e-14);
        assert_close(union(&[&inner, &outer]), 4.0, 1e-14);
    }

    #[test]
    fn union_of_identical_polygons_is_one() {
        let a = rect(0.0, 0.0, 1.0, 1.0);
        // The same square, clockwise and starting at another corner.
        let b = vec![v(1.0, 1.0), v(1.0, 0.0), v(0.0, 0.0), v(0.0, 1.0)];
        assert_close(union(&[&a, &b, &a]), 1.0, 1e-14);
        let t = vec![v(0.0, 0.0), v(3.0, 1.0), v(1.0, 2.0)];
        assert_close(union(&[&t, &t]), signed_area(&t), 1e-14);
    }

    #[test]
    fn union_of_overlapping_axis_squares() {
        // 4 + 4 − (overlap [1, 2] × [0.5, 2] = 1.5).
        let a = rect(0.0, 0.0, 2.0, 2.0);
        let b = rect(1.0, 0.5, 3.0, 2.5);
        assert_close(union(&[&a, &b]), 6.5, 1e-14);
        // A third, [1.5, 2.5] × [−1, 1] (area 2), of which a covers [1.5, 2] × [0, 1] (0.5)
        // and b covers [1.5, 2.5] × [0.5, 1] (0.5), those two overlapping in
        // [1.5, 2] × [0.5, 1] (0.25): it adds 2 − (0.5 + 0.5 − 0.25).
        let c = rect(1.5, -1.0, 2.5, 1.0);
        assert_close(union(&[&a, &b, &c]), 6.5 + 2.0 - 0.75, 1e-14);
    }

    #[test]
    fn union_of_a_triangle_and_a_square() {
        // The hypotenuse x + y = 2 halves the square [0.5, 1.5]² through its centre (1, 1).
        let triangle = vec![v(0.0, 0.0), v(2.0, 0.0), v(0.0, 2.0)];
        let square = rect(0.5, 0.5, 1.5, 1.5);
        assert_close(union(&[&triangle, &square]), 2.0 + 1.0 - 0.5, 1e-14);
    }

    #[test]
    fn union_of_polygons_touching_at_a_vertex() {
        let a = rect(0.0, 0.0, 1.0, 1.0);
        let b = rect(1.0, 1.0, 2.0, 2.0);
        assert_close(union(&[&a, &b]), 2.0, 1e-14);
        // A triangle whose apex touches the middle of the square's right edge.
        let t = vec![v(1.0, 0.5), v(2.0, 0.0), v(2.0, 1.0)];
        assert_close(union(&[&a, &t]), 1.5, 1e-14);
        // A diamond touching the square's corner from below-right.
        let d = vec![v(1.0, 0.0), v(1.5, -0.5), v(2.0, 0.0), v(1.5, 0.5)];
        assert_close(union(&[&a, &d]), 1.5, 1e-14);
    }

    #[test]
    fn union_of_polygons_sharing_an_edge() {
        let a = rect(0.0, 0.0, 1.0, 1.0);
        let b = rect(1.0, 0.0, 2.0, 1.0);
        assert_close(union(&[&a, &b]), 2.0, 1e-14);
        // Sharing part of an edge, and a horizontal one.
        let c = rect(1.0, 0.5, 2.0, 1.5);
        assert_close(union(&[&a, &c]), 2.0, 1e-14);
        let d = rect(0.25, 1.0, 0.75, 2.0);
        assert_close(union(&[&a, &c, &d]), 2.5, 1e-14);
        // Two triangles sharing a diagonal make the square.
        let lower = vec![v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0)];
        let upper = vec![v(0.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)];
        assert_close(union(&[&lower, &upper]), 1.0, 1e-14);
    }

    #[test]
    fn union_ignores_degenerate_polygons_and_collinear_vertices() {
        let a = rect(0.0, 0.0, 1.0, 1.0);
        let segment = vec![v(0.0, 0.0), v(5.0, 5.0)];
        let flat = vec![v(-1.0, 0.0), v(0.0, 1.0), v(1.0, 2.0)];
        let point = vec![v(3.0, 3.0); 4];
        assert_close(union(&[&a, &segment, &flat, &point]), 1.0, 1e-14);
        assert_eq!(union(&[&segment, &flat]), 0.0);
        assert_eq!(union_area(&[]), 0.0);
        // Collinear and repeated vertices on the boundary change nothing.
        let busy = vec![
            v(0.5, 0.0),
            v(1.0, 0.0),
            v(1.5, 0.0),
            v(1.5, 0.0),
            v(1.5, 1.0),
            v(0.5, 1.0),
            v(0.5, 0.5),
        ];
        assert_close(union(&[&a, &busy]), 1.5, 1e-14);
    }

    #[test]
    fn union_far_from_the_origin() {
        // Two overlapping ~1e-3 rectangles at (1e6, −1e6). Their corners are what the sums
        // round to; the differences of those are exact (Sterbenz), so is the reference.
        let (x, y, s) = (1e6, -1e6, 1e-3);
        let a = rect(x, y, x + s, y + s);
        let b = rect(x + 0.5 * s, y + 0.5 * s, x + 1.5 * s, y + 1.5 * s);
        let extent = |p: &[DVec2]| (p[2].x - p[0].x) * (p[2].y - p[0].y);
        let overlap = (a[2].x - b[0].x) * (a[2].y - b[0].y);
        let want = extent(&a) + extent(&b) - overlap;
        assert_close(union(&[&a, &b]), want, 1e-12 * want);
    }

    #[test]
    fn union_with_slivers() {
        let a = rect(0.0, 0.0, 1.0, 1.0);
        // Outside, below the bottom edge: adds its own 5e-10.
        let below = vec![v(0.0, 0.0), v(1.0, -1e-9), v(1.0, 0.0)];
        assert_close(union(&[&a, &below]), 1.0 + 5e-10, 1e-15);
        // A needle crossing the square: 3 × 2e-9 long and thin, 1/3 of it inside.
        let needle = vec![v(-1.0, 0.5), v(2.0, 0.5 - 1e-9), v(2.0, 0.5 + 1e-9)];
        let needle_area = signed_area(&needle);
        let inside = intersection_area(&[&needle, &a]);
        assert_close(union(&[&a, &needle]), 1.0 + needle_area - inside, 1e-15);
    }

    #[test]
    fn clip_square_by_rotated_square_is_the_regular_octagon() {
        // The unit square centred at the origin and the same square turned 45°: both have
        // apothem 1/2, so the intersection is the regular octagon of apothem 1/2, area
        // 8 tan(π/8) (1/2)² = 2 (√2 − 1). Equivalently the square less four corner
        // triangles cut by x + y = √2/2, each with legs 1 − √2/2.
        let square = rect(-0.5, -0.5, 0.5, 0.5);
        let h = SQRT_2 / 2.0;
        let diamond = vec![v(h, 0.0), v(0.0, h), v(-h, 0.0), v(0.0, -h)];
        let octagon_area = 2.0 * (SQRT_2 - 1.0);
        let corner = 0.5 * (1.0 - h) * (1.0 - h);
        assert_close(octagon_area, 1.0 - 4.0 * corner, 1e-15);
        for clip in [diamond.clone(), reversed(&diamond)] {
            let out = intersection(&square, &clip);
            assert_eq!(out.len(), 8);
            // Counter-clockwise in, counter-clockwise out.
            assert_close(signed_area(&out), octagon_area, 1e-15);
            for p in &out {
                // On the square's boundary and inside the diamond, or the other way round.
                let on_square = (p.x.abs().max(p.y.abs()) - 0.5).abs() < 1e-15;
                let on_diamond = (p.x.abs() + p.y.abs() - h).abs() < 1e-15;
                assert!(on_square && on_diamond, "{p}");
            }
        }
        // A clockwise subject stays clockwise.
        let out = intersection(&reversed(&square), &diamond);
        assert_close(signed_area(&out), -octagon_area, 1e-15);
    }

    #[test]
    fn clip_convex_edge_cases() {
        let square = rect(0.0, 0.0, 1.0, 1.0);
        // Disjoint, touching at an edge, touching at a vertex: nothing left.
        assert!(intersection(&square, &rect(2.0, 0.0, 3.0, 1.0)).is_empty());
        assert!(intersection(&square, &rect(1.0, 0.0, 2.0, 1.0)).is_empty());
        assert!(intersection(&square, &rect(1.0, 1.0, 2.0, 2.0)).is_empty());
        // Degenerate clip polygons.
        assert!(intersection(&square, &[v(0.0, 0.0), v(1.0, 1.0)]).is_empty());
        assert!(intersection(&square, &[v(0.0, 0.0), v(0.5, 0.5), v(1.0, 1.0)]).is_empty());
        // Subject inside the clip: unchanged; the clip inside the subject: the clip.
        assert_close(
            signed_area(&intersection(&square, &rect(-1.0, -1.0, 2.0, 2.0))),
            1.0,
            1e-15,
        );
        let inner = rect(0.25, 0.25, 0.5, 0.75);
        assert_close(
            signed_area(&intersection(&square, &inner)),
            signed_area(&inner),
            1e-15,
        );
        // Identical polygons, the clip clockwise and with a repeated vertex.
        let clip = vec![
            v(0.0, 0.0),
            v(0.0, 1.0),
            v(1.0, 1.0),
            v(1.0, 1.0),
            v(1.0, 0.0),
        ];
        assert_close(signed_area(&intersection(&square, &clip)), 1.0, 1e-15);
        // The buffers are reused: stale contents do not leak into the result.
        let (mut out, mut scratch) = (vec![v(9.0, 9.0); 7], vec![v(8.0, 8.0); 3]);
        clip_convex(&square, &rect(0.5, -1.0, 2.0, 2.0), &mut out, &mut scratch);
        assert_close(signed_area(&out), 0.5, 1e-15);
        assert!(out.iter().all(|p| p.x >= 0.5 && p.x <= 1.0));
    }

    #[test]
    fn clip_half_plane_cases() {
        let square = rect(0.0, 0.0, 1.0, 1.0);
        let mut out = Vec::new();
        clip_half_plane(&square, v(1.0, 0.0), 0.25, &mut out);
        assert_close(signed_area(&out), 0.75, 1e-15);
        // x + y ≥ 1: half the square, through two corners (no duplicated vertices).
        clip_half_plane(&square, v(1.0, 1.0), 1.0, &mut out);
        assert_eq!(out.len(), 3);
        assert_close(signed_area(&out), 0.5, 1e-15);
        clip_half_plane(&reversed(&square), v(-1.0, 0.0), -0.5, &mut out);
        assert_close(signed_area(&out), -0.5, 1e-15);
        clip_half_plane(&square, v(0.0, 1.0), -3.0, &mut out);
        assert_close(signed_area(&out), 1.0, 1e-15);
        // Touching the line from inside at an edge, or a vertex: nothing of area is left.
        clip_half_plane(&square, v(1.0, 0.0), 1.0, &mut out);
        assert!(out.is_empty());
        clip_half_plane(&square, v(1.0, 1.0), 2.0, &mut out);
        assert!(out.is_empty());
        clip_half_plane(&square, DVec2::ZERO, 1.0, &mut out);
        assert!(out.is_empty());
        clip_half_plane(&square, DVec2::ZERO, 0.0, &mut out);
        assert_close(signed_area(&out), 1.0, 1e-15);
    }

    /// Regular polygons with random centre, radius, rotation, corner count and orientation.
    fn regular_polygon() -> impl Strategy<Value = Vec<DVec2>> {
        (
            -1.0..1.0f64,
            -1.0..1.0f64,
            0.1..1.5f64,
            0.0..TAU,
            3usize..9,
            any::<bool>(),
        )
            .prop_map(|(cx, cy, radius, spin, n, clockwise)| {
                let polygon: Vec<DVec2> = (0..n)
                    .map(|k| {
                        let angle = spin + TAU * k as f64 / n as f64;
                        v(cx + radius * angle.cos(), cy + radius * angle.sin())
                    })
                    .collect();
                if clockwise {
                    reversed(&polygon)
                } else {
                    polygon
                }
            })
    }

    /// Convex hull (Andrew's monotone chain), counter-clockwise, collinear points dropped.
    fn convex_hull(mut points: Vec<DVec2>) -> Vec<DVec2> {
        points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        let mut hull: Vec<DVec2> = Vec::new();
        for pass in 0..2 {
            let start = hull.len();
            for &p in &points {
                while hull.len() >= start + 2 {
                    let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
                    if (b - a).perp_dot(p - a) > 0.0 {
                        break;
                    }
                    hull.pop();
                }
                hull.push(p);
            }
            hull.pop();
            if pass == 0 {
                points.reverse();
            }
        }
        hull
    }

    /// Convex hulls of random points, in either orientation.
    fn hull_polygon() -> impl Strategy<Value = Vec<DVec2>> {
        (
            prop::collection::vec((-1.5..1.5f64, -1.5..1.5f64), 3..12),
            any::<bool>(),
        )
            .prop_map(|(points, clockwise)| {
                let hull = convex_hull(points.into_iter().map(|(x, y)| v(x, y)).collect());
                if clockwise {
                    reversed(&hull)
                } else {
                    hull
                }
            })
    }

    fn convex_polygon() -> impl Strategy<Value = Vec<DVec2>> {
        prop_oneof![regular_polygon(), hull_polygon()]
    }

    /// Unit cells of a small lattice are split into four quarter triangles by their
    /// diagonals; a shape is a set of whole quarters, so its union's area is a count.
    #[derive(Clone, Debug)]
    enum LatticeShape {
        /// Cells [x, x + w) × [y, y + h).
        Rect(i32, i32, i32, i32),
        /// Half of cell (x, y) cut by a diagonal: which of the four halves.
        Half(i32, i32, u8),
        /// One quarter of cell (x, y).
        Quarter(i32, i32, u8),
    }

    /// Quarter `q` of cell (x, y): 0 bottom, 1 right, 2 top, 3 left.
    fn quarter(x: i32, y: i32, q: u8) -> Vec<DVec2> {
        let (x, y) = (f64::from(x), f64::from(y));
        let corners = [v(x, y), v(x + 1.0, y), v(x + 1.0, y + 1.0), v(x, y + 1.0)];
        let q = usize::from(q % 4);
        vec![corners[q], corners[(q + 1) % 4], v(x + 0.5, y + 0.5)]
    }

    impl LatticeShape {
        fn polygon(&self) -> Vec<DVec2> {
            match *self {
                LatticeShape::Rect(x, y, w, h) => rect(
                    f64::from(x),
                    f64::from(y),
                    f64::from(x + w),
                    f64::from(y + h),
                ),
                LatticeShape::Half(x, y, half) => {
                    let (x, y) = (f64::from(x), f64::from(y));
                    let c = [v(x, y), v(x + 1.0, y), v(x + 1.0, y + 1.0), v(x, y + 1.0)];
                    // The half made of quarters `half` and `half + 1`: the corners of those
                    // two quarters' outer edges.
                    let h = usize::from(half % 4);
                    vec![c[h], c[(h + 1) % 4], c[(h + 2) % 4]]
                }
                LatticeShape::Quarter(x, y, q) => quarter(x, y, q),
            }
        }

        fn quarters(&self) -> Vec<(i32, i32, u8)> {
            match *self {
                LatticeShape::Rect(x, y, w, h) => (x..x + w)
                    .flat_map(|i| (y..y + h).flat_map(move |j| (0..4).map(move |q| (i, j, q))))
                    .collect(),
                LatticeShape::Half(x, y, half) => {
                    vec![(x, y, half % 4), (x, y, (half + 1) % 4)]
                }
                LatticeShape::Quarter(x, y, q) => vec![(x, y, q % 4)],
            }
        }
    }

    fn lattice_shape() -> impl Strategy<Value = LatticeShape> {
        prop_oneof![
            (0..6i32, 0..6i32, 1..4i32, 1..4i32)
                .prop_map(|(x, y, w, h)| LatticeShape::Rect(x, y, w, h)),
            (0..6i32, 0..6i32, 0..4u8).prop_map(|(x, y, h)| LatticeShape::Half(x, y, h)),
            (0..6i32, 0..6i32, 0..4u8).prop_map(|(x, y, q)| LatticeShape::Quarter(x, y, q)),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn union_of_two_matches_inclusion_exclusion(a in convex_polygon(), b in convex_polygon()) {
            let (area_a, area_b) = (signed_area(&a).abs(), signed_area(&b).abs());
            let want = area_a + area_b - intersection_area(&[&a, &b]);
            let got = union_area(&[&a, &b]);
            prop_assert!((got - want).abs() <= 1e-9 * (area_a + area_b), "{got} vs {want}");
        }

        #[test]
        fn union_of_three_matches_inclusion_exclusion(
            a in convex_polygon(),
            b in convex_polygon(),
            c in convex_polygon(),
        ) {
            let sum: f64 = [&a, &b, &c].iter().map(|p| signed_area(p).abs()).sum();
            let want = sum
                - intersection_area(&[&a, &b])
                - intersection_area(&[&a, &c])
                - intersection_area(&[&b, &c])
                + intersection_area(&[&a, &b, &c]);
            let got = union_area(&[&a, &b, &c]);
            prop_assert!((got - want).abs() <= 1e-9 * sum, "{got} vs {want}");
        }

        /// Shared edges, coincident shapes, vertex contacts and (unrotated) vertical edges
        /// everywhere, against an exact count of lattice quarters, under a random similarity.
        #[test]
        fn union_of_lattice_shapes_matches_the_quarter_count(
            shapes in prop::collection::vec(lattice_shape(), 2..8),
            spin in prop_oneof![Just(0.0), Just(TAU / 8.0), 0.0..TAU],
            scale in 0.01..10.0f64,
            shift in (-100.0..100.0f64, -100.0..100.0f64),
            clockwise in any::<bool>(),
        ) {
            let mut covered: Vec<(i32, i32, u8)> =
                shapes.iter().flat_map(LatticeShape::quarters).collect();
            covered.sort_unstable();
            covered.dedup();
            let want = 0.25 * covered.len() as f64 * scale * scale;
            let (sin, cos) = spin.sin_cos();
            let polygons: Vec<Vec<DVec2>> = shapes
                .iter()
                .map(|s| {
                    let p: Vec<DVec2> = s
                        .polygon()
                        .iter()
                        .map(|p| {
                            v(p.x * cos - p.y * sin, p.x * sin + p.y * cos) * scale
                                + v(shift.0, shift.1)
                        })
                        .collect();
                    if clockwise { reversed(&p) } else { p }
                })
                .collect();
            let slices: Vec<&[DVec2]> = polygons.iter().map(Vec::as_slice).collect();
            let sum: f64 = slices.iter().map(|p| signed_area(p).abs()).sum();
            let got = union_area(&slices);
            prop_assert!((got - want).abs() <= 1e-9 * sum, "{got} vs {want}");
        }

        /// Wild scales and slivers: finite, and between the largest polygon and the sum.
        #[test]
        fn union_is_finite_and_bounded(
            triangles in prop::collection::vec(
                (
                    prop::array::uniform6(-1.0..1.0f64),
                    -8i32..8,
                    prop_oneof![Just(0.0), Just(1e-12), 0.0..1.0f64],
                ),
                1..6,
            ),
        ) {
            let polygons: Vec<Vec<DVec2>> = triangles
                .iter()
                .map(|(c, exponent, flatness)| {
                    let s = 10f64.powi(*exponent);
                    let (a, b) = (v(c[0], c[1]) * s, v(c[2], c[3]) * s);
                    // The third corner pulled towards the segment ab: slivers and exact zeros.
                    let apex = v(c[4], c[5]) * s;
                    let foot = a.lerp(b, 0.5);
                    vec![a, b, foot + (apex - foot) * *flatness]
                })
                .collect();
            let slices: Vec<&[DVec2]> = polygons.iter().map(Vec::as_slice).collect();
            let areas: Vec<f64> = slices.iter().map(|p| signed_area(p).abs()).collect();
            let sum: f64 = areas.iter().sum();
            let largest = areas.iter().copied().fold(0.0, f64::max);
            // Slivers' areas (the shoelace's included) are only good to rounding of the
            // bounding box's area: allow that, on top of the relative 1e-9.
            let (low, high) = slices.iter().fold(
                (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
                |(low, high), p| {
                    let (min, max) = bounding_box(p);
                    (low.min(min), high.max(max))
                },
            );
            let size = high - low;
            let slack = 1e-9 * sum + 1e3 * f64::EPSILON * size.x * size.y;
            let got = union_area(&slices);
            prop_assert!(got.is_finite());
            prop_assert!(got >= largest - slack && got <= sum + slack, "{got} {areas:?}");
        }

        #[test]
        fn clip_convex_is_symmetric_and_bounded(a in convex_polygon(), b in convex_polygon()) {
            let (area_a, area_b) = (signed_area(&a).abs(), signed_area(&b).abs());
            let ab = intersection(&a, &b);
            let ba = intersection(&b, &a);
            prop_assert!(ab.iter().chain(&ba).all(|p| p.is_finite()));
            let (s_ab, s_ba) = (signed_area(&ab), signed_area(&ba));
            // The subject's orientation is kept.
            prop_assert!(s_ab == 0.0 || s_ab.signum() == signed_area(&a).signum());
            prop_assert!((s_ab.abs() - s_ba.abs()).abs() <= 1e-12 * (area_a + area_b));
            prop_assert!(s_ab.abs() <= area_a.min(area_b) * (1.0 + 1e-12));
        }

        #[test]
        fn half_planes_split_the_area(p in convex_polygon(), angle in 0.0..TAU, c in -2.0..2.0f64) {
            let n = v(angle.cos(), angle.sin());
            let (mut inside, mut outside) = (Vec::new(), Vec::new());
            clip_half_plane(&p, n, c, &mut inside);
            clip_half_plane(&p, -n, -c, &mut outside);
            let area = signed_area(&p).abs();
            let split = signed_area(&inside).abs() + signed_area(&outside).abs();
            prop_assert!((split - area).abs() <= 1e-12 * area);
            prop_assert!(inside.iter().all(|x| n.dot(*x) - c >= -1e-12));
            prop_assert!(outside.iter().all(|x| n.dot(*x) - c <= 1e-12));
        }
    }
}
