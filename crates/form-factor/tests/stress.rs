//! Stress tests of the contour-integral form factors (Goral et al. 1984, eq. 13) against
//! references that share no code with the integrator (tests/common): closed forms from Howell's
//! catalogue generalised by superposition, and the area integral (eq. 12) by quadratures built
//! for the singular spots (shared edges, touching corners).
//!
//! Every test prints the worst error it measured (`cargo test --test stress -- --nocapture`).

mod common;

use bake_form_factor::{polygon_pair, ContourOptions, FormFactors};
use common::*;
use glam::DVec3;
use importer::{Origin, Polygon, Side};
use mesher::{mesh, Subdivision};

fn r(x0: f64, x1: f64, y0: f64, y1: f64) -> Rect {
    Rect { x0, x1, y0, y1 }
}

/// F_ij and F_ji, each integrated on its own (the dense path would share one integral). With
/// one segment per edge, also checks that cutting every edge into 3 segments (collinear pieces
/// of different lengths, segment ends meeting mid-edge) changes F_ij by rounding only.
fn both_ways(i: &[DVec3], j: &[DVec3], o: &ContourOptions) -> (f64, f64) {
    let (fij, fji) = (polygon_pair(i, j, o), polygon_pair(j, i, o));
    if o.segments == 1 {
        let cut = ContourOptions { segments: 3, ..*o };
        let f3 = polygon_pair(i, j, &cut);
        let allowed = 1e-12 * fij + 2.0 * rounding_floor(i, j);
        assert!((f3 - fij).abs() <= allowed, "3 segments: {f3} vs {fij}");
    }
    (fij, fji)
}

/// |A_i F_ij − A_j F_ji| / (A_i F_ij).
fn reciprocity(i: &[DVec3], j: &[DVec3], fij: f64, fji: f64) -> f64 {
    let (gi, gj) = (area(i) * fij, area(j) * fji);
    (gi - gj).abs() / gi.abs().max(f64::MIN_POSITIVE)
}

fn relative(f: f64, reference: f64) -> f64 {
    (f - reference).abs() / reference.abs()
}

#[test]
fn the_references_agree_with_howell_and_with_each_other() {
    // Generalised closed forms in the special cases of C-11 and C-14.
    let mut worst: f64 = 0.0;
    for &(a, b, c) in &[
        (1.0, 1.0, 1.0),
        (1.0, 2.0, 0.1),
        (3.0, 0.5, 1.0),
        (0.2, 0.3, 0.05),
    ] {
        let general = parallel_rectangles(r(0.0, a, 0.0, b), r(0.0, a, 0.0, b), c);
        worst = worst.max(relative(general, parallel_opposed(a, b, c)));
    }
    for &(l, w, h) in &[
        (1.0, 1.0, 1.0),
        (1.0, 0.5, 2.0),
        (2.0, 1.0, 0.1),
        (0.1, 3.0, 1.0),
    ] {
        let general = perpendicular_rectangles(r(0.0, l, 0.0, w), r(0.0, l, 0.0, h));
        worst = worst.max(relative(general, perpendicular_shared_edge(l, w, h)));
        let reduced = dihedral_reference(l, w, h, 90f64.to_radians());
        worst = worst.max(relative(reduced, perpendicular_shared_edge(l, w, h)));
    }
    eprintln!("generalised closed forms and reference A vs C-11/C-14: {worst:.1e}");
    assert!(worst < 1e-13, "{worst}");

    // The closed forms at offsets, and reference A at other angles, against reference B.
    let mut worst_b: f64 = 0.0;
    let floor = r(0.0, 1.0, 0.0, 1.0);
    for (i, j, c) in [
        (floor, r(0.5, 2.0, -0.3, 0.4), 0.7),
        (floor, r(-1.0, 0.2, 1.5, 2.0), 0.3),
        (r(0.0, 2.0, 0.0, 0.5), r(3.0, 4.0, 1.0, 2.0), 1.0),
    ] {
        let reference = area_reference(
            &[piece(&rect_z(i, 0.0, false))],
            DVec3::Z,
            &rect_z(j, c, true),
            8,
        );
        worst_b = worst_b.max(relative(parallel_rectangles(i, j, c), reference));
    }
    for (i, j) in [
        (floor, r(1.0, 2.0, 0.0, 1.0)),
        (r(0.0, 1.0, 0.3, 1.0), r(-0.5, 0.5, 0.2, 0.9)),
        (r(0.0, 2.0, 0.5, 0.7), r(0.5, 3.0, 0.0, 1.0)),
    ] {
        let reference = area_reference(&[piece(&rect_z(i, 0.0, false))], DVec3::Z, &rect_y0(j), 30);
        worst_b = worst_b.max(relative(perpendicular_rectangles(i, j), reference));
    }
    for deg in [1.0, 10.0, 45.0, 120.0, 170.0, 179.0] {
        let (i, j) = dihedral_pair(1.0, 1.0, 1.0, f64::to_radians(deg));
        let reference = area_reference(&[piece(&i)], normal(&i), &j, 30);
        worst_b = worst_b.max(relative(
            dihedral_reference(1.0, 1.0, 1.0, f64::to_radians(deg)),
            reference,
        ));
    }
    eprintln!("closed forms at offsets and reference A vs reference B: {worst_b:.1e}");
    assert!(worst_b < 1e-12, "{worst_b}");
}

