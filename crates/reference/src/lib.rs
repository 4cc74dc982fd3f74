//! Independent references for form factors: closed forms from Howell's catalogue of
//! configuration factors, generalised by corner-sum superposition to axis-aligned rectangles
//! at any offsets, and a Gauss–Legendre rule for brute-force quadratures of the area integral
//! (Goral et al. 1984, eq. 12).
//!
//! These references share no code with the integrator under test (`bake-form-factor`, the
//! contour integral of eq. 13): they are what its tests and `tools/accuracy-report` measure it
//! against. The crate is not part of the baking pipeline.
//!
//! Public API: [`axis_aligned_rectangles`] (F_ab of two axis-aligned rectangles in any
//! position), [`dense_form_factors`] (the dense matrix of a mesh of such rectangles), the
//! closed forms they rest on ([`parallel_opposed`], [`perpendicular_shared_edge`],
//! [`parallel_rectangles`], [`perpendicular_rectangles`] over [`Rect`]), [`gauss_legendre`],
//! [`box_walls`] and [`unit_cube_walls`].

use glam::DVec3;
use mesher::ElementMesh;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Gauss–Legendre nodes and weights on [-1, 1] of any order, by Newton's method on P_n
/// (independent of the integrator's table).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut rule = Vec::with_capacity(n);
    for k in 0..n {
        // Tricomi's initial guess, then Newton on P_n(x) = 0.
        let mut x = (PI * (k as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for m in 2..=n {
                let p2 = ((2 * m - 1) as f64 * x * p1 - (m - 1) as f64 * p0) / m as f64;
                p0 = p1;
                p1 = p2;
            }
            // P_n'(x) = n (x P_n − P_{n−1}) / (x² − 1).
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        rule.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    rule
}

// ---------------------------------------------------------------------------------------------
// Closed forms (Howell's catalogue of configuration factors).
// ---------------------------------------------------------------------------------------------

/// Directly opposed parallel rectangles a × b, distance c (Howell C-11).
pub fn parallel_opposed(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (x1, y1) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    2.0 / (PI * x * y)
        * (((1.0 + x * x) * (1.0 + y * y) / (1.0 + x * x + y * y))
            .sqrt()
            .ln()
            + x * y1 * (x / y1).atan()
            + y * x1 * (y / x1).atan()
            - x * x.atan()
            - y * y.atan())
}

/// Perpendicular rectangles sharing an edge of length l; i has width w, j height h (Howell C-14).
pub fn perpendicular_shared_edge(l: f64, w: f64, h: f64) -> f64 {
    let (hh, ww) = (h / l, w / l);
    let (h2, w2) = (hh * hh, ww * ww);
    let s = (h2 + w2).sqrt();
    let log = ((1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2)).ln()
        + w2 * (w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2))).ln()
        + h2 * (h2 * (1.0 + h2 + w2) / ((1.0 + h2) * (h2 + w2))).ln();
    (ww * (1.0 / ww).atan() + hh * (1.0 / hh).atan() - s * (1.0 / s).atan() + 0.25 * log)
        / (PI * ww)
}

/// An axis-aligned rectangle `[x0, x1] × [y0, y1]` in its plane's coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
}

impl Rect {
    fn area(&self) -> f64 {
        (self.x1 - self.x0) * (self.y1 - self.y0)
    }
}

/// `s · atan(d / s)`, continuous at s = 0 (→ 0).
fn s_atan(d: f64, s: f64) -> f64 {
    if s == 0.0 {
        0.0
    } else {
        s * (d / s).atan()
    }
}

/// `a · ln b` with the limit 0 when both vanish together (a ∝ b at the corners).
fn a_ln(a: f64, b: f64) -> f64 {
    if b == 0.0 {
        0.0
    } else {
        a * b.ln()
    }
}

/// `Σ_{k,l,m,n ∈ {0,1}} (−1)^{k+l+m+n} g(x_k, y_l, ξ_m, η_n) / A_1` over the corners of `r1`
/// (x, y) and `r2` (ξ, η): the superposition both offset closed forms share.
fn corner_sum(r1: Rect, r2: Rect, g: impl Fn(f64, f64, f64, f64) -> f64) -> f64 {
    let mut sum = 0.0;
    for (k, x) in [r1.x0, r1.x1].into_iter().enumerate() {
        for (l, y) in [r1.y0, r1.y1].into_iter().enumerate() {
            for (m, xi) in [r2.x0, r2.x1].into_iter().enumerate() {
                for (n, eta) in [r2.y0, r2.y1].into_iter().enumerate() {
                    let sign = if (k + l + m + n) % 2 == 0 { 1.0 } else { -1.0 };
                    sum += sign * g(x, y, xi, eta);
                }
            }
        }
    }
    sum / r1.area()
}

