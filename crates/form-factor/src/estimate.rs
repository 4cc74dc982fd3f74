//! Cheaper estimators of `A_i F_ij` than the contour integral, and the automatic choice among
//! them by an a-priori error model.
//!
//! - **Point-to-polygon** (Lambert; Baum, Rushmeier & Winget 1989): the form factor from a
//!   differential area at x (normal n) to a polygon P wholly in front of it is exact in closed
//!   form,
//!   ```text
//!     F_{dx→P} = 1/(2π) Σ_k γ_k  n · (R_k × R_{k+1}) / |R_k × R_{k+1}|,   R_k = p_k − x,
//!   ```
//!   γ_k the angle between R_k and R_{k+1}. Eq. 12's outer integral over element i is then done
//!   by a triangle quadrature rule on each triangle of i's fan: `A_i F_ij ≈ Σ_q w_q F_{dx_q→j}`.
//!   Its error comes only from i's side; the quadrature points go on the smaller element.
//! - **Point-to-point**: eq. 12's integrand at the two centroids,
//!   `A_i F_ij ≈ A_i A_j cosθ_i cosθ_j / (π r²)`. One evaluation; exact only as distance/size → ∞.
//!
//! # Error model (the automatic choice)
//!
//! Both estimators are quadratures of a smooth kernel, so their relative error falls like a
//! power of the ratio of the distance to the size of the integrated element. The distance that
//! matters is the *height* over the other element's plane: the kernel varies over element i on
//! the scale of i's centroid height h above j's plane (a grazing pair, small h, varies fast even
//! when the centroids are far apart). With r_i the largest centroid–vertex distance of i:
//!
//! ```text
//!   point-to-polygon, points on i, rule of degree p−1:   e ≤ C_p (r_i / h_i)^p
//!   point-to-point:                                      e ≤ C_pp max(r_i/h_i, r_j/h_j)²
//! ```
//!
//! with the constants measured as the worst case over random pairs (quads and triangles of
//! random shape, size, orientation and distance; see `error_model_constants` in the tests) and
//! stated with a margin. The contour integral itself is a candidate too, with a fixed Gauss
//! rule of order 2–4 on whole edges (error `C (r/h)^p` on the worse side). [`Estimator::Auto`]
//! takes the cheapest candidate (in ln-evaluation units: point-to-polygon's edge terms cost
//! about two) whose bound meets the tolerance and falls back to the exact contour integral.

use crate::polygon::{Poly, CAPACITY};
use glam::DVec3;
use std::f64::consts::PI;

/// How `A_i F_ij` is computed for each facing pair.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Estimator {
    /// The contour integral (eq. 13) with the [`crate::ContourOptions`] given: exact to the
    /// quadrature's rounding level with the default options.
    #[default]
    Contour,
    /// Point-to-polygon closed form, integrated over the smaller element by `rule`.
    PointPolygon(TriangleRule),
    /// Point-to-point approximation at the centroids.
    PointPoint,
    /// Per pair, the cheapest of point-to-point, point-to-polygon (each rule) and the contour
    /// integral whose error bound keeps the pair's relative error within `tolerance`
    /// (the contour integral everywhere below [`MIN_TOLERANCE`]).
    Auto { tolerance: f64 },
}

impl Estimator {
    /// Bound on `|Σ_j F_ij − 1|` inside a closed enclosure that the solver may assume:
    /// [`crate::ROW_SUM_ACCURACY`] for the contour integral, the tolerance for
    /// [`Estimator::Auto`] (each F_ij within it relatively). The fixed cheap estimators have no
    /// bound (point-to-point is off by tens of percent between touching elements): 0.1 is
    /// assumed for them, so the solver refuses scenes an error that size could ruin.
    pub fn row_sum_accuracy(&self) -> f64 {
        match *self {
            Estimator::Contour => crate::ROW_SUM_ACCURACY,
            Estimator::Auto { tolerance } if tolerance < MIN_TOLERANCE => crate::ROW_SUM_ACCURACY,
            Estimator::Auto { tolerance } => tolerance.max(crate::ROW_SUM_ACCURACY),
            Estimator::PointPolygon(_) | Estimator::PointPoint => 0.1,
        }
    }
}

