//! The axis-aligned references against Howell's values, the identities of the paper (eqs. 14–16),
//! a brute-force quadrature of the area integral (eq. 12) and, as a cross-check, the contour
//! integrator.

use bake_reference::{
    axis_aligned_rectangles, dense_form_factors, gauss_legendre, parallel_opposed,
    perpendicular_shared_edge, unit_cube_walls,
};
use form_factor::{ContourOptions, FormFactors};
use glam::DVec3;
use importer::{Origin, Polygon, Side};
use mesher::{mesh, ElementMesh, Subdivision};
use std::f64::consts::PI;

/// Unit squares one apart, directly opposed (Howell C-11).
const OPPOSED: f64 = 0.19982489569838746;
/// Unit squares sharing an edge at a right angle (Howell C-14).
const SHARED_EDGE: f64 = 0.20004377607540316;

/// The 48 symmetries of the cube as maps of a quad: `q[perm[k]] = sign[k] p[k]`, the vertex
/// order reversed when the map reverses orientation (so the front side maps to the front side).
fn symmetries() -> Vec<impl Fn(&[DVec3]) -> Vec<DVec3>> {
    let mut maps = Vec::new();
    for p in 0..6 {
        // Cyclic shifts (even) and, for p ≥ 3, a shift followed by a swap (odd).
        let (first, odd) = (p % 3, p >= 3);
        let (second, third) = if odd { (2, 1) } else { (1, 2) };
        let perm = [first, (first + second) % 3, (first + third) % 3];
        for bits in 0..8 {
            let sign = [0, 1, 2].map(|k| if bits >> k & 1 == 1 { -1.0 } else { 1.0 });
            let reverses = odd != (sign.iter().product::<f64>() < 0.0);
            maps.push(move |quad: &[DVec3]| {
                let mut out: Vec<DVec3> = quad
                    .iter()
                    .map(|q| {
                        let mut r = DVec3::ZERO;
                        for k in 0..3 {
                            r[perm[k]] = sign[k] * q[k];
                        }
                        r
                    })
                    .collect();
                if reverses {
                    out.reverse();
                }
                out
            });
        }
    }
    maps
}

#[test]
fn the_constants_are_howells() {
    assert!((parallel_opposed(1.0, 1.0, 1.0) - OPPOSED).abs() < 1e-15);
    assert!((perpendicular_shared_edge(1.0, 1.0, 1.0) - SHARED_EDGE).abs() < 1e-15);
}

#[test]
fn unit_cube_walls_in_every_orientation() {
    let walls = unit_cube_walls();
    let mut worst = 0.0f64;
    for map in symmetries() {
        for (i, a) in walls.iter().enumerate() {
            for (j, b) in walls.iter().enumerate() {
                let f = axis_aligned_rectangles(&map(a), &map(b)).expect("rectangles");
                let exact = match (i == j, i / 2 == j / 2) {
                    (true, _) => 0.0,
                    (false, true) => OPPOSED,
                    (false, false) => SHARED_EDGE,
                };
                worst = worst.max((f - exact).abs());
                // Seen from outside (walls facing out) no wall sees another.
                let out = |q: &[DVec3]| q.iter().rev().copied().collect::<Vec<_>>();
                let back = axis_aligned_rectangles(&out(&map(a)), &out(&map(b)));
                assert_eq!(back, Some(0.0), "walls {i} {j} facing out");
            }
        }
    }
    println!("worst |F − Howell| over 48 × 36 wall pairs: {worst:.1e}");
    assert!(worst < 1e-12, "{worst}");
}

#[test]
fn scaled_and_translated_cubes_keep_their_form_factors() {
    let walls = unit_cube_walls();
    for (scale, shift) in [
        (1e-3, DVec3::new(5.0, -7.0, 0.25)),
        (40.0, DVec3::new(-1e3, 3e2, 17.0)),
        (2.5, DVec3::new(1e4, 1e4, -1e4)),
    ] {
        let place = |q: &[DVec3; 4]| q.map(|p| p * scale + shift);
        let f = |i: usize, j: usize| {
            axis_aligned_rectangles(&place(&walls[i]), &place(&walls[j])).expect("rectangles")
        };
        assert!((f(0, 1) - OPPOSED).abs() < 1e-12, "{scale}: {}", f(0, 1));
        assert!(
            (f(2, 4) - SHARED_EDGE).abs() < 1e-12,
            "{scale}: {}",
            f(2, 4)
        );
    }
}

