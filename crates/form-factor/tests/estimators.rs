//! The cheaper estimators against closed forms, and the automatic choice against its stated
//! tolerance on random pairs (the contour integral at high order is the reference there).

mod common;

use bake_form_factor::{
    point_to_polygon, polygon_pair_with, ContourOptions, Estimator, Method, TriangleRule,
};
use common::{parallel_opposed, v};
use glam::DVec3;
use std::f64::consts::PI;

/// Differential element at the origin (normal +z) under the parallel rectangle
/// `[0, a] × [0, b]` at height c (Howell B-2 with the corner over the element).
fn parallel_corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

/// Differential element at the origin (normal +z) to the rectangle x ∈ [0, a], z ∈ [0, c] in the
/// perpendicular plane y = b facing it: F = 1/(2π) [atan X − atan(X/√(1+Y²)) / √(1+Y²)],
/// X = a/b, Y = c/b (eq. 12 integrated by hand: the z integral of z/(s²+z²)² is elementary,
/// then ∫ dx/(x² + k²) = atan(x/k)/k).
fn perpendicular_corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / b, c / b);
    let s = (1.0 + y * y).sqrt();
    (x.atan() - (x / s).atan() / s) / (2.0 * PI)
}

#[test]
fn point_to_polygon_matches_differential_closed_forms() {
    let n = DVec3::Z;
    for (a, b, c) in [
        (1.0, 1.0, 1.0),
        (2.0, 0.5, 0.3),
        (1e-3, 2.0, 5.0),
        (10.0, 10.0, 0.01),
    ] {
        // Facing down towards the element: counter-clockwise about −z.
        let parallel = [v(0.0, 0.0, c), v(0.0, b, c), v(a, b, c), v(a, 0.0, c)];
        let exact = parallel_corner(a, b, c);
        let got = point_to_polygon(DVec3::ZERO, n, &parallel);
        assert!(
            (got - exact).abs() <= 1e-9 * exact,
            "{a} {b} {c}: {got} vs {exact}"
        );
        // Superposition: the element under the middle of a rectangle sees four corner pieces.
        let centred = parallel.map(|p| p - v(a / 2.0, b / 2.0, 0.0));
        let four = 4.0 * parallel_corner(a / 2.0, b / 2.0, c);
        let got = point_to_polygon(DVec3::ZERO, n, &centred);
        assert!((got - four).abs() <= 1e-9 * four, "{got} vs {four}");

        let perpendicular = [v(0.0, b, 0.0), v(0.0, b, c), v(a, b, c), v(a, b, 0.0)];
        let exact = perpendicular_corner(a, b, c);
        let got = point_to_polygon(DVec3::ZERO, n, &perpendicular);
        assert!(
            (got - exact).abs() <= 1e-9 * exact,
            "{a} {b} {c}: {got} vs {exact}"
        );
    }
}

/// Unit squares facing each other at distance c.
fn opposed(c: f64) -> ([DVec3; 4], [DVec3; 4]) {
    (
        [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)],
        [v(0., 0., c), v(0., 1., c), v(1., 1., c), v(1., 0., c)],
    )
}

#[test]
fn point_to_point_converges_as_distance_over_size_grows() {
    let o = ContourOptions::default();
    let mut last = f64::INFINITY;
    for c in [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0] {
        let (a, b) = opposed(c);
        let exact = parallel_opposed(1.0, 1.0, c);
        let got = polygon_pair_with(&a, &b, &o, Estimator::PointPoint);
        assert_eq!(got.method, Some(Method::PointPoint));
        let error = (got.value - exact).abs() / exact;
        // Second order in size/distance: each doubling divides the error by ≈ 4.
        assert!(error < last / 3.5, "c = {c}: {error:e} after {last:e}");
        assert!(error * c * c < 1.0, "c = {c}: {error:e}");
        last = error;
    }
    assert!(last < 2e-4, "{last:e}");
}