/// Quadrature rule on each triangle of an element's fan (a quad is two triangles).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum TriangleRule {
    /// One point at the element's area centroid (not per triangle), exact for polynomials
    /// of degree 1.
    Centroid,
    /// Strang & Fix's 3-point rule: exact to degree 2.
    Three,
    /// Radon's 7-point rule: exact to degree 5.
    Seven,
}

impl TriangleRule {
    pub const ALL: [TriangleRule; 3] = [
        TriangleRule::Centroid,
        TriangleRule::Three,
        TriangleRule::Seven,
    ];

    /// Points per triangle (per element for [`TriangleRule::Centroid`]).
    pub fn points(self) -> u32 {
        match self {
            TriangleRule::Centroid => 1,
            TriangleRule::Three => 3,
            TriangleRule::Seven => 7,
        }
    }

    /// The rule with this many points per triangle.
    pub fn from_points(points: u32) -> Option<TriangleRule> {
        TriangleRule::ALL.into_iter().find(|r| r.points() == points)
    }

    /// The power p of the error bound `C_p (r/h)^p` (degree + 1).
    fn order(self) -> i32 {
        match self {
            TriangleRule::Centroid => 2,
            TriangleRule::Three => 3,
            TriangleRule::Seven => 6,
        }
    }

    /// C_p of the error bound: the measured worst case times a margin of 2 (see the module
    /// documentation and the `error_model_constants` test).
    fn constant(self) -> f64 {
        match self {
            TriangleRule::Centroid => POINT_POLYGON_CONSTANTS[0],
            TriangleRule::Three => POINT_POLYGON_CONSTANTS[1],
            TriangleRule::Seven => POINT_POLYGON_CONSTANTS[2],
        }
    }

    /// Barycentric points and weights (weights sum to 1).
    fn nodes(self) -> &'static [([f64; 3], f64)] {
        match self {
            TriangleRule::Centroid => &CENTROID,
            TriangleRule::Three => &THREE,
            TriangleRule::Seven => &SEVEN,
        }
    }
}

/// Measured worst `e · (h/r)^p` over 4000 random pairs (h/r from 0.5 to beyond 256), about ×2
/// for margin: centroid 1.43 → 3.0, 3-point 0.110 → 0.25, 7-point 0.156 → 0.35. The 7-point
/// rule's error reaches the rounding level of the reference (~1e-11 relative) beyond h/r ≈ 32,
/// so its constant is measured below that; tolerances under [`MIN_TOLERANCE`] use the contour
/// integral alone.
const POINT_POLYGON_CONSTANTS: [f64; 3] = [3.0, 0.25, 0.35];

/// The contour integral with a fixed product Gauss rule on whole edges (the paper's rule
/// without its segments: no semi-analytic near pairs), orders 2, 3, 4: error `C (r/h)^p` with
/// h/r the worse side (both contours are discretised). Measured worst: order 2, p = 3: 0.098
/// → 0.2; order 3, p = 4: 7.9e-3 → 0.02; order 4, p = 6: 2.8e-2 → 0.06 (h/r below 32: beyond
/// it the contour integral's own rounding, ~1e-10 relative, dominates; see `GAUSS_FLOOR`).
const GAUSS_RULES: [(u32, i32, f64); 3] = [(2, 3, 0.2), (3, 4, 0.02), (4, 6, 0.06)];
/// Rounding floor of the fixed Gauss contour rules (relative), added to their bounds.
const GAUSS_FLOOR: f64 = 1e-9;

/// The contour integral with the paper's 3-point rule and the semi-analytic rule only for
/// segment pairs closer than 2 lengths (instead of 8): good at contact, where the Gauss rules
/// above are not. Measured worst error per octave of h/r (worse side): 1.0e-3 below 1,
/// 2.8e-5 at 1–2, 7.6e-5 at 2–4, 4.3e-6 at 4–8, 2.4e-7 at 8–16; bound `2e-3 / max(1, h/r)²`.
const NEAR_RATIO: f64 = 2.0;
const NEAR_CONSTANT: f64 = 2e-3;