/// `[x0, x1] × [y0, y1]` in the plane z = `z`, facing +z (or −z if `down`).
fn floor_at(x: [f64; 2], y: [f64; 2], z: f64, down: bool) -> Vec<DVec3> {
    let q = vec![
        DVec3::new(x[0], y[0], z),
        DVec3::new(x[1], y[0], z),
        DVec3::new(x[1], y[1], z),
        DVec3::new(x[0], y[1], z),
    ];
    if down {
        q.into_iter().rev().collect()
    } else {
        q
    }
}

/// `[x0, x1] × [z0, z1]` in the plane y = `y`, facing +y.
fn wall_at(x: [f64; 2], y: f64, z: [f64; 2]) -> Vec<DVec3> {
    vec![
        DVec3::new(x[0], y, z[0]),
        DVec3::new(x[0], y, z[1]),
        DVec3::new(x[1], y, z[1]),
        DVec3::new(x[1], y, z[0]),
    ]
}

#[test]
fn pairs_that_cannot_see_each_other_are_exactly_zero() {
    let a = floor_at([0.0, 1.0], [0.0, 1.0], 0.0, false);
    let cases = [
        ("same plane", floor_at([2.0, 3.0], [0.0, 1.0], 0.0, false)),
        (
            "same plane, facing down",
            floor_at([0.5, 3.0], [0.0, 1.0], 0.0, true),
        ),
        (
            "parallel, facing away",
            floor_at([0.0, 1.0], [0.0, 1.0], 1.0, false),
        ),
        (
            "parallel, behind",
            floor_at([0.0, 1.0], [0.0, 1.0], -1.0, true),
        ),
        (
            "perpendicular, below",
            wall_at([0.0, 1.0], 0.5, [-1.0, 0.0]),
        ),
        (
            "perpendicular, facing away",
            wall_at([0.0, 1.0], 1.0, [0.0, 1.0]),
        ),
    ];
    for (name, b) in cases {
        assert_eq!(axis_aligned_rectangles(&a, &b), Some(0.0), "{name}: a → b");
        assert_eq!(axis_aligned_rectangles(&b, &a), Some(0.0), "{name}: b → a");
    }
}

#[test]
fn inputs_that_are_not_axis_aligned_rectangles_are_refused() {
    let a = floor_at([0.0, 1.0], [0.0, 1.0], 0.0, false);
    let tilted: Vec<DVec3> = a.iter().map(|p| *p + DVec3::Z * (0.1 * p.x)).collect();
    let trapezoid = {
        let mut q = a.clone();
        q[2].x = 0.8;
        q
    };
    let bow_tie = vec![a[0], a[2], a[1], a[3]];
    let nan = {
        let mut q = a.clone();
        q[1].y = f64::NAN;
        q
    };
    let slightly_off = {
        let mut q = a.clone();
        q[2].z = 1e-9;
        q
    };
    let cases = [
        ("triangle", a[..3].to_vec()),
        ("tilted", tilted),
        ("trapezoid", trapezoid),
        ("bow tie", bow_tie),
        ("NaN", nan),
        ("off its plane by 1e-9", slightly_off),
        ("a line", vec![a[0], a[1], a[1], a[0]]),
    ];
    for (name, b) in cases {
        assert_eq!(axis_aligned_rectangles(&a, &b), None, "{name}");
        assert_eq!(axis_aligned_rectangles(&b, &a), None, "{name}");
    }
    // Within the tolerance (1e-12 of the size) a vertex still counts as on the corner.
    let mut close = a.clone();
    close[2].z = 1e-14;
    let ceiling = floor_at([0.0, 1.0], [0.0, 1.0], 1.0, true);
    let f = axis_aligned_rectangles(&close, &ceiling).expect("within tolerance");
    assert!((f - OPPOSED).abs() < 1e-12, "{f}");
}

fn cube_polygons() -> Vec<Polygon> {
    let wall = |(k, c): (usize, &[DVec3; 4])| {
        let origin = Origin {
            node: 0,
            mesh: 0,
            primitive: 0,
            face: k,
            side: Side::Front,
        };
        let normal = (c[1] - c[0]).cross(c[2] - c[1]).normalize();
        Polygon {
            vertices: c.to_vec(),
            normal,
            material: 0,
            origin,
        }
    };
    unit_cube_walls().iter().enumerate().map(wall).collect()
}