/// Dihedral angles in degrees, 0.1° to 179.9° (the issue asks for 1° to 179°).
const ANGLES: [f64; 23] = [
    0.1, 1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0, 89.0, 90.0, 91.0, 105.0, 120.0,
    135.0, 150.0, 170.0, 175.0, 178.0, 179.0, 179.9,
];

#[test]
fn elements_sharing_an_edge_at_every_dihedral_angle() {
    // Reference A (eq. 12 reduced to one smooth dimension, tests/common). Rounding bounds what
    // any f64 evaluation of eq. 13 can reach: F_ij must be within the rounding floor (see
    // `rounding_floor`), which is 1e-14–1e-15 relative where F is O(0.1) and grows as F → 0
    // towards 180°.
    let (mut worst, mut worst_floor, mut worst_recip) = (0.0f64, 0.0f64, 0.0f64);
    for options in [
        ContourOptions::default(),
        ContourOptions {
            segments: 3,
            ..ContourOptions::default()
        },
    ] {
        for &(l, w, h) in &[
            (1.0, 1.0, 1.0),
            (1.0, 0.5, 2.0),
            (2.0, 1.0, 0.3),
            (0.3, 1.0, 1.0),
        ] {
            for deg in ANGLES {
                let phi = deg.to_radians();
                let (i, j) = dihedral_pair(l, w, h, phi);
                let (fij, fji) = both_ways(&i, &j, &options);
                assert!(fij.is_finite() && fji.is_finite() && fij > 0.0 && fji > 0.0);
                let reference = dihedral_reference(l, w, h, phi);
                let e = relative(fij, reference);
                let floors = (fij - reference).abs() / rounding_floor(&i, &j);
                if floors > worst_floor {
                    eprintln!(
                        "  {l}×{w} | {l}×{h} at {deg}°: F = {fij:.15e}, rel. error {e:.1e} \
                         ({floors:.3} × rounding floor)"
                    );
                }
                worst = worst.max(e);
                worst_floor = worst_floor.max(floors);
                worst_recip = worst_recip.max(reciprocity(&i, &j, fij, fji));
                assert!(
                    e < 1e-6 && floors < 1.0,
                    "{l} {w} {h} {deg}°: {e} ({floors})"
                );
            }
        }
    }
    eprintln!(
        "shared edge, 0.1°–179.9°: worst relative error {worst:.1e}, worst {worst_floor:.3} × \
         rounding floor, reciprocity {worst_recip:.1e}"
    );
    assert!(worst_recip < 1e-8, "{worst_recip}");
}

/// An orthonormal frame for a plane in a generic orientation (so that no coordinate is exact).
fn tilted_frame() -> (DVec3, DVec3, DVec3) {
    let n = v(1.0, 2.0, 3.0).normalize();
    let e1 = n.cross(v(0.3, -0.7, 0.2)).normalize();
    let e2 = n.cross(e1);
    (e1, e2, n)
}

