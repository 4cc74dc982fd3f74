//! Independent references for the form-factor stress tests: closed forms (Howell's catalogue,
//! generalised by superposition; from the `bake-reference` crate) and quadratures of the area
//! integral (Goral et al. 1984, eq. 12) that share no code with the contour integrator under
//! test.
#![allow(dead_code)] // each test binary uses its own subset

use glam::DVec3;
#[allow(unused_imports)] // each test binary uses its own subset
pub use reference::{
    gauss_legendre, parallel_opposed, parallel_rectangles, perpendicular_rectangles,
    perpendicular_shared_edge, Rect,
};
use std::f64::consts::PI;

pub fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// `r1` as a polygon in the plane z = `z`, counter-clockwise about +z (or −z if `down`).
pub fn rect_z(r: Rect, z: f64, down: bool) -> Vec<DVec3> {
    let p = vec![
        v(r.x0, r.y0, z),
        v(r.x1, r.y0, z),
        v(r.x1, r.y1, z),
        v(r.x0, r.y1, z),
    ];
    if down {
        p.into_iter().rev().collect()
    } else {
        p
    }
}

/// `r` (ξ along x, η along z) as a polygon in the plane y = 0, counter-clockwise about +y.
pub fn rect_y0(r: Rect) -> Vec<DVec3> {
    vec![
        v(r.x0, 0.0, r.y0),
        v(r.x0, 0.0, r.y1),
        v(r.x1, 0.0, r.y1),
        v(r.x1, 0.0, r.y0),
    ]
}

// ---------------------------------------------------------------------------------------------
// Reference A: rectangles sharing an edge at a dihedral angle, eq. 12 reduced to one dimension.
// ---------------------------------------------------------------------------------------------

/// i = `[0, l] × [0, w]` in the plane z = 0 (facing +z); j = the rectangle with the same edge
/// `[0, l]` on the x axis, width h, at dihedral angle φ to i: points (x', s cos φ, s sin φ),
/// s ∈ [0, h], normal (0, sin φ, −cos φ) (φ = 90°: a wall; φ → 0: a closing book).
pub fn dihedral_pair(l: f64, w: f64, h: f64, phi: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    let (c, s) = (phi.cos(), phi.sin());
    let i = vec![
        v(0.0, 0.0, 0.0),
        v(l, 0.0, 0.0),
        v(l, w, 0.0),
        v(0.0, w, 0.0),
    ];
    let j = vec![
        v(0.0, 0.0, 0.0),
        v(0.0, h * c, h * s),
        v(l, h * c, h * s),
        v(l, 0.0, 0.0),
    ];
    (i, j)
}

/// F_ij of [`dihedral_pair`] from the area integral (eq. 12), reduced analytically:
///
/// With d = p_j − p_i, n_i·d = s sin φ and −n_j·d = y sin φ, so the kernel
/// cos θ_i cos θ_j / (π r²) is s y sin²φ / (π r⁴), r² = (x − x')² + ρ², ρ² = y² + s² − 2ys cos φ.
/// 1. Over x, x' ∈ [0, l]²: ∫∫ dx dx' / (u² + ρ²)² = 2∫_0^l (l − u) du / (u² + ρ²)²
///    = l atan(l/ρ) / ρ³.
/// 2. Polar coordinates (y, s) = r (cos α, sin α) (a Duffy-type transform that removes the
///    singularity at the shared edge, y = s = 0): ρ = r √q, q = 1 − sin 2α cos φ, and the
///    integrand s y atan(l/ρ)/ρ³ · r becomes sin α cos α q^{-3/2} atan(c/r), c = l/√q.
/// 3. Over r ∈ [0, R(α)], R = min(w / cos α, h / sin α):
///    ∫_0^R atan(c/r) dr = R atan(c/R) + c/2 ln(1 + R²/c²).
///
/// That leaves F_ij = sin²φ / (π w) ∫_0^{π/2} sin α cos α q^{-3/2} [step 3] dα, a smooth
/// integrand (kink at tan α = h/w, a peak of width ~φ at α = π/4 for a closing book),
/// integrated by adaptive Gauss–Legendre to ~1e-15.
pub fn dihedral_reference(l: f64, w: f64, h: f64, phi: f64) -> f64 {
    let cos_phi = phi.cos();
    let one_minus_cos = 2.0 * (0.5 * phi).sin().powi(2);
    let f = |alpha: f64| {
        let (sa, ca) = alpha.sin_cos();
        // 1 − sin 2α cos φ, written to keep its digits when the book nearly closes.
        let q = if cos_phi > 0.0 {
            (ca - sa).powi(2) + 2.0 * sa * ca * one_minus_cos
        } else {
            1.0 - 2.0 * sa * ca * cos_phi
        };
        let big_r = if ca * h > sa * w { w / ca } else { h / sa };
        let c = l / q.sqrt();
        let radial = big_r * (c / big_r).atan() + 0.5 * c * (big_r / c).powi(2).ln_1p();
        sa * ca * q.powf(-1.5) * radial
    };
    let kink = h.atan2(w);
    let rule = gauss_legendre(10);
    let integral = adaptive_1d(&f, 0.0, kink, &rule) + adaptive_1d(&f, kink, 0.5 * PI, &rule);
    phi.sin().powi(2) / (PI * w) * integral
}