/// Parallel, directly facing, axis-aligned rectangles at any offsets (Siegel & Howell; Ehlert &
/// Smith 1993): i = `r1` in the plane z = 0, j = `r2` in the plane z = `c` (c > 0), both in
/// the same (x, y) axes. The corner sum
///
/// ```text
///   F_ij = 1/A_i Σ_{k,l,m,n ∈ {0,1}} (−1)^{k+l+m+n} G(x_k − ξ_m, y_l − η_n)
///   G(X, Y) = 1/(2π) [ Y √(X²+c²) atan(Y/√(X²+c²)) + X √(Y²+c²) atan(X/√(Y²+c²))
///                      − c²/2 ln(X² + Y² + c²) ]
/// ```
///
/// (G is a fourth antiderivative of the kernel c²/(π r⁴) in x, y, ξ, η.)
pub fn parallel_rectangles(r1: Rect, r2: Rect, c: f64) -> f64 {
    let g = |x: f64, y: f64| {
        let (sx, sy) = ((x * x + c * c).sqrt(), (y * y + c * c).sqrt());
        (y * s_atan(y, sx) + x * s_atan(x, sy) - 0.5 * c * c * (x * x + y * y + c * c).ln())
            / (2.0 * PI)
    };
    corner_sum(r1, r2, |x, y, xi, eta| g(x - xi, y - eta))
}

/// Perpendicular axis-aligned rectangles at any offsets (Siegel & Howell; Ehlert & Smith 1993):
/// i = `r1` = `[x0, x1] × [y0, y1]` in the plane z = 0 (facing +z), j = `r2` =
/// `[ξ0, ξ1] × [η0, η1]` in the plane y = 0 (ξ along x, η along z, facing +y), with
/// y0, η0 ≥ 0 (both on the same side of the common line). The corner sum
///
/// ```text
///   F_ij = 1/A_i Σ (−1)^{k+l+m+n} G(x_k − ξ_m, y_l, η_n)
///   G(X, y, η) = 1/(2π) [ X s atan(X/s) + ¼ (X² − s²) ln(X² + s²) ],   s² = y² + η²
/// ```
///
/// Derivation: the kernel is y η / (π r⁴), r² = X² + s², X = x − ξ; it is ∂²/∂y∂η of
/// −ln(r²)/(4π); integrating that twice in X gives −1/(4π) [½ (X² − s²) ln r² + 2 s X atan(X/s)]
/// plus terms in X² or s² alone, which cancel in the corner sum; the double integral over x and ξ
/// of a function of x − ξ has the opposite corner sign to the one over y and η, hence the sign.
pub fn perpendicular_rectangles(r1: Rect, r2: Rect) -> f64 {
    let g = |x: f64, y: f64, eta: f64| {
        let s = (y * y + eta * eta).sqrt();
        let r2 = x * x + s * s;
        (x * s_atan(x, s) + 0.25 * a_ln(x * x - s * s, r2)) / (2.0 * PI)
    };
    corner_sum(r1, r2, |x, y, xi, eta| g(x - xi, y, eta))
}

// ---------------------------------------------------------------------------------------------
// Axis-aligned rectangles in any position.
// ---------------------------------------------------------------------------------------------

/// Relative tolerance of [`axis_aligned_rectangles`]: a coordinate within `TOLERANCE` × the
/// size of a rectangle (or of a pair), plus the rounding of coordinates of that magnitude,
/// counts as equal.
pub const TOLERANCE: f64 = 1e-12;

/// An axis-aligned rectangle in world coordinates: the plane `p[axis] = plane`, facing
/// `facing` (±1) along `axis`, and the intervals `[lo[k], hi[k]]` along the other two axes.
#[derive(Clone, Copy, Debug)]
struct AxisRect {
    axis: usize,
    facing: f64,
    plane: f64,
    lo: [f64; 3],
    hi: [f64; 3],
}

impl AxisRect {
    /// The two in-plane axes, in cyclic order after the normal's.
    fn in_plane(&self) -> (usize, usize) {
        ((self.axis + 1) % 3, (self.axis + 2) % 3)
    }

    fn area(&self) -> f64 {
        let (u, w) = self.in_plane();
        (self.hi[u] - self.lo[u]) * (self.hi[w] - self.lo[w])
    }

    /// The largest coordinate magnitude (for the rounding allowance).
    fn magnitude(&self) -> f64 {
        self.lo
            .iter()
            .chain(&self.hi)
            .fold(0.0f64, |m, c| m.max(c.abs()))
    }

    /// The rectangle's coordinates along the other two axes, as [`Rect`] in the order `(u, w)`.
    fn rect(&self, u: usize, w: usize) -> Rect {
        Rect {
            x0: self.lo[u],
            x1: self.hi[u],
            y0: self.lo[w],
            y1: self.hi[w],
        }
    }
}

