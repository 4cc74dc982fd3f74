//! The edge-pair integrals of the contour form of the form factor (Goral et al. 1984, eq. 13):
//!
//! ```text
//!   A_i F_ij = 1/(2π) ∮_{C_i} ∮_{C_j} ln r (dx_i dx_j + dy_i dy_j + dz_i dz_j)
//! ```
//!
//! For two straight edges P (a→b, unit direction u) and Q (c→d, unit direction w) the integrand
//! is `(u·w) ln r ds dt`, so one edge pair contributes `(u·w) ∫_P ∫_Q ln r ds dt`. Three ways to
//! integrate it, chosen per segment pair:
//! - **collinear** segments: exactly, by the closed form of ∫∫ ln|s − t| (the paper: "when
//!   segments lie on the same line, the integral is evaluated analytically");
//! - **well-separated** segments (distance ≥ `near_ratio` × the longer one): the paper's
//!   product Gauss–Legendre rule, `order` points per segment (3 × 3 = the paper's nine points),
//!   raised for pairs closer than 64 segment lengths until the rule's error is at the rounding
//!   level (`auto_order`; see `far_order`);
//! - **near or touching** segments, where ln r is (nearly) singular: the inner integral over Q
//!   in closed form and the outer one by adaptive Gauss–Legendre (bisection until two levels
//!   agree to 1e-14 of the pair's size, or to the rounding noise of the closed form), so an
//!   r → 0 at a shared vertex is integrated to machine precision instead of converging slowly
//!   under uniform segments.
//!
//! Every loop has a bound on its work, whatever the geometry: an edge pair is `segments²`
//! segment pairs (the caller's choice); a segment pair costs one evaluation (collinear),
//! `order²` ≤ 64 (product rule) or at most [`MAX_SEGMENT_PAIR_EVALUATIONS`] (the adaptive
//! rule's budget of [`MAX_PIECES`] pieces); so [`max_edge_pair_evaluations`].

use glam::DVec3;

/// Quadrature settings of the contour integral.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContourOptions {
    /// Each edge is cut into this many equal segments (the paper's discretisation).
    pub segments: u32,
    /// Gauss–Legendre points per segment for well-separated segment pairs (3: the paper's
    /// rule); with `auto_order`, the least order used.
    pub order: u32,
    /// A segment pair closer than `near_ratio` × its longer segment is integrated
    /// semi-analytically (closed-form inner integral, adaptive outer rule).
    pub near_ratio: f64,
    /// Raise the Gauss order of well-separated segment pairs closer than 64 segment lengths
    /// (5 below 16 lengths, 4 below 64) so that each is integrated to the rounding level.
    /// Off: `order` as given, the paper's fixed rule, whose error at 8 lengths is ~2.5e-10 of
    /// the segments' lengths product: enough for ordinary pairs, not for rows summing to 1
    /// within 1e-11 (the cube's were off by 1.5e-10) or for grazing pairs whose A_i F_ij is
    /// smaller than that error (off by 0.5% at F = 3e-9).
    pub auto_order: bool,
}

impl Default for ContourOptions {
    fn default() -> Self {
        ContourOptions {
            segments: 1,
            order: 3,
            near_ratio: 8.0,
            auto_order: true,
        }
    }
}

