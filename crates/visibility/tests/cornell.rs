//! The Cornell box (fixtures/cornell.gltf) against an independent brute-force reference: Monte
//! Carlo double-area integration of cos θi cos θj / (π r²) × visibility, with its own random
//! numbers, its own area sampling (quads split into two triangles by area) and its own
//! visibility test (f64 Möller–Trumbore against every polygon, no BVH, no offsets).

mod common;

use bake_visibility::{
    Estimator, OccludablePairs, Occluders, Patch, Pattern, Visibility, DEFAULT_SAMPLES,
};
use form_factor::{polygon_pair, ContourOptions, FormFactors};
use glam::DVec3;
use importer::Polygon;
use mesher::{mesh, ElementMesh, Subdivision};
use rayon::prelude::*;

/// xorshift64* (Vigna 2016): the reference's own generator.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A point uniformly distributed over a convex polygon (fan of triangles chosen by area).
fn uniform_point(corners: &[DVec3], rng: &mut XorShift) -> DVec3 {
    let area = |k: usize| {
        (corners[k] - corners[0])
            .cross(corners[k + 1] - corners[0])
            .length()
    };
    let total: f64 = (1..corners.len() - 1).map(area).sum();
    let mut pick = rng.next() * total;
    let mut k = 1;
    while k + 2 < corners.len() && pick > area(k) {
        pick -= area(k);
        k += 1;
    }
    let (mut s, mut t) = (rng.next(), rng.next());
    if s + t > 1.0 {
        (s, t) = (1.0 - s, 1.0 - t);
    }
    corners[0] + (corners[k] - corners[0]) * s + (corners[k + 1] - corners[0]) * t
}

/// Whether the open segment x–y (endpoints excluded by 1e-9 of its length) crosses a triangle
/// of a polygon other than `skip`.
fn blocked(polygons: &[Polygon], x: DVec3, y: DVec3, skip: [usize; 2]) -> bool {
    let d = y - x;
    polygons.iter().enumerate().any(|(k, p)| {
        if skip.contains(&k) {
            return false;
        }
        let v = &p.vertices;
        (1..v.len() - 1).any(|t| {
            // Möller–Trumbore.
            let (e1, e2) = (v[t] - v[0], v[t + 1] - v[0]);
            let h = d.cross(e2);
            let det = e1.dot(h);
            if det.abs() < 1e-300 {
                return false;
            }
            let s = x - v[0];
            let u = s.dot(h) / det;
            let q = s.cross(e1);
            let w = d.dot(q) / det;
            let hit_t = e2.dot(q) / det;
            (0.0..=1.0).contains(&u)
                && w >= 0.0
                && u + w <= 1.0
                && hit_t > 1e-9
                && hit_t < 1.0 - 1e-9
        })
    })
}

