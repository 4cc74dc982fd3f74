//! Occlusion on small scenes with known answers: the paper's cube (nothing to occlude), a
//! full and a half occluder between parallel squares, a block on a floor (contact lines),
//! thin walls, coplanar neighbours, and independence from units and position.

mod common;

use bake_visibility::{
    pair_seed, Counters, Estimator, Occluders, Patch, Visibility, DEFAULT_SAMPLES,
};
use common::{cube, polygon, rect_z};
use form_factor::{polygon_pair, ContourOptions};
use glam::DVec3;
use importer::Polygon;
use mesher::{mesh, ElementMesh, Subdivision};

fn patch(p: &Polygon, index: usize) -> Patch {
    Patch::new(&p.vertices, p.normal, index).unwrap()
}

/// Visibility of every element pair (i < j), summed into counters.
fn all_pairs(occluders: &Occluders, m: &ElementMesh, samples: u32) -> (Vec<Visibility>, Counters) {
    let pairs = occluders.occludable_pairs();
    let mut counters = Counters::default();
    let mut out = Vec::new();
    for i in 0..m.elements.len() {
        for j in i + 1..m.elements.len() {
            let v = occluders.element_pair(&pairs, m, i, j, samples);
            counters.add(&v);
            out.push(v);
        }
    }
    (out, counters)
}

#[test]
fn the_papers_cube_casts_no_rays() {
    let walls = cube();
    let occluders = Occluders::new(&walls).unwrap();
    let pairs = occluders.occludable_pairs();
    assert!(pairs.is_empty());
    assert_eq!(pairs.facing_pairs(), 15);
    let effects = pairs.effects();
    assert!(!effects.occlusion, "{}", effects.reason);
    for a in 0..6 {
        for b in 0..6 {
            let (pa, pb) = (occluders.polygon(a), occluders.polygon(b));
            assert!(!occluders.can_occlude(&pa, &pb), "walls {a} and {b}");
        }
    }
    let m = mesh(&walls, Subdivision::Count(4)).unwrap();
    let (visibility, counters) = all_pairs(&occluders, &m, DEFAULT_SAMPLES);
    assert!(visibility.iter().all(|v| *v == Visibility::UNOCCLUDED));
    let n = m.elements.len() as u64;
    assert_eq!(
        counters,
        Counters {
            pairs_tested: n * (n - 1) / 2,
            pairs_occludable: 0,
            rays_cast: 0
        }
    );
}

/// Two unit squares facing each other at z = 0 and z = 1, and `occluders` between them.
fn squares_with(occluders: Vec<Polygon>) -> Vec<Polygon> {
    let mut scene = vec![
        rect_z([0.0, 1.0], [0.0, 1.0], 0.0, true, 0),
        rect_z([0.0, 1.0], [0.0, 1.0], 1.0, false, 1),
    ];
    scene.extend(occluders);
    scene
}

#[test]
fn a_larger_square_between_parallel_squares_hides_them_exactly() {
    for up in [true, false] {
        let scene = squares_with(vec![rect_z([-0.5, 1.5], [-0.5, 1.5], 0.5, up, 2)]);
        let occluders = Occluders::new(&scene).unwrap();
        let (a, b) = (patch(&scene[0], 0), patch(&scene[1], 1));
        assert!(occluders.can_occlude(&a, &b));
        let v = occluders.visibility(&a, &b, DEFAULT_SAMPLES, 1);
        assert_eq!(v.fraction, 0.0);
        assert_eq!(v.rays, DEFAULT_SAMPLES);
        // Element level: every pair across is hidden, exactly.
        let m = mesh(&scene, Subdivision::Count(2)).unwrap();
        let pairs = occluders.occludable_pairs();
        for i in 0..4 {
            for j in 4..8 {
                let v = occluders.element_pair(&pairs, &m, i, j, DEFAULT_SAMPLES);
                assert!(v.occludable);
                assert_eq!(v.fraction, 0.0);
            }
        }
    }
    // Without the occluder: not occludable, exactly visible.
    let scene = squares_with(vec![]);
    let occluders = Occluders::new(&scene).unwrap();
    let (a, b) = (patch(&scene[0], 0), patch(&scene[1], 1));
    assert!(!occluders.can_occlude(&a, &b));
    assert_eq!(
        occluders.visibility(&a, &b, DEFAULT_SAMPLES, 1).fraction,
        1.0
    );
}

