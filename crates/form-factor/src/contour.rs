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
    if is_collinear(a, u, c, d, scale) {
        *evaluations += 1;
        return cos * collinear(lp, (c - a).dot(u), (d - a).dot(u));
    }
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

/// `∫_0^{lp} ∫_{y0}^{y1} ln|s − y| dy ds` for collinear segments P = [0, lp] and Q between the
/// line coordinates `yc` and `yd` (either order; arc length is |dy|). Exact.
fn collinear(lp: f64, yc: f64, yd: f64) -> f64 {
    let (y0, y1) = if yc <= yd { (yc, yd) } else { (yd, yc) };
    // ∫_{y0}^{y1} ln|s−y| dy = F1(s−y0) − F1(s−y1), F1' = ln|x|, then integrate over s.
    g2(lp - y0) - g2(-y0) - g2(lp - y1) + g2(-y1)
}

/// Product Gauss–Legendre rule (the paper's nine-point rule for order 3).
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

/// Outer integral over P by adaptive Gauss–Legendre (interval bisection until two levels
/// agree to the tolerance or to the rounding noise of the closed form, whichever is larger),
/// inner integral over Q in closed form. The outer integrand is bounded and continuous
/// even where r → 0 (it behaves like s ln s there), so bisection converges; the near-singular
/// spots (closest approach, Q's endpoints seen from P) are found by the bisection itself.
fn semi_analytic(s0: DVec3, s1: DVec3, t0: DVec3, t1: DVec3, evaluations: &mut u64) -> f64 {
    let p = s1 - s0;
    let lp = p.length();
    let q = t1 - t0;
    let lq = q.length();
    let (u, w) = (p / lp, q / lq);
    let outer = Outer {
        s0,
        u,
        t0,
        w,
        lq,
        rule: gauss(ADAPTIVE_ORDER),
    };
    let whole = outer.gauss(0.0, lp, evaluations);
    // Absolute tolerance relative to the size of the pair (coordinates are pair-normalised).
    outer.adaptive(
        0.0,
        lp,
        whole.0,
        ADAPTIVE_TOLERANCE * lp * lq.max(lp),
        0,
        evaluations,
    )
}

/// Gauss order of the adaptive outer rule.
const ADAPTIVE_ORDER: u32 = 8;
/// Relative tolerance of the adaptive outer rule.
const ADAPTIVE_TOLERANCE: f64 = 1e-14;
/// Bisection depth limit (2⁻⁶⁰ of an edge is far below f64 resolution of the pair).
const MAX_DEPTH: u32 = 60;
/// Two levels that agree to this many ε of the magnitude of the cancelling terms agree to
/// rounding, and bisecting further cannot improve them. Where that noise exceeds the tolerance
/// (far from a short Q, |ln r| large) it does so at every level, both halving with the
/// interval: without this stop the bisection went on to MAX_DEPTH everywhere (2⁶⁰ intervals).
const ROUNDING_ULPS: f64 = 16.0;

struct Outer {
    s0: DVec3,
    u: DVec3,
    t0: DVec3,
    w: DVec3,
    lq: f64,
    rule: &'static [(f64, f64)],
}

impl Outer {
    /// The Gauss rule on [from, to] and the magnitude of its cancelling terms.
    fn gauss(&self, from: f64, to: f64, evaluations: &mut u64) -> (f64, f64) {
        let (mid, half) = ((from + to) * 0.5, (to - from) * 0.5);
        let (mut acc, mut mag) = (0.0, 0.0);
        for &(xi, wi) in self.rule {
            let (value, magnitude) = point_segment_log(
                self.s0 + self.u * (mid + half * xi),
                self.t0,
                self.w,
                self.lq,
            );
            acc += wi * value;
            mag += wi * magnitude;
        }
        *evaluations += self.rule.len() as u64;
        (acc * half, mag * half)
    }

    fn adaptive(
        &self,
        from: f64,
        to: f64,
        whole: f64,
        tol: f64,
        depth: u32,
        evaluations: &mut u64,
    ) -> f64 {
        let mid = 0.5 * (from + to);
        let ((left, left_mag), (right, right_mag)) = (
            self.gauss(from, mid, evaluations),
            self.gauss(mid, to, evaluations),
        );
        let noise = ROUNDING_ULPS * f64::EPSILON * (left_mag + right_mag);
        if depth >= MAX_DEPTH || (left + right - whole).abs() <= tol.max(noise) {
            return left + right;
        }
        self.adaptive(from, mid, left, 0.5 * tol, depth + 1, evaluations)
            + self.adaptive(mid, to, right, 0.5 * tol, depth + 1, evaluations)
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
        let exact = collinear(1.0, 1.5, 3.0);
        assert!((exact - brute(a, b, c, d, 64)).abs() < 1e-12, "{exact}");
    }

    #[test]
    fn collinear_self_overlap_is_finite_and_exact() {
        // ∫_0^1∫_0^1 ln|s−t| ds dt = −3/2.
        assert!((collinear(1.0, 0.0, 1.0) + 1.5).abs() < 1e-15);
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
}