/// Brute-force F_ab with visibility (a's polygon and b's are not occluders) and its standard
/// error, from `n` uniform point pairs.
fn reference(polygons: &[Polygon], a: &Patch, b: &Patch, n: u64, seed: u64) -> (f64, f64) {
    let (ca, cb) = (a.corners(), b.corners());
    let area_b: f64 = (1..cb.len() - 1)
        .map(|k| 0.5 * (cb[k] - cb[0]).cross(cb[k + 1] - cb[0]).length())
        .sum();
    let skip = [a.polygon(), b.polygon()];
    let mut rng = XorShift(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..n {
        let (x, y) = (uniform_point(ca, &mut rng), uniform_point(cb, &mut rng));
        let d = y - x;
        let r2 = d.length_squared();
        let (cos_a, cos_b) = (a.normal().dot(d), -b.normal().dot(d));
        let value = if cos_a > 0.0 && cos_b > 0.0 && !blocked(polygons, x, y, skip) {
            cos_a * cos_b / (std::f64::consts::PI * r2 * r2) * area_b
        } else {
            0.0
        };
        sum += value;
        sum2 += value * value;
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}

struct Cornell {
    polygons: Vec<Polygon>,
    names: Vec<String>,
    mesh: ElementMesh,
    occluders: Occluders,
    pairs: OccludablePairs,
}

fn cornell() -> Cornell {
    let (polygons, names) = common::cornell();
    let mesh = mesh(&polygons, Subdivision::MaxSize(100.0)).unwrap();
    let occluders = Occluders::new(&polygons).unwrap();
    let pairs = occluders.occludable_pairs();
    Cornell {
        polygons,
        names,
        mesh,
        occluders,
        pairs,
    }
}

impl Cornell {
    /// A floor patch under the tall block: its footprint shrunk by 10% about its centre.
    fn under_tall_block(&self) -> Patch {
        let top = (0..self.polygons.len())
            .find(|&k| self.names[k] == "tall_block" && self.polygons[k].normal.y > 0.5)
            .unwrap();
        let floor = self.names.iter().position(|n| n == "floor").unwrap();
        let corners: Vec<DVec3> = self.polygons[top]
            .vertices
            .iter()
            .map(|v| DVec3::new(v.x, 0.0, v.z))
            .collect();
        let centre = corners.iter().copied().sum::<DVec3>() / 4.0;
        let shrunk: Vec<DVec3> = corners
            .iter()
            .map(|&v| centre + (v - centre) * 0.9)
            .collect();
        Patch::new(&shrunk, DVec3::Y, floor).unwrap()
    }

    fn name(&self, e: usize) -> &str {
        &self.names[self.mesh.elements[e].polygon as usize]
    }

    /// Element pairs (i < j) between surfaces named `a` and `b`.
    fn between<'a>(&'a self, a: &'a str, b: &'a str) -> impl Iterator<Item = (usize, usize)> + 'a {
        let n = self.mesh.elements.len();
        (0..n)
            .flat_map(move |i| (i + 1..n).map(move |j| (i, j)))
            .filter(move |&(i, j)| {
                (self.name(i) == a && self.name(j) == b) || (self.name(i) == b && self.name(j) == a)
            })
    }

    /// The first pair between `a` and `b` whose visible fraction (estimated with many rays) lies
    /// in `range`.
    fn pick(&self, a: &str, b: &str, range: std::ops::Range<f64>) -> (usize, usize) {
        self.between(a, b)
            .find(|&(i, j)| {
                let v = self
                    .occluders
                    .element_pair(&self.pairs, &self.mesh, i, j, DEFAULT_SAMPLES);
                range.contains(&v.fraction)
            })
            .unwrap_or_else(|| panic!("no {a}–{b} pair with a visible fraction in {range:?}"))
    }
}

/// Shadow rays per pair for the comparison: 31² = 961, the most. With the default 17² the
/// rms error of F over partly hidden Cornell pairs is about 4% (see `measure_estimators`),
/// too loose for a 2% bound on every pair.
const SAMPLES: u32 = 1024;

/// Compares `F_contour × fraction` with the brute-force reference for a partly hidden element
/// pair of each kind (the first, in element order, whose estimated visible fraction is
/// 0.25–0.75), and for a floor patch under the tall block (its footprint shrunk by 10%) and
/// a light element: fully hidden.
fn compare_with_reference(n: u64) {
    let c = cornell();
    let ff = FormFactors::new(&c.mesh, ContourOptions::default());
    let picks = [
        c.pick("floor", "light", 0.25..0.75),
        c.pick("floor", "back_wall", 0.25..0.75),
        c.pick("red_wall", "green_wall", 0.25..0.75),
        c.pick("floor", "ceiling", 0.25..0.75),
        c.pick("short_block", "back_wall", 0.25..0.75),
    ];
    let mut cases: Vec<(String, Patch, Patch, f64, Visibility)> = picks
        .iter()
        .map(|&(i, j)| {
            let label = format!("{}[{i}] → {}[{j}]", c.name(i), c.name(j));
            let v = c.occluders.element_pair(&c.pairs, &c.mesh, i, j, SAMPLES);
            (
                label,
                Patch::element(&c.mesh, i),
                Patch::element(&c.mesh, j),
                ff.pair(i, j),
                v,
            )
        })
        .collect();
    let under = c.under_tall_block();
    let light = (0..c.mesh.elements.len())
        .find(|&e| c.name(e) == "light")
        .unwrap();
    let light = Patch::element(&c.mesh, light);
    let v = c.occluders.visibility(&under, &light, SAMPLES, 1);
    let exact = polygon_pair(under.corners(), light.corners(), &ContourOptions::default());
    cases.push((
        "floor under the tall block → light".into(),
        under,
        light,
        exact,
        v,
    ));
    let results: Vec<(f64, f64)> = cases
        .par_iter()
        .enumerate()
        .map(|(k, (_, a, b, _, _))| reference(&c.polygons, a, b, n, k as u64 + 1))
        .collect();
    for ((label, _, _, exact, v), (reference, se)) in cases.iter().zip(results) {
        let ours = exact * v.fraction;
        let tolerance = (3.0 * se).max(0.02 * reference);
        println!(
            "{label}: contour {exact:.6} × {:.4} = {ours:.6}, reference {reference:.6} ± {se:.1e} ({:+.2}%)",
            v.fraction,
            100.0 * (ours - reference) / reference.max(1e-300)
        );
        assert!(v.occludable && v.rays > 0, "{label}");
        if reference == 0.0 {
            assert_eq!(v.fraction, 0.0, "{label}: hidden pair");
        } else {
            assert!(
                (ours - reference).abs() <= tolerance,
                "{label}: {ours} vs {reference} ± {se}"
            );
        }
    }
}