/// Relative cost of one edge term of point-to-polygon (an atan2, a cross product, a square
/// root) against one ln of the contour integral, measured on the cube at 4 × 4 per wall:
/// 24 ns against 12 ns.
const EDGE_TERM_COST: f64 = 2.0;

/// What [`Estimator::Auto`] picked for a pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Choice {
    PointPoint,
    PointPolygon(TriangleRule),
    /// The contour integral by a fixed Gauss rule of this order on whole edges.
    Gauss(u32),
    /// The contour integral, 3-point rule, semi-analytic below [`NEAR_RATIO`] lengths.
    Near,
    /// The contour integral with the caller's options (exact to rounding by default).
    Exact,
}

/// The cheapest estimator whose error bound meets `tolerance`: costs in ln evaluations.
pub(crate) fn choose(g: &PairGeometry, polys: [&Poly; 2], tolerance: f64) -> Choice {
    if tolerance < MIN_TOLERANCE {
        return Choice::Exact;
    }
    let mut best = (f64::INFINITY, Choice::Exact);
    let mut consider = |bound: f64, cost: f64, choice: Choice| {
        if bound <= tolerance && cost < best.0 {
            best = (cost, choice);
        }
    };
    consider(g.point_point_bound(), 1.0, Choice::PointPoint);
    let s = g.point_side();
    let edges = polys[1 - s].len() as f64;
    let triangles = polys[s].len().saturating_sub(2) as f64;
    for rule in TriangleRule::ALL {
        let points = match rule {
            TriangleRule::Centroid => 1.0,
            _ => rule.points() as f64 * triangles,
        };
        consider(
            g.point_polygon_bound(rule),
            points * edges * EDGE_TERM_COST,
            Choice::PointPolygon(rule),
        );
    }
    // Counting the non-perpendicular edge pairs (the contour rules' cost) takes 8
    // normalisations: only when some contour rule's bound can meet the tolerance.
    let ratio = g.ratio(0).min(g.ratio(1));
    let gauss_bounds =
        GAUSS_RULES.map(|(_, power, constant)| constant * ratio.powi(-power) + GAUSS_FLOOR);
    let near_bound = NEAR_CONSTANT / ratio.max(1.0).powi(2) + GAUSS_FLOOR;
    if gauss_bounds
        .iter()
        .chain([&near_bound])
        .any(|&b| b <= tolerance)
    {
        let pairs = non_perpendicular_edge_pairs(polys) as f64;
        for ((order, _, _), bound) in GAUSS_RULES.into_iter().zip(gauss_bounds) {
            consider(bound, pairs * (order * order) as f64, Choice::Gauss(order));
        }
        // The semi-analytic segment pairs cost more: counted as twice the 3-point rule.
        consider(near_bound, pairs * 18.0, Choice::Near);
    }
    best.1
}

impl Choice {
    /// The contour options a choice computed by the contour integral uses (`exact`: the
    /// caller's, for [`Choice::Exact`]); `None` for the point estimators.
    pub(crate) fn contour_options(
        self,
        exact: crate::ContourOptions,
    ) -> Option<crate::ContourOptions> {
        let fixed = |order, near_ratio| crate::ContourOptions {
            segments: 1,
            order,
            auto_order: false,
            near_ratio,
        };
        match self {
            Choice::Gauss(order) => Some(fixed(order, 0.0)),
            Choice::Near => Some(fixed(3, NEAR_RATIO)),
            Choice::Exact => Some(exact),
            Choice::PointPoint | Choice::PointPolygon(_) => None,
        }
    }
}

/// Edge pairs of the two contours that are not perpendicular (perpendicular ones contribute
/// nothing to eq. 13 and cost nothing).
fn non_perpendicular_edge_pairs(polys: [&Poly; 2]) -> usize {
    let dirs = |p: &Poly| {
        let mut d = [DVec3::ZERO; 8];
        for (k, slot) in d.iter_mut().enumerate().take(p.len()) {
            *slot = (p.vertex((k + 1) % p.len()) - p.vertex(k)).normalize_or_zero();
        }
        d
    };
    let (a, b) = (dirs(polys[0]), dirs(polys[1]));
    let mut count = 0;
    for u in &a[..polys[0].len()] {
        for w in &b[..polys[1].len()] {
            count += usize::from(u.dot(*w).abs() >= 1e-14);
        }
    }
    count
}
/// Measured worst `e · (h/r)²` of point-to-point over the same pairs: 1.12 → 2.5.
const POINT_POINT_CONSTANT: f64 = 2.5;

