//! The gather against an independent brute force (rays over a stratified sphere that find the
//! element they hit by a point-in-polygon test), the furnace identity and placement.

// Coefficient × band tables read clearest as index loops.
#![allow(clippy::needless_range_loop)]

use bake_probes::{gather, place, sh, Probes};
use glam::DVec3;
use mesher::{ElementMesh, Subdivision};
use scene::{Origin, Polygon};
use std::f64::consts::PI;
use visibility::Occluders;

/// The parallelogram `centre ± u ± v`, facing `u × v`.
fn quad(centre: DVec3, u: DVec3, v: DVec3) -> Polygon {
    let origin = Origin {
        node: 0,
        mesh: 0,
        primitive: 0,
        face: 0,
        side: scene::Side::Front,
    };
    let vertices = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(a, b)| centre + u * a + v * b)
        .to_vec();
    let normal = u.cross(v).normalize();
    Polygon {
        vertices,
        normal,
        material: 0,
        origin,
    }
}

/// The box `lo..hi` seen from inside (`inward`) or outside.
fn cuboid(lo: DVec3, hi: DVec3, inward: bool) -> Vec<Polygon> {
    let (centre, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
    let axes = [DVec3::X, DVec3::Y, DVec3::Z];
    let mut out = Vec::new();
    for k in 0..3 {
        let (n, u, v) = (
            axes[k] * half,
            axes[(k + 1) % 3] * half,
            axes[(k + 2) % 3] * half,
        );
        for side in [-1.0, 1.0] {
            // Facing +u × v = +axis; flipped where it must face the other way.
            let flip = (side > 0.0) == inward;
            out.push(quad(centre + n * side, if flip { -u } else { u }, v));
        }
    }
    out
}

fn unit_box(inward: bool) -> Vec<Polygon> {
    cuboid(DVec3::ZERO, DVec3::ONE, inward)
}

/// The panel in the box: y = 0.3, facing up, x in 0.1..0.7, z in 0.2..0.6.
fn blocker() -> Polygon {
    quad(DVec3::new(0.4, 0.3, 0.4), DVec3::Z * 0.2, DVec3::X * 0.3)
}

const AXES: [DVec3; 6] = [
    DVec3::X,
    DVec3::NEG_X,
    DVec3::Y,
    DVec3::NEG_Y,
    DVec3::Z,
    DVec3::NEG_Z,
];

/// Whether `x` (on the element's plane) lies in element `i`.
fn contains(mesh: &ElementMesh, i: usize, x: DVec3) -> bool {
    let e = &mesh.elements[i];
    let c: Vec<DVec3> = e
        .corner_indices()
        .iter()
        .map(|&k| mesh.vertices[k as usize])
        .collect();
    (0..c.len()).all(|k| {
        let (a, b) = (c[k], c[(k + 1) % c.len()]);
        (b - a).cross(x - a).dot(e.normal) >= -1e-12
    })
}

/// The brute force: n × 2n strata of (z, φ), one jittered direction each (a fixed LCG), the
/// first polygon along it by `Occluders::first_hit`, its element by point-in-polygon; returns
/// the SH coefficients of b/π and the irradiance ∫ L max(n·ω, 0) dω for the six axes.
fn brute_force(
    p: DVec3,
    mesh: &ElementMesh,
    b: &[[f64; 3]],
    occ: &Occluders,
    n: usize,
) -> (sh::Sh, [[f64; 3]; 6]) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let w = 4.0 * PI / (2 * n * n) as f64;
    let reach = 10.0 * occ.scene_scale();
    let mut coefficients = [[0.0; 3]; 9];
    let mut irradiance = [[0.0; 3]; 6];
    for i in 0..n {
        for j in 0..2 * n {
            let z = -1.0 + 2.0 * (i as f64 + next()) / n as f64;
            let phi = PI * (j as f64 + next()) / n as f64;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let d = DVec3::new(s * phi.cos(), s * phi.sin(), z);
            let Some(hit) = occ.first_hit(p, p + d * reach, usize::MAX) else {
                continue;
            };
            if !hit.front {
                continue;
            }
            let x = p + d * reach * hit.t;
            let grid = &mesh.patches[hit.polygon];
            let Some(e) = (grid.elements.start..grid.elements.end)
                .map(|e| e as usize)
                .find(|&e| contains(mesh, e, x))
            else {
                continue;
            };
            let l = b[e].map(|v| v / PI);
            let y = sh::basis(d);
            for k in 0..9 {
                for band in 0..3 {
                    coefficients[k][band] += l[band] * y[k] * w;
                }
            }
            for (a, axis) in AXES.iter().enumerate() {
                let c = d.dot(*axis).max(0.0);
                for band in 0..3 {
                    irradiance[a][band] += l[band] * c * w;
                }
            }
        }
    }
    (coefficients, irradiance)
}