#[test]
fn point_to_polygon_rules_converge_in_order() {
    let o = ContourOptions::default();
    for c in [0.5, 2.0, 8.0] {
        let (a, b) = opposed(c);
        let exact = parallel_opposed(1.0, 1.0, c);
        let errors: Vec<f64> = TriangleRule::ALL
            .into_iter()
            .map(|rule| {
                let got = polygon_pair_with(&a, &b, &o, Estimator::PointPolygon(rule));
                (got.value - exact).abs() / exact
            })
            .collect();
        assert!(
            errors[0] > errors[1] && errors[1] > errors[2],
            "c = {c}: {errors:?}"
        );
        if c >= 8.0 {
            assert!(errors[2] < 1e-7, "c = {c}: {errors:?}");
        }
    }
}

/// A small deterministic generator (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }

    fn unit(&mut self) -> DVec3 {
        loop {
            let p = v(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let l = p.length();
            if l > 0.1 && l <= 1.0 {
                return p / l;
            }
        }
    }
}

/// A random convex polygon (triangle, rectangle, parallelogram or trapezoid) of size ~`size`,
/// centred at `centre`, counter-clockwise about `normal`.
fn polygon(rng: &mut Rng, centre: DVec3, normal: DVec3, size: f64) -> Vec<DVec3> {
    let u = normal.any_orthonormal_vector();
    let w = normal.cross(u);
    let turn = rng.range(0.0, 2.0 * PI);
    let (u, w) = (
        u * turn.cos() + w * turn.sin(),
        w * turn.cos() - u * turn.sin(),
    );
    let aspect = rng.range(1.0, 4.0);
    let (sx, sy) = (size * aspect.sqrt(), size / aspect.sqrt());
    let shear = rng.range(-0.5, 0.5);
    let taper = rng.range(0.5, 1.0);
    let local: Vec<(f64, f64)> = match (rng.next() * 3.0) as u32 {
        0 => vec![(-0.5, -0.5), (0.5, -0.5), (shear, 0.5)],
        1 => vec![
            (-0.5 + shear, -0.5),
            (0.5 + shear, -0.5),
            (0.5 - shear, 0.5),
            (-0.5 - shear, 0.5),
        ],
        _ => vec![
            (-0.5, -0.5),
            (0.5, -0.5),
            (0.5 * taper, 0.5),
            (-0.5 * taper, 0.5),
        ],
    };
    local
        .into_iter()
        .map(|(x, y)| centre + u * (x * sx) + w * (y * sy))
        .collect()
}

/// Random facing pairs over distance/size ratios from 0.3 to 300, with the high-order contour
/// value as reference; pairs that barely see each other (F < 1e-9) are skipped.
fn random_pairs(seed: u64, count: usize) -> Vec<(Vec<DVec3>, Vec<DVec3>, f64)> {
    let reference = ContourOptions {
        segments: 2,
        ..ContourOptions::default()
    };
    let mut rng = Rng(seed);
    let mut pairs = Vec::new();
    while pairs.len() < count {
        let size_i = rng.range(0.2, 1.0);
        let size_j = size_i * rng.range(0.25, 4.0);
        let ratio = 10f64.powf(rng.range(-0.5, 2.5));
        let direction = rng.unit();
        let distance = ratio * size_i.max(size_j);
        // i faces roughly towards j and j towards i, at random tilts (grazing included).
        let ni = (direction + rng.unit() * rng.range(0.0, 1.2)).normalize();
        let nj = (-direction + rng.unit() * rng.range(0.0, 1.2)).normalize();
        let a = polygon(&mut rng, DVec3::ZERO, ni, size_i);
        let b = polygon(&mut rng, direction * distance, nj, size_j);
        let exact = polygon_pair_with(&a, &b, &reference, Estimator::Contour).value;
        let area = common::area(&a);
        if exact / area > 1e-9 {
            pairs.push((a, b, exact));
        }
    }
    pairs
}