fn in_plane(origin: DVec3, e1: DVec3, e2: DVec3, corners: &[(f64, f64)]) -> Vec<DVec3> {
    corners
        .iter()
        .map(|&(a, b)| origin + e1 * a + e2 * b)
        .collect()
}

fn quad_polygon(vertices: Vec<DVec3>, k: usize) -> Polygon {
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

#[test]
fn coplanar_neighbours_are_exactly_zero() {
    let o = ContourOptions::default();
    let (e1, e2, _) = tilted_frame();
    let square = |x: f64, y: f64, s: f64| [(x, y), (x + s, y), (x + s, y + s), (x, y + s)];
    for (scale, shift) in [
        (1.0, DVec3::ZERO),
        (1e-6, DVec3::ZERO),
        (1e6, DVec3::ZERO),
        (1.0, v(1e6, -2e6, 3e6)),
    ] {
        let at = |c: [(f64, f64); 4]| {
            let c: Vec<(f64, f64)> = c.iter().map(|&(a, b)| (a * scale, b * scale)).collect();
            in_plane(shift + v(0.1, 0.2, 0.3) * scale, e1, e2, &c)
        };
        let base = at(square(0.0, 0.0, 1.0));
        // Sharing an edge, a partial edge, touching at a corner, apart, and overlapping.
        for other in [
            square(1.0, 0.0, 1.0),
            square(1.0, 0.5, 0.3),
            square(1.0, 1.0, 1.0),
            square(3.0, -2.0, 0.5),
            square(0.5, 0.5, 1.0),
        ] {
            let (fij, fji) = both_ways(&base, &at(other), &o);
            assert_eq!(
                (fij, fji),
                (0.0, 0.0),
                "scale {scale}, shift {shift}, {other:?}"
            );
        }
        // The same as separate polygons of a mesh, and as elements of one polygon.
        let polygons = vec![
            quad_polygon(base.clone(), 0),
            quad_polygon(at(square(1.0, 0.0, 1.0)), 1),
            quad_polygon(at(square(0.0, 1.0, 2.0)), 2),
        ];
        let m = mesh(&polygons, Subdivision::Count(3)).expect("mesh");
        let f = FormFactors::new(&m, o).dense();
        assert!(
            f.data.iter().all(|&x| x == 0.0),
            "scale {scale}, shift {shift}"
        );
    }
    eprintln!("coplanar neighbours: all exactly 0");
}

#[test]
fn elements_touching_only_at_a_corner() {
    let o = ContourOptions::default();
    let mut worst: f64 = 0.0;
    let mut worst_recip: f64 = 0.0;
    // Perpendicular: the wall starts where the floor's edge ends (closed form).
    for (i, j) in [
        (r(0.0, 1.0, 0.0, 1.0), r(1.0, 2.0, 0.0, 1.0)),
        (r(0.0, 1.0, 0.0, 1.0), r(-0.5, 0.0, 0.0, 2.0)),
        (r(0.0, 0.2, 0.0, 3.0), r(0.2, 5.0, 0.0, 0.1)),
    ] {
        let (pi, pj) = (rect_z(i, 0.0, false), rect_y0(j));
        let (fij, fji) = both_ways(&pi, &pj, &o);
        assert!(fij.is_finite() && fij > 0.0);
        worst = worst.max(relative(fij, perpendicular_rectangles(i, j)));
        worst_recip = worst_recip.max(reciprocity(&pi, &pj, fij, fji));
    }
    // At other angles: the dihedral pair with j slid along the edge by its length, so that the
    // two touch at the point (l, 0, 0) only (reference B, graded towards i's corners).
    for deg in [30.0, 60.0, 120.0, 150.0] {
        let (i, j) = dihedral_pair(1.0, 1.0, 1.0, f64::to_radians(deg));
        let j: Vec<DVec3> = j.iter().map(|p| *p + DVec3::X).collect();
        let (fij, fji) = both_ways(&i, &j, &o);
        assert!(fij.is_finite() && fij > 0.0);
        let reference = area_reference(&[piece(&i)], DVec3::Z, &j, 30);
        worst = worst.max(relative(fij, reference));
        worst_recip = worst_recip.max(reciprocity(&i, &j, fij, fji));
    }
    eprintln!(
        "touching at a corner: worst relative error {worst:.1e}, reciprocity {worst_recip:.1e}"
    );
    assert!(worst < 1e-10, "{worst}");
    assert!(worst_recip < 1e-12, "{worst_recip}");
}

#[test]
fn collinear_edges_of_different_lengths_partial_overlaps_and_t_junctions() {
    let o = ContourOptions::default();
    let floor = r(0.0, 1.0, 0.0, 1.0);
    let mut worst: f64 = 0.0;
    let mut worst_recip: f64 = 0.0;
    // Perpendicular walls on the floor's edge line (closed form by superposition).
    for wall in [
        r(0.25, 0.5, 0.0, 1.0), // shorter edge, inside the floor's
        r(-0.5, 1.5, 0.0, 1.0), // longer edge, past both ends
        r(0.0, 2.0, 0.0, 0.5),  // longer, one end shared
        r(0.5, 1.5, 0.0, 1.0),  // partial overlap
        r(-0.7, 0.3, 0.0, 0.2), // partial overlap, other end
        r(0.0, 0.5, 0.0, 1.0),  // T-junction halves
        r(0.5, 1.0, 0.0, 1.0),
    ] {
        let (pi, pj) = (rect_z(floor, 0.0, false), rect_y0(wall));
        let (fij, fji) = both_ways(&pi, &pj, &o);
        worst = worst.max(relative(fij, perpendicular_rectangles(floor, wall)));
        worst_recip = worst_recip.max(reciprocity(&pi, &pj, fij, fji));
    }
    // T-junction: one long edge (the floor's) against two short ones (the wall's halves): the
    // halves sum to the whole (C-14), seen from either side.
    let pf = rect_z(floor, 0.0, false);
    let halves = [
        rect_y0(r(0.0, 0.5, 0.0, 1.0)),
        rect_y0(r(0.5, 1.0, 0.0, 1.0)),
    ];
    let whole = perpendicular_shared_edge(1.0, 1.0, 1.0);
    let sum: f64 = halves.iter().map(|h| polygon_pair(&pf, h, &o)).sum();
    worst = worst.max(relative(sum, whole));
    let from_halves: f64 = halves
        .iter()
        .map(|h| polygon_pair(h, &pf, &o) * area(h))
        .sum();
    worst = worst.max(relative(from_halves, whole));
    // Non-perpendicular: a wall at 60° whose edge covers [0.5, 1.5] of the floor's [0, 1]
    // (reference B with the floor split at x = 0.5, where the wall's corner touches its edge).
    for deg in [60.0, 135.0] {
        let (i, j) = dihedral_pair(1.0, 1.0, 1.0, f64::to_radians(deg));
        let j: Vec<DVec3> = j.iter().map(|p| *p + DVec3::X * 0.5).collect();
        let (fij, fji) = both_ways(&i, &j, &o);
        let pieces = [
            piece(&rect_z(r(0.0, 0.5, 0.0, 1.0), 0.0, false)),
            piece(&rect_z(r(0.5, 1.0, 0.0, 1.0), 0.0, false)),
        ];
        worst = worst.max(relative(fij, area_reference(&pieces, DVec3::Z, &j, 30)));
        worst_recip = worst_recip.max(reciprocity(&i, &j, fij, fji));
    }
    eprintln!(
        "collinear edges, partial overlaps, T-junctions: worst relative error {worst:.1e}, \
         reciprocity {worst_recip:.1e}"
    );
    assert!(worst < 1e-10, "{worst}");
    assert!(worst_recip < 1e-12, "{worst_recip}");
}

/// `(I − diag(ρ) F) b = e` by Gaussian elimination with partial pivoting (n is small).
fn solve_radiosity(f: &[f64], n: usize, rho: &[f64], e: &[f64]) -> Vec<f64> {
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            a[i * n + j] = f64::from(u8::from(i == j)) - rho[i] * f[i * n + j];
        }
    }
    let mut b = e.to_vec();
    for k in 0..n {
        let p = (k..n)
            .max_by(|&x, &y| a[x * n + k].abs().total_cmp(&a[y * n + k].abs()))
            .unwrap_or(k);
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
            b.swap(k, p);
        }
        for i in k + 1..n {
            let m = a[i * n + k] / a[k * n + k];
            for j in k..n {
                a[i * n + j] -= m * a[k * n + j];
            }
            b[i] -= m * b[k];
        }
    }
    for k in (0..n).rev() {
        let s: f64 = (k + 1..n).map(|j| a[k * n + j] * b[j]).sum();
        b[k] = (b[k] - s) / a[k * n + k];
    }
    b
}

