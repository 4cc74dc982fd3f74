//! Element-to-element form factors by the contour integral (Goral et al. 1984, eq. 13):
//!
//! ```text
//!   F_ij = 1/(2π A_i) ∮_{C_i} ∮_{C_j} [ln r dx_i dx_j + ln r dy_i dy_j + ln r dz_i dz_j]
//! ```
//!
//! F_ij is the fraction of the light leaving element i that reaches element j (eq. 12), so the
//! radiosity system reads `b_i = e_i + ρ_i Σ_j F_ij b_j`.
//!
//! Public API: [`FormFactors`] over an [`ElementMesh`]: a single pair ([`FormFactors::pair`]),
//! one row on demand ([`FormFactors::row`]), or every pair at once ([`FormFactors::dense`],
//! computing each unordered pair once and using reciprocity, eq. 14). Callers that cannot
//! afford an N×N matrix use rows or pairs; the dense matrix is one user of them.
//!
//! Invariants: F ≥ 0; `A_i F_ij = A_j F_ji` (the double contour integral is symmetric, and the
//! dense path computes it once per pair); `F_ii = 0` (a plane does not see itself, eq. 16);
//! back-facing and coplanar pairs are exactly 0; rows are never renormalised.

mod contour;
mod estimate;
mod polygon;

pub use contour::{
    max_edge_pair_evaluations, ContourOptions, MAX_ORDER, MAX_PIECES, MAX_SEGMENT_PAIR_EVALUATIONS,
};
pub use estimate::{point_to_polygon, Estimator, TriangleRule, MIN_TOLERANCE};
use estimate::{Choice, PairGeometry};
use glam::DVec3;
use mesher::ElementMesh;
use polygon::Poly;
use rayon::prelude::*;
use scene::Convex;
use std::sync::Mutex;
use visibility::{Counters, OccludablePairs, Occluders, Visibility};

/// Normals with `n_i · n_j ≥ 1 − PARALLEL` count as parallel (angle ≤ 1.4e-7 rad). Two
/// elements tilted by θ see each other with F ~ 0.1 θ² at most (e.g. 0.078 θ² for unit squares
/// sharing an edge), so the pairs this culls have F ≲ 2e-15; rounding of normals from world
/// coordinates of magnitude X on polygons of size S is ~ε X / S rad (1e-9 at X / S = 1e7).
const PARALLEL: f64 = 1e-14;

/// How one pair was classified before integrating.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairKind {
    /// The same element, parallel planes facing the same way (coplanar neighbours included),
    /// or either element lies wholly behind (or in) the other's plane.
    Culled,
    /// Both face each other wholly: the contour integral of the elements as they are.
    Facing,
    /// One element straddles the other's plane and was clipped to the part in front.
    Clipped,
}

/// Work counters of a form-factor computation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Unordered element pairs considered.
    pub pairs: u64,
    /// Pairs whose contour integral was evaluated (not culled).
    pub pairs_integrated: u64,
    /// Of those, pairs that needed clipping.
    pub pairs_clipped: u64,
    /// Kernel evaluations: ln r or one closed-form segment integral (contour), one edge term
    /// (point-to-polygon), one centroid kernel (point-to-point).
    pub evaluations: u64,
    /// Integrated pairs by the estimator that computed them.
    pub pairs_by_method: MethodCounts,
    /// Occlusion work over the facing pairs: pairs tested, pairs occludable, rays cast.
    pub visibility: Counters,
}

/// Form factors between the elements of one mesh.
pub struct FormFactors<'a> {
    mesh: &'a ElementMesh,
    options: ContourOptions,
    estimator: Estimator,
    occlusion: Option<Occlusion<'a>>,
}

/// Which estimator computed a pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Contour,
    PointPolygon,
    PointPoint,
}

/// Pairs per [`Method`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MethodCounts {
    pub contour: u64,
    pub point_polygon: u64,
    pub point_point: u64,
}

impl<'a> FormFactors<'a> {
    /// Form factors of a scene where nothing occludes (the paper's assumption).
    pub fn new(mesh: &'a ElementMesh, options: ContourOptions) -> Self {
        FormFactors {
            mesh,
            options,
            estimator: Estimator::Contour,
            occlusion: None,
        }
    }