/// Gauss–Legendre nodes and weights on [-1, 1] (Abramowitz & Stegun 25.4.29), orders 1–8.
#[allow(clippy::excessive_precision)] // the table as published
fn gauss(order: u32) -> &'static [(f64, f64)] {
    const G1: [(f64, f64); 1] = [(0.0, 2.0)];
    const G2: [(f64, f64); 2] = [
        (-0.577_350_269_189_625_8, 1.0),
        (0.577_350_269_189_625_8, 1.0),
    ];
    const G3: [(f64, f64); 3] = [
        (-0.774_596_669_241_483_4, 0.555_555_555_555_555_6),
        (0.0, 0.888_888_888_888_888_9),
        (0.774_596_669_241_483_4, 0.555_555_555_555_555_6),
    ];
    const G4: [(f64, f64); 4] = [
        (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
        (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
        (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
        (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    ];
    const G5: [(f64, f64); 5] = [
        (-0.906_179_845_938_664_0, 0.236_926_885_056_189_1),
        (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (0.0, 0.568_888_888_888_888_9),
        (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (0.906_179_845_938_664_0, 0.236_926_885_056_189_1),
    ];
    const G6: [(f64, f64); 6] = [
        (-0.932_469_514_203_152_0, 0.171_324_492_379_170_3),
        (-0.661_209_386_466_264_5, 0.360_761_573_048_138_6),
        (-0.238_619_186_083_196_9, 0.467_913_934_572_691_0),
        (0.238_619_186_083_196_9, 0.467_913_934_572_691_0),
        (0.661_209_386_466_264_5, 0.360_761_573_048_138_6),
        (0.932_469_514_203_152_0, 0.171_324_492_379_170_3),
    ];
    const G7: [(f64, f64); 7] = [
        (-0.949_107_912_342_758_5, 0.129_484_966_168_869_7),
        (-0.741_531_185_599_394_4, 0.279_705_391_489_276_7),
        (-0.405_845_151_377_397_2, 0.381_830_050_505_118_9),
        (0.0, 0.417_959_183_673_469_4),
        (0.405_845_151_377_397_2, 0.381_830_050_505_118_9),
        (0.741_531_185_599_394_4, 0.279_705_391_489_276_7),
        (0.949_107_912_342_758_5, 0.129_484_966_168_869_7),
    ];
    const G8: [(f64, f64); 8] = [
        (-0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
        (-0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
        (-0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (-0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
        (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
    ];
    match order {
        0 | 1 => &G1,
        2 => &G2,
        3 => &G3,
        4 => &G4,
        5 => &G5,
        6 => &G6,
        7 => &G7,
        _ => &G8,
    }
}

/// Highest supported Gauss order.
pub const MAX_ORDER: u32 = 8;

/// Kernel evaluations of one [`edge_pair`] at most with `opts`: `segments²` segment pairs, each
/// at most the adaptive rule's budget (which exceeds the product rule's `MAX_ORDER²` and the
/// collinear closed form's one).
pub fn max_edge_pair_evaluations(opts: &ContourOptions) -> u64 {
    let n = u64::from(opts.segments.max(1));
    n * n * MAX_SEGMENT_PAIR_EVALUATIONS.max(u64::from(MAX_ORDER * MAX_ORDER))
}

/// `(u·w) ∫_P ∫_Q ln r ds dt` for the edges P = a→b and Q = c→d.
/// `evaluations` counts kernel evaluations (for the accuracy–cost report).
pub fn edge_pair(
    a: DVec3,
    b: DVec3,
    c: DVec3,
    d: DVec3,
    opts: &ContourOptions,
    evaluations: &mut u64,
) -> f64 {
    let (p, q) = (b - a, d - c);
    let (lp, lq) = (p.length(), q.length());
    if lp == 0.0 || lq == 0.0 {
        return 0.0;
    }
    let (u, w) = (p / lp, q / lq);
    let cos = u.dot(w);
    // Perpendicular edges contribute nothing: dx_i · dx_j = 0.
    if cos.abs() < 1e-14 {
        return 0.0;
    }
    let scale = lp.max(lq);
    // Collinearity is decided on the longer segment's line: a short segment's direction is
    // known only to ε × its coordinates / its length, and the other's far end is off that line
    // by that times the longer length (a 1:10⁵ pair sharing an end on the planes' intersection
    // line was collinear one way round and not the other). Deciding it the same way for
    // (P, Q) and (Q, P) keeps each edge pair symmetric.
    let (line, dir, other) = if lp >= lq {
        ((a, b), u, (c, d))
    } else {
        ((c, d), w, (a, b))
    };
    if is_collinear(line.0, dir, other.0, other.1, scale) {
        *evaluations += 1;
        return cos * collinear(line, dir, other);
    }
    // n² segment pairs (the caller's discretisation), each within the larger of the product
    // rule's order² ≤ MAX_ORDER² and the adaptive rule's budget: max_edge_pair_evaluations.
    let n = opts.segments.max(1);
    let mut sum = 0.0;
    for k in 0..n {
        let (s0, s1) = (
            a + p * (k as f64 / n as f64),
            a + p * ((k + 1) as f64 / n as f64),
        );
        for m in 0..n {
            let (t0, t1) = (
                c + q * (m as f64 / n as f64),
                c + q * ((m + 1) as f64 / n as f64),
            );
            let longer = (lp.max(lq)) / n as f64;
            // The paper's fixed rule (no near pairs, no order raise) needs no distance.
            let gap = if opts.near_ratio > 0.0 || opts.auto_order {
                segment_distance(s0, s1, t0, t1)
            } else {
                f64::INFINITY
            };
            sum += if gap >= opts.near_ratio * longer {
                let order = if opts.auto_order {
                    opts.order.max(far_order(gap / longer))
                } else {
                    opts.order
                };
                product_gauss(s0, s1, t0, t1, order, evaluations)
            } else {
                semi_analytic(s0, s1, t0, t1, evaluations)
            };
        }
    }
    cos * sum
}

/// Gauss order at which the product rule's error on a segment pair whose gap is `ratio` × its
/// longer segment L stays at the rounding level, ≲ 2e-15 L² (the integrand ln r is analytic in
/// an ellipse around each segment whose size grows with the ratio, so the error falls like
/// (4 ratio)^(−2 order)). Measured worst errors over orientations, in units of L²:
///
/// | ratio | order 3 | order 4 | order 5 | order 6 |
/// |------:|--------:|--------:|--------:|--------:|
/// |     4 |  8.7e-9 | 1.9e-11 | 2.1e-14 | 1.3e-15 |
/// |     8 | 2.5e-10 | 1.3e-13 | 8.9e-16 |         |
/// |    16 | 5.3e-12 | 1.8e-15 |         |         |
/// |    32 | 9.6e-14 |         |         |         |
/// |    64 | 2.7e-15 |         |         |         |
fn far_order(ratio: f64) -> u32 {
    if ratio >= 64.0 {
        3
    } else if ratio >= 16.0 {
        4
    } else if ratio >= 6.0 {
        5
    } else if ratio >= 4.0 {
        6
    } else {
        MAX_ORDER
    }
}

/// Both endpoints of Q lie on the line through `a` with direction `u` (relative tolerance).
fn is_collinear(a: DVec3, u: DVec3, c: DVec3, d: DVec3, scale: f64) -> bool {
    let off = |x: DVec3| {
        let r = x - a;
        (r - u * r.dot(u)).length()
    };
    let tol = 1e-12 * scale.max((c - a).length());
    off(c) <= tol && off(d) <= tol
}

/// Second antiderivative of ln|x|: G(x) = x² ln|x| / 2 − 3x²/4, G(0) = 0.
fn g2(x: f64) -> f64 {
    if x == 0.0 {
        0.0
    } else {
        let x2 = x * x;
        0.5 * x2 * x.abs().ln() - 0.75 * x2
    }
}

/// `G(x) − G(z)` for `x − z = h` (given exactly): the sum of the two without cancelling them
/// where x and z are close (a short segment beside the end of a long one, where each G is
/// ~ε × x² off and the difference only ~h x ln x). G is even, so for x, z of one sign it is
/// `G(|x|) − G(|z|) = ½ [(p² − q²) ln p + q² ln(p/q)] − ¾ (p² − q²)`, p = |x|, q = |z|,
/// with p² − q² = (p − q)(p + q) and ln(p/q) = ln_1p((p − q)/q), p − q = ±h.
fn g2_diff(x: f64, z: f64, h: f64) -> f64 {
    if x == 0.0 || z == 0.0 || (x > 0.0) != (z > 0.0) {
        // An end at 0 or the two on either side of it: nothing large cancels.
        return g2(x) - g2(z);
    }
    let (p, q) = (x.abs(), z.abs());
    let diff = if x > 0.0 { h } else { -h };
    let sum = p + q;
    // ln(p/q) by ln_1p where p and q are close (its point); elsewhere the two logs do not
    // cancel, and x, z, h measured apart need not give diff / q > −1 exactly (one end a
    // rounding away from the other's end: ln_1p(−1) = −∞).
    let ln_ratio = if diff.abs() <= 0.5 * q {
        (diff / q).ln_1p()
    } else {
        p.ln() - q.ln()
    };
    0.5 * (diff * sum * p.ln() + q * q * ln_ratio) - 0.75 * diff * sum
}

/// `∫_P ∫_Q ln|s − t| ds dt` for collinear segments P = a→b (unit direction u) and Q = c→d
/// on its line. Exact: with Q running from y0 to y1 along u, ∫_Q ln|s−y| dy = F1(s−y0) −
/// F1(s−y1), F1' = ln|x|, and over s ∈ P the second difference of G = ∫F1 at the four gaps
/// between the ends. Each gap is measured from the points themselves (accurate to ε of itself,
/// where a coordinate along P was only accurate to ε of P's length), and the four terms are
/// paired into first differences over the shorter segment (`g2_diff`), so nothing large
/// cancels when one segment is far shorter than the other.
fn collinear((a, b): (DVec3, DVec3), u: DVec3, (c, d): (DVec3, DVec3)) -> f64 {
    let (y0, y1) = if (d - c).dot(u) >= 0.0 {
        (c, d)
    } else {
        (d, c)
    };
    let (hq, hp) = ((y1 - y0).dot(u), (b - a).dot(u));
    let gap = |p: DVec3, y: DVec3| (p - y).dot(u);
    if hq <= hp {
        g2_diff(gap(b, y0), gap(b, y1), hq) - g2_diff(gap(a, y0), gap(a, y1), hq)
    } else {
        g2_diff(gap(b, y0), gap(a, y0), hp) - g2_diff(gap(b, y1), gap(a, y1), hp)
    }
}

/// Product Gauss–Legendre rule (the paper's nine-point rule for order 3): order² evaluations,
/// at most MAX_ORDER² = 64 (`gauss` caps the order).
fn product_gauss(
    s0: DVec3,
    s1: DVec3,
    t0: DVec3,
    t1: DVec3,
    order: u32,
    evaluations: &mut u64,
) -> f64 {
    let rule = gauss(order);
    let (sm, sh) = ((s0 + s1) * 0.5, (s1 - s0) * 0.5);
    let (tm, th) = ((t0 + t1) * 0.5, (t1 - t0) * 0.5);
    let mut sum = 0.0;
    for &(xi, wi) in rule {
        let x = sm + sh * xi;
        let mut inner = 0.0;
        for &(xj, wj) in rule {
            // ln r = ½ ln r²: one log, no square root.
            inner += wj * (x - (tm + th * xj)).length_squared().ln();
        }
        sum += wi * inner;
    }
    *evaluations += (rule.len() * rule.len()) as u64;
    0.5 * sum * sh.length() * th.length()
}

/// `∫_0^{L} ln|x − (c + t w)| dt` in closed form (w unit, L = |Q|):
/// with t0 the projection of x on Q's line and h the distance to it,
/// ∫ ln √((t−t0)² + h²) dt = ½ [X ln(X² + h²) − 2X + 2h atan(X/h)], X = t − t0.
/// Also returns the magnitude of the terms that cancel in it (its rounding scale): far from a
/// short Q the two ends nearly cancel, and the result is only known to ~ε × that.
fn point_segment_log(x: DVec3, c: DVec3, w: DVec3, len: f64) -> (f64, f64) {
    let r = x - c;
    let t0 = r.dot(w);
    let h = (r - w * t0).length();
    let f = |big_x: f64| {
        let r2 = big_x * big_x + h * h;
        let log_term = if r2 > 0.0 { big_x * r2.ln() } else { 0.0 };
        let atan_term = if h > 0.0 {
            2.0 * h * (big_x / h).atan()
        } else {
            0.0
        };
        (
            log_term - 2.0 * big_x + atan_term,
            log_term.abs() + 2.0 * big_x.abs() + atan_term.abs(),
        )
    };
    let ((hi, hi_mag), (lo, lo_mag)) = (f(len - t0), f(-t0));
    (0.5 * (hi - lo), 0.5 * (hi_mag + lo_mag))
}

/// Outer integral over the shorter segment by adaptive Gauss–Legendre (bisection until two
/// levels agree to the tolerance or to their rounding noise, whichever is larger), inner
/// integral over the longer one in closed form. The outer integrand is bounded and continuous
/// even where r → 0 (it behaves like s ln s there), so bisection converges; the pieces start
/// at its near-singular spots (Q's endpoints seen from P, the closest approach: see
/// [`Outer::breaks`]), and bisection closes in on them from there.
///
/// The work is bounded: at most [`MAX_PIECES`] pieces, so at most
/// [`MAX_SEGMENT_PAIR_EVALUATIONS`] kernel evaluations, whatever the geometry.
fn semi_analytic(s0: DVec3, s1: DVec3, t0: DVec3, t1: DVec3, evaluations: &mut u64) -> f64 {
    // ∫_P ∫_Q ln r is symmetric in P and Q. Seen from the shorter segment, the closed form over
    // the longer one keeps its digits; the other way round its two ends cancel (a short Q seen
    // from along a long P: up to 3e-11 of lp lq lost at lengths 1:10⁶ against a 40-digit
    // reference, 4e-15 this way round).
    let (s0, s1, t0, t1) = if (s1 - s0).length_squared() > (t1 - t0).length_squared() {
        (t0, t1, s0, s1)
    } else {
        (s0, s1, t0, t1)
    };
    // A local frame: origin at s0, unit the longer length. The evaluation points and their
    // offsets from Q are then rounded to ε × the segment pair's own size, not × its distance
    // from the pair frame's origin, and ln r' = O(1), so that the rounding noise and the
    // tolerance compare as they do for any segment pair of unit size (issue 14: clipped
    // slivers 1.6e-7 across, 0.05 from the origin; every evaluation was off by ~3e5 × the
    // rounding noise the bisection allowed for, no piece was ever accepted and it bisected to
    // the depth limit everywhere, 2⁶⁰ pieces). With r = L r', ∫∫ ln r ds dt =
    // L² (∫∫ ln r' ds' dt' + lp' lq' ln L).
    let unit = (t1 - t0).length();
    let p = (s1 - s0) / unit;
    let lp = p.length();
    let c = (t0 - s0) / unit;
    let q = (t1 - t0) / unit;
    let lq = q.length();
    let outer = Outer {
        u: p / lp,
        c,
        w: q / lq,
        lq,
        rule: gauss(ADAPTIVE_ORDER),
    };
    // Absolute tolerance relative to the size of the pair, lp lq (lp ≤ lq after the swap).
    let integral = outer.integrate(lp, ADAPTIVE_TOLERANCE * lp * lq, evaluations);
    unit * unit * (integral + lp * lq * unit.ln())
}

/// Gauss order of the adaptive outer rule.
const ADAPTIVE_ORDER: u32 = 8;
/// Relative tolerance of the adaptive outer rule (over lp lq); halved with each bisection.
const ADAPTIVE_TOLERANCE: f64 = 1e-14;
/// A piece this deep is not bisected again: 2⁻⁵⁰ of the outer segment is 4 ε of it, where the
/// Gauss nodes of a piece stop being distinct parameters.
const MAX_DEPTH: u32 = 50;
/// Budget of the adaptive outer rule: pieces of the outer segment (each bisection adds one).
///
/// Why it suffices: a piece needs bisecting only next to a spot where the integrand is
/// (nearly) singular, one piece per bisection level on each side of the spot (the far half of a
/// bisected piece there is smooth and accepted at once); a segment pair has at most three such
/// spots (see [`Outer::breaks`]), each refined to at most ~35 levels (an `s ln s` end against
/// the tolerance halving per level): ~210 pieces at worst. Measured: at most 68 pieces over
/// 160 000 random touching, T-junction, near-crossing, 1:10⁶ and sliver segment pairs (and the
/// unit test `adaptive_rule_stays_far_below_its_budget`).
///
/// Why it is needed: the stop at the rounding noise (see [`ROUNDING_ULPS`]) relies on a model
/// of that noise, and where the model is short (as it was for issue 14's slivers) pieces stay
/// above their tolerance at every depth and the depth limit alone allowed 2⁵⁰ of them. The
/// piece with the largest error is bisected first, so if the budget runs out it has gone
/// where the error was.
pub const MAX_PIECES: usize = 256;
/// Near-singular spots of a segment pair at most (see [`Outer::breaks`]).
const SPOTS: usize = 3;
/// Breaks closer than this × the outer segment to an end or to each other are dropped: the
/// bisection closes in on such a spot from the end within ~30 levels.
const MIN_BREAK: f64 = 1e-9;
/// Kernel evaluations of one semi-analytic segment pair at most: three rules (the whole and
/// two halves) per starting piece, two pieces' two halves per bisection, at most
/// [`MAX_PIECES`] pieces: 24 k + 32 (MAX_PIECES − k) for k ≥ 1 starting pieces.
pub const MAX_SEGMENT_PAIR_EVALUATIONS: u64 =
    (ADAPTIVE_ORDER as u64) * (3 + 4 * (MAX_PIECES as u64 - 1));
/// Two levels that agree to this many ε of the magnitude of the cancelling terms agree to
/// rounding, and bisecting further cannot improve them. Where that noise exceeds the tolerance
/// (far from a short Q, |ln r| large) it does so at every level, both halving with the
/// interval: without this stop the bisection went on to the depth limit everywhere. The model
/// assumes x − c is rounded to ε of the segment pair's size, which the local frame of
/// [`semi_analytic`] makes true (in units of the longer segment |x| ≤ 1 and |c| ≤ 1 + the gap,
/// below `near_ratio` + 1 for a near pair): in the pair frame it was not (issue 14), and the
/// budget ([`MAX_PIECES`]) bounds the work wherever it is not.
const ROUNDING_ULPS: f64 = 16.0;

struct Outer {
    /// The outer segment is `u s`, s ∈ [0, lp] (the local frame: origin at its start, unit the
    /// inner segment's length).
    u: DVec3,
    /// Start, direction and length of the inner segment, relative to the same origin.
    c: DVec3,
    w: DVec3,
    lq: f64,
    rule: &'static [(f64, f64)],
}

/// One piece [from, to] of the outer segment, integrated by the rule on both halves.
#[derive(Clone, Copy, Debug, Default)]
struct Piece {
    from: f64,
    to: f64,
    left: f64,
    right: f64,
    /// |left + right − the rule on the whole piece|: the coarser level's error estimate.
    error: f64,
    /// The larger of the piece's tolerance and the rounding noise of left + right.
    allowed: f64,
    depth: u32,
}

impl Piece {
    /// Accepted: its two levels agree to its tolerance or to rounding, or it is at the depth
    /// limit.
    fn accepted(&self) -> bool {
        self.error <= self.allowed || self.depth >= MAX_DEPTH
    }
}

impl Outer {
    /// The Gauss rule on [from, to] and its rounding scale.
    fn gauss(&self, from: f64, to: f64, evaluations: &mut u64) -> (f64, f64) {
        let (mid, half) = ((from + to) * 0.5, (to - from) * 0.5);
        let (mut acc, mut scale) = (0.0, 0.0);
        for &(xi, wi) in self.rule {
            let (value, magnitude) =
                point_segment_log(self.u * (mid + half * xi), self.c, self.w, self.lq);
            acc += wi * value;
            scale += wi * magnitude;
        }
        *evaluations += self.rule.len() as u64;
        (acc * half, scale * half)
    }

    /// [from, to] at bisection depth `depth`, whose coarser value (the rule on the whole of
    /// it) is `whole`, with tolerance `tol`.
    fn piece(
        &self,
        (from, to): (f64, f64),
        whole: f64,
        tol: f64,
        depth: u32,
        evaluations: &mut u64,
    ) -> Piece {
        let mid = 0.5 * (from + to);
        let ((left, left_scale), (right, right_scale)) = (
            self.gauss(from, mid, evaluations),
            self.gauss(mid, to, evaluations),
        );
        let noise = ROUNDING_ULPS * f64::EPSILON * (left_scale + right_scale);
        Piece {
            from,
            to,
            left,
            right,
            error: (left + right - whole).abs(),
            allowed: tol.max(noise),
            depth,
        }
    }

    /// Where in (0, len) the integrand is nearly singular: the feet on P of Q's ends and of the
    /// lines' closest approach, each where it lies closer to P (or Q) than `len`, sorted,
    /// none within [`MIN_BREAK`] × len of an end or of another. Starting the bisection with
    /// pieces that end there puts every singular spot at a piece's end, where halving closes in
    /// on it; a spot inside a piece can fool the two-level error estimate (both levels off by
    /// the same amount: a near crossing at 1e-6 was accepted at once, 1e-12 of lp lq off).
    fn breaks(&self, len: f64) -> ([f64; SPOTS], usize) {
        let mut spots = [f64::NAN; SPOTS];
        let d = self.c + self.w * self.lq;
        for (spot, end) in spots.iter_mut().zip([self.c, d]) {
            let s = end.dot(self.u);
            if (end - self.u * s).length() < len {
                *spot = s;
            }
        }
        let uw = self.u.dot(self.w);
        let den = 1.0 - uw * uw;
        if den > 0.0 {
            let s = (self.c.dot(self.u) - uw * self.c.dot(self.w)) / den;
            let t = uw * s - self.c.dot(self.w);
            if (0.0..=self.lq).contains(&t) && (self.u * s - self.c - self.w * t).length() < len {
                spots[2] = s;
            }
        }
        // NaN (no spot) sorts last, and fails the range test below.
        spots.sort_by(f64::total_cmp);
        let margin = MIN_BREAK * len;
        let (mut breaks, mut count, mut last) = ([0.0; SPOTS], 0, 0.0);
        for s in spots {
            if s - last > margin && len - s > margin {
                breaks[count] = s;
                count += 1;
                last = s;
            }
        }
        (breaks, count)
    }

    /// `∫_0^{len}` of the inner closed form, from pieces that end at the [`Outer::breaks`]: a
    /// piece w wide is accepted when its two levels agree to `tol` × w / len (the tolerance
    /// halves with each bisection) or to rounding (which pieces are accepted does not depend on
    /// the order they are looked at in); the others are bisected, the one with the largest
    /// error first, until none is left or the budget of [`MAX_PIECES`] is spent.
    fn integrate(&self, len: f64, tol: f64, evaluations: &mut u64) -> f64 {
        let mut pieces = [Piece::default(); MAX_PIECES];
        let (breaks, inner) = self.breaks(len);
        let mut from = 0.0;
        for (k, &to) in breaks[..inner].iter().chain([&len]).enumerate() {
            let whole = self.gauss(from, to, evaluations).0;
            pieces[k] = self.piece((from, to), whole, tol * (to - from) / len, 0, evaluations);
            from = to;
        }
        let mut count = inner + 1;
        while count < MAX_PIECES {
            let mut worst = None::<(usize, f64)>;
            for (k, piece) in pieces[..count].iter().enumerate() {
                if !piece.accepted() && worst.is_none_or(|(_, e)| piece.error > e) {
                    worst = Some((k, piece.error));
                }
            }
            let Some((k, _)) = worst else { break };
            let p = pieces[k];
            let mid = 0.5 * (p.from + p.to);
            let (tol, depth) = (tol * (mid - p.from) / len, p.depth + 1);
            pieces[k] = self.piece((p.from, mid), p.left, tol, depth, evaluations);
            pieces[count] = self.piece((mid, p.to), p.right, tol, depth, evaluations);
            count += 1;
        }
        // In index order: the same sum for the same pair, whatever the thread.
        pieces[..count].iter().map(|p| p.left + p.right).sum()
    }
}

/// Parameter (0..1) on segment s0–s1 of its point closest to segment t0–t1, and the distance.
fn closest_on_first(s0: DVec3, s1: DVec3, t0: DVec3, t1: DVec3) -> (f64, f64) {
    let (d1, d2, r) = (s1 - s0, t1 - t0, s0 - t0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let (b, c) = (d1.dot(d2), d1.dot(r));
    let denom = a * e - b * b;
    // Closest points of two segments (Ericson, Real-Time Collision Detection, 5.1.9).
    let mut s = if denom > 1e-300 {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    let gap = ((s0 + d1 * s) - (t0 + d2 * t)).length();
    (s, gap)
}

fn segment_distance(s0: DVec3, s1: DVec3, t0: DVec3, t1: DVec3) -> f64 {
    closest_on_first(s0, s1, t0, t1).1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute-force ∫∫ ln r over two segments by many-point composite Gauss (for smooth cases).
    fn brute(a: DVec3, b: DVec3, c: DVec3, d: DVec3, n: u32) -> f64 {
        let mut e = 0;
        let mut sum = 0.0;
        for k in 0..n {
            for m in 0..n {
                let f = |x: DVec3, y: DVec3, k: u32| x + (y - x) * (k as f64 / n as f64);
                sum += product_gauss(
                    f(a, b, k),
                    f(a, b, k + 1),
                    f(c, d, m),
                    f(c, d, m + 1),
                    8,
                    &mut e,
                );
            }
        }
        sum
    }

    #[test]
    fn collinear_closed_form_matches_brute_force_on_separated_segments() {
        let (a, b) = (DVec3::ZERO, DVec3::X);
        let (c, d) = (DVec3::X * 1.5, DVec3::X * 3.0);
        let exact = collinear((a, b), DVec3::X, (c, d));
        assert!((exact - brute(a, b, c, d, 64)).abs() < 1e-12, "{exact}");
    }

    #[test]
    fn collinear_self_overlap_is_finite_and_exact() {
        // ∫_0^1∫_0^1 ln|s−t| ds dt = −3/2.
        let (a, b) = (DVec3::ZERO, DVec3::X);
        assert!((collinear((a, b), DVec3::X, (a, b)) + 1.5).abs() < 1e-15);
        assert!((collinear((a, b), DVec3::X, (b, a)) + 1.5).abs() < 1e-15);
    }

    #[test]
    fn collinear_closed_form_keeps_its_digits_beside_a_long_segment() {
        // P = [−1, 0], Q = [0, h] (exact coordinates): G(1 + h) − G(1) − G(h), 40-digit
        // references (mpmath). The four-term sum of G lost ε / h of it: 8e-11 at h = 1e-6.
        for (h, reference) in [
            (1e-6, -9.999_923_422_445_543e-7),
            (3e-5, -2.999_463_855_457_07e-5),
            (1e-9, -9.999_999_888_883_67e-10),
        ] {
            let (a, b, d) = (-DVec3::X, DVec3::ZERO, DVec3::X * h);
            for got in [
                collinear((a, b), DVec3::X, (b, d)),
                collinear((b, d), DVec3::X, (a, b)),
                collinear((d, b), -DVec3::X, (b, a)),
            ] {
                assert!(
                    ((got - reference) / reference).abs() < 1e-14,
                    "{h}: {got:e}"
                );
            }
        }
    }

    #[test]
    fn point_segment_log_matches_quadrature() {
        let (x, c, w) = (DVec3::new(0.3, 0.2, 0.1), DVec3::ZERO, DVec3::X);
        let mut brute = 0.0;
        let n = 2000;
        for k in 0..n {
            let t = (k as f64 + 0.5) / n as f64;
            brute += (x - w * t).length().ln() / n as f64;
        }
        assert!((point_segment_log(x, c, w, 1.0).0 - brute).abs() < 1e-6);
    }

    #[test]
    fn semi_analytic_agrees_with_product_rule_on_smooth_pairs() {
        let (a, b) = (DVec3::ZERO, DVec3::new(1.0, 0.2, 0.0));
        let (c, d) = (DVec3::new(0.1, 1.0, 0.5), DVec3::new(1.2, 1.1, 0.4));
        let mut e = 0;
        let s = semi_analytic(a, b, c, d, &mut e);
        assert!((s - brute(a, b, c, d, 16)).abs() < 1e-12, "{s}");
    }

    #[test]
    fn touching_at_a_vertex_converges() {
        // Edges meeting at the origin at 60°: r → 0 at one end of both.
        let (a, b) = (DVec3::ZERO, DVec3::X);
        let (c, d) = (DVec3::ZERO, DVec3::new(0.5, 0.75f64.sqrt(), 0.0));
        let mut e = 0;
        let s = semi_analytic(a, b, c, d, &mut e);
        // Reference by splitting the singular corner into a geometric sequence of squares.
        let mut reference = 0.0;
        let mut lo = 1.0;
        for _ in 0..60 {
            let hi = lo;
            lo *= 0.5;
            let f = |x: f64| (a + (b - a) * x, c + (d - c) * x);
            let (p0, q0) = f(lo);
            let (p1, q1) = f(hi);
            let (pz, qz) = f(0.0);
            reference +=
                brute(p0, p1, q0, q1, 4) + brute(pz, p0, q0, q1, 4) + brute(p0, p1, qz, q0, 4);
            let _ = (pz, qz);
        }
        assert!((s - reference).abs() < 1e-9, "{s} vs {reference}");
    }

    /// Segment pairs at `ratio` × their length apart, in several orientations.
    fn separated_pairs(ratio: f64) -> Vec<[DVec3; 4]> {
        let dirs = [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::new(1.0, 1.0, 0.0).normalize(),
            DVec3::new(0.3, -0.5, 0.8).normalize(),
        ];
        let offsets = [DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 1.0).normalize()];
        let mut pairs = Vec::new();
        for &u in &dirs {
            for &w in &dirs {
                for &off in &offsets {
                    let c = u * 0.5 + off * (ratio + 1.0);
                    if segment_distance(DVec3::ZERO, u, c, c + w) >= ratio {
                        pairs.push([DVec3::ZERO, u, c, c + w]);
                    }
                }
            }
        }
        pairs
    }

    #[test]
    fn far_order_reaches_the_rounding_level() {
        // The table in far_order's documentation, re-measured at its thresholds.
        for ratio in [4.0, 6.0, 8.0, 16.0, 64.0, 300.0] {
            let mut worst: f64 = 0.0;
            for [a, b, c, d] in separated_pairs(ratio) {
                let mut e = 0;
                let g = product_gauss(a, b, c, d, far_order(ratio), &mut e);
                worst = worst.max((g - brute(a, b, c, d, 4)).abs());
            }
            assert!(worst < 4e-15, "ratio {ratio}: {worst:e}");
        }
    }

    #[test]
    fn semi_analytic_stops_at_the_rounding_noise_of_its_closed_form() {
        // Far from Q the two ends of the closed form cancel to ~ε × (R ln R): the bisection
        // used to chase a tolerance below that noise down to depth 60. Now it stops at once.
        for [a, b, c, d] in separated_pairs(256.0) {
            let mut e = 0;
            let s = semi_analytic(a, b, c, d, &mut e);
            assert!(e <= 24 * 4, "{e} evaluations");
            assert!((s - brute(a, b, c, d, 2)).abs() < 1e-12, "{s}");
        }
    }

    /// Pieces the adaptive rule used, from its evaluations: 8 (4 N − k) for N pieces, k ∈ 1..=4
    /// of them starting ones (see MAX_SEGMENT_PAIR_EVALUATIONS).
    fn pieces(evaluations: u64) -> u64 {
        (evaluations / u64::from(ADAPTIVE_ORDER) + 4) / 4
    }

    /// A small deterministic generator (xorshift64*), so the unit tests need no dependency.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }

        fn unit(&mut self) -> DVec3 {
            loop {
                let v = DVec3::new(self.next(), self.next(), self.next()) * 2.0 - 1.0;
                if (0.1..1.0).contains(&v.length()) {
                    return v.normalize();
                }
            }
        }
    }

    #[test]
    fn tiny_segments_far_from_the_origin_finish_and_scale_exactly() {
        // Issue 14: two clipped slivers 1.6e-7 across, 0.05 from the pair frame's origin,
        // touching at a corner. Each evaluation was rounded to ε × 0.05, 3e5 × the noise the
        // bisection allowed for, and it bisected all 2⁶⁰ pieces. Now: the same segments at
        // unit size, scaled by λ = 2⁻²³ and moved to 0.05 (both exact in f64), must give
        // λ² (I + cos lp lq ln λ), ∫∫ ln(λ r) = λ² ∫∫ (ln r + ln λ).
        let lambda = 2f64.powi(-23);
        let offset = DVec3::new(0.05, -0.03125, 0.0625);
        let mut rng = Rng(0x0dd_ba11);
        let (mut worst, mut most) = (0.0f64, 0u64);
        for _ in 0..200 {
            let (a, u, w) = (DVec3::ZERO, rng.unit(), rng.unit());
            let (b, lq) = (a + u * (0.5 + rng.next()), 0.5 + rng.next());
            // Q starts at P's end (a touching corner) or at a point of P (a T-junction).
            let c = if rng.next() < 0.5 {
                a + (b - a) * rng.next()
            } else {
                b
            };
            let d = c + w * lq;
            let [a, b, c, d] = [a, b, c, d].map(|x| {
                // Snap the unit-size points to a grid that scales exactly.
                (x * 2f64.powi(20)).round() / 2f64.powi(20)
            });
            let opts = ContourOptions::default();
            let mut e = 0;
            let unit = edge_pair(a, b, c, d, &opts, &mut e);
            let tiny = [a, b, c, d].map(|x| offset + x * lambda);
            assert!(tiny
                .iter()
                .zip([a, b, c, d])
                .all(|(t, x)| (*t - offset) / lambda == x));
            let mut e = 0;
            let got = edge_pair(tiny[0], tiny[1], tiny[2], tiny[3], &opts, &mut e);
            let (lp, lq) = ((b - a).length(), (d - c).length());
            let cos = (b - a).dot(d - c) / (lp * lq);
            let expected = lambda * lambda * (unit + cos * lp * lq * lambda.ln());
            worst = worst.max((got - expected).abs() / (lambda * lambda * lp * lq));
            most = most.max(e);
            assert!(e <= MAX_SEGMENT_PAIR_EVALUATIONS, "{e}");
        }
        eprintln!("tiny far segments: worst error {worst:.1e} of λ² lp lq, {most} evaluations");
        assert!(worst < 1e-13, "{worst:e}");
        assert!(pieces(most) <= 64, "{most} evaluations");
    }

    #[test]
    fn adaptive_rule_stays_far_below_its_budget() {
        // The budget's claim (MAX_PIECES): touching ends, T-junctions, near crossings, lengths
        // 1:10⁶ either way round and slivers far from the origin need at most about half of
        // it (measured 68 over 160 000 pairs of these kinds in a prototype).
        let mut rng = Rng(0x5eed);
        let mut most = [0u64; 7];
        for _ in 0..150 {
            for (kind, most) in most.iter_mut().enumerate() {
                let scale = if kind == 6 { 1e-7 } else { 1.0 };
                let a = (DVec3::new(rng.next(), rng.next(), rng.next()) - 0.5) * 0.5;
                let (u, w) = (rng.unit(), rng.unit());
                let (mut lp, mut lq) = ((0.2 + rng.next()) * scale, (0.2 + rng.next()) * scale);
                match kind {
                    4 => lp *= 1e-6f64.powf(rng.next()),
                    5 => lq *= 1e-6f64.powf(rng.next()),
                    _ => {}
                }
                let b = a + u * lp;
                let c = match kind {
                    1 => a + u * (lp * rng.next()),
                    2 => b + rng.unit() * (lp.min(lq) * 1e-3 * rng.next()),
                    3 => a + u * (lp * rng.next()) + rng.unit() * 1e-6 * lp,
                    _ => b,
                };
                let mut e = 0;
                let v = semi_analytic(a, b, c, c + w * lq, &mut e);
                assert!(v.is_finite());
                *most = (*most).max(pieces(e));
            }
        }
        eprintln!("adaptive pieces at most, per kind: {most:?} (budget {MAX_PIECES})");
        assert!(most.iter().all(|&m| m <= MAX_PIECES as u64 / 2), "{most:?}");
    }
}