/// The occluder covers x < 0.5 at z = 0.5: the point reflection through the pair's centre
/// swaps hidden and visible point pairs and keeps the kernel, so exactly half of F is visible.
/// A straight shadow edge through the middle of both elements is the hardest case for point
/// sampling. Measured over 400 seeds, the fraction's rms error is 0.0094 with the default 289
/// rays and 0.0046 with 961 (|error| > 1% of F for 30% and 3% of the seeds): so the 2% bound
/// is asserted with 961 rays for the seed the pipeline would use, plus the mean and spread
/// over 64 seeds at both counts.
#[test]
fn a_half_occluder_hides_half_the_form_factor() {
    let scene = squares_with(vec![rect_z([-1.0, 0.5], [-1.0, 2.0], 0.5, true, 2)]);
    let occluders = Occluders::new(&scene).unwrap();
    let (a, b) = (patch(&scene[0], 0), patch(&scene[1], 1));
    let f = polygon_pair(
        &scene[0].vertices,
        &scene[1].vertices,
        &ContourOptions::default(),
    );
    assert!(
        (f - 0.199_824_5).abs() < 1e-6,
        "unit squares at distance 1: {f}"
    );
    let v = occluders.visibility(&a, &b, 1024, pair_seed(0, 1));
    assert_eq!(v.rays, 961);
    let error = (f * v.fraction - f / 2.0).abs() / (f / 2.0);
    println!(
        "961 rays, pair seed: fraction {} (F off by {:.2}%)",
        v.fraction,
        100.0 * error
    );
    assert!(error < 0.02);
    for (samples, rms_bound) in [(DEFAULT_SAMPLES, 0.014), (1024, 0.007)] {
        let errors: Vec<f64> = (0..64)
            .map(|s| occluders.visibility(&a, &b, samples, 1000 + s).fraction - 0.5)
            .collect();
        let mean = errors.iter().sum::<f64>() / 64.0;
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / 64.0).sqrt();
        println!("{samples} samples, 64 seeds: mean error {mean:+.4}, rms {rms:.4}");
        assert!(mean.abs() < 0.3 * rms_bound, "{samples}: biased, {mean}");
        assert!(rms < rms_bound, "{samples}: {rms}");
    }
}

/// An axis-aligned quad at `at` on `axis` (0 = x, 1 = y, 2 = z), facing `+axis` if `positive`,
/// spanning u and v on the next two axes (cyclically).
fn rect(axis: usize, positive: bool, at: f64, u: [f64; 2], v: [f64; 2], index: usize) -> Polygon {
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    let point = |s: f64, t: f64| {
        let mut p = [0.0; 3];
        p[axis] = at;
        p[a] = s;
        p[b] = t;
        DVec3::from(p)
    };
    let mut c = vec![
        point(u[0], v[0]),
        point(u[1], v[0]),
        point(u[1], v[1]),
        point(u[0], v[1]),
    ];
    if !positive {
        c.reverse();
    }
    polygon(&c, index)
}

/// A 4 × 4 floor (z = 0, facing up), a ceiling at z = 2, and a unit block standing on the
/// floor (x, y in −0.5..0.5, z in 0..1): top and four sides facing out, no bottom.
fn block_on_floor() -> Vec<Polygon> {
    let span = [-2.0, 2.0];
    let b = [-0.5, 0.5];
    vec![
        rect_z(span, span, 0.0, true, 0),
        rect_z(span, span, 2.0, false, 1),
        rect_z(b, b, 1.0, true, 2),
        rect(0, true, 0.5, b, [0.0, 1.0], 3),
        rect(0, false, -0.5, b, [0.0, 1.0], 4),
        rect(1, true, 0.5, [0.0, 1.0], b, 5),
        rect(1, false, -0.5, [0.0, 1.0], b, 6),
    ]
}