/// 2·10⁵ reference samples per pair (about a second in the test profile).
#[test]
fn partly_hidden_pairs_match_the_brute_force_reference() {
    compare_with_reference(200_000);
}

/// The same with 10⁶ samples per pair: `cargo test --release -p bake-visibility -- --ignored`.
#[test]
#[ignore = "heavier reference (10⁶ samples per pair); run in release"]
fn partly_hidden_pairs_match_the_brute_force_reference_tightly() {
    compare_with_reference(1_000_000);
}

/// Whether the point (x, z) lies in the floor element's quad (seen from above).
fn over(floor: &Patch, x: f64, z: f64) -> bool {
    let c = floor.corners();
    (0..c.len()).all(|k| {
        let (a, b) = (c[k], c[(k + 1) % c.len()]);
        // Counter-clockwise about +y.
        (b.z - a.z) * (x - a.x) - (b.x - a.x) * (z - a.z) >= 0.0
    })
}

/// Block sides and the floor elements their bottom edge runs across share a contact line:
/// nothing can come between them (unless the other block is near), so their form factor is
/// the exact contour value.
#[test]
fn pairs_on_a_contact_line_keep_the_contour_value() {
    let c = cornell();
    let bounds = |name: &str| {
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for (p, n) in c.polygons.iter().zip(&c.names) {
            if n == name {
                for v in &p.vertices {
                    lo = lo.min(*v);
                    hi = hi.max(*v);
                }
            }
        }
        (lo, hi)
    };
    let (mut checked, mut near_other_block) = (0, 0);
    for (block, other) in [("short_block", "tall_block"), ("tall_block", "short_block")] {
        let (olo, ohi) = bounds(other);
        for (i, j) in c.between(block, "floor") {
            let (side, floor) = if c.name(i) == "floor" { (j, i) } else { (i, j) };
            let (a, b) = (
                Patch::element(&c.mesh, side),
                Patch::element(&c.mesh, floor),
            );
            let bottom: Vec<DVec3> = a.corners().iter().copied().filter(|p| p.y == 0.0).collect();
            if a.normal().y != 0.0 || bottom.len() != 2 {
                continue;
            }
            let crosses = (0..=64).any(|k| {
                let p = bottom[0].lerp(bottom[1], k as f64 / 64.0);
                over(&b, p.x, p.z)
            });
            if !crosses {
                continue;
            }
            let lo = a
                .corners()
                .iter()
                .chain(b.corners())
                .fold(DVec3::INFINITY, |m, p| m.min(*p));
            let hi = a
                .corners()
                .iter()
                .chain(b.corners())
                .fold(DVec3::NEG_INFINITY, |m, p| m.max(*p));
            if lo.cmple(ohi).all() && hi.cmpge(olo).all() {
                near_other_block += 1;
                continue;
            }
            assert!(!c.occluders.can_occlude(&a, &b), "{side} {floor}");
            let v = c
                .occluders
                .element_pair(&c.pairs, &c.mesh, side, floor, DEFAULT_SAMPLES);
            assert_eq!(v, Visibility::UNOCCLUDED, "{side} {floor}");
            checked += 1;
        }
    }
    println!("{checked} contact-line pairs unoccludable; {near_other_block} skipped (other block within their box)");
    assert!(checked >= 16, "{checked}");
}

/// The BVH-based test and the precomputed polygon-pair candidates agree on every element
/// pair; and the share of pairs that need rays.
#[test]
fn both_occludability_tests_agree_on_every_pair() {
    let c = cornell();
    let n = c.mesh.elements.len();
    let (mut facing, mut occludable) = (0u64, 0u64);
    for i in 0..n {
        let a = Patch::element(&c.mesh, i);
        for j in i + 1..n {
            let b = Patch::element(&c.mesh, j);
            let bvh = c.occluders.can_occlude(&a, &b);
            assert_eq!(bvh, c.pairs.can_occlude(&c.occluders, &a, &b), "{i} {j}");
            occludable += u64::from(bvh);
            facing += u64::from(
                a.corners()
                    .iter()
                    .any(|p| (*p - b.corners()[0]).dot(b.normal()) > 1e-3)
                    && b.corners()
                        .iter()
                        .any(|p| (*p - a.corners()[0]).dot(a.normal()) > 1e-3),
            );
        }
    }
    println!(
        "Cornell box, {n} elements: {occludable} of {facing} facing element pairs occludable ({:.1}%); polygon level: {} of {} ({})",
        100.0 * occludable as f64 / facing as f64,
        c.pairs.len(),
        c.pairs.facing_pairs(),
        c.pairs.effects().reason
    );
    assert!(c.pairs.effects().occlusion);
    assert!(occludable > 0 && occludable < facing);
}

