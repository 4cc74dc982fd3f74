//! Independent references for form factors: closed forms from Howell's catalogue of
//! configuration factors, generalised by corner-sum superposition to axis-aligned rectangles
//! at any offsets, and a Gauss–Legendre rule for brute-force quadratures of the area integral
//! (Goral et al. 1984, eq. 12).
//!
//! These references share no code with the integrator under test (`bake-form-factor`, the
//! contour integral of eq. 13): they are what its tests and `tools/accuracy-report` measure it
//! against. The crate is not part of the baking pipeline.
//!
//! Public API: the closed forms ([`parallel_opposed`], [`perpendicular_shared_edge`],
//! [`parallel_rectangles`], [`perpendicular_rectangles`] over [`Rect`]), [`gauss_legendre`],
//! [`box_walls`] and [`unit_cube_walls`].

use glam::DVec3;
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