/// The element of `m` on `polygon` whose centroid is nearest to `at`.
fn element_at(m: &ElementMesh, polygon: u32, at: DVec3) -> usize {
    (0..m.elements.len())
        .filter(|&e| m.elements[e].polygon == polygon)
        .min_by(|&a, &b| {
            let d = |e: usize| m.elements[e].centroid.distance(at);
            d(a).total_cmp(&d(b))
        })
        .unwrap()
}

#[test]
fn a_block_on_the_floor_hides_what_is_under_it_and_nothing_beside_it() {
    let scene = block_on_floor();
    let occluders = Occluders::new(&scene).unwrap();
    let pairs = occluders.occludable_pairs();
    // 0.5 m elements: the block's footprint covers 2 × 2 floor elements.
    let floor_ceiling = mesh(&scene, Subdivision::Count(8)).unwrap();
    let under = element_at(&floor_ceiling, 0, DVec3::new(0.25, 0.25, 0.0));
    let beside = element_at(&floor_ceiling, 0, DVec3::new(0.75, 0.25, 0.0));
    let above_beside = element_at(&floor_ceiling, 1, DVec3::new(0.75, 0.25, 2.0));
    let ceiling: Vec<usize> = (0..floor_ceiling.elements.len())
        .filter(|&e| floor_ceiling.elements[e].polygon == 1)
        .collect();
    // Under the block: every ceiling element is hidden, exactly (rays leave through the sides
    // right at the contact line and must not slip through the seam).
    for &c in &ceiling {
        let v = occluders.element_pair(&pairs, &floor_ceiling, under, c, DEFAULT_SAMPLES);
        assert!(v.occludable);
        assert_eq!(v.fraction, 0.0, "under the block to ceiling element {c}");
    }
    // Just outside, to the ceiling straight above: nothing can come between, and the rays agree.
    let v = occluders.element_pair(
        &pairs,
        &floor_ceiling,
        beside,
        above_beside,
        DEFAULT_SAMPLES,
    );
    assert_eq!(v, Visibility::UNOCCLUDED);
    let (a, b) = (
        Patch::element(&floor_ceiling, beside),
        Patch::element(&floor_ceiling, above_beside),
    );
    assert_eq!(occluders.visibility(&a, &b, 256, 9).fraction, 1.0);
    // Some ceiling elements beyond the block are partly hidden from `beside`, none fully.
    let partly = ceiling
        .iter()
        .map(|&c| occluders.element_pair(&pairs, &floor_ceiling, beside, c, DEFAULT_SAMPLES))
        .filter(|v| v.fraction > 0.0 && v.fraction < 1.0)
        .count();
    assert!(partly > 0);
}

#[test]
fn pairs_sharing_a_contact_line_are_not_occludable() {
    let scene = block_on_floor();
    let occluders = Occluders::new(&scene).unwrap();
    let pairs = occluders.occludable_pairs();
    let m = mesh(&scene, Subdivision::Count(8)).unwrap();
    let mut checked = 0;
    for side in 3..7u32 {
        for s in (0..m.elements.len()).filter(|&e| m.elements[e].polygon == side) {
            let (a, sa) = (Patch::element(&m, s), &m.elements[s]);
            if sa.centroid.z > 0.125 {
                continue; // only side elements touching the floor
            }
            for f in (0..m.elements.len()).filter(|&e| m.elements[e].polygon == 0) {
                let b = Patch::element(&m, f);
                let touching = a
                    .corners()
                    .iter()
                    .filter(|p| p.z == 0.0)
                    .any(|p| b.corners().iter().any(|q| q.distance(*p) < 1e-12));
                let facing = (m.elements[f].centroid - sa.centroid).dot(sa.normal) > 0.0;
                if !(touching && facing) {
                    continue;
                }
                assert!(!occluders.can_occlude(&a, &b), "side {s} / floor {f}");
                assert!(!pairs.can_occlude(&occluders, &a, &b));
                let v = occluders.element_pair(&pairs, &m, s, f, DEFAULT_SAMPLES);
                assert_eq!(v, Visibility::UNOCCLUDED);
                checked += 1;
            }
        }
    }
    assert!(checked >= 4 * 8, "{checked}");
}