/// Tolerances below this select the contour integral for every pair: the error model is only
/// measured down to here (the reference itself is accurate to ~1e-11 on far pairs).
pub const MIN_TOLERANCE: f64 = 1e-8;

const THIRD: f64 = 1.0 / 3.0;
const CENTROID: [([f64; 3], f64); 1] = [([THIRD, THIRD, THIRD], 1.0)];
const THREE: [([f64; 3], f64); 3] = [
    ([2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0], THIRD),
    ([1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0], THIRD),
    ([1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0], THIRD),
];
// Radon's degree-5 rule: a = (6 − √15)/21, b = (9 + 2√15)/21, weight (155 − √15)/1200;
// c = (6 + √15)/21, d = (9 − 2√15)/21, weight (155 + √15)/1200; centroid 9/40.
const SQRT15: f64 = 3.872_983_346_207_417;
const RA: f64 = (6.0 - SQRT15) / 21.0;
const RB: f64 = (9.0 + 2.0 * SQRT15) / 21.0;
const RC: f64 = (6.0 + SQRT15) / 21.0;
const RD: f64 = (9.0 - 2.0 * SQRT15) / 21.0;
const WA: f64 = (155.0 - SQRT15) / 1200.0;
const WC: f64 = (155.0 + SQRT15) / 1200.0;
const SEVEN: [([f64; 3], f64); 7] = [
    ([THIRD, THIRD, THIRD], 9.0 / 40.0),
    ([RB, RA, RA], WA),
    ([RA, RB, RA], WA),
    ([RA, RA, RB], WA),
    ([RD, RC, RC], WC),
    ([RC, RD, RC], WC),
    ([RC, RC, RD], WC),
];

/// Form factor from a differential area at `x` with unit normal `n` to the convex polygon
/// `polygon` wholly in front of it (Lambert's closed form; see the module documentation).
/// Exact for the unoccluded differential case.
pub fn point_to_polygon(x: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    edge_sum(x, n, polygon) / (2.0 * PI)
}

/// γ_k n·(R_k × R_{k+1}) / |R_k × R_{k+1}|, with γ_k by atan2 (accurate at small and large
/// angles, unlike acos of a dot product).
#[inline]
fn edge_term(x: DVec3, n: DVec3, p0: DVec3, p1: DVec3) -> f64 {
    let (r0, r1) = (p0 - x, p1 - x);
    let c = r0.cross(r1);
    let len = c.length();
    if len > 0.0 {
        len.atan2(r0.dot(r1)) * n.dot(c) / len
    } else {
        0.0
    }
}

/// `2π F_{dx→P}` for a polygon in front of x: the edge terms summed, sign dropped (it is
/// fixed by the polygon's orientation seen from x).
#[inline]
fn edge_sum(x: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for k in 0..polygon.len() {
        sum += edge_term(x, n, polygon[k], polygon[(k + 1) % polygon.len()]);
    }
    sum.abs()
}

/// Geometry of a facing pair that the estimators and their error bounds need.
pub(crate) struct PairGeometry {
    area: [f64; 2],
    centroid: [DVec3; 2],
    /// Largest centroid–vertex distance.
    radius: [f64; 2],
    /// Height of each centroid above the other polygon's plane.
    height: [f64; 2],
}

impl PairGeometry {
    pub(crate) fn new(a: &Poly, na: DVec3, b: &Poly, nb: DVec3) -> PairGeometry {
        let (area_a, ca) = area_centroid(a, na);
        let (area_b, cb) = area_centroid(b, nb);
        PairGeometry {
            area: [area_a, area_b],
            centroid: [ca, cb],
            radius: [radius(a, ca), radius(b, cb)],
            // Height of a's centroid above b's plane, and of b's above a's.
            height: [(ca - b.vertex(0)).dot(nb), (cb - a.vertex(0)).dot(na)],
        }
    }