fn cube_mesh(k: u32) -> ElementMesh {
    mesh(&cube_polygons(), Subdivision::Count(k)).expect("mesh")
}

#[test]
fn cube_rows_sum_to_one_with_reciprocity() {
    for k in 1..=6 {
        let m = cube_mesh(k);
        let n = m.elements.len();
        assert_eq!(n, 6 * (k * k) as usize);
        let f = dense_form_factors(&m).expect("rectangles");
        assert_eq!(f.len(), n * n);
        let (mut worst_sum, mut worst_reciprocity) = (0.0f64, 0.0f64);
        for i in 0..n {
            let row = &f[i * n..(i + 1) * n];
            assert!(row.iter().all(|&x| x >= 0.0), "subdivision {k}: row {i}");
            assert_eq!(row[i], 0.0);
            worst_sum = worst_sum.max((row.iter().sum::<f64>() - 1.0).abs());
            for j in 0..n {
                let (ai, aj) = (m.elements[i].area, m.elements[j].area);
                let g = (ai * f[i * n + j] - aj * f[j * n + i]).abs();
                worst_reciprocity = worst_reciprocity.max(g / (ai * aj));
            }
        }
        println!(
            "subdivision {k}: {n} elements, worst |Σ_j F_ij − 1| = {worst_sum:.1e}, \
             worst |A_i F_ij − A_j F_ji| / (A_i A_j) = {worst_reciprocity:.1e}"
        );
        assert!(worst_sum < 1e-12, "subdivision {k}: {worst_sum}");
        assert!(
            worst_reciprocity < 1e-13,
            "subdivision {k}: {worst_reciprocity}"
        );
        if k == 1 {
            assert!((f[1] - OPPOSED).abs() < 1e-12 && (f[2] - SHARED_EDGE).abs() < 1e-12);
        }
    }
}

#[test]
fn meshes_with_other_elements_are_refused() {
    let mut m = cube_mesh(2);
    m.elements[3].sides = 3;
    assert_eq!(dense_form_factors(&m), None);
    let mut m = cube_mesh(2);
    m.elements[5].corners[2] = m.vertices.len() as u32;
    assert_eq!(dense_form_factors(&m), None);
    let mut m = cube_mesh(2);
    m.vertices[0].x += 0.1;
    assert_eq!(dense_form_factors(&m), None);
}

#[test]
fn the_contour_integrator_agrees_on_the_cube() {
    let m = cube_mesh(3);
    let exact = dense_form_factors(&m).expect("rectangles");
    let contour = FormFactors::new(&m, ContourOptions::default()).dense();
    assert_eq!(contour.data.len(), exact.len());
    let worst = exact
        .iter()
        .zip(&contour.data)
        .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
    println!("subdivision 3: worst |F_contour − F_closed| = {worst:.1e}");
    assert!(worst < 1e-9, "{worst}");
}

// ---------------------------------------------------------------------------------------------
// Brute force: eq. 12 by a tensor Gauss–Legendre rule over both rectangles.
// ---------------------------------------------------------------------------------------------

/// Unit normal by the right-hand rule on the vertex order.
fn front(q: &[DVec3]) -> DVec3 {
    (q[1] - q[0]).cross(q[2] - q[1]).normalize()
}

/// Points of the parallelogram `q` as `q0 + u (q1 − q0) + w (q3 − q0)` and the breakpoints in
/// u and in w where it crosses the plane of `other` (where the clamped cosine has its kink).
fn breakpoints(q: &[DVec3], other: &[DVec3]) -> [Vec<f64>; 2] {
    let n = front(other);
    let edges = [q[1] - q[0], q[3] - q[0]];
    [0, 1].map(|k| {
        let mut t = vec![0.0, 1.0];
        if n.dot(edges[1 - k]) == 0.0 && n.dot(edges[k]) != 0.0 {
            let cross = n.dot(other[0] - q[0]) / n.dot(edges[k]);
            if cross > 0.0 && cross < 1.0 {
                t.insert(1, cross);
            }
        }
        t
    })
}