    /// Compute facing pairs by `estimator` instead of the contour integral alone.
    pub fn with_estimator(mut self, estimator: Estimator) -> Self {
        self.estimator = estimator;
        self
    }

    /// Hidden surfaces: every facing pair that some polygon can come between gets the exact
    /// contour value times its visible fraction (0 exactly when fully hidden); pairs nothing
    /// can come between keep the exact value and cast no ray.
    pub fn with_occlusion(mut self, occlusion: Occlusion<'a>) -> Self {
        self.occlusion = Some(occlusion);
        self
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.mesh.elements.len()
    }

    pub fn is_empty(&self) -> bool {
        self.mesh.elements.is_empty()
    }

    /// `A_i F_ij` (= `A_j F_ji`): the symmetric double contour integral over 2π, times the
    /// pair's visible fraction when occlusion is on ([`FormFactors::with_occlusion`]).
    pub fn area_weighted(&self, i: usize, j: usize) -> PairResult {
        if i == j {
            return PairResult::CULLED;
        }
        let (a, b) = (self.surface(i), self.surface(j));
        let Some(facing) = facing(&a, &b) else {
            return PairResult::CULLED;
        };
        let visibility = match &self.occlusion {
            Some(o) => o
                .occluders
                .element_pair(o.pairs, self.mesh, i, j, o.samples),
            None => Visibility::UNOCCLUDED,
        };
        // Fully hidden pairs are exactly 0: no integral needed.
        let (value, evaluations, method) = if visibility.fraction == 0.0 {
            (0.0, 0, None)
        } else {
            let (g, evaluations, method) =
                estimate_pair(&facing, [a.normal, b.normal], &self.options, self.estimator);
            (g * visibility.fraction, evaluations, Some(method))
        };
        PairResult {
            value,
            kind: facing.kind,
            evaluations,
            method,
            visibility,
        }
    }

    /// Element `i` as a [`Surface`].
    pub fn surface(&self, i: usize) -> Surface {
        Surface::element(self.mesh, i)
    }

    /// `F_ij`: the fraction of the light leaving element i that reaches element j.
    pub fn pair(&self, i: usize, j: usize) -> f64 {
        self.area_weighted(i, j).value / self.mesh.elements[i].area
    }

    /// Row i of F into `out` (length = number of elements), computed on demand.
    pub fn row(&self, i: usize, out: &mut [f64]) -> Stats {
        let mut stats = Stats::default();
        let area = self.mesh.elements[i].area;
        for (j, f) in out.iter_mut().enumerate() {
            let pair = self.area_weighted(i, j);
            *f = pair.value / area;
            stats.count(&pair);
        }
        stats
    }

    /// The whole matrix, row-major (`data[i * n + j] = F_ij`). Each unordered pair is
    /// integrated once, in parallel; F_ji follows by reciprocity (eq. 14). The result does not
    /// depend on the thread count (every entry is computed by the same sequential code).
    pub fn dense(&self) -> DenseFormFactors {
        self.dense_with_progress(&|_| {})
    }

    /// [`FormFactors::dense`], calling `progress(rows_done)` as rows finish (from any thread).
    pub fn dense_with_progress(&self, progress: &(dyn Fn(u64) + Sync)) -> DenseFormFactors {
        let n = self.len();
        let mut data = vec![0.0f64; n * n];
        // Upper triangle: G_ij = A_i F_ij for j > i, each row by one task; counters are sums
        // of integers, so their totals do not depend on the order rows finish in.
        let stats = Mutex::new(Stats::default());
        data.par_chunks_mut(n.max(1))
            .enumerate()
            .for_each(|(i, row)| {
                let mut local = Stats::default();
                for (j, g) in row.iter_mut().enumerate().skip(i + 1) {
                    let pair = self.area_weighted(i, j);
                    *g = pair.value;
                    local.count(&pair);
                }
                if let Ok(mut total) = stats.lock() {
                    total.merge(&local);
                }
                progress(1);
            });
        // Reciprocity: F_ij = G_ij / A_i and F_ji = G_ij / A_j.
        let areas: Vec<f64> = self.mesh.elements.iter().map(|e| e.area).collect();
        for i in 0..n {
            for j in i + 1..n {
                let g = data[i * n + j];
                data[i * n + j] = g / areas[i];
                data[j * n + i] = g / areas[j];
            }
        }
        let stats = stats.into_inner().unwrap_or_default();
        DenseFormFactors { n, data, stats }
    }
}