#[test]
fn automatic_choice_stays_within_its_tolerance() {
    let o = ContourOptions::default();
    let pairs = random_pairs(7, 3000);
    let exact_work: Vec<u64> = pairs
        .iter()
        .map(|(a, b, _)| polygon_pair_with(a, b, &o, Estimator::Contour).evaluations)
        .collect();
    let total: u64 = exact_work.iter().sum();
    // Which candidates were taken at some tolerance: point-point, point-to-polygon, and the
    // contour integral by a cheap fixed rule (fewer evaluations than the exact one).
    let mut used = [false; 3];
    for tolerance in [0.3, 0.1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8] {
        let (mut work, mut worst) = (0, 0.0f64);
        for ((a, b, exact), exact_work) in pairs.iter().zip(&exact_work) {
            let got = polygon_pair_with(a, b, &o, Estimator::Auto { tolerance });
            let error = (got.value - exact).abs() / exact;
            worst = worst.max(error / tolerance);
            assert!(
                error <= tolerance,
                "tolerance {tolerance:e}: error {error:e} by {:?} on {a:?} {b:?}",
                got.method
            );
            work += got.evaluations;
            match got.method {
                Some(Method::PointPoint) => used[0] = true,
                Some(Method::PointPolygon) => used[1] = true,
                _ => used[2] |= got.evaluations < *exact_work,
            }
        }
        eprintln!(
            "tolerance {tolerance:e}: {:.1}% of the exact contour's evaluations, worst error = {worst:.3} × tolerance",
            100.0 * work as f64 / total as f64
        );
        // The choice is not vacuous: it saves work (measured: 20% of the exact contour's
        // evaluations at 0.3, 42% at 1e-2, 51% at 1e-3; the near third of these pairs needs
        // the exact integral at any tolerance and costs the most).
        if tolerance >= 1e-3 {
            assert!(work * 10 < total * 6, "{tolerance:e}: {work} of {total}");
        }
    }
    assert_eq!(used, [true; 3], "every candidate is taken somewhere");
}

/// Measures the constants of the error model: the worst `error · (h/r)^p` per estimator over
/// random pairs. Run with `--ignored --nocapture` after changing an estimator; the constants
/// in `estimate.rs` are these values with a margin.
#[test]
#[ignore]
fn error_model_constants() {
    let default = ContourOptions::default();
    let gauss = |order| ContourOptions {
        segments: 1,
        order,
        auto_order: false,
        near_ratio: 0.0,
    };
    let near = |near_ratio| ContourOptions {
        segments: 1,
        order: 3,
        auto_order: false,
        near_ratio,
    };
    let rule = Estimator::PointPolygon;
    for (name, estimator, o, power) in [
        ("point-point", Estimator::PointPoint, default, 2),
        ("centroid", rule(TriangleRule::Centroid), default, 2),
        ("three", rule(TriangleRule::Three), default, 3),
        ("seven", rule(TriangleRule::Seven), default, 6),
        ("contour gauss 2", Estimator::Contour, gauss(2), 3),
        ("contour gauss 3", Estimator::Contour, gauss(3), 4),
        ("contour gauss 4", Estimator::Contour, gauss(4), 6),
        ("contour near 1", Estimator::Contour, near(1.0), 0),
        ("contour near 2", Estimator::Contour, near(2.0), 0),
        ("contour near 4", Estimator::Contour, near(4.0), 0),
    ] {
        // Point-to-polygon integrates over one side: the better one; the others both sides.
        let one_sided = matches!(estimator, Estimator::PointPolygon(_));
        // Worst error · (h/r)^p per octave of h/r from 1/2 to 256.
        let mut worst = [0.0f64; 10];
        for (a, b, exact) in random_pairs(11, 4000) {
            let got = polygon_pair_with(&a, &b, &o, estimator).value;
            let error = (got - exact).abs() / exact;
            let ratio = ratio_of(&a, &b, !one_sided);
            let bin = (ratio.log2() + 1.0).clamp(0.0, 9.0) as usize;
            if error > 1e-13 {
                worst[bin] = worst[bin].max(error * ratio.powi(power));
            }
        }
        eprintln!(
            "{name}: worst error · (h/r)^{power} per octave from 1/2: {:?}",
            worst.map(|w| format!("{w:.2e}"))
        );
    }
}

/// The error model's ratio h/r (test-side copy: centroid height over the other's plane over
/// the largest centroid–vertex distance; the better side, or the worse side for point-point).
fn ratio_of(a: &[DVec3], b: &[DVec3], worst: bool) -> f64 {
    let side = |p: &[DVec3], q: &[DVec3]| {
        let c = p.iter().copied().sum::<DVec3>() / p.len() as f64;
        let r = p.iter().map(|x| x.distance(c)).fold(0.0, f64::max);
        let h = (c - q[0]).dot(common::normal(q));
        h / r
    };
    let (x, y) = (side(a, b), side(b, a));
    if worst {
        x.min(y)
    } else {
        x.max(y)
    }
}