/// The six inward walls of a box with unequal, non-dyadic sides (so that scaled and shifted
/// coordinates round), one corner at `corner`.
fn box_walls(corner: DVec3, size: DVec3) -> Vec<Polygon> {
    reference::box_walls(corner, size)
        .iter()
        .enumerate()
        .map(|(k, w)| quad_polygon(w.to_vec(), k))
        .collect()
}

#[test]
fn radiosities_do_not_depend_on_scale_or_position() {
    // A closed box (convex, so unoccluded), one emitting wall, a different ρ per wall.
    let size = v(1.0, 0.7, 1.3);
    let corner = v(0.1, 0.2, 0.3);
    let rho_wall = [0.5, 0.8, 0.9, 0.3, 0.7, 0.6];
    let bake = |scale: f64, shift: DVec3| {
        let polygons = box_walls(corner * scale + shift, size * scale);
        let m = mesh(&polygons, Subdivision::Count(4)).expect("mesh");
        let f = FormFactors::new(&m, ContourOptions::default()).dense();
        let rho: Vec<f64> = m
            .elements
            .iter()
            .map(|e| rho_wall[e.polygon as usize])
            .collect();
        let e: Vec<f64> = m
            .elements
            .iter()
            .map(|e| f64::from(u8::from(e.polygon == 1)))
            .collect();
        let worst_row = f
            .row_sums()
            .iter()
            .map(|s| (s - 1.0).abs())
            .fold(0.0, f64::max);
        (solve_radiosity(&f.data, f.n, &rho, &e), worst_row)
    };
    let (unit, row) = bake(1.0, DVec3::ZERO);
    eprintln!(
        "box at unit scale: {} elements, worst |row sum − 1| {row:.1e}",
        unit.len()
    );
    assert!(row < 1e-12, "{row}");
    let mut worst_all: f64 = 0.0;
    for (scale, shift) in [
        (1e-6, DVec3::ZERO),
        (1e6, DVec3::ZERO),
        (1.0, v(1e6, -2e6, 3e6)),
    ] {
        let (b, row) = bake(scale, shift);
        let worst = b
            .iter()
            .zip(&unit)
            .map(|(x, y)| (x - y).abs() / y.abs())
            .fold(0.0, f64::max);
        eprintln!("scale {scale:e}, shift {shift}: worst relative change of b {worst:.1e}, row sums {row:.1e}");
        worst_all = worst_all.max(worst);
    }
    assert!(worst_all < 1e-9, "{worst_all}");
}

