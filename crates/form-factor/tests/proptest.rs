//! Property tests of the contour-integral form factors over random quads, rectangles and
//! enclosures: F ≥ 0, F ≤ 1, reciprocity (eq. 14), row sums (eq. 15), and agreement with the
//! closed forms for axis-aligned parallel and perpendicular rectangles at arbitrary offsets
//! (tests/common, Howell's catalogue generalised by superposition).

mod common;

use bake_form_factor::{polygon_pair, ContourOptions, FormFactors};
use common::*;
use glam::{DMat3, DVec3};
use importer::{Origin, Polygon, Side};
use mesher::{mesh, Subdivision};
use proptest::prelude::*;
use std::f64::consts::TAU;

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 64,
        ..ProptestConfig::default()
    }
}

fn perimeter(p: &[DVec3]) -> f64 {
    (0..p.len())
        .map(|k| p[k].distance(p[(k + 1) % p.len()]))
        .sum()
}

/// A unit vector from two uniform numbers (uniform on the sphere).
fn unit(z: f64, phi: f64) -> DVec3 {
    let s = (1.0 - z * z).sqrt();
    DVec3::new(s * phi.cos(), s * phi.sin(), z)
}

/// A convex quad in a random plane: four points in cyclic order on an ellipse (so convex),
/// counter-clockwise about the plane's normal.
fn convex_quad() -> impl Strategy<Value = Vec<DVec3>> {
    (
        prop::array::uniform3(-2.0..2.0f64),
        -1.0..1.0f64,
        0.0..TAU,
        0.0..TAU,
        0.05..2.0f64,
        0.05..2.0f64,
        prop::array::uniform4(0.3..1.0f64),
    )
        .prop_map(|(c, z, phi, spin, a, b, gaps)| {
            let n = unit(z, phi);
            let e1 = n.any_orthonormal_vector();
            let e1 = DMat3::from_axis_angle(n, spin) * e1;
            let e2 = n.cross(e1);
            let total: f64 = gaps.iter().sum();
            let mut angle: f64 = 0.0;
            gaps.iter()
                .map(|g| {
                    let p = DVec3::from(c) + e1 * (a * angle.cos()) + e2 * (b * angle.sin());
                    angle += g / total * TAU;
                    p
                })
                .collect()
        })
}

/// A rectangle in a random plane.
fn rectangle() -> impl Strategy<Value = Vec<DVec3>> {
    (
        prop::array::uniform3(-2.0..2.0f64),
        -1.0..1.0f64,
        0.0..TAU,
        0.0..TAU,
        0.05..2.0f64,
        0.05..2.0f64,
    )
        .prop_map(|(c, z, phi, spin, a, b)| {
            let n = unit(z, phi);
            let e1 = DMat3::from_axis_angle(n, spin) * n.any_orthonormal_vector();
            let e2 = n.cross(e1);
            [(0.0, 0.0), (a, 0.0), (a, b), (0.0, b)]
                .iter()
                .map(|&(x, y)| DVec3::from(c) + e1 * x + e2 * y)
                .collect()
        })
}

/// F ≥ 0, F ≤ 1 and reciprocity for one pair, each direction integrated on its own.
fn pair_properties(i: &[DVec3], j: &[DVec3]) -> Result<(), TestCaseError> {
    let o = ContourOptions::default();
    let (fij, fji) = (polygon_pair(i, j, &o), polygon_pair(j, i, &o));
    prop_assert!(fij.is_finite() && fji.is_finite());
    prop_assert!(fij >= 0.0 && fji >= 0.0, "{fij} {fji}");
    prop_assert!(fij <= 1.0 + 1e-12 && fji <= 1.0 + 1e-12, "{fij} {fji}");
    let (gij, gji) = (area(i) * fij, area(j) * fji);
    // Both are the same double contour integral, up to the rounding floor of eq. 13
    // (~ε × the perimeters' product) and the adaptive rule's 1e-14.
    let allowed = 1e-10 * gij.max(gji) + 4.0 * f64::EPSILON * perimeter(i) * perimeter(j);
    prop_assert!((gij - gji).abs() <= allowed, "{gij} vs {gji}");
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn random_convex_quads_are_non_negative_bounded_and_reciprocal(
        i in convex_quad(),
        j in convex_quad(),
    ) {
        pair_properties(&i, &j)?;
    }

    #[test]
    fn random_rectangles_are_non_negative_bounded_and_reciprocal(
        i in rectangle(),
        j in rectangle(),
    ) {
        pair_properties(&i, &j)?;
    }
}

// ---------------------------------------------------------------------------------------------
// Enclosures: rows of a closed convex body sum to 1 (eq. 15), of an open one to at most 1.
// ---------------------------------------------------------------------------------------------

fn polygon(vertices: Vec<DVec3>, k: usize) -> Polygon {
    let normal = normal(&vertices);
    Polygon {
        vertices,
        normal,
        material: 0,
        origin: Origin {
            node: k,
            mesh: k,
            primitive: 0,
            face: 0,
            side: Side::Front,
        },
    }
}

/// The six inward faces of the parallelepiped `corner + M [0, 1]³` (det M > 0): parallelogram
/// walls, a convex enclosure in which nothing is occluded.
fn parallelepiped(corner: DVec3, m: DMat3) -> Vec<Polygon> {
    let faces = reference::unit_cube_walls().map(|f| f.map(|q| corner + m * q));
    faces
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let poly = polygon(f.to_vec(), k);
            // Inward: the body's centre is in front of every face.
            let centre = corner + m * DVec3::splat(0.5);
            if (centre - f[0]).dot(poly.normal) > 0.0 {
                poly
            } else {
                polygon(f.iter().rev().copied().collect(), k)
            }
        })
        .collect()
}