/// Estimator and point-layout errors against the reference, for the report:
/// `cargo test --release -p bake-visibility --test cornell -- --ignored measure --nocapture`.
#[test]
#[ignore = "measurement, prints a table; run in release"]
fn measure_estimators() {
    let c = cornell();
    let ff = FormFactors::new(&c.mesh, ContourOptions::default());
    let n = c.mesh.elements.len();
    let mut partial = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let v = c.occluders.element_pair(&c.pairs, &c.mesh, i, j, 1024);
            if v.fraction > 0.05 && v.fraction < 0.95 {
                partial.push((i, j));
            }
        }
    }
    let stride = (partial.len() / 200).max(1);
    let chosen: Vec<(usize, usize)> = partial.iter().copied().step_by(stride).collect();
    println!(
        "{} partly hidden pairs, {} measured",
        partial.len(),
        chosen.len()
    );
    let references: Vec<(f64, f64)> = chosen
        .par_iter()
        .map(|&(i, j)| {
            let (a, b) = (Patch::element(&c.mesh, i), Patch::element(&c.mesh, j));
            reference(&c.polygons, &a, &b, 400_000, (i * n + j) as u64)
        })
        .collect();
    let layouts = [
        (Pattern::Shuffled, Estimator::Uniform),
        (Pattern::Shuffled, Estimator::KernelWeighted),
        (Pattern::OrthogonalArray, Estimator::Uniform),
        (Pattern::OrthogonalArray, Estimator::KernelWeighted),
    ];
    for (pattern, estimator) in layouts {
        for samples in [64u32, 128, 256, 512, 1024] {
            let start = std::time::Instant::now();
            let (mut sq, mut sq_abs, mut rays) = (0.0, 0.0, 0u64);
            let (mut within, mut mid, mut mid_within) = (0, 0, 0);
            for (&(i, j), &(reference, se)) in chosen.iter().zip(&references) {
                let (a, b) = (Patch::element(&c.mesh, i), Patch::element(&c.mesh, j));
                let seed = bake_visibility::pair_seed(i, j);
                let v = c
                    .occluders
                    .visibility_pattern(&a, &b, samples, seed, estimator, pattern);
                let exact = ff.pair(i, j);
                let ours = exact * v.fraction;
                let e = (ours - reference) / reference;
                sq += e * e;
                sq_abs += (v.fraction - reference / exact).powi(2);
                rays += u64::from(v.rays);
                let ok = (ours - reference).abs() <= (3.0 * se).max(0.02 * reference);
                if !ok
                    && std::env::var("VIS_DETAIL")
                        .is_ok_and(|d| d == format!("{estimator:?}{samples}"))
                {
                    let (ei, ej) = (&c.mesh.elements[i], &c.mesh.elements[j]);
                    println!(
                        "  {}[{i}] {}[{j}] dist {:.0} F {:.5} frac {:.4} ref frac {:.4} ± {:.4} err {:+.1}%",
                        c.name(i), c.name(j), ei.centroid.distance(ej.centroid), exact,
                        v.fraction, reference / exact, se / exact, 100.0 * e
                    );
                }
                within += usize::from(ok);
                if (0.25..0.75).contains(&(reference / exact)) {
                    mid += 1;
                    mid_within += usize::from(ok);
                }
            }
            let m = chosen.len() as f64;
            println!(
                "{pattern:?} {estimator:?} K={samples}: {:.1} µs/pair, rays/pair {:.0}, F rms {:.2}%, fraction rms {:.4}, within max(3se,2%): {within}/{}, fraction 0.25–0.75: {mid_within}/{mid}",
                start.elapsed().as_secs_f64() * 1e6 / m,
                rays as f64 / m,
                100.0 * (sq / m).sqrt(),
                (sq_abs / m).sqrt(),
                chosen.len()
            );
        }
    }
}