#[test]
fn no_ray_slips_through_the_contact_line() {
    let scene = block_on_floor();
    let occluders = Occluders::new(&scene).unwrap();
    let lift = DVec3::Z * occluders.ray_offset();
    let ceiling = |k: f64| DVec3::new(2.0 * (k * 0.37).sin(), 2.0 * (k * 0.91).cos(), 2.0);
    for k in 0..2000 {
        let k = k as f64;
        // Floor points under the block, down to 1e-9 from its sides, to anywhere on the ceiling.
        let d = 10f64.powf(-9.0 + 8.0 * ((k * 0.618) % 1.0));
        let under = DVec3::new(0.5 - d, 0.5 * ((k * 0.13).sin()), 0.0) + lift;
        assert!(occluders.segment_blocked(under, ceiling(k) - lift, [0, 1]));
        // Just outside, straight up: free. (Closer than 1e-9 × the scene size a point counts
        // as on the block's edge, which blocks: the tolerance errs towards no leaks.)
        let d = d.max(1e-7);
        let beside = DVec3::new(0.5 + d, under.y, 0.0) + lift;
        let up = DVec3::new(beside.x, beside.y, 2.0) - lift;
        assert!(!occluders.segment_blocked(beside, up, [0, 1]), "d = {d}");
    }
}

#[test]
fn thin_walls_block_from_both_sides() {
    let v = |x: f64, positive: bool, index| rect(0, positive, x, [0.0, 1.0], [0.0, 1.0], index);
    for wall_faces_a in [true, false] {
        let scene = vec![
            v(0.0, true, 0),
            v(2.0, false, 1),
            rect(0, !wall_faces_a, 1.0, [-1.0, 2.0], [-1.0, 2.0], 2),
        ];
        let occluders = Occluders::new(&scene).unwrap();
        let (a, b) = (patch(&scene[0], 0), patch(&scene[1], 1));
        assert!(occluders.can_occlude(&a, &b));
        for (from, to) in [(a, b), (b, a)] {
            let vis = occluders.visibility(&from, &to, DEFAULT_SAMPLES, 3);
            assert_eq!(vis.fraction, 0.0);
            assert_eq!(vis.rays, DEFAULT_SAMPLES);
        }
    }
}

#[test]
fn coplanar_neighbours_never_shadow_each_other() {
    // Two floor tiles side by side, the first one's back side (a double-sided twin), a ceiling.
    let mut twin = rect_z([0.0, 1.0], [0.0, 1.0], 0.0, false, 2);
    twin.origin.side = importer::Side::Back;
    let scene = vec![
        rect_z([0.0, 1.0], [0.0, 1.0], 0.0, true, 0),
        rect_z([1.0, 2.0], [0.0, 1.0], 0.0, true, 1),
        twin,
        rect_z([0.0, 2.0], [0.0, 1.0], 1.0, false, 3),
    ];
    let occluders = Occluders::new(&scene).unwrap();
    let pairs = occluders.occludable_pairs();
    assert!(pairs.is_empty(), "{:?}", pairs.pairs());
    let (tile, ceiling) = (patch(&scene[0], 0), patch(&scene[3], 3));
    assert_eq!(occluders.visibility(&tile, &ceiling, 1024, 5).fraction, 1.0);
    // Grazing rays along the floor, from one tile over the other.
    let lift = DVec3::Z * occluders.ray_offset();
    for k in 1..100 {
        let x = k as f64 / 50.0;
        let p = DVec3::new(0.01, 0.5, 0.0) + lift;
        let q = DVec3::new(x, 0.3, 0.0) + lift;
        assert!(!occluders.segment_blocked(p, q, [0, 1]));
    }
}