impl Stats {
    fn count(&mut self, pair: &PairResult) {
        self.pairs += 1;
        self.evaluations += pair.evaluations;
        match pair.method {
            Some(Method::Contour) => self.pairs_by_method.contour += 1,
            Some(Method::PointPolygon) => self.pairs_by_method.point_polygon += 1,
            Some(Method::PointPoint) => self.pairs_by_method.point_point += 1,
            None => {}
        }
        if pair.kind != PairKind::Culled {
            self.visibility.add(&pair.visibility);
        }
        match pair.kind {
            PairKind::Culled => {}
            PairKind::Facing => self.pairs_integrated += 1,
            PairKind::Clipped => {
                self.pairs_integrated += 1;
                self.pairs_clipped += 1;
            }
        }
    }

    fn merge(&mut self, other: &Stats) {
        self.pairs += other.pairs;
        self.pairs_integrated += other.pairs_integrated;
        self.pairs_clipped += other.pairs_clipped;
        self.evaluations += other.evaluations;
        self.pairs_by_method.contour += other.pairs_by_method.contour;
        self.pairs_by_method.point_polygon += other.pairs_by_method.point_polygon;
        self.pairs_by_method.point_point += other.pairs_by_method.point_point;
        self.visibility = self.visibility.merge(other.visibility);
    }
}

/// One pair's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairResult {
    /// `A_i F_ij` (visible part).
    pub value: f64,
    pub kind: PairKind,
    /// Kernel evaluations of the estimator.
    pub evaluations: u64,
    /// The estimator that computed the value (`None`: culled or fully hidden).
    pub method: Option<Method>,
    /// What the occlusion test decided ([`Visibility::UNOCCLUDED`] without occlusion).
    pub visibility: Visibility,
}

impl PairResult {
    const CULLED: PairResult = PairResult {
        value: 0.0,
        kind: PairKind::Culled,
        evaluations: 0,
        method: None,
        visibility: Visibility::UNOCCLUDED,
    };
}

/// A planar convex polygon ([`Convex`]: 3 or 4 corners, counter-clockwise about its unit
/// normal) with its area and area centroid: an element, or a node of a hierarchy over
/// elements. The unit of every pair function of this crate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Its corners (3 or 4; a triangle repeats its third corner) and unit normal; the surface
    /// derefs to it.
    pub shape: Convex,
    pub centroid: DVec3,
    pub area: f64,
}

impl std::ops::Deref for Surface {
    type Target = Convex;

    fn deref(&self) -> &Convex {
        &self.shape
    }
}

impl Surface {
    /// A surface from 3 or 4 corners (counter-clockwise about the unit `normal`): area and area
    /// centroid by a fan of triangles. `None` for another corner count or no area.
    pub fn new(corners: &[DVec3], normal: DVec3) -> Option<Surface> {
        let shape = Convex::new(corners, normal)?;
        let (c, sides) = (shape.corners, usize::from(shape.sides));
        let mut area = 0.0;
        let mut moment = DVec3::ZERO;
        for k in 1..sides - 1 {
            let t = (c[k] - c[0]).cross(c[k + 1] - c[0]).dot(normal) * 0.5;
            area += t;
            moment += (c[0] + c[k] + c[k + 1]) * (t / 3.0);
        }
        (area > 0.0 && area.is_finite()).then(|| Surface {
            shape,
            centroid: moment / area,
            area,
        })
    }

    /// Element `i` of `mesh` (its corners, normal, area and centroid as the mesher computed
    /// them).
    pub fn element(mesh: &ElementMesh, i: usize) -> Surface {
        let e = &mesh.elements[i];
        Surface {
            shape: mesh.convex(i),
            centroid: e.centroid,
            area: e.area,
        }
    }

