//! Form factors against closed forms (Howell's catalogue of configuration factors, cases
//! C-11 and C-14) and the identities of the paper (eqs. 14–16).

use bake_form_factor::{polygon_pair, ContourOptions, FormFactors};
use glam::DVec3;
use importer::{Origin, Polygon, Side};
use mesher::{mesh, Subdivision};
use reference::{parallel_opposed, perpendicular_shared_edge};

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn floor(w: f64, l: f64) -> Vec<DVec3> {
    // z = 0, x ∈ [0, l], y ∈ [0, w], facing +z.
    vec![
        v(0.0, 0.0, 0.0),
        v(l, 0.0, 0.0),
        v(l, w, 0.0),
        v(0.0, w, 0.0),
    ]
}

fn wall(l: f64, z0: f64, z1: f64) -> Vec<DVec3> {
    // y = 0, x ∈ [0, l], z ∈ [z0, z1], facing +y.
    vec![
        v(0.0, 0.0, z0),
        v(0.0, 0.0, z1),
        v(l, 0.0, z1),
        v(l, 0.0, z0),
    ]
}

fn ceiling(a: f64, b: f64, c: f64) -> Vec<DVec3> {
    // z = c, facing −z.
    vec![v(0.0, 0.0, c), v(0.0, b, c), v(a, b, c), v(a, 0.0, c)]
}

#[test]
fn opposed_unit_squares_one_apart() {
    let f = polygon_pair(
        &floor(1.0, 1.0),
        &ceiling(1.0, 1.0, 1.0),
        &ContourOptions::default(),
    );
    assert!((f - 0.19982).abs() < 1e-5, "{f}");
    assert!((f - parallel_opposed(1.0, 1.0, 1.0)).abs() < 1e-10, "{f}");
}

#[test]
fn opposed_rectangles_at_several_distances() {
    for &(a, b, c) in &[
        (1.0, 2.0, 0.1),
        (3.0, 0.5, 1.0),
        (1.0, 1.0, 10.0),
        (0.2, 0.3, 0.05),
    ] {
        let f = polygon_pair(&floor(b, a), &ceiling(a, b, c), &ContourOptions::default());
        let exact = parallel_opposed(a, b, c);
        assert!(
            (f - exact).abs() < 1e-9 * exact.max(1e-3),
            "{a} {b} {c}: {f} vs {exact}"
        );
    }
}

#[test]
fn perpendicular_unit_squares_sharing_an_edge() {
    let f = polygon_pair(
        &floor(1.0, 1.0),
        &wall(1.0, 0.0, 1.0),
        &ContourOptions::default(),
    );
    assert!((f - 0.20004).abs() < 1e-5, "{f}");
    assert!(
        (f - perpendicular_shared_edge(1.0, 1.0, 1.0)).abs() < 1e-10,
        "{f}"
    );
}

#[test]
fn perpendicular_rectangles_sharing_an_edge() {
    for &(l, w, h) in &[(1.0, 0.5, 2.0), (2.0, 1.0, 0.1), (0.1, 3.0, 1.0)] {
        let f = polygon_pair(&floor(w, l), &wall(l, 0.0, h), &ContourOptions::default());
        let exact = perpendicular_shared_edge(l, w, h);
        assert!(
            (f - exact).abs() < 1e-9 * exact,
            "{l} {w} {h}: {f} vs {exact}"
        );
    }
}

#[test]
fn a_square_partly_behind_the_others_plane_counts_only_its_front_part() {
    // The wall reaches from z = −0.5 to 0.5: only z ∈ [0, 0.5] is in front of the floor.
    let f = polygon_pair(
        &floor(1.0, 1.0),
        &wall(1.0, -0.5, 0.5),
        &ContourOptions::default(),
    );
    let exact = perpendicular_shared_edge(1.0, 1.0, 0.5);
    assert!((f - exact).abs() < 1e-10, "{f} vs {exact}");
    // Seen from the wall (area 1, same as the floor): F_wall→floor = F_floor→wall by eq. 14.
    let back = polygon_pair(
        &wall(1.0, -0.5, 0.5),
        &floor(1.0, 1.0),
        &ContourOptions::default(),
    );
    assert!((back - exact).abs() < 1e-10, "{back} vs {exact}");
}