/// Scaling and moving the scene changes nothing but rounding.
#[test]
fn results_do_not_depend_on_units_or_position() {
    let base = squares_with(vec![rect_z([-1.0, 0.5], [-1.0, 2.0], 0.5, true, 2)]);
    let fraction = |scale: f64, shift: f64| {
        let scene: Vec<Polygon> = base
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let c: Vec<DVec3> = p.vertices.iter().map(|v| *v * scale + shift).collect();
                polygon(&c, k)
            })
            .collect();
        let occluders = Occluders::new(&scene).unwrap();
        let (a, b) = (patch(&scene[0], 0), patch(&scene[1], 1));
        occluders.visibility(&a, &b, 256, 11).fraction
    };
    let reference = fraction(1.0, 0.0);
    for (scale, shift) in [(1e-3, 0.0), (1e3, 0.0), (1e-3, 1e2), (1e3, -1e6)] {
        let f = fraction(scale, shift);
        assert!(
            (f - reference).abs() < 1e-9,
            "× {scale} + {shift}: {f} vs {reference}"
        );
    }
}

/// Both estimators give exactly 0 and 1 at the extremes and agree on the symmetric half.
#[test]
fn estimators_agree_at_the_extremes() {
    let half = squares_with(vec![rect_z([-1.0, 0.5], [-1.0, 2.0], 0.5, true, 2)]);
    let occluders = Occluders::new(&half).unwrap();
    let (a, b) = (patch(&half[0], 0), patch(&half[1], 1));
    for estimator in [Estimator::KernelWeighted, Estimator::Uniform] {
        let v = occluders.visibility_with(&a, &b, 1024, 2, estimator);
        assert!(
            (v.fraction - 0.5).abs() < 0.01,
            "{estimator:?}: {}",
            v.fraction
        );
    }
}

/// `shadow_candidates` (the oriented sweep query of issue 29) misses no polygon that blocks a
/// light segment: random quads in every orientation, each a receiver of three suns (one
/// grazing) and two point lights; every segment from a random receiver point to its far point
/// is tested against every polygon alone (brute force), and each polygon that blocks one must
/// be a candidate. `can_shadow` agrees with the candidate list being non-empty.
#[test]
fn shadow_candidates_miss_no_blocker() {
    let mut rng = bake_visibility::SplitMix64::new(29);
    let mut r = move || rng.next_f64();
    let mut quads = Vec::new();
    for k in 0..60 {
        let centre = DVec3::new(10.0 * r(), 10.0 * r(), 10.0 * r());
        let n = DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize();
        let u = n.any_orthonormal_vector();
        let v = n.cross(u);
        let (a, b) = (0.3 + 1.5 * r(), 0.3 + 1.5 * r());
        let c = [
            centre - u * a - v * b,
            centre + u * a - v * b,
            centre + u * a + v * b,
            centre - u * a + v * b,
        ];
        quads.push(polygon(&c, k));
    }
    let occluders = Occluders::new(&quads).unwrap();
    let alone: Vec<Occluders> = quads
        .iter()
        .map(|q| Occluders::new(std::slice::from_ref(q)).unwrap())
        .collect();
    let reach = 2.0 * occluders.scene_scale();
    let suns = [
        DVec3::new(0.3, -1.0, 0.2).normalize(),
        DVec3::new(-0.7, -0.2, 0.6).normalize(),
        DVec3::new(1.0, -0.02, 0.0).normalize(),
    ];
    let points = [DVec3::new(5.0, 12.0, 5.0), DVec3::new(1.0, 4.0, 8.0)];
    let (mut tested, mut blocked) = (0, 0);
    let mut candidates = Vec::new();
    for (i, q) in quads.iter().enumerate() {
        let receiver = patch(q, i);
        let c = &q.vertices;
        let lights: Vec<Vec<DVec3>> = suns
            .iter()
            .map(|d| c.iter().map(|&p| p - *d * reach).collect())
            .chain(points.iter().map(|&l| vec![l]))
            .collect();
        for far in &lights {
            occluders.shadow_candidates(&receiver, far, &mut candidates);
            assert_eq!(
                occluders.can_shadow(&receiver, far),
                !candidates.is_empty(),
                "receiver {i}"
            );
            for _ in 0..30 {
                let (s, t) = (r(), r());
                let p = c[0] + (c[1] - c[0]) * s + (c[3] - c[0]) * t;
                let end = if far.len() == 1 {
                    far[0]
                } else {
                    // The far point of this receiver point along the sun.
                    p + (far[0] - c[0])
                };
                if q.normal.dot(end - p) <= 0.0 {
                    continue;
                }
                tested += 1;
                for (k, one) in alone.iter().enumerate() {
                    if k != i && one.segment_blocked(p, end, [usize::MAX, usize::MAX]) {
                        blocked += 1;
                        assert!(
                            candidates.contains(&k),
                            "receiver {i}: polygon {k} blocks a light segment but is no candidate"
                        );
                    }
                }
            }
        }
    }
    assert!(
        tested > 2000 && blocked > 200,
        "{tested} segments, {blocked} blocked"
    );
}