    fn poly(&self) -> Poly {
        Poly::from_points(self.corners().iter().copied())
    }
}

/// One unoccluded surface pair, as [`surface_pair`] computes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePair {
    /// `A_a F_ab` (= `A_b F_ba`) without occlusion.
    pub value: f64,
    pub kind: PairKind,
    pub evaluations: u64,
    pub method: Method,
}

/// `A_a F_ab` of two surfaces by `estimator` (no occlusion); `None` when they cannot exchange light (parallel and facing the same way, or one
/// wholly behind or in the other's plane). Straddling surfaces are clipped to their front
/// parts, as for elements. Symmetric up to rounding: `surface_pair(b, a)` gives the same value.
pub fn surface_pair(
    a: &Surface,
    b: &Surface,
    options: &ContourOptions,
    estimator: Estimator,
) -> Option<SurfacePair> {
    let f = facing(a, b)?;
    let (value, evaluations, method) = estimate_pair(&f, [a.normal, b.normal], options, estimator);
    Some(SurfacePair {
        value,
        kind: f.kind,
        evaluations,
        method,
    })
}

/// Kernel evaluations of one pair at most ([`surface_pair`], [`FormFactors::area_weighted`],
/// [`polygon_pair_with`]), by any estimator with these contour options: a surface has at most
/// 4 corners and clipping it by the other's plane adds at most one (a plane cuts a convex
/// polygon's boundary at most twice and drops at least one corner), so at most 5 × 5 edge
/// pairs, each within [`max_edge_pair_evaluations`]. The point estimators use far fewer (at
/// most 7 points on each of 3 triangles times 5 edge terms).
pub fn max_pair_evaluations(options: &ContourOptions) -> u64 {
    const MAX_CLIPPED_SIDES: u64 = 5;
    MAX_CLIPPED_SIDES * MAX_CLIPPED_SIDES * max_edge_pair_evaluations(options)
}

/// What [`surface_screen`] finds out about a pair without integrating it.
#[derive(Clone, Copy, Debug)]
pub struct PairScreen {
    pub kind: PairKind,
    /// `A_a F_ab` (unoccluded) by a point rule: the mean of the point-to-surface kernel over
    /// the sample points of the smaller surface (its centre alone if that side is not fitted),
    /// times its area. Good to about the kernel's spread (relative); for deciding, not for
    /// keeping.
    pub rough: f64,
    /// Per side (`a`, then `b`): the kernel towards the other side sampled at points of the
    /// side (its centroid, the midpoints towards its corners, points 95 % of the way to them).
    pub sides: [SideScreen; 2],
    /// The pair clipped in its own frame, for [`screened_pair`] to integrate without
    /// clipping again.
    facing: Facing,
}

/// One side of a [`PairScreen`]: how the kernel `F_{dx→other}` varies over it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SideScreen {
    /// `(max − min) / mean` of the kernel over the side's points: 0 when the kernel is constant
    /// over it (a distant pair), about 1 or more when the side sees the other very differently
    /// from place to place (a corner).
    pub spread: f64,
    /// `(max − min) / mean` of what the least-squares plane through those values leaves over:
    /// how far a linear model of the side's irradiance from the other side is off.
    pub residual: f64,
    /// That plane's gradient, `∇F_{dx→other}` in world units (per length), lying in the
    /// side's plane; zero for a clipped pair (the fit covers only the front part).
    pub gradient: DVec3,
}

/// The cheap half of [`surface_pair`]: clipping, how the kernel varies over each side and a
/// rough value, for deciding whether a pair is worth integrating at all (a hierarchy refines
/// most pairs it looks at). `fit[k]`: whether side k's variation is wanted (else only its
/// centre is sampled and its [`SideScreen`] is zero). `None` exactly when [`surface_pair`] is
/// `None`.
pub fn surface_screen(a: &Surface, b: &Surface, fit: [bool; 2]) -> Option<PairScreen> {
    let f = facing(a, b)?;
    let fa = estimate::side_fit(&f.a, a.normal, &f.b, fit[0]);
    let fb = estimate::side_fit(&f.b, b.normal, &f.a, fit[1]);
    // A_a mean_x F_{dx→b} and A_b mean_y F_{dy→a} estimate the same G; the smaller surface's
    // points sample its kernel better.
    let rough = if a.area <= b.area {
        a.area * fa.mean
    } else {
        b.area * fb.mean
    };
    // The fit ran in the pair's frame (world / unit): per world length, ∇ scales by 1/unit.
    let side = |s: estimate::SideFit| SideScreen {
        spread: s.spread,
        residual: s.residual,
        gradient: if f.kind == PairKind::Clipped {
            DVec3::ZERO
        } else {
            s.gradient / f.unit
        },
    };
    Some(PairScreen {
        kind: f.kind,
        rough,
        sides: [side(fa), side(fb)],
        facing: f,
    })
}