    /// `(h/r)` for quadrature points on side `s`.
    pub(crate) fn ratio(&self, s: usize) -> f64 {
        if self.radius[s] > 0.0 {
            self.height[s].max(0.0) / self.radius[s]
        } else {
            f64::INFINITY
        }
    }

    /// The side to put quadrature points on: the smaller one (relative to its height).
    fn point_side(&self) -> usize {
        if self.ratio(0) >= self.ratio(1) {
            0
        } else {
            1
        }
    }

    /// Error bound of point-to-polygon with `rule` (points on the better side).
    pub(crate) fn point_polygon_bound(&self, rule: TriangleRule) -> f64 {
        rule.constant() * self.ratio(self.point_side()).powi(-rule.order())
    }

    /// Error bound of point-to-point.
    pub(crate) fn point_point_bound(&self) -> f64 {
        let worst = self.ratio(0).min(self.ratio(1));
        POINT_POINT_CONSTANT * worst.powi(-2)
    }
}

/// Area (by the fan about vertex 0, projected on `n`) and centroid.
fn area_centroid(p: &Poly, n: DVec3) -> (f64, DVec3) {
    let mut area = 0.0;
    let mut moment = DVec3::ZERO;
    let o = p.vertex(0);
    for k in 1..p.len().saturating_sub(1) {
        let (b, c) = (p.vertex(k), p.vertex(k + 1));
        let t = 0.5 * (b - o).cross(c - o).dot(n);
        area += t;
        moment += (o + b + c) * (t / 3.0);
    }
    let centroid = if area > 0.0 { moment / area } else { o };
    (area, centroid)
}

fn radius(p: &Poly, c: DVec3) -> f64 {
    (0..p.len())
        .map(|k| p.vertex(k).distance_squared(c))
        .fold(0.0, f64::max)
        .sqrt()
}

/// `A_a F_ab` (= `A_b F_ba`) by point-to-point at the centroids; 1 evaluation.
pub(crate) fn point_point(g: &PairGeometry, na: DVec3, nb: DVec3, evaluations: &mut u64) -> f64 {
    *evaluations += 1;
    let d = g.centroid[1] - g.centroid[0];
    let r2 = d.length_squared();
    if r2 == 0.0 {
        return 0.0;
    }
    // cosθ_a cosθ_b / r² = (n_a·d)(−n_b·d) / r⁴.
    let cos_product = (na.dot(d) * -nb.dot(d)).max(0.0);
    g.area[0] * g.area[1] * cos_product / (PI * r2 * r2)
}

/// `A_a F_ab` by point-to-polygon: quadrature points of `rule` on the smaller side's fan, the
/// other polygon exactly. Evaluations count edge terms.
pub(crate) fn point_polygon(
    g: &PairGeometry,
    polys: [&Poly; 2],
    normals: [DVec3; 2],
    rule: TriangleRule,
    evaluations: &mut u64,
) -> f64 {
    let s = g.point_side();
    let (from, n, to) = (polys[s], normals[s], polys[1 - s]);
    if rule == TriangleRule::Centroid {
        *evaluations += to.len() as u64;
        return g.area[s] * edge_sum(g.centroid[s], n, to.vertices()) / (2.0 * PI);
    }
    let o = from.vertex(0);
    let mut total = 0.0;
    for k in 1..from.len().saturating_sub(1) {
        let (b, c) = (from.vertex(k), from.vertex(k + 1));
        let area = 0.5 * (b - o).cross(c - o).dot(n);
        if area <= 0.0 {
            continue;
        }
        let mut tri = 0.0;
        for &([l0, l1, l2], w) in rule.nodes() {
            tri += w * edge_sum(o * l0 + b * l1 + c * l2, n, to.vertices());
        }
        *evaluations += (rule.nodes().len() * to.len()) as u64;
        total += area * tri;
    }
    total / (2.0 * PI)
}