fn mesh(polygons: &[Polygon], n: u32) -> ElementMesh {
    mesher::mesh(polygons, Subdivision::Count(n)).expect("mesh")
}

#[test]
fn furnace_a_uniform_closed_box_gives_its_radiosity_in_every_direction() {
    let polygons = unit_box(true);
    let mesh = mesh(&polygons, 5);
    let occ = Occluders::new(&polygons).expect("occluders");
    let b = vec![[1.0, 0.5, 0.25]; mesh.elements.len()];
    let sources = gather::Sources::new(&mesh, &b, &occ);
    for p in [DVec3::splat(0.5), DVec3::new(0.2, 0.7, 0.9)] {
        let g = gather::gather(p, &sources);
        // ∫ L dω = 4π b/π = 4b: c₀ = 4b Y₀₀.
        let y00 = 0.5 / PI.sqrt();
        for band in 0..3 {
            let want = 4.0 * b[0][band] * y00;
            assert!(
                (g.sh[0][band] - want).abs() < 1e-5 * want,
                "{p}: c0 {} vs {want}",
                g.sh[0][band]
            );
        }
        for n in [DVec3::X, -DVec3::Y, DVec3::new(1.0, 1.0, -1.0).normalize()] {
            let e = sh::irradiance(&g.sh, n);
            for band in 0..3 {
                assert!(
                    (e[band] - b[0][band]).abs() < 1e-5 * b[0][band],
                    "{p} {n}: H {} vs {}",
                    e[band],
                    b[0][band]
                );
            }
        }
    }
}

/// A non-uniform b on the box's walls, and a panel inside that hides part of them.
#[test]
fn gather_matches_the_brute_force_with_and_without_an_occluder() {
    for panel in [false, true] {
        let mut polygons = unit_box(true);
        if panel {
            // Facing up, between the probe and part of the floor.
            polygons.push(blocker());
        }
        let mesh = mesh(&polygons, 6);
        let occ = Occluders::new(&polygons).expect("occluders");
        let b: Vec<[f64; 3]> = mesh
            .elements
            .iter()
            .map(|e| {
                let c = e.centroid;
                [
                    0.2 + c.x + 2.0 * c.y * c.y,
                    1.0 - 0.5 * c.z,
                    0.1 + (3.0 * c.x).sin().abs(),
                ]
            })
            .collect();
        let sources = gather::Sources::new(&mesh, &b, &occ);
        let p = DVec3::new(0.45, 0.55, 0.4);
        let g = gather::gather(p, &sources);
        let (reference, irradiance) = brute_force(p, &mesh, &b, &occ, 1500);
        for band in 0..3 {
            let scale = reference[0][band].abs();
            for k in 0..9 {
                let diff = (g.sh[k][band] - reference[k][band]).abs();
                println!(
                    "panel {panel} band {band} c{k}: {:.6} vs {:.6} ({:.2e} of c0)",
                    g.sh[k][band],
                    reference[k][band],
                    diff / scale
                );
                // Quadrature, and at most 0.63 (max |Y_k|) of the unresolved shadow edges.
                let allowed = 2.5e-4 * scale + 0.63 * g.unresolved[band];
                assert!(diff < allowed, "c{k} band {band}: {diff} > {allowed}");
            }
        }
        let bound = sh::truncation_bound(&g.sh, g.square);
        for (a, axis) in AXES.iter().enumerate() {
            let e = sh::irradiance(&g.sh, *axis);
            for band in 0..3 {
                let exact = irradiance[a][band];
                let err = (e[band] - exact).abs();
                println!(
                    "panel {panel} {axis} band {band}: L2 {:.5} exact {:.5} ({:.2}%, bound {:.2}%)",
                    e[band],
                    exact,
                    100.0 * err / exact,
                    100.0 * bound[band] / exact
                );
                assert!(
                    err <= bound[band] + g.unresolved[band] + 2e-3 * exact,
                    "{axis} band {band}"
                );
            }
        }
    }
}