/// Adaptive Gauss–Legendre: bisect until the two halves agree with the whole to 1e-16 of the
/// integral's scale (relative; a depth limit stops it at the f64 floor).
pub fn adaptive_1d(f: &dyn Fn(f64) -> f64, a: f64, b: f64, rule: &[(f64, f64)]) -> f64 {
    fn gauss(f: &dyn Fn(f64) -> f64, a: f64, b: f64, rule: &[(f64, f64)]) -> f64 {
        let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
        rule.iter().map(|&(x, w)| w * f(m + h * x)).sum::<f64>() * h
    }
    fn recurse(
        f: &dyn Fn(f64) -> f64,
        a: f64,
        b: f64,
        whole: f64,
        scale: f64,
        rule: &[(f64, f64)],
        depth: u32,
    ) -> f64 {
        let m = 0.5 * (a + b);
        let (left, right) = (gauss(f, a, m, rule), gauss(f, m, b, rule));
        if depth >= 50 || (left + right - whole).abs() <= 1e-16 * scale {
            return left + right;
        }
        recurse(f, a, m, left, scale, rule, depth + 1)
            + recurse(f, m, b, right, scale, rule, depth + 1)
    }
    let whole = gauss(f, a, b, rule);
    // The scale: a coarse estimate of ∫|f| (the integrands here are one-signed).
    let scale = whole.abs().max(f64::MIN_POSITIVE);
    recurse(f, a, b, whole, scale, rule, 0)
}

// ---------------------------------------------------------------------------------------------
// Reference B: any pair of planar convex polygons, i wholly in front of j and vice versa.
// ---------------------------------------------------------------------------------------------

/// Form factor from a differential area at `x` (unit normal `n`) to the polygon `poly` wholly in
/// front of it (Lambert's / Hottel's closed form, the inner area integral of eq. 12 over A_j):
/// F = 1/(2π) Σ_k γ_k n·(R_k × R_{k+1}) / |R_k × R_{k+1}|, R_k = v_k − x, γ_k the angle between
/// R_k and R_{k+1}; the sign is fixed by the polygon's orientation, and it is used as |·|.
pub fn point_to_polygon(x: DVec3, n: DVec3, poly: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for k in 0..poly.len() {
        let (r0, r1) = (poly[k] - x, poly[(k + 1) % poly.len()] - x);
        let c = r0.cross(r1);
        let len = c.length();
        if len > 0.0 {
            sum += len.atan2(r0.dot(r1)) * n.dot(c) / len;
        }
    }
    (sum / (2.0 * PI)).abs()
}

/// Points 0 < … < 1 graded geometrically (ratio ½) towards both ends, `levels` per end.
fn graded(levels: u32) -> Vec<f64> {
    let mut t = vec![0.0];
    for k in (2..=levels).rev() {
        t.push(0.5f64.powi(k as i32));
    }
    t.push(0.5);
    for k in 2..=levels {
        t.push(1.0 - 0.5f64.powi(k as i32));
    }
    t.push(1.0);
    t
}

/// F_ij = 1/A_i ∫_{A_i} F_{dA_i → A_j} dA_i (eq. 12 with the inner integral in closed form),
/// A_i given as convex quads `pieces` (bilinear maps, counter-clockwise about `n_i`; split A_i
/// at points where j's corners touch the interior of an edge of i). Each piece is integrated by
/// a tensor Gauss–Legendre rule on cells graded geometrically towards all four of its edges and
/// corners, where the outer integrand has its x ln x-type singularities (shared edges, touching
/// corners), so the rule converges exponentially there too.
pub fn area_reference(pieces: &[[DVec3; 4]], n_i: DVec3, j: &[DVec3], levels: u32) -> f64 {
    let rule = gauss_legendre(8);
    let t = graded(levels);
    let mut integral = 0.0;
    let mut area = 0.0;
    for &[a, b, c, d] in pieces {
        let p = |u: f64, w: f64| (a * (1.0 - u) + b * u) * (1.0 - w) + (d * (1.0 - u) + c * u) * w;
        let jac = |u: f64, w: f64| {
            let du = (b - a) * (1.0 - w) + (c - d) * w;
            let dw = (d - a) * (1.0 - u) + (c - b) * u;
            du.cross(dw).dot(n_i)
        };
        for cu in t.windows(2) {
            let (um, uh) = (0.5 * (cu[0] + cu[1]), 0.5 * (cu[1] - cu[0]));
            for cw in t.windows(2) {
                let (wm, wh) = (0.5 * (cw[0] + cw[1]), 0.5 * (cw[1] - cw[0]));
                for &(xu, au) in &rule {
                    let u = um + uh * xu;
                    for &(xw, aw) in &rule {
                        let w = wm + wh * xw;
                        let weight = au * aw * uh * wh * jac(u, w);
                        integral += weight * point_to_polygon(p(u, w), n_i, j);
                        area += weight;
                    }
                }
            }
        }
    }
    integral / area
}

/// Area of a planar convex polygon (fan).
pub fn area(poly: &[DVec3]) -> f64 {
    let mut a = DVec3::ZERO;
    for k in 1..poly.len() - 1 {
        a += (poly[k] - poly[0]).cross(poly[k + 1] - poly[0]);
    }
    0.5 * a.length()
}

/// Unit normal of a planar polygon, counter-clockwise convention (Newell's method about the
/// first vertex, as the importer computes it).
pub fn normal(poly: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for k in 0..poly.len() {
        n += (poly[k] - poly[0]).cross(poly[(k + 1) % poly.len()] - poly[0]);
    }
    n.normalize()
}

/// The quad `poly` (4 vertices) as one piece for [`area_reference`].
pub fn piece(poly: &[DVec3]) -> [DVec3; 4] {
    [poly[0], poly[1], poly[2], poly[3]]
}