/// A random parallelepiped: edge lengths 0.2–3, shear up to ±0.5 of the neighbouring edge.
fn enclosure() -> impl Strategy<Value = Vec<Polygon>> {
    (
        prop::array::uniform3(-5.0..5.0f64),
        prop::array::uniform3(0.2..3.0f64),
        prop::array::uniform3(-0.5..0.5f64),
    )
        .prop_map(|(corner, size, shear)| {
            let m = DMat3::from_cols(
                DVec3::new(size[0], 0.0, 0.0),
                DVec3::new(shear[0] * size[0], size[1], 0.0),
                DVec3::new(shear[1] * size[0], shear[2] * size[1], size[2]),
            );
            parallelepiped(DVec3::from(corner), m)
        })
}

fn subdivision() -> impl Strategy<Value = Subdivision> {
    prop_oneof![
        (1u32..4).prop_map(Subdivision::Count),
        (0.4..1.5f64).prop_map(Subdivision::MaxSize),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..config() })]

    #[test]
    fn rows_of_random_closed_enclosures_sum_to_one(
        walls in enclosure(),
        subdivision in subdivision(),
    ) {
        let m = mesh(&walls, subdivision).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assume!(m.elements.len() <= 150);
        let f = FormFactors::new(&m, ContourOptions::default()).dense();
        for (i, s) in f.row_sums().iter().enumerate() {
            // The issue asks for 1e-9; 512 cases measured at most 4.4e-15.
            prop_assert!((s - 1.0).abs() <= 1e-12, "row {i}: {s}");
        }
    }

    #[test]
    fn rows_of_random_open_enclosures_sum_to_at_most_one(
        walls in enclosure(),
        keep in prop::array::uniform6(any::<bool>()),
        subdivision in subdivision(),
    ) {
        let walls: Vec<Polygon> = walls
            .into_iter()
            .zip(keep)
            .filter_map(|(w, k)| k.then_some(w))
            .collect();
        prop_assume!(!walls.is_empty());
        let m = mesh(&walls, subdivision).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assume!(m.elements.len() <= 150);
        let f = FormFactors::new(&m, ContourOptions::default()).dense();
        for (i, s) in f.row_sums().iter().enumerate() {
            prop_assert!(*s <= 1.0 + 1e-12, "row {i}: {s}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Closed forms at arbitrary offsets.
// ---------------------------------------------------------------------------------------------

/// A coordinate: sometimes on a coarse grid, so that edges touch, overlap and line up exactly.
fn coordinate(range: f64) -> impl Strategy<Value = f64> {
    let steps = (range / 0.25) as i32;
    prop_oneof![
        (-steps..=steps).prop_map(|k| f64::from(k) * 0.25),
        -range..range,
    ]
}

/// A side length, sometimes on the grid.
fn side() -> impl Strategy<Value = f64> {
    prop_oneof![(1i32..=6).prop_map(|k| f64::from(k) * 0.25), 0.05..2.0f64]
}

/// A non-negative distance from the common line, sometimes exactly 0 (on it).
fn from_line() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), coordinate(2.0).prop_map(f64::abs)]
}

fn rect(x0: f64, w: f64, y0: f64, h: f64) -> Rect {
    Rect {
        x0,
        x1: x0 + w,
        y0,
        y1: y0 + h,
    }
}

/// |F − F_closed| ≤ 1e-8 relative, or 1e-11 absolute for F < 1e-3 (where the closed form's
/// corner sum itself loses digits to cancellation). The issue asks for 1e-6; 512 cases per
/// property measured at most 4.3e-11.
fn agrees(f: f64, closed: f64) -> Result<(), TestCaseError> {
    prop_assert!(
        (f - closed).abs() <= 1e-8 * closed.abs().max(1e-3),
        "{f} vs closed form {closed}"
    );
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn parallel_rectangles_at_any_offset_match_the_closed_form(
        (x0, w, y0, h) in (coordinate(2.0), side(), coordinate(2.0), side()),
        (xi0, wj, eta0, hj) in (coordinate(2.0), side(), coordinate(2.0), side()),
        c in prop_oneof![(1i32..=8).prop_map(|k| f64::from(k) * 0.25), 0.01..3.0f64],
    ) {
        let (i, j) = (rect(x0, w, y0, h), rect(xi0, wj, eta0, hj));
        let f = polygon_pair(&rect_z(i, 0.0, false), &rect_z(j, c, true), &ContourOptions::default());
        agrees(f, parallel_rectangles(i, j, c))?;
    }

    #[test]
    fn perpendicular_rectangles_at_any_offset_match_the_closed_form(
        (x0, w, y0, h) in (coordinate(2.0), side(), from_line(), side()),
        (xi0, wj, eta0, hj) in (coordinate(2.0), side(), from_line(), side()),
    ) {
        let (i, j) = (rect(x0, w, y0, h), rect(xi0, wj, eta0, hj));
        let f = polygon_pair(&rect_z(i, 0.0, false), &rect_y0(j), &ContourOptions::default());
        agrees(f, perpendicular_rectangles(i, j))?;
        let back = polygon_pair(&rect_y0(j), &rect_z(i, 0.0, false), &ContourOptions::default());
        agrees(back * (wj * hj) / (w * h), perpendicular_rectangles(i, j))?;
    }
}