#[test]
fn probes_inside_a_solid_or_too_close_are_moved_or_invalid() {
    // A room [−2, 3]³ seen from inside, with a solid unit block [0, 1]³ in it.
    let mut polygons = cuboid(DVec3::splat(-2.0), DVec3::splat(3.0), true);
    polygons.extend(unit_box(false));
    let occ = Occluders::new(&polygons).expect("occluders");
    let dirs = place::directions();
    let spacing = 1.0;
    // In the block's middle: moved out of its cell's part inside the block? The cell is the
    // block itself, so every candidate is inside or within a quarter spacing of it: invalid.
    let inside = place::settle(DVec3::splat(0.5), spacing, &occ, &dirs);
    assert!(!inside.valid && !inside.moved, "{inside:?}");
    // Inside, near a face: moved out.
    let near_face = place::settle(DVec3::new(0.5, 0.5, 0.9), 2.0, &occ, &dirs);
    assert!(near_face.valid && near_face.moved, "{near_face:?}");
    let c = place::check(near_face.position, &occ, &dirs, 0.5);
    assert!(c.back == 0 && c.nearest >= 0.5, "{c:?}");
    // Outside, 0.1 from the block's top: moved away to a quarter spacing.
    let close = place::settle(DVec3::new(0.5, 0.5, 1.1), spacing, &occ, &dirs);
    assert!(close.valid && close.moved, "{close:?}");
    assert!(close.position.z >= 1.25 - 1e-12, "{close:?}");
    // In the open: kept.
    let open = place::settle(DVec3::new(2.0, 2.0, 2.0), spacing, &occ, &dirs);
    assert!(open.valid && !open.moved, "{open:?}");
}

#[test]
fn options_parse_and_refuse() {
    assert_eq!("off".parse::<Probes>().ok(), Some(Probes::Off));
    assert_eq!("auto".parse::<Probes>().ok(), Some(Probes::Auto));
    assert_eq!("grid:0.5".parse::<Probes>().ok(), Some(Probes::Grid(0.5)));
    for bad in ["grid:0", "grid:-1", "grid:nan", "grid:x", "on", "grid:inf"] {
        assert!(bad.parse::<Probes>().is_err(), "{bad}");
    }
}

#[test]
fn same_probes_for_any_thread_count() {
    let mut polygons = unit_box(true);
    polygons.push(blocker());
    let mesh = mesh(&polygons, 4);
    let occ = Occluders::new(&polygons).expect("occluders");
    let b: Vec<[f64; 3]> = (0..mesh.elements.len())
        .map(|i| [i as f64 * 0.01, 1.0, 0.5])
        .collect();
    let bounds = scene::bounds(&polygons);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| bake_probes::bake(Probes::Grid(0.3), &[], &mesh, &b, &occ, bounds, None))
            .expect("probes")
            .expect("some")
    };
    let (one, four) = (run(1), run(4));
    assert_eq!(one.probes, four.probes);
    assert!(one.summary.valid > 0);
}