/// F_ab = 1/A_a ∫∫ max(cos θ_a, 0) max(cos θ_b, 0) / (π r²) dA_a dA_b by `order` Gauss–Legendre
/// points per piece in each of the four parameters.
fn brute_force(a: &[DVec3], b: &[DVec3], order: usize) -> f64 {
    let rule = gauss_legendre(order);
    let nodes = |breaks: &[f64]| -> Vec<(f64, f64)> {
        breaks
            .windows(2)
            .flat_map(|w| {
                let (m, h) = (0.5 * (w[0] + w[1]), 0.5 * (w[1] - w[0]));
                rule.iter().map(move |&(x, wt)| (m + h * x, h * wt))
            })
            .collect()
    };
    let points = |q: &[DVec3], other: &[DVec3]| -> Vec<(DVec3, f64)> {
        let [bu, bw] = breakpoints(q, other);
        let (eu, ew) = (q[1] - q[0], q[3] - q[0]);
        let area = eu.cross(ew).length();
        let mut out = Vec::new();
        for &(u, wu) in &nodes(&bu) {
            for &(w, ww) in &nodes(&bw) {
                out.push((q[0] + eu * u + ew * w, wu * ww * area));
            }
        }
        out
    };
    let (na, nb) = (front(a), front(b));
    let (pa, pb) = (points(a, b), points(b, a));
    let mut integral = 0.0;
    for &(x, wx) in &pa {
        for &(y, wy) in &pb {
            let d = y - x;
            let r2 = d.length_squared();
            let (ca, cb) = (na.dot(d).max(0.0), (-nb.dot(d)).max(0.0));
            integral += wx * wy * ca * cb / (PI * r2 * r2);
        }
    }
    let area_a = (a[1] - a[0]).cross(a[3] - a[0]).length();
    integral / area_a
}

#[test]
fn straddling_perpendicular_pairs_match_a_brute_force_quadrature() {
    let cases = [
        (
            "floor straddles the wall's plane",
            floor_at([0.0, 1.0], [-0.4, 0.8], 0.0, false),
            wall_at([0.3, 1.5], 0.1, [0.2, 1.1]),
        ),
        (
            "wall straddles the floor's plane",
            floor_at([0.0, 1.0], [0.3, 1.0], 0.0, false),
            wall_at([-0.5, 0.6], 0.1, [-0.5, 0.7]),
        ),
        (
            "both straddle, apart along x",
            floor_at([0.0, 1.0], [-0.4, 0.8], 0.0, false),
            wall_at([1.3, 2.0], 0.1, [-0.5, 0.7]),
        ),
    ];
    let maps = symmetries();
    for (name, a, b) in cases {
        for (x, y) in [(&a, &b), (&b, &a)] {
            let reference = brute_force(x, y, 24);
            let coarser = brute_force(x, y, 16);
            // Converged far below the tolerance of the comparison.
            assert!(
                (reference - coarser).abs() < 1e-7,
                "{name}: {reference} vs {coarser}"
            );
            let mut worst = 0.0f64;
            for map in &maps {
                let f = axis_aligned_rectangles(&map(x), &map(y)).expect("rectangles");
                worst = worst.max((f - reference).abs());
            }
            println!("{name}: F = {reference:.12}, worst |closed − quadrature| = {worst:.1e}");
            assert!(worst < 1e-6, "{name}: {worst}");
        }
    }
}

#[test]
fn offset_pairs_keep_reciprocity() {
    // A_a F_ab = A_b F_ba: the two directions go through different frames of the closed forms.
    let pairs = [
        (
            floor_at([0.0, 1.0], [-0.4, 0.8], 0.0, false),
            wall_at([0.3, 1.5], 0.1, [-0.2, 1.1]),
        ),
        (
            floor_at([0.2, 1.7], [0.1, 0.6], 0.0, false),
            floor_at([-1.0, 0.5], [0.4, 2.0], 0.7, true),
        ),
    ];
    for (a, b) in pairs {
        let area = |q: &[DVec3]| (q[1] - q[0]).cross(q[3] - q[0]).length();
        let fab = axis_aligned_rectangles(&a, &b).expect("rectangles");
        let fba = axis_aligned_rectangles(&b, &a).expect("rectangles");
        assert!(fab > 0.0);
        let (ga, gb) = (area(&a) * fab, area(&b) * fba);
        assert!((ga - gb).abs() < 1e-14 * ga.max(gb), "{ga} vs {gb}");
    }
}

#[test]
fn the_dense_matrix_does_not_depend_on_the_thread_count() {
    let m = cube_mesh(4);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .expect("pool");
    let a = one.install(|| dense_form_factors(&m)).expect("rectangles");
    let b = three
        .install(|| dense_form_factors(&m))
        .expect("rectangles");
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
}