/// `(max − min) / mean` of the point-to-polygon kernel over both sides of a facing pair (see
/// [`crate::PairScreen::variation`]): `F_{dx→b}` at points of `a` (the centroid of its
/// vertices, the midpoints from there towards each vertex, and points 95 % of the way to each
/// vertex, where the kernel of a pair sharing an edge peaks) and `F_{dy→a}` at the same points of `b`; the
/// larger.
/// Also returns the mean kernel over each side's points (`F_{dx→b}` over a, `F_{dy→a}` over b).
/// One side of a pair screened: the point-to-polygon kernel `F_{dx→to}` at sample points x
/// of `from` (see [`side_fit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SideFit {
    /// Mean of the kernel over the sample points.
    pub mean: f64,
    /// `(max − min) / mean` of the kernel over the points (0 when the mean is 0).
    pub spread: f64,
    /// `(max − min) / mean` of what a least-squares linear fit in the plane leaves over.
    pub residual: f64,
    /// The fit's gradient (in the plane of `from`, per unit of the coordinates given).
    pub gradient: DVec3,
}

/// How far towards each corner the outer sample points of [`side_fit`] lie: near the
/// corner, where the kernel of a pair sharing an edge peaks, but off the edge, where an edge
/// term of the closed form has no direction (x on the other polygon's edge line).
const CORNER_INSET: f64 = 0.95;

/// The kernel `F_{dx→to}` at points x of `from` (its centre, the midpoints towards its
/// corners, points [`CORNER_INSET`] of the way to them): its mean and relative spread, and the
/// least-squares plane `m + g · (x − x̄)` through the values (x̄ the points' mean, which is
/// the centre: the points are symmetric about it) with what that plane leaves unexplained.
/// The spread says how much a constant misrepresents the kernel over `from`, the residual how
/// much a linear function does (a first-order Taylor model of the receiver's irradiance).
/// With `fit` false only the centre is sampled (the mean is that one value; spread, residual
/// and gradient are 0): for a side whose variation does not matter (an element, which a
/// hierarchy never splits).
pub(crate) fn side_fit(from: &Poly, n: DVec3, to: &Poly, fit: bool) -> SideFit {
    let v = from.vertices();
    let centre = v.iter().copied().sum::<DVec3>() / v.len() as f64;
    if !fit {
        let mean = rough_point_to_polygon(centre, n, to.vertices());
        return SideFit {
            mean: if mean.is_finite() { mean } else { 0.0 },
            spread: 0.0,
            residual: 0.0,
            gradient: DVec3::ZERO,
        };
    }
    // An orthonormal frame of the plane.
    let t1 = (v[1] - v[0]).reject_from(n).normalize_or_zero();
    let t2 = n.cross(t1);
    let mut xs = [DVec3::ZERO; 1 + 2 * CAPACITY];
    let mut fs = [0.0f64; 1 + 2 * CAPACITY];
    let mut count = 0;
    // Near the corners too: next to a shared edge the kernel peaks where the midpoints miss it.
    let points = std::iter::once(centre)
        .chain(v.iter().map(|&c| (c + centre) * 0.5))
        .chain(v.iter().map(|&c| centre + (c - centre) * CORNER_INSET));
    for x in points.take(xs.len()) {
        xs[count] = x;
        fs[count] = rough_point_to_polygon(x, n, to.vertices());
        count += 1;
    }
    let (xs, fs) = (&xs[..count], &fs[..count]);
    let mean = fs.iter().sum::<f64>() / count as f64;
    if mean <= 0.0 || !mean.is_finite() {
        return SideFit {
            mean: 0.0,
            spread: 0.0,
            residual: 0.0,
            gradient: DVec3::ZERO,
        };
    }
    let (lo, hi) = fs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &f| {
            (lo.min(f), hi.max(f))
        });
    // Normal equations of the centred fit f − mean ≈ a u + b v.
    let (mut suu, mut suv, mut svv, mut suf, mut svf) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (x, f) in xs.iter().zip(fs) {
        let d = *x - centre;
        let (u, w) = (d.dot(t1), d.dot(t2));
        let df = f - mean;
        suu += u * u;
        suv += u * w;
        svv += w * w;
        suf += u * df;
        svf += w * df;
    }
    let det = suu * svv - suv * suv;
    let (a, b) = if det > 1e-12 * (suu * svv).max(f64::MIN_POSITIVE) {
        ((svv * suf - suv * svf) / det, (suu * svf - suv * suf) / det)
    } else {
        (0.0, 0.0)
    };
    let (mut rlo, mut rhi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (x, f) in xs.iter().zip(fs) {
        let d = *x - centre;
        let r = f - mean - a * d.dot(t1) - b * d.dot(t2);
        rlo = rlo.min(r);
        rhi = rhi.max(r);
    }
    SideFit {
        mean,
        spread: (hi - lo) / mean,
        residual: (rhi - rlo) / mean,
        gradient: t1 * a + t2 * b,
    }
}