/// Perimeter of a polygon.
fn perimeter(p: &[DVec3]) -> f64 {
    (0..p.len())
        .map(|k| p[k].distance(p[(k + 1) % p.len()]))
        .sum()
}

/// The rounding floor of eq. 13 for a pair, as a bound on |ΔF_ij|: the double contour sum adds
/// edge-pair terms of size ~ l_a l_b |ln r| (pair frame, ln r = O(1)), each good to a few ε,
/// and their sum is A_i F_ij; so A_i F_ij cannot be better than ~4 ε P_i P_j (perimeters),
/// whatever the quadrature. Thin and grazing pairs, whose A_i F_ij is far below P_i P_j, lose
/// relative digits to it.
fn rounding_floor(i: &[DVec3], j: &[DVec3]) -> f64 {
    4.0 * f64::EPSILON * perimeter(i) * perimeter(j) / area(i)
}

/// Checks F_ij of every case against its reference: relative error ≤ `bound` and absolute
/// error within the rounding floor; and A_i F_ij against A_j F_ji (integrated on its own), each
/// within the floor of the truth, and A_i × floor(i, j) = A_j × floor(j, i) = 4 ε P_i P_j.
fn check_cases(what: &str, cases: &[(&str, Vec<DVec3>, Vec<DVec3>, f64)], bound: f64) {
    let o = ContourOptions::default();
    let (mut worst, mut worst_floor, mut worst_recip) = (0.0f64, 0.0f64, 0.0f64);
    for (name, i, j, reference) in cases {
        let (fij, fji) = both_ways(i, j, &o);
        assert!(fij.is_finite() && fij > 0.0, "{name}: {fij}");
        let e = relative(fij, *reference);
        let floors = (fij - reference).abs() / rounding_floor(i, j);
        let rc = reciprocity(i, j, fij, fji);
        eprintln!(
            "  {name}: F = {fij:.6e}, rel. error {e:.1e} ({floors:.1e} × rounding floor), \
             reciprocity {rc:.1e}"
        );
        worst = worst.max(e);
        worst_floor = worst_floor.max(floors);
        worst_recip = worst_recip.max(rc);
        assert!(e < bound, "{name}: {e}");
        assert!(floors < 1.0, "{name}: {floors}");
        let allowed = 2.0 * area(i) * rounding_floor(i, j);
        assert!(
            (area(i) * fij - area(j) * fji).abs() <= allowed,
            "{name}: {rc}"
        );
    }
    eprintln!(
        "{what}: worst relative error {worst:.1e}, worst {worst_floor:.1e} × rounding floor, \
         reciprocity {worst_recip:.1e}"
    );
}

