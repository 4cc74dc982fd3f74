//! `surface_screen`'s per-side kernel fit: the gradient it reports is the gradient of the
//! point-to-polygon closed form (checked by central differences), in world units, and the
//! linear fit explains most of the kernel's spread over a smooth pair.

use bake_form_factor::{point_to_polygon, surface_screen, Surface};
use glam::DVec3;

fn square(centre: DVec3, u: DVec3, v: DVec3) -> (Vec<DVec3>, DVec3) {
    let corners = vec![
        centre - u - v,
        centre + u - v,
        centre + u + v,
        centre - u + v,
    ];
    (corners, u.cross(v).normalize())
}

fn pair(scale: f64) -> (Surface, Vec<DVec3>, Surface, Vec<DVec3>) {
    // A 1 × 1 floor and a 0.2 × 0.2 panel above and to the side of it, tilted towards it.
    let (a, na) = square(DVec3::ZERO, DVec3::X * 0.5 * scale, DVec3::Y * 0.5 * scale);
    let tilt = DVec3::new(-0.6, 0.0, -0.8);
    let u = DVec3::Y * 0.1 * scale;
    let v = tilt.cross(u).normalize() * 0.1 * scale;
    let (b, nb) = square(DVec3::new(1.5, 0.2, 1.2) * scale, u, v);
    assert!(nb.dot(tilt) > 0.99, "{nb}");
    let sa = Surface::new(&a, na).expect("floor");
    let sb = Surface::new(&b, nb).expect("panel");
    (sa, a, sb, b)
}

#[test]
fn the_fitted_gradient_is_the_kernels_gradient_in_world_units() {
    for scale in [1.0, 1000.0] {
        let (sa, _, sb, b) = pair(scale);
        let screen = surface_screen(&sa, &sb, [true, true]).expect("the pair faces");
        let side = screen.sides[0];
        // Central differences of F_{dx→b} at the floor's centre, in the floor's plane.
        let h = 1e-4 * scale;
        let f = |x: DVec3| point_to_polygon(x, sa.normal, &b);
        let exact = DVec3::new(
            (f(DVec3::X * h) - f(-DVec3::X * h)) / (2.0 * h),
            (f(DVec3::Y * h) - f(-DVec3::Y * h)) / (2.0 * h),
            0.0,
        );
        let error = (side.gradient - exact).length() / exact.length();
        // The fit spans the whole floor, the difference quotient one point: they agree to the
        // kernel's curvature over the floor.
        assert!(
            error < 0.15,
            "scale {scale}: fitted {} vs {exact} ({error:.3})",
            side.gradient
        );
        assert!(side.gradient.z.abs() < 1e-12 * exact.length());
        assert!(
            side.residual < 0.5 * side.spread,
            "scale {scale}: residual {} vs spread {}",
            side.residual,
            side.spread
        );
    }
}

#[test]
fn the_fit_scales_with_the_scene_and_is_skipped_when_not_asked_for() {
    let (sa, _, sb, _) = pair(1.0);
    let (ta, _, tb, _) = pair(1000.0);
    let s = surface_screen(&sa, &sb, [true, true]).expect("faces");
    let t = surface_screen(&ta, &tb, [true, true]).expect("faces");
    for k in 0..2 {
        assert!((s.sides[k].spread - t.sides[k].spread).abs() < 1e-9);
        assert!((s.sides[k].residual - t.sides[k].residual).abs() < 1e-9);
        let ratio = s.sides[k].gradient.length() / t.sides[k].gradient.length();
        assert!((ratio - 1000.0).abs() < 1e-6 * 1000.0, "{ratio}");
    }
    let none = surface_screen(&sa, &sb, [false, true]).expect("faces");
    assert_eq!(none.sides[0].gradient, DVec3::ZERO);
    assert_eq!(none.sides[0].residual, 0.0);
    assert_eq!(none.sides[1], s.sides[1]);
    assert!((none.rough - s.rough).abs() < 0.1 * s.rough);
}