#[test]
fn first_hit_finds_the_nearest_polygon_and_its_side() {
    // Three stacked unit squares at z = 1 (facing up), 2 (facing down), 3 (facing up).
    let squares = vec![
        rect_z([0.0, 1.0], [0.0, 1.0], 1.0, true, 0),
        rect_z([0.0, 1.0], [0.0, 1.0], 2.0, false, 1),
        rect_z([0.0, 1.0], [0.0, 1.0], 3.0, true, 2),
    ];
    let occluders = Occluders::new(&squares).unwrap();
    let (p, q) = (DVec3::new(0.5, 0.5, 0.0), DVec3::new(0.5, 0.5, 4.0));
    // Upwards from below: square 0 from its back at t = 1/4.
    let hit = occluders.first_hit(p, q, usize::MAX).unwrap();
    assert_eq!((hit.polygon, hit.front), (0, false));
    assert!((hit.t - 0.25).abs() < 1e-12, "{hit:?}");
    // Skipping it: square 1, met from its front (it faces down, the ray goes up).
    let hit = occluders.first_hit(p, q, 0).unwrap();
    assert_eq!((hit.polygon, hit.front), (1, true));
    assert!((hit.t - 0.5).abs() < 1e-12, "{hit:?}");
    // Downwards from above: square 2 from its front.
    let hit = occluders.first_hit(q, p, usize::MAX).unwrap();
    assert_eq!((hit.polygon, hit.front), (2, true));
    // Beside the squares: nothing.
    let off = DVec3::new(2.0, 0.5, 0.0);
    assert_eq!(
        occluders.first_hit(off, off + DVec3::Z * 4.0, usize::MAX),
        None
    );
}

/// `any_in_front` (the sky's test): a polygon with only coplanar or behind neighbours has
/// nothing in front; one that another polygon rises above has.
#[test]
fn what_is_in_front_of_a_polygon_is_found() {
    let with_ceiling = block_on_floor();
    let occluders = Occluders::new(&with_ceiling).unwrap();
    // Floor, ceiling, block top (under the ceiling), a block side (the floor reaches past it).
    for k in [0, 1, 2, 3] {
        assert!(occluders.any_in_front(&occluders.polygon(k)), "polygon {k}");
    }
    // Without the ceiling, the block's top has only the floor below and sides ending at its
    // own plane: nothing in front.
    let open: Vec<Polygon> = with_ceiling
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != 1)
        .map(|(_, p)| p.clone())
        .collect();
    let occluders = Occluders::new(&open).unwrap();
    assert!(
        !occluders.any_in_front(&occluders.polygon(1)),
        "open block top"
    );
    assert!(
        occluders.any_in_front(&occluders.polygon(0)),
        "floor beside the block"
    );
}