/// [`surface_pair`] of the pair that `screen` ([`surface_screen`] of the same `a`, `b`)
/// looked at, reusing its clipping: the same value, bit for bit.
pub fn screened_pair(
    screen: &PairScreen,
    a: &Surface,
    b: &Surface,
    options: &ContourOptions,
    estimator: Estimator,
) -> SurfacePair {
    let f = &screen.facing;
    let (value, evaluations, method) = estimate_pair(f, [a.normal, b.normal], options, estimator);
    SurfacePair {
        value,
        kind: f.kind,
        evaluations,
        method,
    }
}

/// The pair in its own frame, each surface clipped to the part in front of the other's
/// plane; `None` when they cannot exchange light (back-facing, coplanar, parallel same-facing).
fn facing(sa: &Surface, sb: &Surface) -> Option<Facing> {
    let (ni, nj) = (sa.normal, sb.normal);
    // Parallel planes facing the same way never see each other: each lies behind or in the
    // other's plane. Deciding it from the normals makes coplanar neighbours exactly 0 even
    // where their vertices are only known to the rounding of large world coordinates
    // (a scene far from the origin), which the clip tolerance below cannot resolve.
    if ni.dot(nj) >= 1.0 - PARALLEL {
        return None;
    }
    let (mut a, mut b) = (sa.poly(), sb.poly());
    // Work relative to the pair's own frame: origin between the centroids, unit = their
    // distance. ln r then stays near 0 and the result is independent of where the scene
    // sits and of its scale (the contour integral of a constant vanishes on closed loops).
    let (ci, cj) = (sa.centroid, sb.centroid);
    let origin = (ci + cj) * 0.5;
    let unit = ci.distance(cj).max(a.extent().max(b.extent()) * 1e-3);
    a.move_to_frame(origin, unit);
    b.move_to_frame(origin, unit);
    // Clip each surface to the half-space in front of the other (eq. 13 assumes both
    // surfaces see each other wholly), each by the other's unclipped plane point. Tolerance
    // relative to the pair's size.
    let tol = 1e-11 * (a.extent().max(b.extent())).max(1.0);
    let (a0, b0) = (a.vertex(0), b.vertex(0));
    let clipped_i = a.clip_front(b0, nj, tol)?;
    let clipped_j = b.clip_front(a0, ni, tol)?;
    let kind = if clipped_i || clipped_j {
        PairKind::Clipped
    } else {
        PairKind::Facing
    };
    Some(Facing { a, b, unit, kind })
}

/// `A_i F_ij` of a facing pair by `estimator`, and its kernel evaluations.
fn estimate_pair(
    f: &Facing,
    normals: [DVec3; 2],
    options: &ContourOptions,
    estimator: Estimator,
) -> (f64, u64, Method) {
    if estimator == Estimator::Contour {
        let (v, e) = contour_with(f, options);
        return (v, e, Method::Contour);
    }
    let g = PairGeometry::new(&f.a, normals[0], &f.b, normals[1]);
    let choice = match estimator {
        Estimator::PointPolygon(rule) => Choice::PointPolygon(rule),
        Estimator::PointPoint => Choice::PointPoint,
        Estimator::Auto { tolerance } => estimate::choose(&g, [&f.a, &f.b], tolerance),
        Estimator::Contour => Choice::Exact,
    };
    if let Some(options) = choice.contour_options(*options) {
        let (v, e) = contour_with(f, &options);
        return (v, e, Method::Contour);
    }
    let mut evaluations = 0;
    let (v, method) = match choice {
        Choice::PointPolygon(rule) => (
            estimate::point_polygon(&g, [&f.a, &f.b], normals, rule, &mut evaluations),
            Method::PointPolygon,
        ),
        // Choice::PointPoint: every contour choice returned above.
        _ => (
            estimate::point_point(&g, normals[0], normals[1], &mut evaluations),
            Method::PointPoint,
        ),
    };
    (v * f.unit * f.unit, evaluations, method)
}