/// Reads 4 vertices as an axis-aligned rectangle: one axis along which they agree (within
/// tolerance), the other two each taking two values, the vertices visiting the four corners in
/// cyclic order; the facing side by the right-hand rule on the vertex order. `None` otherwise
/// (other vertex counts, non-finite coordinates, zero extent, a non-rectangle).
fn axis_rect(p: &[DVec3]) -> Option<AxisRect> {
    if p.len() != 4 || !p.iter().all(|q| q.is_finite()) {
        return None;
    }
    let (lo, hi) = p
        .iter()
        .fold((p[0], p[0]), |(lo, hi), &q| (lo.min(q), hi.max(q)));
    let extent = hi - lo;
    let magnitude = lo.abs().max(hi.abs()).max_element();
    let tol = TOLERANCE * extent.max_element() + 4.0 * f64::EPSILON * magnitude;
    let flat: Vec<usize> = (0..3).filter(|&k| extent[k] <= tol).collect();
    let [axis] = flat[..] else {
        return None;
    };
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    // Which corner each vertex is at: (at hi along u, at hi along w).
    let side = |c: f64, k: usize| {
        if (c - lo[k]).abs() <= tol {
            Some(false)
        } else if (c - hi[k]).abs() <= tol {
            Some(true)
        } else {
            None
        }
    };
    let mut corners = [(false, false); 4];
    for (corner, q) in corners.iter_mut().zip(p) {
        *corner = (side(q[u], u)?, side(q[w], w)?);
    }
    for k in 0..4 {
        let (a, b) = (corners[k], corners[(k + 1) % 4]);
        // Consecutive vertices differ in exactly one coordinate; with 4 of them, all distinct.
        if (a.0 != b.0) == (a.1 != b.1) {
            return None;
        }
    }
    if corners[0] == corners[2] {
        return None;
    }
    let normal = (p[1] - p[0]).cross(p[2] - p[1]);
    Some(AxisRect {
        axis,
        facing: normal[axis].signum(),
        plane: 0.5 * (lo[axis] + hi[axis]),
        lo: lo.to_array(),
        hi: hi.to_array(),
    })
}

/// The part `[max(lo, 0), hi]` of an interval of heights in front of a plane, or `None` where
/// nothing is in front; heights within `tol` of the plane count as on it.
fn front(lo: f64, hi: f64, tol: f64) -> Option<(f64, f64)> {
    if hi <= tol {
        None
    } else if lo <= tol {
        Some((0.0, hi))
    } else {
        Some((lo, hi))
    }
}

/// Heights `facing · (c − plane)` of the interval `[lo, hi]`, sorted.
fn heights(lo: f64, hi: f64, plane: f64, facing: f64) -> (f64, f64) {
    let (a, b) = (facing * (lo - plane), facing * (hi - plane));
    (a.min(b), a.max(b))
}

/// F_ab of two valid axis-aligned rectangles (see [`axis_aligned_rectangles`]).
fn pair(a: &AxisRect, b: &AxisRect) -> f64 {
    let size = (0..3).fold(0.0f64, |m, k| {
        m.max(a.hi[k].max(b.hi[k]) - a.lo[k].min(b.lo[k]))
    });
    let tol = TOLERANCE * size + 4.0 * f64::EPSILON * a.magnitude().max(b.magnitude());
    if a.axis == b.axis {
        let d = b.plane - a.plane;
        // Same plane, b behind a, or a behind b (both then face the same way).
        if d.abs() <= tol || a.facing * d <= 0.0 || b.facing * d >= 0.0 {
            return 0.0;
        }
        let (u, w) = a.in_plane();
        return parallel_rectangles(a.rect(u, w), b.rect(u, w), d.abs());
    }
    // Perpendicular: a isometry (permutation and reflections of the axes) to the frame of
    // `perpendicular_rectangles`: x along the common axis t, z the height in front of a,
    // y the height in front of b.
    let t = 3 - a.axis - b.axis;
    let (ya0, ya1) = heights(a.lo[b.axis], a.hi[b.axis], b.plane, b.facing);
    let (zb0, zb1) = heights(b.lo[a.axis], b.hi[a.axis], a.plane, a.facing);
    let (Some((y0, y1)), Some((eta0, eta1))) = (front(ya0, ya1, tol), front(zb0, zb1, tol)) else {
        return 0.0;
    };
    let r1 = Rect {
        x0: a.lo[t],
        x1: a.hi[t],
        y0,
        y1,
    };
    let r2 = Rect {
        x0: b.lo[t],
        x1: b.hi[t],
        y0: eta0,
        y1: eta1,
    };
    // Only the front parts exchange light: F_ab = A_a' F_a'b' / A_a.
    perpendicular_rectangles(r1, r2) * (y1 - y0) / (ya1 - ya0)
}