#[test]
fn coplanar_back_facing_and_self_are_exactly_zero() {
    let o = ContourOptions::default();
    let neighbour: Vec<DVec3> = floor(1.0, 1.0).iter().map(|p| *p + DVec3::X).collect();
    assert_eq!(polygon_pair(&floor(1.0, 1.0), &neighbour, &o), 0.0);
    // A ceiling facing up (away from the floor) and a floor facing away from a ceiling.
    let up: Vec<DVec3> = ceiling(1.0, 1.0, 1.0).into_iter().rev().collect();
    assert_eq!(polygon_pair(&floor(1.0, 1.0), &up, &o), 0.0);
    let below: Vec<DVec3> = ceiling(1.0, 1.0, -1.0);
    assert_eq!(polygon_pair(&floor(1.0, 1.0), &below, &o), 0.0);
    let m = form_factor_mesh_of_cube(2);
    assert_eq!(FormFactors::new(&m, o).pair(3, 3), 0.0);
}

fn cube_polygons() -> Vec<Polygon> {
    let origin = |k| Origin {
        node: k,
        mesh: k,
        primitive: 0,
        face: 0,
        side: Side::Front,
    };
    let quad = |k: usize, c: [DVec3; 4]| {
        let normal = (c[1] - c[0]).cross(c[2] - c[0]).normalize();
        Polygon {
            vertices: c.to_vec(),
            normal,
            material: 0,
            origin: origin(k),
        }
    };
    vec![
        quad(
            0,
            [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)],
        ), // z=0, +z
        quad(
            1,
            [v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)],
        ), // z=1, −z
        quad(
            2,
            [v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)],
        ), // x=0, +x
        quad(
            3,
            [v(1., 0., 0.), v(1., 0., 1.), v(1., 1., 1.), v(1., 1., 0.)],
        ), // x=1, −x
        quad(
            4,
            [v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)],
        ), // y=0, +y
        quad(
            5,
            [v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)],
        ), // y=1, −y
    ]
}

fn form_factor_mesh_of_cube(n: u32) -> mesher::ElementMesh {
    let polygons = cube_polygons();
    for p in &polygons {
        // Every wall faces the cube's centre.
        assert!((DVec3::splat(0.5) - p.vertices[0]).dot(p.normal) > 0.0);
    }
    mesh(&polygons, Subdivision::Count(n)).unwrap()
}

#[test]
fn rows_of_the_closed_cube_sum_to_one_at_every_subdivision() {
    for n in 1..=8 {
        let m = form_factor_mesh_of_cube(n);
        let f = FormFactors::new(&m, ContourOptions::default()).dense();
        let worst = f
            .row_sums()
            .iter()
            .map(|s| (s - 1.0).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "subdiv {n}: {} elements, max |row sum − 1| = {worst:.3e}",
            f.n
        );
        // ≤ 3.5e-15 measured (1.5e-10 with the paper's fixed order 3 for separated pairs).
        assert!(worst < 1e-12, "subdiv {n}: {worst}");
    }
}

#[test]
fn dense_matrix_is_reciprocal_and_agrees_with_single_pairs() {
    // Unequal element areas: a 1 × 0.5 × 2 box meshed with max element size.
    let mut polygons = cube_polygons();
    for p in &mut polygons {
        for x in &mut p.vertices {
            *x *= v(1.0, 0.5, 2.0);
        }
    }
    let m = mesh(&polygons, Subdivision::MaxSize(0.3)).unwrap();
    let ff = FormFactors::new(&m, ContourOptions::default());
    let f = ff.dense();
    let a: Vec<f64> = m.elements.iter().map(|e| e.area).collect();
    let mut worst_recip: f64 = 0.0;
    let mut worst_direction: f64 = 0.0;
    for i in 0..f.n {
        for j in 0..f.n {
            let (gij, gji) = (a[i] * f.get(i, j), a[j] * f.get(j, i));
            worst_recip = worst_recip.max((gij - gji).abs() / gij.abs().max(1e-300));
            assert!(f.get(i, j) >= 0.0);
        }
    }
    for (i, j) in [(0, 5), (3, 40), (17, 2), (9, f.n - 1)] {
        let (fij, fji) = (ff.pair(i, j), ff.pair(j, i));
        worst_direction =
            worst_direction.max((a[i] * fij - a[j] * fji).abs() / (a[i] * fij).max(1e-300));
        assert!((fij - f.get(i, j)).abs() <= 1e-15 * fij.max(1.0));
    }
    eprintln!(
        "reciprocity (dense) {worst_recip:.2e}, independent directions {worst_direction:.2e}"
    );
    assert!(worst_recip < 1e-12);
    assert!(worst_direction < 1e-9);
    let worst_sum = f
        .row_sums()
        .iter()
        .map(|s| (s - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(worst_sum < 1e-12, "{worst_sum}");
}