/// Eq. 13 over the (clipped) contours: `A_i F_ij` in world units, and kernel evaluations.
fn contour_with(f: &Facing, options: &ContourOptions) -> (f64, u64) {
    let mut evaluations = 0;
    let mut sum = 0.0;
    for a in 0..f.a.len() {
        let (p0, p1) = (f.a.vertex(a), f.a.vertex((a + 1) % f.a.len()));
        for b in 0..f.b.len() {
            let (q0, q1) = (f.b.vertex(b), f.b.vertex((b + 1) % f.b.len()));
            sum += contour::edge_pair(p0, p1, q0, q1, options, &mut evaluations);
        }
    }
    // Eq. 13 with both contours counter-clockwise about their own normals. Quadrature
    // noise can leave a tiny negative value for a pair that barely sees itself: F ≥ 0.
    let g = (sum / (2.0 * std::f64::consts::PI)).max(0.0) * f.unit * f.unit;
    (g, evaluations)
}

/// A facing pair in its own frame, clipped.
#[derive(Clone, Copy, Debug)]
struct Facing {
    a: Poly,
    b: Poly,
    unit: f64,
    kind: PairKind,
}

/// Occlusion for [`FormFactors::with_occlusion`]: the scene's occluders, the polygon pairs
/// that need rays at all (from [`Occluders::occludable_pairs`]), and the rays per pair.
#[derive(Clone, Copy)]
pub struct Occlusion<'a> {
    pub occluders: &'a Occluders,
    pub pairs: &'a OccludablePairs,
    pub samples: u32,
}

/// A dense form-factor matrix, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseFormFactors {
    pub n: usize,
    /// `data[i * n + j] = F_ij`.
    pub data: Vec<f64>,
    pub stats: Stats,
}