#[test]
fn very_thin_elements() {
    // Aspect ratio 1:10⁴ (references: reference B, graded towards every edge of i; it agrees
    // with the closed forms evaluated in 50-digit arithmetic, which lose digits in f64 here).
    let t = 1e-4;
    let perpendicular = |name, i: Rect, j: Rect| {
        let (pi, pj) = (rect_z(i, 0.0, false), rect_y0(j));
        let reference = area_reference(&[piece(&pi)], DVec3::Z, &pj, 30);
        (name, pi, pj, reference)
    };
    let parallel = |name, i: Rect, j: Rect, c: f64, pieces: &[Rect]| {
        let (pi, pj) = (rect_z(i, 0.0, false), rect_z(j, c, true));
        let pieces: Vec<[DVec3; 4]> = pieces
            .iter()
            .map(|&p| piece(&rect_z(p, 0.0, false)))
            .collect();
        let reference = area_reference(&pieces, DVec3::Z, &pj, 30);
        (name, pi, pj, reference)
    };
    let cases = [
        perpendicular(
            "strip on a wall, long edge shared",
            r(0.0, 1.0, 0.0, t),
            r(0.0, 1.0, 0.0, 1.0),
        ),
        perpendicular(
            "wall strip seen from a square",
            r(0.0, 1.0, 0.0, 1.0),
            r(0.0, 1.0, 0.0, t),
        ),
        perpendicular(
            "strip against a strip, long edge",
            r(0.0, 1.0, 0.0, t),
            r(0.0, 1.0, 0.0, t),
        ),
        perpendicular(
            "strip against a strip, short edge",
            r(0.0, t, 0.0, 1.0),
            r(0.0, t, 0.0, 1.0),
        ),
        perpendicular(
            "strip against a wall, short edge",
            r(0.0, t, 0.0, 1.0),
            r(0.0, 1.0, 0.0, 1.0),
        ),
        perpendicular(
            "strips touching at a corner",
            r(0.0, 1.0, 0.0, t),
            r(1.0, 2.0, 0.0, t),
        ),
        perpendicular(
            "strips apart",
            r(0.0, 1.0, 0.5, 0.5 + t),
            r(0.0, 1.0, 0.3, 0.3 + t),
        ),
        parallel(
            "opposed strips",
            r(0.0, 1.0, 0.0, t),
            r(0.0, 1.0, 0.0, t),
            1.0,
            &[r(0.0, 1.0, 0.0, t)],
        ),
        parallel(
            "opposed strips, one width apart",
            r(0.0, 1.0, 0.0, t),
            r(0.0, 1.0, 0.0, t),
            t,
            &[r(0.0, 1.0, 0.0, t)],
        ),
        parallel(
            "strip under a square",
            r(0.0, 1.0, 0.0, t),
            r(0.0, 1.0, 0.0, 1.0),
            0.1,
            &[r(0.0, 1.0, 0.0, t)],
        ),
        parallel(
            "crossed strips",
            r(0.0, 1.0, 0.0, t),
            r(0.5, 0.5 + t, -0.5, 0.5),
            0.01,
            &[
                r(0.0, 0.5, 0.0, t),
                r(0.5, 0.5 + t, 0.0, t),
                r(0.5 + t, 1.0, 0.0, t),
            ],
        ),
    ];
    check_cases("thin elements (1:10⁴)", &cases, 1e-6);
}