/// [`point_to_polygon`] with a polynomial arctangent (absolute error below 1e-5 rad per edge):
/// for screening pairs, where four digits are plenty and the libm atan2 was a fifth of a
/// hierarchical bake's time.
fn rough_point_to_polygon(x: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    // A `Poly` holds at most CAPACITY corners.
    let m = polygon.len().min(CAPACITY);
    let mut r = [DVec3::ZERO; CAPACITY];
    for (rk, p) in r.iter_mut().zip(polygon) {
        *rk = *p - x;
    }
    let mut sum = 0.0;
    for k in 0..m {
        let (r0, r1) = (r[k], r[(k + 1) % m]);
        let c = r0.cross(r1);
        let cc = c.length_squared();
        if cc > 0.0 {
            let d = r0.dot(r1);
            // θ = atan2(|c|, d), and the edge term is θ (n·c) / |c|. Below 45° (d ≥ |c|),
            // atan(t) = t P(t²) with t = |c| / d gives θ / |c| = P(cc / d²) / d: no square
            // root (most edges of a screened pair are seen under small angles).
            if d > 0.0 && d * d >= cc {
                let inv = 1.0 / d;
                sum += atan_over_t(cc * inv * inv) * n.dot(c) * inv;
            } else {
                let len = cc.sqrt();
                sum += fast_atan2(len, d) * n.dot(c) / len;
            }
        }
    }
    sum.abs() / (2.0 * PI)
}

/// `atan(t) / t` for `t² = t2 ∈ [0, 1]`: the polynomial of [`fast_atan2`].
#[inline]
fn atan_over_t(t2: f64) -> f64 {
    0.999_977_26
        + t2 * (-0.332_623_47
            + t2 * (0.193_543_46 + t2 * (-0.116_432_87 + t2 * (0.052_653_32 - t2 * 0.011_721_20))))
}

/// atan2(y, x) for y ≥ 0, in [0, π]: a degree-11 odd minimax polynomial for atan on [0, 1]
/// (max error 2e-6 rad; Abramowitz & Stegun 4.4.49 style), reflected into the octants.
#[inline]
fn fast_atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den) = if ax >= ay { (ay, ax) } else { (ax, ay) };
    if den == 0.0 {
        return 0.0;
    }
    let t = num / den;
    let mut a = t * atan_over_t(t * t);
    if ay > ax {
        a = std::f64::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    a
}

#[cfg(test)]
mod fast_atan_tests {
    use glam::DVec3;

    #[test]
    fn rough_point_to_polygon_is_within_1e_5_of_the_closed_form() {
        // Points near and far from a unit square, in front of it and beside its plane.
        let square = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let mut worst = 0.0f64;
        for i in 0..40 {
            for h in [0.01, 0.3, 1.0, 5.0, 40.0] {
                let t = i as f64 / 39.0;
                let x = DVec3::new(-0.5 + 2.0 * t, 0.3 + t, h);
                for n in [
                    DVec3::NEG_Z,
                    DVec3::new(0.6, 0.0, -0.8),
                    DVec3::new(-0.6, 0.0, -0.8),
                ] {
                    let exact = super::point_to_polygon(x, n, &square);
                    let rough = super::rough_point_to_polygon(x, n, &square);
                    worst = worst.max((rough - exact).abs());
                }
            }
        }
        assert!(worst < 1e-5, "worst {worst}");
    }

    #[test]
    fn fast_atan2_is_within_1e_5_of_libm() {
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let angle = std::f64::consts::PI * i as f64 / 1999.0;
            for r in [1e-3, 1.0, 7e4] {
                let (y, x) = (r * angle.sin(), r * angle.cos());
                worst = worst.max((super::fast_atan2(y.abs(), x) - y.abs().atan2(x)).abs());
            }
        }
        assert!(worst < 1e-5, "worst {worst}");
    }
}