impl DenseFormFactors {
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.n + j]
    }

    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.n..(i + 1) * self.n]
    }

    /// Σ_j F_ij for every row (1 for an element inside a closed enclosure, eq. 15).
    pub fn row_sums(&self) -> Vec<f64> {
        (0..self.n).map(|i| self.row(i).iter().sum()).collect()
    }

    /// Scales down every row that sums past 1 so that it sums to 1, keeping reciprocity;
    /// reports the rows that were past `1 + margin` (a margin above what integration and
    /// visibility sampling can explain).
    ///
    /// No element can send more than all its light (eq. 15: Σ_j F_ij ≤ 1), but real geometry
    /// can make the integrated rows sum past 1: coincident faces facing the same way are both
    /// seen in full (neither hides the other), and faces inside or through other solids see
    /// surfaces twice. Such rows create light, and with ρ near 1 the system `(I − ρF) b = e`
    /// has no meaningful answer. With `s_i = 1 / Σ_j F_ij` on rows past 1 and 1 elsewhere,
    /// `F'_ij = F_ij · min(s_i, s_j)` keeps `A_i F'_ij = A_j F'_ji` (eq. 14; `min` is
    /// symmetric) and bounds every row: `Σ_j F'_ij ≤ s_i Σ_j F_ij`, which is 1 on a scaled row
    /// and the unchanged sum (≤ 1) on any other. Rows of a closed enclosure that integration
    /// put a rounding above 1 move by that rounding; every element's escape `1 − Σ_j F_ij`
    /// is then ≥ 0.
    pub fn limit_row_sums(&mut self, margin: f64) -> RowSumLimit {
        self.limit_row_sums_stopped(margin, &[])
    }

    /// [`DenseFormFactors::limit_row_sums`] where element j stops only `stopped[j]` of the
    /// light that reaches it (1 − its transmission: glass passes the rest on, and what lies
    /// behind it is seen too): the bounded sum is `Σ_j F_ij stopped_j`, which is ≤ 1 for any
    /// ray's chain of panes ((1 − t₁) + t₁ (1 − t₂) + … + t₁ t₂ … = 1). Empty `stopped`: 1
    /// for every element (missing entries are 1).
    pub fn limit_row_sums_stopped(&mut self, margin: f64, stopped: &[f64]) -> RowSumLimit {
        let n = self.n;
        let sums: Vec<f64> = self
            .data
            .par_chunks(n.max(1))
            .map(|row| {
                if stopped.is_empty() {
                    row.iter().sum()
                } else {
                    row.iter()
                        .enumerate()
                        .map(|(j, f)| f * stopped.get(j).copied().unwrap_or(1.0))
                        .sum()
                }
            })
            .collect();
        let limit = 1.0 + margin.max(0.0);
        let beyond_margin: Vec<(usize, f64)> = sums
            .iter()
            .enumerate()
            .filter(|(_, &s)| s > limit)
            .map(|(i, &s)| (i, s))
            .collect();
        let scaled = sums.iter().filter(|&&s| s > 1.0).count();
        let largest = sums.iter().copied().fold(0.0f64, f64::max);
        let mut largest_after = largest;
        if scaled > 0 {
            let scale: Vec<f64> = sums
                .iter()
                .map(|&s| if s > 1.0 { 1.0 / s } else { 1.0 })
                .collect();
            self.data
                .par_chunks_mut(n)
                .zip(&scale)
                .for_each(|(row, &si)| {
                    for (f, &sj) in row.iter_mut().zip(&scale) {
                        *f *= si.min(sj);
                    }
                });
            largest_after = self
                .data
                .par_chunks(n)
                .map(|row| {
                    row.iter()
                        .enumerate()
                        .map(|(j, f)| f * stopped.get(j).copied().unwrap_or(1.0))
                        .sum::<f64>()
                })
                .reduce(|| 0.0, f64::max);
        }
        RowSumLimit {
            scaled,
            largest,
            largest_after,
            beyond_margin,
        }
    }
}

/// What [`DenseFormFactors::limit_row_sums`] changed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RowSumLimit {
    /// Rows that summed past 1 and were scaled to 1.
    pub scaled: usize,
    /// The largest row sum before scaling.
    pub largest: f64,
    /// The largest row sum after (≤ 1 up to rounding).
    pub largest_after: f64,
    /// Of those, the rows past 1 + the margin (row, sum before scaling), in row order:
    /// geometry that sees surfaces twice, not integration or sampling error.
    pub beyond_margin: Vec<(usize, f64)>,
}

/// Exact form factor between two convex planar polygons given as vertex lists
/// (counter-clockwise about their normals): for tests and tools that check the integrator
/// outside a mesh.
pub fn polygon_pair(a: &[DVec3], b: &[DVec3], options: &ContourOptions) -> f64 {
    let mesh = polygon::two_element_mesh(a, b);
    FormFactors::new(&mesh, *options).pair(0, 1)
}

/// [`polygon_pair`] by any [`Estimator`]: the pair's result (`value` = `A_a F_ab`), with the
/// estimator it used and its kernel evaluations.
pub fn polygon_pair_with(
    a: &[DVec3],
    b: &[DVec3],
    options: &ContourOptions,
    estimator: Estimator,
) -> PairResult {
    let mesh = polygon::two_element_mesh(a, b);
    FormFactors::new(&mesh, *options)
        .with_estimator(estimator)
        .area_weighted(0, 1)
}

/// Bound on `|Σ_j F_ij − 1|` for an element inside a closed enclosure, with the default
/// [`ContourOptions`]: measured ≤ 4e-15 on the test scenes (the cube at subdivisions 1–8,
/// random sheared boxes, a furnace box with unequal elements) and stated with a wide margin,
/// since 1:10⁴ strips and grazing pairs carry up to ~1e-7 relative error on their own (tiny)
/// values. The solver uses it to refuse
/// systems whose answer an error this size could change entirely (e.g. ρ = 1 everywhere).
pub const ROW_SUM_ACCURACY: f64 = 1e-9;