/// Exact F_ab, the fraction of the light leaving `a` that reaches `b` (eq. 12, no occluders),
/// for two planar rectangles whose edges are each parallel to a coordinate axis, each given as
/// 4 vertices counter-clockwise about its front side (the normal by the right-hand rule on the
/// vertex order).
///
/// - Parallel planes facing each other, at any offsets: [`parallel_rectangles`].
/// - Perpendicular planes, any of the axis pairs, either facing side, at any offsets:
///   [`perpendicular_rectangles`] after mapping the pair onto its frame by a permutation and
///   reflections of the axes. A rectangle that straddles the other's plane is clipped to its
///   part in front (only front parts exchange light, as the cosines of eq. 12 are clamped at
///   0), and F_ab is that part's share of the area times its form factor.
/// - `Some(0.0)` for pairs that cannot see each other: the same plane, parallel planes facing
///   the same way or away from each other, or one wholly behind (or in) the other's plane.
///
/// `None` when an input is not an axis-aligned rectangle: not 4 vertices, a non-finite
/// coordinate, zero extent, or vertices off the rectangle's corners or out of cyclic order by
/// more than [`TOLERANCE`] × its size (plus the rounding of coordinates of its magnitude).
pub fn axis_aligned_rectangles(a: &[DVec3], b: &[DVec3]) -> Option<f64> {
    Some(pair(&axis_rect(a)?, &axis_rect(b)?))
}

/// The row-major n×n form-factor matrix `data[i * n + j] = F_ij` of a mesh whose elements are
/// all axis-aligned rectangles (corners `mesh.elements[i].corner_indices()` into
/// `mesh.vertices`, counter-clockwise about the front side), by [`axis_aligned_rectangles`].
///
/// Each unordered pair is computed once (rows in parallel; every entry by the same sequential
/// code, so the result does not depend on the thread count) as F_ij for i < j, and F_ji follows
/// by reciprocity, `A_i F_ij = A_j F_ji` (eq. 14), with the rectangles' areas from their
/// corners. `None` if any element is not an axis-aligned rectangle (a triangle, a tilted quad,
/// a corner index out of range).
pub fn dense_form_factors(mesh: &ElementMesh) -> Option<Vec<f64>> {
    let rects = mesh
        .elements
        .iter()
        .map(|e| {
            let corners = e
                .corner_indices()
                .iter()
                .map(|&c| mesh.vertices.get(c as usize).copied())
                .collect::<Option<Vec<DVec3>>>()?;
            axis_rect(&corners)
        })
        .collect::<Option<Vec<AxisRect>>>()?;
    let n = rects.len();
    let mut data = vec![0.0f64; n * n];
    data.par_chunks_mut(n.max(1))
        .enumerate()
        .for_each(|(i, row)| {
            for (j, f) in row.iter_mut().enumerate().skip(i + 1) {
                *f = pair(&rects[i], &rects[j]);
            }
        });
    let areas: Vec<f64> = rects.iter().map(AxisRect::area).collect();
    for i in 0..n {
        for j in i + 1..n {
            data[j * n + i] = data[i * n + j] * areas[i] / areas[j];
        }
    }
    Some(data)
}

/// The six walls of the axis-aligned box `corner + size · [0, 1]³` (`size` > 0 in every
/// component), each counter-clockwise about the normal that faces the box's centre (inward: the
/// inside of a closed box), in the order z = 0, z = 1, x = 0, x = 1, y = 0, y = 1 of the unit
/// coordinates.
pub fn box_walls(corner: DVec3, size: DVec3) -> [[DVec3; 4]; 6] {
    let p = |x: f64, y: f64, z: f64| corner + size * DVec3::new(x, y, z);
    [
        [p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.)],
        [p(0., 0., 1.), p(0., 1., 1.), p(1., 1., 1.), p(1., 0., 1.)],
        [p(0., 0., 0.), p(0., 1., 0.), p(0., 1., 1.), p(0., 0., 1.)],
        [p(1., 0., 0.), p(1., 0., 1.), p(1., 1., 1.), p(1., 1., 0.)],
        [p(0., 0., 0.), p(0., 0., 1.), p(1., 0., 1.), p(1., 0., 0.)],
        [p(0., 1., 0.), p(1., 1., 0.), p(1., 1., 1.), p(0., 1., 1.)],
    ]
}

/// The six inward walls of the unit cube `[0, 1]³` (the paper's cube), as [`box_walls`].
pub fn unit_cube_walls() -> [[DVec3; 4]; 6] {
    box_walls(DVec3::ZERO, DVec3::ONE)
}