#[test]
fn near_grazing_pairs() {
    // Each sees the other (or one sees the other) at a small angle; F is small and carried by
    // the tiny cosines, so quadrature errors that are negligible elsewhere would dominate.
    let floor = r(0.0, 1.0, 0.0, 1.0);
    let mut cases = Vec::new();
    for (name, j, c) in [
        ("parallel, 10⁻³ apart, 1 aside", r(2.0, 3.0, 0.0, 1.0), 1e-3),
        (
            "parallel, 10⁻² apart, 9 aside",
            r(10.0, 11.0, 0.0, 1.0),
            1e-2,
        ),
        (
            "parallel, 10⁻⁴ apart, 0.1 aside",
            r(1.1, 2.1, 0.2, 0.8),
            1e-4,
        ),
    ] {
        let (pi, pj) = (rect_z(floor, 0.0, false), rect_z(j, c, true));
        let reference = area_reference(&[piece(&pi)], DVec3::Z, &pj, 30);
        cases.push((name, pi, pj, reference));
    }
    for (name, i, j) in [
        (
            "low wall, 1 away",
            r(0.0, 1.0, 1.0, 2.0),
            r(0.0, 1.0, 0.0, 1e-3),
        ),
        (
            "low wall, 5 away",
            r(0.0, 1.0, 5.0, 6.0),
            r(0.0, 1.0, 0.0, 1e-3),
        ),
        ("low wall, 3 aside", floor, r(3.0, 4.0, 0.0, 1e-3)),
        (
            "raised low wall",
            r(0.0, 1.0, 0.5, 1.0),
            r(-1.0, 2.0, 0.3, 0.3001),
        ),
    ] {
        let (pi, pj) = (rect_z(i, 0.0, false), rect_y0(j));
        let reference = area_reference(&[piece(&pi)], DVec3::Z, &pj, 30);
        cases.push((name, pi, pj, reference));
    }
    // Nearly coplanar, apart: j is the square [1.25, 2.25] × [0, 1] folded up about the line
    // x = 1.25 by a small angle δ, its normal (−sin δ, 0, cos δ) tipped towards i.
    for delta in [1e-2, 1e-4] {
        let (s, c) = f64::sin_cos(delta);
        let pj: Vec<DVec3> = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
            .iter()
            .map(|&(a, y)| v(1.25 + a * c, y, a * s))
            .collect();
        let pi = rect_z(floor, 0.0, false);
        let reference = area_reference(&[piece(&pi)], DVec3::Z, &pj, 30);
        let name = if delta > 1e-3 {
            "folded by 10⁻²"
        } else {
            "folded by 10⁻⁴"
        };
        cases.push((name, pi, pj, reference));
    }
    check_cases("near-grazing pairs", &cases, 1e-6);
}