/// Glass (`with_transmission`): a segment keeps the product of the panes' transmissions it
/// crosses, 0 at an opaque polygon; the conservative test still casts rays through glass,
/// and a pair behind a pane that covers all of it sees exactly t of each other.
#[test]
fn glass_passes_the_product_of_its_transmissions() {
    // Three stacked unit squares at z = 1, 2, 3: glass of t = 0.5 and 0.25, then opaque.
    let squares = vec![
        rect_z([0.0, 1.0], [0.0, 1.0], 1.0, true, 0),
        rect_z([0.0, 1.0], [0.0, 1.0], 2.0, false, 1),
        rect_z([0.0, 1.0], [0.0, 1.0], 3.0, true, 2),
    ];
    let occluders = Occluders::new(&squares)
        .unwrap()
        .with_transmission(vec![0.5, 0.25, 0.0]);
    assert!(occluders.has_transmission());
    let at = |z: f64| DVec3::new(0.5, 0.5, z);
    let none = [usize::MAX; 2];
    assert_eq!(occluders.segment_transmittance(at(0.0), at(1.5), none), 0.5);
    assert_eq!(
        occluders.segment_transmittance(at(0.0), at(2.5), none),
        0.125
    );
    assert_eq!(
        occluders.segment_transmittance(at(2.5), at(0.0), none),
        0.125
    );
    assert_eq!(occluders.segment_transmittance(at(0.0), at(4.0), none), 0.0);
    assert_eq!(
        occluders.segment_transmittance(at(0.0), at(2.5), [0, 9]),
        0.25
    );
    // Glass still blocks for the boolean query, whose callers do not average light.
    assert!(occluders.segment_blocked(at(0.0), at(1.5), none));
    let off = DVec3::new(2.0, 0.5, 0.0);
    assert_eq!(
        occluders.segment_transmittance(off, off + DVec3::Z * 4.0, none),
        1.0
    );
    // Without glass the query is the boolean one as 0 or 1.
    let opaque = Occluders::new(&squares)
        .unwrap()
        .with_transmission(vec![0.0; 3]);
    assert!(!opaque.has_transmission());
    assert_eq!(opaque.segment_transmittance(at(0.0), at(1.5), none), 0.0);
    assert_eq!(opaque.segment_transmittance(off, off + DVec3::Z, none), 1.0);

    // Two parallel squares 2 apart with a larger pane of t = 0.9 between them: the pair is
    // still occludable (rays are cast) and sees 0.9 of each other, from every ray.
    let scene = vec![
        rect_z([0.0, 1.0], [0.0, 1.0], 0.0, true, 0),
        rect_z([0.0, 1.0], [0.0, 1.0], 2.0, false, 1),
        rect_z([-5.0, 6.0], [-5.0, 6.0], 1.0, true, 2),
    ];
    let glass = Occluders::new(&scene)
        .unwrap()
        .with_transmission(vec![0.0, 0.0, 0.9]);
    let (a, b) = (glass.polygon(0), glass.polygon(1));
    assert!(glass.can_occlude(&a, &b));
    let v = glass.visibility(&a, &b, DEFAULT_SAMPLES, 7);
    assert!(v.rays > 0);
    assert!((v.fraction - 0.9).abs() < 1e-14, "{}", v.fraction);
    // Half the pane (x < 0.5): between the open 1 and the glazed 0.9, by the same rays.
    let half = vec![
        scene[0].clone(),
        scene[1].clone(),
        rect_z([-5.0, 0.5], [-5.0, 6.0], 1.0, true, 2),
    ];
    let glass = Occluders::new(&half)
        .unwrap()
        .with_transmission(vec![0.0, 0.0, 0.9]);
    let f = glass.visibility(&a, &b, DEFAULT_SAMPLES, 7).fraction;
    let opaque = Occluders::new(&half).unwrap();
    let g = opaque.visibility(&a, &b, DEFAULT_SAMPLES, 7).fraction;
    // Each ray keeps 0.9 where the opaque pane blocked it: f = 1 − 0.1 (1 − g).
    assert!(
        (f - (1.0 - 0.1 * (1.0 - g))).abs() < 1e-12,
        "{f} against {g}"
    );
}
